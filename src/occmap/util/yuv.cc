#include "occmap/util/yuv.h"

#include <algorithm>

namespace occmap {
namespace {

constexpr int kShift = 14;  // weights in units of 2^-14
constexpr int32_t kYr = 4899, kYg = 9617, kYb = 1868;
constexpr int32_t kUr = -2765, kUg = -5427, kUb = 8192;
constexpr int32_t kVr = 8192, kVg = -6860, kVb = -1332;

// 128 + round(sum / (n 2^14)) for a sum of n pixels' weighted values, n = 1 << log2_n.
// sum >= -n 255 2^13, so the numerator is positive and the shift rounds half up.
inline uint8_t MeanChroma(int32_t sum, int log2_n) {
  const int shift = kShift + log2_n;
  const int32_t offset = (128 << shift) + (1 << (shift - 1));
  return static_cast<uint8_t>(std::min((sum + offset) >> shift, 255));
}

}  // namespace

void LumaFromRgb(ImageView<const Rgb8> rgb, Image<uint8_t>& gray) {
  if (gray.width() != rgb.width() || gray.height() != rgb.height()) gray = Image<uint8_t>(rgb.width(), rgb.height());
  for (int y = 0; y < rgb.height(); ++y) {
    const Rgb8* src = rgb.row(y);
    uint8_t* dst = gray.row(y);
    for (int x = 0; x < rgb.width(); ++x) {
      dst[x] = static_cast<uint8_t>((src[x].r * kYr + src[x].g * kYg + src[x].b * kYb + (1 << (kShift - 1))) >> kShift);
    }
  }
}

void ChromaFromRgb(ImageView<const Rgb8> rgb, Image<uint8_t>& u, Image<uint8_t>& v) {
  const int width = rgb.width(), height = rgb.height();
  const int chroma_width = ChromaPlaneSize(width), chroma_height = ChromaPlaneSize(height);
  if (u.width() != chroma_width || u.height() != chroma_height) u = Image<uint8_t>(chroma_width, chroma_height);
  if (v.width() != chroma_width || v.height() != chroma_height) v = Image<uint8_t>(chroma_width, chroma_height);
  for (int j = 0; j < chroma_height; ++j) {
    const Rgb8* row0 = rgb.row(2 * j);
    const Rgb8* row1 = 2 * j + 1 < height ? rgb.row(2 * j + 1) : nullptr;
    uint8_t* u_row = u.row(j);
    uint8_t* v_row = v.row(j);
    for (int i = 0; i < chroma_width; ++i) {
      // Sums of R, G, B over the block's pixels inside the image (1, 2 or 4 of them).
      const int x0 = 2 * i;
      const bool two_columns = x0 + 1 < width;
      int32_t r = row0[x0].r, g = row0[x0].g, b = row0[x0].b;
      if (two_columns) {
        r += row0[x0 + 1].r;
        g += row0[x0 + 1].g;
        b += row0[x0 + 1].b;
      }
      if (row1 != nullptr) {
        r += row1[x0].r;
        g += row1[x0].g;
        b += row1[x0].b;
        if (two_columns) {
          r += row1[x0 + 1].r;
          g += row1[x0 + 1].g;
          b += row1[x0 + 1].b;
        }
      }
      const int log2_n = (two_columns ? 1 : 0) + (row1 != nullptr ? 1 : 0);
      u_row[i] = MeanChroma(r * kUr + g * kUg + b * kUb, log2_n);
      v_row[i] = MeanChroma(r * kVr + g * kVg + b * kVb, log2_n);
    }
  }
}

}  // namespace occmap
