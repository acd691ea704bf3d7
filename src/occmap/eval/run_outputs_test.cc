#include "occmap/eval/run_outputs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "occmap/util/testing.h"

namespace occmap {
namespace {

TEST(ParseDetections, ReadsTheBlobsOfEachFrameAsOccmapRunWritesThem) {
  const std::string text =
      "{\"frame\":0,\"time_s\":0.0,\"blobs\":[]}\n"
      "\n"
      "{\"frame\":3,\"time_s\":0.12,\"blobs\":[{\"x_m\":1.5,\"y_m\":-2.25,\"area_m2\":0.12,\"cells\":192},"
      "{\"x_m\":0,\"y_m\":4,\"extra\":true}]}\r\n";
  const Result<std::vector<DetectionFrame>> frames = ParseDetections(text, "run/detections.jsonl");
  ASSERT_TRUE(frames.ok()) << frames.status().message();
  ASSERT_EQ(frames->size(), 2u);
  EXPECT_EQ((*frames)[0].frame, 0);
  EXPECT_TRUE((*frames)[0].blobs.empty());
  const DetectionFrame& f = (*frames)[1];
  EXPECT_EQ(f.frame, 3);
  EXPECT_DOUBLE_EQ(f.time_s, 0.12);
  ASSERT_EQ(f.blobs.size(), 2u);
  EXPECT_DOUBLE_EQ(f.blobs[0].x_m, 1.5);
  EXPECT_DOUBLE_EQ(f.blobs[0].y_m, -2.25);
  EXPECT_DOUBLE_EQ(f.blobs[0].area_m2, 0.12);
  EXPECT_EQ(f.blobs[0].cells, 192);
  EXPECT_TRUE(std::isnan(f.blobs[1].area_m2));  // optional fields absent: unknown
  EXPECT_EQ(f.blobs[1].cells, -1);
}

TEST(ParseDetections, EmptyTextHasNoFrames) {
  const Result<std::vector<DetectionFrame>> frames = ParseDetections("", "d.jsonl");
  ASSERT_TRUE(frames.ok());
  EXPECT_TRUE(frames->empty());
}

struct MalformedCase {
  std::string text;
  std::string message;
};

TEST(ParseDetections, MalformedLinesGiveTheFileLineFieldExpectedAndFound) {
  const std::string ok = "{\"frame\":1,\"time_s\":0,\"blobs\":[]}\n";
  const std::vector<MalformedCase> cases = {
      {"{\"frame\":1,", "d.jsonl:1: expected a JSON object, found invalid JSON at column 12"},
      {"[1, 2]", "d.jsonl:1: expected a JSON object, found [1,2]"},
      {"{\"time_s\":0,\"blobs\":[]}", "d.jsonl:1: frame: expected an integer >= 0, found nothing"},
      {"{\"frame\":1.5,\"time_s\":0,\"blobs\":[]}", "d.jsonl:1: frame: expected an integer >= 0, found 1.5"},
      {"{\"frame\":-2,\"time_s\":0,\"blobs\":[]}", "d.jsonl:1: frame: expected an integer >= 0, found -2"},
      {"{\"frame\":\"3\",\"time_s\":0,\"blobs\":[]}", "d.jsonl:1: frame: expected an integer >= 0, found \"3\""},
      {"{\"frame\":1,\"blobs\":[]}", "d.jsonl:1: time_s: expected a number, found nothing"},
      {"{\"frame\":1,\"time_s\":null,\"blobs\":[]}", "d.jsonl:1: time_s: expected a number, found null"},
      {"{\"frame\":1,\"time_s\":0}", "d.jsonl:1: blobs: expected a list, found nothing"},
      {"{\"frame\":1,\"time_s\":0,\"blobs\":{}}", "d.jsonl:1: blobs: expected a list, found {}"},
      {"{\"frame\":1,\"time_s\":0,\"blobs\":[{\"x_m\":1,\"y_m\":2},3]}",
       "d.jsonl:1: blobs[1]: expected an object {\"x_m\", \"y_m\", ...}, found 3"},
      {"{\"frame\":1,\"time_s\":0,\"blobs\":[{\"y_m\":2}]}", "d.jsonl:1: blobs[0].x_m: expected a number, found nothing"},
      {"{\"frame\":1,\"time_s\":0,\"blobs\":[{\"x_m\":\"1.5\",\"y_m\":2}]}",
       "d.jsonl:1: blobs[0].x_m: expected a number, found \"1.5\""},
      {"{\"frame\":1,\"time_s\":0,\"blobs\":[{\"x_m\":1,\"y_m\":[2]}]}", "d.jsonl:1: blobs[0].y_m: expected a number, found [2]"},
      {"{\"frame\":1,\"time_s\":0,\"blobs\":[{\"x_m\":1,\"y_m\":2,\"area_m2\":-0.5}]}",
       "d.jsonl:1: blobs[0].area_m2: expected a number >= 0, found -0.5"},
      {"{\"frame\":1,\"time_s\":0,\"blobs\":[{\"x_m\":1,\"y_m\":2,\"cells\":2.5}]}",
       "d.jsonl:1: blobs[0].cells: expected an integer >= 0, found 2.5"},
      {"{\"frame\":1,\"time_s\":0,\"blobs\":[{\"x_m\":\"a very long text that will be shortened in the message\",\"y_m\":2}]}",
       "d.jsonl:1: blobs[0].x_m: expected a number, found \"a very long text that will be shorte..."},
      // Line numbers count every line, blank ones included; frames must increase.
      {ok + "\n" + ok, "d.jsonl:3: frame: expected a frame after 1 (frames increase line by line), found 1"},
      {ok + "{\"frame\":0,\"time_s\":0,\"blobs\":[]}", "d.jsonl:2: frame: expected a frame after 1 (frames increase line by line), found 0"},
  };
  for (const MalformedCase& c : cases) {
    const Result<std::vector<DetectionFrame>> frames = ParseDetections(c.text, "d.jsonl");
    ASSERT_FALSE(frames.ok()) << c.text;
    EXPECT_EQ(frames.status().code(), StatusCode::kInvalidInput) << c.text;
    EXPECT_EQ(frames.status().message(), c.message) << c.text;
  }
}

TEST(ParseTracks, ReadsTheTracksOfEachFrame) {
  const std::string text =
      "{\"frame\":5,\"time_s\":0.2,\"tracks\":[{\"id\":3,\"x_m\":1.5,\"y_m\":2,\"vx_mps\":0.4,\"vy_mps\":-0.1,"
      "\"class\":\"person\"},{\"id\":4,\"x_m\":0,\"y_m\":0}]}\n"
      "{\"frame\":6,\"time_s\":0.24,\"tracks\":[]}\n";
  const Result<std::vector<TrackFrame>> frames = ParseTracks(text, "t.jsonl");
  ASSERT_TRUE(frames.ok()) << frames.status().message();
  ASSERT_EQ(frames->size(), 2u);
  const TrackFrame& f = (*frames)[0];
  EXPECT_EQ(f.frame, 5);
  ASSERT_EQ(f.tracks.size(), 2u);
  EXPECT_EQ(f.tracks[0].id, 3);
  EXPECT_DOUBLE_EQ(f.tracks[0].x_m, 1.5);
  EXPECT_DOUBLE_EQ(f.tracks[0].y_m, 2.0);
  EXPECT_DOUBLE_EQ(f.tracks[0].vx_mps, 0.4);
  EXPECT_DOUBLE_EQ(f.tracks[0].vy_mps, -0.1);
  EXPECT_EQ(f.tracks[0].object_class, "person");
  EXPECT_EQ(f.tracks[1].id, 4);
  EXPECT_DOUBLE_EQ(f.tracks[1].vx_mps, 0.0);
  EXPECT_EQ(f.tracks[1].object_class, "");
  EXPECT_TRUE((*frames)[1].tracks.empty());
}

TEST(ParseTracks, MalformedLinesGiveTheFileLineFieldExpectedAndFound) {
  const std::string head = "{\"frame\":1,\"time_s\":0,\"tracks\":";
  const std::vector<MalformedCase> cases = {
      {"{\"frame\":1,\"time_s\":0,\"blobs\":[]}", "t.jsonl:1: tracks: expected a list, found nothing"},
      {head + "[{\"x_m\":1,\"y_m\":2}]}", "t.jsonl:1: tracks[0].id: expected an integer, found nothing"},
      {head + "[{\"id\":1.5,\"x_m\":1,\"y_m\":2}]}", "t.jsonl:1: tracks[0].id: expected an integer, found 1.5"},
      {head + "[{\"id\":18446744073709551615,\"x_m\":1,\"y_m\":2}]}",
       "t.jsonl:1: tracks[0].id: expected an integer, found 18446744073709551615"},
      {head + "[{\"id\":1,\"x_m\":1,\"y_m\":2},{\"id\":1,\"x_m\":3,\"y_m\":4}]}",
       "t.jsonl:1: tracks[1].id: expected an id not used by another track of the frame, found 1 again"},
      {head + "[{\"id\":1,\"y_m\":2}]}", "t.jsonl:1: tracks[0].x_m: expected a number, found nothing"},
      {head + "[{\"id\":1,\"x_m\":1,\"y_m\":true}]}", "t.jsonl:1: tracks[0].y_m: expected a number, found true"},
      {head + "[{\"id\":1,\"x_m\":1,\"y_m\":2,\"vx_mps\":\"fast\"}]}",
       "t.jsonl:1: tracks[0].vx_mps: expected a number, found \"fast\""},
      {head + "[{\"id\":1,\"x_m\":1,\"y_m\":2,\"vy_mps\":null}]}", "t.jsonl:1: tracks[0].vy_mps: expected a number, found null"},
      {head + "[{\"id\":1,\"x_m\":1,\"y_m\":2,\"class\":7}]}", "t.jsonl:1: tracks[0].class: expected a text, found 7"},
      {head + "[[1,2]]}", "t.jsonl:1: tracks[0]: expected an object {\"id\", \"x_m\", \"y_m\", ...}, found [1,2]"},
      {"{\"frame\":2,\"time_s\":0,\"tracks\":[]}\n{\"frame\":2,\"time_s\":0,\"tracks\":[]}",
       "t.jsonl:2: frame: expected a frame after 2 (frames increase line by line), found 2"},
  };
  for (const MalformedCase& c : cases) {
    const Result<std::vector<TrackFrame>> frames = ParseTracks(c.text, "t.jsonl");
    ASSERT_FALSE(frames.ok()) << c.text;
    EXPECT_EQ(frames.status().message(), c.message) << c.text;
  }
}

TEST(ReadDetections, ReadsAFileAndNamesItInMessages) {
  testing::TempDir dir;
  testing::WriteText(dir / "detections.jsonl", "{\"frame\":0,\"time_s\":0,\"blobs\":[{\"x_m\":1,\"y_m\":2}]}\nnot json\n");
  const Result<std::vector<DetectionFrame>> frames = ReadDetections(dir / "detections.jsonl");
  ASSERT_FALSE(frames.ok());
  EXPECT_EQ(frames.status().message(),
            (dir / "detections.jsonl").string() + ":2: expected a JSON object, found invalid JSON at column 2");
}

TEST(ReadDetections, MissingFileIsNotFound) {
  EXPECT_EQ(ReadDetections("/nonexistent/detections.jsonl").status().code(), StatusCode::kNotFound);
  EXPECT_EQ(ReadTracks("/nonexistent/tracks.jsonl").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace occmap
