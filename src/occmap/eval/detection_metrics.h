// Detection metrics: the CLEAR MOD protocol as used on WILDTRACK, on floor positions.
//
// Per frame, ground-truth positions and detections are matched one to one by the Hungarian
// method (MatchWithinDistance): the most pairs with distance <= EvalOptions::match_threshold_m,
// then the least total distance. Matched pairs are true positives (TP), unmatched detections
// false positives (FP), unmatched ground truth misses (FN). Over a sequence, with N_gt the
// number of ground-truth objects summed over frames and t the threshold:
//   MODA = 1 - (FN + FP) / N_gt          (can be negative; NaN when N_gt = 0)
//   MODP = sum over matches (1 - d / t) / TP   (WILDTRACK's definition; NaN when TP = 0)
//   precision = TP / (TP + FP), recall = TP / N_gt, mean matched distance = sum d / TP.
// An undefined ratio is NaN here and null in the report's JSON.
//
// Which frames count is the caller's choice: every frame given to AddFrame is evaluated (a
// frame with ground truth and no detections is all misses; one with detections and no ground
// truth all false positives). EvaluateRun (evaluate_run.h) decides it for files.
//
//   DetectionEvaluator evaluator(options);
//   for (...) evaluator.AddFrame(gt_frame, detections_m);
//   DetectionMetrics m = evaluator.Metrics();   // m.moda, m.modp, ...
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "occmap/eval/eval_options.h"
#include "occmap/fusion/blobs.h"
#include "occmap/sim/ground_truth.h"

namespace occmap {

// Every pair (i, j, distance) of a[i] and b[j] at most threshold_m apart, ordered by i then j;
// found through a grid of threshold_m cells, not by trying all |a| x |b| pairs.
struct PointPair {
  int i, j;
  double distance_m;
};
std::vector<PointPair> PairsWithinDistance(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b,
                                           double threshold_m);

// The optimal one-to-one matching of ground-truth points to predicted points: the largest
// number of pairs whose distance is <= threshold_m, and among those the least total distance.
// Returns, for each ground-truth point, the index of its predicted point or -1. The pairs within
// the gate split the points into groups no pair joins; each group is solved alone (Hungarian,
// cubic in its size): 5000 x 5000 points a frame took over 60 s as one matrix.
std::vector<int> MatchWithinDistance(std::span<const Eigen::Vector2d> gt_m,
                                     std::span<const Eigen::Vector2d> predicted_m, double threshold_m);

// num / den, or NaN when den is 0 (an undefined metric).
double RatioOrNaN(double num, double den);

struct FrameDetectionCounts {
  int64_t frame = 0;
  int64_t gt = 0;          // ground-truth objects (after the class filter)
  int64_t detections = 0;  // detections (after the area filter)
  int64_t tp = 0, fp = 0, fn = 0;
  double distance_sum_m = 0;  // over the frame's matches
};

struct DetectionMetrics {
  int64_t frames = 0;  // frames evaluated
  int64_t gt = 0;      // N_gt
  int64_t detections = 0;
  int64_t tp = 0, fp = 0, fn = 0;
  double moda = 0, modp = 0, precision = 0, recall = 0, mean_distance_m = 0;  // NaN: undefined
  // Filled by EvaluateRun: ground-truth frames with no line in the run (their objects are
  // misses unless EvalOptions::skip_frames_missing_from_run), and lines of the run whose frame
  // has no ground truth (not evaluated).
  int64_t gt_frames_missing_from_run = 0;
  int64_t run_frames_without_gt = 0;
};

class DetectionEvaluator {
 public:
  explicit DetectionEvaluator(const EvalOptions& options = {});

  // Ground-truth objects of the classes the options select, against detections in metres.
  void AddFrame(const GroundTruthFrame& gt, const std::vector<Eigen::Vector2d>& detections_m);
  // The same with blobs, dropping those with area_m2 < options.min_detection_area_m2.
  void AddFrame(const GroundTruthFrame& gt, const std::vector<Blob>& blobs);
  // Plain positions, no filter.
  void AddFrame(int64_t frame, std::span<const Eigen::Vector2d> gt_m, std::span<const Eigen::Vector2d> detections_m);

  const std::vector<FrameDetectionCounts>& frames() const { return frames_; }
  DetectionMetrics Metrics() const;

 private:
  EvalOptions options_;
  std::vector<FrameDetectionCounts> frames_;
  double closeness_sum_ = 0;  // sum over matches of 1 - d / threshold
};

// The positions of the objects in `frame` whose class the options select.
std::vector<Eigen::Vector2d> GroundTruthPositions(const GroundTruthFrame& frame, const EvalOptions& options);

}  // namespace occmap
