// Google Benchmark micro-benchmarks of the per-frame kernels, each beside its reference, on
// the built-in lab site (four 640x480 cameras onto 450 x 325 cells of 2 cm):
//   build/release/src/occmap/occmap_micro_benchmark [--benchmark_filter=Fusion]
// Report ratios between rows of one run, not absolute times (shared machines are noisy).
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "occmap/bench/bench.h"
#include "occmap/detect/change_detection.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/fusion.h"
#include "occmap/site/demo_scene.h"

namespace occmap {
namespace {

// The lab's tables and one frame per camera with about 10% of its pixels changed.
struct LabFrames {
  Site site = MakeDemoLabSite();
  Context ctx{1};
  GroundLut lut;
  std::vector<Image<uint8_t>> frames, backgrounds;
  std::vector<ImageView<const uint8_t>> frame_views, background_views;
  std::vector<uint8_t> changes;

  LabFrames() {
    lut = BuildGroundLut(site.LutInputs(), site.grid, site.lut, ctx).value();
    std::mt19937 rng(5);
    for (int n = 0; n < lut.num_cameras(); ++n) {
      const ImageSize s = lut.image_size(n);
      Image<uint8_t> bg(s.width, s.height), frame(s.width, s.height);
      for (int y = 0; y < s.height; ++y) {
        for (int x = 0; x < s.width; ++x) {
          bg(x, y) = static_cast<uint8_t>(rng() % 200);
          frame(x, y) = rng() % 10 == 0 ? static_cast<uint8_t>(bg(x, y) + 50) : bg(x, y);
        }
      }
      backgrounds.push_back(std::move(bg));
      frames.push_back(std::move(frame));
    }
    for (int n = 0; n < lut.num_cameras(); ++n) {
      frame_views.push_back(frames[n].view());
      background_views.push_back(backgrounds[n].view());
    }
    changes.assign(lut.total_pixels(), 0);
    for (int n = 0; n < lut.num_cameras(); ++n) {
      const ImageSize s = lut.image_size(n);
      DetectChangesGray(frame_views[n], background_views[n], 30,
                        ImageView<uint8_t>(changes.data() + lut.pixel_offset(n), s.width, s.height, s.width));
    }
  }
  int64_t Pixels() const { return lut.total_pixels(); }
};

LabFrames& Lab() {
  static LabFrames lab;
  return lab;
}

void BM_DetectChangesGrayReference(benchmark::State& state) {
  LabFrames& lab = Lab();
  Image<uint8_t> out(640, 480);
  for (auto _ : state) {
    DetectChangesGrayReference(lab.frame_views[0], lab.background_views[0], 30, out.view());
    benchmark::DoNotOptimize(out.row(0));
  }
  state.SetItemsProcessed(state.iterations() * 640 * 480);
}
BENCHMARK(BM_DetectChangesGrayReference);

void BM_DetectChangesGray(benchmark::State& state) {
  LabFrames& lab = Lab();
  Image<uint8_t> out(640, 480);
  for (auto _ : state) {
    DetectChangesGray(lab.frame_views[0], lab.background_views[0], 30, out.view());
    benchmark::DoNotOptimize(out.row(0));
  }
  state.SetItemsProcessed(state.iterations() * 640 * 480);
}
BENCHMARK(BM_DetectChangesGray);

void BM_PaperLoopWithChangeTest(benchmark::State& state) {
  LabFrames& lab = Lab();
  std::vector<uint8_t> occupancy;
  for (auto _ : state) {
    bench::PaperLoop(lab.lut, lab.frame_views, lab.background_views, 30, occupancy);
    benchmark::DoNotOptimize(occupancy.data());
  }
  state.SetItemsProcessed(state.iterations() * lab.Pixels());
}
BENCHMARK(BM_PaperLoopWithChangeTest);

void BM_FusionReferenceImageBased(benchmark::State& state) {
  LabFrames& lab = Lab();
  Fusion fusion(lab.lut);
  OccupancyMap map(lab.site.grid);
  const std::vector<bool> active(lab.lut.num_cameras(), true);
  for (auto _ : state) {
    fusion.Fuse(lab.changes, active, FusionOptions{}, map);
    benchmark::DoNotOptimize(map.states().data());
  }
  state.SetItemsProcessed(state.iterations() * lab.Pixels());
}
BENCHMARK(BM_FusionReferenceImageBased);

// FastFusion's two methods beside the reference above: cell probes (Fuse, the default, what
// occmap run calls) and row streaming (every pixel), over the change buffer and fused with the
// change test from the frames; range(0) = threads, range(1) = method (0 cell probes, 1 row
// streaming).
FastFusion::Method MethodArg(const benchmark::State& state) {
  return state.range(1) == 0 ? FastFusion::Method::kCellProbe : FastFusion::Method::kRowStreaming;
}

void BM_FastFusionChanges(benchmark::State& state) {
  LabFrames& lab = Lab();
  FastFusion fast(lab.lut);
  OccupancyMap map(lab.site.grid);
  Context ctx(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    fast.FuseChangesWith(MethodArg(state), lab.changes, ctx, map);
    benchmark::DoNotOptimize(map.states().data());
  }
  state.SetItemsProcessed(state.iterations() * lab.Pixels());
}
BENCHMARK(BM_FastFusionChanges)->ArgsProduct({{1, 2}, {0, 1}})->ArgNames({"threads", "streaming"})->UseRealTime();

void BM_FastFusionFromFrames(benchmark::State& state) {
  LabFrames& lab = Lab();
  FastFusion fast(lab.lut);
  OccupancyMap map(lab.site.grid);
  Context ctx(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    fast.FuseWith(MethodArg(state), lab.frame_views, lab.background_views, 30, ctx, map);
    benchmark::DoNotOptimize(map.states().data());
  }
  state.SetItemsProcessed(state.iterations() * lab.Pixels());
}
BENCHMARK(BM_FastFusionFromFrames)->ArgsProduct({{1, 2}, {0, 1}})->ArgNames({"threads", "streaming"})->UseRealTime();

// The worst case of the cell probes: every pixel changed (they hand the frame to row streaming).
void BM_FastFusionFromFramesAllChanged(benchmark::State& state) {
  LabFrames& lab = Lab();
  FastFusion fast(lab.lut);
  OccupancyMap map(lab.site.grid);
  Context ctx(static_cast<int>(state.range(0)));
  std::vector<Image<uint8_t>> frames;
  std::vector<ImageView<const uint8_t>> views;
  for (const Image<uint8_t>& b : lab.backgrounds) {
    Image<uint8_t> f(b.width(), b.height());
    for (int y = 0; y < b.height(); ++y) {
      for (int x = 0; x < b.width(); ++x) f(x, y) = static_cast<uint8_t>(b(x, y) ^ 0x80);
    }
    frames.push_back(std::move(f));
  }
  for (const Image<uint8_t>& f : frames) views.push_back(f.view());
  for (auto _ : state) {
    fast.FuseWith(MethodArg(state), views, lab.background_views, 30, ctx, map);
    benchmark::DoNotOptimize(map.states().data());
  }
  state.SetItemsProcessed(state.iterations() * lab.Pixels());
}
BENCHMARK(BM_FastFusionFromFramesAllChanged)
    ->ArgsProduct({{1, 2}, {0, 1}})
    ->ArgNames({"threads", "streaming"})
    ->UseRealTime();

}  // namespace
}  // namespace occmap

BENCHMARK_MAIN();
