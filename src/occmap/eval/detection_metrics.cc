#include "occmap/eval/detection_metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <utility>
#include <limits>

#include "occmap/util/hungarian.h"

namespace occmap {

std::vector<PointPair> PairsWithinDistance(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b,
                                           double threshold_m) {
  std::vector<PointPair> pairs;
  if (a.empty() || b.empty()) return pairs;
  // Cells of threshold_m: a pair within the gate lies in the same or a neighbouring cell. Cell
  // numbers are clamped (a point at 1e300 m shares a far cell; distances still decide).
  const double cell_m = threshold_m > 0 ? threshold_m : 1.0;
  auto cell = [&](double v) {
    return static_cast<int64_t>(std::clamp(std::floor(v / cell_m), -double(int64_t{1} << 40), double(int64_t{1} << 40)));
  };
  std::map<std::pair<int64_t, int64_t>, std::vector<int>> grid;
  for (size_t j = 0; j < b.size(); ++j) grid[{cell(b[j].x()), cell(b[j].y())}].push_back(static_cast<int>(j));
  for (size_t i = 0; i < a.size(); ++i) {
    const int64_t cx = cell(a[i].x()), cy = cell(a[i].y());
    const size_t first = pairs.size();
    for (int64_t dx = -1; dx <= 1; ++dx) {
      for (int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = grid.find({cx + dx, cy + dy});
        if (it == grid.end()) continue;
        for (int j : it->second) {
          const double d = (a[i] - b[static_cast<size_t>(j)]).norm();
          if (d <= threshold_m) pairs.push_back({static_cast<int>(i), j, d});
        }
      }
    }
    std::sort(pairs.begin() + static_cast<std::ptrdiff_t>(first), pairs.end(),
              [](const PointPair& p, const PointPair& q) { return p.j < q.j; });
  }
  return pairs;
}

std::vector<int> MatchWithinDistance(std::span<const Eigen::Vector2d> gt_m,
                                     std::span<const Eigen::Vector2d> predicted_m, double threshold_m) {
  std::vector<int> match(gt_m.size(), -1);
  const std::vector<PointPair> pairs = PairsWithinDistance(gt_m, predicted_m, threshold_m);
  if (pairs.empty()) return match;
  // Groups: connected components of the pairs (ground truth i is node i, prediction j node n + j).
  const size_t n = gt_m.size();
  std::vector<size_t> parent(n + predicted_m.size());
  std::iota(parent.begin(), parent.end(), size_t{0});
  auto find = [&](size_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const PointPair& p : pairs) parent[find(static_cast<size_t>(p.i))] = find(n + static_cast<size_t>(p.j));
  std::map<size_t, std::vector<const PointPair*>> groups;
  for (const PointPair& p : pairs) groups[find(static_cast<size_t>(p.i))].push_back(&p);
  // Pairs beyond the gate cost infinity, which SolveAssignment never assigns; its forbidden
  // cost stays infinite so that a pair at exactly threshold_m is allowed (d <= t matches).
  const double kForbidden = std::numeric_limits<double>::infinity();
  for (const auto& [root, group] : groups) {
    std::map<int, int> row_of, col_of;  // point index -> row or column of the group's matrix
    for (const PointPair* p : group) {
      row_of.emplace(p->i, 0);
      col_of.emplace(p->j, 0);
    }
    std::vector<int> gt_of_row, pred_of_col;
    for (auto& [i, row] : row_of) {
      row = static_cast<int>(gt_of_row.size());
      gt_of_row.push_back(i);
    }
    for (auto& [j, col] : col_of) {
      col = static_cast<int>(pred_of_col.size());
      pred_of_col.push_back(j);
    }
    const int rows = static_cast<int>(gt_of_row.size()), cols = static_cast<int>(pred_of_col.size());
    std::vector<double> cost(static_cast<size_t>(rows) * static_cast<size_t>(cols), kForbidden);
    for (const PointPair* p : group) {
      cost[static_cast<size_t>(row_of[p->i]) * static_cast<size_t>(cols) + static_cast<size_t>(col_of[p->j])] = p->distance_m;
    }
    const std::vector<int> m = SolveAssignment(cost, rows, cols);
    for (int r = 0; r < rows; ++r) {
      if (m[static_cast<size_t>(r)] >= 0) match[static_cast<size_t>(gt_of_row[static_cast<size_t>(r)])] = pred_of_col[static_cast<size_t>(m[static_cast<size_t>(r)])];
    }
  }
  return match;
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
