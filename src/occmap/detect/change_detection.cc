#include "occmap/detect/change_detection.h"

#include <fmt/core.h>

#include <algorithm>
#include <cstdlib>

namespace occmap {
namespace {

static_assert(sizeof(Rgb8) == 3, "Rgb8 must be three packed bytes");

// The column pass keeps the number of set pixels of each column's window in a byte.
constexpr int kMaxDilationRadius = 127;

template <typename A, typename B>
bool SameSize(ImageView<A> a, ImageView<B> b) {
  return a.width() == b.width() && a.height() == b.height();
}

// |a - b| in bytes, written so that the compiler vectorises it (max - min).
inline uint8_t AbsDiff(uint8_t a, uint8_t b) {
  return static_cast<uint8_t>(std::max(a, b) - std::min(a, b));
}

}  // namespace

Status ChangeDetectionOptions::Validate() const {
  if (threshold < 0 || threshold > 254) {
    return InvalidInput(fmt::format("threshold: expected 0..254 grey levels, found {}", threshold));
  }
  if (tolerance_px < 0 || tolerance_px > kMaxTolerancePx) {
    return InvalidInput(
        fmt::format("tolerance_px: expected 0..{} pixels, found {}", kMaxTolerancePx, tolerance_px));
  }
  if (block_width_px < 1 || block_width_px > 2 || block_height_px < 1 || block_height_px > 2) {
    return InvalidInput(fmt::format("block_px: expected 1 or 2 pixels wide and high, found {} x {}", block_width_px,
                                    block_height_px));
  }
  return Status::Ok();
}

void QuantiseChanges(ImageView<uint8_t> changes, int block_w, int block_h, BlockRule rule) {
  OCCMAP_CHECK(block_w >= 1 && block_w <= 2 && block_h >= 1 && block_h <= 2, "QuantiseChanges: blocks of 1 or 2 pixels");
  if (block_w == 1 && block_h == 1) return;
  const int w = changes.width(), h = changes.height();
  // Of a block's n pixels, c changed: any c >= 1; half 2c >= n (a block of 2: any).
  const bool any = rule == BlockRule::kAny;
  for (int y = 0; y < h; y += block_h) {
    uint8_t* a = changes.row(y);
    uint8_t* b = block_h == 2 && y + 1 < h ? changes.row(y + 1) : a;
    if (block_w == 1) {
      for (int x = 0; x < w; ++x) a[x] = b[x] = (a[x] | b[x]) != 0;
      continue;
    }
    int x = 0;
    if (any || a == b) {
      for (; x + 2 <= w; x += 2) {
        const uint8_t v = (a[x] | a[x + 1] | b[x] | b[x + 1]) != 0;
        a[x] = a[x + 1] = b[x] = b[x + 1] = v;
      }
    } else {
      for (; x + 2 <= w; x += 2) {
        const int c = (a[x] != 0) + (a[x + 1] != 0) + (b[x] != 0) + (b[x + 1] != 0);
        a[x] = a[x + 1] = b[x] = b[x + 1] = c >= 2;
      }
    }
    if (x < w) a[x] = b[x] = (a[x] | b[x]) != 0;
  }
}

void QuantiseChangesReference(ImageView<uint8_t> changes, int block_w, int block_h, BlockRule rule) {
  if (block_w == 1 && block_h == 1) return;
  const int w = changes.width(), h = changes.height();
  for (int by = 0; by < h; by += block_h) {
    for (int bx = 0; bx < w; bx += block_w) {
      int n = 0, c = 0;
      for (int y = by; y < std::min(h, by + block_h); ++y) {
        for (int x = bx; x < std::min(w, bx + block_w); ++x) {
          ++n;
          c += changes.row(y)[x] != 0;
        }
      }
      const uint8_t v = rule == BlockRule::kAny ? c >= 1 : 2 * c >= n;
      for (int y = by; y < std::min(h, by + block_h); ++y) {
        for (int x = bx; x < std::min(w, bx + block_w); ++x) changes.row(y)[x] = v;
      }
    }
  }
}

void DetectChangesGray(ImageView<const uint8_t> frame, ImageView<const uint8_t> background, int threshold,
                       ImageView<uint8_t> out) {
  OCCMAP_CHECK(SameSize(frame, background) && SameSize(frame, out), "change detection: image sizes differ");
  OCCMAP_CHECK(threshold >= 0 && threshold <= 255, "change detection: threshold outside 0..255");
  const uint8_t t = static_cast<uint8_t>(threshold);
  const int width = frame.width();
  for (int y = 0; y < frame.height(); ++y) {
    const uint8_t* f = frame.row(y);
    const uint8_t* b = background.row(y);
    uint8_t* o = out.row(y);
    for (int x = 0; x < width; ++x) o[x] = static_cast<uint8_t>(AbsDiff(f[x], b[x]) > t);
  }
}

void DetectChangesGrayReference(ImageView<const uint8_t> frame, ImageView<const uint8_t> background,
                                int threshold, ImageView<uint8_t> out) {
  OCCMAP_CHECK(SameSize(frame, background) && SameSize(frame, out), "change detection: image sizes differ");
  for (int y = 0; y < frame.height(); ++y) {
    for (int x = 0; x < frame.width(); ++x) {
      const int difference = std::abs(int{frame(x, y)} - int{background(x, y)});
      out(x, y) = difference > threshold ? 1 : 0;
    }
  }
}

void DetectChangesRgb(ImageView<const Rgb8> frame, ImageView<const Rgb8> background, int threshold,
                      ImageView<uint8_t> out) {
  OCCMAP_CHECK(SameSize(frame, background) && SameSize(frame, out), "change detection: image sizes differ");
  OCCMAP_CHECK(threshold >= 0 && threshold <= 255, "change detection: threshold outside 0..255");
  const uint8_t t = static_cast<uint8_t>(threshold);
  const int width = frame.width();
  for (int y = 0; y < frame.height(); ++y) {
    const Rgb8* f = frame.row(y);
    const Rgb8* b = background.row(y);
    uint8_t* o = out.row(y);
    for (int x = 0; x < width; ++x) {
      const uint8_t d = std::max({AbsDiff(f[x].r, b[x].r), AbsDiff(f[x].g, b[x].g), AbsDiff(f[x].b, b[x].b)});
      o[x] = static_cast<uint8_t>(d > t);
    }
  }
}

void DetectChangesRgbReference(ImageView<const Rgb8> frame, ImageView<const Rgb8> background, int threshold,
                               ImageView<uint8_t> out) {
  OCCMAP_CHECK(SameSize(frame, background) && SameSize(frame, out), "change detection: image sizes differ");
  for (int y = 0; y < frame.height(); ++y) {
    for (int x = 0; x < frame.width(); ++x) {
      const Rgb8 f = frame(x, y), b = background(x, y);
      const int dr = std::abs(int{f.r} - int{b.r});
      const int dg = std::abs(int{f.g} - int{b.g});
      const int db = std::abs(int{f.b} - int{b.b});
      out(x, y) = (dr > threshold || dg > threshold || db > threshold) ? 1 : 0;
    }
  }
}

namespace {

// dst[x] = OR of src[x - r .. x + r] clipped to the row (w pixels): shifted ORs the compiler
// vectorises.
void OrRowNeighbours(const uint8_t* src, size_t w, int r, uint8_t* dst) {
  for (size_t x = 0; x < w; ++x) dst[x] = src[x];
  for (size_t shift = 1; shift <= static_cast<size_t>(r) && shift < w; ++shift) {
    for (size_t x = 0; x + shift < w; ++x) dst[x] |= src[x + shift];  // right neighbours
    for (size_t x = shift; x < w; ++x) dst[x] |= src[x - shift];      // left neighbours
  }
}

}  // namespace

// Up to this radius the dilation ORs shifted rows (cost grows with r); beyond, running counts
// (cost independent of r).
constexpr int kSmallDilationRadius = 4;

namespace {

// DilateChanges of in's pixels where floor is non-zero (all of them when floor is empty).
void DilateWithin(ImageView<const uint8_t> in, ImageView<const uint8_t> floor, int radius_px, ImageView<uint8_t> out,
                  std::vector<uint8_t>& scratch) {
  OCCMAP_CHECK(SameSize(in, out), "dilation: image sizes differ");
  OCCMAP_CHECK(floor.empty() || SameSize(in, floor), "dilation: the floor mask's size differs");
  OCCMAP_CHECK(radius_px >= 0 && radius_px <= kMaxDilationRadius, "dilation: radius outside 0..127");
  const int width = in.width(), height = in.height();
  if (width == 0 || height == 0) return;
  const size_t w = static_cast<size_t>(width);
  // scratch: height rows of the row pass (1 / 0), one row of per-column window counts, and one
  // row of in's pixels on the floor.
  const size_t needed = w * static_cast<size_t>(height) + 2 * w;
  if (scratch.size() < needed) scratch.resize(needed);
  uint8_t* rows = scratch.data();
  uint8_t* counts = scratch.data() + w * static_cast<size_t>(height);
  uint8_t* on_floor = counts + w;
  const int r = radius_px;
  auto source_row = [&](int y) -> const uint8_t* {
    if (floor.empty()) return in.row(y);
    const uint8_t* a = in.row(y);
    const uint8_t* f = floor.row(y);
    for (size_t x = 0; x < w; ++x) on_floor[x] = f[x] != 0 ? a[x] : uint8_t{0};
    return on_floor;
  };

  if (r <= kSmallDilationRadius) {
    // Small radii: ORs of shifted rows, which the compiler vectorises (64 pixels per
    // instruction with AVX-512) where running counts go pixel by pixel. Row pass: 1 where any
    // pixel of [x - r, x + r], clipped to the row, is set.
    for (int y = 0; y < height; ++y) {
      const uint8_t* src = source_row(y);
      uint8_t* dst = rows + static_cast<size_t>(y) * w;
      OrRowNeighbours(src, w, r, dst);
      for (size_t x = 0; x < w; ++x) dst[x] = static_cast<uint8_t>(dst[x] != 0);
    }
    // Column pass: the OR of the row-pass rows [y - r, y + r], clipped to the image.
    for (int y = 0; y < height; ++y) {
      uint8_t* dst = out.row(y);
      const int lo = std::max(0, y - r), hi = std::min(height - 1, y + r);
      const uint8_t* first = rows + static_cast<size_t>(lo) * w;
      for (size_t x = 0; x < w; ++x) dst[x] = first[x];
      for (int v = lo + 1; v <= hi; ++v) {
        const uint8_t* add = rows + static_cast<size_t>(v) * w;
        for (size_t x = 0; x < w; ++x) dst[x] |= add[x];
      }
    }
    return;
  }

  // Larger radii. Row pass: a running count of the non-zero pixels in [x - r, x + r] clipped to the row.
  for (int y = 0; y < height; ++y) {
    const uint8_t* src = source_row(y);
    uint8_t* dst = rows + static_cast<size_t>(y) * w;
    int count = 0;
    for (int x = 0; x < std::min(r, width); ++x) count += src[x] != 0;  // [0, r) before x = 0
    for (int x = 0; x < width; ++x) {
      if (x + r < width) count += src[x + r] != 0;     // enters the window
      dst[x] = static_cast<uint8_t>(count != 0);
      if (x - r >= 0) count -= src[x - r] != 0;        // leaves it before x + 1
    }
  }

  // Column pass, row by row so that every step runs along contiguous rows: counts[x] is the
  // number of set row-pass pixels in rows [y - r, y + r] of column x (at most 2r + 1 <= 255).
  std::fill(counts, counts + w, uint8_t{0});
  for (int y = 0; y < std::min(r, height); ++y) {
    const uint8_t* add = rows + static_cast<size_t>(y) * w;
    for (size_t x = 0; x < w; ++x) counts[x] = static_cast<uint8_t>(counts[x] + add[x]);
  }
  for (int y = 0; y < height; ++y) {
    if (y + r < height) {
      const uint8_t* add = rows + static_cast<size_t>(y + r) * w;
      for (size_t x = 0; x < w; ++x) counts[x] = static_cast<uint8_t>(counts[x] + add[x]);
    }
    uint8_t* dst = out.row(y);
    for (size_t x = 0; x < w; ++x) dst[x] = static_cast<uint8_t>(counts[x] != 0);
    if (y - r >= 0) {
      const uint8_t* sub = rows + static_cast<size_t>(y - r) * w;
      for (size_t x = 0; x < w; ++x) counts[x] = static_cast<uint8_t>(counts[x] - sub[x]);
    }
  }
}

}  // namespace

void DilateChanges(ImageView<const uint8_t> in, int radius_px, ImageView<uint8_t> out,
                   std::vector<uint8_t>& scratch) {
  DilateWithin(in, ImageView<const uint8_t>(), radius_px, out, scratch);
}

void DilateFloorChanges(ImageView<const uint8_t> in, ImageView<const uint8_t> floor_mask, int radius_px,
                        ImageView<uint8_t> out, std::vector<uint8_t>& scratch) {
  if (floor_mask.empty()) {
    DilateChanges(in, radius_px, out, scratch);
    return;
  }
  OCCMAP_CHECK(SameSize(in, out) && SameSize(in, floor_mask), "dilation: image sizes differ");
  const size_t w = static_cast<size_t>(in.width()), h = static_cast<size_t>(in.height());
  if (w == 0 || h == 0) return;
  // scratch: DilateWithin's (h + 2 rows of w), then the floor's own widening (w x h).
  const size_t own = w * h + 2 * w;
  if (scratch.size() < own + w * h) scratch.resize(own + w * h);
  const ImageView<uint8_t> on_floor(scratch.data() + own, in.width(), in.height(), in.width());
  DilateWithin(in, floor_mask, radius_px, on_floor, scratch);
  DilateWithin(in, ImageView<const uint8_t>(), radius_px, out, scratch);
  for (size_t y = 0; y < h; ++y) {
    const uint8_t* a = in.row(static_cast<int>(y));
    const uint8_t* f = floor_mask.row(static_cast<int>(y));
    const uint8_t* d = on_floor.row(static_cast<int>(y));
    uint8_t* o = out.row(static_cast<int>(y));
    for (size_t x = 0; x < w; ++x) {
      if (f[x] != 0) o[x] = static_cast<uint8_t>(d[x] | (a[x] != 0));
    }
  }
}

void DetectChangesGrayDilated(ImageView<const uint8_t> frame, ImageView<const uint8_t> background, int threshold,
                              int radius_px, ImageView<uint8_t> out, std::vector<uint8_t>& scratch) {
  OCCMAP_CHECK(SameSize(frame, background) && SameSize(frame, out), "change detection: image sizes differ");
  OCCMAP_CHECK(threshold >= 0 && threshold <= 255, "change detection: threshold outside 0..255");
  OCCMAP_CHECK(radius_px >= 0 && radius_px <= kMaxDilationRadius, "dilation: radius outside 0..127");
  const int width = frame.width(), height = frame.height();
  if (width == 0 || height == 0) return;
  const uint8_t t = static_cast<uint8_t>(threshold);
  const int r = radius_px;
  const size_t w = static_cast<size_t>(width);
  const int ring_rows = 2 * r + 1;
  // scratch: a ring of 2r + 1 row-dilated change rows, then one row of raw changes.
  const size_t needed = w * static_cast<size_t>(ring_rows) + w;
  if (scratch.size() < needed) scratch.resize(needed);
  uint8_t* ring = scratch.data();
  uint8_t* raw = scratch.data() + w * static_cast<size_t>(ring_rows);
  auto ring_row = [&](int y) { return ring + static_cast<size_t>(y % ring_rows) * w; };
  // Row y's changes, dilated along the row, into its ring slot.
  auto make_row = [&](int y) {
    const uint8_t* f = frame.row(y);
    const uint8_t* b = background.row(y);
    for (size_t x = 0; x < w; ++x) raw[x] = static_cast<uint8_t>(AbsDiff(f[x], b[x]) > t);
    OrRowNeighbours(raw, w, r, ring_row(y));
  };
  int made = 0;  // rows [0, made) have been made
  for (int y = 0; y < height; ++y) {
    const int lo = std::max(0, y - r), hi = std::min(height - 1, y + r);
    while (made <= hi) make_row(made++);
    uint8_t* dst = out.row(y);
    const uint8_t* first = ring_row(lo);
    for (size_t x = 0; x < w; ++x) dst[x] = first[x];
    for (int v = lo + 1; v <= hi; ++v) {
      const uint8_t* add = ring_row(v);
      for (size_t x = 0; x < w; ++x) dst[x] |= add[x];
    }
  }
}

void DilateChangesReference(ImageView<const uint8_t> in, int radius_px, ImageView<uint8_t> out) {
  OCCMAP_CHECK(SameSize(in, out), "dilation: image sizes differ");
  OCCMAP_CHECK(radius_px >= 0, "dilation: negative radius");
  for (int y = 0; y < in.height(); ++y) {
    for (int x = 0; x < in.width(); ++x) {
      uint8_t set = 0;
      for (int v = std::max(0, y - radius_px); v <= std::min(in.height() - 1, y + radius_px); ++v) {
        for (int u = std::max(0, x - radius_px); u <= std::min(in.width() - 1, x + radius_px); ++u) {
          if (in(u, v) != 0) set = 1;
        }
      }
      out(x, y) = set;
    }
  }
}

void DilateFloorChangesReference(ImageView<const uint8_t> in, ImageView<const uint8_t> floor_mask, int radius_px,
                                 ImageView<uint8_t> out) {
  OCCMAP_CHECK(SameSize(in, out) && (floor_mask.empty() || SameSize(in, floor_mask)), "dilation: image sizes differ");
  for (int y = 0; y < in.height(); ++y) {
    for (int x = 0; x < in.width(); ++x) {
      const bool on_floor = floor_mask.empty() || floor_mask(x, y) != 0;
      uint8_t set = in(x, y) != 0;
      for (int v = std::max(0, y - radius_px); v <= std::min(in.height() - 1, y + radius_px); ++v) {
        for (int u = std::max(0, x - radius_px); u <= std::min(in.width() - 1, x + radius_px); ++u) {
          if (in(u, v) != 0 && (!on_floor || floor_mask.empty() || floor_mask(u, v) != 0)) set = 1;
        }
      }
      out(x, y) = set;
    }
  }
}

void MaskToChanges(ImageView<const uint8_t> mask, ImageView<uint8_t> out) {
  OCCMAP_CHECK(mask.empty() == out.empty(), "mask resampling: one image is empty");
  if (out.empty()) return;
  const int64_t w_in = mask.width(), h_in = mask.height();
  const int64_t w_out = out.width(), h_out = out.height();
  // floor((x + 0.5) * w_in / w_out) = floor((2x + 1) * w_in / (2 w_out)), always < w_in.
  auto source = [](int64_t x, int64_t n_in, int64_t n_out) {
    return static_cast<int>(((2 * x + 1) * n_in) / (2 * n_out));
  };
  for (int y = 0; y < out.height(); ++y) {
    const uint8_t* src = mask.row(source(y, h_in, h_out));
    uint8_t* dst = out.row(y);
    if (w_in == w_out) {
      for (int x = 0; x < out.width(); ++x) dst[x] = static_cast<uint8_t>(src[x] != 0);
    } else {
      for (int x = 0; x < out.width(); ++x) dst[x] = static_cast<uint8_t>(src[source(x, w_in, w_out)] != 0);
    }
  }
}

}  // namespace occmap
