// Column fusion: the paper's AND (equation 5) asked of the vertical column above a floor
// position instead of its floor cell. A candidate position (lut/column_lut.h) is occupied when
// every active camera that sees it sees change over at least min_changed of the image of the
// column's band (z from band_low_m to band_high_m, radius_m around the axis); cameras whose
// view of it a static occluder hides, or whose image holds less than half of the band's rows,
// abstain; a camera that sees the band with the feet below its image (ColumnView::feet_cut: a
// person close to it) tests. Tri-state as the floor AND (Fusion): unseen when fewer than
// min_views cameras test it, occupied when every testing camera says changed, or when at most
// max_free_views say free and at least min_changed_views others say changed.
//
// Why: legs leave the floor cell under a person unchanged in some views (the floor AND misses
// the person), while the band above it is a torso in every view that sees it; a static occluder
// in front of a person turns one camera's "unchanged" into "cannot tell". The vote: a coat of the
// wall's colour behind it leaves a torso unchanged in one view (real footage: a dark jacket
// against a dark parapet), which the strict AND turns into a missed person; two other views that
// see the torso changed outvote it. The ghosts this lets in (where two views' silhouettes cross)
// are what the views' explanation removes (view_explainer.h).
//
// Counting: each camera's changes are summed along rows once per frame (ChangeRowSums), so a
// row of a span costs two reads; at most max_rows rows of the band are read per camera (evenly
// spaced), after a first look at 4 of them: a camera that sees less than half of min_changed
// there votes free at once (most columns are empty). The first look's rows and spans are worked
// out once for the band and radius (the plan: per candidate, the cameras that test it and
// their spans), so a frame reads only counts. Fuse takes every camera's first look before any
// camera's whole band (the state depends only on how many cameras test and vote free, not on the
// order). ColumnFusion::FuseReference counts the same rows pixel by pixel, camera after camera,
// working out every span (equal, tested).
//
//   ChangeRowSums counts[n]; counts[n].Build(changes_n);
//   ColumnFusion fusion(columns);
//   fusion.Fuse(counts, active, options, ctx, column_map);
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/lut/column_lut.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

struct ColumnFusionOptions {
  double band_low_m = 0.3;    // the band of the column tested, above the floor plane
  double band_high_m = 1.5;
  double radius_m = 0.1;      // its half-width
  double min_changed = 0.5;   // the fraction of its pixels that must have changed
  int max_free_views = 1;     // views that may say free (0 .. max(1, cameras - 1)) ...
  int min_changed_views = 2;  // ... when at least this many say changed
  // Cameras that must test a position (fewer: unseen), or all active ones when fewer are
  // active: one view cannot place a person on the floor, and what a single view sees changed
  // at the floor's edge (a wall the exposure brightens, a person in front) is not a person there.
  int min_views = 2;
  int max_rows = 24;          // rows of the band read per camera (evenly spaced)
  Status Validate(double column_height_m, int num_cameras) const;
};

// One camera's changes as bits with a count per 64-pixel word: Count(y, x0, x1) is the number
// of changed pixels (non-zero) in row y from column x0 to x1 inclusive, in constant time.
// Why bits: building them reads the mask once and writes an eighth of it (16-bit sums per pixel
// wrote twice the mask's bytes), and the tables the counts read stay in the caches.
// A span within two words (a column's or a person's, mostly) is counted from its words alone,
// masked at both ends; a longer one from the sums. Bits are counted with the POPCNT instruction
// when Build ran under the AVX2 or AVX-512 kernel set (every such CPU has it), else portably.
class ChangeRowSums {
 public:
  // Images up to 65535 pixels wide (checked).
  void Build(ImageView<const uint8_t> changes);
  int width() const { return width_; }
  int height() const { return height_; }
  int Count(int y, int x0, int x1) const {
    if (x1 < x0) return 0;
    const int w0 = x0 >> 6, w1 = x1 >> 6;
    if (w1 - w0 > 1) return Before(y, x1 + 1) - Before(y, x0);
    const uint64_t* bits = row_bits(y);
    const uint64_t first = ~uint64_t{0} << (x0 & 63);
    const uint64_t last = ~uint64_t{0} >> (63 - (x1 & 63));
    if (w0 == w1) return Bits(bits[w0] & first & last);
    return Bits(bits[w0] & first) + Bits(bits[w1] & last);
  }
  // Changed pixels of row y left of column x (0 <= x <= width).
  int Before(int y, int x) const {
    const size_t at = static_cast<size_t>(y) * static_cast<size_t>(row_words_) + static_cast<size_t>(x >> 6);
    const uint64_t below = (uint64_t{1} << (x & 63)) - 1;
    return prefix_[at] + Bits(bits_[at] & below);
  }
  // Bit x % 64 of word x / 64 of row y: pixel (x, y) changed; a row has width / 64 + 1 words.
  const uint64_t* row_bits(int y) const { return bits_.data() + static_cast<size_t>(y) * static_cast<size_t>(row_words_); }

  static int PopCount(uint64_t v) {  // portable: the build targets CPUs without popcnt too
    v = v - ((v >> 1) & 0x5555555555555555ULL);
    v = (v & 0x3333333333333333ULL) + ((v >> 2) & 0x3333333333333333ULL);
    v = (v + (v >> 4)) & 0x0f0f0f0f0f0f0f0fULL;
    return static_cast<int>((v * 0x0101010101010101ULL) >> 56);
  }

 private:
  // Set bits of v: POPCNT (inline assembly, so no target attribute) or PopCount.
  int Bits(uint64_t v) const {
#if OCCMAP_X86_KERNELS && defined(__x86_64__)
    if (popcnt_) {
      uint64_t n;
      __asm__("popcnt %1, %0" : "=r"(n) : "r"(v));
      return static_cast<int>(n);
    }
#endif
    return PopCount(v);
  }

  bool popcnt_ = false;  // the kernel set at Build has POPCNT
  int width_ = 0, height_ = 0, row_words_ = 1;
  std::vector<uint64_t> bits_;    // per row: row_words_ words, the last one's bits past the width 0
  std::vector<uint16_t> prefix_;  // per row and word: changed pixels in the row's earlier words
};

// One row's span of a ColumnSpans: pixels x0 to x1 (inclusive) of row y.
struct RowSpan {
  uint16_t y, x0, x1;
};

// The rows and spans of a ColumnView for a radius and a band: row y covers the pixels whose
// centres lie within radius of the axis (at least the axis's own pixel), clipped to the image.
struct ColumnSpans {
  int first_row = 0, last_row = -1;  // unclipped band rows (inclusive)
  int visible_rows = 0;              // of those, inside the image
  // The span of row y (first_row <= y <= last_row); false when it misses the image.
  bool Span(int y, int& x0, int& x1) const {
    if (y < 0 || y >= height) return false;
    const float dy = static_cast<float>(y) - bottom_row;
    const float axis = axis_bottom + axis_slope * dy;
    const float half = std::max(0.0f, half_bottom + half_slope * dy);
    int a = static_cast<int>(std::ceil(axis - half));
    int b = static_cast<int>(std::floor(axis + half));
    if (b < a) a = b = static_cast<int>(std::lround(axis));
    a = std::max(a, 0);
    b = std::min(b, width - 1);
    if (b < a) return false;
    x0 = a;
    x1 = b;
    return true;
  }

  // The rows y_first, y_first + step, ... up to y_last whose Span meets the image, with their
  // spans, into out (room for (y_last - y_first) / step + 1); returns how many. Needs
  // 0 <= y_first, y_last < height <= 65536, width <= 65536, step >= 1. Equal to Span row by row
  // (tested); four rows at a time with SSE2 on x86-64, the lanes of an unusual row (a span
  // narrower than a pixel, or off the image) by Span itself.
  int Rows(int y_first, int y_last, int step, RowSpan* out) const;
  // fn(y, x0, x1) for each row Rows gives, in order (64 rows at a time on the stack).
  template <typename Fn>
  void ForEachRow(int y_first, int y_last, int step, const Fn& fn) const {
    constexpr int kChunk = 64;
    RowSpan rows[kChunk];
    for (int y = y_first; y <= y_last;) {
      const int chunk_last = static_cast<int>(std::min<int64_t>(y_last, y + int64_t{kChunk - 1} * step));
      const int n = Rows(y, chunk_last, step, rows);
      for (int i = 0; i < n; ++i) fn(static_cast<int>(rows[i].y), static_cast<int>(rows[i].x0), static_cast<int>(rows[i].x1));
      y = chunk_last + step;
      if (chunk_last == y_last) break;
    }
  }

  float bottom_row = 0, row_range = 1;
  float axis_bottom = 0, axis_slope = 0;     // axis(y) = axis_bottom + axis_slope * (y - bottom_row)
  float half_bottom = 0, half_slope = 0;     // half-width(y), in pixels, for the radius
  int width = 0, height = 0;
};
ColumnSpans MakeColumnSpans(const ColumnView& view, double radius_m, double band_low, double band_high,
                            ImageSize image);

// The changed pixels of a band's spans over at most max_rows of its rows (evenly spaced from its
// first, as the column fusion reads them); pixels: how many pixels those spans hold.
int64_t CountBand(const ColumnSpans& spans, const ChangeRowSums& counts, int max_rows, int64_t& pixels);

class ColumnFusion {
 public:
  explicit ColumnFusion(const ColumnLut& columns) : columns_(columns) {}

  // counts: one per camera (those of inactive cameras are not read). `map` is reset to the
  // candidate grid; every candidate is written. The first call for a band and radius works out
  // the plan (calls may come from several threads).
  void Fuse(std::span<const ChangeRowSums> counts, const std::vector<bool>& active, const ColumnFusionOptions& options,
            Context& ctx, OccupancyMap& map) const;
  // The same map from the change masks themselves, pixel by pixel, on the calling thread.
  void FuseReference(std::span<const ImageView<const uint8_t>> changes, const std::vector<bool>& active,
                     const ColumnFusionOptions& options, OccupancyMap& map) const;

  const ColumnLut& columns() const { return columns_; }

 private:
  // Per candidate, the cameras whose view of the band the vote reads, with the first look's spans.
  struct Plan {
    double band_low_m = -1, band_high_m = -1, radius_m = -1;
    uint64_t revision = 0;  // the table's (its learned blocks)
    struct Entry {
      uint32_t first_span;  // into spans
      uint32_t pixels;      // of the first look's spans (0: the first look reads nothing)
      uint8_t camera, num_spans;
    };
    struct Span {
      uint16_t y, x0, x1;
    };
    std::vector<uint32_t> first_entry;  // per candidate, and one past the last
    std::vector<Entry> entries;
    std::vector<Span> spans;
  };
  // Shared: a plan replaced (other options, the table's blocks learned) lives while a Fuse reads it.
  std::shared_ptr<const Plan> PlanFor(const ColumnFusionOptions& options) const;

  const ColumnLut& columns_;
  mutable std::mutex plan_mutex_;
  mutable std::shared_ptr<const Plan> plan_;
};

}  // namespace occmap
