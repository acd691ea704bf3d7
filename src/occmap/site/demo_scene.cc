#include "occmap/site/demo_scene.h"

#include <Eigen/Geometry>

#include "occmap/geometry/pinhole_camera.h"
#include "occmap/geometry/rotation.h"

namespace occmap {
namespace {

PinholeCamera WallCamera(const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m) {
  PinholeParameters p;
  p.image_size = {640, 480};
  p.fx_px = p.fy_px = 350;  // an 85 degree horizontal field of view (a 3.5 mm lens on a 1/2" sensor)
  p.cx_px = 319.5;
  p.cy_px = 239.5;
  p.distortion = {-0.16, 0.035, 0, 0, 0};  // barrel distortion, as a real wide lens
  p.cam_from_world_rotation = LookAtRotation(position_m, target_m);
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * position_m;
  return PinholeCamera::Create(p).value();
}

}  // namespace

Site MakeDemoLabSite() {
  Site site;
  site.name = "demo-lab";
  site.grid = FloorGrid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 450, .cells_y = 325, .cell_size_m = 0.02};
  const Eigen::Vector3d positions[4] = {{0.1, 0.1, 2.7}, {8.9, 0.1, 2.7}, {8.9, 6.4, 2.7}, {0.1, 6.4, 2.7}};
  const char* ids[4] = {"cam1", "cam2", "cam3", "cam4"};
  for (int i = 0; i < 4; ++i) {
    // Each camera looks across the room at a point beyond the centre, down at about 25 degrees.
    const Eigen::Vector3d target(9.0 - positions[i].x(), 6.5 - positions[i].y(), 0.0);
    const Eigen::Vector3d aim = positions[i] + 0.5 * (target - positions[i]);
    SiteCamera cam;
    cam.id = ids[i];
    cam.camera = std::make_unique<PinholeCamera>(WallCamera(positions[i], aim));
    cam.calibrated_size = cam.camera->image_size();
    cam.calibration_format = "built-in";
    site.cameras.push_back(std::move(cam));
  }
  return site;
}

}  // namespace occmap
