#include "occmap/fusion/column_fusion.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace occmap {

Status ColumnFusionOptions::Validate(double column_height_m, int num_cameras) const {
  if (!(band_low_m >= 0 && band_high_m > band_low_m && band_high_m <= column_height_m + 1e-9))
    return InvalidInput(fmt::format("band_m: expected 0 <= low < high <= the column's height {} m, found [{}, {}]",
                                    column_height_m, band_low_m, band_high_m));
  if (!(radius_m > 0 && radius_m <= 1))
    return InvalidInput(fmt::format("radius_m: expected a radius in (0, 1] m, found {}", radius_m));
  if (!(min_changed > 0 && min_changed <= 1))
    return InvalidInput(fmt::format("min_changed: expected a fraction in (0, 1], found {}", min_changed));
  if (max_free_views < 0 || max_free_views >= std::max(1, num_cameras))
    return InvalidInput(fmt::format("max_free_views: expected 0 to {}, found {}", std::max(0, num_cameras - 1),
                                    max_free_views));
  if (max_rows < 1) return InvalidInput(fmt::format("max_rows: expected at least 1, found {}", max_rows));
  return Status::Ok();
}

void ChangeRowSums::Build(ImageView<const uint8_t> changes) {
  OCCMAP_CHECK(changes.width() < 65536, "ChangeRowSums: images up to 65535 pixels wide");
  width_ = changes.width();
  height_ = changes.height();
  sums_.resize(static_cast<size_t>(width_ + 1) * static_cast<size_t>(height_));
  for (int y = 0; y < height_; ++y) {
    const uint8_t* in = changes.row(y);
    uint16_t* out = sums_.data() + static_cast<size_t>(y) * static_cast<size_t>(width_ + 1);
    uint16_t sum = 0;
    out[0] = 0;
    for (int x = 0; x < width_; ++x) {
      sum = static_cast<uint16_t>(sum + (in[x] != 0 ? 1 : 0));
      out[x + 1] = sum;
    }
  }
}

ColumnSpans MakeColumnSpans(const ColumnView& view, double radius_m, double band_low, double band_high,
                            ImageSize image) {
  ColumnSpans s;
  s.width = image.width;
  s.height = image.height;
  s.bottom_row = view.bottom_row;
  s.row_range = view.bottom_row - view.top_row;
  // Rows of the band: the column's rows interpolated linearly (band_* are fractions of it).
  const double y_low = view.bottom_row - band_low * s.row_range;
  const double y_high = view.bottom_row - band_high * s.row_range;
  s.first_row = static_cast<int>(std::ceil(y_high - 0.5));
  s.last_row = std::max(s.first_row, static_cast<int>(std::floor(y_low + 0.5)));
  s.visible_rows = std::max(0, std::min(s.last_row, image.height - 1) - std::max(s.first_row, 0) + 1);
  const float range = std::max(s.row_range, 1e-3f);
  s.axis_bottom = view.axis_x_bottom;
  s.axis_slope = (view.axis_x_bottom - view.axis_x_top) / range;
  s.half_bottom = static_cast<float>(radius_m) * view.half_width_bottom;
  s.half_slope = static_cast<float>(radius_m) * (view.half_width_bottom - view.half_width_top) / range;
  return s;
}

namespace {

// The rows of a band read: evenly spaced, at most max_rows, the same for both versions.
int RowStride(const ColumnSpans& s, int max_rows) {
  const int rows = s.last_row - s.first_row + 1;
  return std::max(1, (rows + max_rows - 1) / max_rows);
}

constexpr int kCoarseRows = 4;

CellState Decide(int tested, int free_votes, int k) {
  if (tested == 0) return CellState::kUnseen;
  return free_votes <= k && free_votes < tested ? CellState::kOccupied : CellState::kFree;
}

// Candidate k's state with the changed-pixel count of a span given by count(camera, y, x0, x1).
template <typename CountFn>
CellState CandidateState(const ColumnLut& columns, int64_t k, const std::vector<bool>& active,
                         const ColumnFusionOptions& o, const CountFn& count) {
  const double h = columns.options().height_m;
  int tested = 0, free_votes = 0;
  for (int c = 0; c < columns.num_cameras(); ++c) {
    if (!active[c]) continue;
    const ColumnView& v = columns.view(c, k);
    if (!v.seen || v.blocked) continue;
    const ColumnSpans s = MakeColumnSpans(v, o.radius_m, o.band_low_m / h, o.band_high_m / h, columns.image_size(c));
    if (2 * s.visible_rows < s.last_row - s.first_row + 1) continue;  // mostly off the image
    // A first look at a few rows: a column less than half as changed as asked there is free
    // without reading the rest (most columns are empty).
    int64_t changed = 0, pixels = 0;
    const int coarse = RowStride(s, kCoarseRows);
    for (int y = s.first_row + coarse / 2; y <= s.last_row; y += coarse) {
      int x0, x1;
      if (!s.Span(y, x0, x1)) continue;
      changed += count(c, y, x0, x1);
      pixels += x1 - x0 + 1;
    }
    if (pixels > 0 && 2 * static_cast<double>(changed) < o.min_changed * static_cast<double>(pixels)) {
      ++tested;
      if (++free_votes > o.max_free_views) return CellState::kFree;
      continue;
    }
    const int stride = RowStride(s, o.max_rows);
    changed = pixels = 0;
    for (int y = s.first_row; y <= s.last_row; y += stride) {
      int x0, x1;
      if (!s.Span(y, x0, x1)) continue;
      changed += count(c, y, x0, x1);
      pixels += x1 - x0 + 1;
    }
    if (pixels == 0) continue;
    ++tested;
    if (static_cast<double>(changed) < o.min_changed * static_cast<double>(pixels)) {
      ++free_votes;
      if (free_votes > o.max_free_views) return CellState::kFree;
    }
  }
  return Decide(tested, free_votes, o.max_free_views);
}

}  // namespace

void ColumnFusion::Fuse(std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                        const ColumnFusionOptions& options, Context& ctx, OccupancyMap& map) const {
  const FloorGrid& grid = columns_.candidates();
  if (!(map.grid() == grid)) map = OccupancyMap(grid);
  std::vector<CellState>& states = map.states();
  const auto count = [&](int c, int y, int x0, int x1) { return counts[c].Count(y, x0, x1); };
  ParallelFor(
      ctx, 0, grid.num_cells(),
      [&](int64_t begin, int64_t end, int) {
        for (int64_t k = begin; k < end; ++k) states[k] = CandidateState(columns_, k, active, options, count);
      },
      1024);
}

void ColumnFusion::FuseReference(std::span<const ImageView<const uint8_t>> changes, const std::vector<bool>& active,
                                 const ColumnFusionOptions& options, OccupancyMap& map) const {
  const FloorGrid& grid = columns_.candidates();
  if (!(map.grid() == grid)) map = OccupancyMap(grid);
  const auto count = [&](int c, int y, int x0, int x1) {
    int n = 0;
    for (int x = x0; x <= x1; ++x) n += changes[c](x, y) != 0 ? 1 : 0;
    return n;
  };
  for (int64_t k = 0; k < grid.num_cells(); ++k) map.states()[k] = CandidateState(columns_, k, active, options, count);
}

}  // namespace occmap
