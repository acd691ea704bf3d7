#include "occmap/objects/elevated_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "occmap/fusion/blobs.h"
#include "occmap/util/status.h"

namespace occmap {

ElevatedCheck::ElevatedCheck(const ObjectOptions& options, double plane_height_m,
                             std::vector<const CameraModel*> cameras, std::vector<const Image<uint8_t>*> masks)
    : support_heights_m_(options.support_heights_m), min_support_(options.min_support),
      support_slack_m_(options.support_slack_m), plane_height_m_(plane_height_m), cameras_(std::move(cameras)),
      masks_(std::move(masks)) {
  OCCMAP_CHECK(masks_.size() == cameras_.size(), "ElevatedCheck: one mask (or null) per camera");
  for (const CameraModel* model : cameras_) {
    // Sites allow 16384 pixels a side (site.cc): an invariant here.
    OCCMAP_CHECK(model->image_size().width <= 65536 && model->image_size().height <= 32768,
                 "ElevatedCheck: camera images up to 65536 x 32768 pixels (pixels are packed)");
  }
}

void ElevatedCheck::Apply(const OccupancyMap& map, std::span<const int32_t> labels, const std::vector<bool>& active,
                          const ChangeLookup& changed, std::span<const ChangeBuffer> buffers,
                          const std::vector<int>& kept_index, const std::vector<Blob>& kept_groups,
                          std::vector<Detection>& detections) {
  OCCMAP_CHECK(buffers.empty() || buffers.size() == cameras_.size(), "ElevatedCheck: one change buffer per camera");
  const bool begun = std::exchange(frame_begun_, false);
  if (support_heights_m_.empty() || (!changed && buffers.empty()) || detections.empty()) return;
  if (!begun) BeginFrame(active);
  frame_begun_ = false;  // BeginFrame sets it; the next frame starts afresh
  RemoveUnsupported(map, labels, changed, buffers, kept_index, kept_groups, detections);
}

void ElevatedCheck::BeginFrame(const std::vector<bool>& active) {
  // A new generation of the memos of SupportAt (all cleared before the counter overflows).
  if (++support_generation_ >= (1 << 28)) {
    support_generation_ = 1;
    for (size_t k = cameras_.size(); k < support_pixel_.size(); k += cameras_.size() + 1) {
      support_pixel_[k] = kNotProjected;
    }
  }
  active_cameras_.clear();
  for (size_t n = 0; n < cameras_.size() && n < active.size(); ++n) {
    if (active[n]) active_cameras_.push_back(n);
  }
  frame_begun_ = true;
}

double ElevatedCheck::TallestArea(const FloorGrid& grid, double x_m, double y_m, double radius_m,
                                  const ChangeLookup& changed, std::span<const ChangeBuffer> buffers) {
  if (support_heights_m_.empty() || (!changed && buffers.empty())) return 0;
  OCCMAP_CHECK(frame_begun_, "ElevatedCheck: TallestArea before BeginFrame");
  PrepareSupport(grid);
  const int ci = static_cast<int>(std::floor((x_m - grid.origin_x_m) / grid.cell_size_m));
  const int cj = static_cast<int>(std::floor((y_m - grid.origin_y_m) / grid.cell_size_m));
  const int r = static_cast<int>(std::ceil(radius_m / grid.cell_size_m));
  int best = 0;
  for (size_t h = 0; h < support_heights_m_.size(); ++h) {
    int occupied = 0;
    for (int j = std::max(0, cj - r); j <= std::min(grid.cells_y - 1, cj + r); ++j) {
      for (int i = std::max(0, ci - r); i <= std::min(grid.cells_x - 1, ci + r); ++i) {
        if ((i - ci) * (i - ci) + (j - cj) * (j - cj) > r * r) continue;
        occupied += SupportAt(h, int64_t{j} * grid.cells_x + i, changed, buffers) == 1;
      }
    }
    best = std::max(best, occupied);
  }
  return best * grid.cell_size_m * grid.cell_size_m;
}

void ElevatedCheck::PrepareSupport(const FloorGrid& grid) {
  if (support_grid_ && *support_grid_ == grid) return;
  support_grid_ = grid;
  // Filled on first use, in square tiles of kTileSide x kTileSide cells: a frame needs the cells
  // under and beside its detections only. Tiles of 4096 cells in row order (8.5 rows of
  // WILDTRACK's 480-cell grid, 1 MB each at 64 cameras) made the first frame sets fill hundreds of
  // MB for a few hundred cells: 0.8 s of `occmap fuse`'s first frame set at 64 cameras.
  support_tiles_x_ = static_cast<size_t>((grid.cells_x + kTileSide - 1) / kTileSide);
  support_tiles_ = support_tiles_x_ * static_cast<size_t>((grid.cells_y + kTileSide - 1) / kTileSide);
  support_tile_start_.assign(support_heights_m_.size() * support_tiles_, -1);
  support_pixel_.clear();
  // Room for every tile up front: the vector then never moves as tiles are added (a move
  // copied all the tiles so far into fresh pages, on WILDTRACK most of the page faults of a
  // short run). Only the pages of the tiles used are ever touched.
  support_pixel_.reserve(support_tile_start_.size() * static_cast<size_t>(kTileSide * kTileSide) * (cameras_.size() + 1));
}

int32_t* ElevatedCheck::SupportPixels(size_t h, int64_t cell) {
  const int64_t cells_x = support_grid_->cells_x;
  const int64_t i = cell % cells_x, j = cell / cells_x;
  const size_t tile = static_cast<size_t>(j / kTileSide) * support_tiles_x_ + static_cast<size_t>(i / kTileSide);
  int64_t& start = support_tile_start_[h * support_tiles_ + tile];
  const size_t entries = cameras_.size() + 1;
  if (start < 0) {
    start = static_cast<int64_t>(support_pixel_.size());
    support_pixel_.resize(support_pixel_.size() + static_cast<size_t>(kTileSide * kTileSide) * entries, kNotProjected);
  }
  const auto in_tile = static_cast<size_t>((j % kTileSide) * kTileSide + i % kTileSide);
  return support_pixel_.data() + static_cast<size_t>(start) + in_tile * entries;
}

int32_t ElevatedCheck::SupportPixel(size_t h, size_t n, int64_t cell, int32_t* pixels) {
  int32_t& pixel = pixels[n];
  if (pixel != kNotProjected) return pixel;
  pixel = -1;
  const CameraModel& model = *cameras_[n];
  const Eigen::Vector2d c = support_grid_->CellCenter(cell);
  const auto px = model.Project(Eigen::Vector3d(c.x(), c.y(), plane_height_m_ + support_heights_m_[h]));
  if (!px || !model.InImage(*px)) return pixel;
  const int x = static_cast<int>(std::lround(px->x()));
  const int y = static_cast<int>(std::lround(px->y()));
  const ImageSize size = model.image_size();
  if (x < 0 || y < 0 || x >= size.width || y >= size.height) return pixel;
  // A masked pixel (outside the floor, or a static object in front) tells nothing.
  const Image<uint8_t>* mask = masks_[n];
  if (mask != nullptr && !mask->empty() && (*mask)(x, y) == 0) return pixel;
  pixel = PackPixel(x, y);
  return pixel;
}

int ElevatedCheck::SupportAt(size_t h, int64_t cell, const ChangeLookup& changed,
                              std::span<const ChangeBuffer> buffers) {
  int32_t* pixels = SupportPixels(h, cell);
  // The cell's state is asked again by neighbouring samples: kept for this frame.
  int32_t& memo = pixels[cameras_.size()];
  if (memo >= 0 && (memo >> 2) == support_generation_) return (memo & 3) - 1;
  const int state = SupportState(h, cell, pixels, changed, buffers);
  memo = support_generation_ * 4 + (state + 1);
  return state;
}

int ElevatedCheck::SupportState(size_t h, int64_t cell, int32_t* pixels, const ChangeLookup& changed,
                                std::span<const ChangeBuffer> buffers) {
  if (!buffers.empty()) return SupportStateFromBuffers(h, cell, pixels, buffers);
  // The reference: each camera's pixel asked through the lookup.
  int seeing = 0;
  for (size_t n : active_cameras_) {
    const int32_t p = SupportPixel(h, n, cell, pixels);
    if (p < 0) continue;
    ++seeing;
    if (!changed(static_cast<int>(n), static_cast<int>(PixelX(p)), static_cast<int>(PixelY(p)))) return 0;
  }
  return seeing > 0 ? 1 : -1;
}

void ElevatedCheck::RemoveUnsupported(const OccupancyMap& map, std::span<const int32_t> labels,
                                      const ChangeLookup& changed, std::span<const ChangeBuffer> buffers,
                                      const std::vector<int>& kept_index, const std::vector<Blob>& kept_groups,
                                      std::vector<Detection>& blobs) {
  const FloorGrid& grid = map.grid();
  PrepareSupport(grid);
  // Each detection's footprint cells: the occupied cells of its group (within the group's
  // box), each given to the group's nearest detection.
  std::vector<std::vector<int>> detections_of(kept_index.size());
  for (size_t d = 0; d < blobs.size(); ++d) detections_of[static_cast<size_t>(blobs[d].group)].push_back(static_cast<int>(d));
  std::vector<std::vector<std::pair<int, int>>>& footprint = footprint_;
  if (footprint.size() < blobs.size()) footprint.resize(blobs.size());
  for (size_t d = 0; d < blobs.size(); ++d) footprint[d].clear();
  for (size_t g = 0; g < kept_index.size(); ++g) {
    const Blob& box = kept_groups[g];
    const std::vector<int>& candidates = detections_of[g];
    if (candidates.empty()) continue;  // no cell would be given to anyone
    for (int j = box.min_j; j <= box.max_j; ++j) {
      // The row's occupied cells in order, free spans skipped a word at a time.
      const CellState* row = map.states().data() + int64_t{j} * grid.cells_x;
      for (int i = static_cast<int>(NextOccupied(row, box.min_i, box.max_i + 1)); i <= box.max_i;
           i = static_cast<int>(NextOccupied(row, i + 1, box.max_i + 1))) {
        const int64_t cell = int64_t{j} * grid.cells_x + i;
        if (labels[static_cast<size_t>(cell)] != kept_index[g]) continue;
        if (candidates.size() == 1) {  // the nearest of one (a finite distance beats the initial infinity)
          footprint[static_cast<size_t>(candidates[0])].push_back({i, j});
          continue;
        }
        // FloorGrid::CellCenter's expression, from (i, j) without a division.
        const double cx = grid.origin_x_m + (static_cast<double>(i) + 0.5) * grid.cell_size_m;
        const double cy = grid.origin_y_m + (static_cast<double>(j) + 0.5) * grid.cell_size_m;
        int best = -1;
        double best_d2 = std::numeric_limits<double>::infinity();
        for (int d : candidates) {
          const double dx = blobs[d].x_m - cx, dy = blobs[d].y_m - cy;
          const double d2 = dx * dx + dy * dy;
          if (d2 < best_d2) {
            best_d2 = d2;
            best = d;
          }
        }
        if (best >= 0) footprint[static_cast<size_t>(best)].push_back({i, j});
      }
    }
  }
  const int reach = std::max(0, static_cast<int>(std::lround(support_slack_m_ / grid.cell_size_m)));
  // The plane-h state of footprint cell (i, j): occupied when the plane shows the object over
  // it or beside it (within the slack: legs lean, a foot is ahead of the knee); free when some
  // camera sees that neighbourhood free; unknown (-1) when no camera sees it.
  auto state_near = [&](size_t h, int i, int j) {
    int state = -1;
    for (int dj = -reach; dj <= reach && state < 1; dj += std::max(1, reach)) {
      for (int di = -reach; di <= reach && state < 1; di += std::max(1, reach)) {
        const int ii = i + di, jj = j + dj;
        if (ii < 0 || jj < 0 || ii >= grid.cells_x || jj >= grid.cells_y) continue;
        state = std::max(state, SupportAt(h, int64_t{jj} * grid.cells_x + ii, changed, buffers));
      }
    }
    return state;
  };
  // A detection is dropped when some plane saw at least half of its footprint and no such
  // plane shows the object over min_support of what it saw; with no plane seeing it, nothing
  // speaks against it. Planes are tried in order and the first that supports it ends the test;
  // at most kSupportSamples footprint cells, evenly spread, are tested.
  constexpr size_t kSupportSamples = 64;
  std::vector<Detection> kept;
  for (size_t d = 0; d < blobs.size(); ++d) {
    const std::vector<std::pair<int, int>>& cells = footprint[d];
    const size_t stride = std::max<size_t>(1, (cells.size() + kSupportSamples - 1) / kSupportSamples);
    size_t samples = 0;
    for (size_t k = 0; k < cells.size(); k += stride) ++samples;
    bool evidence = false, support = false;
    for (size_t h = 0; h < support_heights_m_.size() && !support; ++h) {
      int seen = 0, supported = 0;
      for (size_t k = 0; k < cells.size(); k += stride) {
        const int state = state_near(h, cells[k].first, cells[k].second);
        seen += state >= 0;
        supported += state == 1;
      }
      if (seen == 0 || 2 * static_cast<size_t>(seen) < samples) continue;
      evidence = true;
      support = supported >= min_support_ * seen;
    }
    if (evidence && !support) continue;
    kept.push_back(std::move(blobs[d]));
  }
  blobs = std::move(kept);
}

}  // namespace occmap
