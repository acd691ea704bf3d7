// Google Benchmark micro-benchmarks of the per-frame kernels, each beside its reference, on
// the built-in lab site (four 640x480 cameras onto 450 x 325 cells of 2 cm), and FastFusion on
// frames of the WILDTRACK scene rendered by the simulator (the 7 real calibrations onto 480 x
// 1440 cells; BM_Wildtrack*, skipped when ../shared/datasets is absent; run from the checkout):
//   build/release/src/occmap/occmap_micro_benchmark [--benchmark_filter=Fusion]
// Report ratios between rows of one run, not absolute times (shared machines are noisy).
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "occmap/bench/bench.h"
#include "occmap/detect/change_detection.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/fusion.h"
#include "occmap/site/demo_scene.h"
#include "occmap/site/site.h"

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

// Four WILDTRACK frames rendered by the simulator (real calibrations and trajectories, changes
// clustered on people), as `occmap bench` measures them; rendered once per process (~8 s).
struct WildtrackFrames {
  bool ok = false;
  std::string why;
  Context ctx{2};
  GroundLut lut;
  std::unique_ptr<FastFusion> fast;
  bench::RenderedFrames rendered;
  std::vector<std::vector<ImageView<const uint8_t>>> frame_views;
  std::vector<ImageView<const uint8_t>> background_views;

  bool LoadRendered(const char* path, const std::vector<ImageSize>& sizes);
  void SaveRendered(const char* path) const;

  WildtrackFrames() {
    SiteLoadOptions load;
    load.data_root = "../shared/datasets";
    auto site = LoadSite("sites/wildtrack.yaml", load);
    if (!site.ok()) {
      why = site.status().message();
      return;
    }
    lut = BuildGroundLut(site->LutInputs(), site->grid, site->lut, ctx).value();
    fast = std::make_unique<FastFusion>(lut);
    std::vector<ImageSize> sizes;
    for (int n = 0; n < lut.num_cameras(); ++n) sizes.push_back(lut.image_size(n));
    // OCCMAP_MICRO_FRAMES=FILE keeps the rendered frames in FILE between runs (raw bytes).
    const char* cache = std::getenv("OCCMAP_MICRO_FRAMES");
    if (cache == nullptr || !LoadRendered(cache, sizes)) {
      auto frames = bench::RenderWildtrackFrames("../shared/datasets/wildtrack", 4, sizes, ctx);
      if (!frames.ok()) {
        why = frames.status().message();
        return;
      }
      rendered = std::move(frames).value();
      if (cache != nullptr) SaveRendered(cache);
    }
    for (const auto& b : rendered.backgrounds) background_views.push_back(b.view());
    for (const auto& f : rendered.frames) {
      frame_views.emplace_back();
      for (const auto& image : f) frame_views.back().push_back(image.view());
    }
    ok = true;
  }
};

bool WildtrackFrames::LoadRendered(const char* path, const std::vector<ImageSize>& sizes) {
  std::FILE* f = std::fopen(path, "rb");
  if (f == nullptr) return false;
  auto read = [&](Image<uint8_t>& image, ImageSize size) {
    image = Image<uint8_t>(size.width, size.height);
    for (int y = 0; y < size.height; ++y) {
      if (std::fread(image.row(y), 1, static_cast<size_t>(size.width), f) != static_cast<size_t>(size.width)) return false;
    }
    return true;
  };
  bool good = true;
  rendered.backgrounds.resize(sizes.size());
  rendered.frames.assign(4, std::vector<Image<uint8_t>>(sizes.size()));
  for (size_t n = 0; n < sizes.size() && good; ++n) good = read(rendered.backgrounds[n], sizes[n]);
  for (auto& set : rendered.frames) {
    for (size_t n = 0; n < sizes.size() && good; ++n) good = read(set[n], sizes[n]);
  }
  std::fclose(f);
  return good;
}

void WildtrackFrames::SaveRendered(const char* path) const {
  std::FILE* f = std::fopen(path, "wb");
  if (f == nullptr) return;
  auto write = [&](const Image<uint8_t>& image) {
    for (int y = 0; y < image.height(); ++y) std::fwrite(image.row(y), 1, static_cast<size_t>(image.width()), f);
  };
  for (const auto& b : rendered.backgrounds) write(b);
  for (const auto& set : rendered.frames) {
    for (const auto& image : set) write(image);
  }
  std::fclose(f);
}

WildtrackFrames& Wildtrack() {
  static WildtrackFrames w;
  return w;
}

void BM_WildtrackRenderedFastFusion(benchmark::State& state) {
  WildtrackFrames& w = Wildtrack();
  if (!w.ok) {
    state.SkipWithError(("WILDTRACK not available: " + w.why).c_str());
    return;
  }
  {
    OccupancyMap m;
    Context one(1);
    int64_t probed = 0, failed = 0, secondary = 0, bit_tests = 0;
    for (const auto& views : w.frame_views) {
      w.fast->Fuse(views, w.background_views, 30, one, m);
      probed += w.fast->last_frame_stats().primary_probed;
      failed += w.fast->last_frame_stats().primary_failed;
      secondary += w.fast->last_frame_stats().secondary_probed;
      bit_tests += w.fast->last_frame_stats().secondary_bit_tests;
    }
    state.counters["bit_tests_per_frame"] = static_cast<double>(bit_tests) / static_cast<double>(w.frame_views.size());
    state.counters["primary_failed"] = static_cast<double>(failed) / static_cast<double>(probed);
    state.counters["secondary_per_frame"] = static_cast<double>(secondary) / static_cast<double>(w.frame_views.size());
  }
  OccupancyMap map;
  Context ctx(static_cast<int>(state.range(0)));
  size_t f = 0;
  for (auto _ : state) {
    w.fast->Fuse(w.frame_views[f], w.background_views, 30, ctx, map);
    f = (f + 1) % w.frame_views.size();
    benchmark::DoNotOptimize(map.states().data());
  }
  state.SetItemsProcessed(state.iterations() * w.lut.total_pixels());
}
BENCHMARK(BM_WildtrackRenderedFastFusion)->Arg(1)->Arg(2)->ArgName("threads")->UseRealTime()->MinTime(2.0);

void BM_WildtrackRenderedPaperLoop(benchmark::State& state) {
  WildtrackFrames& w = Wildtrack();
  if (!w.ok) {
    state.SkipWithError(("WILDTRACK not available: " + w.why).c_str());
    return;
  }
  std::vector<uint8_t> occupancy;
  size_t f = 0;
  for (auto _ : state) {
    bench::PaperLoop(w.lut, w.frame_views[f], w.background_views, 30, occupancy);
    f = (f + 1) % w.frame_views.size();
    benchmark::DoNotOptimize(occupancy.data());
  }
  state.SetItemsProcessed(state.iterations() * w.lut.total_pixels());
}
BENCHMARK(BM_WildtrackRenderedPaperLoop)->UseRealTime();

}  // namespace
}  // namespace occmap

BENCHMARK_MAIN();
