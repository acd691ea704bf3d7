#include "occmap/eval/evaluate_run.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;

GroundTruthObject Person(int64_t id, double x_m, double y_m) {
  return {.id = id, .object_class = "person", .x_m = x_m, .y_m = y_m, .footprint_m = {}};
}

// Writes a raster picture from rows of text, top row first: '#' occupied, '.' free, '?' unseen,
// in OccupancyMap::ToGrayImage's grey levels (computed maps, hull rasters).
void WriteRaster(const fs::path& path, const std::vector<std::string>& rows, const OccupancyGrayCodes& codes = {}) {
  Image<uint8_t> picture(static_cast<int>(rows[0].size()), static_cast<int>(rows.size()));
  for (int y = 0; y < picture.height(); ++y) {
    for (int x = 0; x < picture.width(); ++x) {
      const char c = rows[static_cast<size_t>(y)][static_cast<size_t>(x)];
      picture(x, y) = c == '#' ? codes.occupied : c == '?' ? codes.unseen : codes.free;
    }
  }
  fs::create_directories(path.parent_path());
  ASSERT_TRUE(WritePng(path, picture.view()).ok());
}

bool HasNote(const EvaluationReport& report, const std::string& note) {
  const std::vector<std::string> notes = EvaluationNotes(report);
  return std::find(notes.begin(), notes.end(), note) != notes.end();
}

// A dataset of three frames and a run that lacks frame 2 and has a frame 7 without ground truth.
//   ground truth: frame 0: 1 (0, 0), 2 (2, 0); frame 1: the same; frame 2: 1 (0, 0).
//   detections:   frame 0: (0.1, 0), (2, 0.3) -> TP 2
//                 frame 1: (0, 0.2), (4, 4)   -> TP 1, FP 1, FN 1
//                 frame 2: no line            -> FN 1 (object 1)
//                 frame 7: (9, 9)             -> not evaluated
//     N_gt = 5: MODA = 1 - (2 + 1) / 5 = 0.4; MODP = (0.8 + 0.4 + 0.6) / 3 = 0.6.
//   tracks: exact in every ground-truth frame, ids 11 and 12: MOTA 1, IDF1 1.
//   occupancy (2 x 2 cells): computed frame 0 "#." / ".?", frame 1 "##" / "..";
//     footprint (frame 0 only): "#." / "#." -> TP 1, FN 1, TN 1 (one cell unseen):
//       IoU 1/2, precision 1, recall 1/2; computed frame 1 has no footprint raster.
//     hull: frame 0 "#." / "..", frame 1 "##" / "##" -> TP 1 + 2, FN 0 + 2, TN 2 + 0:
//       IoU 3/5, precision 1, recall 3/5.
class EvaluateRunTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(dataset_);
    fs::create_directories(run_);
    std::vector<GroundTruthFrame> gt(3);
    for (int f = 0; f < 3; ++f) gt[static_cast<size_t>(f)].frame = f;
    gt[0].objects = {Person(1, 0, 0), Person(2, 2, 0)};
    gt[1].objects = {Person(1, 0, 0), Person(2, 2, 0)};
    gt[2].objects = {Person(1, 0, 0)};
    ASSERT_TRUE(WriteGroundTruth(dataset_ / "ground_truth.jsonl", gt).ok());
    testing::WriteText(run_ / "detections.jsonl",
                       "{\"frame\":0,\"time_s\":0,\"blobs\":[{\"x_m\":0.1,\"y_m\":0},{\"x_m\":2,\"y_m\":0.3}]}\n"
                       "{\"frame\":1,\"time_s\":0.1,\"blobs\":[{\"x_m\":0,\"y_m\":0.2},{\"x_m\":4,\"y_m\":4}]}\n"
                       "{\"frame\":7,\"time_s\":0.7,\"blobs\":[{\"x_m\":9,\"y_m\":9}]}\n");
    testing::WriteText(run_ / "tracks.jsonl",
                       "{\"frame\":0,\"time_s\":0,\"tracks\":[{\"id\":11,\"x_m\":0,\"y_m\":0},{\"id\":12,\"x_m\":2,\"y_m\":0}]}\n"
                       "{\"frame\":1,\"time_s\":0.1,\"tracks\":[{\"id\":11,\"x_m\":0,\"y_m\":0},{\"id\":12,\"x_m\":2,\"y_m\":0}]}\n"
                       "{\"frame\":2,\"time_s\":0.2,\"tracks\":[{\"id\":11,\"x_m\":0,\"y_m\":0}]}\n");
    WriteRaster(run_ / "occupancy" / "000000.png", {"#.", ".?"});
    WriteRaster(run_ / "occupancy" / "000001.png", {"##", ".."});
    // The simulator's footprint raster: 255 where an object stands, 0 elsewhere.
    WriteRaster(dataset_ / "gt" / "footprint" / "000000.png", {"#.", "#."}, {.free = 0, .occupied = 255, .unseen = 128});
    WriteRaster(dataset_ / "gt" / "hull" / "000000.png", {"#.", ".."});
    WriteRaster(dataset_ / "gt" / "hull" / "000001.png", {"##", "##"});
  }

  testing::TempDir dir_;
  fs::path dataset_ = dir_ / "dataset";
  fs::path run_ = dir_ / "run";
};

TEST_F(EvaluateRunTest, ScoresDetectionsTracksAndOccupancyOfARunFolder) {
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->gt_frames, 3);

  ASSERT_TRUE(report->detection.has_value());
  const DetectionMetrics& d = *report->detection;
  EXPECT_EQ(d.frames, 3);
  EXPECT_EQ(d.gt, 5);
  EXPECT_EQ(d.tp, 3);
  EXPECT_EQ(d.fp, 1);
  EXPECT_EQ(d.fn, 2);
  EXPECT_DOUBLE_EQ(d.moda, 0.4);
  EXPECT_NEAR(d.modp, 0.6, 1e-12);
  EXPECT_EQ(d.gt_frames_missing_from_run, 1);
  EXPECT_EQ(d.run_frames_without_gt, 1);
  ASSERT_EQ(report->detection_frames.size(), 3u);
  EXPECT_EQ(report->detection_frames[2].fn, 1);
  EXPECT_TRUE(HasNote(*report, "detections.jsonl: 1 ground-truth frames have no line; their 1 objects count as misses"));
  EXPECT_TRUE(HasNote(*report, "detections.jsonl: 1 lines are of frames without ground truth; not evaluated"));

  ASSERT_TRUE(report->tracking.has_value());
  EXPECT_EQ(report->tracking->tp, 5);
  EXPECT_DOUBLE_EQ(report->tracking->mota, 1.0);
  EXPECT_DOUBLE_EQ(report->tracking->idf1, 1.0);

  ASSERT_TRUE(report->footprint.has_value());
  EXPECT_EQ(report->footprint->frames, 1);
  EXPECT_EQ(report->footprint->tp, 1);
  EXPECT_EQ(report->footprint->fn, 1);
  EXPECT_EQ(report->footprint->tn, 1);
  EXPECT_EQ(report->footprint->computed_unseen, 1);
  EXPECT_DOUBLE_EQ(report->footprint->iou, 0.5);
  EXPECT_EQ(report->footprint->computed_frames_without_reference, 1);
  EXPECT_TRUE(HasNote(*report, "occupancy: 1 computed maps have no gt/footprint raster of their frame; not evaluated"));
  ASSERT_TRUE(report->hull.has_value());
  EXPECT_EQ(report->hull->frames, 2);
  EXPECT_DOUBLE_EQ(report->hull->iou, 0.6);
  EXPECT_DOUBLE_EQ(report->hull->precision, 1.0);
  EXPECT_DOUBLE_EQ(report->hull->recall, 0.6);

  const nlohmann::json j = EvaluationReportJson(*report);
  EXPECT_DOUBLE_EQ(j["detection"]["moda"].get<double>(), 0.4);
  EXPECT_EQ(j["detection"]["per_frame"].size(), 3u);
  EXPECT_EQ(j["detection"]["per_frame"][1], (nlohmann::json{{"frame", 1}, {"gt", 2}, {"detections", 2}, {"tp", 1}, {"fp", 1}, {"fn", 1}}));
  EXPECT_DOUBLE_EQ(j["occupancy"]["hull"]["iou"].get<double>(), 0.6);
  EXPECT_DOUBLE_EQ(j["tracking"]["idf1"].get<double>(), 1.0);
}

TEST_F(EvaluateRunTest, SkippingFramesMissingFromTheRunLeavesThemOut) {
  // Without frame 2: N_gt = 4, FN 1, FP 1: MODA = 1 - 2 / 4 = 0.5.
  EvalOptions options;
  options.skip_frames_missing_from_run = true;
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_, options);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->detection->frames, 2);
  EXPECT_EQ(report->detection->gt, 4);
  EXPECT_DOUBLE_EQ(report->detection->moda, 0.5);
  EXPECT_TRUE(HasNote(*report, "detections.jsonl: 1 ground-truth frames have no line; their 1 objects are left out "
                               "(skip_frames_missing_from_run)"));
}

TEST_F(EvaluateRunTest, RunWithoutTracksOrOccupancyEvaluatesDetectionsOnly) {
  fs::remove(run_ / "tracks.jsonl");
  fs::remove_all(run_ / "occupancy");
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_TRUE(report->detection.has_value());
  EXPECT_FALSE(report->tracking.has_value());
  EXPECT_FALSE(report->footprint.has_value());
  EXPECT_FALSE(report->hull.has_value());
  EXPECT_TRUE(HasNote(*report, "no tracks.jsonl in the run: tracking not evaluated"));
  EXPECT_TRUE(HasNote(*report, "no occupancy/NNNNNN.png in the run: occupancy not evaluated"));
  const nlohmann::json j = EvaluationReportJson(*report);
  EXPECT_TRUE(j["tracking"].is_null());
  EXPECT_TRUE(j["occupancy"]["footprint"].is_null());
}

TEST_F(EvaluateRunTest, RunWithoutChangesFolderHasNoChangesSection) {
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_FALSE(report->changes.has_value());
  EXPECT_FALSE(EvaluationReportJson(*report).contains("changes"));
  EXPECT_EQ(EvaluationReportText(*report).find("\nchanges"), std::string::npos);
}

// Change masks of one camera, two frames: frame 0 TP 1, FP 1, FN 1, TN 1, one shadow pixel
// the run calls changed; frame 1 (no shadow mask) TP 2, TN 2.
//   precision 3/4, recall 3/4, F1 3/4, shadow_changed_fraction 1.
void WriteChangeMasks(const fs::path& run, const fs::path& dataset) {
  WriteRaster(run / "changes" / "C1" / "000000.png", {"##", ".."}, {.free = 0, .occupied = 255, .unseen = 128});
  WriteRaster(run / "changes" / "C1" / "000001.png", {"##", ".."}, {.free = 0, .occupied = 255, .unseen = 128});
  WriteRaster(dataset / "gt" / "changes" / "C1" / "000000.png", {"#.", "#."}, {.free = 0, .occupied = 255, .unseen = 128});
  WriteRaster(dataset / "gt" / "changes" / "C1" / "000001.png", {"##", ".."}, {.free = 0, .occupied = 255, .unseen = 128});
  WriteRaster(dataset / "gt" / "shadows" / "C1" / "000000.png", {".#", ".."}, {.free = 0, .occupied = 255, .unseen = 128});
}

TEST_F(EvaluateRunTest, ChangeMasksAreScoredPerCameraAndOverall) {
  WriteChangeMasks(run_, dataset_);
  Context ctx(2);
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_, {}, ctx);
  ASSERT_TRUE(report.ok()) << report.status().message();
  ASSERT_TRUE(report->changes.has_value());
  EXPECT_EQ(report->changes->overall.frames, 2);
  EXPECT_DOUBLE_EQ(report->changes->overall.f1, 0.75);
  EXPECT_DOUBLE_EQ(report->changes->overall.shadow_changed_fraction, 1.0);

  const nlohmann::json j = EvaluationReportJson(*report);
  ASSERT_TRUE(j.contains("changes"));
  const nlohmann::json& c = j["changes"];
  for (const char* key : {"precision", "recall", "f1", "shadow_changed_fraction", "frames", "cameras"}) {
    EXPECT_TRUE(c.contains(key)) << key;
  }
  EXPECT_EQ(c["precision"], 0.75);
  EXPECT_EQ(c["recall"], 0.75);
  EXPECT_EQ(c["f1"], 0.75);
  EXPECT_EQ(c["shadow_changed_fraction"], 1.0);
  EXPECT_EQ(c["frames"], 2);
  ASSERT_EQ(c["cameras"].size(), 1u);
  const nlohmann::json& camera = c["cameras"][0];
  EXPECT_EQ(camera["id"], "C1");
  for (const char* key : {"precision", "recall", "f1", "shadow_changed_fraction"}) EXPECT_EQ(camera[key], c[key]) << key;
  EXPECT_EQ(nlohmann::json::parse(j.dump()), j);

  const std::string text = EvaluationReportText(*report);
  EXPECT_NE(text.find("\nchanges (pixels of the run's change masks against gt/changes)\n"
                      "  camera            frames   precision      recall          F1  shadow changed\n"
                      "  all                    2      0.7500      0.7500      0.7500          1.0000\n"
                      "  C1                     2      0.7500      0.7500      0.7500          1.0000\n"),
            std::string::npos)
      << text;
}

TEST_F(EvaluateRunTest, ChangeMasksWithoutShadowMasksHaveANullShadowFraction) {
  WriteChangeMasks(run_, dataset_);
  fs::remove_all(dataset_ / "gt" / "shadows");
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  const nlohmann::json j = EvaluationReportJson(*report);
  EXPECT_TRUE(j["changes"]["shadow_changed_fraction"].is_null());
  EXPECT_TRUE(j["changes"]["cameras"][0]["shadow_changed_fraction"].is_null());
  EXPECT_NE(EvaluationReportText(*report).find("  all                    2      0.7500      0.7500      0.7500               -\n"),
            std::string::npos);
}

TEST_F(EvaluateRunTest, ChangeMasksOfDifferentSizesAreAnError) {
  WriteChangeMasks(run_, dataset_);
  WriteRaster(dataset_ / "gt" / "changes" / "C1" / "000001.png", {"###"});
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(ExitCodeFor(report.status()), 2);
  EXPECT_EQ(report.status().message(), (dataset_ / "gt" / "changes" / "C1" / "000001.png").string() +
                                           ": expected 2x2 pixels like " +
                                           (run_ / "changes" / "C1" / "000001.png").string() + ", found 3x1");
}

TEST_F(EvaluateRunTest, ChangeMasksWithoutGroundTruthMasksAreNotEvaluated) {
  WriteChangeMasks(run_, dataset_);
  fs::remove_all(dataset_ / "gt" / "changes");
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_FALSE(report->changes.has_value());
  EXPECT_TRUE(HasNote(*report, "no gt/changes folder in the dataset: change masks not evaluated"));
}

TEST_F(EvaluateRunTest, RunWithOnlyChangeMasksIsEvaluated) {
  fs::remove(run_ / "detections.jsonl");
  fs::remove(run_ / "tracks.jsonl");
  fs::remove_all(run_ / "occupancy");
  WriteChangeMasks(run_, dataset_);
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_FALSE(report->detection.has_value());
  ASSERT_TRUE(report->changes.has_value());
  EXPECT_EQ(report->changes->overall.counts.tp, 3);
}

TEST_F(EvaluateRunTest, GroundTruthInTheGtFolderIsFoundToo) {
  fs::rename(dataset_ / "ground_truth.jsonl", dataset_ / "gt" / "ground_truth.jsonl");
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->gt_frames, 3);
}

TEST_F(EvaluateRunTest, ReferenceRasterOfAnotherSizeIsAnError) {
  WriteRaster(dataset_ / "gt" / "hull" / "000001.png", {"###", "###"});
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(report.status().message(), (dataset_ / "gt" / "hull" / "000001.png").string() + ": expected 2x2 cells like " +
                                           (run_ / "occupancy" / "000001.png").string() + ", found 3x2");
}

TEST_F(EvaluateRunTest, MalformedDetectionsFileIsAnErrorWithItsLine) {
  testing::WriteText(run_ / "detections.jsonl", "{\"frame\":0,\"time_s\":0,\"blobs\":[{\"x_m\":0}]}\n");
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().message(), (run_ / "detections.jsonl").string() + ":1: blobs[0].y_m: expected a number, found nothing");
}

TEST_F(EvaluateRunTest, DuplicateObjectIdInAGroundTruthFrameIsAnError) {
  std::vector<GroundTruthFrame> gt(1);
  gt[0].frame = 4;
  gt[0].objects = {Person(1, 0, 0), Person(1, 2, 0)};
  ASSERT_TRUE(WriteGroundTruth(dataset_ / "ground_truth.jsonl", gt).ok());
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().message(), (dataset_ / "ground_truth.jsonl").string() +
                                           ": frame 4: objects[].id: expected ids unique within a frame, found 1 twice");
}

TEST_F(EvaluateRunTest, RunFolderWithNothingToEvaluateIsNotFound) {
  const fs::path empty = dir_ / "empty-run";
  fs::create_directories(empty);
  const Result<EvaluationReport> report = EvaluateRun(dataset_, empty);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(report.status().message(),
            empty.string() + ": nothing to evaluate: expected detections.jsonl, tracks.jsonl, occupancy/NNNNNN.png or "
                             "changes/<camera>/NNNNNN.png");
}

TEST_F(EvaluateRunTest, DatasetWithoutGroundTruthIsNotFound) {
  const Result<EvaluationReport> report = EvaluateRun(dir_ / "nowhere", run_);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(report.status().message(),
            (dir_ / "nowhere").string() + ": no ground truth: expected ground_truth.jsonl or gt/ground_truth.jsonl");
}

TEST_F(EvaluateRunTest, InvalidOptionsAreRejectedBeforeAnyWork) {
  EvalOptions options;
  options.match_threshold_m = -1;
  const Result<EvaluationReport> report = EvaluateRun(dataset_, run_, options);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().message(), "match_threshold_m: expected a distance > 0 m, found -1");
}

// The same run against ground truth given in memory: the same detection and tracking figures
// (the dataset's frames), no occupancy (positions have no rasters), a name in the report.
TEST_F(EvaluateRunTest, GroundTruthGivenInMemoryScoresDetectionsAndTracksOnly) {
  const Result<std::vector<GroundTruthFrame>> gt = ReadGroundTruth(dataset_ / "ground_truth.jsonl");
  ASSERT_TRUE(gt.ok()) << gt.status().message();
  Context serial(1);
  const Result<EvaluationReport> report = EvaluateRunAgainst(*gt, "annotations", run_, {}, serial);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->dataset, "annotations");
  EXPECT_DOUBLE_EQ(report->detection->moda, 0.4);
  EXPECT_DOUBLE_EQ(report->tracking->mota, 1.0);
  EXPECT_FALSE(report->footprint.has_value());
  EXPECT_FALSE(report->hull.has_value());
  EXPECT_TRUE(HasNote(*report, "the ground truth is positions only: occupancy and change masks not evaluated"));

  std::vector<GroundTruthFrame> swapped = *gt;
  std::swap(swapped[0], swapped[1]);
  EXPECT_EQ(EvaluateRunAgainst(swapped, "annotations", run_, {}, serial).status().message(),
            "annotations: frames: expected increasing frame numbers, found 0 after 1");
  std::vector<GroundTruthFrame> twice = *gt;
  twice[1].objects[1].id = 1;
  EXPECT_EQ(EvaluateRunAgainst(twice, "annotations", run_, {}, serial).status().message(),
            "annotations: frame 1: objects[].id: expected ids unique within a frame, found 1 twice");
  const fs::path maps_only = dir_ / "maps-only";
  fs::create_directories(maps_only / "occupancy");
  fs::copy(run_ / "occupancy" / "000000.png", maps_only / "occupancy" / "000000.png");
  const Result<EvaluationReport> nothing = EvaluateRunAgainst(*gt, "annotations", maps_only, {}, serial);
  EXPECT_EQ(nothing.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(nothing.status().message(),
            maps_only.string() + ": nothing to evaluate against annotations: expected detections.jsonl or tracks.jsonl");
}

}  // namespace
}  // namespace occmap
