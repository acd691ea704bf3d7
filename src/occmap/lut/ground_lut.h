// GroundLut: the paper's lookup tables between image pixels and floor cells (section 2.5).
//
// L1[n, c, r] (per camera, row-major over the image): the cell the pixel's ray meets on the
// plane z = plane_height_m, or sentinel() = num_cells (the paper's extra map cell one past the
// end) for pixels that are masked, whose ray misses the grid, or whose ray never meets the plane
// in front of the camera.
// L2[x, y]: for each cell, the global ids of every pixel of every camera that views it, in CSR
// form (l2_offsets has num_cells + 1 entries). A pixel's global id is
// pixel_offset(camera) + row * width + column.
//
// Coverage fix. Rounding pixel rays alone leaves cells far from a camera without any pixel
// although the camera sees them (far cells are smaller than a pixel's footprint). For every
// cell whose centre projects into the image onto an unmasked pixel and that no ray of that
// camera hit, the projected pixel is added to the cell (extra_pixels / extra_cells: the pixel
// also views that cell). So every cell a camera sees has at least one of its pixels, and the
// image-based and map-based fusions see exactly the same pixel-cell pairs.
//
// view_count[cell] is how many cameras see the cell (0 = unseen). Tables are immutable once
// built and shared by all threads without locks.
//
//   std::vector<LutCameraInput> cams = {{&camera0, mask0.view()}, ...};
//   OCCMAP_ASSIGN_OR_RETURN(GroundLut lut, BuildGroundLut(cams, grid, LutOptions{}, ctx));
//   uint32_t cell = lut.l1(0)[row * width + col];
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "occmap/geometry/camera_model.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

struct LutCameraInput {
  const CameraModel* camera = nullptr;  // not owned
  // Floor mask (the paper's M, with the opposite sign convention): non-zero pixels are
  // monitored floor, zero pixels are excluded. Empty = every pixel is floor. Same size as the
  // camera's image.
  ImageView<const uint8_t> mask;
};

struct LutOptions {
  double plane_height_m = 0.0;       // the support plane z = h; 0 is the floor
  bool add_cell_projections = true;  // the coverage fix (see above)
  Status Validate() const;
};

// Per-camera figures, to print and to check.
struct CameraCoverage {
  int64_t pixels = 0;           // width * height
  int64_t pixels_masked = 0;    // excluded by the floor mask
  int64_t pixels_no_ray = 0;    // ray never meets the plane in front (or lens model invalid)
  int64_t pixels_off_grid = 0;  // ray meets the plane outside the grid
  int64_t pixels_mapped = 0;    // L1 entry is a cell
  int64_t cells_from_rays = 0;  // distinct cells hit by the camera's pixel rays
  int64_t cells_added = 0;      // in-view cells no ray hit, given their projected pixel
  int64_t cells_seen = 0;       // cells_from_rays + cells_added
  friend bool operator==(const CameraCoverage&, const CameraCoverage&) = default;
};

class GroundLut {
 public:
  static constexpr int kMaxCameras = 255;

  GroundLut() = default;

  const FloorGrid& grid() const { return grid_; }
  double plane_height_m() const { return plane_height_m_; }
  int num_cameras() const { return static_cast<int>(image_sizes_.size()); }
  ImageSize image_size(int camera) const { return image_sizes_[camera]; }
  uint32_t sentinel() const { return static_cast<uint32_t>(grid_.num_cells()); }
  uint32_t pixel_offset(int camera) const { return pixel_offsets_[camera]; }
  uint32_t total_pixels() const { return pixel_offsets_.back(); }

  std::span<const uint32_t> l1(int camera) const { return l1_[camera]; }
  std::span<const uint32_t> extra_pixels(int camera) const { return extra_pixels_[camera]; }
  std::span<const uint32_t> extra_cells(int camera) const { return extra_cells_[camera]; }
  std::span<const uint32_t> l2_offsets() const { return l2_offsets_; }
  std::span<const uint32_t> l2_pixels() const { return l2_pixels_; }
  std::span<const uint32_t> l2_pixels_of(int64_t cell) const {
    return std::span<const uint32_t>(l2_pixels_).subspan(l2_offsets_[cell], l2_offsets_[cell + 1] - l2_offsets_[cell]);
  }
  std::span<const uint8_t> view_count() const { return view_count_; }
  const std::vector<CameraCoverage>& coverage() const { return coverage_; }

  // Bytes of the tables in memory.
  int64_t MemoryBytes() const;
  // Checks every structural invariant (used on tables read from files).
  Status CheckConsistency() const;

  friend bool operator==(const GroundLut&, const GroundLut&) = default;

 private:
  friend Result<GroundLut> BuildGroundLut(const std::vector<LutCameraInput>&, const FloorGrid&,
                                          const LutOptions&, Context&);
  friend class LutFileCodec;

  // L2 (CSR) from L1 and the coverage-fix pairs, which must pass CheckCameraTables.
  void DeriveL2();
  // The per-camera half of CheckConsistency (sizes, offsets, L1 and extra entries in range).
  Status CheckCameraTables() const;

  FloorGrid grid_;
  double plane_height_m_ = 0;
  std::vector<ImageSize> image_sizes_;
  std::vector<uint32_t> pixel_offsets_;  // num_cameras + 1
  std::vector<std::vector<uint32_t>> l1_;
  std::vector<std::vector<uint32_t>> extra_pixels_;
  std::vector<std::vector<uint32_t>> extra_cells_;
  std::vector<uint32_t> l2_offsets_;
  std::vector<uint32_t> l2_pixels_;
  std::vector<uint8_t> view_count_;
  std::vector<CameraCoverage> coverage_;
};

Result<GroundLut> BuildGroundLut(const std::vector<LutCameraInput>& cameras, const FloorGrid& grid,
                                 const LutOptions& options, Context& ctx);

// The cache key of the tables these inputs produce: format version, every camera's geometry,
// image size and mask, the grid and the options.
uint64_t GroundLutKey(const std::vector<LutCameraInput>& cameras, const FloorGrid& grid,
                      const LutOptions& options);

}  // namespace occmap
