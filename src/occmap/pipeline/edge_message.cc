#include "occmap/pipeline/edge_message.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "occmap/lut/ground_lut.h"
#include "occmap/pipeline/wire_bytes.h"
#include "occmap/util/hash.h"

namespace occmap {
namespace {

constexpr char kMagic[4] = {'O', 'C', 'M', 'E'};
constexpr size_t kHeaderBytes = 4 + 2 + 2 + 8 + 8 + 4 + 4 + 4 + 8 + 8 + 8 + 8 + 4 + 4 + 2;
constexpr size_t kModesAt = kHeaderBytes - 10, kBlockAt = kHeaderBytes - 2;
// The trailer: HashBytes of every byte before it. A broker, a bridge or a disk in between that
// damages a message (or a publisher of junk) is caught on arrival, before the message can take
// a frame set's place (issue 39); a range decode on arrival would double the fuse's decoding.
constexpr size_t kChecksumBytes = 8;

uint64_t Checksum(std::string_view bytes) { return HashBytes(std::as_bytes(std::span(bytes.data(), bytes.size()))); }

using wire::Get;
using wire::Put;

// The rows are coded as fax machines do (ITU-T T.6, "modified READ"): each row's changing
// elements (where a pixel differs from its left neighbour) relative to the row above's, as
// modes: vertical (a change within 3 pixels of the one above), pass (the row above's run ends
// here), horizontal (two run lengths). A silhouette's edges move by a pixel or so per row, so
// most modes are "vertical 0"; a range coder then codes the modes and the run lengths in
// context (below). Per camera-frame, whole messages (76 bytes of header included), measured by
// scripts/bench-edge-fuse.sh on this machine (2026-12-04): WILDTRACK at 960x540 1370 bytes with
// zstd (level 1) of the modes as bytes, 1198 range-coded; lab 640x480 488 -> 392. Tried on the
// WILDTRACK masks: the row's previous mode as a further context 1200 (no gain), slower
// adaptation (1/32) 1216. On 1080p: zstd of the bits 6.8 kB, T.6 + zstd 3.3 kB, JBIG 2.9 kB.
enum Mode : uint8_t { kV0 = 0, kVR1, kVR2, kVR3, kVL1, kVL2, kVL3, kPass, kHorizontal, kModes };
constexpr int kMaxVertical = 3;

// changes: the row's changing elements, then `width` twice (the row's end).
void ChangingElements(const uint8_t* row, int width, std::vector<int>& changes) {
  changes.clear();
  int x = 0;
  bool on = false;
  while (x < width) {
    // Skip whole words of one colour (most of a mask).
    if (!on) {
      while (x + 8 <= width) {
        uint64_t w;
        std::memcpy(&w, row + x, 8);
        if (w != 0) break;
        x += 8;
      }
      while (x < width && row[x] == 0) ++x;
    } else {
      while (x < width && row[x] != 0) ++x;
    }
    if (x < width) {
      changes.push_back(x);
      on = !on;
    }
  }
  changes.push_back(width);
  changes.push_back(width);
}

// b1: the row above's first changing element right of a0 whose colour is not `colour` (element
// k turns the row on for even k); ib is kept between calls and moved back when a0 went left of it.
int FindB1(const std::vector<int>& ref, size_t& ib, int a0, int colour, int width) {
  while (ib > 0 && ref[ib - 1] > a0) --ib;
  while (ref[ib] < width && (ref[ib] <= a0 || static_cast<int>(ib % 2 == 0) == colour)) ++ib;
  return ref[ib];
}

// An adaptive binary range coder (LZMA's): each decision is coded with a probability learned
// from the decisions of its context so far (11-bit, adapting by 1/16 of the error).
constexpr int kProbBits = 11;
constexpr uint16_t kProbHalf = 1 << (kProbBits - 1);
constexpr int kAdapt = 4;

class RangeEncoder {
 public:
  void Encode(uint16_t& p, int bit) {
    const uint32_t bound = (range_ >> kProbBits) * p;
    if (bit == 0) {
      range_ = bound;
      p = static_cast<uint16_t>(p + (((1 << kProbBits) - p) >> kAdapt));
    } else {
      low_ += bound;
      range_ -= bound;
      p = static_cast<uint16_t>(p - (p >> kAdapt));
    }
    while (range_ < (1u << 24)) {
      range_ <<= 8;
      ShiftLow();
    }
  }
  std::string Finish() {
    for (int k = 0; k < 5; ++k) ShiftLow();
    return std::move(out_);
  }

 private:
  void ShiftLow() {
    if (static_cast<uint32_t>(low_) < 0xFF000000u || (low_ >> 32) != 0) {
      const auto carry = static_cast<uint8_t>(low_ >> 32);
      uint8_t byte = cache_;
      do {
        out_ += static_cast<char>(static_cast<uint8_t>(byte + carry));
        byte = 0xFF;
      } while (--pending_ != 0);
      cache_ = static_cast<uint8_t>(low_ >> 24);
    }
    ++pending_;
    low_ = (low_ & 0x00FFFFFFu) << 8;
  }
  uint64_t low_ = 0;
  uint32_t range_ = 0xFFFFFFFFu;
  uint8_t cache_ = 0;
  uint64_t pending_ = 1;
  std::string out_;
};

class RangeDecoder {
 public:
  explicit RangeDecoder(std::string_view in) : in_(in) {
    for (int k = 0; k < 5; ++k) code_ = (code_ << 8) | Next();
  }
  int Decode(uint16_t& p) {
    const uint32_t bound = (range_ >> kProbBits) * p;
    int bit;
    if (code_ < bound) {
      range_ = bound;
      p = static_cast<uint16_t>(p + (((1 << kProbBits) - p) >> kAdapt));
      bit = 0;
    } else {
      code_ -= bound;
      range_ -= bound;
      p = static_cast<uint16_t>(p - (p >> kAdapt));
      bit = 1;
    }
    while (range_ < (1u << 24)) {
      range_ <<= 8;
      code_ = (code_ << 8) | Next();
    }
    return bit;
  }
  // Bytes read past the end (read as 0): a valid stream reads none.
  size_t overrun() const { return overrun_; }
  size_t left() const { return at_ < in_.size() ? in_.size() - at_ : 0; }

 private:
  uint32_t Next() {
    if (at_ < in_.size()) return static_cast<uint8_t>(in_[at_++]);
    ++overrun_;
    return 0;
  }
  std::string_view in_;
  size_t at_ = 0, overrun_ = 0;
  uint32_t code_ = 0, range_ = 0xFFFFFFFFu;
};

// The contexts. A mode is coded as "vertical 0 or not", then, if not, its index among the other
// eight in three binary decisions; both in the context of the colour and of the mode that made
// b1 in the row above (an edge that went straight down or slanted one way goes on so: the
// mode's own "slope" is predicted by the one above). A horizontal mode's run lengths r are
// coded as r + 1 in Elias gamma: the number of bits after the leading one in unary, then those
// bits, the first two in context.
constexpr int kOrigins = kModes + 1;  // b1 made by mode m; kModes: no b1 (the row's end) or the first row
constexpr int kMaxRunBits = 24;
struct Contexts {
  uint16_t v0[2][kOrigins];
  uint16_t other[2][kOrigins][8];
  uint16_t run_bits[2][2][kMaxRunBits + 1];
  uint16_t run_top[2][2][kMaxRunBits][4];
  uint16_t run_low = kProbHalf;
  Contexts() {
    std::fill_n(&v0[0][0], sizeof(v0) / 2, kProbHalf);
    std::fill_n(&other[0][0][0], sizeof(other) / 2, kProbHalf);
    std::fill_n(&run_bits[0][0][0], sizeof(run_bits) / 2, kProbHalf);
    std::fill_n(&run_top[0][0][0][0], sizeof(run_top) / 2, kProbHalf);
  }
};

template <typename Coder, typename Bit>
void CodeMode(Contexts& c, int colour, int origin, int& mode, Coder& coder, Bit bit) {
  const int is_other = bit(coder, c.v0[colour][origin], mode != kV0);
  if (!is_other) {
    mode = kV0;
    return;
  }
  const int m = mode - 1;  // 0..7 for the eight other modes
  int node = 1;
  for (int k = 2; k >= 0; --k) node = node * 2 + bit(coder, c.other[colour][origin][node - 1 < 8 ? node - 1 : 0], (m >> k) & 1);
  mode = node - 8 + 1;
}

template <typename Coder, typename Bit>
void CodeRun(Contexts& c, int which, int colour, uint32_t& run, Coder& coder, Bit bit) {
  const uint32_t v = run + 1;
  int n = 0;
  while (n < kMaxRunBits && (v >> (n + 1)) != 0) ++n;
  int bits = 0;
  while (bits < kMaxRunBits && bit(coder, c.run_bits[which][colour][bits], bits < n)) ++bits;
  uint32_t value = 1;
  for (int k = bits - 1; k >= 0; --k) {
    const int top = bits - 1 - k;  // 0 for the bit after the leading one
    uint16_t& p = top < 2 ? c.run_top[which][colour][bits - 1][top * 2 + (top == 1 ? value & 1 : 0)] : c.run_low;
    value = value * 2 + static_cast<uint32_t>(bit(coder, p, (v >> k) & 1));
  }
  run = value - 1;
}

int EncodeBit(RangeEncoder& e, uint16_t& p, int bit) {
  e.Encode(p, bit);
  return bit;
}
int DecodeBit(RangeDecoder& d, uint16_t& p, int /*bit*/) { return d.Decode(p); }

// The coded rows: the T.6 modes of every row, range-coded; returns the number of modes.
std::string CodeRows(const uint8_t* pixels, int width, int height, uint32_t& n_modes) {
  auto contexts = std::make_unique<Contexts>();
  RangeEncoder coder;
  n_modes = 0;
  std::vector<int> ref{width, width}, cur;
  // The mode that made each of the row above's changing elements (kModes: none).
  std::vector<uint8_t> ref_origin{kModes, kModes}, cur_origin;
  for (int y = 0; y < height; ++y) {
    ChangingElements(pixels + static_cast<size_t>(y) * width, width, cur);
    cur_origin.assign(cur.size(), kModes);
    int a0 = -1, colour = 0;
    size_t ia = 0, ib = 0;
    while (a0 < width) {
      while (cur[ia] <= a0) ++ia;
      const int a1 = cur[ia];
      const int b1 = FindB1(ref, ib, a0, colour, width);
      const int b2 = b1 < width ? ref[ib + 1] : width;
      const int origin = b1 < width ? static_cast<int>(ref_origin[ib]) : static_cast<int>(kModes);
      int mode;
      const int d = a1 - b1;
      if (b2 < a1) {
        mode = kPass;
      } else if (d >= -kMaxVertical && d <= kMaxVertical) {
        mode = d >= 0 ? kV0 + d : kVR3 - d;
      } else {
        mode = kHorizontal;
      }
      CodeMode(*contexts, colour, origin, mode, coder, EncodeBit);
      ++n_modes;
      if (mode == kPass) {
        a0 = b2;
      } else if (mode == kHorizontal) {
        const int a2 = a1 < width ? cur[ia + 1] : width;
        uint32_t r1 = static_cast<uint32_t>(a1 - std::max(a0, 0)), r2 = static_cast<uint32_t>(a2 - a1);
        CodeRun(*contexts, 0, colour, r1, coder, EncodeBit);
        CodeRun(*contexts, 1, colour, r2, coder, EncodeBit);
        if (a1 < width) cur_origin[ia] = kHorizontal;
        if (a2 < width) cur_origin[ia + 1] = kHorizontal;
        a0 = a2;
      } else {
        if (a1 < width) cur_origin[ia] = static_cast<uint8_t>(mode);
        a0 = a1;
        colour ^= 1;
      }
    }
    std::swap(ref, cur);
    std::swap(ref_origin, cur_origin);
  }
  return coder.Finish();
}

// The inverse of CodeRows into pixels (width * height, 0 or 1); an error names what is broken.
Status DecodeRows(std::string_view coded, uint32_t n_modes, int width, int height, uint8_t* pixels) {
  auto broken = [](const std::string& what) { return InvalidInput("coded rows: " + what); };
  auto contexts = std::make_unique<Contexts>();
  RangeDecoder coder(coded);
  uint32_t modes = 0;
  std::vector<int> ref{width, width}, cur;
  std::vector<uint8_t> ref_origin{kModes, kModes}, cur_origin;
  for (int y = 0; y < height; ++y) {
    cur.clear();
    cur_origin.clear();
    int a0 = -1, colour = 0;
    size_t ib = 0;
    while (a0 < width) {
      if (modes++ >= n_modes) return broken(fmt::format("row {}: more than the {} modes stated", y, n_modes));
      if (coder.overrun() > 4) return broken(fmt::format("row {}: expected more bytes, found the end", y));
      const int b1 = FindB1(ref, ib, a0, colour, width);
      const int b2 = b1 < width ? ref[ib + 1] : width;
      const int origin = b1 < width ? static_cast<int>(ref_origin[ib]) : static_cast<int>(kModes);
      int m = kV0;
      CodeMode(*contexts, colour, origin, m, coder, DecodeBit);
      if (m == kPass) {
        if (b2 >= width) return broken(fmt::format("row {}: a pass with nothing to pass", y));
        a0 = b2;
      } else if (m == kHorizontal) {
        uint32_t r1 = 0, r2 = 0;
        CodeRun(*contexts, 0, colour, r1, coder, DecodeBit);
        CodeRun(*contexts, 1, colour, r2, coder, DecodeBit);
        const int64_t a1 = std::max(a0, 0) + static_cast<int64_t>(r1), a2 = a1 + r2;
        if (a1 > width || a2 > width || a1 <= a0 || (a1 < width && a2 <= a1)) {
          return broken(fmt::format("row {}: run lengths: expected changes in ({}, {}], found others", y, a0, width));
        }
        if (a1 < width) {
          cur.push_back(static_cast<int>(a1));
          cur_origin.push_back(kHorizontal);
        }
        if (a2 < width) {
          cur.push_back(static_cast<int>(a2));
          cur_origin.push_back(kHorizontal);
        }
        a0 = static_cast<int>(a2);
      } else if (m < kModes) {
        const int a1 = b1 + (m <= kVR3 ? m - kV0 : kVR3 - m);
        if (a1 <= a0 || a1 > width) {
          return broken(fmt::format("row {}: a change at {}: expected one in ({}, {}]", y, a1, a0, width));
        }
        if (a1 < width) {
          cur.push_back(a1);
          cur_origin.push_back(static_cast<uint8_t>(m));
        }
        a0 = a1;
        colour ^= 1;
      } else {
        return broken(fmt::format("row {}: mode {}: expected 0..{}", y, m, kModes - 1));
      }
    }
    uint8_t* row = pixels + static_cast<size_t>(y) * width;
    int x = 0;
    uint8_t value = 0;
    for (const int c : cur) {
      std::memset(row + x, value, static_cast<size_t>(c - x));
      x = c;
      value ^= 1;
    }
    std::memset(row + x, value, static_cast<size_t>(width - x));
    cur.push_back(width);
    cur.push_back(width);
    cur_origin.push_back(kModes);
    cur_origin.push_back(kModes);
    std::swap(ref, cur);
    std::swap(ref_origin, cur_origin);
  }
  if (modes != n_modes || coder.overrun() > 4 || coder.left() > 0) {
    return broken(fmt::format("{} of {} modes decoded, {} bytes left over, {} missing", modes, n_modes, coder.left(),
                              coder.overrun()));
  }
  return Status::Ok();
}

// The coded image's width or height: one pixel per block (those at the edges clipped).
int Blocks(uint32_t pixels, int block_px) { return static_cast<int>((pixels + block_px - 1) / block_px); }
bool ValidBlock(int w, int h) { return w >= 1 && w <= 2 && h >= 1 && h <= 2; }

}  // namespace

std::string wire::KeysMismatch(uint64_t table_key, uint64_t settings_key, uint64_t expected_table_key,
                               uint64_t expected_settings_key, std::string_view sender) {
  if (table_key != expected_table_key) {
    return fmt::format("built for other tables (table key {:016x}, this site's {:016x}): the {}'s site file has other "
                       "cameras, calibrations, masks or grid",
                       table_key, expected_table_key, sender);
  }
  if (settings_key != expected_settings_key) {
    return fmt::format("made with other detection settings (key {:016x}, this site's {:016x}): the {}'s site file has "
                       "another threshold, tolerance, block, colour, backgrounds or camera ids",
                       settings_key, expected_settings_key, sender);
  }
  return {};
}

uint64_t EdgeTableKey(const Site& site) { return GroundLutKey(site.LutInputs(), site.grid, site.lut); }

uint64_t EdgeSettingsKey(const Site& site) {
  Hasher h;
  h.Add(std::string_view("edge-settings-v1"));
  h.AddPod(static_cast<int64_t>(site.detection.threshold));
  h.AddPod(static_cast<int64_t>(site.detection.tolerance_px));
  h.AddPod(static_cast<uint8_t>(site.detection.colour));
  h.AddPod(static_cast<uint8_t>(site.backgrounds.adaptive));
  if (site.detection.blocks()) {
    h.AddPod(static_cast<int64_t>(site.detection.block_width_px));
    h.AddPod(static_cast<int64_t>(site.detection.block_height_px));
    h.AddPod(static_cast<int64_t>(site.detection.block_rule));
  }
  for (const SiteCamera& c : site.cameras) h.Add(c.id);
  return h.Digest();
}

std::string EncodeEdgeMessage(const EdgeMessage& m) {
  const size_t pixels = static_cast<size_t>(m.width) * m.height;
  std::string payload;
  uint32_t n_modes = 0;
  OCCMAP_CHECK(ValidBlock(m.block_w, m.block_h), "EncodeEdgeMessage: blocks of 1 or 2 pixels");
  const int block_w = m.block_w, block_h = m.block_h;
  if (m.kind == EdgeMessageKind::kChanges && pixels > 0) {
    std::vector<uint8_t> whole;
    const uint8_t* changes = m.changes.data();
    if (m.changes.size() < pixels) {
      whole = m.changes;
      whole.resize(pixels, 0);
      changes = whole.data();
    }
    if (block_w == 1 && block_h == 1) {
      payload = CodeRows(changes, static_cast<int>(m.width), static_cast<int>(m.height), n_modes);
    } else {  // a block is changed when any of its pixels is (QuantiseChanges made them alike)
      const int w = static_cast<int>(m.width), h = static_cast<int>(m.height);
      const int bw = Blocks(m.width, block_w), bh = Blocks(m.height, block_h);
      std::vector<uint8_t> blocks(static_cast<size_t>(bw) * bh, 0);
      for (int y = 0; y < h; ++y) {
        const uint8_t* row = changes + static_cast<size_t>(y) * w;
        uint8_t* out = blocks.data() + static_cast<size_t>(y / block_h) * bw;
        for (int x = 0; x < w; ++x) out[x / block_w] |= row[x] != 0;
      }
      payload = CodeRows(blocks.data(), bw, bh, n_modes);
    }
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
  Put<uint32_t>(out, n_modes);
  Put<uint32_t>(out, static_cast<uint32_t>(payload.size()));
  Put<uint8_t>(out, static_cast<uint8_t>(block_w));
  Put<uint8_t>(out, static_cast<uint8_t>(block_h));
  out += payload;
  Put<uint64_t>(out, Checksum(out));
  return out;
}

void SealEdgeMessage(std::string& bytes) {
  if (bytes.size() < kHeaderBytes + kChecksumBytes) return;
  const size_t body = bytes.size() - kChecksumBytes;
  const uint64_t sum = Checksum(std::string_view(bytes).substr(0, body));
  std::memcpy(bytes.data() + body, &sum, kChecksumBytes);
}

void RestampEdgeMessage(std::string& bytes, int64_t frame, double timestamp_s, double t_unix) {
  constexpr size_t kFrameAt = 4 + 2 + 2 + 8 + 8 + 4 + 4 + 4;
  if (bytes.size() < kHeaderBytes) return;
  std::memcpy(bytes.data() + kFrameAt, &frame, 8);
  std::memcpy(bytes.data() + kFrameAt + 8, &timestamp_s, 8);
  std::memcpy(bytes.data() + kFrameAt + 16, &t_unix, 8);
  SealEdgeMessage(bytes);
}

void RekeyEdgeMessage(std::string& bytes, uint64_t table_key, uint64_t settings_key, uint32_t camera, double fps) {
  constexpr size_t kKeysAt = 4 + 2 + 2, kCameraAt = kKeysAt + 16, kFpsAt = kCameraAt + 12 + 8 + 8 + 8;
  if (bytes.size() < kHeaderBytes) return;
  std::memcpy(bytes.data() + kKeysAt, &table_key, 8);
  std::memcpy(bytes.data() + kKeysAt + 8, &settings_key, 8);
  std::memcpy(bytes.data() + kCameraAt, &camera, 4);
  std::memcpy(bytes.data() + kFpsAt, &fps, 8);
  SealEdgeMessage(bytes);
}

Result<EdgeMessage> DecodeEdgeHeader(std::string_view bytes, const EdgeExpectation& expect, std::string_view source) {
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
  if (bytes.size() < kHeaderBytes + kChecksumBytes) {
    return bad(fmt::format("header: expected {} bytes, found {}", kHeaderBytes + kChecksumBytes, bytes.size()));
  }
  {
    const size_t body = bytes.size() - kChecksumBytes;
    size_t sum_at = body;
    const uint64_t stated = Get<uint64_t>(bytes, sum_at);
    if (const uint64_t sum = Checksum(bytes.substr(0, body)); sum != stated) {
      return bad(fmt::format("checksum: expected {:016x} (of its {} bytes), found {:016x}: damaged on the way", sum, body,
                             stated));
    }
    bytes = bytes.substr(0, body);  // what follows reads the header and payload alone
  }
  EdgeMessage m;
  const uint16_t kind = Get<uint16_t>(bytes, at);
  if (kind > 1) return bad(fmt::format("kind: expected 0 (changes) or 1 (end), found {}", kind));
  m.kind = static_cast<EdgeMessageKind>(kind);
  m.table_key = Get<uint64_t>(bytes, at);
  m.settings_key = Get<uint64_t>(bytes, at);
  if (std::string keys = wire::KeysMismatch(m.table_key, m.settings_key, expect.table_key, expect.settings_key, "edge");
      !keys.empty()) {
    return bad(keys);
  }
  m.camera = Get<uint32_t>(bytes, at);
  m.width = Get<uint32_t>(bytes, at);
  m.height = Get<uint32_t>(bytes, at);
  m.frame = Get<int64_t>(bytes, at);
  m.timestamp_s = Get<double>(bytes, at);
  m.t_unix = Get<double>(bytes, at);
  m.fps = Get<double>(bytes, at);
  const uint32_t n_modes = Get<uint32_t>(bytes, at);
  const uint32_t payload_bytes = Get<uint32_t>(bytes, at);
  m.block_w = Get<uint8_t>(bytes, at);
  m.block_h = Get<uint8_t>(bytes, at);
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
  if (!ValidBlock(m.block_w, m.block_h)) {
    return bad(fmt::format("block: expected 1 or 2 pixels wide and high, found {} x {}", m.block_w, m.block_h));
  }
  // A row of blocks has at most one mode per block and one at its end.
  const uint32_t bw = static_cast<uint32_t>(Blocks(m.width, m.block_w)), bh = static_cast<uint32_t>(Blocks(m.height, m.block_h));
  const size_t most = static_cast<size_t>(bw) * bh + bh;
  if (n_modes < bh || n_modes > most) {
    return bad(fmt::format("modes: expected {}..{} for {}x{} blocks, found {}", bh, most, bw, bh, n_modes));
  }
  if (bytes.size() - at != payload_bytes) {
    return bad(fmt::format("payload: expected {} bytes, found {}", payload_bytes, bytes.size() - at));
  }
  return m;
}

Status DecodeEdgeChanges(std::string_view bytes, std::span<uint8_t> out, std::string_view source) {
  constexpr size_t kSizeAt = 4 + 2 + 2 + 8 + 8 + 4;
  uint32_t width = 0, height = 0, n_modes = 0;
  uint8_t block_w = 0, block_h = 0;
  if (bytes.size() >= kHeaderBytes) {
    std::memcpy(&width, bytes.data() + kSizeAt, 4);
    std::memcpy(&height, bytes.data() + kSizeAt + 4, 4);
    std::memcpy(&n_modes, bytes.data() + kModesAt, 4);
    std::memcpy(&block_w, bytes.data() + kBlockAt, 1);
    std::memcpy(&block_h, bytes.data() + kBlockAt + 1, 1);
  }
  if (bytes.size() < kHeaderBytes + kChecksumBytes || static_cast<size_t>(width) * height != out.size() ||
      !ValidBlock(block_w, block_h)) {
    return InvalidInput(fmt::format("{}: edge message: expected a message of {} pixels, found {} bytes", source,
                                    out.size(), bytes.size()));
  }
  const std::string_view payload = bytes.substr(kHeaderBytes, bytes.size() - kHeaderBytes - kChecksumBytes);
  const int w = static_cast<int>(width), h = static_cast<int>(height);
  if (block_w == 1 && block_h == 1) {
    const Status rows = DecodeRows(payload, n_modes, w, h, out.data());
    if (!rows.ok()) return InvalidInput(fmt::format("{}: edge message: payload: {}", source, rows.message()));
    return Status::Ok();
  }
  // The blocks, then each block's value into its pixels (the fuse's threads decode in parallel).
  thread_local std::vector<uint8_t> blocks;
  const int bw = Blocks(width, block_w), bh = Blocks(height, block_h);
  blocks.resize(static_cast<size_t>(bw) * bh);
  const Status rows = DecodeRows(payload, n_modes, bw, bh, blocks.data());
  if (!rows.ok()) return InvalidInput(fmt::format("{}: edge message: payload: {}", source, rows.message()));
  for (int y = 0; y < h; ++y) {
    const uint8_t* in = blocks.data() + static_cast<size_t>(y / block_h) * bw;
    uint8_t* row = out.data() + static_cast<size_t>(y) * w;
    if (block_w == 1) {
      std::memcpy(row, in, static_cast<size_t>(w));
    } else {
      for (int x = 0; x < w; ++x) row[x] = in[x / 2];
    }
  }
  return Status::Ok();
}

Result<EdgeMessage> DecodeEdgeMessage(std::string_view bytes, const EdgeExpectation& expect, std::string_view source) {
  OCCMAP_ASSIGN_OR_RETURN(EdgeMessage m, DecodeEdgeHeader(bytes, expect, source));
  if (m.kind == EdgeMessageKind::kEnd) return m;
  m.changes.resize(static_cast<size_t>(m.width) * m.height);
  OCCMAP_RETURN_IF_ERROR(DecodeEdgeChanges(bytes, m.changes, source));
  return m;
}

}  // namespace occmap
