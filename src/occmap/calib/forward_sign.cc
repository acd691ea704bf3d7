#include "occmap/calib/forward_sign.h"

#include <fmt/core.h>

namespace occmap {

Result<int> ChooseForwardSign(const PinholeParameters& params,
                              const std::vector<Eigen::Vector3d>& points) {
  int votes[2] = {0, 0};  // [0]: z_cam > 0, [1]: z_cam < 0
  for (int sign : {+1, -1}) {
    PinholeParameters p = params;
    p.forward_sign = sign;
    auto cam = PinholeCamera::Create(p);
    if (!cam.ok()) return cam.status();
    for (const auto& pw : points) {
      auto px = cam->Project(pw);
      if (px && cam->InImage(*px)) ++votes[sign > 0 ? 0 : 1];
    }
  }
  if (votes[0] == 0 && votes[1] == 0) {
    return InvalidInput(fmt::format(
        "the camera sees none of the {} floor sample points (calibration, unit or grid wrong?)",
        points.size()));
  }
  return votes[0] >= votes[1] ? +1 : -1;
}

}  // namespace occmap
