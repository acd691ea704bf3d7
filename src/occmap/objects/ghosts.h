// Ghost detections: with few cameras, the intersection of their views leaves "ghosts": floor
// cells that every camera seeing them sees only through another object standing in front
// (the map is right about what it cannot see past, but nothing stands there). A detection is
// a ghost when, for every camera that sees its floor point, the line of sight passes through
// another detection nearer to that camera, low enough to be blocked by an object of
// occluder_height_m standing there. Real objects hidden that way from every camera are
// dropped too: nothing in the images tells them from ghosts.
//
// With min_clear_views = 2, a detection that two cameras or more see must also be seen by two
// of them clear of every other detection (no line of sight within clear_radius_m, a body, of
// one): otherwise a single camera places it, and the others only look through someone. That
// is the false detection a cast shadow makes beside a person or by a wall, where one camera
// takes the shadow's thin tip for a change and the others see that floor through the person.
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
  // A detection seen by n cameras needs min(n, min_clear_views) of them to see it clear: past
  // every other detection by more than clear_radius_m (1: one clear view keeps it, as above).
  int min_clear_views = 1;
  double clear_radius_m = 0.25;
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
