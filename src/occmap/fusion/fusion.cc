#include "occmap/fusion/fusion.h"

#include <fmt/core.h>

#include <algorithm>

namespace occmap {
namespace {

// The image-based scatter of one camera: marks[cell] = value for every cell one of the camera's
// unchanged pixels views, through L1 (the sentinel cell absorbs unmapped pixels: no branch on
// it) and then through the coverage-fix pairs. marks has num_cells + 1 entries.
void ScatterUnchanged(const GroundLut& lut, int camera, std::span<const uint8_t> changes, uint8_t value,
                      uint8_t* marks) {
  const uint8_t* camera_changes = changes.data() + lut.pixel_offset(camera);
  const std::span<const uint32_t> l1 = lut.l1(camera);
  for (size_t p = 0; p < l1.size(); ++p) {
    if (camera_changes[p] == 0) marks[l1[p]] = value;
  }
  const std::span<const uint32_t> extra_pixels = lut.extra_pixels(camera);
  const std::span<const uint32_t> extra_cells = lut.extra_cells(camera);
  for (size_t e = 0; e < extra_pixels.size(); ++e) {
    if (camera_changes[extra_pixels[e]] == 0) marks[extra_cells[e]] = value;
  }
}

}  // namespace

Status FusionOptions::Validate(int num_cameras) const {
  if (method != FusionMethod::kImageBased && method != FusionMethod::kMapBased) {
    return InvalidInput("method: expected image-based or map-based");
  }
  if (max_free_views < 0 || max_free_views >= std::max(num_cameras, 1)) {
    return InvalidInput(fmt::format("max_free_views: expected 0..{} (fewer than the {} cameras), found {}",
                                    std::max(num_cameras - 1, 0), num_cameras, max_free_views));
  }
  return Status::Ok();
}

Fusion::Fusion(const GroundLut& lut) : lut_(lut) {
  const int num_cameras = lut.num_cameras();
  OCCMAP_CHECK(num_cameras > 0, "fusion: tables without cameras");
  const size_t num_cells = static_cast<size_t>(lut.grid().num_cells());
  camera_sees_.assign(static_cast<size_t>(num_cameras), std::vector<uint8_t>(num_cells, 0));
  const std::span<const uint32_t> offsets = lut.l2_offsets();
  const std::span<const uint32_t> pixels = lut.l2_pixels();
  for (size_t cell = 0; cell < num_cells; ++cell) {
    int camera = 0;
    for (uint32_t e = offsets[cell]; e < offsets[cell + 1]; ++e) {
      const uint32_t pixel = pixels[e];
      // L2 lists a cell's pixels camera by camera in ascending camera order (BuildGroundLut);
      // the map-based vote count relies on it.
      OCCMAP_CHECK(pixel >= lut.pixel_offset(camera), "fusion: L2 entries of a cell are not grouped by camera");
      while (pixel >= lut.pixel_offset(camera + 1)) ++camera;
      camera_sees_[static_cast<size_t>(camera)][cell] = 1;
    }
  }
  camera_active_.assign(static_cast<size_t>(num_cameras), 0);
}

void Fusion::CountActiveViews(const std::vector<bool>& active) {
  const size_t num_cells = static_cast<size_t>(lut_.grid().num_cells());
  if (active_views_.size() == num_cells && active == active_for_counts_) return;
  active_views_.assign(num_cells, 0);
  for (size_t n = 0; n < active.size(); ++n) {
    if (!active[n]) continue;
    const uint8_t* sees = camera_sees_[n].data();
    for (size_t cell = 0; cell < num_cells; ++cell) {
      active_views_[cell] = static_cast<uint8_t>(active_views_[cell] + sees[cell]);
    }
  }
  active_for_counts_ = active;
}

void Fusion::Fuse(std::span<const uint8_t> changes, const std::vector<bool>& active, const FusionOptions& options,
                  OccupancyMap& map) {
  OCCMAP_CHECK(changes.size() == lut_.total_pixels(), "fusion: change buffer size differs from the tables' pixels");
  OCCMAP_CHECK(active.size() == static_cast<size_t>(lut_.num_cameras()), "fusion: one active flag per camera");
  OCCMAP_CHECK(options.Validate(lut_.num_cameras()).ok(), "fusion: invalid options (validate them first)");
  if (!(map.grid() == lut_.grid()) || map.states().size() != static_cast<size_t>(lut_.grid().num_cells())) {
    map = OccupancyMap(lut_.grid());
  }
  for (size_t n = 0; n < active.size(); ++n) camera_active_[n] = active[n] ? 1 : 0;
  CountActiveViews(active);
  if (options.method == FusionMethod::kImageBased) {
    FuseImageBased(changes, active, options.max_free_views, map);
  } else {
    FuseMapBased(changes, active, options.max_free_views, map);
  }
}

void Fusion::FuseImageBased(std::span<const uint8_t> changes, const std::vector<bool>& active, int k,
                            OccupancyMap& map) {
  const size_t num_cells = static_cast<size_t>(lut_.grid().num_cells());
  CellState* states = map.states().data();
  if (k == 0) {
    // The paper's AND: O = 1 (occupied) everywhere, O = 0 where an unchanged active pixel
    // views the cell; an inactive camera's pixels are skipped.
    scratch_.assign(num_cells + 1, 1);
    for (int n = 0; n < lut_.num_cameras(); ++n) {
      if (active[static_cast<size_t>(n)]) ScatterUnchanged(lut_, n, changes, 0, scratch_.data());
    }
    for (size_t cell = 0; cell < num_cells; ++cell) {
      states[cell] = Decide(active_views_[cell], scratch_[cell] != 0 ? 0 : 1, 0);
    }
    return;
  }
  // Votes: each active camera marks the cells it says free (one byte per cell, so a camera
  // with several unchanged pixels in a cell votes once), and the marks are summed.
  free_votes_.assign(num_cells, 0);
  for (int n = 0; n < lut_.num_cameras(); ++n) {
    if (!active[static_cast<size_t>(n)]) continue;
    scratch_.assign(num_cells + 1, 0);
    ScatterUnchanged(lut_, n, changes, 1, scratch_.data());
    for (size_t cell = 0; cell < num_cells; ++cell) {
      free_votes_[cell] = static_cast<uint8_t>(free_votes_[cell] + scratch_[cell]);
    }
  }
  for (size_t cell = 0; cell < num_cells; ++cell) states[cell] = Decide(active_views_[cell], free_votes_[cell], k);
}

void Fusion::FuseMapBased(std::span<const uint8_t> changes, const std::vector<bool>& active, int k,
                          OccupancyMap& map) {
  const size_t num_cells = static_cast<size_t>(lut_.grid().num_cells());
  const uint32_t* offsets = lut_.l2_offsets().data();
  const uint32_t* pixels = lut_.l2_pixels().data();
  const uint8_t* change = changes.data();
  CellState* states = map.states().data();
  const bool all_active = std::all_of(active.begin(), active.end(), [](bool a) { return a; });
  if (k == 0 && all_active) {
    // The paper's map-based loop: free at the first unchanged view.
    for (size_t cell = 0; cell < num_cells; ++cell) {
      int free_votes = 0;
      for (uint32_t e = offsets[cell]; e < offsets[cell + 1]; ++e) {
        if (change[pixels[e]] == 0) {
          free_votes = 1;
          break;
        }
      }
      states[cell] = Decide(active_views_[cell], free_votes, 0);
    }
    return;
  }
  // General rule: count the distinct active cameras with an unchanged view. A cell's entries
  // come camera by camera in ascending order, so `camera` only moves forward, and a camera
  // that already voted is skipped until its entries end. Stops once more than k say free.
  for (size_t cell = 0; cell < num_cells; ++cell) {
    if (active_views_[cell] == 0) {
      states[cell] = CellState::kUnseen;
      continue;
    }
    int free_votes = 0;
    int camera = 0;
    uint32_t camera_end = lut_.pixel_offset(1);
    int last_voter = -1;
    for (uint32_t e = offsets[cell]; e < offsets[cell + 1]; ++e) {
      const uint32_t pixel = pixels[e];
      while (pixel >= camera_end) {
        ++camera;
        OCCMAP_DCHECK(camera < lut_.num_cameras(), "L2 pixel id beyond the last camera");
        camera_end = lut_.pixel_offset(camera + 1);
      }
      if (camera == last_voter || camera_active_[static_cast<size_t>(camera)] == 0) continue;
      if (change[pixel] == 0) {
        last_voter = camera;
        if (++free_votes > k) break;
      }
    }
    states[cell] = Decide(active_views_[cell], free_votes, k);
  }
}

std::vector<uint8_t> PaperImageBasedLoop(const GroundLut& lut, std::span<const uint8_t> changes) {
  OCCMAP_CHECK(changes.size() == lut.total_pixels(), "fusion: change buffer size differs from the tables' pixels");
  std::vector<uint8_t> occupancy(static_cast<size_t>(lut.grid().num_cells()) + 1, 1);
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const uint32_t offset = lut.pixel_offset(n);
    const std::span<const uint32_t> l1 = lut.l1(n);
    for (size_t p = 0; p < l1.size(); ++p) {
      if (changes[offset + p] == 0) occupancy[l1[p]] = 0;
    }
    const std::span<const uint32_t> extra_pixels = lut.extra_pixels(n);
    const std::span<const uint32_t> extra_cells = lut.extra_cells(n);
    for (size_t e = 0; e < extra_pixels.size(); ++e) {
      if (changes[offset + extra_pixels[e]] == 0) occupancy[extra_cells[e]] = 0;
    }
  }
  return occupancy;
}

}  // namespace occmap
