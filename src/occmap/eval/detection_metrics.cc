#include "occmap/eval/detection_metrics.h"

#include <cmath>
#include <limits>

#include "occmap/util/hungarian.h"

namespace occmap {

std::vector<int> MatchWithinDistance(std::span<const Eigen::Vector2d> gt_m,
                                     std::span<const Eigen::Vector2d> predicted_m, double threshold_m) {
  const int rows = static_cast<int>(gt_m.size()), cols = static_cast<int>(predicted_m.size());
  if (rows == 0 || cols == 0) return std::vector<int>(gt_m.size(), -1);
  // Pairs beyond the gate cost infinity, which SolveAssignment never assigns; its forbidden
  // cost stays infinite so that a pair at exactly threshold_m is allowed (d <= t matches).
  const double kForbidden = std::numeric_limits<double>::infinity();
  std::vector<double> cost(static_cast<size_t>(rows) * static_cast<size_t>(cols));
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const double d = (gt_m[static_cast<size_t>(i)] - predicted_m[static_cast<size_t>(j)]).norm();
      cost[static_cast<size_t>(i) * static_cast<size_t>(cols) + static_cast<size_t>(j)] = d <= threshold_m ? d : kForbidden;
    }
  }
  return SolveAssignment(cost, rows, cols);
}

double RatioOrNaN(double num, double den) {
  return den == 0 ? std::numeric_limits<double>::quiet_NaN() : num / den;
}

std::vector<Eigen::Vector2d> GroundTruthPositions(const GroundTruthFrame& frame, const EvalOptions& options) {
  std::vector<Eigen::Vector2d> positions;
  for (const GroundTruthObject& o : frame.objects) {
    if (options.EvaluatesClass(o.object_class)) positions.emplace_back(o.x_m, o.y_m);
  }
  return positions;
}

DetectionEvaluator::DetectionEvaluator(const EvalOptions& options) : options_(options) {
  OCCMAP_CHECK(options_.Validate().ok(), options_.Validate().message());
}

void DetectionEvaluator::AddFrame(const GroundTruthFrame& gt, const std::vector<Eigen::Vector2d>& detections_m) {
  const std::vector<Eigen::Vector2d> gt_m = GroundTruthPositions(gt, options_);
  AddFrame(gt.frame, gt_m, detections_m);
}

void DetectionEvaluator::AddFrame(const GroundTruthFrame& gt, const std::vector<Blob>& blobs) {
  std::vector<Eigen::Vector2d> detections_m;
  for (const Blob& b : blobs) {
    if (b.area_m2 >= options_.min_detection_area_m2) detections_m.emplace_back(b.x_m, b.y_m);
  }
  AddFrame(gt, detections_m);
}

void DetectionEvaluator::AddFrame(int64_t frame, std::span<const Eigen::Vector2d> gt_m,
                                  std::span<const Eigen::Vector2d> detections_m) {
  const std::vector<int> match = MatchWithinDistance(gt_m, detections_m, options_.match_threshold_m);
  FrameDetectionCounts c;
  c.frame = frame;
  c.gt = static_cast<int64_t>(gt_m.size());
  c.detections = static_cast<int64_t>(detections_m.size());
  for (size_t i = 0; i < match.size(); ++i) {
    if (match[i] < 0) continue;
    const double d = (gt_m[i] - detections_m[static_cast<size_t>(match[i])]).norm();
    ++c.tp;
    c.distance_sum_m += d;
    closeness_sum_ += 1.0 - d / options_.match_threshold_m;
  }
  c.fn = c.gt - c.tp;
  c.fp = c.detections - c.tp;
  frames_.push_back(c);
}

DetectionMetrics DetectionEvaluator::Metrics() const {
  DetectionMetrics m;
  double distance_sum_m = 0;
  for (const FrameDetectionCounts& c : frames_) {
    ++m.frames;
    m.gt += c.gt;
    m.detections += c.detections;
    m.tp += c.tp;
    m.fp += c.fp;
    m.fn += c.fn;
    distance_sum_m += c.distance_sum_m;
  }
  const auto gt = static_cast<double>(m.gt), tp = static_cast<double>(m.tp);
  m.moda = m.gt == 0 ? std::numeric_limits<double>::quiet_NaN() : 1.0 - static_cast<double>(m.fn + m.fp) / gt;
  m.modp = RatioOrNaN(closeness_sum_, tp);
  m.precision = RatioOrNaN(tp, static_cast<double>(m.tp + m.fp));
  m.recall = RatioOrNaN(tp, gt);
  m.mean_distance_m = RatioOrNaN(distance_sum_m, tp);
  return m;
}

}  // namespace occmap
