#include "occmap/detect/adaptive_change_kernels.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <utility>

#include "occmap/util/simd.h"

namespace occmap {
namespace {

constexpr uint8_t kFreeProtection = 0;  // BackgroundModel::kFree
constexpr uint8_t kBackgroundClass = 0;  // BackgroundModel::kBackground

// One exponential step in 8.8: (target - value) * alpha / 65536 rounded half up, the division
// truncated towards zero (BackgroundModel::Update's integer expression).
inline int32_t Follow(int32_t value, int32_t target, int32_t alpha) {
  return value + ((target - value) * alpha + 32768) / 65536;
}

// The luma part of a row, the pointers as restrict parameters (see ChangeTestLoop).
[[gnu::always_inline]] inline int UpdateLumaLoop(int w, const uint8_t* __restrict frame_y,
                                                 const uint8_t* __restrict protection,
                                                 const uint8_t* __restrict classes, uint16_t* __restrict background_y,
                                                 uint8_t* __restrict previous_y, uint16_t* __restrict steady_frames,
                                                 int32_t* __restrict set_frame, const int32_t* __restrict inv_y,
                                                 uint8_t* __restrict rest, int32_t alpha, int32_t frame,
                                                 bool even_to_model) {
  static_assert(kFreeProtection == 0 && kBackgroundClass == 0);
  const int odd_only = even_to_model ? 0 : 1;  // 0: the even pixels go to the model's loop
  int newly = 0;
  for (int x = 0; x < w; ++x) {
    const int level = frame_y[x];
    // With a fitted colour transfer the chroma blocks' top-left pixels go to the model's loop.
    const int simple = static_cast<int>((protection[x] | classes[x]) == 0) & ((x & 1) | odd_only);
    // Selects as masks (m: all ones where simple): selects of stored values become branches.
    const int32_t m = -static_cast<int32_t>(simple);
    const int32_t b = background_y[x];
    const int32_t nb = Follow(b, inv_y[level], alpha);
    background_y[x] = static_cast<uint16_t>(b + ((nb - b) & m));
    steady_frames[x] = static_cast<uint16_t>(steady_frames[x] & ~m);
    const int32_t s = set_frame[x];
    newly += simple & (s < 0);
    set_frame[x] = s + ((frame - s) & m);
    const int32_t p = previous_y[x];
    previous_y[x] = static_cast<uint8_t>(p + ((level - p) & m));
    rest[x] = static_cast<uint8_t>(simple ^ 1);
  }
  return newly;
}

[[gnu::always_inline]] inline void UpdateChromaLoop(int cw, const uint8_t* __restrict rest,
                                                    const uint8_t* __restrict frame_u, const uint8_t* __restrict frame_v,
                                                    uint16_t* __restrict background_u, uint16_t* __restrict background_v,
                                                    const int32_t* __restrict inv_c, int32_t alpha) {
  for (int c = 0; c < cw; ++c) {
    const bool simple = rest[2 * c] == 0;
    const int32_t bu = background_u[c], bv = background_v[c];
    const int32_t nu = Follow(bu, inv_c[frame_u[c]], alpha);
    const int32_t nv = Follow(bv, inv_c[frame_v[c]], alpha);
    background_u[c] = static_cast<uint16_t>(simple ? nu : bu);
    background_v[c] = static_cast<uint16_t>(simple ? nv : bv);
  }
}

// The loop as selects, no branches, so that the compiler vectorises it (the tables read by
// gathers on AVX2 and AVX-512); the same arithmetic as the reference.
[[gnu::always_inline]] inline int64_t UpdateRowBody(const UpdateRowArgs& a) {
  const bool chroma_row = a.frame_u != nullptr;
  const bool chroma_fast = chroma_row && a.inv_c != nullptr;
  const int newly = UpdateLumaLoop(a.width, a.frame_y, a.protection, a.classes, a.background_y, a.previous_y,
                                   a.steady_frames, a.set_frame, a.inv_y, a.rest, a.alpha, a.frame,
                                   chroma_row && !chroma_fast);
  if (chroma_fast) {
    UpdateChromaLoop((a.width + 1) / 2, a.rest, a.frame_u, a.frame_v, a.background_u, a.background_v, a.inv_c, a.alpha);
  }
  return newly;
}

constexpr int kClippedWhite = 250, kClippedBlack = 3;  // BackgroundModel::kClippedWhite, kClippedBlack

[[gnu::always_inline]] inline void ChromaFlagsRowBody(int width, const uint8_t* __restrict fu,
                                                     const uint8_t* __restrict fv, const uint8_t* __restrict eu,
                                                     const uint8_t* __restrict ev, int strong, int weak,
                                                     uint8_t* __restrict flags) {
  const int pairs = width / 2;
  // weak <= 0: no weak chroma; 255 is never exceeded by a difference of bytes.
  const int wt = weak > 0 ? weak : 255;
  for (int c = 0; c < pairs; ++c) {
    const int du = std::abs(fu[c] - eu[c]), dv = std::abs(fv[c] - ev[c]);
    const uint8_t f = static_cast<uint8_t>(((du > strong) | (dv > strong)) | (((du > wt) | (dv > wt)) << 1));
    flags[2 * c] = f;
    flags[2 * c + 1] = f;
  }
  if (width % 2 != 0) {
    const int c = pairs;
    const int du = std::abs(fu[c] - eu[c]), dv = std::abs(fv[c] - ev[c]);
    flags[2 * c] = static_cast<uint8_t>(((du > strong) | (dv > strong)) | (((du > wt) | (dv > wt)) << 1));
  }
}

// Branch-free over the row (the compiler vectorises it: 32-bit multiplies for the expected
// level, the rest in bytes).
// The pointers as restrict parameters (GCC takes restrict from parameters, not from locals):
// without, the overlap checks of six arrays exceed its limit and the loop stays scalar.
[[gnu::always_inline]] inline int ChangeTestLoop(int width, const uint8_t* __restrict frame,
                                                 const uint8_t* __restrict background, const uint8_t* __restrict cc,
                                                 int32_t gq, int32_t cq, int t, int tw, uint8_t* __restrict classes,
                                                 uint8_t* __restrict changes, uint8_t* __restrict weak) {
  int count = 0;
  for (int x = 0; x < width; ++x) {
    const int b = background[x];
    int p = (gq * b + cq) >> 16;
    p = p < 0 ? 0 : (p > 255 ? 255 : p);
    p = b >= kClippedWhite ? (p + 256) >> 1 : (b <= kClippedBlack ? p >> 1 : p);
    const int d = frame[x] - p;
    const uint8_t c = static_cast<uint8_t>((d > t) | (d < -t) | (cc[x] & 1));
    const uint8_t w = static_cast<uint8_t>(((d > tw) | (d < -tw) | (cc[x] >> 1)) & (c ^ 1));
    classes[x] = c;
    changes[x] = c;
    weak[x] = w;
    count += c;
  }
  return count;
}

[[gnu::always_inline]] inline int ChangeTestRowBody(const ChangeRowArgs& a) {
  return ChangeTestLoop(a.width, a.frame_y, a.background_y, a.chroma_flags, a.gain_q16, a.offset_q16, a.threshold,
                        a.weak_threshold, a.classes, a.changes, a.weak);
}

// 3 x 3 dilation of seed rows above, at and below (null: out of the image) into band: the
// vertical maximum into column[1, width] (column[0] and column[width + 1] are 0), then the
// horizontal one over it.
[[gnu::always_inline]] inline void DilateRowBody(int width, const uint8_t* __restrict above,
                                                const uint8_t* __restrict at, const uint8_t* __restrict below,
                                                uint8_t* __restrict column, uint8_t* __restrict band) {
  uint8_t* v = column + 1;
  for (int x = 0; x < width; ++x) v[x] = at[x];
  if (above != nullptr) {
    for (int x = 0; x < width; ++x) v[x] |= above[x];
  }
  if (below != nullptr) {
    for (int x = 0; x < width; ++x) v[x] |= below[x];
  }
  for (int x = 0; x < width; ++x) band[x] = static_cast<uint8_t>(column[x] | column[x + 1] | column[x + 2]);
}

// The weak pixels of a band row become changes and seeds; returns how many.
[[gnu::always_inline]] inline int GrowRowBody(int width, const uint8_t* __restrict band, uint8_t* __restrict weak,
                                              uint8_t* __restrict changes, uint8_t* __restrict seeds,
                                              uint8_t* __restrict classes) {
  // Masks, not selects: the compiler keeps selects of stores as branches.
  int added = 0;
  for (int x = 0; x < width; ++x) {
    const uint8_t n = static_cast<uint8_t>((band[x] != 0) & (weak[x] != 0));
    const uint8_t keep = static_cast<uint8_t>(n - 1);  // 0 where it grows, 0xff elsewhere
    changes[x] = static_cast<uint8_t>((changes[x] & keep) | n);
    seeds[x] = static_cast<uint8_t>((seeds[x] & keep) | n);
    classes[x] = static_cast<uint8_t>((classes[x] & keep) | n);
    weak[x] = static_cast<uint8_t>(weak[x] & keep);
    added += n;
  }
  return added;
}

#if OCCMAP_X86_KERNELS
__attribute__((target("avx2,bmi,bmi2"))) void ChromaFlagsRowAvx2(int width, const uint8_t* fu, const uint8_t* fv,
                                                                  const uint8_t* eu, const uint8_t* ev, int strong,
                                                                  int weak, uint8_t* flags) {
  ChromaFlagsRowBody(width, fu, fv, eu, ev, strong, weak, flags);
}
__attribute__((target("avx512f,avx512bw,avx2,bmi,bmi2"))) void ChromaFlagsRowAvx512(
    int width, const uint8_t* fu, const uint8_t* fv, const uint8_t* eu, const uint8_t* ev, int strong, int weak,
    uint8_t* flags) {
  ChromaFlagsRowBody(width, fu, fv, eu, ev, strong, weak, flags);
}
__attribute__((target("avx2,bmi,bmi2"))) int ChangeTestRowAvx2(const ChangeRowArgs& a) { return ChangeTestRowBody(a); }
__attribute__((target("avx512f,avx512bw,avx2,bmi,bmi2"))) int ChangeTestRowAvx512(const ChangeRowArgs& a) {
  return ChangeTestRowBody(a);
}
__attribute__((target("avx2,bmi,bmi2"))) void DilateRowAvx2(int width, const uint8_t* above, const uint8_t* at,
                                                             const uint8_t* below, uint8_t* column, uint8_t* band) {
  DilateRowBody(width, above, at, below, column, band);
}
__attribute__((target("avx2,bmi,bmi2"))) int GrowRowAvx2(int width, const uint8_t* band, uint8_t* weak,
                                                          uint8_t* changes, uint8_t* seeds, uint8_t* classes) {
  return GrowRowBody(width, band, weak, changes, seeds, classes);
}
#endif

void DilateRow(int width, const uint8_t* above, const uint8_t* at, const uint8_t* below, uint8_t* column,
               uint8_t* band) {
#if OCCMAP_X86_KERNELS
  if (ActiveKernels() >= KernelSet::kAvx2) return DilateRowAvx2(width, above, at, below, column, band);
#endif
  DilateRowBody(width, above, at, below, column, band);
}

int GrowRow(int width, const uint8_t* band, uint8_t* weak, uint8_t* changes, uint8_t* seeds, uint8_t* classes) {
#if OCCMAP_X86_KERNELS
  if (ActiveKernels() >= KernelSet::kAvx2) return GrowRowAvx2(width, band, weak, changes, seeds, classes);
#endif
  return GrowRowBody(width, band, weak, changes, seeds, classes);
}

// The first non-zero byte of row[from, width), or width.
int NextNonZero(const uint8_t* row, int from, int width) {
  int x = from;
  while (x + 8 <= width) {
    uint64_t word;
    std::memcpy(&word, row + x, 8);
    if (word != 0) break;
    x += 8;
  }
  while (x < width && row[x] == 0) ++x;
  return x;
}

// The first zero byte of row[from, width), or width.
int NextZero(const uint8_t* row, int from, int width) {
  int x = from;
  while (x < width && row[x] != 0) ++x;
  return x;
}

int32_t FindRoot(std::vector<int32_t>& parent, int32_t i) {
  while (parent[static_cast<size_t>(i)] != i) {
    parent[static_cast<size_t>(i)] = parent[static_cast<size_t>(parent[static_cast<size_t>(i)])];
    i = parent[static_cast<size_t>(i)];
  }
  return i;
}

#if OCCMAP_X86_KERNELS
__attribute__((target("avx2,bmi,bmi2"))) int64_t UpdateRowAvx2(const UpdateRowArgs& a) { return UpdateRowBody(a); }
__attribute__((target("avx512f,avx512bw,avx2,bmi,bmi2"))) int64_t UpdateRowAvx512(const UpdateRowArgs& a) {
  return UpdateRowBody(a);
}
#endif

}  // namespace

int64_t UpdateFreeBackgroundRowReference(const UpdateRowArgs& a) {
  int64_t newly = 0;
  const bool chroma_row = a.frame_u != nullptr;
  for (int x = 0; x < a.width; ++x) {
    a.rest[x] = 1;
    if (a.protection[x] != kFreeProtection || a.classes[x] != kBackgroundClass) continue;
    const bool top_left = chroma_row && x % 2 == 0;
    if (top_left && a.inv_c == nullptr) continue;
    a.rest[x] = 0;
    a.previous_y[x] = a.frame_y[x];
    a.steady_frames[x] = 0;
    a.background_y[x] = static_cast<uint16_t>(Follow(a.background_y[x], a.inv_y[a.frame_y[x]], a.alpha));
    if (top_left) {
      const int c = x / 2;
      a.background_u[c] = static_cast<uint16_t>(Follow(a.background_u[c], a.inv_c[a.frame_u[c]], a.alpha));
      a.background_v[c] = static_cast<uint16_t>(Follow(a.background_v[c], a.inv_c[a.frame_v[c]], a.alpha));
    }
    newly += a.set_frame[x] < 0;
    a.set_frame[x] = a.frame;
  }
  return newly;
}

void ChromaFlagsRowReference(int width, const uint8_t* frame_u, const uint8_t* frame_v, const uint8_t* expected_u,
                             const uint8_t* expected_v, int strong, int weak, uint8_t* flags) {
  for (int x = 0; x < width; ++x) {
    const int c = x / 2;
    const int du = std::abs(frame_u[c] - expected_u[c]), dv = std::abs(frame_v[c] - expected_v[c]);
    flags[x] = static_cast<uint8_t>((du > strong || dv > strong ? 1 : 0) + (weak > 0 && (du > weak || dv > weak) ? 2 : 0));
  }
}

void ChromaFlagsRow(int width, const uint8_t* frame_u, const uint8_t* frame_v, const uint8_t* expected_u,
                    const uint8_t* expected_v, int strong, int weak, uint8_t* flags) {
#if OCCMAP_X86_KERNELS
  const KernelSet set = ActiveKernels();
  if (set >= KernelSet::kAvx512) return ChromaFlagsRowAvx512(width, frame_u, frame_v, expected_u, expected_v, strong, weak, flags);
  if (set >= KernelSet::kAvx2) return ChromaFlagsRowAvx2(width, frame_u, frame_v, expected_u, expected_v, strong, weak, flags);
#endif
  ChromaFlagsRowBody(width, frame_u, frame_v, expected_u, expected_v, strong, weak, flags);
}

int ChangeTestRowReference(const ChangeRowArgs& a) {
  int count = 0;
  for (int x = 0; x < a.width; ++x) {
    const int b = a.background_y[x];
    int expected = std::clamp((a.gain_q16 * b + a.offset_q16) >> 16, 0, 255);
    if (b >= kClippedWhite) expected = (expected + 256) >> 1;
    if (b <= kClippedBlack) expected >>= 1;
    const int d = std::abs(a.frame_y[x] - expected);
    const bool changed = d > a.threshold || (a.chroma_flags[x] & 1) != 0;
    a.classes[x] = a.changes[x] = changed ? 1 : 0;
    a.weak[x] = !changed && (d > a.weak_threshold || (a.chroma_flags[x] & 2) != 0) ? 1 : 0;
    count += changed;
  }
  return count;
}

int ChangeTestRow(const ChangeRowArgs& a) {
#if OCCMAP_X86_KERNELS
  const KernelSet set = ActiveKernels();
  if (set >= KernelSet::kAvx512) return ChangeTestRowAvx512(a);
  if (set >= KernelSet::kAvx2) return ChangeTestRowAvx2(a);
#endif
  return ChangeTestRowBody(a);
}

int64_t GrowChangesFromWeak(ImageView<uint8_t> changes, ImageView<uint8_t> weak, ImageView<uint8_t> classes, int steps,
                            int64_t min_seed_pixels, Image<uint8_t>& seeds, Image<uint8_t>& band) {
  const int w = changes.width(), h = changes.height();
  if (seeds.width() != w || seeds.height() != h) seeds = Image<uint8_t>(w, h);
  if (band.width() != w || band.height() != h) band = Image<uint8_t>(w, h);
  // The changes' runs per row, joined into 8-connected components (union-find over runs: the
  // changes are a few percent of the pixels, so this reads each row once and little else).
  struct Run {
    int32_t y, x0, x1;
  };
  std::vector<Run> runs;
  std::vector<int32_t> parent;
  int32_t previous_begin = 0, previous_end = 0;
  for (int y = 0; y < h; ++y) {
    const uint8_t* row = changes.row(y);
    const int32_t begin = static_cast<int32_t>(runs.size());
    int32_t k = previous_begin;
    for (int x = NextNonZero(row, 0, w); x < w; x = NextNonZero(row, x, w)) {
      const int x1 = NextZero(row, x, w);
      const int32_t id = static_cast<int32_t>(runs.size());
      runs.push_back({y, x, x1});
      parent.push_back(id);
      // Runs of the row above touching [x - 1, x1] (8-connected).
      while (k < previous_end && runs[static_cast<size_t>(k)].x1 < x) ++k;
      for (int32_t j = k; j < previous_end && runs[static_cast<size_t>(j)].x0 <= x1; ++j) {
        const int32_t a = FindRoot(parent, id), b = FindRoot(parent, j);
        if (a != b) parent[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
      }
      x = x1;
    }
    previous_begin = begin;
    previous_end = static_cast<int32_t>(runs.size());
  }
  std::vector<int64_t> area(runs.size(), 0);
  for (size_t r = 0; r < runs.size(); ++r) area[static_cast<size_t>(FindRoot(parent, static_cast<int32_t>(r)))] += runs[r].x1 - runs[r].x0;
  for (int y = 0; y < h; ++y) std::memset(seeds.row(y), 0, static_cast<size_t>(w));
  int y_lo = h, y_hi = -1;  // rows holding seeds
  for (size_t r = 0; r < runs.size(); ++r) {
    if (area[static_cast<size_t>(FindRoot(parent, static_cast<int32_t>(r)))] < min_seed_pixels) continue;
    const Run& run = runs[r];
    std::memset(seeds.row(run.y) + run.x0, 1, static_cast<size_t>(run.x1 - run.x0));
    y_lo = std::min(y_lo, static_cast<int>(run.y));
    y_hi = std::max(y_hi, static_cast<int>(run.y));
  }
  int64_t added = 0;
  std::vector<uint8_t> column(static_cast<size_t>(w) + 2, 0);
  for (int step = 0; step < steps && y_lo <= y_hi; ++step) {
    // The band of this step's seeds (the rows next to them), then the weak pixels in it.
    const int lo = std::max(0, y_lo - 1), hi = std::min(h - 1, y_hi + 1);
    for (int y = lo; y <= hi; ++y) {
      DilateRow(w, y > 0 ? seeds.row(y - 1) : nullptr, seeds.row(y), y + 1 < h ? seeds.row(y + 1) : nullptr, column.data(),
                band.row(y));
    }
    int64_t step_added = 0;
    for (int y = lo; y <= hi; ++y) {
      const int n = GrowRow(w, band.row(y), weak.row(y), changes.row(y), seeds.row(y), classes.row(y));
      if (n > 0) {
        y_lo = std::min(y_lo, y);
        y_hi = std::max(y_hi, y);
      }
      step_added += n;
    }
    added += step_added;
    if (step_added == 0) break;
  }
  return added;
}

int64_t GrowChangesFromWeakReference(ImageView<uint8_t> changes, ImageView<uint8_t> weak, ImageView<uint8_t> classes,
                                     int steps, int64_t min_seed_pixels) {
  const int w = changes.width(), h = changes.height();
  Image<uint8_t> seeds(w, h, 0), seen(w, h, 0);
  std::vector<std::pair<int, int>> component, stack;
  for (int y0 = 0; y0 < h; ++y0) {
    for (int x0 = 0; x0 < w; ++x0) {
      if (changes(x0, y0) == 0 || seen(x0, y0) != 0) continue;
      component.clear();
      stack.assign(1, {x0, y0});
      seen(x0, y0) = 1;
      while (!stack.empty()) {
        const auto [x, y] = stack.back();
        stack.pop_back();
        component.push_back({x, y});
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || xx >= w || yy < 0 || yy >= h || changes(xx, yy) == 0 || seen(xx, yy) != 0) continue;
            seen(xx, yy) = 1;
            stack.push_back({xx, yy});
          }
        }
      }
      if (static_cast<int64_t>(component.size()) < min_seed_pixels) continue;
      for (const auto& [x, y] : component) seeds(x, y) = 1;
    }
  }
  int64_t added = 0;
  for (int step = 0; step < steps; ++step) {
    const Image<uint8_t> before = seeds;
    int64_t step_added = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (weak(x, y) == 0) continue;
        bool next_to_seed = false;
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx >= 0 && xx < w && yy >= 0 && yy < h && before(xx, yy) != 0) next_to_seed = true;
          }
        }
        if (!next_to_seed) continue;
        changes(x, y) = seeds(x, y) = classes(x, y) = 1;
        weak(x, y) = 0;
        ++step_added;
      }
    }
    added += step_added;
    if (step_added == 0) break;
  }
  return added;
}

int64_t UpdateFreeBackgroundRow(const UpdateRowArgs& a) {
#if OCCMAP_X86_KERNELS
  const KernelSet set = ActiveKernels();
  if (set >= KernelSet::kAvx512) return UpdateRowAvx512(a);
  if (set >= KernelSet::kAvx2) return UpdateRowAvx2(a);
#endif
  return UpdateRowBody(a);
}

}  // namespace occmap
