#include "occmap/detect/background.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace occmap {
namespace {

Image<uint8_t> RandomImage(std::mt19937& rng, int width, int height) {
  std::uniform_int_distribution<int> value(0, 255);
  Image<uint8_t> image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) image(x, y) = static_cast<uint8_t>(value(rng));
  }
  return image;
}

TEST(MedianBackground, PixelsCoveredInFewerThanHalfTheFramesRecoverTheBackgroundExactly) {
  // A 60-pixel-wide object of random values (above and below the background) walks across a
  // 301 x 7 background, 20 pixels a step over 11 frames: each pixel is covered in up to 3 of
  // the 11 frames, fewer than half.
  std::mt19937 rng(1);
  const int width = 301, height = 7, frames = 11;
  const Image<uint8_t> background = RandomImage(rng, width, height);
  MedianBackground estimator(width, height);
  std::vector<int> covered(width, 0);
  for (int f = 0; f < frames; ++f) {
    Image<uint8_t> frame = background;
    const Image<uint8_t> object = RandomImage(rng, width, height);
    for (int x = f * 20; x < std::min(width, f * 20 + 60); ++x) {
      ++covered[x];
      for (int y = 0; y < height; ++y) frame(x, y) = object(x, y);
    }
    estimator.Add(frame.view());
  }
  EXPECT_EQ(estimator.count(), frames);
  EXPECT_EQ(*std::max_element(covered.begin(), covered.end()), 3);
  EXPECT_TRUE(estimator.Median() == background);
}

TEST(MedianBackground, EvenCountGivesTheLowerMedian) {
  MedianBackground estimator(3, 1);
  // Pixel 0: {40, 10, 30, 20} -> 20; pixel 1: {7, 9} then more; pixel 2: all 5 but one 200.
  const uint8_t values[4][3] = {{40, 7, 5}, {10, 9, 5}, {30, 255, 200}, {20, 0, 5}};
  for (const auto& v : values) {
    Image<uint8_t> frame(3, 1);
    for (int x = 0; x < 3; ++x) frame(x, 0) = v[x];
    estimator.Add(frame.view());
  }
  const Image<uint8_t> median = estimator.Median();
  EXPECT_EQ(median(0, 0), 20);  // sorted 10 20 | 30 40
  EXPECT_EQ(median(1, 0), 7);   // sorted 0 7 | 9 255
  EXPECT_EQ(median(2, 0), 5);   // sorted 5 5 | 5 200
  MedianBackground two(1, 1);
  Image<uint8_t> a(1, 1, 40), b(1, 1, 10);
  two.Add(a.view());
  two.Add(b.view());
  EXPECT_EQ(two.Median()(0, 0), 10);
  MedianBackground one(1, 1);
  one.Add(a.view());
  EXPECT_EQ(one.Median()(0, 0), 40);
}

TEST(MedianBackground, MatchesSortingOnRandomFramesUpToTheMaximumCount) {
  std::mt19937 rng(2);
  for (int frames : {1, 2, 3, 8, 255}) {
    const int width = 37, height = 11;  // more pixels than one selection block, odd sizes
    MedianBackground estimator(width, height);
    estimator.Reserve(frames);
    std::vector<Image<uint8_t>> all;
    for (int f = 0; f < frames; ++f) {
      all.push_back(RandomImage(rng, width, height));
      estimator.Add(all.back().view());
    }
    EXPECT_TRUE(estimator.full() == (frames == MedianBackground::kMaxFrames));
    const Image<uint8_t> median = estimator.Median();
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        std::vector<uint8_t> v;
        for (const auto& image : all) v.push_back(image(x, y));
        std::sort(v.begin(), v.end());
        ASSERT_EQ(median(x, y), v[(v.size() - 1) / 2]) << frames << " frames, pixel " << x << "," << y;
      }
    }
  }
}

TEST(MedianBackground, AcceptsStridedFrames) {
  std::vector<uint8_t> buffer(5 * 3 + 2, 99);  // a 3 x 3 view with stride 5, offset 1
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 3; ++x) buffer[static_cast<size_t>(1 + y * 5 + x)] = static_cast<uint8_t>(10 * y + x);
  }
  MedianBackground estimator(3, 3);
  estimator.Add(ImageView<const uint8_t>(buffer.data() + 1, 3, 3, 5));
  const Image<uint8_t> median = estimator.Median();
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 3; ++x) EXPECT_EQ(median(x, y), 10 * y + x);
  }
}

TEST(MedianBackgroundRgb, TakesTheMedianOfEachChannelSeparately) {
  MedianBackgroundRgb estimator(2, 1);
  // Pixel 0: the channels order the frames differently, so the result is no single frame's
  // colour. Pixel 1: a red object in 2 of 5 frames over a grey background.
  const Rgb8 p0[5] = {{1, 90, 50}, {2, 80, 10}, {3, 70, 40}, {4, 60, 20}, {5, 50, 30}};
  const Rgb8 grey{120, 121, 122}, red{250, 0, 0};
  for (int f = 0; f < 5; ++f) {
    Image<Rgb8> frame(2, 1);
    frame(0, 0) = p0[f];
    frame(1, 0) = (f == 1 || f == 3) ? red : grey;
    estimator.Add(frame.view());
  }
  EXPECT_EQ(estimator.count(), 5);
  const Image<Rgb8> median = estimator.Median();
  EXPECT_EQ(median(0, 0), (Rgb8{3, 70, 30}));
  EXPECT_EQ(median(1, 0), grey);
}

}  // namespace
}  // namespace occmap
