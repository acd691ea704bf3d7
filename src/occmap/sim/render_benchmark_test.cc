// Render-speed measurements (disabled by default; timings are not assertions). Run with
//   occmap_sim_test --gtest_also_run_disabled_tests --gtest_filter='*RenderSpeed*'
#include <gtest/gtest.h>

#include <chrono>
#include <ctime>
#include <cstdio>

#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/sim/gt_rasters.h"
#include "occmap/sim/renderer.h"
#include "occmap/util/testing.h"

namespace occmap::sim {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

void Measure(const Scene& scene, int threads, int64_t frames, const char* what, int64_t first = 0, bool shadow_mask = false) {
  Context ctx(threads);
  auto t0 = Clock::now();
  std::vector<CameraRenderer> renderers;
  for (size_t c = 0; c < scene.num_cameras(); ++c) renderers.emplace_back(scene, c, ctx);
  const double statics = Since(t0);
  RenderedView view;
  t0 = Clock::now();
  const std::clock_t cpu0 = std::clock();
  for (int64_t f = first; f < first + frames; ++f) {
    const SceneState state = scene.StateAt(f);
    for (const CameraRenderer& r : renderers) r.Render(state, ctx, &view, /*noise=*/true, shadow_mask);
  }
  const double render = Since(t0);
  // CPU time too: on a shared machine it varies much less than the wall time.
  const double cpu = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  std::printf("%s, %d thread(s): static scene %.2f s; %lld frames in %.2f s = %.3f s per frame (all %zu cameras), "
              "CPU %.3f s per frame\n",
              what, threads, statics, static_cast<long long>(frames), render, render / static_cast<double>(frames),
              scene.num_cameras(), cpu / static_cast<double>(frames));
}

TEST(SimBenchmark, DISABLED_LabRenderSpeed) {
  const Scene lab = Scene::Create(MakeLabSceneSpec({})).value();
  Measure(lab, 1, lab.num_frames(), "lab 4 x 640x480");
  Measure(lab, 2, lab.num_frames(), "lab 4 x 640x480");
  Context ctx(2);
  occmap::testing::TempDir dir;
  DatasetOptions options;
  options.out_dir = dir / "lab";
  const auto t0 = Clock::now();
  auto s = WriteDataset(lab, options, ctx);
  ASSERT_TRUE(s.ok()) << s.status().message();
  std::printf("lab dataset (PNG) on 2 threads: %.2f s (static %.2f, render %.2f, ground truth %.2f, write %.2f)\n",
              Since(t0), s->static_seconds, s->render_seconds, s->ground_truth_seconds, s->write_seconds);
}

TEST(SimBenchmark, DISABLED_WildtrackRenderSpeed) {
  OCCMAP_REQUIRE_DATASETS(root);
  WildtrackSceneOptions wt;
  wt.dataset_dir = root / "wildtrack";
  wt.first_frame = 500;
  for (double scale : {1.0, 0.5}) {
    BuiltinSceneOptions o;
    o.image_scale = scale;
    o.num_frames = 10;
    const Scene scene = Scene::Create(MakeWildtrackSceneSpec(o, wt).value()).value();
    Measure(scene, 2, 10, scale == 1.0 ? "wildtrack 7 x 1920x1080" : "wildtrack 7 x 960x540");
    Context ctx(2);
    std::vector<Image<uint8_t>> masks;
    for (size_t c = 0; c < scene.num_cameras(); ++c) masks.push_back(CameraRenderer(scene, c, ctx).floor_mask());
    const HullComputer hull(scene, masks, ctx);
    const auto t0 = Clock::now();
    for (int64_t f = 0; f < 10; ++f) (void)hull.Compute(scene.StateAt(f), ctx);
    std::printf("  ideal hull on 480 x 1440 cells: %.3f s per frame\n", Since(t0) / 10);
  }
}


TEST(SimBenchmark, DISABLED_PlazaRenderSpeed) {
  // 6 x 1280x720, 16 people, shadows (static and cast) on and off, 20 frames from the middle.
  const SceneSpec spec = MakePlazaSceneSpec({});
  SceneSpec flat = spec;
  flat.photometry.shadows = false;
  const Scene with = Scene::Create(spec).value(), without = Scene::Create(flat).value();
  Measure(without, 2, 20, "plaza 6 x 1280x720, no shadows", 300);
  Measure(with, 2, 20, "plaza 6 x 1280x720, shadows", 300);
  Measure(with, 2, 20, "plaza 6 x 1280x720, shadows and shadow masks", 300, true);
}

}  // namespace
}  // namespace occmap::sim
