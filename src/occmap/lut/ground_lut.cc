#include "occmap/lut/ground_lut.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace occmap {
namespace {

constexpr uint32_t kLutFormatVersion = 2;  // 2: the cache file holds no L2 (derived on load)

struct CameraTables {
  std::vector<uint32_t> l1;
  std::vector<uint32_t> extra_pixels;
  std::vector<uint32_t> extra_cells;
  std::vector<uint8_t> seen;  // per cell: 1 when this camera views it
  CameraCoverage coverage;
};

// L1 by casting every pixel centre's ray to the plane (equations 2-3), rows split over threads.
void BuildL1(const LutCameraInput& input, const FloorGrid& grid, double plane_z, Context& ctx,
             CameraTables& out) {
  const ImageSize size = input.camera->image_size();
  const uint32_t sentinel = static_cast<uint32_t>(grid.num_cells());
  out.l1.assign(static_cast<size_t>(size.width) * size.height, sentinel);
  std::vector<CameraCoverage> partial(ctx.num_threads());
  ParallelFor(
      ctx, 0, size.height,
      [&](int64_t row_begin, int64_t row_end, int worker) {
        CameraCoverage& c = partial[worker];
        for (int64_t y = row_begin; y < row_end; ++y) {
          const uint8_t* mask_row = input.mask.empty() ? nullptr : input.mask.row(static_cast<int>(y));
          uint32_t* l1_row = out.l1.data() + y * size.width;
          for (int x = 0; x < size.width; ++x) {
            if (mask_row != nullptr && mask_row[x] == 0) {
              ++c.pixels_masked;
              continue;
            }
            const auto on_plane =
                input.camera->PixelToPlane(Eigen::Vector2d(x, static_cast<double>(y)), plane_z);
            if (!on_plane) {
              ++c.pixels_no_ray;
              continue;
            }
            const int64_t cell = grid.CellAt(on_plane->x(), on_plane->y());
            if (cell < 0) {
              ++c.pixels_off_grid;
              continue;
            }
            l1_row[x] = static_cast<uint32_t>(cell);
            ++c.pixels_mapped;
          }
        }
      },
      /*min_chunk=*/8);
  out.coverage.pixels = int64_t{size.width} * size.height;
  for (const auto& c : partial) {
    out.coverage.pixels_masked += c.pixels_masked;
    out.coverage.pixels_no_ray += c.pixels_no_ray;
    out.coverage.pixels_off_grid += c.pixels_off_grid;
    out.coverage.pixels_mapped += c.pixels_mapped;
  }
}

// The coverage fix: every in-view cell that no ray hit gets its own projected pixel.
void AddCellProjections(const LutCameraInput& input, const FloorGrid& grid, double plane_z, Context& ctx,
                        CameraTables& out) {
  const ImageSize size = input.camera->image_size();
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> partial(ctx.num_threads());
  ParallelFor(
      ctx, 0, grid.num_cells(),
      [&](int64_t begin, int64_t end, int worker) {
        auto& added = partial[worker];
        for (int64_t cell = begin; cell < end; ++cell) {
          if (out.seen[cell]) continue;
          const Eigen::Vector2d c = grid.CellCenter(cell);
          const auto px = input.camera->Project(Eigen::Vector3d(c.x(), c.y(), plane_z));
          if (!px || !input.camera->InImage(*px)) continue;
          const int x = std::clamp(static_cast<int>(std::lround(px->x())), 0, size.width - 1);
          const int y = std::clamp(static_cast<int>(std::lround(px->y())), 0, size.height - 1);
          if (!input.mask.empty() && input.mask(x, y) == 0) continue;
          added.emplace_back(static_cast<uint32_t>(y * size.width + x), static_cast<uint32_t>(cell));
        }
      },
      /*min_chunk=*/4096);
  std::vector<std::pair<uint32_t, uint32_t>> all;
  for (auto& p : partial) all.insert(all.end(), p.begin(), p.end());
  std::sort(all.begin(), all.end());  // by pixel: streams like L1, and is deterministic
  out.extra_pixels.reserve(all.size());
  out.extra_cells.reserve(all.size());
  for (const auto& [pixel, cell] : all) {
    out.extra_pixels.push_back(pixel);
    out.extra_cells.push_back(cell);
    out.seen[cell] = 1;
  }
  out.coverage.cells_added = static_cast<int64_t>(all.size());
}

}  // namespace

Status LutOptions::Validate() const {
  if (!std::isfinite(plane_height_m)) return InvalidInput("plane_height_m: expected a finite number");
  return Status::Ok();
}

Result<GroundLut> BuildGroundLut(const std::vector<LutCameraInput>& cameras, const FloorGrid& grid,
                                 const LutOptions& options, Context& ctx) {
  OCCMAP_RETURN_IF_ERROR(grid.Validate());
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  if (cameras.empty()) return InvalidInput("cameras: expected at least one camera, found none");
  if (cameras.size() > GroundLut::kMaxCameras) {
    return InvalidInput(fmt::format("cameras: at most {} cameras, found {}", GroundLut::kMaxCameras, cameras.size()));
  }
  if (grid.num_cells() >= std::numeric_limits<uint32_t>::max()) {
    return ResourceExhausted("grid: too many cells for 32-bit cell indices");
  }
  uint64_t total_pixels = 0;
  for (size_t n = 0; n < cameras.size(); ++n) {
    const auto& cam = cameras[n];
    OCCMAP_CHECK(cam.camera != nullptr, "null camera");
    const ImageSize size = cam.camera->image_size();
    if (!cam.mask.empty() && (cam.mask.width() != size.width || cam.mask.height() != size.height)) {
      return InvalidInput(fmt::format("camera {}: mask: expected {}x{} pixels (the image size), found {}x{}", n,
                                      size.width, size.height, cam.mask.width(), cam.mask.height()));
    }
    if (!cam.camera->SupportsPlaneHeight(options.plane_height_m)) {
      return InvalidInput(fmt::format("camera {}: a {} calibration only knows the floor; cannot build tables for "
                                      "plane_height_m = {}",
                                      n, cam.camera->kind(), options.plane_height_m));
    }
    total_pixels += static_cast<uint64_t>(size.width) * static_cast<uint64_t>(size.height);
  }
  if (total_pixels >= std::numeric_limits<uint32_t>::max()) {
    return ResourceExhausted(fmt::format("cameras: {} pixels in all is too many for 32-bit pixel ids", total_pixels));
  }

  GroundLut lut;
  lut.grid_ = grid;
  lut.plane_height_m_ = options.plane_height_m;
  const size_t num_cells = static_cast<size_t>(grid.num_cells());
  lut.view_count_.assign(num_cells, 0);
  lut.pixel_offsets_.push_back(0);
  for (const auto& input : cameras) {
    CameraTables t;
    BuildL1(input, grid, options.plane_height_m, ctx, t);
    t.seen.assign(num_cells, 0);
    for (uint32_t cell : t.l1) {
      if (cell < num_cells) t.seen[cell] = 1;
    }
    t.coverage.cells_from_rays = std::count(t.seen.begin(), t.seen.end(), 1);
    if (options.add_cell_projections) AddCellProjections(input, grid, options.plane_height_m, ctx, t);
    t.coverage.cells_seen = t.coverage.cells_from_rays + t.coverage.cells_added;
    for (size_t c = 0; c < num_cells; ++c) lut.view_count_[c] = static_cast<uint8_t>(lut.view_count_[c] + t.seen[c]);

    const ImageSize size = input.camera->image_size();
    lut.image_sizes_.push_back(size);
    lut.pixel_offsets_.push_back(lut.pixel_offsets_.back() + static_cast<uint32_t>(size.width * size.height));
    lut.l1_.push_back(std::move(t.l1));
    lut.extra_pixels_.push_back(std::move(t.extra_pixels));
    lut.extra_cells_.push_back(std::move(t.extra_cells));
    lut.coverage_.push_back(t.coverage);
  }

  lut.DeriveL2();
  return lut;
}

int64_t GroundLut::MemoryBytes() const {
  int64_t bytes = 0;
  for (const auto& v : l1_) bytes += static_cast<int64_t>(v.size() * sizeof(uint32_t));
  for (const auto& v : extra_pixels_) bytes += static_cast<int64_t>(v.size() * sizeof(uint32_t) * 2);
  bytes += static_cast<int64_t>((l2_offsets_.size() + l2_pixels_.size()) * sizeof(uint32_t));
  bytes += static_cast<int64_t>(view_count_.size());
  return bytes;
}

Status GroundLut::CheckCameraTables() const {
  OCCMAP_RETURN_IF_ERROR(grid_.Validate());
  const size_t n = image_sizes_.size();
  const uint64_t num_cells = static_cast<uint64_t>(grid_.num_cells());
  if (n == 0 || n > kMaxCameras) return DataLoss(fmt::format("camera count {} out of range", n));
  if (pixel_offsets_.size() != n + 1 || l1_.size() != n || extra_pixels_.size() != n || extra_cells_.size() != n ||
      coverage_.size() != n) {
    return DataLoss("per-camera table counts disagree");
  }
  if (pixel_offsets_[0] != 0) return DataLoss("pixel offsets do not start at 0");
  for (size_t c = 0; c < n; ++c) {
    const uint64_t pixels = static_cast<uint64_t>(image_sizes_[c].width) * image_sizes_[c].height;
    if (image_sizes_[c].width <= 0 || image_sizes_[c].height <= 0) return DataLoss("bad image size");
    if (pixel_offsets_[c + 1] != pixel_offsets_[c] + pixels) return DataLoss("pixel offsets disagree with image sizes");
    if (l1_[c].size() != pixels) return DataLoss(fmt::format("camera {}: L1 has {} entries, expected {}", c, l1_[c].size(), pixels));
    for (uint32_t cell : l1_[c]) {
      if (cell > num_cells) return DataLoss(fmt::format("camera {}: L1 entry {} beyond the sentinel", c, cell));
    }
    if (extra_pixels_[c].size() != extra_cells_[c].size()) return DataLoss("extra pixel and cell lists differ in length");
    for (size_t e = 0; e < extra_pixels_[c].size(); ++e) {
      if (extra_pixels_[c][e] >= pixels || extra_cells_[c][e] >= num_cells) return DataLoss("extra entry out of range");
    }
  }
  return Status::Ok();
}

void GroundLut::DeriveL2() {
  // L2 by counting sort: offsets from the counts, then every (pixel, cell) pair in camera and
  // pixel order (L1 pairs of a camera, then its extra pairs).
  const size_t num_cells = static_cast<size_t>(grid_.num_cells());
  std::vector<uint32_t> counts(num_cells + 1, 0);
  for (int n = 0; n < num_cameras(); ++n) {
    for (uint32_t cell : l1_[n]) ++counts[cell];  // the sentinel counts into counts[num_cells]
    for (uint32_t cell : extra_cells_[n]) ++counts[cell];
  }
  l2_offsets_.assign(num_cells + 1, 0);
  uint64_t running = 0;
  for (size_t c = 0; c < num_cells; ++c) {
    l2_offsets_[c] = static_cast<uint32_t>(running);
    running += counts[c];
  }
  l2_offsets_[num_cells] = static_cast<uint32_t>(running);
  l2_pixels_.resize(running);
  std::vector<uint32_t> cursor(l2_offsets_.begin(), l2_offsets_.end() - 1);
  for (int n = 0; n < num_cameras(); ++n) {
    const uint32_t base = pixel_offsets_[n];
    const auto& l1 = l1_[n];
    for (size_t p = 0; p < l1.size(); ++p) {
      if (l1[p] < num_cells) l2_pixels_[cursor[l1[p]]++] = base + static_cast<uint32_t>(p);
    }
    for (size_t e = 0; e < extra_cells_[n].size(); ++e) {
      l2_pixels_[cursor[extra_cells_[n][e]]++] = base + extra_pixels_[n][e];
    }
  }
}

Status GroundLut::CheckConsistency() const {
  OCCMAP_RETURN_IF_ERROR(CheckCameraTables());
  const size_t n = image_sizes_.size();
  const uint64_t num_cells = static_cast<uint64_t>(grid_.num_cells());
  if (l2_offsets_.size() != num_cells + 1 || view_count_.size() != num_cells) return DataLoss("per-cell table sizes disagree");
  if (l2_offsets_[0] != 0 || l2_offsets_.back() != l2_pixels_.size()) return DataLoss("L2 offsets do not span L2");
  for (size_t c = 0; c < num_cells; ++c) {
    if (l2_offsets_[c] > l2_offsets_[c + 1]) return DataLoss("L2 offsets decrease");
    if (view_count_[c] > n) return DataLoss("view count exceeds the camera count");
  }
  const uint32_t total = pixel_offsets_.back();
  for (uint32_t p : l2_pixels_) {
    if (p >= total) return DataLoss("L2 pixel id out of range");
  }
  return Status::Ok();
}

uint64_t GroundLutKey(const std::vector<LutCameraInput>& cameras, const FloorGrid& grid, const LutOptions& options) {
  Hasher h;
  h.Add("occmap-ground-lut");
  h.AddPod(kLutFormatVersion);
  grid.AppendToHash(h);
  h.AddPod(options.plane_height_m);
  h.AddPod(options.add_cell_projections);
  h.AddPod(cameras.size());
  for (const auto& cam : cameras) {
    cam.camera->AppendToHash(h);
    if (cam.mask.empty()) {
      h.Add("no-mask");
    } else {
      h.Add("mask");
      h.AddPod(cam.mask.width());
      h.AddPod(cam.mask.height());
      for (int y = 0; y < cam.mask.height(); ++y) h.AddBytes(cam.mask.row(y), static_cast<size_t>(cam.mask.width()));
    }
  }
  return h.Digest();
}

}  // namespace occmap
