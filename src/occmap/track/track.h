// Track: one tracked object as both trackers report it per frame, in world metres on the
// floor plane (the FloorGrid's frame) and metres per second.
//
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<Track> tracks, tracker.Update(blobs, map, time_s));
//   for (const Track& t : tracks) draw(t.id, t.x_m, t.y_m);
//   // ids are > 0, unique over a tracker's life, never reused
#pragma once

#include <cstdint>
#include <string>

#include "occmap/util/status.h"

namespace occmap {

struct Track {
  int64_t id = 0;           // > 0; given once (at confirmation) and never reused
  double x_m = 0, y_m = 0;  // position: the filtered estimate, or the prediction when coasting
  double vx_mps = 0, vy_mps = 0;
  std::string object_class;  // a TrackerOptions::classes name; "person" without classes,
                             // "object" from the WindowTracker
  bool coasting = false;     // no detection (no occupied cell for the window tracker) this frame
  double time_since_update_s = 0;  // since the last frame with a detection
  int64_t hits = 0;                // frames with a detection
  double area_m2 = 0;              // smoothed footprint area (the window tracker: last window's)
};

// Whether a track is written out (TrackerOptions::report_coasting_s): it had a detection within
// report_coasting_s (1 us of slack for rounded frame times).
inline bool IsReported(const Track& track, double report_coasting_s) {
  return track.time_since_update_s <= report_coasting_s + 1e-6;
}

// The time step between a tracker's frames: times must be finite and strictly increasing.
class FrameClock {
 public:
  // The seconds since the previous frame (0 for the first), or an error naming both times.
  Result<double> Advance(double time_s);

 private:
  bool has_time_ = false;
  double last_time_s_ = 0;
};

}  // namespace occmap
