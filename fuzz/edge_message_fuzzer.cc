// Fuzz target: the MQTT evidence messages of `occmap edge` as `occmap fuse` takes them
// (pipeline/edge_message.h DecodeEdgeMessage, and the fuse's halves of it, DecodeEdgeHeader and
// DecodeEdgeChanges, which must agree with it; then the fuse's checks and the frame-set aligner
// of pipeline/edge_align.h). The fuse's site is fixed: table key 0x1234, settings key 0x5678,
// camera 0 64x48, camera 1 33x17 (the edge_message test's).
//
// Input: byte 0 picks the alignment (even: by frame index, odd: by timestamp), then records
// [u8 topic camera, its high bit: keep the checksum as it is][u16 length, little-endian][length
// bytes: one MQTT payload], each arriving 10 ms after the one before. Without the high bit the
// payload's checksum is made true (SealEdgeMessage), so that mutations reach the decoder. A
// message that decodes must encode back to the same message.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/core.h>

#include "fuzz/fuzz_util.h"
#include "occmap/pipeline/edge_align.h"
#include "occmap/pipeline/edge_message.h"

namespace {

bool Same(double a, double b) { return std::memcmp(&a, &b, sizeof(a)) == 0; }

// Encode(Decode(x)) decodes to the same message: what an edge would have sent.
void CheckRoundTrip(const occmap::EdgeMessage& m, const occmap::EdgeExpectation& expect) {
  auto back = occmap::DecodeEdgeMessage(occmap::EncodeEdgeMessage(m), expect, "round trip");
  if (!back.ok() || back->kind != m.kind || back->camera != m.camera || back->frame != m.frame ||
      !Same(back->timestamp_s, m.timestamp_s) || !Same(back->t_unix, m.t_unix) || !Same(back->fps, m.fps) ||
      back->changes != m.changes) {
    std::abort();
  }
}

// The fuse's two halves (DecodeEdgeHeader on arrival, DecodeEdgeChanges into the frame set's
// buffer) take and refuse what DecodeEdgeMessage does, and give its changes.
void CheckHalves(std::string_view payload, const occmap::Result<occmap::EdgeMessage>& whole,
                 const occmap::EdgeExpectation& expect) {
  auto header = occmap::DecodeEdgeHeader(payload, expect, "halves");
  if (!header.ok()) {
    if (whole.ok()) std::abort();
    return;
  }
  if (header->kind == occmap::EdgeMessageKind::kEnd) {
    if (!whole.ok()) std::abort();
    return;
  }
  std::vector<uint8_t> changes(static_cast<size_t>(header->width) * header->height);
  const occmap::Status decoded = occmap::DecodeEdgeChanges(payload, changes, "halves");
  if (decoded.ok() != whole.ok() || (whole.ok() && whole->changes != changes)) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using Clock = std::chrono::steady_clock;
  if (size < 1) return 0;
  occmap::EdgeExpectation expect;
  expect.table_key = 0x1234;
  expect.settings_key = 0x5678;
  expect.camera_sizes = {{64, 48}, {33, 17}};
  occmap::AlignOptions align;
  align.sync = data[0] % 2 ? occmap::FrameSync::kTimestamp : occmap::FrameSync::kIndex;
  const Clock::time_point t0{};
  occmap::FrameSetAligner aligner(expect.camera_sizes.size(), align, t0);
  Clock::time_point now = t0;
  double fps = 0;
  size_t at = 1;
  while (at + 3 <= size) {
    const size_t topic = data[at] & 0x7f;
    const bool keep_checksum = (data[at] & 0x80) != 0;
    const size_t length = data[at + 1] | (static_cast<size_t>(data[at + 2]) << 8);
    at += 3;
    std::string bytes(occmap::fuzz::AsText(data + at, std::min(length, size - at)));
    at += bytes.size();
    if (!keep_checksum) occmap::SealEdgeMessage(bytes);
    const std::string_view payload = bytes;
    now += std::chrono::milliseconds(10);
    if (topic >= expect.camera_sizes.size()) continue;  // not a camera's topic: not read
    auto m = occmap::DecodeEdgeMessage(payload, expect, "occmap/edge/cam");
    CheckHalves(payload, m, expect);
    // The fuse's own checks (pipeline/edge_fuse.cc): the camera of the topic, a timestamp to align by.
    if (std::getenv("OCCMAP_FUZZ_VERBOSE") != nullptr) {
      std::fprintf(stderr, "%s\n", m.ok() ? fmt::format("camera {} frame {}", m->camera, m->frame).c_str()
                                           : m.status().message().c_str());
    }
    if (!m.ok() || m->camera != topic) continue;
    if (m->kind == occmap::EdgeMessageKind::kEnd) {
      aligner.End(m->camera, m->frame, now);
      continue;
    }
    if (align.sync == occmap::FrameSync::kTimestamp && std::isnan(m->timestamp_s)) continue;
    if (fps == 0 && m->fps > 0) aligner.set_tolerance(0.9 / (fps = m->fps));
    CheckRoundTrip(*m, expect);
    aligner.Add(std::move(m).value(), now);
    while (auto set = aligner.Next(now)) {
      if (set->cameras.size() != expect.camera_sizes.size()) std::abort();
    }
  }
  // Every camera silent past the latency budget: whatever is pending comes out.
  now += std::chrono::seconds(5);
  while (auto set = aligner.Next(now)) (void)set;
  return 0;
}
