#include "occmap/bench/bench.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "occmap/detect/change_detection.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/fusion.h"
#include "occmap/fusion/people_options.h"
#include "occmap/lut/column_lut.h"
#include "occmap/lut/test_scene.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/sim/scene.h"
#include "occmap/site/site.h"
#include "occmap/util/testing.h"

namespace occmap::bench {
namespace {

struct Frames {
  std::vector<Image<uint8_t>> frames, backgrounds;
  std::vector<ImageView<const uint8_t>> frame_views, background_views;
};

// Random backgrounds; frames differ by 0..2T so both sides of the threshold occur, with
// runs of changed pixels so that some cells are occupied.
Frames RandomFrames(const GroundLut& lut, int threshold, double changed_fraction, std::mt19937& rng) {
  Frames f;
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const ImageSize size = lut.image_size(n);
    Image<uint8_t> b(size.width, size.height), i(size.width, size.height);
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        b(x, y) = static_cast<uint8_t>(byte(rng));
        const int d = unit(rng) < changed_fraction ? threshold + 1 : static_cast<int>(rng() % (threshold + 1));
        i(x, y) = static_cast<uint8_t>(b(x, y) >= 128 ? b(x, y) - d : b(x, y) + d);
      }
    }
    f.frames.push_back(std::move(i));
    f.backgrounds.push_back(std::move(b));
  }
  for (size_t n = 0; n < f.frames.size(); ++n) {
    f.frame_views.push_back(f.frames[n].view());
    f.background_views.push_back(f.backgrounds[n].view());
  }
  return f;
}

// DetectChangesGray into the global change buffer, then Fusion (image-based, k = 0, all active).
OccupancyMap Reference(const GroundLut& lut, const Frames& f, int threshold, std::vector<uint8_t>& changes) {
  changes.assign(lut.total_pixels(), 0);
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const ImageSize size = lut.image_size(n);
    DetectChangesGray(f.frame_views[static_cast<size_t>(n)], f.background_views[static_cast<size_t>(n)], threshold,
                      ImageView<uint8_t>(changes.data() + lut.pixel_offset(n), size.width, size.height, size.width));
  }
  Fusion fusion(lut);
  OccupancyMap map;
  fusion.Fuse(changes, std::vector<bool>(static_cast<size_t>(lut.num_cameras()), true), FusionOptions{}, map);
  return map;
}

GroundLut RoomLut(const testing::SmallRoom& room) {
  std::vector<LutCameraInput> inputs;
  for (const auto& cam : room.cameras) inputs.push_back({&cam, {}});
  Context ctx(1);
  return BuildGroundLut(inputs, room.grid, {}, ctx).value();
}

TEST(Bench, PaperLoopAndFastFusionEqualTheReference) {
  testing::SmallRoom room(120, 90);
  const GroundLut lut = RoomLut(room);
  FastFusion fast(lut);
  std::mt19937 rng(5);
  Context ctx(2);
  int64_t occupied = 0;
  for (int trial = 0; trial < 8; ++trial) {
    const int threshold = 5 + static_cast<int>(rng() % 60);
    const Frames f = RandomFrames(lut, threshold, trial % 2 == 0 ? 0.97 : 0.5, rng);
    std::vector<uint8_t> changes;
    const OccupancyMap expected = Reference(lut, f, threshold, changes);
    occupied += expected.Count(CellState::kOccupied);
    std::vector<uint8_t> paper;
    PaperLoop(lut, f.frame_views, f.background_views, threshold, paper);
    ASSERT_EQ(paper.size(), expected.states().size() + 1);
    EXPECT_EQ(paper, PaperImageBasedLoop(lut, changes));
    for (size_t c = 0; c < expected.states().size(); ++c) {
      if (expected.states()[c] == CellState::kUnseen) continue;
      ASSERT_EQ(paper[c] != 0, expected.states()[c] == CellState::kOccupied) << "cell " << c;
    }
    OccupancyMap map;
    fast.Fuse(f.frame_views, f.background_views, threshold, ctx, map);
    EXPECT_EQ(map, expected);
  }
  EXPECT_GT(occupied, 0);
}

TEST(Bench, OpenCvVersionRuns) {
  testing::SmallRoom room(120, 90);
  const GroundLut lut = RoomLut(room);
  std::vector<const CameraModel*> cams;
  for (const auto& c : room.cameras) cams.push_back(&c);
  OpenCvFusion opencv(cams, room.grid, 0.0);
  std::mt19937 rng(6);
  const Frames f = RandomFrames(lut, 20, 0.0, rng);  // nothing changed: every seen cell free
  cv::Mat out;
  opencv.Fuse(f.frame_views, f.background_views, 20, out);
  ASSERT_EQ(out.rows, room.grid.cells_y);
  ASSERT_EQ(out.cols, room.grid.cells_x);
  // Every cell some camera sees is free (0); cells no camera sees stay 255.
  int free_cells = 0;
  for (int j = 0; j < out.rows; ++j) {
    for (int i = 0; i < out.cols; ++i) free_cells += out.at<uint8_t>(j, i) == 0;
  }
  EXPECT_GT(free_cells, room.grid.num_cells() / 2);
}

TEST(Bench, JsonHasTheRequiredKeys) {
  BenchOptions o;
  o.workload = "tiny";
  o.frames = 1;
  o.repetitions = 1;
  Context ctx(2);
  auto results = RunBench(o, ctx);
  ASSERT_TRUE(results.ok()) << results.status().ToString();
  ASSERT_EQ(results->workloads.size(), 1u);
  const nlohmann::json j = BenchJson(*results);
  for (const char* key : {"machine", "nproc", "end_to_end_vs_decode", "workloads"}) EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_TRUE(j["end_to_end_vs_decode"].is_null());  // end_to_end_frames = 0
  const nlohmann::json& w = j["workloads"][0];
  for (const char* key :
       {"speedup_vs_opencv", "speedup_vs_paper_loop", "paper_loop_pixels_per_second", "opencv_pixels_per_second",
        "fast_1_thread_pixels_per_second", "fast_all_threads_pixels_per_second", "threads", "machine",
        "lut_bytes", "fast_bytes", "lut_build_seconds", "fast_all_threads_vs_1_thread",
        "row_streaming_1_thread_pixels_per_second", "row_streaming_all_threads_pixels_per_second",
        "all_changed_1_thread_pixels_per_second", "all_changed_all_threads_pixels_per_second",
        "fast_probe_table_bytes", "fast_streaming_table_bytes", "probe_bytes_read_per_frame"}) {
    EXPECT_TRUE(w.contains(key)) << key;
  }
  EXPECT_GT(w["speedup_vs_opencv"].get<double>(), 0.0);
  EXPECT_GT(w["all_changed_all_threads_pixels_per_second"].get<double>(), 0.0);
  EXPECT_GT(w["primary_probes"].get<int64_t>(), 0);
  EXPECT_EQ(w["threads"].get<int>(), 2);
  EXPECT_FALSE(BenchTable(*results).empty());
}

TEST(Bench, EndToEndMeasuresRunAndDecode) {
  Context ctx(2);
  auto e = MeasureEndToEnd(/*frames=*/4, ctx);
  ASSERT_TRUE(e.ok()) << e.status().ToString();
  EXPECT_TRUE(e->measured);
  EXPECT_EQ(e->frames, 4);
  EXPECT_GT(e->run_fps, 0.0);
  EXPECT_GT(e->decode_fps, 0.0);
  // CPU per frame set over the steady sets (here from the second: a short pass), in the JSON.
  EXPECT_GT(e->decode_steady_cpu_ms_per_frame, 0.0);
  EXPECT_GT(e->run_steady_cpu_ms_per_frame, 0.0);
  BenchResults all;
  all.end_to_end = *e;
  const nlohmann::json j = BenchJson(all);
  EXPECT_TRUE(j["end_to_end_vs_decode"].is_number());
  EXPECT_DOUBLE_EQ(j["end_to_end"]["run_steady_cpu_ms_per_frame"].get<double>(), e->run_steady_cpu_ms_per_frame);
  EXPECT_DOUBLE_EQ(j["end_to_end"]["decode_steady_cpu_ms_per_frame"].get<double>(),
                   e->decode_steady_cpu_ms_per_frame);
  // Latency, arrival to outputs: the run's own histogram (RunSummary::latency), in text and JSON.
  EXPECT_GT(e->latency_p50_ms, 0.0);
  EXPECT_LE(e->latency_p50_ms, e->latency_p95_ms);
  EXPECT_LE(e->latency_p95_ms, e->latency_p99_ms);
  EXPECT_DOUBLE_EQ(j["end_to_end"]["latency_ms"]["p99"].get<double>(), e->latency_p99_ms);
  EXPECT_NE(BenchTable(all).find(fmt::format("p99 {:.1f} ms", e->latency_p99_ms)), std::string::npos);
}

TEST(Bench, WildtrackSkippedWithoutItsSiteFile) {
  BenchOptions o;
  o.workload = "wildtrack";
  o.wildtrack_site = "/nonexistent/wildtrack.yaml";
  Context ctx(1);
  auto results = RunBench(o, ctx);
  ASSERT_TRUE(results.ok());
  ASSERT_EQ(results->workloads.size(), 1u);
  EXPECT_TRUE(results->workloads[0].skipped);
  EXPECT_FALSE(results->workloads[0].note.empty());
  BenchOptions bad;
  bad.workload = "nope";
  EXPECT_FALSE(bad.Validate().ok());
}

// FastFusion on the real WILDTRACK tables (7 x 1920x1080 onto 480 x 1440), one random frame,
// 1 and 2 threads, against DetectChangesGray + Fusion. (Here rather than in the fusion module's
// tests, which cannot link the site loader.)
TEST(Bench, FastFusionIdenticalToReferenceOnWildtrack) {
  OCCMAP_REQUIRE_DATASETS(root);
  const std::filesystem::path site_file = std::filesystem::path(OCCMAP_SOURCE_DIR) / "sites" / "wildtrack.yaml";
  auto site = LoadSite(site_file, SiteLoadOptions{root});
  ASSERT_TRUE(site.ok()) << site.status().ToString();
  Context ctx(2);
  auto lut = BuildGroundLut(site->LutInputs(), site->grid, site->lut, ctx);
  ASSERT_TRUE(lut.ok());
  FastFusion fast(*lut);
  std::mt19937 rng(7);
  const int threshold = 25;
  const Frames f = RandomFrames(*lut, threshold, 0.97, rng);
  std::vector<uint8_t> changes;
  const OccupancyMap expected = Reference(*lut, f, threshold, changes);
  EXPECT_GT(expected.Count(CellState::kOccupied), 0);
  Context ctx1(1);
  for (Context* c : {&ctx1, &ctx}) {
    OccupancyMap map;
    fast.Fuse(f.frame_views, f.background_views, threshold, *c, map);
    EXPECT_EQ(map, expected) << c->num_threads() << " threads";
    OccupancyMap from_changes;
    fast.FuseChanges(changes, *c, from_changes);
    EXPECT_EQ(from_changes, expected) << c->num_threads() << " threads (changes)";
    OccupancyMap streamed;
    fast.FuseWith(FastFusion::Method::kRowStreaming, f.frame_views, f.background_views, threshold, *c, streamed);
    EXPECT_EQ(streamed, expected) << c->num_threads() << " threads (row streaming)";
  }
  // Few changes (the cell probes resolve their failures themselves), and every pixel changed
  // (the hand-over to row streaming).
  for (const double fraction : {0.1, 1.0}) {
    const Frames g = RandomFrames(*lut, threshold, fraction, rng);
    const OccupancyMap want = Reference(*lut, g, threshold, changes);
    for (Context* c : {&ctx1, &ctx}) {
      OccupancyMap map;
      fast.Fuse(g.frame_views, g.background_views, threshold, *c, map);
      EXPECT_EQ(map, want) << c->num_threads() << " threads, changed fraction " << fraction;
      fast.FuseChanges(changes, *c, map);
      EXPECT_EQ(map, want) << c->num_threads() << " threads, changed fraction " << fraction << " (changes)";
    }
  }
}

// FastFusion on frames rendered by the simulator (WILDTRACK trajectories: changes clustered on
// people, 13-15 % of the primary probes fail) against DetectChangesGray + Fusion, every path.
TEST(Bench, FastFusionIdenticalToReferenceOnRenderedWildtrackFrames) {
  OCCMAP_REQUIRE_DATASETS(root);
  const std::filesystem::path site_file = std::filesystem::path(OCCMAP_SOURCE_DIR) / "sites" / "wildtrack.yaml";
  auto site = LoadSite(site_file, SiteLoadOptions{root});
  ASSERT_TRUE(site.ok()) << site.status().ToString();
  Context ctx(2), ctx1(1);
  auto lut = BuildGroundLut(site->LutInputs(), site->grid, site->lut, ctx);
  ASSERT_TRUE(lut.ok());
  std::vector<ImageSize> sizes;
  for (int n = 0; n < lut->num_cameras(); ++n) sizes.push_back(lut->image_size(n));
  auto rendered = RenderWildtrackFrames(root / "wildtrack", /*count=*/1, sizes, ctx);
  ASSERT_TRUE(rendered.ok()) << rendered.status().ToString();
  Frames f;
  for (size_t n = 0; n < sizes.size(); ++n) {
    f.frame_views.push_back(rendered->frames[0][n].view());
    f.background_views.push_back(rendered->backgrounds[n].view());
  }
  const int threshold = 30;
  std::vector<uint8_t> changes;
  const OccupancyMap expected = Reference(*lut, f, threshold, changes);
  EXPECT_GT(expected.Count(CellState::kOccupied), 1000);
  FastFusion fast(*lut);
  for (Context* c : {&ctx1, &ctx}) {
    for (const double fallback : {0.15, 2.0, 0.0}) {
      fast.SetStreamingFallbackForTesting(fallback, 4096);
      OccupancyMap map;
      fast.Fuse(f.frame_views, f.background_views, threshold, *c, map);
      EXPECT_EQ(map, expected) << c->num_threads() << " threads, fallback " << fallback;
      if (fallback == 2.0) {
        EXPECT_GT(fast.last_frame_stats().primary_failed, 10000);
      }
      fast.FuseChanges(changes, *c, map);
      EXPECT_EQ(map, expected) << c->num_threads() << " threads, fallback " << fallback << " (changes)";
    }
    OccupancyMap streamed;
    fast.FuseWith(FastFusion::Method::kRowStreaming, f.frame_views, f.background_views, threshold, *c, streamed);
    EXPECT_EQ(streamed, expected) << c->num_threads() << " threads (row streaming)";
  }
}

TEST(Bench, JsonHasTheRenderedFramesRecord) {
  BenchResults all;
  WorkloadResult w;
  w.name = "wildtrack";
  w.rendered.measured = true;
  w.rendered.frames = 4;
  w.rendered.opencv_pps = 1e9;
  w.rendered.paper_pps = 1e9;
  w.rendered.fast_1_pps = 2e9;
  w.rendered.fast_all_pps = 4e9;
  all.workloads.push_back(w);
  WorkloadResult missing;
  missing.name = "wildtrack";
  missing.rendered.note = "skipped: no data";
  all.workloads.push_back(missing);
  const nlohmann::json j = BenchJson(all);
  const nlohmann::json& r = j["workloads"][0]["rendered"];
  for (const char* key : {"frames", "render_seconds", "changed_fraction", "paper_loop_pixels_per_second",
                          "opencv_pixels_per_second", "fast_1_thread_pixels_per_second",
                          "fast_all_threads_pixels_per_second", "fast_all_threads_vs_1_thread", "speedup_vs_opencv",
                          "speedup_vs_paper_loop", "primary_failure_fraction", "secondary_probes_per_frame",
                          "streamed_frame_fraction", "row_streaming_1_thread_pixels_per_second"}) {
    EXPECT_TRUE(r.contains(key)) << key;
  }
  EXPECT_DOUBLE_EQ(r["speedup_vs_opencv"].get<double>(), 4.0);
  EXPECT_DOUBLE_EQ(r["fast_all_threads_vs_1_thread"].get<double>(), 2.0);
  EXPECT_TRUE(j["workloads"][1]["rendered"]["skipped"].get<bool>());
  EXPECT_NE(BenchTable(all).find("rendered frames"), std::string::npos);
}

// Two people standing in the small room: every camera's frame shows their columns (the column
// table's trapezoids, 0.2 m wide) changed against a flat background, nothing else.
struct PeopleScene {
  std::vector<LutCameraInput> inputs;
  std::vector<Image<uint8_t>> frames, backgrounds;
  std::vector<std::vector<ImageView<const uint8_t>>> frame_views;  // [set][camera]
  std::vector<ImageView<const uint8_t>> background_views;
};

PeopleScene TwoPeople(const testing::SmallRoom& room, const PeopleOptions& people, Context& ctx) {
  PeopleScene p;
  for (const auto& cam : room.cameras) p.inputs.push_back({&cam, {}});
  const ColumnLut columns = BuildColumnLut(p.inputs, room.grid, 0.0, people.columns, {}, ctx).value();
  const FloorGrid& candidates = columns.candidates();
  const int64_t standing[] = {candidates.CellAt(1.2, 1.0), candidates.CellAt(2.8, 2.0)};
  for (int n = 0; n < columns.num_cameras(); ++n) {
    const ImageSize size = columns.image_size(n);
    Image<uint8_t> b(size.width, size.height, 60), f(size.width, size.height, 60);
    for (const int64_t k : standing) {
      const ColumnView& v = columns.view(n, k);
      if (!v.seen) continue;
      for (int y = std::max(0, static_cast<int>(v.top_row)); y <= std::min(size.height - 1, static_cast<int>(v.bottom_row));
           ++y) {
        const float t = v.bottom_row > v.top_row ? (static_cast<float>(y) - v.top_row) / (v.bottom_row - v.top_row) : 0;
        const float axis = v.axis_x_top + t * (v.axis_x_bottom - v.axis_x_top);
        const float half = 0.2f * (v.half_width_top + t * (v.half_width_bottom - v.half_width_top));
        for (int x = std::max(0, static_cast<int>(axis - half)); x <= std::min(size.width - 1, static_cast<int>(axis + half));
             ++x) {
          f(x, y) = 200;
        }
      }
    }
    p.frames.push_back(std::move(f));
    p.backgrounds.push_back(std::move(b));
  }
  p.frame_views.resize(2);  // the same set twice: two frames per repetition
  for (size_t n = 0; n < p.frames.size(); ++n) {
    for (auto& set : p.frame_views) set.push_back(p.frames[n].view());
    p.background_views.push_back(p.backgrounds[n].view());
  }
  return p;
}

TEST(Bench, PeopleRowsAreMeasuredOnATinyRoom) {
  testing::SmallRoom room(96, 72);
  PeopleOptions people;
  people.enabled = true;
  Context ctx(2);
  const PeopleScene scene = TwoPeople(room, people, ctx);
  auto rates = MeasurePeople(scene.inputs, room.grid, 0.0, {}, people, scene.frame_views, scene.background_views,
                             /*threshold=*/30, /*repetitions=*/1, ctx);
  ASSERT_TRUE(rates.ok()) << rates.status().ToString();
  EXPECT_TRUE(rates->measured);
  EXPECT_FALSE(rates->note.empty());
  EXPECT_GT(rates->candidates, 0);
  EXPECT_GT(rates->column_lut_bytes, 0);
  for (const double pps : {rates->change_test_1_pps, rates->column_1_pps, rates->column_all_pps, rates->explain_1_pps,
                           rates->explain_all_pps, rates->path_1_pps, rates->path_all_pps}) {
    EXPECT_GT(pps, 0.0);
  }
  EXPECT_GT(rates->occupied_candidates_per_frame, 0.0);
  EXPECT_GE(rates->people_per_frame, 1.0);

  // In the wildtrack workload's rendered record: the JSON and the table carry them.
  BenchResults all;
  WorkloadResult w;
  w.name = "wildtrack";
  w.camera_pixels = 4 * 96 * 72;
  w.rendered.measured = true;
  w.rendered.opencv_pps = 1e9;
  w.rendered.fast_all_pps = 4e9;
  w.rendered.people = *rates;
  w.rendered.people.column_all_pps = 2e9;
  all.workloads.push_back(w);
  const nlohmann::json j = BenchJson(all);
  const nlohmann::json& p = j["workloads"][0]["rendered"]["people"];
  for (const char* key : {"note", "candidates", "column_lut_build_seconds", "change_test_1_thread_pixels_per_second",
                          "column_fusion_1_thread_pixels_per_second", "column_fusion_all_threads_pixels_per_second",
                          "explain_1_thread_pixels_per_second", "explain_all_threads_pixels_per_second",
                          "path_1_thread_pixels_per_second", "path_all_threads_pixels_per_second",
                          "column_fusion_all_threads_ms_per_frame_set", "explain_all_threads_ms_per_frame_set",
                          "path_all_threads_ms_per_frame_set", "path_vs_opencv", "path_vs_fast_fusion",
                          "people_per_frame"}) {
    EXPECT_TRUE(p.contains(key)) << key;
  }
  EXPECT_TRUE(p["measured"].get<bool>());
  EXPECT_DOUBLE_EQ(p["column_fusion_vs_opencv"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(p["column_fusion_vs_fast_fusion"].get<double>(), 0.5);
  EXPECT_GT(p["explain_all_threads_ms_per_frame_set"].get<double>(), 0.0);
  const std::string table = BenchTable(all);
  for (const char* row : {"(j) column fusion 1 thread", "(k) explanation 1 thread", "(l) people path 1 thread"}) {
    EXPECT_NE(table.find(row), std::string::npos) << row;
  }
}

TEST(Bench, PeopleRowsNeedTheExplainDetectorAndMatchingFrames) {
  testing::SmallRoom room(96, 72);
  PeopleOptions people;
  people.enabled = true;
  Context ctx(1);
  const PeopleScene scene = TwoPeople(room, people, ctx);
  PeopleOptions column = people;
  column.detector = PeopleDetector::kColumn;
  auto r = MeasurePeople(scene.inputs, room.grid, 0.0, {}, column, scene.frame_views, scene.background_views, 30, 1, ctx);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "people bench: detector explain expected, found column");
  const std::vector<ImageView<const uint8_t>> three(scene.background_views.begin(), scene.background_views.end() - 1);
  r = MeasurePeople(scene.inputs, room.grid, 0.0, {}, people, scene.frame_views, three, 30, 1, ctx);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "people bench: 2 frame sets, 3 backgrounds for 4 cameras, 1 repetitions");
}

// The WILDTRACK scene as `occmap synth` writes it: the people detector on, and the floor AND
// measured beside it on the same files.
TEST(Bench, EndToEndOnWildtrackRunsThePeopleDetectorAndTheFloor) {
  OCCMAP_REQUIRE_DATASETS(root);
  Context ctx(2);
  auto e = MeasureEndToEnd(/*frames=*/3, ctx, root / "wildtrack");
  ASSERT_TRUE(e.ok()) << e.status().ToString();
  EXPECT_EQ(e->scene, "wildtrack");
  EXPECT_EQ(e->people_detector, "explain");
  EXPECT_NE(e->note.find("ViewExplainer"), std::string::npos) << e->note;
  EXPECT_GT(e->people_s, 0.0);
  EXPECT_GT(e->run_steady_cpu_ms_per_frame, 0.0);
  ASSERT_TRUE(e->floor.measured);
  EXPECT_NE(e->floor.fusion_path.find("FuseTolerant"), std::string::npos) << e->floor.fusion_path;
  EXPECT_GT(e->floor.run_fps, 0.0);
  EXPECT_GT(e->floor.run_steady_cpu_ms_per_frame, 0.0);
  EXPECT_GT(e->latency_p95_ms, 0.0);
}

// The end-to-end record with a people detector: both runs, and occmap's own CPU over the
// decoding's for each.
TEST(Bench, EndToEndJsonCarriesThePeopleAndFloorRuns) {
  BenchResults all;
  EndToEndResult& e = all.wildtrack_end_to_end;
  e.measured = true;
  e.scene = "wildtrack";
  e.people_detector = "explain";
  e.decode_steady_cpu_ms_per_frame = 80;
  e.run_steady_cpu_ms_per_frame = 128;
  e.people_s = 1.5;
  e.floor.measured = true;
  e.floor.run_steady_cpu_ms_per_frame = 120;
  e.floor.run_fps = 10;
  e.decode_fps = 20;
  const nlohmann::json j = BenchJson(all);
  const nlohmann::json& w = j["wildtrack_end_to_end"];
  EXPECT_EQ(w["people_detector"], "explain");
  EXPECT_DOUBLE_EQ(w["own_steady_cpu_ms_per_frame"].get<double>(), 48.0);
  EXPECT_DOUBLE_EQ(w["own_cpu_vs_decode"].get<double>(), 0.6);
  EXPECT_DOUBLE_EQ(w["run_stage_seconds"]["people"].get<double>(), 1.5);
  ASSERT_TRUE(w["floor_and"].is_object());
  EXPECT_DOUBLE_EQ(w["floor_and"]["own_steady_cpu_ms_per_frame"].get<double>(), 40.0);
  EXPECT_DOUBLE_EQ(w["floor_and"]["own_cpu_vs_decode"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(w["floor_and"]["run_vs_decode"].get<double>(), 0.5);
  EXPECT_TRUE(j["end_to_end"]["floor_and"].is_null());  // the lab: no people detector
  EXPECT_NE(BenchTable(all).find("floor AND (people detector off"), std::string::npos);
}



// The adaptive workload on a small rendered lab (quarter size, a few frames): the real-scene
// path, OpenCV's MOG2 and the paper's fused test are each measured on 1 and 2 threads, and the
// table and the JSON carry them. No timing is asserted.
TEST(Bench, AdaptiveWorkloadMeasuresTheRealScenePathMog2AndThePaperTest) {
  testing::TempDir dir;
  Context ctx(2);
  sim::BuiltinSceneOptions o;
  o.num_frames = 6;
  o.image_scale = 0.25;
  auto spec = sim::MakeBuiltinSceneSpec("lab", o);
  ASSERT_TRUE(spec.ok()) << spec.status().ToString();
  auto scene = sim::Scene::Create(std::move(*spec));
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  sim::DatasetOptions d;
  d.out_dir = dir.path() / "lab";
  d.change_masks = false;
  d.gt_rasters = false;
  auto written = sim::WriteDataset(*scene, d, ctx);
  ASSERT_TRUE(written.ok()) << written.status().ToString();

  BenchOptions b;
  b.workload = "adaptive";
  b.repetitions = 1;
  b.adaptive.datasets = {d.out_dir};
  b.adaptive.frames = 4;
  b.adaptive.repetitions = 1;
  auto results = RunBench(b, ctx);
  ASSERT_TRUE(results.ok()) << results.status().ToString();
  EXPECT_TRUE(results->workloads.empty());
  EXPECT_FALSE(results->end_to_end.measured);
  ASSERT_EQ(results->adaptive.size(), 1u);
  const AdaptiveResult& r = results->adaptive[0];
  EXPECT_EQ(r.name, "lab");
  EXPECT_EQ(r.cameras, 4);
  EXPECT_EQ(r.frames, 4);
  EXPECT_EQ(r.threads, 2);
  EXPECT_TRUE(r.chroma);
  for (double pps : {r.adaptive_1_pps, r.adaptive_all_pps, r.change_1_pps, r.update_1_pps, r.mog2_1_pps,
                     r.mog2_all_pps, r.paper_1_pps, r.paper_all_pps}) {
    EXPECT_GT(pps, 0.0);
  }
  const std::string table = BenchTable(*results);
  for (const char* row : {"adaptive: change test + upkeep, 1 thread", "adaptive: change test + upkeep, 2 threads",
                          "OpenCV MOG2 apply(), 1 thread", "OpenCV MOG2 apply(), 2 threads",
                          "paper's test fused (FastFusion), 1 thread", "paper's test fused (FastFusion), 2 threads"}) {
    EXPECT_NE(table.find(row), std::string::npos) << row << "\n" << table;
  }
  const nlohmann::json j = BenchJson(*results);
  ASSERT_EQ(j["adaptive"].size(), 1u);
  EXPECT_DOUBLE_EQ(j["adaptive"][0]["mog2_all_threads_pixels_per_second"].get<double>(), r.mog2_all_pps);
  EXPECT_DOUBLE_EQ(j["adaptive"][0]["paper_fused_1_thread_pixels_per_second"].get<double>(), r.paper_1_pps);
  EXPECT_DOUBLE_EQ(j["adaptive"][0]["adaptive_all_threads_pixels_per_second"].get<double>(), r.adaptive_all_pps);
}

TEST(Bench, AdaptiveWorkloadNeedsADatasetOfFrames) {
  BenchOptions b;
  b.workload = "adaptive";
  const Status none = b.Validate();
  EXPECT_FALSE(none.ok());
  EXPECT_NE(none.message().find("--dataset"), std::string::npos) << none.message();
  b.adaptive.datasets = {"/nonexistent/dataset"};
  Context ctx(1);
  auto results = RunBench(b, ctx);
  EXPECT_FALSE(results.ok());
  EXPECT_NE(results.status().message().find("/nonexistent/dataset"), std::string::npos) << results.status().message();
  b.adaptive.frames = 1;
  EXPECT_FALSE(b.Validate().ok());
}

}  // namespace
}  // namespace occmap::bench
