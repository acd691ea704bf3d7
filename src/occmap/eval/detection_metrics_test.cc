#include "occmap/eval/detection_metrics.h"

#include <gtest/gtest.h>

#include "occmap/util/hungarian.h"

#include <cmath>
#include <limits>
#include <random>
#include <utility>
#include <string>
#include <vector>

namespace occmap {
namespace {

using V = Eigen::Vector2d;

GroundTruthFrame Frame(int64_t frame, const std::vector<V>& positions, const std::string& object_class = "person") {
  GroundTruthFrame f;
  f.frame = frame;
  int64_t id = 1;
  for (const V& p : positions) f.objects.push_back({.id = id++, .object_class = object_class, .x_m = p.x(), .y_m = p.y(), .footprint_m = {}});
  return f;
}

TEST(DetectionEvaluator, TwoFramesWithAMissAndAFalsePositiveGiveModaOneHalf) {
  // Frame 0: objects a (0, 0) and b (2, 0); detections at 0.1 m from a and 0.3 m from b.
  //   TP 2, FP 0, FN 0.
  // Frame 1: objects a (0, 0) and c (2, 0); detections at 0.2 m from a and far away (4, 4).
  //   TP 1, FP 1, FN 1 (c).
  // N_gt = 4: MODA = 1 - (FN + FP) / N_gt = 1 - (1 + 1) / 4 = 0.5.
  // MODP = ((1 - 0.1/0.5) + (1 - 0.3/0.5) + (1 - 0.2/0.5)) / 3 = (0.8 + 0.4 + 0.6) / 3 = 0.6.
  // precision = 3 / 4, recall = 3 / 4, mean distance = (0.1 + 0.3 + 0.2) / 3 = 0.2 m.
  DetectionEvaluator evaluator;
  evaluator.AddFrame(Frame(0, {V(0, 0), V(2, 0)}), std::vector<V>{V(0.1, 0), V(2, 0.3)});
  evaluator.AddFrame(Frame(1, {V(0, 0), V(2, 0)}), std::vector<V>{V(0, 0.2), V(4, 4)});
  const DetectionMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.frames, 2);
  EXPECT_EQ(m.gt, 4);
  EXPECT_EQ(m.detections, 4);
  EXPECT_EQ(m.tp, 3);
  EXPECT_EQ(m.fp, 1);
  EXPECT_EQ(m.fn, 1);
  EXPECT_DOUBLE_EQ(m.moda, 0.5);
  EXPECT_NEAR(m.modp, 0.6, 1e-12);
  EXPECT_DOUBLE_EQ(m.precision, 0.75);
  EXPECT_DOUBLE_EQ(m.recall, 0.75);
  EXPECT_NEAR(m.mean_distance_m, 0.2, 1e-12);
  ASSERT_EQ(evaluator.frames().size(), 2u);
  const FrameDetectionCounts& f1 = evaluator.frames()[1];
  EXPECT_EQ(f1.frame, 1);
  EXPECT_EQ(f1.gt, 2);
  EXPECT_EQ(f1.detections, 2);
  EXPECT_EQ(f1.tp, 1);
  EXPECT_EQ(f1.fp, 1);
  EXPECT_EQ(f1.fn, 1);
  EXPECT_NEAR(f1.distance_sum_m, 0.2, 1e-12);
}

TEST(MatchWithinDistance, DetectionAt049MetresMatchesAndAt051DoesNot) {
  const std::vector<V> gt = {V(1, 1)};
  EXPECT_EQ(MatchWithinDistance(gt, std::vector<V>{V(1.49, 1)}, 0.5), std::vector<int>{0});
  EXPECT_EQ(MatchWithinDistance(gt, std::vector<V>{V(1.51, 1)}, 0.5), std::vector<int>{-1});
}

TEST(MatchWithinDistance, DetectionExactlyAtTheThresholdMatches) {
  // (0.5, 0) is exactly 0.5 m from the origin in floating point: d <= t is a match.
  EXPECT_EQ(MatchWithinDistance(std::vector<V>{V(0, 0)}, std::vector<V>{V(0.5, 0)}, 0.5), std::vector<int>{0});
}

TEST(MatchWithinDistance, PrefersTheGlobalOptimumOverGreedyNearest) {
  // Objects A (0, 0) and B (0.8, 0); detections p (0.35, 0) and q (-0.45, 0).
  // Greedy nearest pairs p with A (0.35 m, the shortest distance), then q has nothing within
  // 0.5 m of it (B is 1.25 m away): one match. The optimum pairs A-q (0.45) and B-p (0.45).
  const std::vector<int> match = MatchWithinDistance(std::vector<V>{V(0, 0), V(0.8, 0)},
                                                     std::vector<V>{V(0.35, 0), V(-0.45, 0)}, 0.5);
  EXPECT_EQ(match, (std::vector<int>{1, 0}));
}

TEST(MatchWithinDistance, AmongEquallyManyPairsChoosesTheLeastTotalDistance) {
  // Gate 1 m: A (0, 0), B (1, 0); p (0.4, 0), q (0.6, 0). A-p + B-q = 0.4 + 0.4 = 0.8 beats
  // A-q + B-p = 0.6 + 0.6 = 1.2.
  const std::vector<int> match = MatchWithinDistance(std::vector<V>{V(0, 0), V(1, 0)},
                                                     std::vector<V>{V(0.6, 0), V(0.4, 0)}, 1.0);
  EXPECT_EQ(match, (std::vector<int>{1, 0}));
}

TEST(MatchWithinDistance, EmptySidesMatchNothing) {
  EXPECT_EQ(MatchWithinDistance(std::vector<V>{V(0, 0), V(1, 1)}, std::vector<V>{}, 0.5), (std::vector<int>{-1, -1}));
  EXPECT_TRUE(MatchWithinDistance(std::vector<V>{}, std::vector<V>{V(0, 0)}, 0.5).empty());
}

// The reference: one dense matrix of every pair, as MatchWithinDistance was.
std::vector<int> DenseMatch(const std::vector<V>& gt, const std::vector<V>& pred, double t) {
  if (gt.empty() || pred.empty()) return std::vector<int>(gt.size(), -1);
  std::vector<double> cost;
  for (const V& g : gt) {
    for (const V& p : pred) cost.push_back((g - p).norm() <= t ? (g - p).norm() : std::numeric_limits<double>::infinity());
  }
  return SolveAssignment(cost, static_cast<int>(gt.size()), static_cast<int>(pred.size()));
}

std::pair<int, double> CountAndCost(const std::vector<int>& m, const std::vector<V>& gt, const std::vector<V>& pred) {
  int n = 0;
  double cost = 0;
  for (size_t i = 0; i < m.size(); ++i) {
    if (m[i] < 0) continue;
    ++n;
    cost += (gt[i] - pred[static_cast<size_t>(m[i])]).norm();
  }
  return {n, cost};
}

TEST(MatchWithinDistance, GatedGroupsGiveTheDenseOptimum) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 4.0);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<V> gt(rng() % 25), pred(rng() % 25);
    for (V& g : gt) g = {u(rng), u(rng)};
    for (V& p : pred) p = {u(rng), u(rng)};
    const std::vector<int> fast = MatchWithinDistance(gt, pred, 0.5), dense = DenseMatch(gt, pred, 0.5);
    const auto [n_fast, cost_fast] = CountAndCost(fast, gt, pred);
    const auto [n_dense, cost_dense] = CountAndCost(dense, gt, pred);
    ASSERT_EQ(n_fast, n_dense) << trial;
    ASSERT_NEAR(cost_fast, cost_dense, 1e-9) << trial;
    std::vector<int> used(pred.size(), 0);
    for (int j : fast) {
      if (j >= 0) {
        ASSERT_EQ(used[static_cast<size_t>(j)]++, 0) << "prediction matched twice";
      }
    }
  }
}

// 5000 x 5000 points a frame were one 25 M-entry matrix (over 60 s); gated, groups of one pair.
TEST(MatchWithinDistance, FiveThousandPointsEachMatchTheirNeighbour) {
  std::vector<V> gt, pred;
  for (int k = 0; k < 5000; ++k) {
    gt.push_back({(k % 100) * 1.0, (k / 100) * 1.0});
    pred.push_back({(k % 100) * 1.0 + 0.1, (k / 100) * 1.0 - 0.2});
  }
  const std::vector<int> m = MatchWithinDistance(gt, pred, 0.5);
  for (int k = 0; k < 5000; ++k) ASSERT_EQ(m[static_cast<size_t>(k)], k);
  EXPECT_EQ(PairsWithinDistance(gt, pred, 0.5).size(), 5000u);
}

TEST(DetectionEvaluator, ModaIsNegativeWhenFalsePositivesOutnumberGroundTruth) {
  // One object, matched; two more detections far away: FP 2, FN 0, MODA = 1 - 2 / 1 = -1.
  DetectionEvaluator evaluator;
  evaluator.AddFrame(Frame(0, {V(0, 0)}), std::vector<V>{V(0, 0), V(3, 0), V(0, 3)});
  const DetectionMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.fp, 2);
  EXPECT_DOUBLE_EQ(m.moda, -1.0);
  EXPECT_DOUBLE_EQ(m.modp, 1.0);  // the match is exact: 1 - 0 / 0.5
  EXPECT_NEAR(m.precision, 1.0 / 3.0, 1e-12);
}

TEST(DetectionEvaluator, NoGroundTruthLeavesModaAndRecallUndefined) {
  // Two detections, no object: FP 2; MODA and recall divide by N_gt = 0, MODP by TP = 0.
  DetectionEvaluator evaluator;
  evaluator.AddFrame(Frame(0, {}), std::vector<V>{V(0, 0), V(1, 0)});
  const DetectionMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.fp, 2);
  EXPECT_TRUE(std::isnan(m.moda));
  EXPECT_TRUE(std::isnan(m.recall));
  EXPECT_TRUE(std::isnan(m.modp));
  EXPECT_TRUE(std::isnan(m.mean_distance_m));
  EXPECT_DOUBLE_EQ(m.precision, 0.0);
}

TEST(DetectionEvaluator, GroundTruthWithoutDetectionsIsAllMisses) {
  // Three objects, nothing detected: FN 3, MODA = 1 - 3 / 3 = 0, recall 0, precision 0 / 0.
  DetectionEvaluator evaluator;
  evaluator.AddFrame(Frame(0, {V(0, 0), V(1, 0), V(2, 0)}), std::vector<V>{});
  const DetectionMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.fn, 3);
  EXPECT_DOUBLE_EQ(m.moda, 0.0);
  EXPECT_DOUBLE_EQ(m.recall, 0.0);
  EXPECT_TRUE(std::isnan(m.precision));
}

TEST(DetectionEvaluator, NoFramesLeaveEveryRatioUndefined) {
  const DetectionMetrics m = DetectionEvaluator().Metrics();
  EXPECT_EQ(m.frames, 0);
  EXPECT_TRUE(std::isnan(m.moda));
  EXPECT_TRUE(std::isnan(m.modp));
  EXPECT_TRUE(std::isnan(m.precision));
  EXPECT_TRUE(std::isnan(m.recall));
}

TEST(DetectionEvaluator, ClassFilterDropsObjectsOfOtherClasses) {
  // A person at (0, 0) and a chair at (3, 0), people only: the detection on the chair is a
  // false positive, the person a miss. N_gt = 1, MODA = 1 - (1 + 1) / 1 = -1.
  EvalOptions options;
  options.object_classes = {"person"};
  GroundTruthFrame frame = Frame(0, {V(0, 0)});
  frame.objects.push_back({.id = 9, .object_class = "chair", .x_m = 3, .y_m = 0, .footprint_m = {}});
  DetectionEvaluator evaluator(options);
  evaluator.AddFrame(frame, std::vector<V>{V(3, 0)});
  const DetectionMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.gt, 1);
  EXPECT_EQ(m.fp, 1);
  EXPECT_EQ(m.fn, 1);
  EXPECT_DOUBLE_EQ(m.moda, -1.0);
}

TEST(DetectionEvaluator, BlobsSmallerThanTheMinimumAreaAreNotDetections) {
  // Minimum 0.05 m^2: the 0.04 m^2 blob on the object is dropped (FN 1), the 0.06 m^2 one
  // far away stays (FP 1).
  EvalOptions options;
  options.min_detection_area_m2 = 0.05;
  DetectionEvaluator evaluator(options);
  std::vector<Blob> blobs(2);
  blobs[0] = {.x_m = 0, .y_m = 0, .area_m2 = 0.04, .cells = 4};
  blobs[1] = {.x_m = 5, .y_m = 5, .area_m2 = 0.06, .cells = 6};
  evaluator.AddFrame(Frame(0, {V(0, 0)}), blobs);
  const DetectionMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.detections, 1);
  EXPECT_EQ(m.tp, 0);
  EXPECT_EQ(m.fp, 1);
  EXPECT_EQ(m.fn, 1);
}

TEST(EvalOptions, RejectsANonPositiveThresholdAndEqualGreyCodes) {
  EvalOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.match_threshold_m = 0;
  EXPECT_EQ(options.Validate().message(), "match_threshold_m: expected a distance > 0 m, found 0");
  options = {};
  options.hull_codes.unseen = options.hull_codes.free;
  EXPECT_EQ(options.Validate().message(),
            "hull_codes: grey codes: expected three different levels, found free 255, occupied 0, unseen 255");
  options = {};
  options.mostly_lost_ratio = 0.9;
  EXPECT_EQ(options.Validate().message(),
            "mostly_lost_ratio, mostly_tracked_ratio: expected 0 <= lost <= tracked <= 1, found 0.9 and 0.8");
}

}  // namespace
}  // namespace occmap
