// Image<T>: an owning single-plane image with 64-byte-aligned rows; ImageView<T>: a borrow.
//
// Invariants: width, height >= 0; stride_elems >= width; every row starts on a 64-byte
// boundary (so SIMD loads of a row never split a cache line at its start). Pixel (x, y) is
// column x, row y; row 0 is the top of the picture. Functions take views and return owning
// images. Zero-copy interop with cv::Mat happens at the I/O boundary only (image_io.h).
//
//   Image<uint8_t> mask(1920, 1080, 0);
//   mask(10, 20) = 255;
//   ImageView<const uint8_t> view = mask.view();
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <numeric>
#include <type_traits>
#include <utility>

#include "occmap/util/status.h"

namespace occmap {

struct Rgb8 {
  uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb8&, const Rgb8&) = default;
};

template <typename T>
class ImageView {
 public:
  ImageView() = default;
  ImageView(T* data, int width, int height, ptrdiff_t stride_elems)
      : data_(data), width_(width), height_(height), stride_(stride_elems) {}
  // A view of T converts to a view of const T.
  operator ImageView<const T>() const { return {data_, width_, height_, stride_}; }  // NOLINT

  int width() const { return width_; }
  int height() const { return height_; }
  ptrdiff_t stride_elems() const { return stride_; }
  bool empty() const { return width_ == 0 || height_ == 0; }
  T* row(int y) const { return data_ + static_cast<ptrdiff_t>(y) * stride_; }
  T& operator()(int x, int y) const { return row(y)[x]; }
  T* data() const { return data_; }
  bool contiguous() const { return stride_ == width_; }

 private:
  T* data_ = nullptr;
  int width_ = 0;
  int height_ = 0;
  ptrdiff_t stride_ = 0;
};

template <typename T>
class Image {
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  static constexpr size_t kRowAlignment = 64;

  Image() = default;
  Image(int width, int height) { Allocate(width, height); }
  Image(int width, int height, T fill) {
    Allocate(width, height);
    for (int y = 0; y < height_; ++y) {
      T* r = row(y);
      for (int x = 0; x < width_; ++x) r[x] = fill;
    }
  }
  Image(const Image& other) { *this = other; }
  Image& operator=(const Image& other) {
    if (this == &other) return *this;
    Allocate(other.width_, other.height_);
    for (int y = 0; y < height_; ++y) std::memcpy(row(y), other.row(y), sizeof(T) * width_);
    return *this;
  }
  Image(Image&&) noexcept = default;
  Image& operator=(Image&&) noexcept = default;

  int width() const { return width_; }
  int height() const { return height_; }
  ptrdiff_t stride_elems() const { return stride_; }
  bool empty() const { return width_ == 0 || height_ == 0; }
  T* row(int y) { return data_.get() + static_cast<ptrdiff_t>(y) * stride_; }
  const T* row(int y) const { return data_.get() + static_cast<ptrdiff_t>(y) * stride_; }
  T& operator()(int x, int y) { return row(y)[x]; }
  const T& operator()(int x, int y) const { return row(y)[x]; }

  ImageView<T> view() { return {data_.get(), width_, height_, stride_}; }
  ImageView<const T> view() const { return {data_.get(), width_, height_, stride_}; }

  friend bool operator==(const Image& a, const Image& b) {
    if (a.width_ != b.width_ || a.height_ != b.height_) return false;
    for (int y = 0; y < a.height_; ++y) {
      if (std::memcmp(a.row(y), b.row(y), sizeof(T) * a.width_) != 0) return false;
    }
    return true;
  }

 private:
  struct AlignedFree {
    void operator()(T* p) const { ::operator delete[](p, std::align_val_t(kRowAlignment)); }
  };
  void Allocate(int width, int height) {
    OCCMAP_CHECK(width >= 0 && height >= 0, "negative image size");
    width_ = width;
    height_ = height;
    // Rows are a multiple of lcm(64, sizeof(T)) bytes so that each one starts 64-byte aligned.
    const size_t unit = std::lcm(kRowAlignment, sizeof(T));
    const size_t row_bytes = (sizeof(T) * static_cast<size_t>(width) + unit - 1) / unit * unit;
    stride_ = static_cast<ptrdiff_t>(row_bytes / sizeof(T));
    const size_t total = row_bytes * static_cast<size_t>(height);
    // A copy into an image of the same size or larger keeps its buffer (no new pages per copy).
    if (data_ && total <= capacity_bytes_ && total > 0) return;
    data_.reset(total == 0 ? nullptr
                           : static_cast<T*>(::operator new[](total, std::align_val_t(kRowAlignment))));
    capacity_bytes_ = total;
  }

  std::unique_ptr<T[], AlignedFree> data_;
  size_t capacity_bytes_ = 0;  // of data_ (meaningful only while data_ is set)
  int width_ = 0;
  int height_ = 0;
  ptrdiff_t stride_ = 0;
};

}  // namespace occmap
