#include "occmap/io/limited_range.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "occmap/util/simd_testing.h"

namespace occmap {
namespace {

// Every value, then random rows of many widths (vector bodies and scalar tails), offset from
// an aligned start so that unaligned loads are exercised too.
template <typename Fast, typename Reference>
void ExpectFastEqualsReference(Fast fast, Reference reference) {
  std::vector<uint8_t> all(256), out(256);
  for (int c = 0; c < 256; ++c) all[static_cast<size_t>(c)] = static_cast<uint8_t>(c);
  fast(all.data(), out.data(), 256);
  for (int c = 0; c < 256; ++c) ASSERT_EQ(out[static_cast<size_t>(c)], reference(static_cast<uint8_t>(c))) << "value " << c;

  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int width : {1, 15, 16, 31, 32, 33, 63, 64, 100, 321, 960, 1921}) {
    for (int offset : {0, 1, 7}) {
      std::vector<uint8_t> src(static_cast<size_t>(width + offset)), dst(static_cast<size_t>(width + offset), 0xAB);
      for (uint8_t& v : src) v = static_cast<uint8_t>(byte(rng));
      fast(src.data() + offset, dst.data() + offset, width);
      for (int x = 0; x < width; ++x) {
        ASSERT_EQ(dst[static_cast<size_t>(x + offset)], reference(src[static_cast<size_t>(x + offset)]))
            << "width " << width << " offset " << offset << " x " << x;
      }
      for (int x = 0; x < offset; ++x) ASSERT_EQ(dst[static_cast<size_t>(x)], 0xAB) << "wrote before the row";
    }
  }
}

// Every kernel set this CPU has (util/simd.h), the portable one included.
class ExpandLimitedRange : public KernelSetTest {};

TEST_P(ExpandLimitedRange, LumaFastPathEqualsItsReference) {
  ExpectFastEqualsReference(ExpandLimitedRangeLuma, ExpandLimitedRangeLumaReference);
}

TEST_P(ExpandLimitedRange, ChromaFastPathEqualsItsReference) {
  ExpectFastEqualsReference(ExpandLimitedRangeChroma, ExpandLimitedRangeChromaReference);
}

INSTANTIATE_TEST_SUITE_P(KernelSets, ExpandLimitedRange, ::testing::Values("portable", "avx2", "avx512"));

TEST(ExpandLimitedRangeLuma, MapsBlackAndWhiteToTheFullRangeWithinOneLevel) {
  EXPECT_EQ(ExpandLimitedRangeLumaReference(16), 0);
  EXPECT_EQ(ExpandLimitedRangeLumaReference(235), 255);
  EXPECT_EQ(ExpandLimitedRangeLumaReference(0), 0);
  EXPECT_EQ(ExpandLimitedRangeLumaReference(255), 255);
  for (int y = 16; y <= 235; ++y) {
    EXPECT_NEAR(ExpandLimitedRangeLumaReference(static_cast<uint8_t>(y)), (y - 16) * 255.0 / 219.0, 1.0) << y;
  }
}

TEST(ExpandLimitedRangeChroma, KeepsNeutralAndRoundsTheExactRatio) {
  EXPECT_EQ(ExpandLimitedRangeChromaReference(128), 128);
  EXPECT_EQ(ExpandLimitedRangeChromaReference(16), 0);
  EXPECT_EQ(ExpandLimitedRangeChromaReference(240), 255);
  EXPECT_EQ(ExpandLimitedRangeChromaReference(3), 0);
  EXPECT_EQ(ExpandLimitedRangeChromaReference(250), 255);
  for (int c = 16; c <= 240; ++c) {
    EXPECT_NEAR(ExpandLimitedRangeChromaReference(static_cast<uint8_t>(c)), (c - 16) * 255.0 / 224.0, 0.5) << c;
  }
}

}  // namespace
}  // namespace occmap
