#include "occmap/eval/report.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace occmap {
namespace {

using V = Eigen::Vector2d;

// The two-frame case of DetectionMetrics' test: TP 3, FP 1, FN 1, MODA 0.5, MODP 0.6.
DetectionEvaluator TwoFrameDetections() {
  DetectionEvaluator evaluator;
  evaluator.AddFrame(0, std::vector<V>{V(0, 0), V(2, 0)}, std::vector<V>{V(0.1, 0), V(2, 0.3)});
  evaluator.AddFrame(1, std::vector<V>{V(0, 0), V(2, 0)}, std::vector<V>{V(0, 0.2), V(4, 4)});
  return evaluator;
}

TEST(EvaluationReportJson, UndefinedModaIsNullAndANoteSaysWhy) {
  DetectionEvaluator evaluator;
  evaluator.AddFrame(0, std::vector<V>{}, std::vector<V>{V(1, 1)});  // no ground truth, one FP
  const EvaluationReport report = MakeEvaluationReport({}, &evaluator, nullptr, nullptr, nullptr);
  const nlohmann::json j = EvaluationReportJson(report);
  EXPECT_TRUE(j["detection"]["moda"].is_null());
  EXPECT_TRUE(j["detection"]["recall"].is_null());
  EXPECT_TRUE(j["detection"]["modp"].is_null());
  EXPECT_EQ(j["detection"]["precision"], 0.0);
  EXPECT_EQ(j["detection"]["fp"], 1);
  EXPECT_TRUE(j["tracking"].is_null());
  EXPECT_TRUE(j["occupancy"]["footprint"].is_null());
  const std::vector<std::string> notes = j["notes"].get<std::vector<std::string>>();
  EXPECT_NE(std::find(notes.begin(), notes.end(), "MODA and recall undefined: no ground-truth objects in the evaluated frames"),
            notes.end());
  // Serialised text stays valid JSON (NaN would not be): it parses back the same.
  EXPECT_EQ(nlohmann::json::parse(j.dump()), j);
}

TEST(EvaluationReportJson, HoldsTheMetricsRoundedAndThePerFrameCounts) {
  const DetectionEvaluator detections = TwoFrameDetections();
  EvaluationReport report = MakeEvaluationReport({}, &detections, nullptr, nullptr, nullptr);
  report.dataset = "sim";
  report.run = "out";
  const nlohmann::json j = EvaluationReportJson(report);
  EXPECT_EQ(j["dataset"], "sim");
  EXPECT_EQ(j["gt_frames"], 2);
  EXPECT_EQ(j["match_threshold_m"], 0.5);
  EXPECT_EQ(j["detection"]["moda"], 0.5);
  EXPECT_EQ(j["detection"]["modp"], 0.6);  // 0.6 within 1e-12, rounded to 1e-6: exactly 0.6
  EXPECT_EQ(j["detection"]["mean_distance_m"], 0.2);
  EXPECT_EQ(j["detection"]["per_frame"][0], (nlohmann::json{{"frame", 0}, {"gt", 2}, {"detections", 2}, {"tp", 2}, {"fp", 0}, {"fn", 0}}));
  EXPECT_TRUE(j["notes"].empty());
}

TEST(EvaluationReportText, IsAFixedWidthTableOfEverySection) {
  const DetectionEvaluator detections = TwoFrameDetections();
  TrackingEvaluator tracking;
  tracking.AddFrame(std::vector<IdPosition>{{1, V(0, 0)}}, std::vector<IdPosition>{{5, V(0, 0.1)}});
  OccupancyEvaluator hull;
  hull.AddFrame(0, CellRaster{2, 1, {CellState::kOccupied, CellState::kFree}},
                CellRaster{2, 1, {CellState::kOccupied, CellState::kOccupied}});
  EvaluationReport report = MakeEvaluationReport({}, &detections, &tracking, nullptr, &hull);
  report.dataset = "sim";
  report.run = "out";
  report.notes = {"no gt/footprint folder in the dataset: occupancy against it not evaluated"};
  const std::string expected =
      "occmap evaluation\n"
      "  dataset  sim\n"
      "  run      out\n"
      "  match when distance <= 0.500 m; 2 frames of ground truth\n"
      "\n"
      "detection (CLEAR MOD)\n"
      "  frames                           2    ground truth (N_gt)              4\n"
      "  detections                       4    true positives                   3\n"
      "  false positives                  1    misses                           1\n"
      "  MODA                        0.5000    MODP                        0.6000\n"
      "  precision                   0.7500    recall                      0.7500\n"
      "  mean distance (m)           0.2000\n"
      "\n"
      "tracking (CLEAR MOT, identity)\n"
      "  frames                           1    ground truth (N_gt)              1\n"
      "  track positions                  1    true positives                   1\n"
      "  false positives                  0    misses                           0\n"
      "  ID switches                      0    fragmentations                   0\n"
      "  MOTA                        1.0000    MOTP (m)                    0.1000\n"
      "  MOTP (1 - d/t)              0.8000    IDF1                        1.0000\n"
      "  IDP                         1.0000    IDR                         1.0000\n"
      "  IDTP                             1    IDFP / IDFN                  0 / 0\n"
      "  GT trajectories                  1    tracks                           1\n"
      "  mostly tracked                   1    partially tracked                0\n"
      "  mostly lost                      0\n"
      "\n"
      "occupancy (cells the computed map sees)\n"
      "                           footprint          hull\n"
      "  frames                           -             1\n"
      "  cells evaluated                  -             2\n"
      "  true positives                   -             1\n"
      "  false positives                  -             0\n"
      "  misses                           -             1\n"
      "  IoU                              -        0.5000\n"
      "  precision                        -        1.0000\n"
      "  recall                           -        0.5000\n"
      "\n"
      "notes\n"
      "  - no gt/footprint folder in the dataset: occupancy against it not evaluated\n";
  EXPECT_EQ(EvaluationReportText(report), expected);
}

TEST(EvaluationReportText, SaysNotEvaluatedForAbsentSectionsAndNaForUndefinedRatios) {
  DetectionEvaluator evaluator;  // no frames at all
  const EvaluationReport report = MakeEvaluationReport({}, &evaluator, nullptr, nullptr, nullptr);
  const std::string text = EvaluationReportText(report);
  EXPECT_NE(text.find("  MODA                           n/a    MODP                           n/a\n"), std::string::npos) << text;
  EXPECT_NE(text.find("tracking (CLEAR MOT, identity)\n  not evaluated\n"), std::string::npos) << text;
  EXPECT_NE(text.find("occupancy (cells the computed map sees)\n  not evaluated\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  - MODA and recall undefined: no ground-truth objects in the evaluated frames\n"), std::string::npos);
}

TEST(EvaluationReportText, ChangesBlockGivesTheSumThenEachCameraAndNotesUndefinedRatios) {
  EvaluationReport report;
  ChangeEvaluation changes;
  changes.cameras.push_back({"C1", MakeChangeMetrics(3, 3, ChangeCounts{.tp = 6, .fp = 2, .fn = 2, .tn = 90})});
  changes.cameras.push_back({"C2", MakeChangeMetrics(3, 0, ChangeCounts{.tn = 100})});  // no change, no shadow
  changes.overall = MakeChangeMetrics(3, 3, ChangeCounts{.tp = 6, .fp = 2, .fn = 2, .tn = 190});
  report.changes = changes;
  const std::string text = EvaluationReportText(report);
  EXPECT_NE(text.find("\nchanges (pixels of the run's change masks against gt/changes)\n"
                      "  camera            frames   precision      recall          F1  shadow changed\n"
                      "  all                    3      0.7500      0.7500      0.7500             n/a\n"
                      "  C1                     3      0.7500      0.7500      0.7500             n/a\n"
                      "  C2                     3         n/a         n/a         n/a               -\n"),
            std::string::npos)
      << text;
  // Shadow masks were read but mark no pixel: undefined, and a note says why.
  EXPECT_NE(text.find("  - shadow_changed_fraction undefined: the gt/shadows masks mark no pixel\n"), std::string::npos)
      << text;
  const nlohmann::json j = EvaluationReportJson(report);
  EXPECT_TRUE(j["changes"]["shadow_changed_fraction"].is_null());
  EXPECT_TRUE(j["changes"]["cameras"][1]["precision"].is_null());
  EXPECT_EQ(j["changes"]["cameras"][0]["tp"], 6);
  EXPECT_EQ(j["changes"]["frames"], 3);
}

}  // namespace
}  // namespace occmap
