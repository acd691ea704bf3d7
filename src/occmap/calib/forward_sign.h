// Which way a pinhole camera looks: forward_sign = +1 (z_cam > 0 in front, every ordinary
// calibration) or -1 (MultiviewX, calibrated in a left-handed world, where the points a camera
// sees have z_cam < 0).
//
// Decided from where the floor projects: the floor points (e.g. a sample of the site's grid)
// that land inside the image under x/z, y/z vote with the sign of their z_cam; the majority
// wins. A camera that sees none of the points is an error (wrong calibration or grid).
//
//   OCCMAP_ASSIGN_OR_RETURN(int sign, ChooseForwardSign(params, floor_points_in_world));
#pragma once

#include <Eigen/Core>
#include <vector>

#include "occmap/geometry/pinhole_camera.h"
#include "occmap/util/status.h"

namespace occmap {

Result<int> ChooseForwardSign(const PinholeParameters& params,
                              const std::vector<Eigen::Vector3d>& floor_points_in_world);

}  // namespace occmap
