#include "occmap/fusion/fast_fusion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdlib>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "occmap/fusion/fusion.h"
#include "occmap/lut/test_scene.h"

namespace occmap {
namespace {

struct RandomScene {
  std::vector<std::unique_ptr<CameraModel>> cameras;
  std::vector<Image<uint8_t>> masks;
  GroundLut lut;
};

// The small room at a random image size (often not a multiple of 64), a random grid and
// random rectangular masks on some cameras.
RandomScene MakeRandomScene(std::mt19937& rng) {
  std::uniform_int_distribution<int> width_dist(40, 210), height_dist(30, 120);
  const int width = width_dist(rng);
  const int height = height_dist(rng);
  testing::SmallRoom room(width, height);
  RandomScene scene;
  for (const auto& cam : room.cameras) scene.cameras.push_back(cam.Clone());
  FloorGrid grid = room.grid;
  std::uniform_real_distribution<double> cell_dist(0.02, 0.12);
  grid.cell_size_m = cell_dist(rng);
  grid.cells_x = static_cast<int>(4.0 / grid.cell_size_m) + 1;
  grid.cells_y = static_cast<int>(3.0 / grid.cell_size_m) + 1;
  std::vector<LutCameraInput> inputs;
  scene.masks.resize(scene.cameras.size());
  for (size_t n = 0; n < scene.cameras.size(); ++n) {
    if (rng() % 2 == 0) {
      Image<uint8_t> mask(width, height, 255);
      std::uniform_int_distribution<int> x_dist(0, width - 1), y_dist(0, height - 1);
      for (int k = 0; k < 3; ++k) {
        const int x0 = x_dist(rng), x1 = x_dist(rng), y0 = y_dist(rng), y1 = y_dist(rng);
        for (int y = std::min(y0, y1); y <= std::max(y0, y1); ++y) {
          for (int x = std::min(x0, x1); x <= std::max(x0, x1); ++x) mask(x, y) = 0;
        }
      }
      scene.masks[n] = std::move(mask);
    }
    inputs.push_back({scene.cameras[n].get(), scene.masks[n].view()});
  }
  Context ctx(1);
  scene.lut = BuildGroundLut(inputs, grid, {}, ctx).value();
  return scene;
}

// Background random; each pixel of the frame differs from it by T - 1, T, T + 1 or a random
// amount (so both sides of the strict comparison occur), with `changed_fraction` of the pixels
// pushed above T.
void MakeFrame(std::mt19937& rng, int threshold, double changed_fraction, Image<uint8_t>& frame,
               Image<uint8_t>& background) {
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int y = 0; y < frame.height(); ++y) {
    for (int x = 0; x < frame.width(); ++x) {
      const int b = byte(rng);
      background(x, y) = static_cast<uint8_t>(b);
      const bool change = unit(rng) < changed_fraction;
      int d = change ? threshold + 1 + static_cast<int>(rng() % 3 == 0 ? byte(rng) : 0) : threshold - static_cast<int>(rng() % 2);
      if (!change && rng() % 3 == 0) d = byte(rng) % (threshold + 1);
      const int sign = rng() % 2 == 0 ? 1 : -1;
      int f = b + sign * d;
      if (f > 255 || f < 0) f = b - sign * d;
      frame(x, y) = static_cast<uint8_t>(std::clamp(f, 0, 255));
    }
  }
}

// Changes clustered like people's silhouettes: the background random, the frame equal to it up
// to T (both sides of the comparison) but inside `discs` random discs and upright ellipses
// (radius 1 .. a quarter of the image height), where it differs by more than T; plus a few
// isolated changed pixels. Cells under a disc fail their first probes in some cameras and not in
// others, as on rendered frames.
void MakeClusteredFrame(std::mt19937& rng, int threshold, int discs, Image<uint8_t>& frame,
                        Image<uint8_t>& background) {
  MakeFrame(rng, threshold, 0.002, frame, background);
  const int w = frame.width(), h = frame.height();
  std::uniform_int_distribution<int> x_dist(0, w - 1), y_dist(0, h - 1), r_dist(1, std::max(1, h / 4));
  for (int k = 0; k < discs; ++k) {
    const int cx = x_dist(rng), cy = y_dist(rng), rx = r_dist(rng);
    const int ry = rng() % 2 == 0 ? rx : 3 * rx;  // a disc or a standing person's ellipse
    for (int y = std::max(0, cy - ry); y <= std::min(h - 1, cy + ry); ++y) {
      for (int x = std::max(0, cx - rx); x <= std::min(w - 1, cx + rx); ++x) {
        const double dx = static_cast<double>(x - cx) / rx, dy = static_cast<double>(y - cy) / ry;
        if (dx * dx + dy * dy > 1.0) continue;
        const int b = background(x, y);
        const int d = threshold + 1 + static_cast<int>(rng() % 3 == 0 ? rng() % 100 : 0);
        frame(x, y) = static_cast<uint8_t>(b + d <= 255 ? b + d : std::max(0, b - d));
        if (b + d > 255 && b - d < 0) frame(x, y) = background(x, y);  // no room: stays unchanged
      }
    }
  }
}

// The reference: change detection per camera into the global buffer, then Fusion.
// One frame and background per camera of `lut`, filled by make(frame, background), with
// their views.
struct CameraFrames {
  std::vector<Image<uint8_t>> frames, backgrounds;
  std::vector<ImageView<const uint8_t>> frame_views, background_views;
};
CameraFrames MakeCameraFrames(const GroundLut& lut,
                              const std::function<void(Image<uint8_t>&, Image<uint8_t>&)>& make) {
  CameraFrames c;
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const ImageSize size = lut.image_size(n);
    c.frames.emplace_back(size.width, size.height);
    c.backgrounds.emplace_back(size.width, size.height);
    make(c.frames.back(), c.backgrounds.back());
  }
  for (size_t n = 0; n < c.frames.size(); ++n) {
    c.frame_views.push_back(c.frames[n].view());
    c.background_views.push_back(c.backgrounds[n].view());
  }
  return c;
}

OccupancyMap Reference(const GroundLut& lut, const std::vector<Image<uint8_t>>& frames,
                       const std::vector<Image<uint8_t>>& backgrounds, int threshold, std::vector<uint8_t>& changes) {
  changes.assign(lut.total_pixels(), 0);
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const ImageSize size = lut.image_size(n);
    ImageView<uint8_t> out(changes.data() + lut.pixel_offset(n), size.width, size.height, size.width);
    // Equation 4 as detect/change_detection.h computes it (the fusion module does not link
    // detect; bench_test checks against DetectChangesGray itself).
    const Image<uint8_t>& f = frames[static_cast<size_t>(n)];
    const Image<uint8_t>& b = backgrounds[static_cast<size_t>(n)];
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) out(x, y) = std::abs(int{f(x, y)} - int{b(x, y)}) > threshold ? 1 : 0;
    }
  }
  Fusion fusion(lut);
  OccupancyMap map;
  fusion.Fuse(changes, std::vector<bool>(static_cast<size_t>(lut.num_cameras()), true), FusionOptions{}, map);
  return map;
}

class FastFusionKernels : public ::testing::TestWithParam<const char*> {
 protected:
  void SetUp() override {
    if (!FastFusion::ForceKernelForTesting(GetParam())) GTEST_SKIP() << GetParam() << " not supported here";
  }
  void TearDown() override { FastFusion::ForceKernelForTesting("best"); }
};

INSTANTIATE_TEST_SUITE_P(AllKernels, FastFusionKernels, ::testing::Values("portable", "avx2", "avx512bw"));

TEST_P(FastFusionKernels, IdenticalToReferenceOnRandomScenesAndFrames) {
  std::mt19937 rng(1234);
  Context ctx1(1), ctx2(2);
  int occupied_total = 0;
  for (int trial = 0; trial < 24; ++trial) {
    RandomScene scene = MakeRandomScene(rng);
    FastFusion fast(scene.lut);
    for (int frame_index = 0; frame_index < 4; ++frame_index) {
      const int threshold = static_cast<int>(rng() % 256);
      const double fractions[] = {0.0, 0.05, 0.2, 0.5, 0.95, 0.995, 1.0};
      const double fraction = threshold == 255 ? 0.0 : fractions[rng() % 7];
      const CameraFrames camera_frames = MakeCameraFrames(
          scene.lut, [&](Image<uint8_t>& f, Image<uint8_t>& b) { MakeFrame(rng, threshold, fraction, f, b); });
      const auto& [frames, backgrounds, frame_views, background_views] = camera_frames;
      std::vector<uint8_t> changes;
      const OccupancyMap expected = Reference(scene.lut, frames, backgrounds, threshold, changes);
      occupied_total += static_cast<int>(expected.Count(CellState::kOccupied));
      for (Context* ctx : {&ctx1, &ctx2}) {
        OccupancyMap map;
        fast.Fuse(frame_views, background_views, threshold, *ctx, map);
        ASSERT_EQ(map, expected) << "trial " << trial << " frame " << frame_index << " T " << threshold
                                 << " threads " << ctx->num_threads();
        OccupancyMap from_changes;
        fast.FuseChanges(changes, *ctx, from_changes);
        ASSERT_EQ(from_changes, expected) << "trial " << trial << " (changes)";
        // Every path of both methods: cell probes resolving every failure themselves (fallback
        // never taken), handing over to row streaming at the first failure, row streaming.
        for (const double fallback : {2.0, 0.0, 0.1, 0.3}) {
          fast.SetStreamingFallbackForTesting(fallback, /*sample=*/fallback == 0.3 ? 4096 : 16);
          OccupancyMap probed;
          fast.FuseWith(FastFusion::Method::kCellProbe, frame_views, background_views, threshold, *ctx, probed);
          ASSERT_EQ(probed, expected) << "trial " << trial << " fallback " << fallback;
          fast.FuseChangesWith(FastFusion::Method::kCellProbe, changes, *ctx, probed);
          ASSERT_EQ(probed, expected) << "trial " << trial << " fallback " << fallback << " (changes)";
        }
        fast.SetStreamingFallbackForTesting(0.15, 4096);
        OccupancyMap streamed;
        fast.FuseWith(FastFusion::Method::kRowStreaming, frame_views, background_views, threshold, *ctx, streamed);
        ASSERT_EQ(streamed, expected) << "trial " << trial << " (row streaming)";
        fast.FuseChangesWith(FastFusion::Method::kRowStreaming, changes, *ctx, streamed);
        ASSERT_EQ(streamed, expected) << "trial " << trial << " (row streaming, changes)";
        // PaperImageBasedLoop agrees where some camera sees the cell.
        const std::vector<uint8_t> paper = PaperImageBasedLoop(scene.lut, changes);
        for (size_t c = 0; c < expected.states().size(); ++c) {
          if (expected.states()[c] != CellState::kUnseen) {
            ASSERT_EQ(paper[c] != 0, expected.states()[c] == CellState::kOccupied);
          }
        }
      }
    }
  }
  EXPECT_GT(occupied_total, 0);  // the test exercises occupied cells, not only free ones
}

// Every method and path against the reference on clustered changes: the cell probes with the
// default hand-over, never handing over (every failure resolved by the second pass), handing
// over at the first failure, and row streaming; frames and a change buffer; 1 and 2 threads.
TEST_P(FastFusionKernels, IdenticalToReferenceOnClusteredChanges) {
  std::mt19937 rng(4321);
  Context ctx1(1), ctx2(2);
  int64_t occupied_total = 0, failed_total = 0, secondary_total = 0, bit_tests_total = 0;
  for (int trial = 0; trial < 16; ++trial) {
    RandomScene scene = MakeRandomScene(rng);
    FastFusion fast(scene.lut);
    for (int frame_index = 0; frame_index < 4; ++frame_index) {
      const int threshold = static_cast<int>(rng() % 100);
      const int discs = 1 + static_cast<int>(rng() % 12);
      const CameraFrames camera_frames = MakeCameraFrames(
          scene.lut, [&](Image<uint8_t>& f, Image<uint8_t>& b) { MakeClusteredFrame(rng, threshold, discs, f, b); });
      const auto& [frames, backgrounds, frame_views, background_views] = camera_frames;
      std::vector<uint8_t> changes;
      const OccupancyMap expected = Reference(scene.lut, frames, backgrounds, threshold, changes);
      occupied_total += expected.Count(CellState::kOccupied);
      for (Context* ctx : {&ctx1, &ctx2}) {
        const std::string where = "trial " + std::to_string(trial) + " frame " + std::to_string(frame_index) +
                                  " threads " + std::to_string(ctx->num_threads());
        for (const double fallback : {0.35, 2.0, 0.0}) {
          fast.SetStreamingFallbackForTesting(fallback, /*sample=*/16);
          OccupancyMap map;
          fast.Fuse(frame_views, background_views, threshold, *ctx, map);
          ASSERT_EQ(map, expected) << where << " fallback " << fallback;
          if (fallback == 2.0) {
            failed_total += fast.last_frame_stats().primary_failed;
            secondary_total += fast.last_frame_stats().secondary_probed;
            bit_tests_total += fast.last_frame_stats().secondary_bit_tests;
            EXPECT_FALSE(fast.last_frame_stats().streamed);
          }
          OccupancyMap from_changes;
          fast.FuseChanges(changes, *ctx, from_changes);
          ASSERT_EQ(from_changes, expected) << where << " fallback " << fallback << " (changes)";
        }
        fast.SetStreamingFallbackForTesting(0.35, 4096);
        OccupancyMap streamed;
        fast.FuseWith(FastFusion::Method::kRowStreaming, frame_views, background_views, threshold, *ctx, streamed);
        ASSERT_EQ(streamed, expected) << where << " (row streaming)";
        EXPECT_TRUE(fast.last_frame_stats().streamed);
      }
    }
  }
  // The frames exercise what they are meant to: occupied cells, failed primary probes, the
  // second pass both in pass 1's bits and in the images.
  EXPECT_GT(occupied_total, 0);
  EXPECT_GT(failed_total, 0);
  EXPECT_GT(bit_tests_total, 0);
  EXPECT_GT(secondary_total - bit_tests_total, 0);
}

// FuseTolerant against the reference: change detection, the square dilation by r (brute force,
// clipped to the image, as DilateChangesReference), then Fusion; and its bits against the
// dilated changes at every pixel. Random and clustered frames, r = 1..8, 1 and 2 threads, the
// hand-over to row streaming included (it reads the same bits).
TEST_P(FastFusionKernels, TolerantIdenticalToDilatedReference) {
  std::mt19937 rng(777);
  Context ctx1(1), ctx2(2);
  int64_t occupied_total = 0, streamed_frames = 0;
  for (int trial = 0; trial < 12; ++trial) {
    RandomScene scene = MakeRandomScene(rng);
    FastFusion fast(scene.lut);
    for (int frame_index = 0; frame_index < 3; ++frame_index) {
      const int threshold = static_cast<int>(rng() % 100);
      const int radius = 1 + static_cast<int>(rng() % FastFusion::kMaxFusedTolerancePx);
      const bool clustered = rng() % 2 == 0;
      const double fraction = (rng() % 4 == 0) ? 0.3 : 0.01;
      const int discs = 1 + static_cast<int>(rng() % 6);
      const CameraFrames camera_frames = MakeCameraFrames(scene.lut, [&](Image<uint8_t>& f, Image<uint8_t>& b) {
        if (clustered) {
          MakeClusteredFrame(rng, threshold, discs, f, b);
        } else {
          MakeFrame(rng, threshold, fraction, f, b);
        }
      });
      const auto& [frames, backgrounds, frame_views, background_views] = camera_frames;
      std::vector<uint8_t> raw;
      Reference(scene.lut, frames, backgrounds, threshold, raw);
      // The dilation of every camera's changes (brute force over the clipped window).
      std::vector<uint8_t> dilated(raw.size(), 0);
      for (int n = 0; n < scene.lut.num_cameras(); ++n) {
        const ImageSize size = scene.lut.image_size(n);
        const uint8_t* in = raw.data() + scene.lut.pixel_offset(n);
        uint8_t* out = dilated.data() + scene.lut.pixel_offset(n);
        for (int y = 0; y < size.height; ++y) {
          for (int x = 0; x < size.width; ++x) {
            uint8_t set = 0;
            for (int v = std::max(0, y - radius); v <= std::min(size.height - 1, y + radius); ++v) {
              for (int u = std::max(0, x - radius); u <= std::min(size.width - 1, x + radius); ++u) {
                set |= in[static_cast<size_t>(v) * size.width + u];
              }
            }
            out[static_cast<size_t>(y) * size.width + x] = set;
          }
        }
      }
      Fusion fusion(scene.lut);
      OccupancyMap expected;
      fusion.Fuse(dilated, std::vector<bool>(static_cast<size_t>(scene.lut.num_cameras()), true), FusionOptions{},
                  expected);
      occupied_total += expected.Count(CellState::kOccupied);
      for (Context* ctx : {&ctx1, &ctx2}) {
        for (const double fallback : {0.15, 2.0, 0.0}) {
          fast.SetStreamingFallbackForTesting(fallback, /*sample=*/16);
          const std::string where = "trial " + std::to_string(trial) + " frame " + std::to_string(frame_index) +
                                    " r " + std::to_string(radius) + " threads " + std::to_string(ctx->num_threads()) +
                                    " fallback " + std::to_string(fallback);
          OccupancyMap map;
          ChangeBits bits;
          fast.FuseTolerant(frame_views, background_views, threshold, radius, *ctx, map, bits);
          ASSERT_EQ(map, expected) << where;
          streamed_frames += fast.last_frame_stats().streamed ? 1 : 0;
          for (int n = 0; n < scene.lut.num_cameras(); ++n) {
            const ImageSize size = scene.lut.image_size(n);
            for (int y = 0; y < size.height; ++y) {
              for (int x = 0; x < size.width; ++x) {
                ASSERT_EQ(bits.Changed(n, x, y),
                          dilated[scene.lut.pixel_offset(n) + static_cast<size_t>(y) * size.width + x] != 0)
                    << where << " camera " << n << " pixel " << x << "," << y;
              }
            }
          }
        }
      }
    }
  }
  EXPECT_GT(occupied_total, 0);
  EXPECT_GT(streamed_frames, 0);  // the hand-over happened on some frames
}

// Runs longer than the probe loop's window (56 pixels: their tail is a secondary run): big cells
// on big images, every pixel changed but, in camera 0, the pixels past the 56th of each cell's
// longest run in its row with the most trailing zero bits (the primary run when camera 0 has the
// most pixels on the cell): those cells are free through the tail alone.
TEST_P(FastFusionKernels, LongRunsAreTestedToTheirLastPixel) {
  testing::SmallRoom room(1280, 960);
  FloorGrid grid = room.grid;
  grid.cell_size_m = 0.25;
  grid.cells_x = 16;
  grid.cells_y = 12;
  std::vector<LutCameraInput> inputs;
  for (const auto& cam : room.cameras) inputs.push_back({&cam, {}});
  Context ctx1(1), ctx2(2);
  const GroundLut lut = BuildGroundLut(inputs, grid, {}, ctx1).value();
  const int threshold = 30;
  std::vector<Image<uint8_t>> frames, backgrounds;
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const ImageSize size = lut.image_size(n);
    backgrounds.emplace_back(size.width, size.height, 100);
    frames.emplace_back(size.width, size.height, 200);  // changed
  }
  struct BestRun {
    int rank = -1, x = 0, y = 0, length = 0;
  };
  std::vector<BestRun> best(static_cast<size_t>(grid.num_cells()));
  const ImageSize size0 = lut.image_size(0);
  const std::span<const uint32_t> l1 = lut.l1(0);
  for (int y = 0; y < size0.height; ++y) {
    int x = 0;
    while (x < size0.width) {
      const uint32_t cell = l1[static_cast<size_t>(y) * size0.width + x];
      int length = 1;
      while (x + length < size0.width && length < 64 && l1[static_cast<size_t>(y) * size0.width + x + length] == cell) {
        ++length;
      }
      if (cell != lut.sentinel()) {
        const int rank = std::min(std::countr_zero(static_cast<unsigned>(y) | 64u), 6) * 128 + length;
        if (rank > best[cell].rank) best[cell] = BestRun{rank, x, y, length};
      }
      x += length;
    }
  }
  int64_t long_runs = 0;
  for (const BestRun& run : best) {
    if (run.length <= 56) continue;
    ++long_runs;
    for (int i = 56; i < run.length; ++i) frames[0](run.x + i, run.y) = 100;  // unchanged
  }
  ASSERT_GT(long_runs, 10);
  std::vector<ImageView<const uint8_t>> frame_views, background_views;
  for (size_t n = 0; n < frames.size(); ++n) {
    frame_views.push_back(frames[n].view());
    background_views.push_back(backgrounds[n].view());
  }
  std::vector<uint8_t> changes;
  const OccupancyMap expected = Reference(lut, frames, backgrounds, threshold, changes);
  ASSERT_GT(expected.Count(CellState::kFree), 0);  // freed by long runs' tails only
  FastFusion fast(lut);
  fast.SetStreamingFallbackForTesting(2.0);  // resolve every failure with the cell probes
  for (Context* ctx : {&ctx1, &ctx2}) {
    OccupancyMap map;
    fast.Fuse(frame_views, background_views, threshold, *ctx, map);
    EXPECT_EQ(map, expected) << ctx->num_threads() << " threads";
    fast.FuseChanges(changes, *ctx, map);
    EXPECT_EQ(map, expected) << ctx->num_threads() << " threads (changes)";
  }
}

TEST_P(FastFusionKernels, StridedViewsAndReuse) {
  std::mt19937 rng(99);
  RandomScene scene = MakeRandomScene(rng);
  FastFusion fast(scene.lut);
  Context ctx(2);
  OccupancyMap map;  // reused across frames
  for (int frame_index = 0; frame_index < 3; ++frame_index) {
    const int threshold = 20;
    std::vector<Image<uint8_t>> frames, backgrounds, wide_frames, wide_backgrounds;
    std::vector<ImageView<const uint8_t>> frame_views, background_views;
    for (int n = 0; n < scene.lut.num_cameras(); ++n) {
      const ImageSize size = scene.lut.image_size(n);
      frames.emplace_back(size.width, size.height);
      backgrounds.emplace_back(size.width, size.height);
      MakeFrame(rng, threshold, 0.9, frames.back(), backgrounds.back());
      // Copies inside wider images: views with a stride larger than the width.
      wide_frames.emplace_back(size.width + 37, size.height, 0);
      wide_backgrounds.emplace_back(size.width + 37, size.height, 255);
      for (int y = 0; y < size.height; ++y) {
        for (int x = 0; x < size.width; ++x) {
          wide_frames.back()(x, y) = frames.back()(x, y);
          wide_backgrounds.back()(x, y) = backgrounds.back()(x, y);
        }
      }
    }
    for (size_t n = 0; n < frames.size(); ++n) {
      frame_views.emplace_back(wide_frames[n].view().data(), frames[n].width(), frames[n].height(),
                               wide_frames[n].view().stride_elems());
      background_views.emplace_back(wide_backgrounds[n].view().data(), frames[n].width(), frames[n].height(),
                                    wide_backgrounds[n].view().stride_elems());
    }
    std::vector<uint8_t> changes;
    const OccupancyMap expected = Reference(scene.lut, frames, backgrounds, threshold, changes);
    fast.Fuse(frame_views, background_views, threshold, ctx, map);
    ASSERT_EQ(map, expected);
  }
  EXPECT_GT(fast.MemoryBytes(), 0);
  EXPECT_GT(fast.num_runs(), 0);
}

// A frame starts from every seen cell free and tests only the primary probes whose first pixel
// is changed: none on an unchanged frame, and on a frame with one changed pixel at most those
// starting in its 64-pixel word (one, unless two probes of the row start at one pixel); the map
// still equal to the reference.
TEST_P(FastFusionKernels, ProbesOnlyWordsWithChanges) {
  std::mt19937 rng(5);
  RandomScene scene = MakeRandomScene(rng);
  FastFusion fast(scene.lut);
  Context ctx(2);
  OccupancyMap map;
  const int threshold = 25;
  CameraFrames same = MakeCameraFrames(scene.lut, [&](Image<uint8_t>& f, Image<uint8_t>& b) {
    MakeFrame(rng, threshold, 0.0, f, b);
  });
  std::vector<uint8_t> changes;
  fast.Fuse(same.frame_views, same.background_views, threshold, ctx, map);
  EXPECT_EQ(map, Reference(scene.lut, same.frames, same.backgrounds, threshold, changes));
  EXPECT_EQ(fast.last_frame_stats().primary_probed, fast.num_primary_probes());
  EXPECT_EQ(fast.last_frame_stats().primary_tested, 0);
  EXPECT_EQ(fast.last_frame_stats().primary_failed, 0);
  int64_t free_cells = 0;
  for (CellState c : map.states()) free_cells += c == CellState::kFree;
  EXPECT_EQ(free_cells, fast.num_primary_probes());  // one primary probe per seen cell
  // One changed pixel in camera 0, in the middle of its image.
  CameraFrames one = same;
  for (size_t n = 0; n < one.frames.size(); ++n) {
    one.frame_views[n] = one.frames[n].view();
    one.background_views[n] = one.backgrounds[n].view();
  }
  Image<uint8_t>& f0 = one.frames[0];
  const int x = f0.width() / 2, y = f0.height() / 2;
  const int b0 = one.backgrounds[0](x, y);
  f0(x, y) = static_cast<uint8_t>(b0 > 127 ? b0 - threshold - 1 : b0 + threshold + 1);
  fast.Fuse(one.frame_views, one.background_views, threshold, ctx, map);
  EXPECT_EQ(map, Reference(scene.lut, one.frames, one.backgrounds, threshold, changes));
  EXPECT_LE(fast.last_frame_stats().primary_tested, 64);
}

TEST(FastFusion, KernelNameIsKnown) {
  const std::string name = FastFusion::KernelName();
  EXPECT_TRUE(name == "avx512bw" || name == "avx2" || name == "portable") << name;
}

}  // namespace
}  // namespace occmap

