// Hasher: a fast, deterministic 64-bit hash for cache keys and payload checksums.
//
// Not cryptographic. Deterministic across runs and machines (little-endian assumed and checked
// at compile time: x86-64 and aarch64 agree), so a key computed today matches the one stored
// in a file tomorrow, on another board.
//
//   Hasher h;
//   h.Add(std::string_view("lut-v1"));
//   h.AddPod(cell_size_m);
//   uint64_t key = h.Digest();
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <type_traits>

namespace occmap {

static_assert(std::endian::native == std::endian::little, "occmap assumes little-endian");

class Hasher {
 public:
  explicit Hasher(uint64_t seed = 0x6f63636d61703031ULL) : state_(seed) {}

  void AddBytes(const void* data, size_t size);
  void Add(std::string_view text) {
    AddPod(static_cast<uint64_t>(text.size()));
    AddBytes(text.data(), text.size());
  }
  template <typename T>
  void AddPod(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    AddBytes(&value, sizeof(T));
  }
  uint64_t Digest() const;

 private:
  uint64_t state_;
  uint64_t length_ = 0;
};

// One-shot hash of a byte span.
uint64_t HashBytes(std::span<const std::byte> bytes, uint64_t seed = 0);

}  // namespace occmap
