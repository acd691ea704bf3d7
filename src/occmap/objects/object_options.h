// ObjectOptions: everything that turns an occupancy map into detections (ObjectDetector in
// object_detector.h): grouping, the small-group filter, splitting at necks, the elevated check
// and the ghost rule. Lengths in metres, areas in square metres.
//
// In the site file these settings keep their two historical homes: the `blobs:` section
// (grouping, filters, elevated check, ghosts) and the person-size and split keys of the
// `tracking:` section (person_diameter_m, min_detection_area_m2, max_people_per_blob,
// split_area_margin, split_min_neck_m, split_min_peak_radius_m; docs/formats.md). Both are
// read here; ParseTrackerOptions (track/) skips the split keys (kObjectKeysInTracking) and
// reads person_diameter_m for the tracker's own use.
//
// Validate() checks every field and names it as the site file does:
//   blobs.group_radius_m: expected 0..5 m, found 7
//
//   ObjectOptions options;
//   if (auto f = root.Find("blobs")) OCCMAP_RETURN_IF_ERROR(ParseObjectOptions(*f, options));
//   if (auto f = root.Find("tracking")) OCCMAP_RETURN_IF_ERROR(ParseObjectKeysOfTracking(*f, options));
#pragma once

#include <array>
#include <string_view>
#include <vector>

#include "occmap/util/status.h"
#include "occmap/util/yaml_util.h"

namespace occmap {

struct ObjectOptions {
  // --- The `blobs:` section.
  // 1. Occupied fragments closer than 2 * group_radius_m form one group (grouping.h: a
  //    person's two feet, a chair's four legs, when the grid is fine enough to see them apart;
  //    0 = the paper's connected components).
  double group_radius_m = 0.0;
  // 2. Groups whose footprint (their occupied cells before the growth) is smaller than this
  //    are dropped.
  double min_area_m2 = 0.0;
  // 3. A group too large for one person is split at the necks of its shape (split.h).
  bool split = true;
  // 4. A detection that every camera seeing it sees only through another, nearer detection is
  //    dropped (ghosts.h).
  bool remove_ghosts = true;
  double occluder_height_m = 1.8;  // objects that hide the floor behind them (ghost test)
  // With remove_ghosts: a detection that n cameras see must be seen by min(n, min_clear_views)
  // of them clear of every other detection (no line of sight within person_radius_m of one).
  // 2: one camera alone does not place it while the others look through someone (a cast
  // shadow's tip beside a person or by a wall); 1: one clear view is enough.
  int min_clear_views = 2;
  // The elevated check (empty = off): a detection is kept only when, on one of the planes
  // support_heights_m above the floor, at least min_support of its footprint cells are also
  // occupied within support_slack_m (tested pixel by pixel through each camera's changes).
  std::vector<double> support_heights_m;
  double min_support = 0.2;
  double support_slack_m = 0.05;
  // With the elevated check: a footprint under min_area_m2 (but at least a fifth of it) is kept
  // when one of the planes shows min_area_m2 occupied within standing_radius_m of it (0 = off).
  // Legs leave gaps and dark shoes in front of their own cast shadow can leave little of a person
  // on the floor, while the body above stands whole; a speck of the floor has nothing above it.
  double standing_radius_m = 0.2;

  // --- Person size and splitting: keys of the `tracking:` section.
  // Expected diameter of one person's footprint in the map (a disc): the unit for splitting,
  // and the radius around a detection that blocks a line of sight (ghosts).
  double person_diameter_m = 0.5;
  // Groups, and parts of split groups, smaller than this are ignored as noise (with split).
  double min_detection_area_m2 = 0.03;
  // The most detections one group may give.
  int max_people_per_blob = 8;
  // A group may hold n people only if its area is at least (n - 1 + split_area_margin)
  // person areas (person area = pi person_diameter_m^2 / 4).
  double split_area_margin = 0.2;
  // Distance-transform peaks: a secondary peak counts as another person only if it stands at
  // least this much above the saddle joining it to a higher peak (the "neck" between two
  // people; at least one cell size is used). 3 cm: a chair pushed a step ahead of its pusher
  // leaves a neck of 3-5 cm once their fragments are grouped; one person's feet are kept whole
  // by the area cap (split_area_margin), not by the neck ...
  double split_min_neck_m = 0.03;
  // ... and is at least this far from the group's edge.
  double split_min_peak_radius_m = 0.08;

  double person_radius_m() const { return 0.5 * person_diameter_m; }
  double person_area_m2() const;
  // Every field checked; the message names it as the site file does (blobs.x or tracking.x).
  Status Validate() const;
};

// The keys of the `tracking:` section that only ObjectOptions reads (person_diameter_m, read
// by both, is not among them).
inline constexpr std::array<std::string_view, 5> kObjectKeysInTracking = {
    "min_detection_area_m2", "max_people_per_blob", "split_area_margin", "split_min_neck_m", "split_min_peak_radius_m"};

// Reads a `blobs:` section over `options` (absent keys keep their values; a null field changes
// nothing). Errors are located: file, line and field path. `options` is left alone on error.
Status ParseObjectOptions(const YamlField& blobs, ObjectOptions& options);
// Reads person_diameter_m and kObjectKeysInTracking from a `tracking:` section over `options`,
// ignoring its other keys (ParseTrackerOptions checks those).
Status ParseObjectKeysOfTracking(const YamlField& tracking, ObjectOptions& options);

}  // namespace occmap
