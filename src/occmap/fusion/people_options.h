// The site's `people:` section: how upright people are found, when the site has any.
//
// detector:
//   floor    the paper's floor AND and its blobs (the default without the section: robots,
//            carts and the lab's chairs are found by what touches the floor);
//   column   column fusion (column_fusion.h): blobs of the candidate positions whose column
//            every camera sees changed;
//   explain  the column map's positions as candidates, and the set of people that best explains
//            every camera's changes (view_explainer.h): the default with the section.
// The floor AND still runs (occupancy.mp4 and the footprints' outline come from it).
//
//   people:
//     detector: explain
//     height_m: 1.7          # the column and the person model: floor to this height
//     step_m: 0.1            # candidate spacing
//     column: {band_m: [0.8, 1.5], radius_m: 0.1, min_changed: 0.5, max_free_views: 1,
//              min_changed_views: 2, min_views: 2}
//     explain: {radius_m: 0.15, unchanged_weight: 0.9, min_gain: 0.7, min_separation_m: 0.35,
//               moves: 2, move_radius_m: 0.5, ground_band: 0.2, ground_weight: 2}
//     occluders: {learn: false, max_changed: 0.1, min_others: 2, episode_frames: 20,
//                 min_episodes: 6, max_contrary: 0.2}   # learned static occluders
#pragma once

#include "occmap/fusion/column_fusion.h"
#include "occmap/fusion/occluder_learning.h"
#include "occmap/fusion/view_explainer.h"
#include "occmap/lut/column_lut.h"
#include "occmap/util/status.h"
#include "occmap/util/yaml_util.h"

namespace occmap {

enum class PeopleDetector { kFloor, kColumn, kExplain };
const char* ToString(PeopleDetector d);

struct PeopleOptions {
  bool enabled = false;  // the section is there
  PeopleDetector detector = PeopleDetector::kExplain;
  ColumnLutOptions columns;
  // The band tested: the torso (legs leave gaps, heads are small), fixed by measurement on the
  // rendered WILDTRACK crowd (docs/perf-log.md).
  ColumnFusionOptions column{.band_low_m = 0.8, .band_high_m = 1.5};
  ExplainOptions explain;
  OccluderLearningOptions occluders;
  Status Validate(int num_cameras) const;
};

// Reads the section (keys as above, each optional); errors name the field's line.
Status ParsePeopleOptions(const YamlField& section, int num_cameras, PeopleOptions& options);

}  // namespace occmap
