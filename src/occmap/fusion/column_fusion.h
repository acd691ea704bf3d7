// Column fusion: the paper's AND (equation 5) asked of the vertical column above a floor
// position instead of its floor cell. A candidate position (lut/column_lut.h) is occupied when
// every active camera that sees it sees change over at least min_changed of the image of the
// column's band (z from band_low_m to band_high_m, radius_m around the axis); cameras whose
// view of it a static occluder hides, or whose image holds less than half of the band's rows,
// abstain. Tri-state and vote as the floor AND (Fusion): unseen when no camera tests it,
// occupied when at most max_free_views of the testing cameras (and fewer than all) say free.
//
// Why: legs leave the floor cell under a person unchanged in some views (the floor AND misses
// the person), while the band above it is a torso in every view that sees it; a static occluder
// in front of a person turns one camera's "unchanged" into "cannot tell".
//
// Counting: each camera's changes are summed along rows once per frame (ChangeRowSums), so a
// row of a span costs two reads; at most max_rows rows of the band are read per camera (evenly
// spaced), after a first look at 4 of them: a camera that sees less than half of min_changed
// there votes free at once (most columns are empty). ColumnFusion::FuseReference counts the
// same rows pixel by pixel (equal, tested).
//
//   ChangeRowSums counts[n]; counts[n].Build(changes_n);
//   ColumnFusion fusion(columns);
//   fusion.Fuse(counts, active, options, ctx, column_map);
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
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
  int max_free_views = 0;     // the vote, as FusionOptions::max_free_views
  int max_rows = 24;          // rows of the band read per camera (evenly spaced)
  Status Validate(double column_height_m, int num_cameras) const;
};

// One camera's changes summed along rows: Count(y, x0, x1) is the number of changed pixels
// (non-zero) in row y from column x0 to x1 inclusive.
class ChangeRowSums {
 public:
  // Images up to 65535 pixels wide (checked).
  void Build(ImageView<const uint8_t> changes);
  int width() const { return width_; }
  int height() const { return height_; }
  int Count(int y, int x0, int x1) const {
    const uint16_t* row = sums_.data() + static_cast<size_t>(y) * static_cast<size_t>(width_ + 1);
    return static_cast<int>(static_cast<uint16_t>(row[x1 + 1] - row[x0]));
  }

 private:
  int width_ = 0, height_ = 0;
  // Per row: width + 1 running sums, 16 bits (a row's count fits; half the memory traffic of 32).
  std::vector<uint16_t> sums_;
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

  float bottom_row = 0, row_range = 1;
  float axis_bottom = 0, axis_slope = 0;     // axis(y) = axis_bottom + axis_slope * (y - bottom_row)
  float half_bottom = 0, half_slope = 0;     // half-width(y), in pixels, for the radius
  int width = 0, height = 0;
};
ColumnSpans MakeColumnSpans(const ColumnView& view, double radius_m, double band_low, double band_high,
                            ImageSize image);

class ColumnFusion {
 public:
  explicit ColumnFusion(const ColumnLut& columns) : columns_(columns) {}

  // counts: one per camera (those of inactive cameras are not read). `map` is reset to the
  // candidate grid; every candidate is written.
  void Fuse(std::span<const ChangeRowSums> counts, const std::vector<bool>& active, const ColumnFusionOptions& options,
            Context& ctx, OccupancyMap& map) const;
  // The same map from the change masks themselves, pixel by pixel, on the calling thread.
  void FuseReference(std::span<const ImageView<const uint8_t>> changes, const std::vector<bool>& active,
                     const ColumnFusionOptions& options, OccupancyMap& map) const;

  const ColumnLut& columns() const { return columns_; }

 private:
  const ColumnLut& columns_;
};

}  // namespace occmap
