// Kernel sets: the one place where the SIMD paths of the fast kernels are chosen.
//
// Every fast kernel has a portable path (plain C++, or Highway at its static target: NEON on
// aarch64, baseline SSE2/emulation on x86-64) and, on x86-64 builds, hand-written AVX2 and
// AVX-512BW paths compiled with target attributes. ActiveKernels() says which set runs: the
// best this CPU and build have, or the one named by the environment variable
//
//   OCCMAP_KERNELS=portable|avx2|avx512|best
//
// (read once; a set the CPU lacks falls back to the best below it, with a line on stderr; a
// value not in the list is an error, exit 2). Builds with OCCMAP_NO_X86_KERNELS (the
// `portable` preset) and non-x86 builds have only the portable set.
//
//   if (ActiveKernels() >= KernelSet::kAvx2) return RowAvx2(...);   // inside #if OCCMAP_X86_KERNELS
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "occmap/util/status.h"

#if (defined(__x86_64__) || defined(__i386__)) && !defined(OCCMAP_NO_X86_KERNELS)
#define OCCMAP_X86_KERNELS 1
#else
#define OCCMAP_X86_KERNELS 0
#endif

namespace occmap {

// Ordered: a set includes what the sets below it need (kAvx2: AVX2, BMI1, BMI2, POPCNT;
// kAvx512: those and AVX-512F, AVX-512BW).
enum class KernelSet { kPortable = 0, kAvx2 = 1, kAvx512 = 2 };

// The set every fast kernel uses now (cheap: one atomic load after the first call).
KernelSet ActiveKernels();
// "portable", "avx2", "avx512".
const char* KernelSetName(KernelSet set);
// "portable", "avx2", "avx512" (or "avx512bw"); nullopt otherwise ("best" included).
std::optional<KernelSet> ParseKernelSet(std::string_view name);
// The best set this build and CPU support.
KernelSet BestKernels();
// True when this build has the set's code and the CPU its instructions.
bool KernelsSupported(KernelSet set);
// The set for an OCCMAP_KERNELS value (empty = best): a set the CPU lacks gives the best
// below it and a line for stderr in `note`; an unknown value is an InvalidInput error.
Result<KernelSet> KernelsForSetting(std::string_view value, std::string* note);
// Tests and benchmarks: selects a set ("portable", "avx2", "avx512", or "best") for the whole
// process; false (nothing changed) when unsupported or unknown. Call with no kernel running.
bool ForceKernelsForTesting(std::string_view name);

// A spin-wait hint: x86 PAUSE, Arm YIELD, nothing elsewhere.
inline void CpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__) || defined(__arm__)
  asm volatile("yield" ::: "memory");
#endif
}

}  // namespace occmap
