// The run's files against the eval readers (eval/run_outputs.h): what OutputFiles writes reads
// back the same, in both modes; live files hold whole lines while the run goes on, atomic ones
// appear only at Close.
#include "occmap/pipeline/output_files.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <csignal>
#include <random>

#include "occmap/eval/run_outputs.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

Site TinySite() {
  Site site;
  site.name = "tiny";
  site.grid.cells_x = 20;
  site.grid.cells_y = 10;
  site.grid.cell_size_m = 0.1;
  return site;
}

// Frame f: f % 4 detections and (f + 1) % 3 tracks at random positions, a zone event every
// third frame set.
std::vector<FrameRecord> RandomRecords(const Site& site, int frames) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> pos(-3.0, 12.0), v(-2.0, 2.0), area(0.0, 1.0);
  std::vector<FrameRecord> records;
  for (int f = 0; f < frames; ++f) {
    FrameRecord r;
    r.frame = f;
    r.time_s = 0.04 * f + 1.0 / 3.0;
    r.t_unix = 1.7e9 + r.time_s;
    r.active = {true, f % 2 == 0};
    r.map = OccupancyMap(site.grid);
    for (int k = 0; k < f % 4; ++k) {
      Detection d;
      d.x_m = pos(rng);
      d.y_m = pos(rng);
      d.area_m2 = area(rng);
      d.cells = 10 + k;
      r.detections.push_back(d);
    }
    for (int k = 0; k < (f + 1) % 3; ++k) {
      Track t;
      t.id = 1 + k;
      t.x_m = pos(rng);
      t.y_m = pos(rng);
      t.vx_mps = v(rng);
      t.vy_mps = v(rng);
      t.object_class = k == 0 ? "person" : "robot";
      r.tracks.push_back(t);
    }
    if (f % 3 == 0) r.zones.events.push_back({f, r.time_s, "door", 1, ZoneEventKind::kEnter, 1});
    MakeJsonLines(r, /*wall_clock_times=*/true);
    records.push_back(std::move(r));
  }
  return records;
}

OutputFilesOptions TextOnly(OutputMode mode) {
  OutputFilesOptions o;
  o.mode = mode;
  o.track = true;
  o.events = true;
  o.occupancy_video = false;
  return o;
}

SinkStart StartIn(const Site& site, const fs::path& out) {
  SinkStart start;
  start.site = &site;
  start.out_dir = out;
  start.camera_ids = {"c1", "c2"};
  return start;
}

void ExpectReadsBack(const fs::path& out, const std::vector<FrameRecord>& records) {
  auto detections = ReadDetections(out / "detections.jsonl");
  ASSERT_TRUE(detections.ok()) << detections.status().message();
  auto tracks = ReadTracks(out / "tracks.jsonl");
  ASSERT_TRUE(tracks.ok()) << tracks.status().message();
  ASSERT_EQ(detections->size(), records.size());
  ASSERT_EQ(tracks->size(), records.size());
  for (size_t f = 0; f < records.size(); ++f) {
    const FrameRecord& r = records[f];
    const DetectionFrame& d = (*detections)[f];
    EXPECT_EQ(d.frame, r.frame);
    EXPECT_NEAR(d.time_s, r.time_s, 0.5e-6);
    ASSERT_EQ(d.blobs.size(), r.detections.size());
    for (size_t k = 0; k < d.blobs.size(); ++k) {
      EXPECT_NEAR(d.blobs[k].x_m, r.detections[k].x_m, 0.5e-4);
      EXPECT_NEAR(d.blobs[k].y_m, r.detections[k].y_m, 0.5e-4);
      EXPECT_NEAR(d.blobs[k].area_m2, r.detections[k].area_m2, 0.5e-5);
      EXPECT_EQ(d.blobs[k].cells, r.detections[k].cells);
    }
    const TrackFrame& t = (*tracks)[f];
    EXPECT_EQ(t.frame, r.frame);
    ASSERT_EQ(t.tracks.size(), r.tracks.size());
    for (size_t k = 0; k < t.tracks.size(); ++k) {
      EXPECT_EQ(t.tracks[k].id, r.tracks[k].id);
      EXPECT_NEAR(t.tracks[k].x_m, r.tracks[k].x_m, 0.5e-4);
      EXPECT_NEAR(t.tracks[k].vy_mps, r.tracks[k].vy_mps, 0.5e-4);
      EXPECT_EQ(t.tracks[k].object_class, r.tracks[k].object_class);
    }
  }
}

TEST(OutputFiles, WhatItWritesTheEvalReadersReadBackInBothModes) {
  const Site site = TinySite();
  const std::vector<FrameRecord> records = RandomRecords(site, 30);
  for (const OutputMode mode : {OutputMode::kLive, OutputMode::kAtomic}) {
    testing::TempDir dir;
    OutputFiles files(TextOnly(mode));
    ASSERT_TRUE(files.Open(StartIn(site, dir.path())).ok());
    for (const FrameRecord& r : records) ASSERT_TRUE(files.Consume(r, RunStats{}).ok());
    ASSERT_TRUE(files.Close(RunStats{}).ok());
    ExpectReadsBack(dir.path(), records);
    const std::string events = *ReadFileToString(dir.path() / "events.jsonl");
    EXPECT_EQ(std::count(events.begin(), events.end(), '\n'), 10) << ToString(mode);
    const std::string mot = *ReadFileToString(dir.path() / "tracks_mot.csv");
    EXPECT_EQ(mot.substr(0, 2), "1,") << "MOTChallenge frames count from 1";
    EXPECT_EQ(files.written().size(), 4u);
  }
}

// Every JSON line starts with the wall-clock time of its frame set; the readers skip it.
TEST(OutputFiles, EveryJsonLineCarriesTheWallClockTime) {
  EXPECT_EQ(WithTUnix(R"({"frame":1})", 1700000000.25), R"({"t_unix":1700000000.250000,"frame":1})");
  EXPECT_EQ(WithTUnix("{}", 1.5), R"({"t_unix":1.500000})");
  const Site site = TinySite();
  const std::vector<FrameRecord> records = RandomRecords(site, 6);
  testing::TempDir dir;
  OutputFiles files(TextOnly(OutputMode::kLive));
  ASSERT_TRUE(files.Open(StartIn(site, dir.path())).ok());
  for (const FrameRecord& r : records) ASSERT_TRUE(files.Consume(r, RunStats{}).ok());
  ASSERT_TRUE(files.Close(RunStats{}).ok());
  for (const char* name : {"detections.jsonl", "tracks.jsonl", "events.jsonl"}) {
    const std::string text = *ReadFileToString(dir.path() / name);
    size_t lines = 0;
    for (size_t at = 0; at < text.size(); at = text.find('\n', at) + 1, ++lines) {
      EXPECT_EQ(text.compare(at, 11, R"({"t_unix":1)"), 0) << name << ": " << text.substr(at, 40);
    }
    EXPECT_GT(lines, 0u) << name;
  }
  ExpectReadsBack(dir.path(), records);
}

// Live: after every frame set the files hold exactly the lines of the frame sets so far, each
// whole, readable by the eval readers while the run goes on.
TEST(OutputFiles, LiveFilesHoldWholeLinesAfterEveryFrameSet) {
  const Site site = TinySite();
  const std::vector<FrameRecord> records = RandomRecords(site, 8);
  testing::TempDir dir;
  OutputFiles files(TextOnly(OutputMode::kLive));
  ASSERT_TRUE(files.Open(StartIn(site, dir.path())).ok());
  for (size_t f = 0; f < records.size(); ++f) {
    ASSERT_TRUE(files.Consume(records[f], RunStats{}).ok());
    const std::string text = *ReadFileToString(dir.path() / "detections.jsonl");
    EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), static_cast<long>(f + 1));
    EXPECT_EQ(text.back(), '\n');
    auto read = ReadDetections(dir.path() / "detections.jsonl");
    ASSERT_TRUE(read.ok()) << read.status().message();
    EXPECT_EQ(read->back().frame, static_cast<int64_t>(f));
  }
  // Abandoned (a failed or killed run): what was written stays.
  files.Abandon();
  auto read = ReadDetections(dir.path() / "detections.jsonl");
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->size(), records.size());
}

// Atomic: nothing under a final name before Close; abandoned, nothing at all.
TEST(OutputFiles, AtomicFilesAppearAtCloseAndNotAtAllWhenAbandoned) {
  const Site site = TinySite();
  const std::vector<FrameRecord> records = RandomRecords(site, 4);
  testing::TempDir dir;
  {
    OutputFiles files(TextOnly(OutputMode::kAtomic));
    ASSERT_TRUE(files.Open(StartIn(site, dir.path())).ok());
    for (const FrameRecord& r : records) ASSERT_TRUE(files.Consume(r, RunStats{}).ok());
    EXPECT_FALSE(fs::exists(dir.path() / "detections.jsonl"));
    files.Abandon();
  }
  for (const auto& e : fs::directory_iterator(dir.path())) ADD_FAILURE() << "left behind: " << e.path();
}

// A fragmented MP4 written in place plays while it is written: after the first two-second
// fragment the file is there and decodes.
TEST(OutputFiles, LiveVideoIsWrittenInPlace) {
  const Site site = TinySite();
  const std::vector<FrameRecord> records = RandomRecords(site, 45);
  testing::TempDir dir;
  OutputFilesOptions o = TextOnly(OutputMode::kLive);
  o.occupancy_video = true;
  OutputFiles files(o);
  SinkStart start = StartIn(site, dir.path());
  start.fps = 10;
  ASSERT_TRUE(files.Open(start).ok());
  for (const FrameRecord& r : records) ASSERT_TRUE(files.Consume(r, RunStats{}).ok());
  EXPECT_TRUE(fs::exists(dir.path() / "occupancy.mp4"));
  EXPECT_GT(fs::file_size(dir.path() / "occupancy.mp4"), 0u);
  ASSERT_TRUE(files.Close(RunStats{}).ok());
  for (const auto& e : fs::directory_iterator(dir.path())) {
    EXPECT_NE(e.path().filename().string().rfind(".tmp-", 0), 0u) << e.path();
  }
}

// Files cannot grow past `bytes` while it lives (RLIMIT_FSIZE, SIGXFSZ ignored): a write across
// the limit is short and the next fails (EFBIG), as a full disk gives a short write, then ENOSPC.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(uint64_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &old_);
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit = old_;
    limit.rlim_cur = static_cast<rlim_t>(bytes);
    EXPECT_EQ(::setrlimit(RLIMIT_FSIZE, &limit), 0);
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &old_);
    std::signal(SIGXFSZ, old_handler_);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;

 private:
  rlimit old_{};
  void (*old_handler_)(int) = SIG_DFL;
};

// Frame sets with 30 tracks each: tracks.jsonl grows fastest.
std::vector<FrameRecord> CrowdedRecords(const Site& site, int frames) {
  std::vector<FrameRecord> records = RandomRecords(site, frames);
  for (FrameRecord& r : records) {
    r.tracks.clear();
    for (int k = 0; k < 30; ++k) {
      Track t;
      t.id = 1 + k;
      t.x_m = 0.1 * k + 0.01 * static_cast<double>(r.frame);
      t.y_m = 0.2 * k;
      t.object_class = "person";
      r.tracks.push_back(t);
    }
    MakeJsonLines(r, /*wall_clock_times=*/true);
  }
  return records;
}

// Issue 39: on a full disk a live run ended with a partial last line in detections.jsonl,
// tracks.jsonl and tracks_mot.csv, and the files disagreed by a line.
TEST(OutputFiles, AWriteThatFailsPartWayLeavesEveryLineFileWholeAtTheSameFrameSet) {
  const Site site = TinySite();
  const std::vector<FrameRecord> records = CrowdedRecords(site, 5);
  testing::TempDir dir;
  OutputFiles files(TextOnly(OutputMode::kLive));
  ASSERT_TRUE(files.Open(StartIn(site, dir.path())).ok());
  for (int f = 0; f < 3; ++f) ASSERT_TRUE(files.Consume(records[f], RunStats{}).ok());
  const uint64_t tracks_size = fs::file_size(dir.path() / "tracks.jsonl");
  const uint64_t line = records[3].tracks_line.size();
  Status s;
  {
    const FileSizeLimit limit(tracks_size + line / 2);  // frame 3's tracks line: half of it fits
    s = files.Consume(records[3], RunStats{});
  }
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kIoError);
  EXPECT_NE(s.message().find("tracks.jsonl': write failed: File too large: frame 3 not written; the line files end at "
                             "the frame set before it, whole"),
            std::string::npos)
      << s.message();
  files.Abandon();
  for (const char* name : {"detections.jsonl", "tracks.jsonl", "events.jsonl"}) {
    const std::string text = *ReadFileToString(dir.path() / name);
    ASSERT_FALSE(text.empty()) << name;
    EXPECT_EQ(text.back(), '\n') << name;
  }
  auto detections = ReadDetections(dir.path() / "detections.jsonl");
  ASSERT_TRUE(detections.ok()) << detections.status().message();
  auto tracks = ReadTracks(dir.path() / "tracks.jsonl");
  ASSERT_TRUE(tracks.ok()) << tracks.status().message();
  EXPECT_EQ(detections->size(), 3u);
  EXPECT_EQ(tracks->size(), 3u);
  const std::string mot = *ReadFileToString(dir.path() / "tracks_mot.csv");
  EXPECT_EQ(std::count(mot.begin(), mot.end(), '\n'), 3 * 30);
  EXPECT_EQ(mot.back(), '\n');
}

// Issue 39: with --atomic-outputs a run whose video failed at its end (no space left) still
// committed the other outputs.
TEST(OutputFiles, AtomicOutputsWhoseVideoFailsAtCloseAreAllLeftOut) {
  const Site site = TinySite();
  const std::vector<FrameRecord> records = RandomRecords(site, 45);
  testing::TempDir dir;
  OutputFilesOptions o = TextOnly(OutputMode::kAtomic);
  o.occupancy_video = true;
  OutputFiles files(o);
  SinkStart start = StartIn(site, dir.path());
  start.fps = 10;
  ASSERT_TRUE(files.Open(start).ok());
  for (const FrameRecord& r : records) ASSERT_TRUE(files.Consume(r, RunStats{}).ok());
  uint64_t video_size = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) {
    if (e.path().filename().string().find("occupancy.mp4") != std::string::npos) video_size = fs::file_size(e.path());
  }
  Status closed;
  {
    const FileSizeLimit limit(video_size + 16);  // the video's end (its index) does not fit
    closed = files.Close(RunStats{});
  }
  ASSERT_FALSE(closed.ok());
  EXPECT_NE(closed.message().find("occupancy.mp4"), std::string::npos) << closed.message();
  EXPECT_NE(closed.message().find("(atomic outputs: none written)"), std::string::npos) << closed.message();
  EXPECT_TRUE(files.written().empty());
  for (const auto& e : fs::directory_iterator(dir.path())) ADD_FAILURE() << "left behind: " << e.path();
}

}  // namespace
}  // namespace occmap
