// EvaluateRun: the library side of `occmap eval`: a run's outputs against a dataset's ground
// truth, every metric whose inputs are there.
//
// dataset_dir holds (written by the simulator):
//   ground_truth.jsonl (or gt/ground_truth.jsonl)   required; sim/ground_truth.h
//   gt/footprint/NNNNNN.png, gt/hull/NNNNNN.png     optional reference rasters per frame
//                                                   (6-digit frame number; sim/gt_rasters.h;
//                                                   grey levels: EvalOptions::footprint_codes
//                                                   (255 object, 0 none), hull_codes (255 free,
//                                                   0 occupied, 128 unseen))
// run_dir holds (written by `occmap run` and the tracker):
//   detections.jsonl      -> detection metrics (CLEAR MOD)
//   tracks.jsonl          -> tracking metrics (CLEAR MOT, IDF1)
//   occupancy/NNNNNN.png  -> occupancy metrics against each reference folder present
//   changes/<camera>/NNNNNN.png -> change-mask metrics against the dataset's
//                         gt/changes/<camera>/ (and gt/shadows/<camera>/ when there);
//                         eval/change_metrics.h. Without changes/ the section is absent.
// At least one of the four must be there. Frames are matched by their "frame" number:
//   - a ground-truth frame with no line in detections.jsonl (tracks.jsonl) counts all its
//     objects as misses, unless EvalOptions::skip_frames_missing_from_run (then it is left out);
//   - a line of the run whose frame is not in the ground truth is not evaluated (WILDTRACK
//     annotates every 5th frame only);
//   - a computed map with no reference raster of its frame is not evaluated.
// Each of these is counted in the metrics and explained in the report's notes. Bad input
// (malformed files, rasters of different sizes, duplicate ids in a frame) is an error naming
// the file, line or pixel, the field, what was expected and what was found.
//
//   OCCMAP_ASSIGN_OR_RETURN(EvaluationReport report, EvaluateRun("sim-out", "occmap-out", {}));
//   std::string table = EvaluationReportText(report);
//   double moda = report.detection->moda;
#pragma once

#include <filesystem>
#include <string_view>
#include <vector>

#include "occmap/eval/eval_options.h"
#include "occmap/eval/report.h"
#include "occmap/sim/ground_truth.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

// Files (change masks) are read on ctx's threads; the overload without a context reads them on
// the calling thread.
Result<EvaluationReport> EvaluateRun(const std::filesystem::path& dataset_dir, const std::filesystem::path& run_dir,
                                     const EvalOptions& options, Context& ctx);
Result<EvaluationReport> EvaluateRun(const std::filesystem::path& dataset_dir, const std::filesystem::path& run_dir,
                                     const EvalOptions& options = {});

// The same against ground truth given in memory (a benchmark's annotations:
// eval/benchmark_annotations.h), which `dataset_name` names in the report and in messages.
// Frames must increase and ids be unique within a frame (an error otherwise). Without reference
// rasters, the run's occupancy maps and change masks are not evaluated (a note says so), and
// the run must have detections.jsonl or tracks.jsonl.
Result<EvaluationReport> EvaluateRunAgainst(const std::vector<GroundTruthFrame>& gt, std::string_view dataset_name,
                                            const std::filesystem::path& run_dir, const EvalOptions& options,
                                            Context& ctx);

}  // namespace occmap
