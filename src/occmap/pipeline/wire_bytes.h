// Little-endian fields of the binary messages between `occmap edge` and `occmap fuse`
// (edge_message.h, protection_message.h), and the check of the site keys they all carry.
// Get reads unchecked: the caller has checked the length first.
//
//   Put<uint32_t>(out, n);            const auto n = Get<uint32_t>(bytes, at);
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace occmap::wire {

template <typename T>
void Put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

template <typename T>
T Get(std::string_view bytes, size_t& at) {
  T v;
  std::memcpy(&v, bytes.data() + at, sizeof(T));
  at += sizeof(T);
  return v;
}

// Empty when a message's keys are this site's; else what differs, in words, with `sender`
// ("edge", "fuse") the process whose site file differs.
std::string KeysMismatch(uint64_t table_key, uint64_t settings_key, uint64_t expected_table_key,
                         uint64_t expected_settings_key, std::string_view sender);

}  // namespace occmap::wire
