// Backgrounds: the paper's B[n, c, r], given as an image, or estimated as the per-pixel median
// of K frames when none is given (a person who moves through the K frames does not survive the
// median). Estimated backgrounds are saved by the pipeline so the next run reuses them.
//
// Exactness: a pixel that shows the same background value in more than half of the frames gets
// exactly that value, whatever the other frames show there.
//
//   MedianBackground estimator(width, height);
//   for (...) estimator.Add(frame.view());
//   Image<uint8_t> background = estimator.Median();
#pragma once

#include <cstdint>
#include <vector>

#include "occmap/util/image.h"

namespace occmap {

// Per-pixel median of 1 to kMaxFrames frames. Per-pixel histograms (256 bins) would be too
// big at 1920x1080, so the frames themselves are stored (K bytes per pixel: 255 frames of
// 1920x1080 take 529 MB) and the median taken by selection (std::nth_element per pixel).
class MedianBackground {
 public:
  static constexpr int kMaxFrames = 255;

  MedianBackground(int width, int height);
  // Same size as given to the constructor (a CHECK), any stride. At most kMaxFrames frames
  // (a CHECK: callers stop adding when full()).
  void Add(ImageView<const uint8_t> frame);
  // Optional: room for `frames` frames in all, so that adding them never reallocates (and the
  // memory stays K bytes per pixel instead of up to twice that from geometric growth).
  void Reserve(int frames);
  int count() const { return count_; }
  bool full() const { return count_ >= kMaxFrames; }
  // The lower median for an even count: the value of rank (count - 1) / 2 from 0 in ascending
  // order. Needs at least one frame (a CHECK).
  Image<uint8_t> Median() const;

 private:
  friend class MedianBackgroundRgb;
  // Grows samples_ by one frame and returns where its width_ x height_ bytes go (row-major).
  uint8_t* AppendFrame();

  int width_, height_;
  int count_ = 0;
  std::vector<uint8_t> samples_;  // frame-major: count_ x height_ x width_
};

// Independent medians of R, G and B (the result may mix channels of different frames).
class MedianBackgroundRgb {
 public:
  static constexpr int kMaxFrames = MedianBackground::kMaxFrames;

  MedianBackgroundRgb(int width, int height);
  void Add(ImageView<const Rgb8> frame);
  void Reserve(int frames);
  int count() const { return r_.count(); }
  bool full() const { return r_.full(); }
  Image<Rgb8> Median() const;  // per channel

 private:
  MedianBackground r_, g_, b_;
  int width_, height_;
};

}  // namespace occmap
