#include "occmap/objects/ghosts.h"

#include <algorithm>

namespace occmap {

namespace {

// Whether detection d is not placed at its floor point p: every viewer that sees p looks at it
// past a detection that can occlude (within occluder_radius_m, nearer to the camera and low
// enough), or fewer than min(seeing, min_clear_views) viewers see it past every such detection
// by more than clear_radius_m; false when no viewer sees it.
bool HiddenAt(const Eigen::Vector2d& p, size_t d, const std::vector<Eigen::Vector2d>& points,
              const std::vector<Viewer>& viewers, const GhostOptions& options, const std::vector<bool>& can_occlude) {
  int seeing = 0, clear = 0, clear_of_bodies = 0;
  const int needed = options.min_clear_views > 1 ? options.min_clear_views : 0;
  for (const Viewer& v : viewers) {
    // Decided: a clear view and the clear views asked (min(seeing, n) <= n), whatever the other
    // viewers see. At 64 cameras, asking every view took a quarter of a fuse's time.
    if (clear > 0 && clear_of_bodies >= needed) return false;
    if (!v.sees_point(p)) continue;
    ++seeing;
    const Eigen::Vector2d c = v.center_m.head<2>();
    const Eigen::Vector2d to_p = p - c;
    const double length = to_p.norm();
    if (length <= 1e-9) {
      ++clear;
      ++clear_of_bodies;
      continue;
    }
    bool is_blocked = false, passes_a_body = false;
    for (size_t e = 0; e < points.size(); ++e) {
      if (e == d || !can_occlude[e]) continue;
      // The closest point of the line of sight (on the floor plan) to the other detection.
      const double t = std::clamp((points[e] - c).dot(to_p) / (length * length), 0.0, 1.0);
      const Eigen::Vector2d closest = c + t * to_p;
      const double miss_m = (points[e] - closest).norm();
      if (t >= 1.0 || miss_m > std::max(options.occluder_radius_m, options.clear_radius_m)) continue;
      // The sight line's height there falls linearly from the camera to the floor point.
      const double height = v.center_m.z() * (1.0 - t);
      if (height > options.occluder_height_m) continue;
      is_blocked |= miss_m <= options.occluder_radius_m;
      passes_a_body |= miss_m <= options.clear_radius_m;
      if (is_blocked && passes_a_body) break;  // nothing further changes this view
    }
    clear += !is_blocked;
    clear_of_bodies += !passes_a_body;
  }
  if (seeing == 0) return false;
  if (clear == 0) return true;
  return options.min_clear_views > 1 && clear_of_bodies < std::min(seeing, options.min_clear_views);
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

// Only detections that are certainly real hide others: those that pass the test when every
// other detection may block (at least one view that none blocks, and the clear views asked).
// A ghost is then a detection whose views are blocked by those. Two detections that only hide
// each other both stay (neither is explained away).
std::vector<bool> FindGhosts(const std::vector<Eigen::Vector2d>& points, const std::vector<Viewer>& viewers,
                             const GhostOptions& options, const std::vector<std::vector<Eigen::Vector2d>>& samples) {
  const std::vector<bool> hidden_by_any =
      GhostPass(points, viewers, options, std::vector<bool>(points.size(), true), samples);
  std::vector<bool> certain(points.size());
  for (size_t i = 0; i < points.size(); ++i) certain[i] = !hidden_by_any[i];
  return GhostPass(points, viewers, options, certain, samples);
}
}  // namespace occmap
