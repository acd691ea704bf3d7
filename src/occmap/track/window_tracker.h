// WindowTracker: the paper's tracker (section 3), kept as written as a baseline: "the
// centroid of occupied space in a window surrounding the previous location of the object,
// the window size set from the maximum expected velocity".
//
// Exactly what it does per frame (Update at time t, dt = t - the previous frame's time, 0 on
// the first frame):
//  1. Each object's window is the square centred at its previous position with half-size
//     max_speed_mps * dt + window_object_radius_m. Its new position is the centroid (mean of
//     the FloorGrid::CellCenter) of the occupied cells whose centres lie in the window (on
//     the grid); its velocity is the displacement over dt. Objects are updated
//     independently from the same map: windows may overlap and share cells.
//  2. An object whose window holds no occupied cell keeps its position (velocity 0, flagged
//     coasting); once more than window_lost_timeout_s has passed since its window last held
//     one, it is lost (removed; its id is never reused).
//  3. Each blob of at least window_min_new_area_m2 whose centroid lies in no window searched
//     this frame (of the objects kept) starts a new object at that centroid, with the next id
//     (from 1). On the first frame, every such blob does.
// Reported class: "object". It has no data association, so its known weakness is
// crossings: when two objects' windows hold the same cells (two people passing within a
// window's size), both centroids are pulled to the same mass and, once they coincide, both
// objects follow the same person for good (one identity is lost, the other duplicated); a
// person entering an existing object's window is merged into it rather than starting an
// object (WindowTracker tests show both).
//
//   OCCMAP_ASSIGN_OR_RETURN(WindowTracker tracker, WindowTracker::Create(options));
//   for (each frame)  OCCMAP_ASSIGN_OR_RETURN(std::vector<Track> objects,
//                                             tracker.Update(FindBlobs(map), map, time_s));
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/track/track.h"
#include "occmap/track/tracker_options.h"
#include "occmap/util/status.h"

namespace occmap {

class WindowTracker {
 public:
  static Result<WindowTracker> Create(const TrackerOptions& options);

  // time_s must increase from frame to frame (an error otherwise, and nothing changes).
  // Returns the objects in increasing id.
  Result<std::vector<Track>> Update(const std::vector<Blob>& blobs, const OccupancyMap& map, double time_s);

  // The centroid of the occupied cells whose centres lie in the square of half-size
  // half_size_m around centre_m, and their number (0: no centroid).
  static int64_t WindowCentroid(const OccupancyMap& map, const Eigen::Vector2d& centre_m, double half_size_m,
                                Eigen::Vector2d& centroid_m);

 private:
  explicit WindowTracker(const TrackerOptions& options) : options_(options) {}

  struct Object {
    int64_t id = 0;
    Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
    Eigen::Vector2d velocity_mps = Eigen::Vector2d::Zero();
    double last_seen_s = 0;
    int64_t hits = 0;
    double area_m2 = 0;
    bool seen = false;  // this frame
  };

  TrackerOptions options_;
  std::vector<Object> objects_;  // increasing id
  int64_t next_id_ = 1;
  FrameClock clock_;
};

}  // namespace occmap
