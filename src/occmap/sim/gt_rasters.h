// Ground-truth rasters on the site's FloorGrid, computed from the scene's geometry (not from
// images).
//
// Footprint raster: per cell 1 where the cell centre lies inside a footprint polygon of a
// present object (even-odd rule), else 0.
//
// Ideal plane hull: what equation 5 yields with perfect change detection. A camera sees a cell
// when the cell centre (z = 0) projects in front of it onto a pixel of its image (rounded to the
// nearest pixel centre) whose floor mask is non-zero. A cell seen by no camera is kUnseen; a
// seen cell is kOccupied when, for every camera that sees it, the segment from the optical
// centre to the cell centre passes through a moving object, else kFree. The result is an
// OccupancyMap (fusion/occupancy_map.h), comparable cell by cell with the pipeline's map.
// The paper's theorem: a footprint cell on an object's boundary seen by a camera is occupied.
//
// Pictures: one pixel per cell, +x right, +y up (image row 0 = cell row cells_y - 1), like
// occmap's occupancy pictures. Footprint: 255 footprint, 0 not. Hull: OccupancyMap's grey
// levels, 255 free, 0 occupied, 128 unseen.
//
//   sim::HullComputer hull(scene, masks, ctx);        // masks: one per camera (floor_mask())
//   OccupancyMap ideal = hull.Compute(scene.StateAt(f), ctx);
//   std::vector<uint8_t> feet = sim::FootprintRaster(scene.grid(), scene.StateAt(f));
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/sim/scene.h"
#include "occmap/util/image.h"
#include "occmap/util/thread_pool.h"

namespace occmap::sim {

// Even-odd point-in-polygon test (points on an edge may go either way).
bool PointInPolygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& p);

std::vector<uint8_t> FootprintRaster(const FloorGrid& grid, const SceneState& state);
// Plan-view picture of a 0/1 raster: 255 where non-zero.
Image<uint8_t> RasterImage(const FloorGrid& grid, const std::vector<uint8_t>& raster);

// Whether the segment from `from` to the floor point `to` passes through a moving object.
bool BlockedByObjects(const SceneState& state, const Eigen::Vector3d& from, const Eigen::Vector3d& to);

class HullComputer {
 public:
  // masks[c]: camera c's floor mask at its image size (non-zero = floor); an empty image means
  // every pixel is floor.
  HullComputer(const Scene& scene, const std::vector<Image<uint8_t>>& masks, Context& ctx);

  // 1 where camera c sees the cell (see above).
  const std::vector<uint8_t>& seen_by(size_t camera) const { return seen_[camera]; }
  OccupancyMap Compute(const SceneState& state, Context& ctx) const;

 private:
  FloorGrid grid_;
  std::vector<Eigen::Vector3d> centres_;       // per camera
  std::vector<std::vector<uint8_t>> seen_;     // per camera, per cell
};

}  // namespace occmap::sim
