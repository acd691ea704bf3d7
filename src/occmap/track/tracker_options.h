// TrackerOptions: the settings of the trackers, the zones and the track outputs: the site
// file's `tracking:` section, but for its person-size and split keys, which are the object
// detector's (objects/object_options.h: kObjectKeysInTracking). Lengths in metres, times in seconds, areas in square metres;
// every default suits people walking on a floor mapped with cells of 2-10 cm.
//
// Validate() checks every field (ranges, confirm_hits <= confirm_frames, class areas in
// increasing order, zone polygons with >= 3 vertices and a non-zero area, unique names; lines
// of non-zero length with unique names).
// ParseTrackerOptions reads the YAML section over the defaults (absent keys keep them); an
// unknown key, a wrong type or a value out of range is an error naming file, line and field:
//   site.yaml:31: tracking.max_speed_mps: expected a number > 0, found -1
//
//   TrackerOptions options;
//   if (auto f = root.Find("tracking")) OCCMAP_RETURN_IF_ERROR(ParseTrackerOptions(*f, options));
//   OCCMAP_ASSIGN_OR_RETURN(MultiTargetTracker tracker, MultiTargetTracker::Create(options));
//
// The section, with every key and its default (docs for each are on the fields below):
//   tracking:
//     algorithm: multi_target          # or: window (the paper's tracker, a baseline)
//     max_speed_mps: 2.5
//     person_diameter_m: 0.5
//     acceleration_psd_m2ps3: 1.0
//     measurement_sigma_m: 0.05
//     spread_noise_weight: 1.0
//     guided_split_sigma_m: 0.15
//     initial_speed_sigma_mps: 1.0
//     gate_chi2: 13.8
//     confirm_hits: 3
//     confirm_frames: 5
//     max_coast_s: 1.0
//     birth_min_separation_m: 0.4
//     classes: []                      # e.g. [{name: robot, max_area_m2: 0.14},
//                                      #       {name: person, max_area_m2: 0.45}, {name: cart}]
//     class_hysteresis: 0.15
//     class_area_smoothing: 0.3
//     window_object_radius_m: 0.25
//     window_lost_timeout_s: 1.0
//     window_min_new_area_m2: 0.05
//     zones: []                        # e.g. [{name: door, polygon: [[0,0],[1,0],[1,1]], dwell_s: 5}]
//     zone_count_every_frame: false
//     lines: []                        # e.g. [{name: door, from: [0, 0], to: [0, 2]}]
//     trail_length: 50
#pragma once

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/util/status.h"
#include "occmap/util/yaml_util.h"

namespace occmap {

enum class TrackerAlgorithm {
  kMultiTarget,  // MultiTargetTracker: split blobs, Kalman filters, gated Hungarian assignment
  kWindow,       // WindowTracker: the paper's centroid-in-a-window tracker, kept as a baseline
};
std::string_view ToString(TrackerAlgorithm algorithm);  // "multi_target", "window"

// A class of objects told apart by the area of their footprint in the map.
struct ObjectClassOptions {
  std::string name;
  // Footprints whose smoothed area is at most this are of this class (and above the previous
  // class's max_area_m2). Classes are listed in increasing order; only the last may be
  // unbounded (infinity, the default; `max_area_m2` left out in YAML).
  double max_area_m2 = std::numeric_limits<double>::infinity();
};

// A named region of the floor whose visitors are counted (ZoneMonitor).
struct ZoneOptions {
  std::string name;
  // Vertices in world metres, either orientation, >= 3, non-zero area; a point is inside by
  // the even-odd rule (PointInPolygon in zones.h).
  std::vector<Eigen::Vector2d> polygon_m;
  // A "dwell" event once per visit when a track has been inside this long; none: no events.
  std::optional<double> dwell_s;
};

// A counting line on the floor (LineCounter in count_lines.h): tracks crossing the segment from
// `from_m` to `to_m` are counted in each direction. "in" is a crossing from the right of the
// segment (looking from `from_m` towards `to_m`) to its left, "out" the other way.
struct LineOptions {
  std::string name;
  Eigen::Vector2d from_m = Eigen::Vector2d::Zero();  // world metres, finite, >= 1 mm apart
  Eigen::Vector2d to_m = Eigen::Vector2d::Zero();
  // A track is on a side only when farther than this from the line (the band between is
  // neither side): a position jittering on the line crosses nothing. Finite, 0..2 m.
  double hysteresis_m = 0.2;
  // A track counts at most once in each direction (people counters' rule: one who wanders
  // back and forth over the line is one visitor).
  bool once_per_track = true;
};

struct TrackerOptions {
  TrackerAlgorithm algorithm = TrackerAlgorithm::kMultiTarget;

  // --- What is tracked.
  // The fastest an object is expected to move: the paper's window size, and the distance
  // gate of the multi-target tracker (an object cannot be farther than max_speed_mps times
  // the time since it was last seen, plus a person's radius, from where it was predicted).
  double max_speed_mps = 2.5;
  // Expected diameter of one person's footprint in the detections (a disc): the margin of the
  // distance gate and the footprint spread counted as no noise. (The site file's
  // person_diameter_m sets it and ObjectOptions::person_diameter_m, the splitter's, alike.)
  double person_diameter_m = 0.5;

  // --- Constant-velocity Kalman filter (state x, y, vx, vy in m and m/s).
  // Spectral density of the white-noise acceleration (m^2/s^3): the process noise over dt is
  // q [dt^3/3, dt^2/2; dt^2/2, dt] per axis.
  double acceleration_psd_m2ps3 = 1.0;
  // Noise of a detection's position; the quantisation variance cell_size^2 / 12 is added.
  double measurement_sigma_m = 0.05;
  // The part of a detection's cell spread (covariance) beyond a single person's disc,
  // times this weight, is added to its measurement covariance (elongated or ragged blobs are
  // less precise).
  double spread_noise_weight = 1.0;
  // Extra noise of a detection cut from a blob along the tracks' predictions (no shape
  // evidence for the cut).
  double guided_split_sigma_m = 0.15;
  // Velocity uncertainty of a new track.
  double initial_speed_sigma_mps = 1.0;
  // Gate on the squared Mahalanobis distance of a detection from a track's prediction
  // (chi-square with 2 degrees of freedom: 13.8 keeps 99.9% of true detections).
  double gate_chi2 = 13.8;

  // --- Track life.
  // A new track is confirmed (and given its id) once it has had confirm_hits detections
  // within its first confirm_frames frames; a tentative track that can no longer reach that
  // is dropped.
  int confirm_hits = 3;
  int confirm_frames = 5;
  // A confirmed track without detections coasts on its prediction and ends once this long
  // has passed since its last detection (or at once when the prediction leaves the grid).
  double max_coast_s = 1.0;
  // A coasting track is written out (tracks.jsonl, the MOT file, the mosaic) only this long
  // after its last detection (IsReported in track.h); it lives on, resumes its id when its
  // object is found again within max_coast_s, and counts in zones meanwhile. Without this, a
  // track whose object was a ghost or was taken by another track would be reported where
  // nothing is for max_coast_s (SORT-style trackers report matched tracks only: 0).
  double report_coasting_s = 0.0;
  // No track is born from a detection this close to a confirmed track.
  double birth_min_separation_m = 0.4;

  // --- Classes by footprint area (none: every track is a "person").
  std::vector<ObjectClassOptions> classes;
  // A track changes class only when its smoothed area leaves its class's range by this
  // fraction of the bound it crosses.
  double class_hysteresis = 0.15;
  // Weight of a new detection in the track's smoothed area (exponential smoothing).
  double class_area_smoothing = 0.3;

  // --- The paper's window tracker (WindowTracker).
  // The window's half-size is max_speed_mps * dt + window_object_radius_m.
  double window_object_radius_m = 0.25;
  // An object whose window has held no occupied cell for longer than this is lost.
  double window_lost_timeout_s = 1.0;
  // Blobs smaller than this never start an object.
  double window_min_new_area_m2 = 0.05;

  // --- Zones (ZoneMonitor).
  std::vector<ZoneOptions> zones;
  // true: a "count" event for every zone every frame; false: only when its count changes.
  bool zone_count_every_frame = false;

  // --- Counting lines (LineCounter): crossings in each direction, names unique.
  std::vector<LineOptions> lines;

  // --- Outputs.
  // Positions kept per track for drawing its trail (TrailHistory).
  int trail_length = 50;

  double person_radius_m() const { return 0.5 * person_diameter_m; }
  double person_area_m2() const;
  Status Validate() const;
};

// Reads a `tracking:` section over `options` (keys left out keep their values). A null
// field (an empty section) changes nothing. Errors are located: file, line and field path.
// other_keys: keys of the section that another reader handles (the site passes the object
// detector's kObjectKeysInTracking); they are accepted and ignored here.
Status ParseTrackerOptions(const YamlField& field, TrackerOptions& options,
                           std::span<const std::string_view> other_keys = {});

}  // namespace occmap
