// ColumnLut: where an upright person standing at a floor position appears in each camera, for
// the height-aware fusions (fusion/column_fusion.h, fusion/view_explainer.h).
//
// Positions are the centres of a candidate grid: the floor grid coarsened to step_m (a whole
// number of cells), because a person is decided at about 10 cm, not at the floor map's 2.5 cm.
// For every camera and candidate the table holds the image of the vertical segment from the
// floor (plane_height_m) to height_m above it as a trapezoid over image rows:
//   rows top_row .. bottom_row (image of the top and of the foot, unclipped),
//   axis x at those rows (the projected segment, straight for a pinhole),
//   the image half-width of one metre across the line of sight at both ends,
// so the image of a cylinder of radius r there is, row by row, the span
//   [axis(y) - r * half_width(y), axis(y) + r * half_width(y)]   (linear in y between the ends).
// A camera sees a candidate when the foot projects onto the image, in front, on a monitored pixel
// of its floor mask (the floor AND's notion of seeing). Where the site names static occluders
// (boxes and cylinders in metres), a camera whose line of sight to at least half the column
// passes through one is marked `blocked`: it abstains rather than reporting "nothing there".
//
//   OCCMAP_ASSIGN_OR_RETURN(ColumnLut columns, BuildColumnLut(cams, site_grid, plane_h, opts, occluders, ctx));
//   const ColumnView& v = columns.view(camera, candidate);
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "occmap/lut/floor_grid.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/util/hash.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"
#include "occmap/util/yaml_util.h"

namespace occmap {

// A static structure that hides what stands behind it (a pillar, a kiosk, a planter).
struct Occluder {
  enum class Shape { kBox, kCylinder };
  Shape shape = Shape::kBox;
  Eigen::Vector2d centre_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d size_m = Eigen::Vector2d(0.5, 0.5);  // box: x-y size before yaw; cylinder: 2 r (x)
  double base_m = 0.0;    // height of its bottom above the floor plane
  double height_m = 1.0;  // its own height (top at base_m + height_m)
  double yaw_deg = 0;     // box: rotation about the vertical axis
  Status Validate() const;
  // Whether the segment from a to b (world, metres) passes through it.
  bool Blocks(const Eigen::Vector3d& a, const Eigen::Vector3d& b) const;
  void AppendToHash(Hasher& hasher) const;
};

// The site's `statics:` list: each {shape: box, centre_m: [x, y], size_m: [sx, sy], height_m: h,
// base_m: 0, yaw_deg: 0} or {shape: cylinder, centre_m: [x, y], diameter_m: d, height_m: h,
// base_m: 0}; errors name the entry's line and field.
Result<std::vector<Occluder>> ParseOccluders(const YamlField& list);

struct ColumnLutOptions {
  double step_m = 0.1;     // candidate spacing; rounded to a whole number of floor cells
  double height_m = 1.7;   // the column: from the floor plane to this height (a person)
  Status Validate(const FloorGrid& grid) const;
  void AppendToHash(Hasher& hasher) const;
};

struct ColumnView {
  float top_row = 0, bottom_row = 0;         // image rows of the column's top and foot
  float axis_x_top = 0, axis_x_bottom = 0;   // image column of the axis at those rows
  float half_width_top = 0, half_width_bottom = 0;  // pixels per metre of radius, at those rows
  bool seen = false;     // the foot projects onto a monitored pixel, in front
  // The foot projects below the image (within its columns) and the column's top into it: a
  // person this close to the camera shows the torso with the feet cut off.
  bool feet_cut = false;
  bool projected = false;  // foot and top project (in front), wherever they land
  bool blocked = false;  // a static occluder hides at least half of the column: the camera abstains
  bool learned = false;  // blocked by learning (fusion/occluder_learning.h), not by a given static
};

class ColumnLut {
 public:
  ColumnLut() = default;
  const FloorGrid& candidates() const { return candidates_; }
  // How many floor cells per candidate side (the candidate grid's step / the floor grid's).
  int cells_per_step() const { return cells_per_step_; }
  const ColumnLutOptions& options() const { return options_; }
  int num_cameras() const { return static_cast<int>(image_sizes_.size()); }
  ImageSize image_size(int camera) const { return image_sizes_[camera]; }
  const ColumnView& view(int camera, int64_t candidate) const {
    return views_[static_cast<size_t>(camera) * static_cast<size_t>(candidates_.num_cells()) +
                  static_cast<size_t>(candidate)];
  }
  // How many cameras see each candidate (blocked ones included).
  std::span<const uint8_t> view_count() const { return view_count_; }
  int64_t MemoryBytes() const;

  // Learned occluders (fusion/occluder_learning.h): blocks or unblocks a view no given static
  // blocks (those are left as they are). revision() counts the changes, so that what is worked
  // out from the blocks (the column fusion's plan) follows them.
  void SetLearnedBlocked(int camera, int64_t candidate, bool blocked) {
    ColumnView& v = views_[static_cast<size_t>(camera) * static_cast<size_t>(candidates_.num_cells()) +
                           static_cast<size_t>(candidate)];
    if (v.blocked && !v.learned) return;
    if (v.learned == blocked) return;
    v.blocked = v.learned = blocked;
    ++revision_;
  }
  uint64_t revision() const { return revision_; }

 private:
  friend Result<ColumnLut> BuildColumnLut(const std::vector<LutCameraInput>&, const FloorGrid&, double,
                                          const ColumnLutOptions&, std::span<const Occluder>, Context&);
  FloorGrid candidates_;
  int cells_per_step_ = 1;
  ColumnLutOptions options_;
  std::vector<ImageSize> image_sizes_;
  std::vector<ColumnView> views_;  // [camera * candidates + candidate]
  std::vector<uint8_t> view_count_;
  uint64_t revision_ = 0;
};

// The candidate grid of a floor grid: cells of step_m (rounded to whole cells, at least one)
// over the same area (a last partial row or column of floor cells is left out).
FloorGrid CandidateGrid(const FloorGrid& grid, double step_m, int* cells_per_step = nullptr);

Result<ColumnLut> BuildColumnLut(const std::vector<LutCameraInput>& cameras, const FloorGrid& grid,
                                 double plane_height_m, const ColumnLutOptions& options,
                                 std::span<const Occluder> occluders, Context& ctx);

}  // namespace occmap
