// EvalOptions: the settings of `occmap eval` and of the in-memory evaluators, and
// OccupancyGrayCodes, the grey levels of a per-cell occupancy raster.
//
// Matching rule (every metric of this module): a ground-truth object and a detection or track
// match when their floor distance is <= match_threshold_m (0.5 m, as on WILDTRACK). Validate()
// once on entry; the evaluators CHECK that their options are valid.
//
//   EvalOptions options;
//   options.match_threshold_m = 0.3;
//   OCCMAP_RETURN_IF_ERROR(options.Validate());
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/util/status.h"

namespace occmap {

// Grey level of each cell state in a raster (one pixel per cell, +x right, +y up: image row 0
// holds cell row cells_y - 1). The defaults are OccupancyMap::ToGrayImage's: white free,
// black occupied, mid grey unseen. Any other level in a raster is an error.
struct OccupancyGrayCodes {
  uint8_t free = OccupancyMap::kFreeGray;          // 255
  uint8_t occupied = OccupancyMap::kOccupiedGray;  // 0
  uint8_t unseen = OccupancyMap::kUnseenGray;      // 128
  Status Validate() const;                         // the three levels differ
};

struct EvalOptions {
  // A ground-truth object and a detection (track) match when their distance is <= this.
  double match_threshold_m = 0.5;
  // Ground-truth classes evaluated by detection and tracking metrics ("person", ...); empty:
  // every object. Objects of other classes are dropped from the ground truth (a detection on
  // them then counts as a false positive).
  std::vector<std::string> object_classes;
  // Blobs with a known area_m2 below this are not detections (blobs without area are kept).
  double min_detection_area_m2 = 0.0;
  // A ground-truth frame that detections.jsonl (tracks.jsonl) has no line for: false counts
  // all its objects as misses (the protocol), true leaves the frame out (for partial runs).
  // Lines of the run whose frame is not in the ground truth are never evaluated.
  bool skip_frames_missing_from_run = false;
  // A ground-truth trajectory is mostly tracked when matched in >= this share of its frames,
  // mostly lost when matched in < mostly_lost_ratio of them, partially tracked otherwise.
  double mostly_tracked_ratio = 0.8;
  double mostly_lost_ratio = 0.2;
  // Grey levels of the computed maps (run_dir/occupancy/*.png, written by `occmap run`) and of
  // the reference rasters written by the simulator (sim/gt_rasters.h): the footprint raster is
  // 255 where an object stands and 0 elsewhere (no unseen cells); the ideal plane hull uses
  // OccupancyMap's levels like the computed maps.
  OccupancyGrayCodes computed_codes;
  OccupancyGrayCodes footprint_codes{.free = 0, .occupied = 255, .unseen = 128};
  OccupancyGrayCodes hull_codes;

  Status Validate() const;
  // Whether ground-truth objects of this class are evaluated.
  bool EvaluatesClass(const std::string& object_class) const;
};

}  // namespace occmap
