#include "occmap/pipeline/protection_message.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "occmap/detect/background_model.h"
#include "occmap/pipeline/wire_bytes.h"

namespace occmap {
namespace {

constexpr char kMagic[4] = {'O', 'C', 'M', 'P'};
constexpr size_t kHeaderBytes = 4 + 2 + 2 + 8 + 8 + 8 + 8 + 8 + 4 + 4 + 4;
constexpr size_t kBoxBytes = 8 + 8 + 8 + 1;
constexpr size_t kPersonBytes = 8 + 8;
constexpr size_t kMostRunBytes = 5 + 5;  // two varints

using wire::Get;
using wire::Put;

// LEB128: 7 bits a byte, least significant first, the high bit set on every byte but the last.
void PutVarint(std::string& out, uint32_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<char>((v & 0x7f) | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<char>(v));
}

// false: the bytes end inside it, or it does not fit 32 bits.
bool GetVarint(std::string_view bytes, size_t& at, uint32_t& v) {
  uint64_t value = 0;
  for (int shift = 0; shift < 35; shift += 7) {
    if (at >= bytes.size()) return false;
    const auto b = static_cast<uint8_t>(bytes[at++]);
    value |= static_cast<uint64_t>(b & 0x7f) << shift;
    if ((b & 0x80) == 0) {
      if (value > UINT32_MAX) return false;
      v = static_cast<uint32_t>(value);
      return true;
    }
  }
  return false;
}

}  // namespace

std::string EncodeProtectionMessage(const ProtectionMessage& m) {
  std::string out;
  out.reserve(kHeaderBytes + m.boxes.size() * kBoxBytes + m.persons_m.size() * kPersonBytes +
              m.occupied.size() * kMostRunBytes);
  out.append(kMagic, 4);
  Put<uint16_t>(out, kProtectionSchemaVersion);
  Put<uint16_t>(out, 0);
  Put<uint64_t>(out, m.table_key);
  Put<uint64_t>(out, m.settings_key);
  Put<int64_t>(out, m.frame);
  Put<double>(out, m.timestamp_s);
  Put<double>(out, m.t_unix);
  Put<uint32_t>(out, static_cast<uint32_t>(m.boxes.size()));
  Put<uint32_t>(out, static_cast<uint32_t>(m.persons_m.size()));
  Put<uint32_t>(out, static_cast<uint32_t>(m.occupied.size()));
  for (const ProtectedBox& b : m.boxes) {
    Put<double>(out, b.x_m);
    Put<double>(out, b.y_m);
    Put<double>(out, b.radius_m);
    Put<uint8_t>(out, b.value);
  }
  for (const Eigen::Vector2d& p : m.persons_m) {
    Put<double>(out, p.x());
    Put<double>(out, p.y());
  }
  uint32_t end = 0;  // of the previous run
  for (const auto& [first, cells] : m.occupied) {
    OCCMAP_CHECK(first >= end && cells > 0, "protection message: occupied runs out of order");
    PutVarint(out, first - end);
    PutVarint(out, cells);
    end = first + cells;
  }
  return out;
}

Result<ProtectionMessage> DecodeProtectionMessage(std::string_view bytes, const ProtectionExpectation& expect,
                                                  std::string_view source) {
  auto bad = [&](const std::string& what) {
    return InvalidInput(fmt::format("{}: protection message: {}", source, what));
  };
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kMagic, 4) != 0) {
    return bad(fmt::format("expected an occmap protection message (\"OCMP\"), found {} bytes of something else",
                           bytes.size()));
  }
  size_t at = 4;
  const uint16_t version = Get<uint16_t>(bytes, at);
  if (version != kProtectionSchemaVersion) {
    return bad(fmt::format("schema version {}, this occmap reads version {}: run edge and fuse of the same release",
                           version, kProtectionSchemaVersion));
  }
  if (bytes.size() < kHeaderBytes) return bad(fmt::format("header: expected {} bytes, found {}", kHeaderBytes, bytes.size()));
  (void)Get<uint16_t>(bytes, at);
  ProtectionMessage m;
  m.table_key = Get<uint64_t>(bytes, at);
  m.settings_key = Get<uint64_t>(bytes, at);
  if (std::string keys = wire::KeysMismatch(m.table_key, m.settings_key, expect.table_key, expect.settings_key, "fuse");
      !keys.empty()) {
    return bad(keys);
  }
  m.frame = Get<int64_t>(bytes, at);
  m.timestamp_s = Get<double>(bytes, at);
  m.t_unix = Get<double>(bytes, at);
  const uint32_t n_boxes = Get<uint32_t>(bytes, at);
  const uint32_t n_persons = Get<uint32_t>(bytes, at);
  const uint32_t n_runs = Get<uint32_t>(bytes, at);
  if (m.frame < 0) return bad(fmt::format("frame: expected >= 0, found {}", m.frame));
  const size_t fixed = kHeaderBytes + static_cast<size_t>(n_boxes) * kBoxBytes + static_cast<size_t>(n_persons) * kPersonBytes;
  if (bytes.size() < fixed + 2 * static_cast<size_t>(n_runs)) {
    return bad(fmt::format("length: expected at least {} bytes for {} boxes, {} persons and {} runs, found {}",
                           fixed + 2 * static_cast<size_t>(n_runs), n_boxes, n_persons, n_runs, bytes.size()));
  }
  m.boxes.resize(n_boxes);
  for (uint32_t k = 0; k < n_boxes; ++k) {
    ProtectedBox& b = m.boxes[k];
    b.x_m = Get<double>(bytes, at);
    b.y_m = Get<double>(bytes, at);
    b.radius_m = Get<double>(bytes, at);
    b.value = Get<uint8_t>(bytes, at);
    if (!std::isfinite(b.x_m) || !std::isfinite(b.y_m)) {
      return bad(fmt::format("boxes[{}].position: expected finite metres, found ({}, {})", k, b.x_m, b.y_m));
    }
    if (!std::isfinite(b.radius_m) || b.radius_m < 0) {
      return bad(fmt::format("boxes[{}].radius_m: expected a finite radius >= 0, found {}", k, b.radius_m));
    }
    if (b.value != BackgroundModel::kObject && b.value != BackgroundModel::kPerson &&
        b.value != BackgroundModel::kWalkedPerson) {
      return bad(fmt::format("boxes[{}].value: expected 1 (object), 2 (person) or 3 (walked person), found {}", k,
                             b.value));
    }
  }
  m.persons_m.resize(n_persons);
  for (uint32_t k = 0; k < n_persons; ++k) {
    const double x = Get<double>(bytes, at), y = Get<double>(bytes, at);
    if (!std::isfinite(x) || !std::isfinite(y)) {
      return bad(fmt::format("persons[{}]: expected finite metres, found ({}, {})", k, x, y));
    }
    m.persons_m[k] = {x, y};
  }
  m.occupied.resize(n_runs);
  int64_t end = 0;  // of the previous run
  for (uint32_t k = 0; k < n_runs; ++k) {
    uint32_t gap = 0, cells = 0;
    if (!GetVarint(bytes, at, gap) || !GetVarint(bytes, at, cells)) {
      return bad(fmt::format("occupied[{}]: expected two varints (gap, cells), found the message's end or more than "
                             "32 bits",
                             k));
    }
    const int64_t first = end + gap;
    if (cells == 0 || first + cells > expect.num_cells) {
      return bad(fmt::format("occupied[{}]: expected cells {}..{}, found {} cells from {}", k, end,
                             expect.num_cells - 1, cells, first));
    }
    m.occupied[k] = {static_cast<uint32_t>(first), cells};
    end = first + cells;
  }
  if (at != bytes.size()) {
    return bad(fmt::format("length: expected {} bytes for {} boxes, {} persons and {} runs, found {}", at, n_boxes,
                           n_persons, n_runs, bytes.size()));
  }
  return m;
}

std::vector<std::pair<uint32_t, uint32_t>> OccupiedRuns(const OccupancyMap& map) {
  std::vector<std::pair<uint32_t, uint32_t>> runs;
  const std::vector<CellState>& s = map.states();
  for (size_t c = 0; c < s.size();) {
    if (s[c] != CellState::kOccupied) {
      ++c;
      continue;
    }
    const size_t first = c;
    while (c < s.size() && s[c] == CellState::kOccupied) ++c;
    runs.emplace_back(static_cast<uint32_t>(first), static_cast<uint32_t>(c - first));
  }
  return runs;
}

void MarkOccupied(const std::vector<std::pair<uint32_t, uint32_t>>& runs, OccupancyMap& map) {
  std::vector<CellState>& s = map.states();
  for (const auto& [first, cells] : runs) {
    OCCMAP_CHECK(static_cast<size_t>(first) + cells <= s.size(), "occupied runs: outside the map");
    std::fill_n(s.begin() + first, cells, CellState::kOccupied);
  }
}

}  // namespace occmap
