#include "occmap/objects/split_fast.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include "occmap/objects/split_internal.h"
#include "occmap/util/simd.h"
#include "occmap/util/status.h"

#if OCCMAP_X86_KERNELS
#include <immintrin.h>
#endif

namespace occmap {
namespace {

using split_internal::LocalBox;
using split_internal::MeanCellCentre;

// DetectionFromCells of the cells whose centres are (xs[k], ys[k]) for k in `indices`, in that
// order: the same sums in the same order (the same doubles), without a division per cell.
Detection DetectionFromPoints(const FloorGrid& grid, const std::vector<double>& xs, const std::vector<double>& ys,
                              const std::vector<int64_t>& indices) {
  Detection d;
  d.cells = static_cast<int64_t>(indices.size());
  d.area_m2 = static_cast<double>(indices.size()) * grid.cell_size_m * grid.cell_size_m;
  double sum_x = 0, sum_y = 0;
  for (int64_t k : indices) {
    sum_x += xs[static_cast<size_t>(k)];
    sum_y += ys[static_cast<size_t>(k)];
  }
  const double n = static_cast<double>(indices.size());
  const double mean_x = sum_x / n, mean_y = sum_y / n;
  double sxx = 0, sxy = 0, syx = 0, syy = 0;
  for (int64_t k : indices) {
    const double rx = xs[static_cast<size_t>(k)] - mean_x, ry = ys[static_cast<size_t>(k)] - mean_y;
    sxx += rx * rx;
    sxy += rx * ry;
    syx += ry * rx;
    syy += ry * ry;
  }
  d.x_m = mean_x;
  d.y_m = mean_y;
  d.spread_m2 << sxx / n, sxy / n, syx / n, syy / n;
  return d;
}

// SquaredDistance1dInto in integers: f[p] = g[p]^2 for whole g, the intersections kept as
// fractions num / den (den = 2 (q - p) > 0) and compared by cross-multiplication (|num| <
// 2^23 and den < 2^13 for boxes under 2 900 cells on a side: the products fit easily). The
// same envelope as the doubles: each double intersection is the correctly rounded quotient of
// the same integers, and two distinct quotients differ by at least 1 / (den den') ~ 1e-8, far
// more than a rounding, so every comparison decides alike; out[q] is a whole number.
void SquaredDistance1dInt(const int* g, int n, double* out, std::vector<int>& v, std::vector<int64_t>& z_num,
                          std::vector<int64_t>& z_den) {
  v.resize(static_cast<size_t>(n));
  z_num.resize(static_cast<size_t>(n));
  z_den.resize(static_cast<size_t>(n));
  auto f = [&](int p) { return int64_t{g[p]} * g[p]; };
  v[0] = 0;
  int k = 0;  // z[0] = -inf, z[k + 1] = +inf past the last parabola
  for (int q = 1; q < n; ++q) {
    const int64_t fq = f(q) + int64_t{q} * q;
    int64_t num, den;
    while (true) {
      const int p = v[static_cast<size_t>(k)];
      num = fq - (f(p) + int64_t{p} * p);
      den = 2 * int64_t{q - p};
      // s <= z[k] (never for k = 0: z[0] = -inf).
      if (k > 0 && num * z_den[static_cast<size_t>(k)] <= z_num[static_cast<size_t>(k)] * den) {
        --k;
        continue;
      }
      break;
    }
    ++k;
    v[static_cast<size_t>(k)] = q;
    z_num[static_cast<size_t>(k)] = num;
    z_den[static_cast<size_t>(k)] = den;
  }
  const int last = k;
  k = 0;
  for (int q = 0; q < n; ++q) {
    // z[k + 1] < q
    while (k < last && z_num[static_cast<size_t>(k) + 1] < int64_t{q} * z_den[static_cast<size_t>(k) + 1]) ++k;
    const int p = v[static_cast<size_t>(k)];
    out[q] = static_cast<double>(int64_t{q - p} * (q - p) + f(p));
  }
}

// SquaredDistanceTransform into scratch.d2, in integers (exact, as the reference's doubles
// are): the column runs row by row (all columns of a row at once), then the row envelopes.
void SquaredDistanceTransformInto(const std::vector<uint8_t>& inside, int width, int height, SplitScratch& s) {
  const size_t size = inside.size();
  s.g.resize(size);
  const size_t w = static_cast<size_t>(width);
  for (size_t a = 0; a < w; ++a) s.g[a] = inside[a] ? 1 : 0;
  for (size_t b = 1; b < static_cast<size_t>(height); ++b) {
    const int* above = s.g.data() + (b - 1) * w;
    int* row = s.g.data() + b * w;
    const uint8_t* in = inside.data() + b * w;
    for (size_t a = 0; a < w; ++a) row[a] = in[a] ? above[a] + 1 : 0;
  }
  // From the top down, the run to the last outside cell above; min with the run below.
  s.v.resize(w);  // the run from below, per column
  for (size_t a = 0; a < w; ++a) s.v[a] = 0;
  for (size_t b = static_cast<size_t>(height); b-- > 0;) {
    int* row = s.g.data() + b * w;
    const uint8_t* in = inside.data() + b * w;
    for (size_t a = 0; a < w; ++a) {
      const int below = in[a] ? s.v[a] + 1 : 0;
      s.v[a] = below;
      row[a] = std::min(row[a], below);
    }
  }
  s.d2.resize(size);
  for (int b = 0; b < height; ++b) {
    SquaredDistance1dInt(s.g.data() + int64_t{b} * width, width, s.d2.data() + int64_t{b} * width, s.v, s.z_num,
                         s.z_den);
  }
}

// DistancePeaks into scratch.peaks, the buffers reused and each distance's square root
// taken only where a persistence is tested (the same expression: the same values).
// The cells' grid coordinates come in s.ci, s.cj (no division per cell).
void DistancePeaksInto(const FloorGrid& grid, const std::vector<int64_t>& cells, const ObjectOptions& options,
                       SplitScratch& s) {
  s.peaks.clear();
  if (cells.empty()) return;
  int min_i = grid.cells_x, min_j = grid.cells_y, max_i = -1, max_j = -1;
  for (size_t k = 0; k < cells.size(); ++k) {
    const int i = static_cast<int>(s.ci[k]), j = static_cast<int>(s.cj[k]);
    min_i = std::min(min_i, i);
    max_i = std::max(max_i, i);
    min_j = std::min(min_j, j);
    max_j = std::max(max_j, j);
  }
  const LocalBox box{min_i - 1, min_j - 1, max_i - min_i + 3, max_j - min_j + 3};
  const size_t size = static_cast<size_t>(box.width) * box.height;
  s.inside.assign(size, 0);
  std::vector<int>& locals = s.locals;
  locals.clear();
  for (size_t k = 0; k < cells.size(); ++k) {
    const int local = box.Index(static_cast<int>(s.ci[k]) - box.i0, static_cast<int>(s.cj[k]) - box.j0);
    s.inside[local] = 1;
    locals.push_back(local);
  }
  SquaredDistanceTransformInto(s.inside, box.width, box.height, s);
  const std::vector<double>& d2 = s.d2;
  auto dist_m = [&](int k) { return std::sqrt(d2[k]) * grid.cell_size_m; };
  {
    int max_key = 0;
    for (int c : locals) max_key = std::max(max_key, static_cast<int>(d2[c]));
    s.start.assign(static_cast<size_t>(max_key) + 2, 0);
    for (int c : locals) ++s.start[static_cast<size_t>(max_key - static_cast<int>(d2[c])) + 1];
    for (size_t k = 1; k < s.start.size(); ++k) s.start[k] += s.start[k - 1];
    s.sorted.resize(locals.size());
    for (int c : locals) s.sorted[static_cast<size_t>(s.start[static_cast<size_t>(max_key - static_cast<int>(d2[c]))]++)] = c;
  }
  const std::vector<int>& order = s.sorted;
  std::vector<int>& parent = s.parent;
  std::vector<int>& peak = s.peak;
  std::vector<int>& rank_of = s.rank_of;
  parent.assign(size, -1);
  peak.resize(size);     // read for processed cells only
  rank_of.resize(size);  // read for cells of `order` only
  for (size_t r = 0; r < order.size(); ++r) rank_of[order[r]] = static_cast<int>(r);
  auto find = [&](int x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  };
  const double min_neck_m = std::max(options.split_min_neck_m, grid.cell_size_m);
  const double half_cell_m = 0.5 * grid.cell_size_m;
  std::vector<int>& significant = s.significant;
  significant.clear();
  const int offsets[8] = {-box.width - 1, -box.width, -box.width + 1, -1, 1, box.width - 1, box.width, box.width + 1};
  // Early end: once every processed cell is in one component and the distance has fallen to a
  // level where a newly born peak could not be significant (its height minus half a cell below
  // split_min_peak_radius_m), nothing left can add a peak: a component born from here on is
  // lower than the one holding the highest peak, so it is the one tested when they meet, and
  // fails the height test. low_key: the largest squared distance (whole cells^2) of that level
  // (dist_m is monotonic in d2, so the level is d2 <= low_key).
  int low_key = -1;
  for (int k = 0; k <= static_cast<int>(d2[order.front()]); ++k) {
    if (std::sqrt(static_cast<double>(k)) * grid.cell_size_m - half_cell_m >= options.split_min_peak_radius_m) break;
    low_key = k;
  }
  int components = 0;
  for (int c : order) {
    if (components == 1 && static_cast<int>(d2[c]) <= low_key) break;
    // The parents of the processed neighbours (outside cells and those not processed yet have
    // none), gathered without a branch per neighbour: which ones are processed is unpredictable.
    int linked[8];
    int num_linked = 0;
    for (int o : offsets) {
      const int p = parent[c + o];  // the border is never inside: in range
      linked[num_linked] = p;
      num_linked += p >= 0;
    }
    int roots[8];
    int num_roots = 0;
    for (int k = 0; k < num_linked; ++k) {
      // A parent that is a root already found adds nothing; otherwise its root (found from the
      // parent rather than from the neighbour: another path halved, the same roots).
      const int p = linked[k];
      if (std::find(roots, roots + num_roots, p) != roots + num_roots) continue;
      const int root = find(p);
      if (std::find(roots, roots + num_roots, root) == roots + num_roots) roots[num_roots++] = root;
    }
    if (num_roots == 0) {
      parent[c] = c;
      peak[c] = c;
      ++components;
      continue;
    }
    int best = roots[0];
    for (int k = 1; k < num_roots; ++k) {
      if (rank_of[peak[roots[k]]] < rank_of[peak[best]]) best = roots[k];
    }
    for (int k = 0; k < num_roots; ++k) {
      const int r = roots[k];
      if (r == best) continue;
      const double height_m = dist_m(peak[r]);
      if (height_m - dist_m(c) >= min_neck_m && height_m - half_cell_m >= options.split_min_peak_radius_m) {
        significant.push_back(peak[r]);
      }
      parent[r] = best;
    }
    components -= num_roots - 1;
    parent[c] = best;
  }
  significant.push_back(order.front());  // the highest peak always counts
  std::sort(significant.begin(), significant.end(), [&](int a, int b) { return rank_of[a] < rank_of[b]; });
  for (int local : significant) {
    const int64_t cell = int64_t{local / box.width + box.j0} * grid.cells_x + (local % box.width + box.i0);
    s.peaks.push_back(grid.CellCenter(cell));
  }
}

// The flat arrays of a partition: points, centres, labels.
struct PartitionArrays {
  explicit PartitionArrays(SplitScratch& s)
      : xs(s.xs.data()), ys(s.ys.data()), cx(s.centre_x.data()), cy(s.centre_y.data()), label(s.label.data()) {}
  const double *xs, *ys, *cx, *cy;
  int* label;
};

// A gap as a float no larger than it (the bounds only ever err towards recomputing): moved
// down by 2^-22 of itself, more than the half float step that rounding to nearest may add.
constexpr double kFloatDown = 0x1p-22;
inline float FloatBelow(double gap) { return static_cast<float>(gap - std::abs(gap) * kFloatDown); }

// The points idx[0, m) partitioned among the first k centres (as Partition: the same
// squared distances, ties to the lower centre) with their gap: the distance to the second
// nearest centre minus that to the nearest (rounded down to a float). Whether a label changed.
bool NearestTwoScalar(const PartitionArrays& a, size_t k, const uint32_t* idx, size_t m, float* gap) {
  const double inf = std::numeric_limits<double>::infinity();
  bool changed = false;
  for (size_t i = 0; i < m; ++i) {
    const size_t p = idx[i];
    double best = inf, second = inf;
    int best_c = 0;
    for (size_t c = 0; c < k; ++c) {
      const double dx = a.xs[p] - a.cx[c], dy = a.ys[p] - a.cy[c];
      const double d2 = dx * dx + dy * dy;
      if (d2 < best) {
        second = best;
        best = d2;
        best_c = static_cast<int>(c);
      } else {
        second = std::min(second, d2);
      }
    }
    changed |= a.label[p] != best_c;
    a.label[p] = best_c;
    gap[p] = FloatBelow(std::sqrt(second) - std::sqrt(best));
  }
  return changed;
}

#if OCCMAP_X86_KERNELS
// AVX2, four points at a time, per lane the scalar loop's operations (no FMA, strict <).
__attribute__((target("avx2"))) bool NearestTwoAvx2(const PartitionArrays& a, size_t k, const uint32_t* idx, size_t m,
                                                    float* gap) {
  const __m256d inf = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  bool changed = false;
  size_t i = 0;
  for (; i + 4 <= m; i += 4) {
    const __m256d x = _mm256_set_pd(a.xs[idx[i + 3]], a.xs[idx[i + 2]], a.xs[idx[i + 1]], a.xs[idx[i]]);
    const __m256d y = _mm256_set_pd(a.ys[idx[i + 3]], a.ys[idx[i + 2]], a.ys[idx[i + 1]], a.ys[idx[i]]);
    __m256d best = inf, second = inf, best_c = _mm256_setzero_pd();
    for (size_t c = 0; c < k; ++c) {
      const __m256d dx = _mm256_sub_pd(x, _mm256_set1_pd(a.cx[c]));
      const __m256d dy = _mm256_sub_pd(y, _mm256_set1_pd(a.cy[c]));
      const __m256d d2 = _mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy));
      const __m256d less = _mm256_cmp_pd(d2, best, _CMP_LT_OQ);
      second = _mm256_blendv_pd(_mm256_min_pd(d2, second), best, less);
      best = _mm256_blendv_pd(best, d2, less);
      best_c = _mm256_blendv_pd(best_c, _mm256_set1_pd(static_cast<double>(c)), less);
    }
    alignas(32) double labels[4];
    alignas(16) float gaps[4];
    _mm256_store_pd(labels, best_c);
    const __m256d g = _mm256_sub_pd(_mm256_sqrt_pd(second), _mm256_sqrt_pd(best));
    const __m256d magnitude = _mm256_andnot_pd(_mm256_set1_pd(-0.0), g);
    _mm_store_ps(gaps, _mm256_cvtpd_ps(_mm256_sub_pd(g, _mm256_mul_pd(magnitude, _mm256_set1_pd(kFloatDown)))));
    for (int lane = 0; lane < 4; ++lane) {
      const size_t p = idx[i + static_cast<size_t>(lane)];
      const int c = static_cast<int>(labels[lane]);
      changed |= a.label[p] != c;
      a.label[p] = c;
      gap[p] = gaps[lane];  // FloatBelow
    }
  }
  return NearestTwoScalar(a, k, idx + i, m - i, gap) || changed;
}
#endif

bool NearestTwo(const PartitionArrays& a, size_t k, const uint32_t* idx, size_t m, float* gap) {
#if OCCMAP_X86_KERNELS
  if (ActiveKernels() >= KernelSet::kAvx2) return NearestTwoAvx2(a, k, idx, m, gap);
#endif
  return NearestTwoScalar(a, k, idx, m, gap);
}

// One round's bounds: each point's gap falls by its centre's shift and the largest shift of
// the other centres (`most` moved most, second_most is the largest of the others'); the points
// whose gap is no longer above `slack` are listed in s.recompute. Returns how many.
size_t MoveBoundsScalar(SplitScratch& s, size_t begin, size_t n, size_t most, float second_most, float slack,
                        size_t m) {
  uint32_t* idx = s.recompute.data();
  const float shift_most = s.shift_f[most];
  for (size_t p = begin; p < n; ++p) {
    const size_t c = static_cast<size_t>(s.label[p]);
    const float gap = s.gap[p] - (s.shift_f[c] + (c == most ? second_most : shift_most));
    s.gap[p] = gap;
    idx[m] = static_cast<uint32_t>(p);
    m += !(gap > slack);
  }
  return m;
}

#if OCCMAP_X86_KERNELS
// AVX2, eight points at a time (the same operations per lane).
__attribute__((target("avx2"))) size_t MoveBoundsAvx2(SplitScratch& s, size_t n, size_t most, float second_most,
                                                      float slack) {
  uint32_t* idx = s.recompute.data();
  const float* shift = s.shift_f.data();
  const __m256i most_v = _mm256_set1_epi32(static_cast<int>(most));
  const __m256 other = _mm256_set1_ps(shift[most]), second = _mm256_set1_ps(second_most);
  const __m256 slack_v = _mm256_set1_ps(slack);
  size_t m = 0, p = 0;
  for (; p + 8 <= n; p += 8) {
    const __m256i c = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(s.label.data() + p));
    // Points come in runs of one cluster: a broadcast then (a gather is slow on AMD).
    const int first = s.label[p];
    const bool one_cluster = _mm256_movemask_epi8(_mm256_cmpeq_epi32(c, _mm256_set1_epi32(first))) == -1;
    const int* l = s.label.data() + p;
    const __m256 own = one_cluster ? _mm256_set1_ps(shift[first])
                                   : _mm256_set_ps(shift[l[7]], shift[l[6]], shift[l[5]], shift[l[4]], shift[l[3]],
                                                   shift[l[2]], shift[l[1]], shift[first]);
    const __m256 is_most = _mm256_castsi256_ps(_mm256_cmpeq_epi32(c, most_v));
    const __m256 gap = _mm256_sub_ps(_mm256_loadu_ps(s.gap.data() + p),
                                     _mm256_add_ps(own, _mm256_blendv_ps(other, second, is_most)));
    _mm256_storeu_ps(s.gap.data() + p, gap);
    unsigned need = ~static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(gap, slack_v, _CMP_GT_OQ))) & 0xffu;
    while (need != 0) {
      idx[m++] = static_cast<uint32_t>(p + static_cast<size_t>(std::countr_zero(need)));
      need &= need - 1;
    }
  }
  return MoveBoundsScalar(s, p, n, most, second_most, slack, m);
}
#endif

size_t MoveBounds(SplitScratch& s, size_t n, size_t most, float second_most, float slack) {
#if OCCMAP_X86_KERNELS
  if (ActiveKernels() >= KernelSet::kAvx2) return MoveBoundsAvx2(s, n, most, second_most, slack);
#endif
  return MoveBoundsScalar(s, 0, n, most, second_most, slack, 0);
}

// KMeansCells on flat arrays: the cells' centres s.xs, s.ys and indices s.ci, s.cj, seeds
// s.centre_x, s.centre_y (k of them); the labels in s.label. The same rounds, the same result.
// The clusters' integer sums are kept and moved by the cells that change cluster.
//
// Hamerly's bounds, as one gap per point: a lower bound of (distance to the second nearest
// centre - distance to its own), which falls each round by its centre's shift and the largest
// shift of the others; a point whose gap stays above a slack far beyond the rounding keeps its
// label without a distance computed (the reference's comparison could not come out otherwise);
// the others are partitioned exactly as the reference does. The gaps are floats rounded down
// and the shifts floats rounded up (half the memory per round: under the decoders' load the
// round is memory-bound). WILDTRACK crowds: groups of ~9 000 cells, ~8 centres, ~18 rounds;
// ~90 % of the points skip each round.
void KMeansInto(const FloorGrid& grid, SplitScratch& s, size_t k) {
  const size_t n = s.xs.size();
  s.label.assign(n, -1);
  s.gap.resize(n);
  s.recompute.resize(n);
  s.previous.resize(n);
  const PartitionArrays a(s);
  uint32_t* idx = s.recompute.data();
  // The slack of the gaps: every point-centre distance is at most the points' box diagonal
  // (the centres are means of the points); the floats' rounding over 50 rounds stays under
  // 1e-5 of it, the squared distances' under 1e-12. The slack only makes more points recompute.
  double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x, min_y = min_x, max_y = -min_x;
  for (size_t p = 0; p < n; ++p) {
    min_x = std::min(min_x, s.xs[p]);
    max_x = std::max(max_x, s.xs[p]);
    min_y = std::min(min_y, s.ys[p]);
    max_y = std::max(max_y, s.ys[p]);
  }
  const float slack = static_cast<float>(1e-5 * std::hypot(max_x - min_x, max_y - min_y) + 1e-9);
  // A shift as a float no smaller than it.
  auto float_above = [](double v) {
    float f = static_cast<float>(v);
    if (static_cast<double>(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return f;
  };
  // Gaps from an exact partition of every point.
  auto full = [&] {
    for (size_t p = 0; p < n; ++p) idx[p] = static_cast<uint32_t>(p);
    return NearestTwo(a, k, idx, n, s.gap.data());
  };
  auto sums_from_scratch = [&] {
    s.sum_i.assign(k, 0);
    s.sum_j.assign(k, 0);
    s.counts.assign(k, 0);
    for (size_t p = 0; p < n; ++p) {
      const size_t c = static_cast<size_t>(s.label[p]);
      s.sum_i[c] += s.ci[p];
      s.sum_j[c] += s.cj[p];
      ++s.counts[c];
    }
  };
  full();
  sums_from_scratch();
  for (int round = 0; round < 50; ++round) {
    size_t next = 0;
    s.shift.assign(k, 0.0);
    for (size_t c = 0; c < k; ++c) {
      if (s.counts[c] == 0) continue;
      const Eigen::Vector2d centre = MeanCellCentre(grid, s.sum_i[c], s.sum_j[c], s.counts[c]);
      s.shift[c] = std::hypot(centre.x() - s.centre_x[next], centre.y() - s.centre_y[next]);  // next == c while none emptied
      s.centre_x[next] = centre.x();
      s.centre_y[next] = centre.y();
      ++next;
    }
    if (next != k) {  // a cluster emptied: the others are renumbered, the gaps and sums start again
      k = next;
      if (!full()) break;
      sums_from_scratch();
      continue;
    }
    // The gaps fall by the point's centre's shift and the largest shift of the other centres.
    size_t most = 0;
    for (size_t c = 1; c < k; ++c) most = s.shift[c] > s.shift[most] ? c : most;
    double second_most = 0;
    for (size_t c = 0; c < k; ++c) second_most = c == most ? second_most : std::max(second_most, s.shift[c]);
    s.shift_f.resize(k);
    for (size_t c = 0; c < k; ++c) s.shift_f[c] = float_above(s.shift[c]);
    const size_t m = MoveBounds(s, n, most, float_above(second_most), slack);
    for (size_t r = 0; r < m; ++r) s.previous[r] = s.label[idx[r]];
    if (!NearestTwo(a, k, idx, m, s.gap.data())) break;
    for (size_t r = 0; r < m; ++r) {
      const size_t p = idx[r];
      const size_t from = static_cast<size_t>(s.previous[r]), to = static_cast<size_t>(s.label[p]);
      if (from == to) continue;
      s.sum_i[from] -= s.ci[p];
      s.sum_j[from] -= s.cj[p];
      --s.counts[from];
      s.sum_i[to] += s.ci[p];
      s.sum_j[to] += s.cj[p];
      ++s.counts[to];
    }
  }
}
}  // namespace

BlobSplit SplitBlob(const Blob& blob, const OccupancyMap& map, const ObjectOptions& options, SplitScratch& scratch) {
  if (blob.area_m2 < options.min_detection_area_m2 || blob.cells <= 0) return BlobSplit{};
  return SplitBlobCells(blob, map.grid(), BlobCells(map, blob), options, scratch);
}

BlobSplit SplitBlob(const Blob& blob, const OccupancyMap& map, std::span<const int32_t> labels, int32_t label,
                    const ObjectOptions& options, SplitScratch& scratch) {
  if (blob.area_m2 < options.min_detection_area_m2 || blob.cells <= 0) return BlobSplit{};
  const FloorGrid& grid = map.grid();
  OCCMAP_CHECK(labels.size() == static_cast<size_t>(grid.num_cells()) && blob.min_i >= 0 && blob.min_j >= 0 &&
                   blob.max_i < grid.cells_x && blob.max_j < grid.cells_y,
               "SplitBlob: labels or box not of the map's grid");
  // The component's cells in map order: its box scanned row by row (BlobCells' result).
  std::vector<int64_t> cells;
  cells.reserve(static_cast<size_t>(blob.cells));
  for (int j = blob.min_j; j <= blob.max_j; ++j) {
    const int64_t row = int64_t{j} * grid.cells_x;
    for (int i = blob.min_i; i <= blob.max_i; ++i) {
      if (labels[static_cast<size_t>(row + i)] == label) cells.push_back(row + i);
    }
  }
  OCCMAP_CHECK(static_cast<int64_t>(cells.size()) == blob.cells, "SplitBlob: the labels do not hold the blob");
  return SplitBlobCells(blob, grid, std::move(cells), options, scratch);
}

BlobSplit SplitBlobCells(const Blob& blob, const FloorGrid& grid, std::vector<int64_t> blob_cells,
                         const ObjectOptions& options, SplitScratch& scratch) {
  BlobSplit split;
  split.cells = std::move(blob_cells);
  const std::vector<int64_t>& cells = split.cells;
  split.max_people = MaxPeopleInArea(blob.area_m2, options);
  std::vector<std::vector<int64_t>>& parts = scratch.parts;
  size_t num_parts = 0;
  if (split.max_people >= 2) {
    // Grid coordinates without a division per cell: the cells are sorted, so the row only
    // moves forward (the same i = c % cells_x, j = c / cells_x).
    scratch.ci.resize(cells.size());
    scratch.cj.resize(cells.size());
    {
      int64_t j = cells.empty() ? 0 : cells.front() / grid.cells_x;
      int64_t row = j * grid.cells_x;
      for (size_t p = 0; p < cells.size(); ++p) {
        OCCMAP_CHECK(cells[p] >= row, "SplitBlobCells: cells not sorted");
        while (cells[p] >= row + grid.cells_x) {
          ++j;
          row += grid.cells_x;
        }
        scratch.ci[p] = cells[p] - row;
        scratch.cj[p] = j;
      }
    }
    DistancePeaksInto(grid, cells, options, scratch);
    const size_t seeds = std::min(scratch.peaks.size(), static_cast<size_t>(split.max_people));
    split.peaks = seeds;
    if (seeds >= 2) {
      scratch.xs.resize(cells.size());
      scratch.ys.resize(cells.size());
      for (size_t p = 0; p < cells.size(); ++p) {
        // FloorGrid::CellCenter's expression.
        scratch.xs[p] = grid.origin_x_m + (static_cast<double>(scratch.ci[p]) + 0.5) * grid.cell_size_m;
        scratch.ys[p] = grid.origin_y_m + (static_cast<double>(scratch.cj[p]) + 0.5) * grid.cell_size_m;
      }
      scratch.centre_x.resize(seeds);
      scratch.centre_y.resize(seeds);
      for (size_t c = 0; c < seeds; ++c) {
        scratch.centre_x[c] = scratch.peaks[c].x();
        scratch.centre_y[c] = scratch.peaks[c].y();
      }
      KMeansInto(grid, scratch, seeds);
      num_parts = static_cast<size_t>(*std::max_element(scratch.label.begin(), scratch.label.end())) + 1;
      if (num_parts >= 2) {
        // The parts as indices into the cells (their centres are in xs, ys).
        if (parts.size() < num_parts) parts.resize(num_parts);
        for (size_t k = 0; k < num_parts; ++k) parts[k].clear();
        for (size_t p = 0; p < cells.size(); ++p) {
          parts[static_cast<size_t>(scratch.label[p])].push_back(static_cast<int64_t>(p));
        }
      } else {
        num_parts = 0;
      }
    }
  }
  auto add = [&](const std::vector<int64_t>& part) {
    if (part.empty()) return;
    Detection d = DetectionFromCells(grid, part);
    if (d.area_m2 < options.min_detection_area_m2) return;
    d.group = 0;
    split.detections.push_back(d);
  };
  if (num_parts == 0) {
    add(cells);
  } else {
    for (size_t k = 0; k < num_parts; ++k) {
      if (parts[k].empty()) continue;
      Detection d = DetectionFromPoints(grid, scratch.xs, scratch.ys, parts[k]);
      if (d.area_m2 < options.min_detection_area_m2) continue;
      d.group = 0;
      split.detections.push_back(d);
    }
  }
  for (Detection& d : split.detections) d.parts = static_cast<int>(split.detections.size());
  return split;
}

}  // namespace occmap
