#include "occmap/eval/benchmark_annotations.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "occmap/sim/builtin_scenes.h"
#include "occmap/site/site.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;

AnnotatedPerson Person(BenchmarkFormat format, int64_t person_id, int64_t position_id, std::vector<AnnotatedBox> views = {}) {
  return {.person_id = person_id,
          .position_id = position_id,
          .position_m = BenchmarkPositionM(format, position_id),
          .views = std::move(views)};
}

bool HasNote(const EvaluationReport& report, const std::string& note) {
  const std::vector<std::string> notes = EvaluationNotes(report);
  return std::find(notes.begin(), notes.end(), note) != notes.end();
}

std::string Notes(const EvaluationReport& report) {
  std::string text;
  for (const std::string& n : EvaluationNotes(report)) text += n + "\n";
  return text;
}

// One detections.jsonl line per (frame, positions).
std::string DetectionsText(const std::vector<std::pair<int64_t, std::vector<Eigen::Vector2d>>>& frames) {
  std::string text;
  for (const auto& [frame, positions] : frames) {
    text += fmt::format("{{\"frame\":{},\"time_s\":{},\"blobs\":[", frame, 0.1 * static_cast<double>(frame));
    for (size_t k = 0; k < positions.size(); ++k) {
      text += fmt::format("{}{{\"x_m\":{:.17g},\"y_m\":{:.17g}}}", k > 0 ? "," : "", positions[k].x(), positions[k].y());
    }
    text += "]}\n";
  }
  return text;
}

std::vector<Eigen::Vector2d> Positions(const AnnotationFrame& frame) {
  std::vector<Eigen::Vector2d> out;
  for (const AnnotatedPerson& p : frame.people) out.push_back(p.position_m);
  return out;
}

TEST(BenchmarkPositionM, FollowsEachDatasetsFormula) {
  // WILDTRACK: X = -300 + 2.5 (id % 480), Y = -900 + 2.5 (id / 480) centimetres.
  EXPECT_EQ(BenchmarkPositionM(BenchmarkFormat::kWildtrack, 0), Eigen::Vector2d(-3.0, -9.0));
  EXPECT_NEAR(BenchmarkPositionM(BenchmarkFormat::kWildtrack, 479).x(), 8.975, 1e-12);
  EXPECT_NEAR(BenchmarkPositionM(BenchmarkFormat::kWildtrack, 480).y(), -8.975, 1e-12);
  EXPECT_NEAR(BenchmarkPositionM(BenchmarkFormat::kWildtrack, 456826).x(), 5.65, 1e-12);   // 456826 = 951 x 480 + 346
  EXPECT_NEAR(BenchmarkPositionM(BenchmarkFormat::kWildtrack, 456826).y(), 14.775, 1e-12);
  EXPECT_NEAR(BenchmarkPositionM(BenchmarkFormat::kWildtrack, 480 * 1440 - 1).y(), 26.975, 1e-12);
  // MultiviewX: x = (id % 1000) / 40, y = (id / 1000) / 40 metres.
  EXPECT_EQ(BenchmarkPositionM(BenchmarkFormat::kMultiviewX, 0), Eigen::Vector2d(0, 0));
  EXPECT_EQ(BenchmarkPositionM(BenchmarkFormat::kMultiviewX, 1001), Eigen::Vector2d(0.025, 0.025));
  EXPECT_EQ(BenchmarkPositionM(BenchmarkFormat::kMultiviewX, 639999), Eigen::Vector2d(24.975, 15.975));
  // The same numbers as the simulator's WILDTRACK scene, bit for bit.
  for (int64_t id : {0, 1, 479, 480, 123457, 456826, 691199}) {
    EXPECT_EQ(BenchmarkPositionM(BenchmarkFormat::kWildtrack, id), sim::WildtrackPositionM(id)) << id;
  }
  // The grids are those of sites/wildtrack.yaml and sites/multiviewx.yaml.
  const BenchmarkGrid& w = GridOf(BenchmarkFormat::kWildtrack);
  EXPECT_EQ(w.cells_x * w.cells_y, 691200);
  EXPECT_TRUE(BenchmarkPositionM(BenchmarkFormat::kWildtrack, 7 * 480 + 9)
                  .isApprox(Eigen::Vector2d(w.origin_x_m + 9 * w.cell_size_m, w.origin_y_m + 7 * w.cell_size_m), 1e-12));
  const BenchmarkGrid& x = GridOf(BenchmarkFormat::kMultiviewX);
  EXPECT_TRUE(BenchmarkPositionM(BenchmarkFormat::kMultiviewX, 7 * 1000 + 9)
                  .isApprox(Eigen::Vector2d(x.origin_x_m + 9 * x.cell_size_m, x.origin_y_m + 7 * x.cell_size_m), 1e-12));
}

TEST(ReadBenchmarkAnnotations, ReadsBackWhatWasWrittenInBothFormats) {
  for (BenchmarkFormat format : {BenchmarkFormat::kWildtrack, BenchmarkFormat::kMultiviewX}) {
    testing::TempDir dir;
    const std::vector<AnnotationFrame> frames = {
        {0, {Person(format, 3, 1000, {{0, 10, 20, 30, 40}, {1, -1, -1, -1, -1}}), Person(format, 7, 0)}},
        {5, {}},
        {10, {Person(format, 7, 639999, {{5, 0, 0, 1919, 1079}})}},
    };
    ASSERT_TRUE(WriteBenchmarkAnnotations(dir.path(), format, frames).ok());
    const fs::path first = dir / (format == BenchmarkFormat::kWildtrack ? "00000000.json" : "00000.json");
    EXPECT_TRUE(fs::is_regular_file(first)) << first;
    const Result<BenchmarkAnnotations> read = ReadBenchmarkAnnotations(dir.path());  // format from the names
    ASSERT_TRUE(read.ok()) << read.status().message();
    EXPECT_EQ(read->format, format);
    EXPECT_EQ(read->folder, dir.path());
    ASSERT_EQ(read->frames.size(), frames.size());
    for (size_t f = 0; f < frames.size(); ++f) {
      EXPECT_EQ(read->frames[f].number, frames[f].number);
      ASSERT_EQ(read->frames[f].people.size(), frames[f].people.size());
      for (size_t p = 0; p < frames[f].people.size(); ++p) {
        const AnnotatedPerson& a = read->frames[f].people[p];
        const AnnotatedPerson& b = frames[f].people[p];
        EXPECT_EQ(a.person_id, b.person_id);
        EXPECT_EQ(a.position_id, b.position_id);
        EXPECT_EQ(a.position_m, b.position_m);
        ASSERT_EQ(a.views.size(), b.views.size());
        for (size_t v = 0; v < a.views.size(); ++v) {
          EXPECT_EQ(a.views[v].view, b.views[v].view);
          EXPECT_EQ(a.views[v].xmin, b.views[v].xmin);
          EXPECT_EQ(a.views[v].ymin, b.views[v].ymin);
          EXPECT_EQ(a.views[v].xmax, b.views[v].xmax);
          EXPECT_EQ(a.views[v].ymax, b.views[v].ymax);
          EXPECT_EQ(a.views[v].visible(), b.views[v].xmin >= 0);
        }
      }
    }
  }
}

TEST(ParseAnnotationFile, ReadsTheDatasetsLayoutAndIgnoresUnknownKeys) {
  const Result<std::vector<AnnotatedPerson>> people = ParseAnnotationFile(
      R"([{"personID": 122, "positionID": 456826, "extra": true,
           "views": [{"viewNum": 0, "xmax": 1561, "xmin": 1510, "ymax": 299, "ymin": 139},
                     {"viewNum": 6, "xmax": -1, "xmin": -1, "ymax": -1, "ymin": -1},
                     {"viewNum": 2, "xmax": 40, "xmin": -549, "ymax": 2751, "ymin": -1}]},
          {"personID": 0, "positionID": 0}])",
      "a.json", BenchmarkFormat::kWildtrack);
  ASSERT_TRUE(people.ok()) << people.status().message();
  ASSERT_EQ(people->size(), 2u);
  EXPECT_EQ((*people)[0].person_id, 122);
  EXPECT_NEAR((*people)[0].position_m.x(), 5.65, 1e-12);
  ASSERT_EQ((*people)[0].views.size(), 3u);
  EXPECT_EQ((*people)[0].views[0].xmin, 1510);
  EXPECT_EQ((*people)[0].views[0].ymax, 299);
  EXPECT_TRUE((*people)[0].views[0].visible());
  EXPECT_EQ((*people)[0].views[1].view, 6);
  EXPECT_FALSE((*people)[0].views[1].visible());
  EXPECT_TRUE((*people)[0].views[2].visible());  // beyond the image, one corner -1: still a box
  EXPECT_EQ((*people)[0].views[2].xmin, -549);
  EXPECT_TRUE((*people)[1].views.empty());
  EXPECT_TRUE(ParseAnnotationFile("[]", "a.json", BenchmarkFormat::kMultiviewX)->empty());
}

struct MalformedCase {
  std::string text;
  BenchmarkFormat format;
  std::string message;
};

TEST(ParseAnnotationFile, MalformedInputGivesTheFileFieldExpectedAndFound) {
  const BenchmarkFormat w = BenchmarkFormat::kWildtrack, x = BenchmarkFormat::kMultiviewX;
  const std::vector<MalformedCase> cases = {
      {"[{\"personID\": 1,", w, "f.json: expected a JSON list of people, found invalid JSON at byte 17"},
      {"", w, "f.json: expected a JSON list of people, found invalid JSON at byte 1"},
      {"{\"personID\": 1}", w, "f.json: expected a list of people, found {\"personID\":1}"},
      {"[3]", w, "f.json: [0]: expected an object {\"personID\", \"positionID\", \"views\"}, found 3"},
      {"[{\"positionID\": 5}]", w, "f.json: [0].personID: expected an integer >= 0, found nothing"},
      {"[{\"personID\": \"7\", \"positionID\": 5}]", w, "f.json: [0].personID: expected an integer >= 0, found \"7\""},
      {"[{\"personID\": -1, \"positionID\": 5}]", w, "f.json: [0].personID: expected an integer >= 0, found -1"},
      {"[{\"personID\": 1.5, \"positionID\": 5}]", w, "f.json: [0].personID: expected an integer >= 0, found 1.5"},
      {"[{\"personID\": 1}]", w,
       "f.json: [0].positionID: expected an integer 0..691199 (a cell of WILDTRACK's 480 x 1440 grid), found nothing"},
      {"[{\"personID\": 1, \"positionID\": 691200}]", w,
       "f.json: [0].positionID: expected an integer 0..691199 (a cell of WILDTRACK's 480 x 1440 grid), found 691200"},
      {"[{\"personID\": 1, \"positionID\": -3}]", w,
       "f.json: [0].positionID: expected an integer 0..691199 (a cell of WILDTRACK's 480 x 1440 grid), found -3"},
      {"[{\"personID\": 1, \"positionID\": 640000}]", x,
       "f.json: [0].positionID: expected an integer 0..639999 (a cell of MultiviewX's 1000 x 640 grid), found 640000"},
      {"[{\"personID\": 1, \"positionID\": 18446744073709551615}]", x,
       "f.json: [0].positionID: expected an integer 0..639999 (a cell of MultiviewX's 1000 x 640 grid), found "
       "18446744073709551615"},
      {"[{\"personID\": 4, \"positionID\": 1}, {\"personID\": 2, \"positionID\": 1}, {\"personID\": 4, \"positionID\": 9}]",
       w, "f.json: [2].personID: expected ids unique within a file, found 4 again (also [0])"},
      {"[{\"personID\": 1, \"positionID\": 1, \"views\": {}}]", w, "f.json: [0].views: expected a list of boxes, found {}"},
      {"[{\"personID\": 1, \"positionID\": 1, \"views\": [7]}]", w,
       "f.json: [0].views[0]: expected an object {\"viewNum\", \"xmin\", \"ymin\", \"xmax\", \"ymax\"}, found 7"},
      {"[{\"personID\": 1, \"positionID\": 1, \"views\": [{\"viewNum\": 7, \"xmin\": 1, \"ymin\": 1, \"xmax\": 2, "
       "\"ymax\": 2}]}]",
       w, "f.json: [0].views[0].viewNum: expected an integer 0..6 (WILDTRACK has 7 views), found 7"},
      {"[{\"personID\": 1, \"positionID\": 1, \"views\": [{\"viewNum\": 6, \"xmin\": 1, \"ymin\": 1, \"xmax\": 2, "
       "\"ymax\": 2}]}]",
       x, "f.json: [0].views[0].viewNum: expected an integer 0..5 (MultiviewX has 6 views), found 6"},
      {"[{\"personID\": 1, \"positionID\": 1, \"views\": [{\"viewNum\": 0, \"xmin\": 1, \"ymin\": 1, \"xmax\": 2}]}]", w,
       "f.json: [0].views[0].ymax: expected an integer, found nothing"},
      {"[{\"personID\": 1, \"positionID\": 1, \"views\": [{\"viewNum\": 0, \"xmin\": 1, \"ymin\": 1.5, \"xmax\": 2, "
       "\"ymax\": 2}]}]",
       w, "f.json: [0].views[0].ymin: expected an integer, found 1.5"},
      {"[{\"personID\": 1, \"positionID\": 1, \"views\": [{\"viewNum\": 0, \"xmin\": 5, \"ymin\": 1, \"xmax\": 2, "
       "\"ymax\": 2}]}]",
       w, "f.json: [0].views[0]: expected xmin <= xmax and ymin <= ymax (or all -1: not in this view), found x 5..2, y 1..2"},
      {"[{\"personID\": 1, \"positionID\": \"a very long text that will be shortened in the message\"}]", x,
       "f.json: [0].positionID: expected an integer 0..639999 (a cell of MultiviewX's 1000 x 640 grid), found \"a very "
       "long text that will be shorte..."},
  };
  for (const MalformedCase& c : cases) {
    const Result<std::vector<AnnotatedPerson>> people = ParseAnnotationFile(c.text, "f.json", c.format);
    ASSERT_FALSE(people.ok()) << c.text;
    EXPECT_EQ(people.status().code(), StatusCode::kInvalidInput) << c.text;
    EXPECT_EQ(people.status().message(), c.message) << c.text;
  }
}

TEST(ReadBenchmarkAnnotations, BadFoldersAreErrorsNamingTheFolderOrFile) {
  testing::TempDir dir;
  const std::string d = dir.path().string();
  // Missing folder.
  Result<BenchmarkAnnotations> read = ReadBenchmarkAnnotations(dir / "none");
  EXPECT_EQ(read.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(read.status().message(), d + "/none: annotation folder not found");
  // Empty folder (other files are ignored).
  testing::WriteText(dir / "README.txt", "not an annotation");
  read = ReadBenchmarkAnnotations(dir.path());
  EXPECT_EQ(read.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(read.status().message(),
            d + ": expected annotation files named by their frame number (00000005.json), found none");
  // A file name that is not a number.
  testing::WriteText(dir / "00000000.json", "[]");
  testing::WriteText(dir / "frame_5.json", "[]");
  read = ReadBenchmarkAnnotations(dir.path());
  EXPECT_EQ(read.status().message(),
            d + "/frame_5.json: file name: expected the frame number in digits (00000005.json), found 'frame_5.json'");
  fs::remove(dir / "frame_5.json");
  testing::WriteText(dir / "-0000005.json", "[]");
  read = ReadBenchmarkAnnotations(dir.path());
  EXPECT_EQ(read.status().message(),
            d + "/-0000005.json: file name: expected the frame number in digits (00000005.json), found '-0000005.json'");
  fs::remove(dir / "-0000005.json");
  // Two files of one frame.
  testing::WriteText(dir / "0.json", "[]");
  read = ReadBenchmarkAnnotations(dir.path(), BenchmarkFormat::kWildtrack);
  EXPECT_EQ(read.status().message(), d + ": expected one file per frame, found 0.json and 00000000.json for frame 0");
  fs::remove(dir / "0.json");
  // File names of neither dataset's width: the format must be given.
  testing::WriteText(dir / "000005.json", "[]");
  read = ReadBenchmarkAnnotations(dir.path());
  EXPECT_EQ(read.status().message(),
            d + ": format: expected file names of 8 digits (WILDTRACK), 5 digits (MultiviewX) or 6 digits (EPFL terrace), found 6 digits "
                "(000005.json), 8 digits (00000000.json); give the format");
  read = ReadBenchmarkAnnotations(dir.path(), BenchmarkFormat::kMultiviewX);
  ASSERT_TRUE(read.ok()) << read.status().message();
  EXPECT_EQ(read->frames.size(), 2u);
  // A bad file names itself.
  testing::WriteText(dir / "000010.json", "[{\"personID\": 1}]");
  read = ReadBenchmarkAnnotations(dir.path(), BenchmarkFormat::kMultiviewX);
  EXPECT_EQ(read.status().message(),
            d + "/000010.json: [0].positionID: expected an integer 0..639999 (a cell of MultiviewX's 1000 x 640 grid), "
                "found nothing");
}

TEST(FindAnnotationFolder, TakesTheDatasetRootOrTheFolderItself) {
  testing::TempDir dir;
  EXPECT_FALSE(FindAnnotationFolder(dir.path()));
  EXPECT_FALSE(FindAnnotationFolder(dir / "none"));
  testing::WriteText(dir / "ground_truth.jsonl", "");
  EXPECT_FALSE(FindAnnotationFolder(dir.path()));
  fs::create_directories(dir / "annotations_positions");
  EXPECT_EQ(FindAnnotationFolder(dir.path()), dir / "annotations_positions");
  testing::WriteText(dir / "annotations_positions" / "00000.json", "[]");
  EXPECT_EQ(FindAnnotationFolder(dir / "annotations_positions"), dir / "annotations_positions");
}

TEST(BenchmarkMapping, MapsAnnotationNumbersToRunFramesAndBack) {
  const BenchmarkMapping images{.first_frame = 0, .step_num = 5, .step_den = 1};  // WILDTRACK's Image_subsets
  EXPECT_EQ(images.RunFrameOf(0), 0);
  EXPECT_EQ(images.RunFrameOf(1995), 399);
  EXPECT_EQ(images.RunFrameOf(7), std::nullopt);
  EXPECT_EQ(images.NumberOf(360), 1800);
  const BenchmarkMapping from_100{.first_frame = 100, .step_num = 1, .step_den = 1};  // 10 fps from frame 100
  EXPECT_EQ(from_100.RunFrameOf(95), std::nullopt);
  EXPECT_EQ(from_100.RunFrameOf(105), 5);
  const BenchmarkMapping video{.first_frame = 0, .step_num = 1, .step_den = 6};  // 60 fps video
  EXPECT_EQ(video.RunFrameOf(5), 30);
  EXPECT_EQ(video.NumberOf(30), 5);
  EXPECT_EQ(video.NumberOf(31), std::nullopt);
  EXPECT_EQ(video.StepText(), "1/6");
  EXPECT_EQ(images.StepText(), "5");
  EXPECT_TRUE(images.Validate().ok());
  EXPECT_EQ(BenchmarkMapping{.first_frame = -1}.Validate().message(),
            "first frame: expected an annotation number 0..999999999999, found -1");
  EXPECT_EQ((BenchmarkMapping{.first_frame = 0, .step_num = 0, .step_den = 1}.Validate().message()),
            "frame step: expected a whole number or a fraction P/Q with 1 <= P, Q <= 1000000, found 0/1");
}

TEST(ParseFrameStepAndRange, AcceptWholeNumbersFractionsAndRanges) {
  using Pair = std::pair<int64_t, int64_t>;
  EXPECT_EQ(*ParseFrameStep("5"), Pair(5, 1));
  EXPECT_EQ(*ParseFrameStep("1/6"), Pair(1, 6));
  const std::string step_expected =
      "--frame-step: expected a whole number or a fraction P/Q (5, 1/6) of whole numbers 1..1000000, found ";
  for (const char* bad : {"", "0", "-5", "2.5", "1/", "/6", "1/0", "5x", "1/6/2", "2000000"}) {
    const Result<std::pair<int64_t, int64_t>> step = ParseFrameStep(bad, "--frame-step");
    ASSERT_FALSE(step.ok()) << bad;
    EXPECT_EQ(step.status().message(), step_expected + "'" + bad + "'");
  }
  EXPECT_EQ(*ParseAnnotationRange("1800:1995"), Pair(1800, 1995));
  EXPECT_EQ(*ParseAnnotationRange("5:5"), Pair(5, 5));
  for (const char* bad : {"1800", "1995:1800", "a:b", ":5", "-5:10", "1:2:3"}) {
    const Result<std::pair<int64_t, int64_t>> range = ParseAnnotationRange(bad, "--annotation-range");
    ASSERT_FALSE(range.ok()) << bad;
    EXPECT_EQ(range.status().message(), std::string("--annotation-range: expected FIRST:LAST, two annotation numbers "
                                                    "0..999999999999 with FIRST <= LAST (1800:1995), found '") +
                                            bad + "'");
  }
  EXPECT_EQ(*ParseBenchmarkFormat("multiviewx"), BenchmarkFormat::kMultiviewX);
  EXPECT_EQ(ParseBenchmarkFormat("WILDTRACK", "--format").status().message(),
            "--format: expected wildtrack, multiviewx or terrace, found 'WILDTRACK'");
}

// A WILDTRACK-style dataset of four annotated frames (files 0, 5, 10, 15: one image each, run
// frames 0..3 by default):
//   file 0: persons 1 (id 0), 2 (id 48010);  file 5: persons 1, 2, 3;  file 10: person 2;
//   file 15: persons 1, 2.  N_gt = 8.
class BenchmarkRunTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const BenchmarkFormat w = BenchmarkFormat::kWildtrack;
    frames_ = {{0, {Person(w, 1, 0), Person(w, 2, 48010)}},
               {5, {Person(w, 1, 481), Person(w, 2, 48050), Person(w, 3, 200000)}},
               {10, {Person(w, 2, 48090)}},
               {15, {Person(w, 1, 1000), Person(w, 2, 48130)}}};
    ASSERT_TRUE(WriteBenchmarkAnnotations(dataset_ / "annotations_positions", w, frames_).ok());
    fs::create_directories(run_);
  }

  void WriteRun(const std::vector<std::pair<int64_t, std::vector<Eigen::Vector2d>>>& detections) {
    testing::WriteText(run_ / "detections.jsonl", DetectionsText(detections));
  }

  testing::TempDir dir_;
  fs::path dataset_ = dir_ / "Wildtrack";
  fs::path run_ = dir_ / "run";
  std::vector<AnnotationFrame> frames_;
};

TEST_F(BenchmarkRunTest, ARunOnTheAnnotatedPositionsScoresOne) {
  WriteRun({{0, Positions(frames_[0])}, {1, Positions(frames_[1])}, {2, Positions(frames_[2])}, {3, Positions(frames_[3])}});
  // Tracks: each person's annotated position under its own track id (personID + 100).
  std::string tracks;
  for (size_t f = 0; f < frames_.size(); ++f) {
    tracks += fmt::format("{{\"frame\":{},\"time_s\":0,\"tracks\":[", f);
    for (size_t k = 0; k < frames_[f].people.size(); ++k) {
      const AnnotatedPerson& p = frames_[f].people[k];
      tracks += fmt::format("{}{{\"id\":{},\"x_m\":{:.17g},\"y_m\":{:.17g}}}", k > 0 ? "," : "", p.person_id + 100,
                            p.position_m.x(), p.position_m.y());
    }
    tracks += "]}\n";
  }
  testing::WriteText(run_ / "tracks.jsonl", tracks);
  const Result<EvaluationReport> report = EvaluateRunOnBenchmark(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  ASSERT_TRUE(report->detection && report->tracking && report->annotations);
  EXPECT_EQ(report->dataset, (dataset_ / "annotations_positions").string());
  EXPECT_EQ(report->gt_frames, 4);
  EXPECT_EQ(report->detection->gt, 8);
  EXPECT_EQ(report->detection->tp, 8);
  EXPECT_DOUBLE_EQ(report->detection->moda, 1.0);
  EXPECT_DOUBLE_EQ(report->detection->modp, 1.0);
  EXPECT_DOUBLE_EQ(report->tracking->mota, 1.0);
  EXPECT_DOUBLE_EQ(report->tracking->idf1, 1.0);
  EXPECT_EQ(report->tracking->gt_trajectories, 3);
  EXPECT_EQ(report->tracking->id_switches, 0);
  const AnnotationSummary& a = *report->annotations;
  EXPECT_EQ(a.format, "wildtrack");
  EXPECT_EQ(a.files, 4);
  EXPECT_EQ(a.files_evaluated, 4);
  EXPECT_EQ(a.people_evaluated, 8);
  EXPECT_EQ(a.step_num, 5);
  EXPECT_EQ(a.range_first, 0);
  EXPECT_EQ(a.range_last, 15);
  EXPECT_FALSE(a.range_given);
  EXPECT_TRUE(HasNote(*report, "the ground truth is positions only: occupancy and change masks not evaluated"))
      << Notes(*report);
  // The JSON names each frame's annotation file and how the files were read.
  const nlohmann::json j = EvaluationReportJson(*report);
  EXPECT_EQ(j["detection"]["per_frame"][3]["frame"], 3);
  EXPECT_EQ(j["detection"]["per_frame"][3]["annotation_file"], 15);
  EXPECT_EQ(j["annotations"]["frame_step"], "5");
  EXPECT_EQ(j["annotations"]["range"], nlohmann::json::array({0, 15}));
  EXPECT_EQ(j["annotations"]["range_from"], "run");
  EXPECT_NE(EvaluationReportText(*report).find("ground truth: wildtrack annotations, 4 files (0..15); file = 0 + 5 x run frame"),
            std::string::npos)
      << EvaluationReportText(*report);
}

TEST_F(BenchmarkRunTest, KnownMissesAndFalsePositivesGiveTheirModa) {
  // Frame 1 misses person 3; frame 2 has a detection 0.6 m from person 2 (a miss and a false
  // positive); frame 3 adds a detection far from everyone; frame 0 is exact.
  //   FN = 1 + 1 = 2, FP = 1 + 1 = 2: MODA = 1 - 4 / 8 = 0.5; precision 6 / 8, recall 6 / 8.
  std::vector<Eigen::Vector2d> f1 = Positions(frames_[1]);
  f1.pop_back();
  std::vector<Eigen::Vector2d> f3 = Positions(frames_[3]);
  f3.emplace_back(8, 20);
  WriteRun({{0, Positions(frames_[0])},
            {1, f1},
            {2, {frames_[2].people[0].position_m + Eigen::Vector2d(0.6, 0)}},
            {3, f3}});
  const Result<EvaluationReport> report = EvaluateRunOnBenchmark(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->detection->fn, 2);
  EXPECT_EQ(report->detection->fp, 2);
  EXPECT_DOUBLE_EQ(report->detection->moda, 0.5);
  EXPECT_DOUBLE_EQ(report->detection->precision, 0.75);
  EXPECT_FALSE(report->tracking);  // no tracks.jsonl
}

TEST_F(BenchmarkRunTest, OnlyTheAnnotationsOfTheRunsFramesCountByDefault) {
  // A run over images 1..2 (`occmap run --start 1 --frames 2`): files 5 and 10 are evaluated,
  // 0 and 15 left out; a range given makes their people misses.
  WriteRun({{1, Positions(frames_[1])}, {2, Positions(frames_[2])}});
  Result<EvaluationReport> report = EvaluateRunOnBenchmark(dataset_, run_);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->detection->frames, 2);
  EXPECT_EQ(report->detection->gt, 4);
  EXPECT_DOUBLE_EQ(report->detection->moda, 1.0);
  EXPECT_EQ(report->annotations->files_outside_range, 2);
  EXPECT_TRUE(HasNote(*report, "annotations: 2 of 4 files are outside the numbers evaluated, 5..10 (the run's frames); left out"))
      << Notes(*report);

  BenchmarkEvalOptions all;
  all.annotation_range = {0, 15};
  report = EvaluateRunOnBenchmark(dataset_, run_, all);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->detection->gt, 8);
  EXPECT_EQ(report->detection->fn, 4);
  EXPECT_DOUBLE_EQ(report->detection->moda, 0.5);
  EXPECT_TRUE(report->annotations->range_given);
  EXPECT_TRUE(HasNote(*report, "detections.jsonl: 2 ground-truth frames have no line; their 4 objects count as misses"))
      << Notes(*report);
}

TEST_F(BenchmarkRunTest, ARunAtTenFramesASecondTakesFrameStepOne) {
  // The simulator's wildtrack scene from its --first-frame 5: run frame k is 10 fps frame 5 + k,
  // so files 5, 10, 15 are run frames 0, 5, 10; file 0 comes before the run.
  std::vector<std::pair<int64_t, std::vector<Eigen::Vector2d>>> run;
  for (int64_t k = 0; k <= 10; ++k) {
    run.emplace_back(k, k % 5 == 0 ? Positions(frames_[static_cast<size_t>(1 + k / 5)]) : std::vector<Eigen::Vector2d>{});
  }
  WriteRun(run);
  BenchmarkEvalOptions ten_fps;
  ten_fps.frame_step = {1, 1};
  ten_fps.first_frame = 5;
  const Result<EvaluationReport> report = EvaluateRunOnBenchmark(dataset_, run_, ten_fps);
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->detection->frames, 3);
  EXPECT_EQ(report->detection->gt, 6);
  EXPECT_DOUBLE_EQ(report->detection->moda, 1.0);
  EXPECT_EQ(report->detection->run_frames_without_gt, 8);
  EXPECT_EQ(report->annotations->files_outside_range, 1);
  const nlohmann::json j = EvaluationReportJson(*report);
  EXPECT_EQ(j["detection"]["per_frame"][1]["frame"], 5);
  EXPECT_EQ(j["detection"]["per_frame"][1]["annotation_file"], 10);

  // Files between run frames: a step of 10 skips files 5 and 15 of the range 0..20.
  BenchmarkEvalOptions every_other;
  every_other.frame_step = {10, 1};
  const Result<EvaluationReport> skipping = EvaluateRunOnBenchmark(dataset_, run_, every_other);
  ASSERT_TRUE(skipping.ok()) << skipping.status().message();
  EXPECT_EQ(skipping->annotations->files_between_frames, 2);
  EXPECT_EQ(skipping->annotations->files_evaluated, 2);  // 0 -> run frame 0, 10 -> run frame 1
}

TEST_F(BenchmarkRunTest, MistakesAreErrorsNamingWhatToCheck) {
  const std::string d = dataset_.string(), r = run_.string();
  // No run outputs.
  Result<EvaluationReport> report = EvaluateRunOnBenchmark(dataset_, run_);
  EXPECT_EQ(report.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(report.status().message(), r + ": nothing to evaluate against " + d +
                                           "/annotations_positions: expected detections.jsonl or tracks.jsonl");
  // No annotations.
  report = EvaluateRunOnBenchmark(run_, run_);
  EXPECT_EQ(report.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(report.status().message(),
            r + ": no annotations: expected an annotations_positions folder or files named by their frame number "
                "(00000005.json)");
  // A run whose frames hold no annotated frame (frames 1..4 at 10 fps).
  WriteRun({{1, {}}, {2, {}}, {3, {}}, {4, {}}});
  BenchmarkEvalOptions ten_fps;
  ten_fps.frame_step = {1, 1};
  report = EvaluateRunOnBenchmark(dataset_, run_, ten_fps);
  EXPECT_EQ(report.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(report.status().message(),
            r + ": expected annotated frames among the run's frames 1..4 (numbers 1..4 with annotation number = 0 + 1 x "
                "run frame), found none; " + d + "/annotations_positions has 4 files numbered 0..15: check the frame "
                "step and first frame");
  // A malformed run file, a malformed annotation file.
  testing::WriteText(run_ / "detections.jsonl", "{\"frame\": 1}\n");
  report = EvaluateRunOnBenchmark(dataset_, run_);
  EXPECT_EQ(report.status().message(), r + "/detections.jsonl:1: time_s: expected a number, found nothing");
  WriteRun({{0, {}}});
  testing::WriteText(dataset_ / "annotations_positions" / "00000005.json", "[{\"personID\": 1, \"positionID\": 1},");
  report = EvaluateRunOnBenchmark(dataset_, run_);
  EXPECT_EQ(report.status().message(),
            d + "/annotations_positions/00000005.json: expected a JSON list of people, found invalid JSON at byte 35");
  // Bad options.
  BenchmarkEvalOptions bad;
  bad.first_frame = -5;
  EXPECT_EQ(EvaluateRunOnBenchmark(dataset_, run_, bad).status().message(),
            "first frame: expected an annotation number 0..999999999999, found -5");
}

// The shared WILDTRACK annotations: the counts of the datasets README, the grid conversion
// through the site users run (sites/wildtrack.yaml: each position projects to its person's
// feet in the views), and a run on the annotations themselves scoring 1.
TEST(ReadBenchmarkAnnotations, ReadsTheSharedWildtrackAnnotations) {
  OCCMAP_REQUIRE_DATASETS(root);
  const fs::path folder = root / "wildtrack" / "annotations_positions";
  if (!fs::is_directory(folder)) GTEST_SKIP() << folder << " not found; skipped";
  const Result<BenchmarkAnnotations> read = ReadBenchmarkAnnotations(folder);
  ASSERT_TRUE(read.ok()) << read.status().message();
  EXPECT_EQ(read->format, BenchmarkFormat::kWildtrack);
  ASSERT_EQ(read->frames.size(), 400u);
  EXPECT_EQ(read->frames.front().number, 0);
  EXPECT_EQ(read->frames.back().number, 1995);
  size_t positions = 0, fewest = 1000, most = 0;
  std::set<int64_t> ids;
  for (size_t k = 0; k < read->frames.size(); ++k) {
    const AnnotationFrame& f = read->frames[k];
    EXPECT_EQ(f.number, static_cast<int64_t>(5 * k));
    positions += f.people.size();
    fewest = std::min(fewest, f.people.size());
    most = std::max(most, f.people.size());
    for (const AnnotatedPerson& p : f.people) {
      ids.insert(p.person_id);
      EXPECT_EQ(p.views.size(), 7u);
      EXPECT_GE(p.position_m.x(), -3.0);
      EXPECT_LT(p.position_m.x(), 9.0);
      EXPECT_GE(p.position_m.y(), -9.0);
      EXPECT_LT(p.position_m.y(), 27.0);
    }
  }
  EXPECT_EQ(positions, 9518u);
  EXPECT_EQ(fewest, 13u);
  EXPECT_EQ(most, 40u);
  // The first file's first person: positionID 456826 = 951 x 480 + 346: (565, 1477.5) cm.
  const AnnotatedPerson& first = read->frames[0].people[0];
  EXPECT_EQ(first.person_id, 122);
  EXPECT_EQ(first.position_id, 456826);
  EXPECT_NEAR(first.position_m.x(), 5.65, 1e-12);
  EXPECT_NEAR(first.position_m.y(), 14.775, 1e-12);

  // Positions are in the world of sites/wildtrack.yaml: projected into each view they land at
  // the bottom centre of the person's box (the README: a median of about 6 px).
  SiteLoadOptions load;
  load.data_root = root;
  const Result<Site> site = LoadSite(fs::path(OCCMAP_SOURCE_DIR) / "sites" / "wildtrack.yaml", load);
  ASSERT_TRUE(site.ok()) << site.status().message();
  ASSERT_EQ(site->cameras.size(), 7u);
  std::vector<double> errors_px;
  for (size_t k = 0; k < read->frames.size(); k += 10) {
    for (const AnnotatedPerson& p : read->frames[k].people) {
      for (const AnnotatedBox& b : p.views) {
        if (!b.visible()) continue;
        const auto pixel = site->cameras[static_cast<size_t>(b.view)].camera->Project({p.position_m.x(), p.position_m.y(), 0});
        ASSERT_TRUE(pixel.has_value());
        const Eigen::Vector2d feet(0.5 * static_cast<double>(b.xmin + b.xmax), static_cast<double>(b.ymax));
        errors_px.push_back((*pixel - feet).norm());
      }
    }
  }
  ASSERT_GT(errors_px.size(), 1000u);
  std::nth_element(errors_px.begin(), errors_px.begin() + static_cast<std::ptrdiff_t>(errors_px.size() / 2), errors_px.end());
  const double median_px = errors_px[errors_px.size() / 2];
  RecordProperty("reprojection_median_px", fmt::format("{:.2f}", median_px));
  EXPECT_LT(median_px, 10.0);

  // A run whose detections are the annotated positions, one image per file (run frame k is
  // file 5k): MODA 1 over every position.
  testing::TempDir run;
  std::vector<std::pair<int64_t, std::vector<Eigen::Vector2d>>> detections;
  for (size_t k = 0; k < read->frames.size(); ++k) detections.emplace_back(k, Positions(read->frames[k]));
  testing::WriteText(run / "detections.jsonl", DetectionsText(detections));
  const Result<EvaluationReport> report = EvaluateRunOnBenchmark(root / "wildtrack", run.path());
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->detection->frames, 400);
  EXPECT_EQ(report->detection->gt, 9518);
  EXPECT_DOUBLE_EQ(report->detection->moda, 1.0);
  EXPECT_EQ(report->annotations->files_outside_range, 0);
}

// The EPFL terrace's ids name the centres of 25 cm cells, and its files are the images' indices.
TEST(TerraceAnnotations, IdsNameCellCentresAndTheDatasetReads) {
  EXPECT_EQ(BenchmarkPositionM(BenchmarkFormat::kTerrace, 0), Eigen::Vector2d(-0.375, -1.375));
  EXPECT_EQ(BenchmarkPositionM(BenchmarkFormat::kTerrace, 639), Eigen::Vector2d(-0.5 + 0.25 * 9.5, -1.5 + 0.25 * 21.5));
  auto people = ParseAnnotationFile(R"([{"personID": 1, "positionID": 1320}])", "t/000008.json", BenchmarkFormat::kTerrace);
  ASSERT_FALSE(people.ok());
  EXPECT_NE(people.status().message().find("positionID"), std::string::npos) << people.status().message();
  EXPECT_EQ(*ParseBenchmarkFormat("terrace"), BenchmarkFormat::kTerrace);
  OCCMAP_REQUIRE_DATASETS(root);
  auto read = ReadBenchmarkAnnotations(root / "terrace-video" / "annotations_positions");
  ASSERT_TRUE(read.ok()) << read.status().message();
  EXPECT_EQ(read->format, BenchmarkFormat::kTerrace);  // told from the 6-digit names
  ASSERT_EQ(read->frames.size(), 291u);
  size_t people_total = 0;
  for (const AnnotationFrame& f : read->frames) people_total += f.people.size();
  EXPECT_EQ(people_total, 1355u);
  EXPECT_EQ(read->frames.front().number, 8);
}

// The terrace's personID is an index within each file: identities are not scored (they would
// count a switch at nearly every frame), detection is.
TEST(TerraceAnnotations, TracksAreNotScoredAgainstIdsThatAreNotIdentities) {
  testing::TempDir dir;
  const fs::path dataset = dir / "terrace", run = dir / "run";
  fs::create_directories(dataset / "annotations_positions");
  fs::create_directories(run);
  // Two people, their personIDs swapped between the files.
  testing::WriteText(dataset / "annotations_positions" / "000000.json",
                     R"([{"personID": 0, "positionID": 639}, {"personID": 1, "positionID": 100}])");
  testing::WriteText(dataset / "annotations_positions" / "000001.json",
                     R"([{"personID": 1, "positionID": 639}, {"personID": 0, "positionID": 100}])");
  const Eigen::Vector2d a = BenchmarkPositionM(BenchmarkFormat::kTerrace, 639);
  const Eigen::Vector2d b = BenchmarkPositionM(BenchmarkFormat::kTerrace, 100);
  testing::WriteText(run / "detections.jsonl", DetectionsText({{0, {a, b}}, {1, {a, b}}}));
  std::string tracks;
  for (int f = 0; f < 2; ++f) {
    tracks += fmt::format("{{\"frame\":{},\"time_s\":0,\"tracks\":[{{\"id\":1,\"x_m\":{},\"y_m\":{}}},"
                          "{{\"id\":2,\"x_m\":{},\"y_m\":{}}}]}}\n",
                          f, a.x(), a.y(), b.x(), b.y());
  }
  testing::WriteText(run / "tracks.jsonl", tracks);
  const Result<EvaluationReport> report = EvaluateRunOnBenchmark(dataset, run);
  ASSERT_TRUE(report.ok()) << report.status().message();
  ASSERT_TRUE(report->detection.has_value());
  EXPECT_DOUBLE_EQ(report->detection->moda, 1.0);
  EXPECT_FALSE(report->tracking.has_value());
  bool said = false;
  for (const std::string& note : report->notes) said |= note.find("tracking not evaluated") != std::string::npos;
  EXPECT_TRUE(said);
}

}  // namespace
}  // namespace occmap
