#include "occmap/fusion/fast_fusion.h"

#include <algorithm>
#include <bit>
#include <tuple>
#include <cstring>
#include <utility>

#include "occmap/util/simd.h"
#include "occmap/util/status.h"

#if OCCMAP_X86_KERNELS
#include <immintrin.h>
#endif

namespace occmap {
namespace {

// Row kernels: bits[w] bit i = 1 when pixel 64 w + i is UNCHANGED, for the width pixels of the
// row; writes ceil(width / 64) words (bits past the width are 0).
using ImagesKernel = void (*)(const uint8_t* frame, const uint8_t* background, int width, uint8_t threshold,
                              uint64_t* bits);
using ChangesKernel = void (*)(const uint8_t* changes, int width, uint64_t* bits);

inline uint8_t AbsDiff(uint8_t a, uint8_t b) { return static_cast<uint8_t>(a > b ? a - b : b - a); }

void ImagesPortable(const uint8_t* f, const uint8_t* b, int width, uint8_t t, uint64_t* bits) {
  for (int x0 = 0, w = 0; x0 < width; x0 += 64, ++w) {
    const int n = std::min(64, width - x0);
    uint64_t m = 0;
    for (int i = 0; i < n; ++i) m |= static_cast<uint64_t>(AbsDiff(f[x0 + i], b[x0 + i]) <= t) << i;
    bits[w] = m;
  }
}

void ChangesPortable(const uint8_t* c, int width, uint64_t* bits) {
  for (int x0 = 0, w = 0; x0 < width; x0 += 64, ++w) {
    const int n = std::min(64, width - x0);
    uint64_t m = 0;
    for (int i = 0; i < n; ++i) m |= static_cast<uint64_t>(c[x0 + i] == 0) << i;
    bits[w] = m;
  }
}

#if OCCMAP_X86_KERNELS
__attribute__((target("avx2"))) void ImagesAvx2(const uint8_t* f, const uint8_t* b, int width, uint8_t t,
                                                uint64_t* bits) {
  const __m256i tv = _mm256_set1_epi8(static_cast<char>(t));
  const __m256i zero = _mm256_setzero_si256();
  int x = 0;
  int w = 0;
  for (; x + 64 <= width; x += 64, ++w) {
    uint64_t m = 0;
    for (int h = 0; h < 2; ++h) {
      const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(f + x + 32 * h));
      const __m256i bb = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b + x + 32 * h));
      const __m256i d = _mm256_or_si256(_mm256_subs_epu8(a, bb), _mm256_subs_epu8(bb, a));
      const __m256i unchanged = _mm256_cmpeq_epi8(_mm256_subs_epu8(d, tv), zero);
      m |= static_cast<uint64_t>(static_cast<uint32_t>(_mm256_movemask_epi8(unchanged))) << (32 * h);
    }
    bits[w] = m;
  }
  if (x < width) ImagesPortable(f + x, b + x, width - x, t, bits + w);
}

__attribute__((target("avx2"))) void ChangesAvx2(const uint8_t* c, int width, uint64_t* bits) {
  const __m256i zero = _mm256_setzero_si256();
  int x = 0;
  int w = 0;
  for (; x + 64 <= width; x += 64, ++w) {
    const __m256i lo = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(c + x));
    const __m256i hi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(c + x + 32));
    const uint32_t mlo = static_cast<uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(lo, zero)));
    const uint32_t mhi = static_cast<uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(hi, zero)));
    bits[w] = static_cast<uint64_t>(mlo) | (static_cast<uint64_t>(mhi) << 32);
  }
  if (x < width) ChangesPortable(c + x, width - x, bits + w);
}

// AVX-512BW: 64 pixels = two loads, two saturated subtractions, an OR and one compare into a
// mask register. The tail uses masked loads (lanes past the width read as 0 and are cleared).
__attribute__((target("avx512f,avx512bw"))) void ImagesAvx512(const uint8_t* f, const uint8_t* b, int width,
                                                              uint8_t t, uint64_t* bits) {
  const __m512i tv = _mm512_set1_epi8(static_cast<char>(t));
  int x = 0;
  int w = 0;
  for (; x + 64 <= width; x += 64, ++w) {
    const __m512i a = _mm512_loadu_si512(f + x);
    const __m512i bb = _mm512_loadu_si512(b + x);
    const __m512i d = _mm512_or_si512(_mm512_subs_epu8(a, bb), _mm512_subs_epu8(bb, a));
    bits[w] = static_cast<uint64_t>(_mm512_cmple_epu8_mask(d, tv));
  }
  if (x < width) {
    const __mmask64 live = (uint64_t{1} << (width - x)) - 1;
    const __m512i a = _mm512_maskz_loadu_epi8(live, f + x);
    const __m512i bb = _mm512_maskz_loadu_epi8(live, b + x);
    const __m512i d = _mm512_or_si512(_mm512_subs_epu8(a, bb), _mm512_subs_epu8(bb, a));
    bits[w] = static_cast<uint64_t>(_mm512_mask_cmple_epu8_mask(live, d, tv));
  }
}

__attribute__((target("avx512f,avx512bw"))) void ChangesAvx512(const uint8_t* c, int width, uint64_t* bits) {
  int x = 0;
  int w = 0;
  for (; x + 64 <= width; x += 64, ++w) {
    const __m512i v = _mm512_loadu_si512(c + x);
    bits[w] = static_cast<uint64_t>(_mm512_testn_epi8_mask(v, v));
  }
  if (x < width) {
    const __mmask64 live = (uint64_t{1} << (width - x)) - 1;
    const __m512i v = _mm512_maskz_loadu_epi8(live, c + x);
    bits[w] = static_cast<uint64_t>(_mm512_mask_testn_epi8_mask(live, v, v));
  }
}
#endif  // OCCMAP_X86_KERNELS

// ---- Cell-major probes -------------------------------------------------------------------
// A probe tests one run of `length` (0..64) consecutive pixels of one image row and answers
// "is any of them unchanged?" (length 0 answers false and reads nothing).

// The longest primary run the probe loop tests (see ProbeGroupImpl).
constexpr uint8_t kMaxPrimaryLength = 56;

constexpr uint64_t LengthMask(unsigned length) {
  return length >= 64 ? ~uint64_t{0} : (uint64_t{1} << length) - 1;
}

#if OCCMAP_X86_KERNELS
// BMI1's bit-field extract. Its own function with the target feature: clang checks a builtin's
// feature in the function that spells it (the probe template has none), and inlines this into
// the flattened BMI kernel as GCC does.
__attribute__((target("bmi"))) inline uint64_t Bextr(uint64_t value, uint32_t control) {
  return __builtin_ia32_bextr_u64(value, control);
}
#endif

// Where the probes read: per camera the frame's and the background's first pixel and strides
// (Fuse), or the camera's slice of the change buffer (FuseChanges, b unused).
struct ProbeSource {
  const uint8_t* const* frame;
  const ptrdiff_t* frame_stride;
  const uint8_t* const* background;
  const ptrdiff_t* background_stride;
  const int* width;
  uint8_t threshold;
  // FuseTolerant: the unchanged bits of every pixel (ChangeBits' layout), read instead.
  const unsigned char* bits = nullptr;
  const size_t* bits_camera_word = nullptr;
  const size_t* bits_row_words = nullptr;
};

// A run in the bits of every pixel: one unaligned 64-bit window per at most 56 pixels.
inline bool ProbeBits(const ProbeSource& s, FastFusion::Probe p) {
  const size_t first = 64 * (s.bits_camera_word[p.camera] + s.bits_row_words[p.camera] * p.row) + p.column;
  for (unsigned done = 0; done < p.length; done += 56) {
    const size_t bit = first + done;
    const unsigned n = std::min(56u, static_cast<unsigned>(p.length) - done);
    uint64_t window;
    std::memcpy(&window, s.bits + bit / 8, sizeof(window));
    if (((window >> (bit % 8)) & ((uint64_t{1} << n) - 1)) != 0) return true;
  }
  return false;
}

inline bool ProbeImagesPortable(const ProbeSource& s, FastFusion::Probe p) {
  const uint8_t* f = s.frame[p.camera] + p.row * s.frame_stride[p.camera] + p.column;
  const uint8_t* b = s.background[p.camera] + p.row * s.background_stride[p.camera] + p.column;
  bool any = false;
  for (unsigned i = 0; i < p.length; ++i) any |= AbsDiff(f[i], b[i]) <= s.threshold;
  return any;
}

inline bool ProbeChangesPortable(const ProbeSource& s, FastFusion::Probe p) {
  const uint8_t* c = s.frame[p.camera] + p.row * s.frame_stride[p.camera] + p.column;
  bool any = false;
  for (unsigned i = 0; i < p.length; ++i) any |= c[i] == 0;
  return any;
}

#if OCCMAP_X86_KERNELS
// AVX2: one 32-byte load per image when the run fits in 32 pixels that stay inside the row.
__attribute__((target("avx2"))) inline bool ProbeImagesAvx2(const ProbeSource& s, FastFusion::Probe p) {
  if (p.length > 32 || p.column + 32 > s.width[p.camera]) return ProbeImagesPortable(s, p);
  const uint8_t* f = s.frame[p.camera] + p.row * s.frame_stride[p.camera] + p.column;
  const uint8_t* b = s.background[p.camera] + p.row * s.background_stride[p.camera] + p.column;
  const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(f));
  const __m256i bb = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b));
  const __m256i d = _mm256_or_si256(_mm256_subs_epu8(a, bb), _mm256_subs_epu8(bb, a));
  const __m256i unchanged =
      _mm256_cmpeq_epi8(_mm256_subs_epu8(d, _mm256_set1_epi8(static_cast<char>(s.threshold))), _mm256_setzero_si256());
  return (static_cast<uint32_t>(_mm256_movemask_epi8(unchanged)) & LengthMask(p.length)) != 0;
}

__attribute__((target("avx2"))) inline bool ProbeChangesAvx2(const ProbeSource& s, FastFusion::Probe p) {
  if (p.length > 32 || p.column + 32 > s.width[p.camera]) return ProbeChangesPortable(s, p);
  const uint8_t* c = s.frame[p.camera] + p.row * s.frame_stride[p.camera] + p.column;
  const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(c));
  const uint32_t zero = static_cast<uint32_t>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(v, _mm256_setzero_si256())));
  return (zero & LengthMask(p.length)) != 0;
}

// AVX-512BW: masked loads (lanes past the run are neither read nor faulted on).
__attribute__((target("avx512f,avx512bw"))) inline bool ProbeImagesAvx512(const ProbeSource& s,
                                                                          FastFusion::Probe p) {
  const uint8_t* f = s.frame[p.camera] + p.row * s.frame_stride[p.camera] + p.column;
  const uint8_t* b = s.background[p.camera] + p.row * s.background_stride[p.camera] + p.column;
  const __mmask64 live = LengthMask(p.length);
  const __m512i a = _mm512_maskz_loadu_epi8(live, f);
  const __m512i bb = _mm512_maskz_loadu_epi8(live, b);
  const __m512i d = _mm512_or_si512(_mm512_subs_epu8(a, bb), _mm512_subs_epu8(bb, a));
  return _mm512_mask_cmple_epu8_mask(live, d, _mm512_set1_epi8(static_cast<char>(s.threshold))) != 0;
}

__attribute__((target("avx512f,avx512bw"))) inline bool ProbeChangesAvx512(const ProbeSource& s,
                                                                           FastFusion::Probe p) {
  const uint8_t* c = s.frame[p.camera] + p.row * s.frame_stride[p.camera] + p.column;
  const __mmask64 live = LengthMask(p.length);
  const __m512i v = _mm512_maskz_loadu_epi8(live, c);
  return _mm512_mask_testn_epi8_mask(live, v, v) != 0;
}
#endif  // OCCMAP_X86_KERNELS

// The cells [begin, end): pass 1 probes every cell's primary run (branch-free: the state is
// written as if the probe decides, failures are appended to job.fails); pass 2 tries each
// failed cell's secondary runs until one is free.
// Software prefetch distance (failed cells ahead) of the secondary probes, see ResolveFailsImpl.
constexpr int64_t kFailPrefetch = 8;
// The same for the bit tests of the first secondary runs.
constexpr int64_t kBitPrefetch = 8;
// Fraction of failed primary probes above which the row-streaming method finishes the frame.
constexpr double kDefaultStreamingFallback = 0.15;

inline void PrefetchProbe(const ProbeSource& s, FastFusion::Probe p, bool images) {
  if (s.bits != nullptr) {
    __builtin_prefetch(s.bits + (64 * (s.bits_camera_word[p.camera] + s.bits_row_words[p.camera] * p.row) + p.column) / 8);
    return;
  }
  __builtin_prefetch(s.frame[p.camera] + p.row * s.frame_stride[p.camera] + p.column);
  if (images) __builtin_prefetch(s.background[p.camera] + p.row * s.background_stride[p.camera] + p.column);
}

// Pass 2 of the cell-probe method, once every task's pass 1 is done: for each failed primary
// probe (index into the primary table), its cell's secondary runs until one is free; writes
// kFree. Most cells' first secondary run lies in the span of an image row that pass 1 already
// turned into unchanged bits (BuildCellTables prefers such runs): it is then one bit test in
// that bitmap (1.8 MB on WILDTRACK, in cache) instead of two reads of image lines from memory.
// The cells still undecided after it, or without such a run, are compacted to the front of the
// list and probed in the images, with software prefetch.
struct FailJob {
  const uint32_t* secondary_offsets;  // per primary probe + 1
  const FastFusion::Probe* secondary;
  const uint32_t* first_bits;         // per primary probe: bit << 6 | (64 - length), or kNoFirstBits
  const unsigned char* bitmap;        // the unchanged bits of pass 1's spans
  ProbeSource src;
  uint8_t* out;
  int64_t* bit_tests;                 // out: the first secondary runs tested in the bitmap
};

template <bool (*kProbe)(const ProbeSource&, FastFusion::Probe), bool kImages>
inline int64_t ResolveFailsImpl(const FailJob& job, FastFusion::Fail* fails, int64_t num_fails) {
  int64_t tested = 0;
  // 1. The first secondary runs that are bits of pass 1 (the rest compacted, branch-free).
  int64_t left = 0;
  for (int64_t k = 0; k < num_fails; ++k) {
    // Latency hiding: the cell's first-bits entry 2 d ahead, then its bitmap word and map byte
    // d ahead (failed cells are sparse in the tables: each is a miss without it).
    if (k + 2 * kBitPrefetch < num_fails) __builtin_prefetch(job.first_bits + fails[k + 2 * kBitPrefetch].probe);
    if (k + kBitPrefetch < num_fails) {
      const FastFusion::Fail ahead = fails[k + kBitPrefetch];
      const uint32_t fb = job.first_bits[ahead.probe];
      if (fb != FastFusion::kNoFirstBits) __builtin_prefetch(job.bitmap + (fb >> 9));
      __builtin_prefetch(job.out + ahead.cell, 1);
    }
    const FastFusion::Fail f = fails[k];
    const uint32_t fb = job.first_bits[f.probe];
    bool free = false;
    if (fb != FastFusion::kNoFirstBits) {
      const uint32_t bit = fb >> 6;
      uint64_t window;
      std::memcpy(&window, job.bitmap + (bit >> 3), sizeof(window));
      free = ((window >> (bit & 7u)) << (fb & 63u)) != 0;
      ++tested;
      if (free) job.out[f.cell] = static_cast<uint8_t>(CellState::kFree);
    }
    fails[left] = f;
    left += !free;
  }
  *job.bit_tests = tested;
  // 2. The rest in the images.
  const uint32_t* offsets = job.secondary_offsets;
  const FastFusion::Probe* secondary = job.secondary;
  auto first_run = [&](uint32_t i) {
    return offsets[i] + (job.first_bits[i] != FastFusion::kNoFirstBits ? 1u : 0u);
  };
  for (int64_t k = 0; k < left; ++k) {
    // The records of the cell 2 d ahead, the pixels of the cell d ahead (then in cache).
    if (k + 2 * kFailPrefetch < left) __builtin_prefetch(secondary + offsets[fails[k + 2 * kFailPrefetch].probe]);
    if (k + kFailPrefetch < left) {
      const uint32_t ahead = fails[k + kFailPrefetch].probe;
      const uint32_t r = first_run(ahead);
      if (r < offsets[ahead + 1]) PrefetchProbe(job.src, secondary[r], kImages);
    }
    const FastFusion::Fail f = fails[k];
    for (uint32_t r = first_run(f.probe); r < offsets[f.probe + 1]; ++r) {
      ++tested;
      if (kProbe(job.src, secondary[r])) {
        job.out[f.cell] = static_cast<uint8_t>(CellState::kFree);
        break;
      }
    }
  }
  return tested;
}

using FailKernel = int64_t (*)(const FailJob& job, FastFusion::Fail* fails, int64_t num_fails);

int64_t FailsBits(const FailJob& job, FastFusion::Fail* fails, int64_t n) {
  return ResolveFailsImpl<ProbeBits, false>(job, fails, n);
}

int64_t FailsImagesPortable(const FailJob& job, FastFusion::Fail* fails, int64_t n) {
  return ResolveFailsImpl<ProbeImagesPortable, true>(job, fails, n);
}
int64_t FailsChangesPortable(const FailJob& job, FastFusion::Fail* fails, int64_t n) {
  return ResolveFailsImpl<ProbeChangesPortable, false>(job, fails, n);
}
#if OCCMAP_X86_KERNELS
__attribute__((target("avx2,bmi2"), flatten)) int64_t FailsImagesAvx2(const FailJob& job, FastFusion::Fail* fails, int64_t n) {
  return ResolveFailsImpl<ProbeImagesAvx2, true>(job, fails, n);
}
__attribute__((target("avx2,bmi2"), flatten)) int64_t FailsChangesAvx2(const FailJob& job, FastFusion::Fail* fails, int64_t n) {
  return ResolveFailsImpl<ProbeChangesAvx2, false>(job, fails, n);
}
__attribute__((target("avx512f,avx512bw,bmi2"), flatten)) int64_t FailsImagesAvx512(const FailJob& job,
                                                                                  FastFusion::Fail* fails, int64_t n) {
  return ResolveFailsImpl<ProbeImagesAvx512, true>(job, fails, n);
}
__attribute__((target("avx512f,avx512bw,bmi2"), flatten)) int64_t FailsChangesAvx512(const FailJob& job,
                                                                                   FastFusion::Fail* fails, int64_t n) {
  return ResolveFailsImpl<ProbeChangesAvx512, false>(job, fails, n);
}
#endif  // OCCMAP_X86_KERNELS

// Pass 1's bit tests of one row group: probes [begin, end) against the unchanged bits of the
// row from pixel x0 (bits[0] bit 0), writing each cell's state and appending the failed probes
// to fails (branch-free). A probe reads the 64-bit window starting at the byte of its first
// pixel (an unaligned load: the bitmap row has a word past the width) and tests its
// length (<= kMaxPrimaryLength = 56, so shift + length <= 63) bits after the first pixel's
// offset in that byte; the table stores the byte from the group's first word and the extract
// control (shift | length << 8). 18 instructions per probe with BMI2 shrx/shlx (against ~30 for
// the two-word window it replaced); BMI1's bextr with the stored control and the loop unrolled
// twice: 13, the lab's cell probes 0.50 -> 0.41 ms per frame on 1 thread (AMD EPYC, AVX2).
// Measured (AMD EPYC, AVX-512BW, second core free, 2026-11): the probe loop is the larger part
// of a frame (the row kernel over the spans ~0.9 ms of WILDTRACK's ~3.5); 4 rendered WILDTRACK
// frames on 1 thread 4.00 -> 3.55 ms per frame (-11 %), random frames 3.3 -> 2.6 ms.
// Tried on the failures without gain (same run, A/B): bucketing them by the image rows of their
// first secondary run (a counting sort; the 100 K first secondaries of a frame fall on only
// 5-8.5 K cache lines per image, yet the probes cost the same in that order), a dense table of
// second runs beside the primary one, a branch-free first-secondary loop (5 % slower), a larger
// prefetch distance, the fallback at 35 % instead of 15 %.
using ProbeGroupKernel = int64_t (*)(const FastFusion::PrimaryProbe* primary, const FastFusion::RowGroup& group,
                                     const uint16_t* word_probes, const uint64_t* starts, const uint64_t* bits,
                                     unsigned last_word_bits, uint8_t* out, FastFusion::Fail* fails,
                                     int64_t num_fails, int64_t& tested);

// kBextr: the probe as BMI1's bit-field extract of the window (one instruction with the
// table's control word), else two shifts and a mask.
// Only the probes whose first pixel is changed are tested: a probe whose first pixel is
// unchanged is free, and the map already says so (the frame starts from every seen cell free).
// starts[w]: bit o set when a probe of the group starts at pixel o of the span's word w; the
// changed starts of a word are found with bit scans, each one's probe index from word_probes[w]
// (the group's probes starting before word w) and the starts below it. When two probes of the
// group start at one pixel (coverage-fix pairs), starts is null and every probe starting in a
// word with a changed pixel is tested. last_word_bits: the valid bits of the span's last word
// (past the image width they are 0, "changed"; 64 = all).
template <bool kBextr>
inline int64_t ProbeGroupImpl(const FastFusion::PrimaryProbe* primary, const FastFusion::RowGroup& group,
                              const uint16_t* word_probes, const uint64_t* starts, const uint64_t* bits,
                              unsigned last_word_bits, uint8_t* out, FastFusion::Fail* fails, int64_t num_fails,
                              int64_t& tested) {
  const unsigned char* bytes = reinterpret_cast<const unsigned char*>(bits);
  const unsigned words = static_cast<unsigned>(group.word_end - group.word_begin);
  int64_t n = num_fails;
  auto probe = [&](uint32_t i) {
    const FastFusion::PrimaryProbe p = primary[i];
    uint64_t window;
    std::memcpy(&window, bytes + p.byte, sizeof(window));
    uint64_t run;
#if OCCMAP_X86_KERNELS
    if constexpr (kBextr) {
      run = Bextr(window, p.extract);
    } else
#endif
    {
      run = (window >> (p.extract & 0xffu)) & LengthMask(p.extract >> 8);
    }
    const bool free = run != 0;
    out[p.cell] = static_cast<uint8_t>(2 - static_cast<int>(free));  // kFree 1, kOccupied 2
    fails[n] = FastFusion::Fail{i, p.cell};
    n += !free;
  };
  for (unsigned w = 0; w < words; ++w) {
    uint64_t changed = ~bits[w];
    if (w + 1 == words) changed &= LengthMask(last_word_bits);
    if (changed == 0) continue;  // every probe starting in this word starts unchanged: free
    const uint32_t begin = group.probes_begin + word_probes[w];
    if (starts == nullptr) {
      const uint32_t end = group.probes_begin + word_probes[w + 1];
      tested += end - begin;
      for (uint32_t i = begin; i < end; ++i) probe(i);
      continue;
    }
    const uint64_t word_starts = starts[w];
    for (uint64_t cand = word_starts & changed; cand != 0; cand &= cand - 1) {
      const unsigned o = static_cast<unsigned>(std::countr_zero(cand));
      probe(begin + static_cast<uint32_t>(std::popcount(word_starts & ((uint64_t{1} << o) - 1))));
      ++tested;
    }
  }
  return n;
}

int64_t ProbeGroupPortable(const FastFusion::PrimaryProbe* primary, const FastFusion::RowGroup& group,
                           const uint16_t* word_probes, const uint64_t* starts, const uint64_t* bits,
                           unsigned last_word_bits, uint8_t* out, FastFusion::Fail* fails, int64_t num_fails,
                           int64_t& tested) {
  return ProbeGroupImpl<false>(primary, group, word_probes, starts, bits, last_word_bits, out, fails, num_fails,
                               tested);
}

#if OCCMAP_X86_KERNELS
__attribute__((target("bmi,bmi2,popcnt"), flatten)) int64_t ProbeGroupBmi2(
    const FastFusion::PrimaryProbe* primary, const FastFusion::RowGroup& group, const uint16_t* word_probes,
    const uint64_t* starts, const uint64_t* bits, unsigned last_word_bits, uint8_t* out, FastFusion::Fail* fails,
    int64_t num_fails, int64_t& tested) {
  return ProbeGroupImpl<true>(primary, group, word_probes, starts, bits, last_word_bits, out, fails, num_fails,
                              tested);
}
#endif

struct Kernels {
  ImagesKernel images;
  ChangesKernel changes;
  FailKernel fails_images;
  FailKernel fails_changes;
  const char* name;
  ProbeGroupKernel probe_group;
};

// The kernels of the process's kernel set (util/simd.h; the AVX2 and AVX-512 sets include BMI2).
const Kernels& TheKernels() {
  static constexpr Kernels kPortable{ImagesPortable, ChangesPortable, FailsImagesPortable, FailsChangesPortable,
                                     "portable", ProbeGroupPortable};
#if OCCMAP_X86_KERNELS
  static constexpr Kernels kAvx2{ImagesAvx2, ChangesAvx2, FailsImagesAvx2, FailsChangesAvx2, "avx2", ProbeGroupBmi2};
  static constexpr Kernels kAvx512{ImagesAvx512, ChangesAvx512, FailsImagesAvx512, FailsChangesAvx512, "avx512bw",
                                   ProbeGroupBmi2};
  switch (ActiveKernels()) {
    case KernelSet::kAvx512:
      return kAvx512;
    case KernelSet::kAvx2:
      return kAvx2;
    case KernelSet::kPortable:
      break;
  }
#endif
  return kPortable;
}

static_assert(static_cast<int>(CellState::kUnseen) == 0 && static_cast<int>(CellState::kFree) == 1 &&
              static_cast<int>(CellState::kOccupied) == 2);

// The reduction works on blocks of cells with a local accumulator (vectorised AND).
constexpr int64_t kReduceBlock = 4096;

}  // namespace

// Measured (occmap bench --workload all, AMD EPYC with AVX-512BW, 2 cores shared with other
// work, 2026-11, commit after 4f63e0f; the run with the second core free): 7 x 1920x1080 onto
// 480 x 1440. Random frames (10 % of pixels changed independently, 3.1 % of primary probes
// fail): cell probes 4.0-4.9 Gpixel/s on 1 thread (3.0-3.6 ms/frame), 7.2-10.5 on 2. Rendered
// WILDTRACK frames (simulator, real trajectories, 7.3 % changed, clustered; 13.9 % of primary
// probes fail, ~100 K cells per frame): 3.2-4.0 Gpixel/s on 1 thread, 7.7 on 2; of a 3.5 ms
// frame the row kernel over the spans takes ~0.9 ms, the probe loop ~1 ms, the failures ~1.6.
// The first pass reads 15.5 MB per frame (primary table 5.5 MB, the probed rows' image words).
// Tried without gain: computing only the words the probes touch (61 305 of ~87 000 per image;
// slower, the spans stream better), software prefetch of the next rows' spans and of the map's
// bytes (and, for the failures, see ProbeGroupImpl). Row streaming: 1.5-2.0 Gpixel/s on 1
// thread; it reads 29 MB of images + 29.5 MB of tables (2.47 M runs, 1.12 M coverage pairs).
// Every pixel changed (the hand-over): 2.8-3.3 Gpixel/s on 1 thread. The paper's loop 0.47-0.59
// Gpixel/s on random frames, 1.0-1.2 on rendered ones (its branch predicts well there).
// Since then (AMD EPYC Zen 3, AVX2 only, 2026-12; pass 2 in pass 1's bits, the tiled map,
// bextr probes): rendered WILDTRACK 5.0-7.0 ms per frame on 1 thread (7.1-8.5 before on this
// machine), 2.5-3.6 on 2; pass 2 now answers 86 % of the ~96 K failures by a bit test.
FastFusion::FastFusion(const GroundLut& lut) : grid_(lut.grid()), streaming_fallback_(kDefaultStreamingFallback) {
  const int num_cameras = lut.num_cameras();
  OCCMAP_CHECK(num_cameras > 0, "fast fusion: tables without cameras");
  const uint32_t sentinel = lut.sentinel();
  const size_t num_cells = static_cast<size_t>(grid_.num_cells());
  view_count_.assign(num_cells, 0);
  std::vector<int16_t> last_camera(num_cells, -1);
  auto see = [&](uint32_t cell, int camera) {
    if (last_camera[cell] != camera) {
      last_camera[cell] = static_cast<int16_t>(camera);
      ++view_count_[cell];
    }
  };
  for (int n = 0; n < num_cameras; ++n) {
    const ImageSize size = lut.image_size(n);
    sizes_.push_back(size);
    pixel_offsets_.push_back(lut.pixel_offset(n));
    OCCMAP_CHECK(size.width < 65536 && size.height < 65536, "fast fusion: image wider or taller than 65535");
    max_width_ = std::max(max_width_, size.width);
    const std::span<const uint32_t> l1 = lut.l1(n);
    std::vector<std::pair<uint32_t, uint32_t>> extra;  // (pixel, cell), sorted by pixel
    const std::span<const uint32_t> extra_pixels = lut.extra_pixels(n);
    const std::span<const uint32_t> extra_cells = lut.extra_cells(n);
    for (size_t e = 0; e < extra_pixels.size(); ++e) extra.emplace_back(extra_pixels[e], extra_cells[e]);
    std::sort(extra.begin(), extra.end());
    size_t next_extra = 0;
    for (int r = 0; r < size.height; ++r) {
      WorkRow row{static_cast<uint16_t>(n), static_cast<uint16_t>(r), static_cast<uint32_t>(runs_.size()), 0,
                  static_cast<uint32_t>(pairs_.size()), 0};
      const uint32_t* cells = l1.data() + static_cast<size_t>(r) * size.width;
      int c = 0;
      while (c < size.width) {
        const uint32_t cell = cells[c];
        if (cell == sentinel) {
          ++c;
          continue;
        }
        int length = 1;
        while (c + length < size.width && length < 64 && cells[c + length] == cell) ++length;
        runs_.push_back(Run{cell, static_cast<uint16_t>(c), static_cast<uint16_t>(length)});
        see(cell, n);
        mapped_pixels_ += length;
        c += length;
      }
      const uint32_t row_end_pixel = static_cast<uint32_t>(r + 1) * static_cast<uint32_t>(size.width);
      while (next_extra < extra.size() && extra[next_extra].first < row_end_pixel) {
        const auto [pixel, cell] = extra[next_extra++];
        pairs_.push_back(Pair{cell, pixel - static_cast<uint32_t>(r) * static_cast<uint32_t>(size.width)});
        see(cell, n);
      }
      row.runs_end = static_cast<uint32_t>(runs_.size());
      row.pairs_end = static_cast<uint32_t>(pairs_.size());
      if (row.runs_end > row.runs_begin || row.pairs_end > row.pairs_begin) rows_.push_back(row);
    }
  }
  task_fn_ = [this](int task, int thread) {
    if (reducing_) {
      ReduceTask(task);
    } else {
      RunTask(task, thread);
    }
  };
  for (const ImageSize& size : sizes_) widths_.push_back(size.width);
  BuildCellTables(lut);
  cell_task_fn_ = [this](int task, int) { CellTask(task); };
  erode_fn_ = [this](int task, int) { ErodeTask(task); };
}

// Every (camera, row) run of pixels viewing a cell, plus the coverage-fix pairs as runs of one,
// grouped by cell (camera by camera, rows in order). Per cell the primary probe is the longest
// run of the camera with the most pixels on the cell (the nearest camera: neighbouring cells
// then probe neighbouring pixels of one image). The secondary runs, tried only when the
// primary is all changed: first the longest run of every other camera, the cameras by their
// pixels on the cell (a change is most often one camera's occlusion), then every remaining run.
void FastFusion::BuildCellTables(const GroundLut& lut) {
  const size_t num_cells = static_cast<size_t>(grid_.num_cells());
  const int num_cameras = lut.num_cameras();
  // Counting sort of the runs by cell: the streaming tables already hold them row by row.
  std::vector<uint32_t> count(num_cells + 1, 0);
  for (const Run& run : runs_) ++count[run.cell + 1];
  for (const Pair& pair : pairs_) ++count[pair.cell + 1];
  for (size_t c = 0; c < num_cells; ++c) count[c + 1] += count[c];
  std::vector<Probe> by_cell(count[num_cells]);
  std::vector<uint32_t> next(count.begin(), count.end() - 1);
  for (const WorkRow& wr : rows_) {
    // Runs and pairs of a row interleave by column so the cell's list stays in pixel order.
    uint32_t r = wr.runs_begin, p = wr.pairs_begin;
    while (r < wr.runs_end || p < wr.pairs_end) {
      const bool take_run = p == wr.pairs_end || (r < wr.runs_end && runs_[r].column <= pairs_[p].column);
      uint32_t cell;
      Probe probe{};
      probe.row = wr.row;
      probe.camera = static_cast<uint8_t>(wr.camera);
      if (take_run) {
        cell = runs_[r].cell;
        probe.column = runs_[r].column;
        probe.length = static_cast<uint8_t>(runs_[r].length);
        ++r;
      } else {
        cell = pairs_[p].cell;
        probe.column = static_cast<uint16_t>(pairs_[p].column);
        probe.length = 1;
        ++p;
      }
      by_cell[next[cell]++] = probe;
    }
  }
  // Per cell (cell order first): the primary probe and the secondary list.
  std::vector<Probe> cell_primary(num_cells, Probe{});
  std::vector<uint32_t> cell_secondary_offsets(num_cells + 1, 0);
  std::vector<Probe> cell_secondary;
  cell_secondary.reserve(by_cell.size() - std::min<size_t>(by_cell.size(), num_cells));
  std::vector<int> pixels(static_cast<size_t>(num_cameras));
  std::vector<int> best(static_cast<size_t>(num_cameras));  // index into the cell's list
  std::vector<int> order(static_cast<size_t>(num_cameras));
  std::vector<uint8_t> used;
  // The primary run of a camera: the one whose row has the most trailing zero bits (up to 6),
  // then the longest. A cell spanning several image rows then probes the same row as its
  // neighbours in the image: on WILDTRACK the 691 200 primary probes fall on 3 627 image rows
  // (of 7 560) and 61 305 cache lines of each image.
  auto rank = [](const Probe& p) {
    return std::min(std::countr_zero(static_cast<unsigned>(p.row) | 64u), 6) * 128 + p.length;
  };
  for (size_t c = 0; c < num_cells; ++c) {
    cell_secondary_offsets[c] = static_cast<uint32_t>(cell_secondary.size());
    const uint32_t b = count[c], e = count[c + 1];
    if (b == e) continue;  // unseen: no probe, kUnseen in the base map
    std::fill(pixels.begin(), pixels.end(), 0);
    std::fill(best.begin(), best.end(), -1);
    for (uint32_t k = b; k < e; ++k) {
      const Probe& p = by_cell[k];
      pixels[p.camera] += p.length;
      const int current = best[p.camera];
      if (current < 0 || rank(by_cell[b + static_cast<uint32_t>(current)]) < rank(p)) {
        best[p.camera] = static_cast<int>(k - b);
      }
    }
    for (int n = 0; n < num_cameras; ++n) order[static_cast<size_t>(n)] = n;
    std::stable_sort(order.begin(), order.end(),
                     [&](int x, int y) { return pixels[static_cast<size_t>(x)] > pixels[static_cast<size_t>(y)]; });
    used.assign(e - b, 0);
    bool first = true;
    for (int n : order) {
      const int k = best[static_cast<size_t>(n)];
      if (k < 0) break;  // cameras without pixels come last
      used[static_cast<size_t>(k)] = 1;
      if (first) {
        // The probe loop tests at most kMaxPrimaryLength pixels (one unaligned 64-bit window of
        // the row's bits): a longer run's tail becomes the cell's first secondary run.
        Probe primary = by_cell[b + static_cast<uint32_t>(k)];
        if (primary.length > kMaxPrimaryLength) {
          Probe tail = primary;
          tail.column = static_cast<uint16_t>(primary.column + kMaxPrimaryLength);
          tail.length = static_cast<uint8_t>(primary.length - kMaxPrimaryLength);
          primary.length = kMaxPrimaryLength;
          cell_secondary.push_back(tail);
        }
        cell_primary[c] = primary;
        first = false;
      } else {
        cell_secondary.push_back(by_cell[b + static_cast<uint32_t>(k)]);
      }
    }
    for (uint32_t k = b; k < e; ++k) {
      if (!used[k - b]) cell_secondary.push_back(by_cell[k]);
    }
  }
  cell_secondary_offsets[num_cells] = static_cast<uint32_t>(cell_secondary.size());
  // The primary table in image order (camera, row, column), grouped by image row.
  std::vector<uint32_t> seen_cells;
  for (size_t c = 0; c < num_cells; ++c) {
    if (cell_primary[c].length != 0) seen_cells.push_back(static_cast<uint32_t>(c));
  }
  std::sort(seen_cells.begin(), seen_cells.end(), [&](uint32_t x, uint32_t y) {
    const Probe& a = cell_primary[x];
    const Probe& b = cell_primary[y];
    return std::tie(a.camera, a.row, a.column, x) < std::tie(b.camera, b.row, b.column, y);
  });
  primary_.clear();
  row_groups_.clear();
  secondary_.clear();
  secondary_.reserve(cell_secondary.size());
  secondary_offsets_.assign(seen_cells.size() + 1, 0);
  for (size_t i = 0; i < seen_cells.size(); ++i) {
    const uint32_t c = seen_cells[i];
    const Probe& p = cell_primary[c];
    const int first_word = p.column / 64, last_word = (p.column + p.length - 1) / 64;
    if (row_groups_.empty() || row_groups_.back().camera != p.camera || row_groups_.back().row != p.row) {
      row_groups_.push_back(
          RowGroup{static_cast<uint32_t>(i), p.camera, p.row, static_cast<uint16_t>(first_word), 0, 0});
    }
    RowGroup& group = row_groups_.back();
    group.word_end = std::max<uint16_t>(group.word_end, static_cast<uint16_t>(last_word + 1));
    const int offset = p.column - group.word_begin * 64;  // bits from the group's first word
    primary_.push_back(PrimaryProbe{c, static_cast<uint16_t>(offset >> 3),
                                    static_cast<uint16_t>((offset & 7) | (p.length << 8))});
    secondary_offsets_[i] = static_cast<uint32_t>(secondary_.size());
    secondary_.insert(secondary_.end(), cell_secondary.begin() + cell_secondary_offsets[c],
                      cell_secondary.begin() + cell_secondary_offsets[c + 1]);
  }
  secondary_offsets_[seen_cells.size()] = static_cast<uint32_t>(secondary_.size());
  row_groups_.push_back(RowGroup{static_cast<uint32_t>(primary_.size()), 0, 0, 0, 0, 0});  // end marker
  // Per group and word w of its span (and one past the span): its first probe whose first
  // pixel is in word w or later, from the group's first probe (a row holds < 65536 probes).
  // And the starts bitmap beside it (starts_[word_probes_begin + w], the extra entry 0), or
  // the group marked in shared_starts_ when two of its probes start at one pixel.
  word_probes_.clear();
  starts_.clear();
  shared_starts_.assign(row_groups_.size(), 0);
  for (size_t g = 0; g + 1 < row_groups_.size(); ++g) {
    RowGroup& group = row_groups_[g];
    group.word_probes_begin = static_cast<uint32_t>(word_probes_.size());
    const uint32_t end = row_groups_[g + 1].probes_begin;
    uint32_t i = group.probes_begin;
    for (int w = 0; w <= group.word_end - group.word_begin; ++w) {
      while (i < end && primary_[i].byte / 8 < w) ++i;
      word_probes_.push_back(static_cast<uint16_t>(i - group.probes_begin));
      starts_.push_back(0);
    }
    for (uint32_t k = group.probes_begin; k < end; ++k) {
      const unsigned offset = primary_[k].byte * 8u + (primary_[k].extract & 7u);  // the first pixel in the span
      uint64_t& word = starts_[group.word_probes_begin + offset / 64];
      const uint64_t bit = uint64_t{1} << (offset % 64);
      if ((word & bit) != 0) shared_starts_[g] = 1;
      word |= bit;
    }
  }
  // The map a frame starts from: every seen cell free.
  base_states_.assign(num_cells, static_cast<uint8_t>(CellState::kUnseen));
  for (uint32_t c : seen_cells) base_states_[c] = static_cast<uint8_t>(CellState::kFree);
  BuildFirstBits();
}

// The bitmap of pass 1 (per camera, rows of ceil(width / 64) + 1 words: the extra word keeps
// an unaligned window read at the row's last pixel inside the row) and, per primary probe, the
// cell's first secondary run as a bit test in it when pass 1 computes the bits of that run: a
// run of at most kMaxPrimaryLength pixels inside the span of its row's group. Such a run of the
// camera ranked first among the others is moved to the front of the cell's secondary runs.
void FastFusion::BuildFirstBits() {
  const size_t cameras = sizes_.size();
  bitmap_row_words_.assign(cameras, 0);
  bitmap_camera_word_.assign(cameras, 0);
  size_t words = 0;
  for (size_t n = 0; n < cameras; ++n) {
    bitmap_row_words_[n] = static_cast<size_t>(sizes_[n].width + 63) / 64 + 1;
    bitmap_camera_word_[n] = words;
    words += bitmap_row_words_[n] * static_cast<size_t>(sizes_[n].height);
  }
  bitmap_.assign(words + 1, 0);
  // The span [word_begin, word_end) of each (camera, row) with a group, else (0, 0).
  std::vector<std::vector<std::pair<uint16_t, uint16_t>>> span(cameras);
  for (size_t n = 0; n < cameras; ++n) span[n].assign(static_cast<size_t>(sizes_[n].height), {0, 0});
  for (size_t g = 0; g + 1 < row_groups_.size(); ++g) {
    const RowGroup& group = row_groups_[g];
    span[group.camera][group.row] = {group.word_begin, group.word_end};
  }
  auto covered = [&](const Probe& q) {
    const auto [b, e] = span[q.camera][q.row];
    return q.length <= kMaxPrimaryLength && q.column >= b * 64 &&
           q.column + q.length <= std::min(widths_[q.camera], e * 64);
  };
  first_bits_.assign(primary_.size(), kNoFirstBits);
  for (size_t i = 0; i < primary_.size(); ++i) {
    Probe* list = secondary_.data() + secondary_offsets_[i];
    const size_t count = secondary_offsets_[i + 1] - secondary_offsets_[i];
    if (count == 0) continue;
    size_t pick = count;
    for (size_t k = 0; k < count && pick == count; ++k) {
      if (covered(list[k])) pick = k;
    }
    if (pick == count) continue;
    std::rotate(list, list + pick, list + pick + 1);
    const Probe& q = list[0];
    const uint64_t bit = 64 * (bitmap_camera_word_[q.camera] + bitmap_row_words_[q.camera] * q.row) + q.column;
    if (bit >= (uint64_t{1} << 26)) continue;
    first_bits_[i] = static_cast<uint32_t>(bit << 6) | (64u - q.length);
  }
}

int64_t FastFusion::StreamingTableBytes() const {
  return static_cast<int64_t>(runs_.size() * sizeof(Run) + pairs_.size() * sizeof(Pair) +
                              rows_.size() * sizeof(WorkRow) + view_count_.size());
}

int64_t FastFusion::ProbeTableBytes() const {
  return static_cast<int64_t>(primary_.size() * sizeof(PrimaryProbe) + row_groups_.size() * sizeof(RowGroup) +
                              secondary_offsets_.size() * sizeof(uint32_t) + secondary_.size() * sizeof(Probe) +
                              first_bits_.size() * sizeof(uint32_t) + bitmap_.size() * sizeof(uint64_t) +
                              word_probes_.size() * sizeof(uint16_t) + starts_.size() * sizeof(uint64_t) +
                              shared_starts_.size() + base_states_.size());
}

int64_t FastFusion::MemoryBytes() const { return StreamingTableBytes() + ProbeTableBytes(); }

int64_t FastFusion::TableBytesPerFrame() const { return StreamingTableBytes(); }

int64_t FastFusion::ProbeBytesPerFrame() const {
  int64_t bytes = static_cast<int64_t>(primary_.size() * sizeof(PrimaryProbe) + row_groups_.size() * sizeof(RowGroup));
  for (size_t g = 0; g + 1 < row_groups_.size(); ++g) {
    const RowGroup& group = row_groups_[g];
    bytes += 2 * (std::min(widths_[group.camera], group.word_end * 64) - group.word_begin * 64);
  }
  return bytes;
}

const char* FastFusion::KernelName() { return TheKernels().name; }

bool FastFusion::ForceKernelForTesting(std::string_view name) { return ForceKernelsForTesting(name); }

void FastFusion::Fuse(std::span<const ImageView<const uint8_t>> frames,
                      std::span<const ImageView<const uint8_t>> backgrounds, int threshold, Context& ctx,
                      OccupancyMap& map) {
  FuseWith(Method::kCellProbe, frames, backgrounds, threshold, ctx, map);
}

void FastFusion::FuseChanges(std::span<const uint8_t> changes, Context& ctx, OccupancyMap& map) {
  FuseChangesWith(Method::kCellProbe, changes, ctx, map);
}

void FastFusion::FuseWith(Method method, std::span<const ImageView<const uint8_t>> frames,
                          std::span<const ImageView<const uint8_t>> backgrounds, int threshold, Context& ctx,
                          OccupancyMap& map) {
  OCCMAP_CHECK(frames.size() == sizes_.size() && backgrounds.size() == sizes_.size(),
               "fast fusion: one frame and one background per camera");
  OCCMAP_CHECK(threshold >= 0 && threshold <= 255, "fast fusion: threshold outside 0..255");
  for (size_t n = 0; n < sizes_.size(); ++n) {
    OCCMAP_CHECK(frames[n].width() == sizes_[n].width && frames[n].height() == sizes_[n].height &&
                     backgrounds[n].width() == sizes_[n].width && backgrounds[n].height() == sizes_[n].height,
                 "fast fusion: image size differs from the tables'");
  }
  input_ = Input::kImages;
  frames_ = frames;
  backgrounds_ = backgrounds;
  threshold_ = static_cast<uint8_t>(threshold);
  bits_base_ = bitmap_.data();
  if (method == Method::kCellProbe) {
    ExecuteCells(ctx, map);
  } else {
    stats_ = FrameStats{};
    Execute(ctx, map);
  }
}

void FastFusion::FuseChangesWith(Method method, std::span<const uint8_t> changes, Context& ctx, OccupancyMap& map) {
  OCCMAP_CHECK(changes.size() == pixel_offsets_.back() + static_cast<size_t>(sizes_.back().width) *
                                                               static_cast<size_t>(sizes_.back().height),
               "fast fusion: change buffer size differs from the tables' pixels");
  input_ = Input::kChanges;
  changes_ = changes;
  bits_base_ = bitmap_.data();
  if (method == Method::kCellProbe) {
    ExecuteCells(ctx, map);
  } else {
    stats_ = FrameStats{};
    Execute(ctx, map);
  }
}

void FastFusion::FuseTolerant(std::span<const ImageView<const uint8_t>> frames,
                              std::span<const ImageView<const uint8_t>> backgrounds, int threshold, int tolerance_px,
                              Context& ctx, OccupancyMap& map, ChangeBits& bits) {
  OCCMAP_CHECK(frames.size() == sizes_.size() && backgrounds.size() == sizes_.size(),
               "fast fusion: one frame and one background per camera");
  OCCMAP_CHECK(threshold >= 0 && threshold <= 255, "fast fusion: threshold outside 0..255");
  OCCMAP_CHECK(tolerance_px >= 1 && tolerance_px <= kMaxFusedTolerancePx, "fast fusion: tolerance outside 1..8");
  for (size_t n = 0; n < sizes_.size(); ++n) {
    OCCMAP_CHECK(frames[n].width() == sizes_[n].width && frames[n].height() == sizes_[n].height &&
                     backgrounds[n].width() == sizes_[n].width && backgrounds[n].height() == sizes_[n].height,
                 "fast fusion: image size differs from the tables'");
  }
  frames_ = frames;
  backgrounds_ = backgrounds;
  threshold_ = static_cast<uint8_t>(threshold);
  tolerance_px_ = tolerance_px;
  bits.row_words = bitmap_row_words_;
  bits.camera_word = bitmap_camera_word_;
  bits.words.resize(bitmap_.size());
  bits_base_ = bits.words.data();
  // Pass 0: the eroded bits, a task per camera and band of rows.
  const int threads = ctx.num_threads();
  erode_tasks_ = static_cast<int>(sizes_.size()) * (threads <= 1 ? 1 : 2);
  const ThreadPool::Burst burst(ctx.pool());  // pass 0 and the cell probes' passes, back to back
  if (erode_rows_.size() < static_cast<size_t>(erode_tasks_)) erode_rows_.resize(static_cast<size_t>(erode_tasks_));
  if (threads <= 1) {
    for (int t = 0; t < erode_tasks_; ++t) ErodeTask(t);
  } else {
    ctx.pool().Run(erode_tasks_, erode_fn_);
  }
  input_ = Input::kBits;
  ExecuteCells(ctx, map);
}

// A camera's band of rows [y0, y1) (task = camera * bands + band): the unchanged bits U of the rows it needs (r more on each
// side), eroded along the row (a pixel stays unchanged when the r pixels on each side are;
// past the image counts as unchanged), then across the rows of the window (clipped).
void FastFusion::ErodeTask(int task) {
  const int bands = erode_tasks_ / static_cast<int>(sizes_.size());
  const size_t n = static_cast<size_t>(task / bands);
  const int band = task % bands;
  const int width = sizes_[n].width, height = sizes_[n].height;
  const int y0 = height * band / bands, y1 = height * (band + 1) / bands;
  const int r = tolerance_px_;
  const size_t words = static_cast<size_t>(width + 63) / 64;
  const size_t row_words = bitmap_row_words_[n];
  const uint64_t past_width = width % 64 == 0 ? 0 : ~uint64_t{0} << (width % 64);
  const int from = std::max(0, y0 - r), to = std::min(height, y1 + r);
  // The task's own buffer: one row of U, then its eroded rows from `from` (bands overlap by r
  // rows, each computes those it reads).
  std::vector<uint64_t>& scratch = erode_rows_[static_cast<size_t>(task)];
  scratch.resize(words * static_cast<size_t>(to - from + 1));
  uint64_t* u = scratch.data();
  uint64_t* eroded = scratch.data() + words;
  const Kernels& kernels = TheKernels();
  for (int y = from; y < to; ++y) {
    kernels.images(frames_[n].row(y), backgrounds_[n].row(y), width, threshold_, u);
    u[words - 1] |= past_width;
    uint64_t* e = eroded + words * static_cast<size_t>(y - from);
    for (size_t w = 0; w < words; ++w) {
      const uint64_t x = u[w];
      const uint64_t prev = w > 0 ? u[w - 1] : ~uint64_t{0};
      const uint64_t next = w + 1 < words ? u[w + 1] : ~uint64_t{0};
      uint64_t acc = x;
      for (int d = 1; d <= r; ++d) {
        acc &= (x << d) | (prev >> (64 - d));  // the pixel d to the left
        acc &= (x >> d) | (next << (64 - d));  // d to the right
      }
      e[w] = acc;
    }
  }
  uint64_t* out = bits_base_ + bitmap_camera_word_[n];
  for (int y = y0; y < y1; ++y) {
    uint64_t* o = out + row_words * static_cast<size_t>(y);
    const int v0 = std::max(0, y - r), v1 = std::min(height - 1, y + r);
    for (size_t w = 0; w < words; ++w) {
      uint64_t acc = ~uint64_t{0};
      for (int v = v0; v <= v1; ++v) acc &= eroded[words * static_cast<size_t>(v - from) + w];
      o[w] = acc;
    }
    o[words - 1] &= ~past_width;
    for (size_t w = words; w < row_words; ++w) o[w] = 0;
  }
}

void FastFusion::ExecuteCells(Context& ctx, OccupancyMap& map) {
  if (!(map.grid() == grid_) || map.states().size() != static_cast<size_t>(grid_.num_cells())) {
    map = OccupancyMap(grid_);
  }
  states_ = map.states().data();
  // Every seen cell free; the probes write the cells whose primary run has a changed pixel.
  std::memcpy(states_, base_states_.data(), base_states_.size());
  const size_t cameras = sizes_.size();
  probe_frame_.resize(cameras);
  probe_background_.resize(cameras);
  probe_frame_stride_.resize(cameras);
  probe_background_stride_.resize(cameras);
  for (size_t n = 0; n < cameras; ++n) {
    if (input_ != Input::kChanges) {
      probe_frame_[n] = frames_[n].data();
      probe_frame_stride_[n] = frames_[n].stride_elems();
      probe_background_[n] = backgrounds_[n].data();
      probe_background_stride_[n] = backgrounds_[n].stride_elems();
    } else {
      probe_frame_[n] = changes_.data() + pixel_offsets_[n];
      probe_frame_stride_[n] = sizes_[n].width;
      probe_background_[n] = probe_frame_[n];
      probe_background_stride_[n] = probe_frame_stride_[n];
    }
  }
  const int threads = ctx.num_threads();
  const ThreadPool::Burst burst(ctx.pool());  // the passes of the frame, back to back
  const size_t probes = row_groups_.back().probes_begin;
  const size_t groups = row_groups_.size() - 1;
  // Contiguous ranges of row groups with about the same number of probes, several per thread
  // (handed out dynamically); each cell is written by the one task that holds its primary
  // probe, so there is no per-thread map and no reduction.
  // On one thread too: the tasks' first probes are the sample that decides the fallback, and
  // they must come from the whole image, not from its first rows.
  num_tasks_ = static_cast<int>(std::clamp<size_t>(groups, 1, static_cast<size_t>(std::max(threads, 2)) * 8));
  task_groups_.resize(static_cast<size_t>(num_tasks_) + 1);
  for (int t = 0; t < num_tasks_; ++t) {
    const uint32_t first_probe = static_cast<uint32_t>(probes * static_cast<size_t>(t) / static_cast<size_t>(num_tasks_));
    task_groups_[static_cast<size_t>(t)] = static_cast<uint32_t>(
        std::lower_bound(row_groups_.begin(), row_groups_.end() - 1, first_probe,
                         [](const RowGroup& g, uint32_t v) { return g.probes_begin < v; }) -
        row_groups_.begin());
  }
  task_groups_[static_cast<size_t>(num_tasks_)] = static_cast<uint32_t>(groups);
  fails_.resize(probes);
  task_fails_.assign(static_cast<size_t>(num_tasks_), 0);
  task_deferred_.assign(static_cast<size_t>(num_tasks_), 0);
  task_stop_.assign(static_cast<size_t>(num_tasks_), 0);
  task_probed_.assign(static_cast<size_t>(num_tasks_), 0);
  task_tested_.assign(static_cast<size_t>(num_tasks_), 0);
  task_secondary_.assign(static_cast<size_t>(num_tasks_), 0);
  task_bit_tests_.assign(static_cast<size_t>(num_tasks_), 0);
  stats_ = FrameStats{};
  auto run = [&](Phase phase) {
    phase_ = phase;
    if (threads <= 1) {
      for (int t = 0; t < num_tasks_; ++t) CellTask(t);
    } else {
      ctx.pool().Run(num_tasks_, cell_task_fn_);
    }
  };
  run(Phase::kProbe);
  // Tasks stop early when their failures pass the fallback fraction; the failure rate of what
  // all tasks probed then decides between finishing with cell probes and row streaming.
  int64_t failed = 0, probed = 0;
  bool any_deferred = false;
  for (size_t t = 0; t < static_cast<size_t>(num_tasks_); ++t) {
    failed += task_fails_[t];
    probed += task_probed_[t];
    any_deferred |= task_deferred_[t] != 0;
  }
  auto gather = [&] {
    stats_.primary_probed = 0;
    stats_.primary_failed = 0;
    stats_.primary_tested = 0;
    stats_.secondary_probed = 0;
    stats_.secondary_bit_tests = 0;
    for (size_t t = 0; t < static_cast<size_t>(num_tasks_); ++t) {
      stats_.primary_probed += task_probed_[t];
      stats_.primary_failed += task_fails_[t];
      stats_.primary_tested += task_tested_[t];
      stats_.secondary_probed += task_secondary_[t];
      stats_.secondary_bit_tests += task_bit_tests_[t];
    }
  };
  if (!any_deferred) {
    if (input_ != Input::kBits) run(Phase::kResolve);  // with bits, every task resolved its own
    gather();
    return;
  }
  if (static_cast<double>(failed) > streaming_fallback_ * static_cast<double>(probed)) {
    // Most cells failed their primary probe (a lighting change, the camera covered): streaming
    // every pixel once beats probing each cell's secondary runs one by one (it writes every cell).
    gather();
    Execute(ctx, map);
    return;
  }
  run(Phase::kFinish);
  if (input_ != Input::kBits) run(Phase::kResolve);
  gather();
}

void FastFusion::CellTask(int task) {
  const size_t t = static_cast<size_t>(task);
  const uint32_t first_probe = row_groups_[task_groups_[t]].probes_begin;
  Fail* fails = fails_.data() + first_probe;
  switch (phase_) {
    case Phase::kProbe: {
      int64_t num_fails = 0;
      int64_t tested = 0;
      const uint32_t stop =
          ProbeRows(task_groups_[t], task_groups_[t + 1], fails, num_fails, tested, /*may_stop=*/true);
      task_tested_[t] = tested;
      task_fails_[t] = num_fails;
      task_stop_[t] = stop;
      task_probed_[t] = row_groups_[stop].probes_begin - first_probe;
      task_deferred_[t] = stop != task_groups_[t + 1];  // decided once every task has counted its failures
      // FuseTolerant's bits are all there before pass 1 (pass 0 computed them): a task that
      // probed all its rows resolves its failures at once, while they are in cache, without
      // waiting for the others (a frame handed to row streaming afterwards overwrites them);
      // a deferred one does so in kFinish. kResolve then never runs with bits.
      if (input_ == Input::kBits && !task_deferred_[t]) ResolveTask(t);
      return;
    }
    case Phase::kFinish: {  // a task that stopped early: its other rows
      if (!task_deferred_[t]) return;
      int64_t num_fails = task_fails_[t];
      ProbeRows(task_stop_[t], task_groups_[t + 1], fails, num_fails, task_tested_[t], /*may_stop=*/false);
      task_fails_[t] = num_fails;
      task_probed_[t] = row_groups_[task_groups_[t + 1]].probes_begin - first_probe;
      if (input_ == Input::kBits) ResolveTask(t);
      return;
    }
    case Phase::kResolve:  // frames and change buffers: once every task's pass 1 is done
      ResolveTask(t);
      return;
  }
}

// Pass 2 of task t: its failed primary probes' secondary runs (ResolveFailsImpl).
void FastFusion::ResolveTask(size_t t) {
  const uint32_t first_probe = row_groups_[task_groups_[t]].probes_begin;
  Fail* fails = fails_.data() + first_probe;
  const Kernels& kernels = TheKernels();
  FailJob job;
  job.secondary_offsets = secondary_offsets_.data();
  job.secondary = secondary_.data();
  job.first_bits = first_bits_.data();
  job.bitmap = reinterpret_cast<const unsigned char*>(bits_base_);
  job.src = ProbeSource{probe_frame_.data(), probe_frame_stride_.data(), probe_background_.data(),
                        probe_background_stride_.data(), widths_.data(), threshold_};
  if (input_ == Input::kBits) {
    job.src.bits = reinterpret_cast<const unsigned char*>(bits_base_);
    job.src.bits_camera_word = bitmap_camera_word_.data();
    job.src.bits_row_words = bitmap_row_words_.data();
  }
  job.out = reinterpret_cast<uint8_t*>(states_);
  job.bit_tests = &task_bit_tests_[t];
  const FailKernel resolve = input_ == Input::kImages    ? kernels.fails_images
                             : input_ == Input::kChanges ? kernels.fails_changes
                                                         : FailsBits;
  task_secondary_[t] = resolve(job, fails, task_fails_[t]);
}

// Pass 1 over the row groups [begin, end): per image row, the unchanged bits of the words the
// row's probes touch, then one bit test per probe (branch-free; failures appended to fails).
// With may_stop, returns early (the first group not done) once more than the fallback fraction
// of at least fallback_sample_ probes (4096) failed.
uint32_t FastFusion::ProbeRows(uint32_t begin, uint32_t end, Fail* fails, int64_t& num_fails, int64_t& tested,
                               bool may_stop) {
  const Kernels& kernels = TheKernels();
  uint8_t* out = reinterpret_cast<uint8_t*>(states_);
  const PrimaryProbe* primary = primary_.data();
  const uint32_t first_probe = row_groups_[begin].probes_begin;
  // The bits of group g + 1 are computed before the probes of group g read those of g: the
  // probes' unaligned windows then read bits whose stores have left the store buffer (a window
  // spanning two just-stored words cannot be forwarded and stalls).
  auto row_bits = [&](uint32_t g) {
    const RowGroup& group = row_groups_[g];
    uint64_t* bits = bits_base_ + bitmap_camera_word_[group.camera] +
                     bitmap_row_words_[group.camera] * static_cast<size_t>(group.row) + group.word_begin;
    if (input_ == Input::kBits) return bits;  // every row's bits are there already
    const int x0 = group.word_begin * 64;
    const int columns = std::min(widths_[group.camera], group.word_end * 64) - x0;
    if (input_ == Input::kImages) {
      kernels.images(probe_frame_[group.camera] + group.row * probe_frame_stride_[group.camera] + x0,
                     probe_background_[group.camera] + group.row * probe_background_stride_[group.camera] + x0,
                     columns, threshold_, bits);
    } else {
      kernels.changes(probe_frame_[group.camera] + group.row * probe_frame_stride_[group.camera] + x0, columns, bits);
    }
    // A window may read a word past the span: inside the row (its extra word), whatever bits
    // it holds are shifted out by the extract.
    return bits;
  };
  if (begin >= end) return end;
  uint64_t* bits = row_bits(begin);
  for (uint32_t g = begin; g < end; ++g) {
    const RowGroup& group = row_groups_[g];
    if (may_stop && group.probes_begin - first_probe >= fallback_sample_ &&
        static_cast<double>(num_fails) > streaming_fallback_ * static_cast<double>(group.probes_begin - first_probe)) {
      return g;
    }
    uint64_t* next = g + 1 < end ? row_bits(g + 1) : nullptr;
    const int span_end = std::min(widths_[group.camera], group.word_end * 64);
    const unsigned last_word_bits = static_cast<unsigned>(span_end - (group.word_end - 1) * 64);
    num_fails = kernels.probe_group(primary, group, word_probes_.data() + group.word_probes_begin,
                                    shared_starts_[g] ? nullptr : starts_.data() + group.word_probes_begin, bits,
                                    last_word_bits, out, fails, num_fails, tested);
    bits = next;
  }
  return end;
}

void FastFusion::Prepare(Context& ctx, OccupancyMap& map) {
  if (!(map.grid() == grid_) || map.states().size() != static_cast<size_t>(grid_.num_cells())) {
    map = OccupancyMap(grid_);
  }
  states_ = map.states().data();
  const size_t threads = static_cast<size_t>(std::max(ctx.num_threads(), ctx.pool().num_workers() + 1));
  if (partial_.size() < threads) {
    partial_.resize(threads);
    bits_.resize(threads);
    thread_used_.resize(threads);
    for (size_t t = 0; t < threads; ++t) {
      partial_[t].resize(static_cast<size_t>(grid_.num_cells()));
      bits_[t].resize(static_cast<size_t>(max_width_) / 64 + 2);
    }
  }
  std::fill(thread_used_.begin(), thread_used_.end(), uint8_t{0});
}

void FastFusion::Execute(Context& ctx, OccupancyMap& map) {
  Prepare(ctx, map);
  stats_.streamed = true;
  const int threads = ctx.num_threads();
  // Several tasks per thread: the pool hands them out dynamically (rows differ in cost).
  reducing_ = false;
  num_tasks_ = threads <= 1 ? 1 : std::min<int>(threads * 4, static_cast<int>(std::max<size_t>(rows_.size(), 1)));
  if (num_tasks_ == 1) {
    RunTask(0, 0);
  } else {
    ctx.pool().Run(num_tasks_, task_fn_);
  }
  reducing_ = true;
  const int64_t blocks = (grid_.num_cells() + kReduceBlock - 1) / kReduceBlock;
  num_tasks_ = static_cast<int>(std::min<int64_t>(threads <= 1 ? 1 : threads, blocks));
  if (num_tasks_ <= 1) {
    ReduceTask(0);
    num_tasks_ = 1;
  } else {
    ctx.pool().Run(num_tasks_, task_fn_);
  }
  reducing_ = false;
}

void FastFusion::RunTask(int task, int thread) {
  const size_t total = rows_.size();
  const size_t begin = total * static_cast<size_t>(task) / static_cast<size_t>(num_tasks_);
  const size_t end = total * static_cast<size_t>(task + 1) / static_cast<size_t>(num_tasks_);
  if (begin == end) return;
  const size_t t = static_cast<size_t>(thread);
  uint8_t* part = partial_[t].data();
  if (thread_used_[t] == 0) {
    std::memset(part, 1, partial_[t].size());
    thread_used_[t] = 1;
  }
  uint64_t* bits = bits_[t].data();
  const Kernels& kernels = TheKernels();
  const Run* runs = runs_.data();
  const Pair* pairs = pairs_.data();
  for (size_t i = begin; i < end; ++i) {
    const WorkRow& wr = rows_[i];
    const int width = sizes_[wr.camera].width;
    const uint64_t* row_bits = bits;
    if (input_ == Input::kBits) {  // FuseTolerant's bits of every pixel (a zero word past the row)
      row_bits = bits_base_ + bitmap_camera_word_[wr.camera] + bitmap_row_words_[wr.camera] * wr.row;
    } else {
      if (input_ == Input::kImages) {
        kernels.images(frames_[wr.camera].row(wr.row), backgrounds_[wr.camera].row(wr.row), width, threshold_, bits);
      } else {
        kernels.changes(changes_.data() + pixel_offsets_[wr.camera] + static_cast<size_t>(wr.row) * width, width,
                        bits);
      }
      bits[(width + 63) / 64] = 0;  // a run never reads past its row, but keep the word defined
    }
    for (uint32_t r = wr.runs_begin; r < wr.runs_end; ++r) {
      const Run run = runs[r];
      const unsigned shift = run.column & 63u;
      const size_t word = run.column >> 6;
      // Branch-free 64-bit window at the run's first pixel (the next word always exists: bits
      // has a zero word past the row); (x << 1) << (63 - s) is x << (64 - s), 0 for s = 0.
      const uint64_t v = (row_bits[word] >> shift) | ((row_bits[word + 1] << 1) << (63 - shift));
      const uint64_t need = ~uint64_t{0} >> (64 - run.length);
      if ((v & need) != 0) part[run.cell] = 0;
    }
    for (uint32_t p = wr.pairs_begin; p < wr.pairs_end; ++p) {
      const Pair pair = pairs[p];
      if ((row_bits[pair.column >> 6] >> (pair.column & 63u)) & 1u) part[pair.cell] = 0;
    }
  }
}

void FastFusion::ReduceTask(int task) {
  const int64_t cells = grid_.num_cells();
  const int64_t blocks = (cells + kReduceBlock - 1) / kReduceBlock;
  const int64_t block_begin = blocks * task / num_tasks_;
  const int64_t block_end = blocks * (task + 1) / num_tasks_;
  uint8_t* out = reinterpret_cast<uint8_t*>(states_);
  const uint8_t* views = view_count_.data();
  uint8_t acc[kReduceBlock];
  for (int64_t blk = block_begin; blk < block_end; ++blk) {
    const int64_t c0 = blk * kReduceBlock;
    const int64_t n = std::min(kReduceBlock, cells - c0);
    std::memset(acc, 1, static_cast<size_t>(n));
    for (size_t t = 0; t < partial_.size(); ++t) {
      if (thread_used_[t] == 0) continue;
      const uint8_t* p = partial_[t].data() + c0;
      for (int64_t i = 0; i < n; ++i) acc[i] = static_cast<uint8_t>(acc[i] & p[i]);
    }
    // kUnseen = 0 when no camera sees the cell, else kFree = 1 / kOccupied = 2.
    for (int64_t i = 0; i < n; ++i) {
      out[c0 + i] = static_cast<uint8_t>(views[c0 + i] != 0 ? 1 + acc[i] : 0);
    }
  }
}

}  // namespace occmap
