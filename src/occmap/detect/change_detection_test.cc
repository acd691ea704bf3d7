#include "occmap/detect/change_detection.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace occmap {
namespace {

// An image of T in a buffer with `pad` extra elements per row and one before the first pixel,
// so that rows are neither contiguous nor aligned. Padding holds `fill` for overwrite checks.
template <typename T>
struct Padded {
  Padded(int width, int height, int pad, T fill = T{})
      : stride(width + pad), buffer(static_cast<size_t>(stride) * static_cast<size_t>(height) + 1, fill) {
    w = width;
    h = height;
  }
  ImageView<T> view() { return {buffer.data() + 1, w, h, stride}; }
  ImageView<const T> cview() const { return {buffer.data() + 1, w, h, stride}; }
  int w = 0, h = 0;
  int stride;
  std::vector<T> buffer;
};

template <typename T>
bool SamePixels(ImageView<const T> a, ImageView<const T> b) {
  if (a.width() != b.width() || a.height() != b.height()) return false;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      if (!(a(x, y) == b(x, y))) return false;
    }
  }
  return true;
}

// A frame near the background (most differences small, around the threshold) so that both
// sides of the threshold are hit often.
void RandomPair(std::mt19937& rng, Padded<uint8_t>& frame, Padded<uint8_t>& background, int threshold) {
  std::uniform_int_distribution<int> value(0, 255), delta(-threshold - 3, threshold + 3), pick(0, 9);
  for (int y = 0; y < frame.h; ++y) {
    for (int x = 0; x < frame.w; ++x) {
      const int b = value(rng);
      const int f = pick(rng) == 0 ? value(rng) : std::clamp(b + delta(rng), 0, 255);
      background.view()(x, y) = static_cast<uint8_t>(b);
      frame.view()(x, y) = static_cast<uint8_t>(f);
    }
  }
}

TEST(DetectChanges, GrayFastMatchesReferenceOnRandomStridedImages) {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> size(1, 97), pad(0, 13), threshold(0, 255);
  for (int trial = 0; trial < 200; ++trial) {
    const int w = size(rng) | 1, h = size(rng), t = trial < 2 ? trial * 254 : threshold(rng);
    Padded<uint8_t> frame(w, h, pad(rng)), background(w, h, pad(rng));
    RandomPair(rng, frame, background, t);
    Padded<uint8_t> fast(w, h, pad(rng), 0xAB), reference(w, h, pad(rng), 0xCD);
    DetectChangesGray(frame.cview(), background.cview(), t, fast.view());
    DetectChangesGrayReference(frame.cview(), background.cview(), t, reference.view());
    ASSERT_TRUE(SamePixels(fast.cview(), reference.cview())) << "trial " << trial << " " << w << "x" << h << " T=" << t;
    // Only the view's pixels are written, and each is 1 or 0.
    for (int y = 0; y < h; ++y) {
      for (int x = w; x < fast.stride; ++x) {
        if (y * fast.stride + x + 1 < static_cast<int>(fast.buffer.size())) {
          ASSERT_EQ(fast.buffer[static_cast<size_t>(y * fast.stride + x + 1)], 0xAB);
        }
      }
      for (int x = 0; x < w; ++x) ASSERT_LE(fast.cview()(x, y), 1);
    }
    ASSERT_EQ(fast.buffer[0], 0xAB);
  }
}

TEST(DetectChanges, RgbFastMatchesReferenceOnRandomStridedImages) {
  std::mt19937 rng(2);
  std::uniform_int_distribution<int> size(1, 61), pad(0, 7), threshold(0, 255), value(0, 255), pick(0, 3);
  for (int trial = 0; trial < 200; ++trial) {
    const int w = size(rng) | 1, h = size(rng), t = trial < 2 ? trial * 254 : threshold(rng);
    std::uniform_int_distribution<int> delta(-t - 2, t + 2);
    Padded<Rgb8> frame(w, h, pad(rng)), background(w, h, pad(rng));
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        Rgb8 b{static_cast<uint8_t>(value(rng)), static_cast<uint8_t>(value(rng)), static_cast<uint8_t>(value(rng))};
        Rgb8 f = b;
        // Usually only one channel moves, so that each channel alone decides some pixels.
        uint8_t* channel = pick(rng) == 0 ? &f.r : pick(rng) == 0 ? &f.g : &f.b;
        *channel = static_cast<uint8_t>(std::clamp(*channel + delta(rng), 0, 255));
        if (pick(rng) == 0) f.g = static_cast<uint8_t>(value(rng));
        background.view()(x, y) = b;
        frame.view()(x, y) = f;
      }
    }
    Padded<uint8_t> fast(w, h, pad(rng), 0xAB), reference(w, h, pad(rng), 0xCD);
    DetectChangesRgb(frame.cview(), background.cview(), t, fast.view());
    DetectChangesRgbReference(frame.cview(), background.cview(), t, reference.view());
    ASSERT_TRUE(SamePixels(fast.cview(), reference.cview())) << "trial " << trial << " " << w << "x" << h << " T=" << t;
  }
}

TEST(DetectChanges, DifferenceEqualToThresholdIsUnchangedAndOneMoreIsChanged) {
  for (int t : {0, 1, 30, 128, 254}) {
    // Columns: |d| = T - 1 (if any), T, T + 1, both signs.
    Image<uint8_t> background(6, 1, 0), frame(6, 1, 0);
    const int base = t < 128 ? 0 : 255;  // so that base +- (T + 1) stays in range on one side
    const int sign = base == 0 ? 1 : -1;
    const int diffs[6] = {std::max(t - 1, 0), t, t + 1, std::max(t - 1, 0), t, t + 1};
    for (int x = 0; x < 6; ++x) {
      // The first three have frame > background when base = 0; the last three swap the roles.
      const uint8_t a = static_cast<uint8_t>(base), b = static_cast<uint8_t>(base + sign * diffs[x]);
      frame(x, 0) = x < 3 ? b : a;
      background(x, 0) = x < 3 ? a : b;
    }
    Image<uint8_t> fast(6, 1), reference(6, 1);
    DetectChangesGray(frame.view(), background.view(), t, fast.view());
    DetectChangesGrayReference(frame.view(), background.view(), t, reference.view());
    const uint8_t expected[6] = {0, 0, 1, 0, 0, 1};
    for (int x = 0; x < 6; ++x) {
      EXPECT_EQ(fast(x, 0), expected[x]) << "T=" << t << " x=" << x;
      EXPECT_EQ(reference(x, 0), expected[x]) << "T=" << t << " x=" << x;
    }
    // Colour: a single channel at T + 1 is a change, every channel at T is not.
    Image<Rgb8> bg(4, 1, Rgb8{static_cast<uint8_t>(base), static_cast<uint8_t>(base), static_cast<uint8_t>(base)});
    Image<Rgb8> fr = bg;
    const uint8_t at_t = static_cast<uint8_t>(base + sign * t), above = static_cast<uint8_t>(base + sign * (t + 1));
    fr(0, 0) = {at_t, at_t, at_t};
    fr(1, 0).r = above;
    fr(2, 0).g = above;
    fr(3, 0).b = above;
    Image<uint8_t> c_fast(4, 1), c_ref(4, 1);
    DetectChangesRgb(fr.view(), bg.view(), t, c_fast.view());
    DetectChangesRgbReference(fr.view(), bg.view(), t, c_ref.view());
    for (int x = 0; x < 4; ++x) {
      EXPECT_EQ(c_fast(x, 0), x == 0 ? 0 : 1) << "T=" << t << " x=" << x;
      EXPECT_EQ(c_ref(x, 0), x == 0 ? 0 : 1) << "T=" << t << " x=" << x;
    }
  }
}

TEST(DetectChanges, ThresholdZeroFlagsEveryDifferenceAnd254OnlyTheFullRange) {
  Image<uint8_t> frame(3, 1), background(3, 1, 0), out(3, 1);
  frame(0, 0) = 0;
  frame(1, 0) = 1;
  frame(2, 0) = 255;
  DetectChangesGray(frame.view(), background.view(), 0, out.view());
  EXPECT_EQ(out(0, 0), 0);
  EXPECT_EQ(out(1, 0), 1);
  EXPECT_EQ(out(2, 0), 1);
  DetectChangesGray(frame.view(), background.view(), 254, out.view());
  EXPECT_EQ(out(0, 0), 0);
  EXPECT_EQ(out(1, 0), 0);
  EXPECT_EQ(out(2, 0), 1);
  frame(2, 0) = 254;
  DetectChangesGray(frame.view(), background.view(), 254, out.view());
  EXPECT_EQ(out(2, 0), 0);
}

TEST(ChangeDetectionOptions, ValidateNamesTheFieldAndTheRange) {
  EXPECT_TRUE(ChangeDetectionOptions{}.Validate().ok());
  EXPECT_TRUE((ChangeDetectionOptions{.threshold = 254, .tolerance_px = 64}).Validate().ok());
  EXPECT_EQ(ChangeDetectionOptions{.threshold = 255}.Validate().message(),
            "threshold: expected 0..254 grey levels, found 255");
  EXPECT_EQ(ChangeDetectionOptions{.threshold = -1}.Validate().message(),
            "threshold: expected 0..254 grey levels, found -1");
  EXPECT_EQ(ChangeDetectionOptions{.tolerance_px = 65}.Validate().message(),
            "tolerance_px: expected 0..64 pixels, found 65");
  EXPECT_EQ(ChangeDetectionOptions{.tolerance_px = -2}.Validate().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(ChangeDetectionOptions{.block_height_px = 3}.Validate().message(),
            "block_px: expected 1 or 2 pixels wide and high, found 1 x 3");
}

// Sparse random masks with arbitrary non-zero values (any non-zero counts as set).
void RandomSparseMask(std::mt19937& rng, ImageView<uint8_t> mask, double density) {
  std::bernoulli_distribution set(density);
  std::uniform_int_distribution<int> value(1, 255);
  for (int y = 0; y < mask.height(); ++y) {
    for (int x = 0; x < mask.width(); ++x) mask(x, y) = set(rng) ? static_cast<uint8_t>(value(rng)) : 0;
  }
}

TEST(DilateChanges, FastMatchesBruteForceForRadiiZeroToNineAndOddSizes) {
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> pad(0, 9);
  std::vector<uint8_t> scratch;  // shared across calls and sizes, as on the run path
  const int sizes[][2] = {{1, 1}, {1, 17}, {17, 1}, {3, 5}, {7, 3}, {37, 23}, {64, 64}, {101, 7}, {5, 99}, {63, 65}};
  for (const auto& size : sizes) {
    for (int r = 0; r <= 9; ++r) {  // both methods: shifted ORs up to 4, running counts beyond
      for (double density : {0.0, 0.003, 0.02, 0.1, 0.5}) {
        Padded<uint8_t> in(size[0], size[1], pad(rng));
        RandomSparseMask(rng, in.view(), density);
        Padded<uint8_t> fast(size[0], size[1], pad(rng), 0xAB), reference(size[0], size[1], pad(rng), 0xCD);
        DilateChanges(in.cview(), r, fast.view(), scratch);
        DilateChangesReference(in.cview(), r, reference.view());
        ASSERT_TRUE(SamePixels(fast.cview(), reference.cview()))
            << size[0] << "x" << size[1] << " r=" << r << " density=" << density;
        for (int y = 0; y < size[1]; ++y) {
          for (int x = 0; x < size[0]; ++x) ASSERT_LE(fast.cview()(x, y), 1);
        }
      }
    }
  }
}

TEST(DetectChangesGrayDilated, EqualsChangeDetectionThenTheReferenceDilation) {
  std::mt19937 rng(5);
  std::vector<uint8_t> scratch;  // shared across calls and sizes, as on the run path
  const int sizes[][2] = {{1, 1}, {1, 17}, {17, 1}, {3, 5}, {37, 23}, {64, 64}, {101, 7}, {5, 99}, {640, 48}};
  for (const auto& size : sizes) {
    for (int r = 0; r <= 6; ++r) {
      for (int threshold : {0, 20, 254}) {
        Padded<uint8_t> frame(size[0], size[1], 3), background(size[0], size[1], 1);
        for (int y = 0; y < size[1]; ++y) {
          for (int x = 0; x < size[0]; ++x) {
            const uint8_t b = static_cast<uint8_t>(rng());
            background.view()(x, y) = b;
            // Mostly near the background (noise), sometimes far (changes), in clusters.
            const bool far = (rng() % 100) < 5 || ((x / 8 + y / 8) % 7 == 0 && rng() % 2);
            frame.view()(x, y) = far ? static_cast<uint8_t>(rng()) : static_cast<uint8_t>(std::clamp(b + static_cast<int>(rng() % 11) - 5, 0, 255));
          }
        }
        Padded<uint8_t> changes(size[0], size[1], 2), reference(size[0], size[1], 0, 0xCD), fused(size[0], size[1], 4, 0xAB);
        DetectChangesGrayReference(frame.cview(), background.cview(), threshold, changes.view());
        DilateChangesReference(changes.cview(), r, reference.view());
        DetectChangesGrayDilated(frame.cview(), background.cview(), threshold, r, fused.view(), scratch);
        ASSERT_TRUE(SamePixels(fused.cview(), reference.cview())) << size[0] << "x" << size[1] << " r=" << r << " T=" << threshold;
      }
    }
  }
}

TEST(DilateChanges, WindowsLargerThanTheImageAreClampedToIt) {
  std::mt19937 rng(4);
  std::vector<uint8_t> scratch;
  for (int r : {6, 20, 64, 127}) {
    Image<uint8_t> in(13, 9, 0), fast(13, 9), reference(13, 9);
    RandomSparseMask(rng, in.view(), 0.01);
    in(12, 8) = 3;  // at least one set pixel, in the far corner
    DilateChanges(in.view(), r, fast.view(), scratch);
    DilateChangesReference(in.view(), r, reference.view());
    EXPECT_TRUE(fast == reference) << "r=" << r;
    if (r >= 13) {
      EXPECT_TRUE(fast == Image<uint8_t>(13, 9, 1)) << "r=" << r;
    }
  }
}

TEST(DilateFloorChanges, FastMatchesBruteForceForRadiiZeroToNineAndOddSizes) {
  std::mt19937 rng(4);
  std::uniform_int_distribution<int> pad(0, 9);
  std::vector<uint8_t> scratch;
  const int sizes[][2] = {{1, 1}, {17, 1}, {3, 5}, {37, 23}, {64, 64}, {5, 99}};
  for (const auto& size : sizes) {
    for (int r = 0; r <= 9; ++r) {
      for (double density : {0.003, 0.1, 0.5}) {
        Padded<uint8_t> in(size[0], size[1], pad(rng)), floor(size[0], size[1], pad(rng));
        RandomSparseMask(rng, in.view(), density);
        RandomSparseMask(rng, floor.view(), 0.6);
        Padded<uint8_t> fast(size[0], size[1], pad(rng), 0xAB), reference(size[0], size[1], pad(rng), 0xCD);
        DilateFloorChanges(in.cview(), floor.cview(), r, fast.view(), scratch);
        DilateFloorChangesReference(in.cview(), floor.cview(), r, reference.view());
        ASSERT_TRUE(SamePixels(fast.cview(), reference.cview()))
            << size[0] << "x" << size[1] << " r=" << r << " density=" << density;
        // Without a floor mask it is DilateChanges.
        DilateFloorChanges(in.cview(), ImageView<const uint8_t>(), r, fast.view(), scratch);
        DilateChangesReference(in.cview(), r, reference.view());
        ASSERT_TRUE(SamePixels(fast.cview(), reference.cview())) << size[0] << "x" << size[1] << " r=" << r;
      }
    }
  }
}

TEST(DilateFloorChanges, AChangeOffTheFloorIsWidenedOffItButNotOntoIt) {
  std::vector<uint8_t> scratch;
  Image<uint8_t> in(12, 10, 0), floor(12, 10, 0), out(12, 10);
  for (int y = 5; y < 10; ++y) {
    for (int x = 0; x < 12; ++x) floor(x, y) = 255;  // rows 5..9 are floor, rows 0..4 a wall
  }
  in(3, 4) = 1;  // on the wall, right above the floor's edge: a shadow on the wall
  in(8, 7) = 1;  // on the floor
  DilateFloorChanges(in.view(), floor.view(), 1, out.view(), scratch);
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 12; ++x) {
      const bool widened_floor_change = std::abs(x - 8) <= 1 && std::abs(y - 7) <= 1;
      const bool widened_on_the_wall = y <= 4 && std::abs(x - 3) <= 1 && y >= 3;
      EXPECT_EQ(out(x, y), (widened_floor_change || widened_on_the_wall) ? 1 : 0) << x << "," << y;
    }
  }
}

TEST(QuantiseChanges, FastMatchesBruteForceOnOddSizesAndStrides) {
  std::mt19937 rng(17);
  for (int bw : {1, 2}) {
    for (int bh : {1, 2}) {
      for (int w : {1, 2, 7, 33, 64}) {
        for (int h : {1, 2, 5, 17}) {
          for (const BlockRule rule : {BlockRule::kAny, BlockRule::kHalf}) {
            Padded<uint8_t> fast(w, h, 3, 9), ref(w, h, 3, 9);
            RandomSparseMask(rng, fast.view(), 0.3);
            ref.buffer = fast.buffer;
            QuantiseChanges(fast.view(), bw, bh, rule);
            QuantiseChangesReference(ref.view(), bw, bh, rule);
            ASSERT_EQ(fast.buffer, ref.buffer) << bw << "x" << bh << " blocks, " << w << "x" << h << " rule "
                                               << static_cast<int>(rule);  // the padding untouched too
          }
        }
      }
    }
  }
}

TEST(QuantiseChanges, OnePixelMarksItsBlockAndBlockOneLeavesTheMask) {
  Image<uint8_t> m(5, 3, 0);
  m(3, 1) = 200;
  m(4, 2) = 1;
  Image<uint8_t> same = m;
  QuantiseChanges(same.view(), 1, 1);
  EXPECT_EQ(same(3, 1), 200);
  QuantiseChanges(m.view(), 2, 2);
  const std::vector<std::vector<int>> expected = {{0, 0, 1, 1, 0}, {0, 0, 1, 1, 0}, {0, 0, 0, 0, 1}};
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 5; ++x) EXPECT_EQ(m(x, y), expected[y][x]) << x << "," << y;
  }
}

TEST(DilateChanges, OnePixelGrowsIntoASquareCutAtTheBorders) {
  std::vector<uint8_t> scratch;
  Image<uint8_t> in(20, 15, 0), out(20, 15);
  in(10, 7) = 200;  // centre
  in(0, 14) = 1;    // bottom-left corner
  DilateChanges(in.view(), 2, out.view(), scratch);
  int64_t set = 0;
  for (int y = 0; y < 15; ++y) {
    for (int x = 0; x < 20; ++x) {
      const bool in_centre_square = std::abs(x - 10) <= 2 && std::abs(y - 7) <= 2;
      const bool in_corner_square = x <= 2 && y >= 12;
      EXPECT_EQ(out(x, y), in_centre_square || in_corner_square ? 1 : 0) << x << "," << y;
      set += out(x, y);
    }
  }
  EXPECT_EQ(set, 25 + 9);
}

TEST(DilateChanges, RadiusZeroCopiesAsOnesAndZeros) {
  std::mt19937 rng(5);
  std::vector<uint8_t> scratch;
  Image<uint8_t> in(31, 11), out(31, 11);
  RandomSparseMask(rng, in.view(), 0.3);
  DilateChanges(in.view(), 0, out.view(), scratch);
  for (int y = 0; y < 11; ++y) {
    for (int x = 0; x < 31; ++x) ASSERT_EQ(out(x, y), in(x, y) != 0 ? 1 : 0);
  }
}

TEST(MaskToChanges, SameSizeMapsNonZeroToOne) {
  std::mt19937 rng(6);
  Padded<uint8_t> mask(33, 17, 5), out(33, 17, 3, 0xAB);
  RandomSparseMask(rng, mask.view(), 0.4);
  MaskToChanges(mask.cview(), out.view());
  for (int y = 0; y < 17; ++y) {
    for (int x = 0; x < 33; ++x) ASSERT_EQ(out.cview()(x, y), mask.cview()(x, y) != 0 ? 1 : 0);
  }
}

TEST(MaskToChanges, FourTimesUpsamplingTurnsEachPixelIntoABlock) {
  std::mt19937 rng(7);
  Image<uint8_t> quarter(12, 7), full(48, 28);
  RandomSparseMask(rng, quarter.view(), 0.5);
  MaskToChanges(quarter.view(), full.view());
  for (int y = 0; y < 28; ++y) {
    for (int x = 0; x < 48; ++x) ASSERT_EQ(full(x, y), quarter(x / 4, y / 4) != 0 ? 1 : 0) << x << "," << y;
  }
}

TEST(MaskToChanges, QuarterSizeReadsThePixelNearestEachBlockCentre) {
  // Block centres of a 4x reduction fall between pixels 4x + 1 and 4x + 2; halves round up.
  std::mt19937 rng(8);
  Image<uint8_t> full(48, 28), quarter(12, 7);
  RandomSparseMask(rng, full.view(), 0.5);
  MaskToChanges(full.view(), quarter.view());
  for (int y = 0; y < 7; ++y) {
    for (int x = 0; x < 12; ++x) ASSERT_EQ(quarter(x, y), full(4 * x + 2, 4 * y + 2) != 0 ? 1 : 0);
  }
  // Constant 4x4 blocks survive a reduction and a blow-up unchanged.
  Image<uint8_t> blocks(48, 28), again(48, 28);
  for (int y = 0; y < 28; ++y) {
    for (int x = 0; x < 48; ++x) blocks(x, y) = quarter(x / 4, y / 4);
  }
  Image<uint8_t> reduced(12, 7);
  MaskToChanges(blocks.view(), reduced.view());
  MaskToChanges(reduced.view(), again.view());
  EXPECT_TRUE(again == blocks);
}

TEST(MaskToChanges, NonIntegerRatiosPickTheNearestPixelCentre) {
  // 5 -> 3 columns: output centres at u = (x + 0.5) * 5 / 3 - 0.5 = 0.33, 2.0, 3.67.
  Image<uint8_t> in(5, 1, 0), out(3, 1);
  const int expected_source[3] = {0, 2, 4};
  for (int source = 0; source < 5; ++source) {
    in(source, 0) = 9;
    MaskToChanges(in.view(), out.view());
    for (int x = 0; x < 3; ++x) EXPECT_EQ(out(x, 0), expected_source[x] == source ? 1 : 0) << source << " " << x;
    in(source, 0) = 0;
  }
  // 3 -> 7 rows: u = (y + 0.5) * 3 / 7 - 0.5 -> rounds to 0, 0, 1, 1, 1, 2, 2.
  Image<uint8_t> column(1, 3, 0), tall(1, 7);
  column(0, 1) = 1;
  MaskToChanges(column.view(), tall.view());
  const uint8_t expected_tall[7] = {0, 0, 1, 1, 1, 0, 0};
  for (int y = 0; y < 7; ++y) EXPECT_EQ(tall(0, y), expected_tall[y]) << y;
}

}  // namespace
}  // namespace occmap
