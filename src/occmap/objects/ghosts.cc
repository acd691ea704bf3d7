#include "occmap/objects/ghosts.h"

#include <algorithm>

namespace occmap {

namespace {

// Whether every viewer that sees floor point p (of detection d) looks at it past a detection
// that can occlude, nearer to the camera and low enough; false when no viewer sees it.
bool HiddenAt(const Eigen::Vector2d& p, size_t d, const std::vector<Eigen::Vector2d>& points,
              const std::vector<Viewer>& viewers, const GhostOptions& options, const std::vector<bool>& can_occlude) {
  int seeing = 0;
  for (const Viewer& v : viewers) {
    if (!v.sees_point(p)) continue;
    ++seeing;
    const Eigen::Vector2d c = v.center_m.head<2>();
    const Eigen::Vector2d to_p = p - c;
    const double length = to_p.norm();
    if (length <= 1e-9) continue;
    bool is_blocked = false;
    for (size_t e = 0; e < points.size() && !is_blocked; ++e) {
      if (e == d || !can_occlude[e]) continue;
      // The closest point of the line of sight (on the floor plan) to the other detection.
      const double t = std::clamp((points[e] - c).dot(to_p) / (length * length), 0.0, 1.0);
      const Eigen::Vector2d closest = c + t * to_p;
      if ((points[e] - closest).norm() > options.occluder_radius_m || t >= 1.0) continue;
      // The sight line's height there falls linearly from the camera to the floor point.
      const double height = v.center_m.z() * (1.0 - t);
      is_blocked = height <= options.occluder_height_m;
    }
    if (!is_blocked) return false;
  }
  return seeing > 0;
}

// One pass: ghosts among `points` when only the detections with can_occlude[e] block views.
std::vector<bool> GhostPass(const std::vector<Eigen::Vector2d>& points, const std::vector<Viewer>& viewers,
                            const GhostOptions& options, const std::vector<bool>& can_occlude,
                            const std::vector<std::vector<Eigen::Vector2d>>& samples) {
  std::vector<bool> ghost(points.size(), false);
  for (size_t d = 0; d < points.size(); ++d) {
    if (d >= samples.size() || samples[d].empty()) {
      ghost[d] = HiddenAt(points[d], d, points, viewers, options, can_occlude);
      continue;
    }
    size_t hidden = 0;
    for (const Eigen::Vector2d& p : samples[d]) hidden += HiddenAt(p, d, points, viewers, options, can_occlude);
    ghost[d] = 2 * hidden > samples[d].size();
  }
  return ghost;
}

}  // namespace

// Only detections that are certainly real hide others: those with at least one view that no
// other detection blocks. A ghost is then a detection whose every view is blocked by one of
// those. Two detections that only hide each other both stay (neither is explained away).
std::vector<bool> FindGhosts(const std::vector<Eigen::Vector2d>& points, const std::vector<Viewer>& viewers,
                             const GhostOptions& options, const std::vector<std::vector<Eigen::Vector2d>>& samples) {
  const std::vector<bool> hidden_by_any =
      GhostPass(points, viewers, options, std::vector<bool>(points.size(), true), samples);
  std::vector<bool> certain(points.size());
  for (size_t i = 0; i < points.size(); ++i) certain[i] = !hidden_by_any[i];
  return GhostPass(points, viewers, options, certain, samples);
}
}  // namespace occmap
