#include "occmap/detect/adaptive_change_kernels.h"

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

// The loop as selects, no branches, so that the compiler vectorises it (the tables read by
// gathers on AVX2 and AVX-512); the same arithmetic as the reference.
[[gnu::always_inline]] inline int64_t UpdateRowBody(const UpdateRowArgs& a) {
  const int w = a.width;
  const bool chroma_row = a.frame_u != nullptr;
  const bool chroma_fast = chroma_row && a.inv_c != nullptr;
  int64_t newly = 0;
  for (int x = 0; x < w; ++x) {
    const int level = a.frame_y[x];
    // With a fitted colour transfer the chroma blocks' top-left pixels go to the model's loop.
    const bool simple = (a.protection[x] == kFreeProtection) & (a.classes[x] == kBackgroundClass) &
                        !(chroma_row & !chroma_fast & ((x & 1) == 0));
    const int32_t b = a.background_y[x];
    const int32_t nb = Follow(b, a.inv_y[level], a.alpha);
    a.background_y[x] = static_cast<uint16_t>(simple ? nb : b);
    a.steady_frames[x] = simple ? uint16_t{0} : a.steady_frames[x];
    const int32_t s = a.set_frame[x];
    newly += simple & (s < 0);
    a.set_frame[x] = simple ? a.frame : s;
    a.previous_y[x] = simple ? static_cast<uint8_t>(level) : a.previous_y[x];
    a.rest[x] = simple ? 0 : 1;
  }
  if (chroma_fast) {
    const int cw = (w + 1) / 2;
    for (int c = 0; c < cw; ++c) {
      const bool simple = a.rest[2 * c] == 0;
      const int32_t bu = a.background_u[c], bv = a.background_v[c];
      const int32_t nu = Follow(bu, a.inv_c[a.frame_u[c]], a.alpha);
      const int32_t nv = Follow(bv, a.inv_c[a.frame_v[c]], a.alpha);
      a.background_u[c] = static_cast<uint16_t>(simple ? nu : bu);
      a.background_v[c] = static_cast<uint16_t>(simple ? nv : bv);
    }
  }
  return newly;
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

int64_t UpdateFreeBackgroundRow(const UpdateRowArgs& a) {
#if OCCMAP_X86_KERNELS
  const KernelSet set = ActiveKernels();
  if (set >= KernelSet::kAvx512) return UpdateRowAvx512(a);
  if (set >= KernelSet::kAvx2) return UpdateRowAvx2(a);
#endif
  return UpdateRowBody(a);
}

}  // namespace occmap
