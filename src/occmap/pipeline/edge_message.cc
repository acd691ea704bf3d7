#include "occmap/pipeline/edge_message.h"

#include <fmt/core.h>
#include <zstd.h>

#include <cmath>
#include <cstring>

#include "occmap/lut/ground_lut.h"
#include "occmap/util/hash.h"

namespace occmap {
namespace {

constexpr char kMagic[4] = {'O', 'C', 'M', 'E'};
constexpr size_t kHeaderBytes = 4 + 2 + 2 + 8 + 8 + 4 + 4 + 4 + 8 + 8 + 8 + 8 + 4 + 4;
// Change masks compress well at the fastest level; higher ones cost the edge CPU for little.
constexpr int kZstdLevel = 1;

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

}  // namespace

uint64_t EdgeTableKey(const Site& site) { return GroundLutKey(site.LutInputs(), site.grid, site.lut); }

uint64_t EdgeSettingsKey(const Site& site) {
  Hasher h;
  h.Add(std::string_view("edge-settings-v1"));
  h.AddPod(static_cast<int64_t>(site.detection.threshold));
  h.AddPod(static_cast<int64_t>(site.detection.tolerance_px));
  h.AddPod(static_cast<uint8_t>(site.detection.colour));
  h.AddPod(static_cast<uint8_t>(site.backgrounds.adaptive));
  for (const SiteCamera& c : site.cameras) h.Add(c.id);
  return h.Digest();
}

std::string EncodeEdgeMessage(const EdgeMessage& m) {
  const size_t pixels = static_cast<size_t>(m.width) * m.height;
  std::string packed;
  if (m.kind == EdgeMessageKind::kChanges) {
    packed.assign((pixels + 7) / 8, '\0');
    for (size_t k = 0; k < pixels && k < m.changes.size(); ++k) {
      if (m.changes[k] != 0) packed[k / 8] = static_cast<char>(packed[k / 8] | (1 << (k % 8)));
    }
  }
  std::string payload(packed.empty() ? 0 : ZSTD_compressBound(packed.size()), '\0');
  if (!packed.empty()) {
    const size_t n = ZSTD_compress(payload.data(), payload.size(), packed.data(), packed.size(), kZstdLevel);
    payload.resize(ZSTD_isError(n) ? 0 : n);
  }
  std::string out;
  out.reserve(kHeaderBytes + payload.size());
  out.append(kMagic, 4);
  Put<uint16_t>(out, kEdgeSchemaVersion);
  Put<uint16_t>(out, static_cast<uint16_t>(m.kind));
  Put<uint64_t>(out, m.table_key);
  Put<uint64_t>(out, m.settings_key);
  Put<uint32_t>(out, m.camera);
  Put<uint32_t>(out, m.width);
  Put<uint32_t>(out, m.height);
  Put<int64_t>(out, m.frame);
  Put<double>(out, m.timestamp_s);
  Put<double>(out, m.t_unix);
  Put<double>(out, m.fps);
  Put<uint32_t>(out, static_cast<uint32_t>(packed.size()));
  Put<uint32_t>(out, static_cast<uint32_t>(payload.size()));
  out += payload;
  return out;
}

Result<EdgeMessage> DecodeEdgeMessage(std::string_view bytes, const EdgeExpectation& expect, std::string_view source) {
  auto bad = [&](const std::string& what) { return InvalidInput(fmt::format("{}: edge message: {}", source, what)); };
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kMagic, 4) != 0) {
    return bad(fmt::format("expected an occmap edge message (\"OCME\"), found {} bytes of something else", bytes.size()));
  }
  size_t at = 4;
  const uint16_t version = Get<uint16_t>(bytes, at);
  if (version != kEdgeSchemaVersion) {
    return bad(fmt::format("schema version {}, this occmap reads version {}: run edge and fuse of the same release",
                           version, kEdgeSchemaVersion));
  }
  if (bytes.size() < kHeaderBytes) {
    return bad(fmt::format("header: expected {} bytes, found {}", kHeaderBytes, bytes.size()));
  }
  EdgeMessage m;
  const uint16_t kind = Get<uint16_t>(bytes, at);
  if (kind > 1) return bad(fmt::format("kind: expected 0 (changes) or 1 (end), found {}", kind));
  m.kind = static_cast<EdgeMessageKind>(kind);
  m.table_key = Get<uint64_t>(bytes, at);
  m.settings_key = Get<uint64_t>(bytes, at);
  if (m.table_key != expect.table_key) {
    return bad(fmt::format("built for other tables (table key {:016x}, this site's {:016x}): the edge's site file "
                           "has other cameras, calibrations, masks or grid",
                           m.table_key, expect.table_key));
  }
  if (m.settings_key != expect.settings_key) {
    return bad(fmt::format("made with other detection settings (key {:016x}, this site's {:016x}): the edge's site "
                           "file has another threshold, tolerance, colour, backgrounds or camera ids",
                           m.settings_key, expect.settings_key));
  }
  m.camera = Get<uint32_t>(bytes, at);
  m.width = Get<uint32_t>(bytes, at);
  m.height = Get<uint32_t>(bytes, at);
  m.frame = Get<int64_t>(bytes, at);
  m.timestamp_s = Get<double>(bytes, at);
  m.t_unix = Get<double>(bytes, at);
  m.fps = Get<double>(bytes, at);
  const uint32_t raw_bytes = Get<uint32_t>(bytes, at);
  const uint32_t payload_bytes = Get<uint32_t>(bytes, at);
  if (m.camera >= expect.camera_sizes.size()) {
    return bad(fmt::format("camera: expected 0..{}, found {}", expect.camera_sizes.size() - 1, m.camera));
  }
  const ImageSize size = expect.camera_sizes[m.camera];
  if (m.kind == EdgeMessageKind::kEnd) return m;
  if (static_cast<int>(m.width) != size.width || static_cast<int>(m.height) != size.height) {
    return bad(fmt::format("camera {}: expected a {}x{} image, found {}x{}", m.camera, size.width, size.height, m.width,
                           m.height));
  }
  if (m.frame < 0) return bad(fmt::format("frame: expected >= 0, found {}", m.frame));
  const size_t pixels = static_cast<size_t>(m.width) * m.height;
  if (raw_bytes != (pixels + 7) / 8) {
    return bad(fmt::format("raw bytes: expected {} for {} pixels, found {}", (pixels + 7) / 8, pixels, raw_bytes));
  }
  if (bytes.size() - at != payload_bytes) {
    return bad(fmt::format("payload: expected {} bytes, found {}", payload_bytes, bytes.size() - at));
  }
  std::string packed(raw_bytes, '\0');
  const size_t n = ZSTD_decompress(packed.data(), packed.size(), bytes.data() + at, payload_bytes);
  if (ZSTD_isError(n) || n != raw_bytes) {
    return bad(fmt::format("payload: expected a zstd frame of {} bytes, found {}", raw_bytes,
                           ZSTD_isError(n) ? std::string(ZSTD_getErrorName(n)) : fmt::format("{} bytes", n)));
  }
  m.changes.resize(pixels);
  for (size_t k = 0; k < pixels; ++k) m.changes[k] = static_cast<uint8_t>((packed[k / 8] >> (k % 8)) & 1);
  return m;
}

}  // namespace occmap
