#include "occmap/detect/background.h"

#include <algorithm>
#include <cstring>

#include "occmap/util/status.h"

namespace occmap {
namespace {

// Pixels whose samples are gathered together before selection: the K samples of a pixel are
// width * height bytes apart, so the block is transposed into a small buffer first
// (kBlockPixels x K bytes, at most 64 KiB) rather than read one strided byte at a time.
constexpr size_t kBlockPixels = 256;

}  // namespace

MedianBackground::MedianBackground(int width, int height) : width_(width), height_(height) {
  OCCMAP_CHECK(width >= 0 && height >= 0, "median background: negative size");
}

void MedianBackground::Reserve(int frames) {
  const size_t frame_bytes = static_cast<size_t>(width_) * static_cast<size_t>(height_);
  samples_.reserve(static_cast<size_t>(std::clamp(frames, 0, kMaxFrames)) * frame_bytes);
}

uint8_t* MedianBackground::AppendFrame() {
  OCCMAP_CHECK(count_ < kMaxFrames, "median background: more than 255 frames");
  const size_t frame_bytes = static_cast<size_t>(width_) * static_cast<size_t>(height_);
  samples_.resize(samples_.size() + frame_bytes);
  ++count_;
  return samples_.data() + (samples_.size() - frame_bytes);
}

void MedianBackground::Add(ImageView<const uint8_t> frame) {
  OCCMAP_CHECK(frame.width() == width_ && frame.height() == height_, "median background: frame size differs");
  uint8_t* dst = AppendFrame();
  for (int y = 0; y < height_; ++y) {
    if (width_ > 0) std::memcpy(dst + static_cast<size_t>(y) * width_, frame.row(y), static_cast<size_t>(width_));
  }
}

Image<uint8_t> MedianBackground::Median() const {
  OCCMAP_CHECK(count_ > 0, "median background: no frames added");
  Image<uint8_t> out(width_, height_);
  const size_t num_pixels = static_cast<size_t>(width_) * static_cast<size_t>(height_);
  const size_t k = static_cast<size_t>(count_);
  const size_t rank = (k - 1) / 2;  // the lower median
  std::vector<uint8_t> block(kBlockPixels * k);
  for (size_t begin = 0; begin < num_pixels; begin += kBlockPixels) {
    const size_t n = std::min(kBlockPixels, num_pixels - begin);
    // block[p * k + f] = sample of pixel begin + p in frame f.
    for (size_t f = 0; f < k; ++f) {
      const uint8_t* src = samples_.data() + f * num_pixels + begin;
      for (size_t p = 0; p < n; ++p) block[p * k + f] = src[p];
    }
    for (size_t p = 0; p < n; ++p) {
      uint8_t* samples = block.data() + p * k;
      std::nth_element(samples, samples + rank, samples + k);
      const size_t pixel = begin + p, w = static_cast<size_t>(width_);
      out(static_cast<int>(pixel % w), static_cast<int>(pixel / w)) = samples[rank];
    }
  }
  return out;
}

MedianBackgroundRgb::MedianBackgroundRgb(int width, int height)
    : r_(width, height), g_(width, height), b_(width, height), width_(width), height_(height) {}

void MedianBackgroundRgb::Reserve(int frames) {
  r_.Reserve(frames);
  g_.Reserve(frames);
  b_.Reserve(frames);
}

void MedianBackgroundRgb::Add(ImageView<const Rgb8> frame) {
  OCCMAP_CHECK(frame.width() == width_ && frame.height() == height_, "median background: frame size differs");
  uint8_t* r = r_.AppendFrame();
  uint8_t* g = g_.AppendFrame();
  uint8_t* b = b_.AppendFrame();
  for (int y = 0; y < height_; ++y) {
    const Rgb8* src = frame.row(y);
    const size_t row_start = static_cast<size_t>(y) * static_cast<size_t>(width_);
    for (int x = 0; x < width_; ++x) {
      r[row_start + x] = src[x].r;
      g[row_start + x] = src[x].g;
      b[row_start + x] = src[x].b;
    }
  }
}

Image<Rgb8> MedianBackgroundRgb::Median() const {
  const Image<uint8_t> r = r_.Median(), g = g_.Median(), b = b_.Median();
  Image<Rgb8> out(width_, height_);
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) out(x, y) = {r(x, y), g(x, y), b(x, y)};
  }
  return out;
}

}  // namespace occmap
