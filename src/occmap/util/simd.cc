#include "occmap/util/simd.h"

#include <fmt/core.h>

#include <atomic>
#include <cstdlib>
#include <string>

namespace occmap {
namespace {

bool CpuHas(KernelSet set) {
  if (set == KernelSet::kPortable) return true;
#if OCCMAP_X86_KERNELS
  __builtin_cpu_init();
  const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("bmi") &&
                    __builtin_cpu_supports("bmi2") && __builtin_cpu_supports("popcnt");
  if (set == KernelSet::kAvx2) return avx2;
  return avx2 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw");
#else
  return false;
#endif
}

// The environment's choice; a bad value ends the process as bad input does (exit 2).
KernelSet FromEnvironment() {
  const char* env = std::getenv("OCCMAP_KERNELS");
  std::string note;
  Result<KernelSet> set = KernelsForSetting(env == nullptr ? "" : env, &note);
  if (!set.ok()) {
    fmt::print(stderr, "{}\n", set.status().message());
    std::exit(2);
  }
  if (!note.empty()) fmt::print(stderr, "{}\n", note);
  return set.value();
}

std::atomic<int>& Active() {
  static std::atomic<int> active{static_cast<int>(FromEnvironment())};
  return active;
}

}  // namespace

KernelSet ActiveKernels() { return static_cast<KernelSet>(Active().load(std::memory_order_relaxed)); }

const char* KernelSetName(KernelSet set) {
  switch (set) {
    case KernelSet::kAvx2:
      return "avx2";
    case KernelSet::kAvx512:
      return "avx512";
    case KernelSet::kPortable:
      break;
  }
  return "portable";
}

std::optional<KernelSet> ParseKernelSet(std::string_view name) {
  if (name == "portable") return KernelSet::kPortable;
  if (name == "avx2") return KernelSet::kAvx2;
  if (name == "avx512" || name == "avx512bw") return KernelSet::kAvx512;
  return std::nullopt;
}

bool KernelsSupported(KernelSet set) {
  static const bool has[3] = {true, CpuHas(KernelSet::kAvx2), CpuHas(KernelSet::kAvx512)};
  return has[static_cast<int>(set)];
}

KernelSet BestKernels() {
  if (KernelsSupported(KernelSet::kAvx512)) return KernelSet::kAvx512;
  if (KernelsSupported(KernelSet::kAvx2)) return KernelSet::kAvx2;
  return KernelSet::kPortable;
}

Result<KernelSet> KernelsForSetting(std::string_view value, std::string* note) {
  if (value.empty() || value == "best") return BestKernels();
  const std::optional<KernelSet> asked = ParseKernelSet(value);
  if (!asked) {
    return InvalidInput(fmt::format("OCCMAP_KERNELS: expected portable, avx2, avx512 or best, found '{}'", value));
  }
  KernelSet set = *asked;
  while (!KernelsSupported(set)) set = static_cast<KernelSet>(static_cast<int>(set) - 1);
  if (set != *asked && note != nullptr) {
    *note = fmt::format("OCCMAP_KERNELS={}: not supported by this {}, using {}", value,
                        OCCMAP_X86_KERNELS ? "CPU" : "build", KernelSetName(set));
  }
  return set;
}

bool ForceKernelsForTesting(std::string_view name) {
  const std::optional<KernelSet> set = name == "best" ? std::optional(BestKernels()) : ParseKernelSet(name);
  if (!set || !KernelsSupported(*set)) return false;
  Active().store(static_cast<int>(*set), std::memory_order_relaxed);
  return true;
}

}  // namespace occmap
