// MultiTargetTracker: tracks people (and other classes of objects) through the detections of
// each frame (objects/object_frame.h), keeping identities through crossings and short
// occlusions.
//
// Per frame (Update), at time t:
//  1. Every track's constant-velocity Kalman filter (kalman.h) is predicted to t.
//  2. The detections are the frame's (the detector split groups holding several people at
//     their necks); when people overlap too much for a neck, the confirmed tracks'
//     predictions on the group, moved together onto its footprint's centroid, are the group's
//     detections (guided; GuidedDetections in objects/object_frame.h: only for detections
//     that come from a group with its split). Each detection's measurement covariance is
//       R = (measurement_sigma_m^2 + cell^2 / 12) I + spread_noise_weight * max(0, spread - disc)
//           (+ guided_split_sigma_m^2 I for a guided cut)
//     where spread is the covariance of its cells and disc = (person radius)^2 / 4 I, that of
//     one person's disc (the excess is clamped to positive semi-definite).
//  3. Gated optimal assignment (Hungarian, util/hungarian.h), first of the confirmed tracks,
//     then of the tentative ones to the detections left. A pair is allowed when the squared
//     Mahalanobis distance d2 of the detection from the prediction is <= gate_chi2 and their
//     distance is <= max_speed_mps * (time since the track's last detection) + person radius;
//     its cost is d2 + ln det S (the negative log-likelihood up to a constant).
//  4. Matched tracks are updated. A detection left over starts a tentative track unless a
//     confirmed track is within birth_min_separation_m.
//  5. A tentative track is confirmed, and only then given an id (the next integer from 1,
//     never reused), once it has confirm_hits detections within its first confirm_frames
//     frames, and dropped as soon as it can no longer make it. A confirmed track without a
//     detection coasts on its prediction and ends once more than max_coast_s has passed since
//     its last detection, or as soon as its prediction leaves the grid.
//  6. With classes, each track's class follows its smoothed footprint area with hysteresis
//     (guided cuts do not count: their area is a guess), or a detection's class hint when it
//     names one of the classes.
// Update returns the confirmed tracks (coasting ones included, flagged), in increasing id.
//
// Limits: inside a merged blob without a neck, the members' relative motion is extrapolated
// from their velocities (only their common position is measured), so people who meet, stop
// together and walk back the way they came may swap identities or lose one track; a track
// whose prediction wanders onto another person's blob big enough for two can be kept alive
// by it. Two-person crossings at 10 fps with 5 cm cells keep identities in the tests at 40
// and 90 degrees and head-on (and down to about 10 degrees in trials).
//
//   OCCMAP_ASSIGN_OR_RETURN(MultiTargetTracker tracker, MultiTargetTracker::Create(options));
//   for (each frame)  OCCMAP_ASSIGN_OR_RETURN(std::vector<Track> tracks,
//                                             tracker.Update(objects, time_s));   // ObjectFrame
#pragma once

#include <cstdint>
#include <vector>

#include "occmap/objects/detection.h"
#include "occmap/objects/object_frame.h"
#include "occmap/track/kalman.h"
#include "occmap/track/track.h"
#include "occmap/track/tracker_options.h"
#include "occmap/util/status.h"

namespace occmap {

class MultiTargetTracker {
 public:
  // Fails when options.Validate() does.
  static Result<MultiTargetTracker> Create(const TrackerOptions& options);

  // One frame: its detections (with their groups, when the detector has them, for the guided
  // split); time_s must increase from frame to frame (an error otherwise, and nothing changes).
  Result<std::vector<Track>> Update(const ObjectFrame& frame, double time_s);

  // The detections of the last frame (for drawing and debugging).
  const std::vector<Detection>& detections() const { return detections_; }
  // Tracks confirmed so far (the largest id given).
  int64_t confirmed_count() const { return next_id_ - 1; }
  // Tentative tracks alive now.
  int tentative_count() const;

  const TrackerOptions& options() const { return options_; }

 private:
  explicit MultiTargetTracker(const TrackerOptions& options) : options_(options) {}

  struct TrackState {
    int64_t id = 0;  // 0 while tentative
    ConstantVelocityKalman filter;
    double last_update_s = 0;
    int64_t hits = 0;
    int64_t frames = 0;  // frames since birth, the birth frame included (counted while tentative)
    bool confirmed = false;
    bool updated = false;  // had a detection this frame
    double area_m2 = 0;    // smoothed footprint area
    int class_index = -1;  // into options_.classes; -1 without classes
  };

  Eigen::Matrix2d MeasurementCovariance(const Detection& detection, const FloorGrid& grid) const;
  // Gated Hungarian assignment of the tracks in `rows` to the detections not yet used.
  void Associate(const std::vector<size_t>& rows, const std::vector<Eigen::Matrix2d>& covariances,
                 std::vector<uint8_t>& detection_used, double time_s);
  void UpdateClass(TrackState& track, const Detection& detection) const;
  Track Report(const TrackState& track, double time_s) const;

  TrackerOptions options_;
  std::vector<TrackState> tracks_;  // in order of birth
  std::vector<Detection> detections_;
  int64_t next_id_ = 1;
  FrameClock clock_;
};

}  // namespace occmap
