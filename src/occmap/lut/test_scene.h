// Small synthetic scenes for lut tests: a 4 x 3 m floor watched by pinhole cameras.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "occmap/geometry/pinhole_camera.h"
#include "occmap/geometry/rotation.h"
#include "occmap/lut/floor_grid.h"

namespace occmap::testing {

// A camera at `position_m` looking at `target_m`, image width x height, focal length f_px.
inline PinholeCamera LookAtCamera(const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m, int width,
                                  int height, double f_px, std::array<double, 5> distortion = {0, 0, 0, 0, 0}) {
  PinholeParameters p;
  p.image_size = {width, height};
  p.fx_px = p.fy_px = f_px;
  p.cx_px = (width - 1) / 2.0;
  p.cy_px = (height - 1) / 2.0;
  p.distortion = distortion;
  p.cam_from_world_rotation = LookAtRotation(position_m, target_m);
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * position_m;
  return PinholeCamera::Create(p).value();
}

// Four cameras at 2.7 m in the corners of a 4 x 3 m room, each looking at the far side; the
// grid covers the room in 5 cm cells.
struct SmallRoom {
  FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 80, .cells_y = 60, .cell_size_m = 0.05};
  std::vector<PinholeCamera> cameras;
  SmallRoom(int width = 160, int height = 120) {
    const Eigen::Vector3d center(2.0, 1.5, 0.0);
    for (const auto& corner : {Eigen::Vector3d(-0.3, -0.3, 2.7), Eigen::Vector3d(4.3, -0.3, 2.7),
                               Eigen::Vector3d(4.3, 3.3, 2.7), Eigen::Vector3d(-0.3, 3.3, 2.7)}) {
      cameras.push_back(LookAtCamera(corner, center, width, height, 0.8 * width));
    }
  }
};

}  // namespace occmap::testing
