#include "occmap/io/limited_range.h"

#include <algorithm>

#include "occmap/util/simd.h"

namespace occmap {

namespace {

// In 16-bit arithmetic so that GCC vectorises it: 0.29 ms per 1920x1080 frame, against 1.2 ms
// for a 256-entry table (2-core x86-64 development machine, -O3, SSE2 baseline); compiled
// again for AVX2 (32 pixels per step), chosen by the kernel set (util/simd.h).
[[gnu::always_inline]] inline void LumaRow(const uint8_t* src, uint8_t* dst, int width) {
  for (int x = 0; x < width; ++x) {
    const uint8_t above_black = src[x] > 16 ? static_cast<uint8_t>(src[x] - 16) : uint8_t{0};
    const uint8_t clamped = std::min(above_black, uint8_t{219});
    dst[x] = static_cast<uint8_t>(static_cast<uint16_t>(clamped * 298 + 128) >> 8);
  }
}

// round(d x 255 / 224) for d = c - 16 in 0..224 as the high half of a 16-bit product:
// ((16 d + 7) x 4663) >> 16 equals it for every d (found by exhaustive search; the vector
// multiply-high needs no 32-bit lanes).
[[gnu::always_inline]] inline void ChromaRow(const uint8_t* src, uint8_t* dst, int width) {
  for (int x = 0; x < width; ++x) {
    const uint8_t above_low = src[x] > 16 ? static_cast<uint8_t>(src[x] - 16) : uint8_t{0};
    const uint16_t clamped = std::min(above_low, uint8_t{224});
    const uint16_t scaled = static_cast<uint16_t>(clamped * 16 + 7);
    dst[x] = static_cast<uint8_t>((static_cast<uint32_t>(scaled) * 4663u) >> 16);
  }
}

#if OCCMAP_X86_KERNELS
__attribute__((target("avx2"))) void LumaRowAvx2(const uint8_t* src, uint8_t* dst, int width) {
  LumaRow(src, dst, width);
}
__attribute__((target("avx2"))) void ChromaRowAvx2(const uint8_t* src, uint8_t* dst, int width) {
  ChromaRow(src, dst, width);
}
#endif

}  // namespace

void ExpandLimitedRangeLuma(const uint8_t* src, uint8_t* dst, int width) {
#if OCCMAP_X86_KERNELS
  if (ActiveKernels() >= KernelSet::kAvx2) return LumaRowAvx2(src, dst, width);
#endif
  LumaRow(src, dst, width);
}

void ExpandLimitedRangeChroma(const uint8_t* src, uint8_t* dst, int width) {
#if OCCMAP_X86_KERNELS
  if (ActiveKernels() >= KernelSet::kAvx2) return ChromaRowAvx2(src, dst, width);
#endif
  ChromaRow(src, dst, width);
}

uint8_t ExpandLimitedRangeLumaReference(uint8_t y) {
  const int d = std::clamp(static_cast<int>(y), 16, 235) - 16;
  return static_cast<uint8_t>((d * 298 + 128) / 256);
}

uint8_t ExpandLimitedRangeChromaReference(uint8_t c) {
  const int d = std::clamp(static_cast<int>(c), 16, 240) - 16;
  return static_cast<uint8_t>((d * 255 + 112) / 224);
}

}  // namespace occmap
