// Test helpers for the trackers: runs a tracker over synthetic floors (objects/test_floor.h)
// and finds tracks in its output.
//
//   const auto tracks = testing::RunTracker(tracker, 30, 0.1, [&](int f) { return people_at(f); });
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <random>
#include <vector>

#include <type_traits>

#include "occmap/fusion/blobs.h"
#include "occmap/objects/object_detector.h"
#include "occmap/objects/test_floor.h"
#include "occmap/track/multi_target_tracker.h"
#include "occmap/track/track.h"

namespace occmap::testing {

// The frame the pipeline's ObjectDetector gives for `map` with `options` (no cameras: no
// elevated check, no ghosts).
inline ObjectFrame DetectObjects(const OccupancyMap& map, ObjectOptions options = {}) {
  options.remove_ghosts = false;
  ObjectDetector detector(options, 0.0, {});
  DetectedObjects out;
  detector.Detect(map, {}, out);
  return static_cast<ObjectFrame&&>(std::move(out));
}

// Runs a tracker (MultiTargetTracker or WindowTracker) over `frames` frames of `dt_s`: the
// people of frame f are people(f), drawn as discs of radius_m with `noise`; the multi-target
// tracker gets DetectObjects of the map, the window tracker its blobs. Returns the tracks
// of every frame; blob_counts (if given) gets the blobs of each frame at least 0.03 m^2.
template <typename Tracker, typename PeopleFn>
std::vector<std::vector<Track>> RunTracker(Tracker& tracker, int frames, double dt_s, PeopleFn&& people,
                                           const FloorNoise& noise = kClean, unsigned seed = 1,
                                           double radius_m = 0.25, std::vector<int>* blob_counts = nullptr) {
  std::mt19937 rng(seed);
  std::vector<std::vector<Track>> out;
  for (int f = 0; f < frames; ++f) {
    const OccupancyMap map = FloorWithDiscs(TestGrid(), people(f), radius_m, noise, rng);
    const std::vector<Blob> blobs = FindBlobs(map);
    if (blob_counts) {
      blob_counts->push_back(static_cast<int>(
          std::count_if(blobs.begin(), blobs.end(), [](const Blob& b) { return b.area_m2 >= 0.03; })));
    }
    auto tracks = [&] {
      if constexpr (std::is_same_v<Tracker, MultiTargetTracker>) {
        return tracker.Update(DetectObjects(map), dt_s * f);
      } else {
        return tracker.Update(blobs, map, dt_s * f);
      }
    }();
    EXPECT_TRUE(tracks.ok()) << tracks.status().ToString();
    out.push_back(tracks.ok() ? *tracks : std::vector<Track>{});
  }
  return out;
}

inline const Track* FindTrack(const std::vector<Track>& tracks, int64_t id) {
  for (const Track& t : tracks) {
    if (t.id == id) return &t;
  }
  return nullptr;
}

inline const Track* NearestTrack(const std::vector<Track>& tracks, const Eigen::Vector2d& p) {
  const Track* best = nullptr;
  for (const Track& t : tracks) {
    if (!best || (Eigen::Vector2d(t.x_m, t.y_m) - p).norm() < (Eigen::Vector2d(best->x_m, best->y_m) - p).norm()) best = &t;
  }
  return best;
}

}  // namespace occmap::testing
