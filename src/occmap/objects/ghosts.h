// Ghost detections: with few cameras, the intersection of their views leaves "ghosts": floor
// cells that every camera seeing them sees only through another object standing in front
// (the map is right about what it cannot see past, but nothing stands there). A detection is
// a ghost when, for every camera that sees its floor point, the line of sight passes through
// another detection nearer to that camera, low enough to be blocked by an object of
// occluder_height_m standing there. Real objects hidden that way from every camera are
// dropped too: nothing in the images tells them from ghosts.
//
//   std::vector<bool> ghost = FindGhosts(points_m, viewers, {.occluder_radius_m = 0.3});
#pragma once

#include <Eigen/Core>
#include <functional>
#include <vector>

namespace occmap {

struct GhostOptions {
  double occluder_radius_m = 0.3;   // how far from a detection's centre a line of sight is blocked
  double occluder_height_m = 1.8;   // how tall the blocking objects are
};

struct Viewer {
  Eigen::Vector3d center_m;                                // the camera's optical centre
  std::function<bool(const Eigen::Vector2d&)> sees_point;  // whether it sees this floor point
};

// points: the detections' floor positions. Returns ghost[i] for each.
// samples (optional, one list per point, empty lists allowed): floor points of each detection's
// own cells. The test is then made at each sample, and a detection is a ghost when it holds at
// most of them: a ghost is a streak along the views that hide it, whose centre may lie beside
// its cells, where a camera that sees none of them sees the floor lit.
std::vector<bool> FindGhosts(const std::vector<Eigen::Vector2d>& points_m, const std::vector<Viewer>& viewers,
                             const GhostOptions& options,
                             const std::vector<std::vector<Eigen::Vector2d>>& samples_m = {});

}  // namespace occmap
