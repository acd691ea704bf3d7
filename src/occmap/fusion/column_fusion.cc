#include "occmap/fusion/column_fusion.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

#include "occmap/util/simd.h"

#if OCCMAP_X86_KERNELS
#include <emmintrin.h>
#endif

namespace occmap {

Status ColumnFusionOptions::Validate(double column_height_m, int num_cameras) const {
  if (!(band_low_m >= 0 && band_high_m > band_low_m && band_high_m <= column_height_m + 1e-9))
    return InvalidInput(fmt::format("band_m: expected 0 <= low < high <= the column's height {} m, found [{}, {}]",
                                    column_height_m, band_low_m, band_high_m));
  if (!(radius_m > 0 && radius_m <= 1))
    return InvalidInput(fmt::format("radius_m: expected a radius in (0, 1] m, found {}", radius_m));
  if (!(min_changed > 0 && min_changed <= 1))
    return InvalidInput(fmt::format("min_changed: expected a fraction in (0, 1], found {}", min_changed));
  if (max_free_views < 0 || max_free_views > std::max(1, num_cameras - 1))
    return InvalidInput(fmt::format("max_free_views: expected 0 to {}, found {}", std::max(1, num_cameras - 1),
                                    max_free_views));
  if (min_changed_views < 1)
    return InvalidInput(fmt::format("min_changed_views: expected at least 1, found {}", min_changed_views));
  if (min_views < 1) return InvalidInput(fmt::format("min_views: expected at least 1, found {}", min_views));
  if (max_rows < 1) return InvalidInput(fmt::format("max_rows: expected at least 1, found {}", max_rows));
  return Status::Ok();
}

namespace {

// Bit x of the result: in[x] != 0, for 64 bytes.
uint64_t ChangedBits64(const uint8_t* in) {
  uint64_t bits = 0;
  for (int x = 0; x < 64; ++x) bits |= static_cast<uint64_t>(in[x] != 0 ? 1 : 0) << x;
  return bits;
}

#if OCCMAP_X86_KERNELS
// The same with SSE2 (every x86-64 has it): 16 compares to zero per instruction.
uint64_t ChangedBits64Sse2(const uint8_t* in) {
  const __m128i zero = _mm_setzero_si128();
  uint64_t zeros = 0;
  for (int q = 0; q < 4; ++q) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + 16 * q));
    zeros |= static_cast<uint64_t>(static_cast<uint32_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, zero)))) << (16 * q);
  }
  return ~zeros;
}
#endif

}  // namespace

void ChangeRowSums::Build(ImageView<const uint8_t> changes) {
  OCCMAP_CHECK(changes.width() < 65536, "ChangeRowSums: images up to 65535 pixels wide");
  width_ = changes.width();
  height_ = changes.height();
  popcnt_ = OCCMAP_X86_KERNELS && ActiveKernels() != KernelSet::kPortable;
  row_words_ = width_ / 64 + 1;
  const size_t n = static_cast<size_t>(row_words_) * static_cast<size_t>(height_);
  bits_.resize(n);
  prefix_.resize(n);
#if OCCMAP_X86_KERNELS
  const bool sse2 = ActiveKernels() != KernelSet::kPortable;
#endif
  for (int y = 0; y < height_; ++y) {
    const uint8_t* in = changes.row(y);
    uint64_t* bits = bits_.data() + static_cast<size_t>(y) * static_cast<size_t>(row_words_);
    uint16_t* prefix = prefix_.data() + static_cast<size_t>(y) * static_cast<size_t>(row_words_);
    const int full = width_ / 64;
#if OCCMAP_X86_KERNELS
    if (sse2) {
      for (int w = 0; w < full; ++w) bits[w] = ChangedBits64Sse2(in + 64 * w);
    } else {
      for (int w = 0; w < full; ++w) bits[w] = ChangedBits64(in + 64 * w);
    }
#else
    for (int w = 0; w < full; ++w) bits[w] = ChangedBits64(in + 64 * w);
#endif
    uint64_t tail = 0;
    for (int x = 64 * full; x < width_; ++x) tail |= static_cast<uint64_t>(in[x] != 0 ? 1 : 0) << (x - 64 * full);
    bits[full] = tail;
    int sum = 0;
    for (int w = 0; w < row_words_; ++w) {
      prefix[w] = static_cast<uint16_t>(sum);
      sum += PopCount(bits[w]);
    }
  }
}

int ColumnSpans::Rows(int y_first, int y_last, int step, RowSpan* out) const {
  OCCMAP_DCHECK(y_first >= 0 && y_last < height && height <= 65536 && width <= 65536 && step >= 1,
                "ColumnSpans::Rows: rows outside the image");
  int n = 0;
  int y = y_first;
  const auto one = [&](int row) {
    int x0, x1;
    if (Span(row, x0, x1)) out[n++] = {static_cast<uint16_t>(row), static_cast<uint16_t>(x0), static_cast<uint16_t>(x1)};
  };
#if OCCMAP_X86_KERNELS
  // As Span, four rows at a time: the same float operations lane by lane (no FMA: the build
  // has -ffp-contract=off), ceil and floor from the truncation (exact below 2^31 in magnitude,
  // where the casts of Span are defined), the clamps by compare and select.
  const __m128 bottom = _mm_set1_ps(bottom_row), axis0 = _mm_set1_ps(axis_bottom), axis_k = _mm_set1_ps(axis_slope);
  const __m128 half0 = _mm_set1_ps(half_bottom), half_k = _mm_set1_ps(half_slope), zero = _mm_setzero_ps();
  const __m128i zero_i = _mm_setzero_si128(), last_x = _mm_set1_epi32(width - 1);
  const __m128i lanes = _mm_setr_epi32(0, step, 2 * step, 3 * step);
  for (; y + 3 * step <= y_last; y += 4 * step) {
    const __m128 dy = _mm_sub_ps(_mm_cvtepi32_ps(_mm_add_epi32(_mm_set1_epi32(y), lanes)), bottom);
    const __m128 axis = _mm_add_ps(axis0, _mm_mul_ps(axis_k, dy));
    const __m128 half = _mm_max_ps(_mm_add_ps(half0, _mm_mul_ps(half_k, dy)), zero);  // max(0, h) as std::max
    const __m128 lo = _mm_sub_ps(axis, half), hi = _mm_add_ps(axis, half);
    __m128i a = _mm_cvttps_epi32(lo), b = _mm_cvttps_epi32(hi);
    a = _mm_sub_epi32(a, _mm_castps_si128(_mm_cmplt_ps(_mm_cvtepi32_ps(a), lo)));  // ceil: +1 where t < lo
    b = _mm_add_epi32(b, _mm_castps_si128(_mm_cmpgt_ps(_mm_cvtepi32_ps(b), hi)));  // floor: -1 where t > hi
    const __m128i narrow = _mm_cmpgt_epi32(a, b);  // Span's lround row
    a = _mm_andnot_si128(_mm_cmplt_epi32(a, zero_i), a);
    const __m128i right = _mm_cmpgt_epi32(b, last_x);
    b = _mm_or_si128(_mm_and_si128(right, last_x), _mm_andnot_si128(right, b));
    const __m128i off = _mm_cmpgt_epi32(a, b);
    // Lanes that are NaN or too large for the casts go to Span too (cvttps gives INT_MIN there).
    const __m128 big = _mm_set1_ps(2147483520.0f);  // the largest float below 2^31
    const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    const __m128 huge = _mm_or_ps(_mm_cmpnle_ps(_mm_and_ps(lo, abs_mask), big), _mm_cmpnle_ps(_mm_and_ps(hi, abs_mask), big));
    const int unusual = _mm_movemask_ps(_mm_or_ps(_mm_castsi128_ps(_mm_or_si128(narrow, off)), huge));
    if (unusual == 0) {
      alignas(16) int32_t av[4], bv[4];
      _mm_store_si128(reinterpret_cast<__m128i*>(av), a);
      _mm_store_si128(reinterpret_cast<__m128i*>(bv), b);
      for (int q = 0; q < 4; ++q)
        out[n + q] = {static_cast<uint16_t>(y + q * step), static_cast<uint16_t>(av[q]), static_cast<uint16_t>(bv[q])};
      n += 4;
      continue;
    }
    for (int q = 0; q < 4; ++q) one(y + q * step);
  }
#endif
  for (; y <= y_last; y += step) one(y);
  return n;
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

// o.min_views, or every active camera when fewer are active (a site of one camera, or one left).
int MinViews(const std::vector<bool>& active, const ColumnFusionOptions& o) {
  return std::min(o.min_views, static_cast<int>(std::count(active.begin(), active.end(), true)));
}

CellState Decide(int tested, int free_votes, const ColumnFusionOptions& o, int min_views) {
  if (tested == 0 || tested < min_views) return CellState::kUnseen;
  if (free_votes == 0) return CellState::kOccupied;
  return free_votes <= o.max_free_views && tested - free_votes >= o.min_changed_views ? CellState::kOccupied
                                                                                        : CellState::kFree;
}

// Candidate k's state with the changed-pixel count of a span given by count(camera, y, x0, x1):
// the reference (ColumnFusion::Fuse reads the same spans from its plan).
template <typename CountFn>
CellState CandidateState(const ColumnLut& columns, int64_t k, const std::vector<bool>& active,
                         const ColumnFusionOptions& o, int min_views, const CountFn& count) {
  const double h = columns.options().height_m;
  int tested = 0, free_votes = 0;
  for (int c = 0; c < columns.num_cameras(); ++c) {
    if (!active[c]) continue;
    const ColumnView& v = columns.view(c, k);
    if (!(v.seen || v.feet_cut) || v.blocked) continue;
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
  return Decide(tested, free_votes, o, min_views);
}

}  // namespace

int64_t CountBand(const ColumnSpans& s, const ChangeRowSums& counts, int max_rows, int64_t& pixels) {
  const int stride = RowStride(s, max_rows);
  int64_t changed = 0;
  pixels = 0;
  // The rows from first_row by stride that lie in the image (Span misses the others).
  const int y_first = s.first_row >= 0 ? s.first_row : s.first_row + (-s.first_row + stride - 1) / stride * stride;
  int64_t n = 0;
  s.ForEachRow(y_first, std::min(s.last_row, s.height - 1), stride, [&](int y, int x0, int x1) {
    changed += counts.Count(y, x0, x1);
    n += x1 - x0 + 1;
  });
  pixels = n;
  return changed;
}

std::shared_ptr<const ColumnFusion::Plan> ColumnFusion::PlanFor(const ColumnFusionOptions& o) const {
  std::lock_guard<std::mutex> lock(plan_mutex_);
  if (plan_ && plan_->band_low_m == o.band_low_m && plan_->band_high_m == o.band_high_m && plan_->radius_m == o.radius_m &&
      plan_->revision == columns_.revision())
    return plan_;
  auto plan = std::make_shared<Plan>();
  plan->band_low_m = o.band_low_m;
  plan->band_high_m = o.band_high_m;
  plan->radius_m = o.radius_m;
  plan->revision = columns_.revision();
  const double h = columns_.options().height_m;
  const int64_t n = columns_.candidates().num_cells();
  OCCMAP_CHECK(columns_.num_cameras() <= 256, "ColumnFusion: at most 256 cameras");
  plan->first_entry.reserve(static_cast<size_t>(n) + 1);
  for (int64_t k = 0; k < n; ++k) {
    plan->first_entry.push_back(static_cast<uint32_t>(plan->entries.size()));
    for (int c = 0; c < columns_.num_cameras(); ++c) {
      const ColumnView& v = columns_.view(c, k);
      if (!(v.seen || v.feet_cut) || v.blocked) continue;
      const ColumnSpans s = MakeColumnSpans(v, o.radius_m, o.band_low_m / h, o.band_high_m / h, columns_.image_size(c));
      if (2 * s.visible_rows < s.last_row - s.first_row + 1) continue;  // mostly off the image: abstains
      Plan::Entry e{static_cast<uint32_t>(plan->spans.size()), 0, static_cast<uint8_t>(c), 0};
      int pixels = 0;
      const int coarse = RowStride(s, kCoarseRows);
      for (int y = s.first_row + coarse / 2; y <= s.last_row; y += coarse) {
        int x0, x1;
        if (!s.Span(y, x0, x1)) continue;
        plan->spans.push_back({static_cast<uint16_t>(y), static_cast<uint16_t>(x0), static_cast<uint16_t>(x1)});
        pixels += x1 - x0 + 1;
        ++e.num_spans;
      }
      e.pixels = static_cast<uint32_t>(pixels);
      plan->entries.push_back(e);
    }
  }
  plan->first_entry.push_back(static_cast<uint32_t>(plan->entries.size()));
  OCCMAP_CHECK(plan->entries.size() < (size_t{1} << 32) && plan->spans.size() < (size_t{1} << 32),
               "ColumnFusion: plan too large");
  plan_ = std::move(plan);
  return plan_;
}

void ColumnFusion::Fuse(std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                        const ColumnFusionOptions& options, Context& ctx, OccupancyMap& map) const {
  const FloorGrid& grid = columns_.candidates();
  if (!(map.grid() == grid)) map = OccupancyMap(grid);
  std::vector<CellState>& states = map.states();
  const std::shared_ptr<const Plan> held = PlanFor(options);
  const Plan& plan = *held;
  const double h = columns_.options().height_m;
  const ColumnFusionOptions& o = options;
  const int min_views = MinViews(active, o);
  // As CandidateState, the first look's spans read from the plan, and every camera's first look
  // before any camera's whole band: the state depends only on how many cameras test and how many
  // of them vote free, not on the order they are asked in (more than max_free_views free votes
  // make it free whatever the rest say), and a first look is a few counts where a band is up to
  // max_rows spans worked out and counted. Most candidates near a person pass the first look in
  // the cameras that see the person on their line of sight and fail it in another.
  const auto state = [&](int64_t k) {
    int tested = 0, free_votes = 0;
    uint32_t pending[256];  // the entries whose first look passed (a camera is a uint8_t)
    int num_pending = 0;
    for (uint32_t e = plan.first_entry[k]; e < plan.first_entry[k + 1]; ++e) {
      const Plan::Entry& entry = plan.entries[e];
      const int c = entry.camera;
      if (!active[c]) continue;
      if (entry.pixels > 0) {
        const ChangeRowSums& count = counts[c];
        int64_t changed = 0;
        for (uint32_t q = entry.first_span; q < entry.first_span + entry.num_spans; ++q)
          changed += count.Count(plan.spans[q].y, plan.spans[q].x0, plan.spans[q].x1);
        if (2 * static_cast<double>(changed) < o.min_changed * static_cast<double>(entry.pixels)) {
          ++tested;
          if (++free_votes > o.max_free_views) return CellState::kFree;
          continue;
        }
      }
      pending[num_pending++] = e;
    }
    for (int p = 0; p < num_pending; ++p) {
      const int c = plan.entries[pending[p]].camera;
      const ColumnSpans s =
          MakeColumnSpans(columns_.view(c, k), o.radius_m, o.band_low_m / h, o.band_high_m / h, columns_.image_size(c));
      int64_t pixels = 0;
      const int64_t changed = CountBand(s, counts[c], o.max_rows, pixels);
      if (pixels == 0) continue;
      ++tested;
      if (static_cast<double>(changed) < o.min_changed * static_cast<double>(pixels)) {
        if (++free_votes > o.max_free_views) return CellState::kFree;
      }
    }
    return Decide(tested, free_votes, o, min_views);
  };
  ParallelFor(
      ctx, 0, grid.num_cells(),
      [&](int64_t begin, int64_t end, int) {
        for (int64_t k = begin; k < end; ++k) states[k] = state(k);
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
  const int min_views = MinViews(active, options);
  for (int64_t k = 0; k < grid.num_cells(); ++k)
    map.states()[k] = CandidateState(columns_, k, active, options, min_views, count);
}

}  // namespace occmap
