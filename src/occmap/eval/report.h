// EvaluationReport: every metric of one evaluation (detection, tracking, occupancy against the
// footprint and the plane-hull rasters, change masks), with what was left out, rendered as JSON or as a
// fixed-width text table. A section is absent (std::nullopt; null in JSON, "not evaluated" in
// text) when its input was not there. Undefined ratios (e.g. MODA with no ground truth) are NaN
// in the structs, null in JSON, "n/a" in text, and a note says why.
//
//   EvaluationReport report = MakeEvaluationReport(options, &detections, &tracks, nullptr, nullptr);
//   std::string json_text = EvaluationReportJson(report).dump(2);
//   std::string table = EvaluationReportText(report);
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "occmap/eval/change_metrics.h"
#include "occmap/eval/detection_metrics.h"
#include "occmap/eval/eval_options.h"
#include "occmap/eval/occupancy_metrics.h"
#include "occmap/eval/tracking_metrics.h"

namespace occmap {

// Where ground truth read from a benchmark's annotation files came from and how their numbers
// were mapped to the run's frames (eval/benchmark_annotations.h).
struct AnnotationSummary {
  std::string format;  // "wildtrack", "multiviewx"
  std::string folder;
  int64_t first_frame = 0;  // annotation number = first_frame + step_num / step_den x run frame
  int64_t step_num = 1, step_den = 1;
  // Annotation numbers evaluated, inclusive (none when range_last < range_first): the run's
  // first to last frame, or given (range_given).
  int64_t range_first = 0, range_last = -1;
  bool range_given = false;
  int64_t files = 0;                      // annotation files read
  int64_t first_file = 0, last_file = 0;  // their numbers
  int64_t files_evaluated = 0;            // in the range and on a run frame
  int64_t people_evaluated = 0;           // positions in those files
  int64_t files_outside_range = 0;
  int64_t files_between_frames = 0;  // in the range but before run frame 0 or between two run frames
  // The annotation number of an evaluated run frame.
  int64_t NumberOf(int64_t frame) const { return first_frame + frame * step_num / step_den; }
};

struct EvaluationReport {
  std::string dataset;  // where the ground truth came from (a folder, or e.g. "demo")
  std::string run;      // where the run's outputs came from
  double match_threshold_m = 0.5;
  int64_t gt_frames = 0;  // frames in the ground truth
  std::optional<DetectionMetrics> detection;
  std::vector<FrameDetectionCounts> detection_frames;  // per frame TP, FP, FN
  std::optional<TrackingMetrics> tracking;
  std::optional<OccupancyMetrics> footprint;  // against the footprint rasters
  std::optional<OccupancyMetrics> hull;       // against the ideal plane-hull rasters
  std::optional<ChangeEvaluation> changes;    // the run's change masks against the perfect ones
  std::vector<std::string> notes;             // what was left out, and why
  std::optional<AnnotationSummary> annotations;  // set when the ground truth is a benchmark's annotations
};

// A report from in-memory evaluators (any may be null: that section is absent). gt_frames is
// the most frames any evaluator saw; dataset and run are left for the caller.
EvaluationReport MakeEvaluationReport(const EvalOptions& options, const DetectionEvaluator* detection,
                                      const TrackingEvaluator* tracking, const OccupancyEvaluator* footprint,
                                      const OccupancyEvaluator* hull);

// The notes of the report followed by one per undefined metric ("MODA undefined: ...").
std::vector<std::string> EvaluationNotes(const EvaluationReport& report);

// {"dataset", "run", "match_threshold_m", "gt_frames",
//  "annotations": {"format", "folder", "files", "first_file", "last_file", "first_frame",
//                  "frame_step" ("5", "1/6"), "range": [first, last], "range_from" ("run" or
//                  "option"), "files_evaluated", "people_evaluated", "files_outside_range",
//                  "files_between_frames"}  (only with a benchmark's annotations),
//  "detection": {"frames", "gt", "detections", "tp", "fp", "fn", "moda", "modp", "precision",
//                "recall", "mean_distance_m", "gt_frames_missing_from_run",
//                "run_frames_without_gt", "per_frame": [{"frame", "gt", "detections", "tp", "fp", "fn"}]},
//                (per_frame entries also have "annotation_file", its number, with annotations)
//  "tracking": {"frames", "gt", "predictions", "tp", "fp", "fn", "id_switches", "fragmentations",
//               "gt_trajectories", "track_trajectories", "mostly_tracked", "partially_tracked",
//               "mostly_lost", "mota", "motp_m", "motp_closeness", "idtp", "idfp", "idfn", "idf1",
//               "idp", "idr", "gt_frames_missing_from_run", "run_frames_without_gt"},
//  "occupancy": {"footprint": {"frames", "cells_evaluated", "tp", "fp", "fn", "tn",
//                "computed_unseen", "reference_unseen", "iou", "precision", "recall",
//                "computed_frames_without_reference"}, "hull": {...}},
//  "changes": {"frames", "shadow_frames", "tp", "fp", "fn", "tn", "shadow_pixels", "shadow_changed",
//              "precision", "recall", "f1", "shadow_changed_fraction",
//              "cameras": [{"id", "frames", "shadow_frames", "tp", "fp", "fn", "tn", "shadow_pixels",
//                           "shadow_changed", "precision", "recall", "f1", "shadow_changed_fraction"}]},
//  "notes": [...]}
// Absent sections and undefined ratios are null, except "changes", which is left out when the
// run has no change masks, and "annotations"; ratios are rounded to 1e-6.
nlohmann::json EvaluationReportJson(const EvaluationReport& report);

// A readable fixed-width table, one section per metric family (changes only when evaluated),
// then the notes; ends in '\n'.
std::string EvaluationReportText(const EvaluationReport& report);

}  // namespace occmap
