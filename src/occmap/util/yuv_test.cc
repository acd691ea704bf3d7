#include "occmap/util/yuv.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace occmap {
namespace {

double ExactY(const Rgb8& p) { return 0.299 * p.r + 0.587 * p.g + 0.114 * p.b; }
double ExactU(const Rgb8& p) { return -0.168736 * p.r - 0.331264 * p.g + 0.5 * p.b; }
double ExactV(const Rgb8& p) { return 0.5 * p.r - 0.418688 * p.g - 0.081312 * p.b; }

Image<Rgb8> RandomRgb(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  Image<Rgb8> rgb(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      rgb(x, y) = {static_cast<uint8_t>(byte(rng)), static_cast<uint8_t>(byte(rng)), static_cast<uint8_t>(byte(rng))};
    }
  }
  return rgb;
}

TEST(LumaFromRgb, IsTheBt601LumaRounded) {
  const Image<Rgb8> rgb = RandomRgb(37, 11, 1);
  Image<uint8_t> gray;
  LumaFromRgb(rgb.view(), gray);
  ASSERT_EQ(gray.width(), 37);
  ASSERT_EQ(gray.height(), 11);
  for (int y = 0; y < rgb.height(); ++y) {
    for (int x = 0; x < rgb.width(); ++x) EXPECT_NEAR(gray(x, y), ExactY(rgb(x, y)), 0.51) << x << "," << y;
  }
}

TEST(ChromaFromRgb, GreyHasNeutralChromaAndLumaEqualToItsLevel) {
  Image<Rgb8> rgb(4, 2);
  for (int x = 0; x < 4; ++x) {
    const uint8_t level = static_cast<uint8_t>(x * 85);
    rgb(x, 0) = rgb(x, 1) = {level, level, level};
  }
  Image<uint8_t> gray, u, v;
  LumaFromRgb(rgb.view(), gray);
  ChromaFromRgb(rgb.view(), u, v);
  for (int x = 0; x < 4; ++x) EXPECT_EQ(gray(x, 0), x * 85);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(u(i, 0), 128);
    EXPECT_EQ(v(i, 0), 128);
  }
}

TEST(ChromaFromRgb, PrimariesGiveTheFullRangeBt601Values) {
  // One 2x2 block per colour: white, red, green, blue, and a block of two red and two blue.
  const Rgb8 white{255, 255, 255}, red{255, 0, 0}, green{0, 255, 0}, blue{0, 0, 255};
  Image<Rgb8> rgb(10, 2);
  const Rgb8 blocks[5][4] = {{white, white, white, white}, {red, red, red, red}, {green, green, green, green},
                             {blue, blue, blue, blue},     {red, blue, blue, red}};
  for (int i = 0; i < 5; ++i) {
    rgb(2 * i, 0) = blocks[i][0];
    rgb(2 * i + 1, 0) = blocks[i][1];
    rgb(2 * i, 1) = blocks[i][2];
    rgb(2 * i + 1, 1) = blocks[i][3];
  }
  Image<uint8_t> u, v;
  ChromaFromRgb(rgb.view(), u, v);
  ASSERT_EQ(u.width(), 5);
  ASSERT_EQ(u.height(), 1);
  // U = 128 + (-0.168736 R - 0.331264 G + 0.5 B), V = 128 + (0.5 R - 0.418688 G - 0.081312 B),
  // rounded, clamped: red V = 255.5 -> 255; the mixed block is the mean of red and blue.
  const int expected_u[5] = {128, 85, 44, 255, 170};
  const int expected_v[5] = {128, 255, 21, 107, 181};
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(u(i, 0), expected_u[i]) << "block " << i;
    EXPECT_EQ(v(i, 0), expected_v[i]) << "block " << i;
  }
}

TEST(ChromaFromRgb, OddSizesAverageThePixelsOfTheBlockInsideTheImage) {
  const Image<Rgb8> rgb = RandomRgb(641, 481, 2);
  Image<uint8_t> u, v;
  ChromaFromRgb(rgb.view(), u, v);
  ASSERT_EQ(u.width(), 321);
  ASSERT_EQ(u.height(), 241);
  ASSERT_EQ(v.width(), 321);
  ASSERT_EQ(v.height(), 241);
  int checked = 0;
  for (int j = 0; j < u.height(); ++j) {
    for (int i = 0; i < u.width(); ++i) {
      // Every block of the last row and column, and a sample of the others.
      if (i != u.width() - 1 && j != u.height() - 1 && (i * 7 + j) % 13 != 0) continue;
      double sum_u = 0, sum_v = 0;
      int n = 0;
      for (int y = 2 * j; y < std::min(2 * j + 2, rgb.height()); ++y) {
        for (int x = 2 * i; x < std::min(2 * i + 2, rgb.width()); ++x) {
          sum_u += ExactU(rgb(x, y));
          sum_v += ExactV(rgb(x, y));
          ++n;
        }
      }
      // Fixed-point weights are within 0.03 of the exact values for 8-bit inputs.
      EXPECT_NEAR(u(i, j), std::clamp(128 + sum_u / n, 0.0, 255.0), 0.53) << i << "," << j;
      EXPECT_NEAR(v(i, j), std::clamp(128 + sum_v / n, 0.0, 255.0), 0.53) << i << "," << j;
      ++checked;
    }
  }
  EXPECT_GT(checked, 6000);
}

TEST(ChromaFromRgb, ReusesPlanesOfTheRightSizeAndResizesOthers) {
  const Image<Rgb8> rgb = RandomRgb(5, 3, 3);
  Image<uint8_t> u(3, 2), v(1, 1);
  const uint8_t* u_data = u.row(0);
  ChromaFromRgb(rgb.view(), u, v);
  EXPECT_EQ(u.row(0), u_data);
  EXPECT_EQ(v.width(), 3);
  EXPECT_EQ(v.height(), 2);
}

}  // namespace
}  // namespace occmap
