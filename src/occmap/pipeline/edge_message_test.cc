#include "occmap/pipeline/edge_message.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace occmap {
namespace {

EdgeExpectation Expect() {
  EdgeExpectation e;
  e.table_key = 0x1234;
  e.settings_key = 0x5678;
  e.camera_sizes = {{64, 48}, {33, 17}};
  return e;
}

EdgeMessage Sample(uint32_t camera = 1) {
  EdgeMessage m;
  m.table_key = 0x1234;
  m.settings_key = 0x5678;
  m.camera = camera;
  m.width = camera == 1 ? 33 : 64;
  m.height = camera == 1 ? 17 : 48;
  m.frame = 41;
  m.timestamp_s = 4.1;
  m.t_unix = 1.7e9 + 0.25;
  m.fps = 25;
  std::mt19937 rng(3);
  m.changes.resize(static_cast<size_t>(m.width) * m.height);
  for (uint8_t& c : m.changes) c = static_cast<uint8_t>(rng() % 3 == 0 ? (rng() % 2 ? 1 : 255) : 0);
  return m;
}

TEST(EdgeMessage, RoundTripKeepsEveryFieldAndEveryChangedPixel) {
  const EdgeMessage m = Sample();
  auto back = DecodeEdgeMessage(EncodeEdgeMessage(m), Expect(), "t");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->kind, EdgeMessageKind::kChanges);
  EXPECT_EQ(back->camera, 1u);
  EXPECT_EQ(back->frame, 41);
  EXPECT_EQ(back->timestamp_s, 4.1);
  EXPECT_EQ(back->t_unix, m.t_unix);
  EXPECT_EQ(back->fps, 25);
  ASSERT_EQ(back->changes.size(), m.changes.size());  // 33 x 17: not a whole number of bytes
  for (size_t k = 0; k < m.changes.size(); ++k) ASSERT_EQ(back->changes[k], m.changes[k] != 0 ? 1 : 0) << k;
}

TEST(EdgeMessage, BlocksOfTwoPixelsRoundTripAsBlocksInFewerBytes) {
  EdgeMessage m = Sample();  // 33 x 17: the last column and row of blocks are clipped
  const std::string whole = EncodeEdgeMessage(m);
  m.block_w = m.block_h = 2;
  const std::string blocks = EncodeEdgeMessage(m);
  auto back = DecodeEdgeMessage(blocks, Expect(), "t");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->block_w, 2);
  EXPECT_EQ(back->block_h, 2);
  EXPECT_LT(blocks.size(), whole.size());
  // Each pixel holds its block's value: changed when any of the block's pixels is.
  for (int y = 0; y < 17; ++y) {
    for (int x = 0; x < 33; ++x) {
      int any = 0;
      for (int v = y / 2 * 2; v < std::min(17, y / 2 * 2 + 2); ++v) {
        for (int u = x / 2 * 2; u < std::min(33, x / 2 * 2 + 2); ++u) any |= m.changes[static_cast<size_t>(v) * 33 + u] != 0;
      }
      ASSERT_EQ(back->changes[static_cast<size_t>(y) * 33 + x], any) << x << "," << y;
    }
  }
  std::string three = blocks;
  three[77] = 3;
  SealEdgeMessage(three);
  auto refused = DecodeEdgeMessage(three, Expect(), "t");
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().message(), "t: edge message: block: expected 1 or 2 pixels wide and high, found 2 x 3");
}

TEST(EdgeMessage, BlocksOneWideTwoHighRoundTrip) {
  EdgeMessage m = Sample();
  m.block_w = 1;
  m.block_h = 2;
  auto back = DecodeEdgeMessage(EncodeEdgeMessage(m), Expect(), "t");
  ASSERT_TRUE(back.ok()) << back.status().message();
  for (int y = 0; y < 17; ++y) {
    for (int x = 0; x < 33; ++x) {
      int any = m.changes[static_cast<size_t>(y) * 33 + x] != 0;
      const int other = y % 2 == 0 ? y + 1 : y - 1;
      if (other < 17) any |= m.changes[static_cast<size_t>(other) * 33 + x] != 0;
      ASSERT_EQ(back->changes[static_cast<size_t>(y) * 33 + x], any) << x << "," << y;
    }
  }
}

TEST(EdgeMessage, NoTimestampAndTheEndOfASourceRoundTrip) {
  EdgeMessage m = Sample(0);
  m.timestamp_s = std::nan("");
  auto back = DecodeEdgeMessage(EncodeEdgeMessage(m), Expect(), "t");
  ASSERT_TRUE(back.ok());
  EXPECT_TRUE(std::isnan(back->timestamp_s));
  EdgeMessage end;
  end.kind = EdgeMessageKind::kEnd;
  end.table_key = 0x1234;
  end.settings_key = 0x5678;
  end.frame = 99;
  auto e = DecodeEdgeMessage(EncodeEdgeMessage(end), Expect(), "t");
  ASSERT_TRUE(e.ok()) << e.status().message();
  EXPECT_EQ(e->kind, EdgeMessageKind::kEnd);
  EXPECT_EQ(e->frame, 99);
}

TEST(EdgeMessage, ASparseMaskIsAFewHundredBytes) {
  EdgeMessage m;
  m.table_key = 0x1234;
  m.settings_key = 0x5678;
  m.width = 640;
  m.height = 480;
  m.changes.assign(640 * 480, 0);
  for (int y = 200; y < 400; ++y) {
    for (int x = 300; x < 340; ++x) m.changes[static_cast<size_t>(y) * 640 + x] = 1;  // a person
  }
  EXPECT_LT(EncodeEdgeMessage(m).size(), 400u);  // 38 400 bytes of bits
}

// The row code (T.6 modes) against every kind of row: empty, full, single pixels at both ends,
// changes more and less than 3 pixels from the row above's, runs that end and start.
TEST(EdgeMessage, EveryPatternOfRowsRoundTrips) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 300; ++trial) {
    EdgeMessage m;
    m.table_key = 0x1234;
    m.settings_key = 0x5678;
    m.camera = 0;
    m.width = static_cast<uint32_t>(1 + rng() % 70);
    m.height = static_cast<uint32_t>(1 + rng() % 30);
    m.changes.assign(static_cast<size_t>(m.width) * m.height, 0);
    const int kind = trial % 5;
    for (uint32_t y = 0; y < m.height; ++y) {
      for (uint32_t x = 0; x < m.width; ++x) {
        uint8_t& c = m.changes[y * m.width + x];
        if (kind == 0) c = static_cast<uint8_t>(rng() % 2);                                   // noise
        if (kind == 1) c = rng() % 8 == 0 ? 255 : 0;                        // specks
        if (kind == 2) c = static_cast<uint8_t>((x + y) % 2);                                // a checkerboard
        if (kind == 3) c = x >= y % m.width && x < (y * 3) % (m.width + 1);  // slanted edges
        if (kind == 4 && y > 0) c = static_cast<uint8_t>(m.changes[(y - 1) * m.width + x] ^ (rng() % 10 == 0 ? 1 : 0));  // rows like the row above
      }
    }
    EdgeExpectation e = Expect();
    e.camera_sizes[0] = {static_cast<int>(m.width), static_cast<int>(m.height)};
    auto back = DecodeEdgeMessage(EncodeEdgeMessage(m), e, "t");
    ASSERT_TRUE(back.ok()) << trial << ": " << back.status().message();
    for (size_t k = 0; k < m.changes.size(); ++k) {
      ASSERT_EQ(back->changes[k], m.changes[k] != 0 ? 1 : 0) << "trial " << trial << " pixel " << k;
    }
  }
}

// Silhouettes (what an edge sends) take far less than their bits.
TEST(EdgeMessage, PeopleTakeAFewHundredBytes) {
  EdgeMessage m;
  m.table_key = 0x1234;
  m.settings_key = 0x5678;
  m.width = 640;
  m.height = 480;
  m.changes.assign(640 * 480, 0);
  for (int p = 0; p < 6; ++p) {  // six slanted people, each a head and a body
    const int cx = 60 + p * 100, top = 150 + p * 20;
    for (int y = top; y < top + 200; ++y) {
      const int half = y < top + 30 ? 12 : 20 + (y - top) / 20, shift = (y - top) / 8;
      for (int x = cx - half + shift; x < cx + half + shift; ++x) m.changes[static_cast<size_t>(y) * 640 + x] = 1;
    }
  }
  EXPECT_LT(EncodeEdgeMessage(m).size(), 600u);  // 38 400 bytes of bits; 330 coded
}

TEST(EdgeMessage, RefusesOtherTablesSettingsVersionsAndBrokenBytes) {
  auto refused = [](const std::string& bytes, const EdgeExpectation& e, const std::string& words) {
    auto r = DecodeEdgeMessage(bytes, e, "occmap/lab/edge/c1");
    ASSERT_FALSE(r.ok()) << words;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidInput);
    EXPECT_NE(r.status().message().find(words), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find("occmap/lab/edge/c1"), std::string::npos);
  };
  const std::string good = EncodeEdgeMessage(Sample());
  EdgeExpectation other = Expect();
  other.table_key = 0x9999;
  refused(good, other, "built for other tables");
  other = Expect();
  other.settings_key = 0x9999;
  refused(good, other, "other detection settings");
  std::string v1 = good;
  v1[4] = 1;
  refused(v1, Expect(), "schema version 1");
  refused("hello", Expect(), "expected an occmap edge message");
  refused(good.substr(0, 30), Expect(), "header");
  refused(good.substr(0, good.size() - 1), Expect(), "checksum: expected");
  std::string short_payload = good.substr(0, good.size() - 9) + good.substr(good.size() - 8);
  SealEdgeMessage(short_payload);
  refused(short_payload, Expect(), "payload: expected");
  // Any byte damaged after the version, header or payload, is caught by the checksum (issue 39:
  // a message with a valid header and a junk payload took a frame set's place).
  for (size_t k = 8; k < good.size(); ++k) {
    std::string flipped = good;
    flipped[k] = static_cast<char>(flipped[k] ^ 0x5a);
    refused(flipped, Expect(), "damaged on the way");
  }
  // Coded rows that are broken but sealed: each byte of a valid message's rows flipped in turn
  // decodes to an error or to some mask, never a crash.
  for (size_t k = 78; k + 8 < good.size(); ++k) {
    std::string flipped = good;
    flipped[k] = static_cast<char>(flipped[k] ^ 0x5a);
    SealEdgeMessage(flipped);
    (void)DecodeEdgeMessage(flipped, Expect(), "t");
  }
  EdgeExpectation one = Expect();
  one.camera_sizes.resize(1);
  refused(good, one, "camera: expected 0..0, found 1");
  one = Expect();
  one.camera_sizes[1] = {32, 17};
  refused(good, one, "expected a 32x17 image, found 33x17");
}

TEST(EdgeMessage, TheFusesHalvesDecodeTheHeaderThenTheChangesIntoItsSlice) {
  const EdgeMessage m = Sample();
  const std::string bytes = EncodeEdgeMessage(m);
  auto header = DecodeEdgeHeader(bytes, Expect(), "t");
  ASSERT_TRUE(header.ok()) << header.status().message();
  EXPECT_TRUE(header->changes.empty());
  EXPECT_EQ(header->camera, 1u);
  EXPECT_EQ(header->frame, 41);
  EXPECT_EQ(header->t_unix, m.t_unix);
  // Into a slice of a larger buffer, as the fuse decodes into its change buffer: every pixel of
  // the slice written (junk before), nothing around it.
  const size_t pixels = m.changes.size();
  std::vector<uint8_t> buffer(pixels + 20, 7);
  const Status decoded = DecodeEdgeChanges(bytes, std::span<uint8_t>(buffer.data() + 10, pixels), "t");
  ASSERT_TRUE(decoded.ok()) << decoded.message();
  for (size_t k = 0; k < pixels; ++k) ASSERT_EQ(buffer[10 + k], m.changes[k] != 0 ? 1 : 0) << k;
  for (size_t k = 0; k < 10; ++k) ASSERT_EQ(buffer[k], 7);
  for (size_t k = 10 + pixels; k < buffer.size(); ++k) ASSERT_EQ(buffer[k], 7);
}

TEST(EdgeMessage, TheChangesRefuseBrokenRowsThatTheHeaderLetThrough) {
  const std::string good = EncodeEdgeMessage(Sample());
  constexpr size_t kModesAt = 68, kPayloadAt = 72, kHeaderBytes = 78;
  const std::string rows = good.substr(kHeaderBytes, good.size() - kHeaderBytes - 8);
  auto with = [&](uint32_t n_modes, std::string_view payload) {
    std::string b = good.substr(0, kHeaderBytes);
    std::memcpy(b.data() + kModesAt, &n_modes, 4);
    const auto n = static_cast<uint32_t>(payload.size());
    std::memcpy(b.data() + kPayloadAt, &n, 4);
    b += std::string(payload) + std::string(8, '\0');
    SealEdgeMessage(b);
    return b;
  };
  std::vector<uint8_t> out(33 * 17);
  struct Case {
    std::string bytes;
    std::string message;
  };
  const std::vector<Case> cases = {
      {with(17, ""), "src: edge message: payload: coded rows: row 0: expected more bytes, found the end"},
      {with(17, rows), "more than the 17 modes stated"},
      {with(33 * 17, rows), "modes decoded"},
  };
  for (const Case& c : cases) {
    ASSERT_TRUE(DecodeEdgeHeader(c.bytes, Expect(), "src").ok()) << c.message;
    const Status s = DecodeEdgeChanges(c.bytes, out, "src");
    ASSERT_FALSE(s.ok()) << c.message;
    EXPECT_EQ(s.code(), StatusCode::kInvalidInput);
    EXPECT_NE(s.message().find(c.message), std::string::npos) << s.message();
    // DecodeEdgeMessage refuses it with the same words.
    auto whole = DecodeEdgeMessage(c.bytes, Expect(), "src");
    ASSERT_FALSE(whole.ok());
    EXPECT_EQ(whole.status().message(), s.message());
  }
  std::vector<uint8_t> small(32 * 17);
  const Status s = DecodeEdgeChanges(good, small, "src");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.message(), fmt::format("src: edge message: expected a message of 544 pixels, found {} bytes", good.size()));
  EXPECT_FALSE(DecodeEdgeChanges("OCME", out, "src").ok());
}

TEST(EdgeMessage, RestampedKeepsEverythingButFrameAndTimes) {
  const EdgeMessage m = Sample();
  std::string bytes = EncodeEdgeMessage(m);
  RestampEdgeMessage(bytes, 7, 0.7, 1.8e9);
  auto d = DecodeEdgeMessage(bytes, Expect(), "restamped");
  ASSERT_TRUE(d.ok()) << d.status().message();
  EXPECT_EQ(d->frame, 7);
  EXPECT_EQ(d->timestamp_s, 0.7);
  EXPECT_EQ(d->t_unix, 1.8e9);
  EXPECT_EQ(d->camera, m.camera);
  EXPECT_EQ(d->fps, m.fps);
  for (size_t k = 0; k < m.changes.size(); ++k) ASSERT_EQ(d->changes[k], m.changes[k] != 0 ? 1 : 0) << k;
}

TEST(EdgeMessage, RekeyedIsAnotherCameraOfAnotherSite) {
  const EdgeMessage m = Sample();
  std::string bytes = EncodeEdgeMessage(m);
  EdgeExpectation other = Expect();
  other.table_key ^= 0x1234;
  other.settings_key ^= 0x5678;
  other.camera_sizes.push_back(other.camera_sizes[m.camera]);
  const uint32_t camera = static_cast<uint32_t>(other.camera_sizes.size() - 1);
  RekeyEdgeMessage(bytes, other.table_key, other.settings_key, camera, 12.5);
  auto d = DecodeEdgeMessage(bytes, other, "rekeyed");
  ASSERT_TRUE(d.ok()) << d.status().message();
  EXPECT_EQ(d->camera, camera);
  EXPECT_EQ(d->fps, 12.5);
  EXPECT_EQ(d->frame, m.frame);
  EXPECT_EQ(d->t_unix, m.t_unix);
  for (size_t k = 0; k < m.changes.size(); ++k) ASSERT_EQ(d->changes[k], m.changes[k] != 0 ? 1 : 0) << k;
}

// The fuzz target's seeds (fuzz/corpus/edge_message, fuzz/edge_message_fuzzer.cc's records)
// written again after a change of the schema: OCCMAP_FUZZ_SEEDS=fuzz/corpus/edge_message
// occmap_pipeline_test --gtest_also_run_disabled_tests --gtest_filter='*WritesFuzzSeeds'.
TEST(EdgeMessage, DISABLED_WritesFuzzSeeds) {
  const char* dir = std::getenv("OCCMAP_FUZZ_SEEDS");
  ASSERT_NE(dir, nullptr) << "set OCCMAP_FUZZ_SEEDS to the corpus folder";
  auto message = [](uint32_t camera, int64_t frame, double timestamp_s, double t_unix, uint64_t table_key = 0x1234,
                    uint32_t stated_camera = 99) {
    EdgeMessage m = Sample(camera);
    m.table_key = table_key;
    m.camera = stated_camera == 99 ? camera : stated_camera;
    m.frame = frame;
    m.timestamp_s = timestamp_s;
    m.t_unix = t_unix;
    m.fps = 10;
    // A person-like box and a speck, moving with the frame (small seeds).
    std::fill(m.changes.begin(), m.changes.end(), 0);
    const int x0 = static_cast<int>(frame % 7) * 2;
    for (int y = 3; y < static_cast<int>(m.height) - 2; ++y) {
      for (int x = x0; x < x0 + 6 + y / 4; ++x) m.changes[static_cast<size_t>(y) * m.width + x] = 1;
    }
    m.changes[m.changes.size() / 2 + 20] = 1;
    return m;
  };
  auto write = [&](const std::string& name, uint8_t align, const std::vector<std::pair<uint8_t, EdgeMessage>>& records) {
    std::string bytes(1, static_cast<char>(align));
    for (const auto& [topic, m] : records) {
      const std::string payload = EncodeEdgeMessage(m);
      const auto n = static_cast<uint16_t>(payload.size());
      bytes += static_cast<char>(topic);
      bytes.append(reinterpret_cast<const char*>(&n), 2);
      bytes += payload;
    }
    std::ofstream(std::string(dir) + "/" + name, std::ios::binary) << bytes;
  };
  EdgeMessage end0, end1;
  end0.kind = end1.kind = EdgeMessageKind::kEnd;
  end0.table_key = end1.table_key = 0x1234;
  end0.settings_key = end1.settings_key = 0x5678;
  end1.camera = 1;
  end0.frame = end1.frame = 3;
  end0.timestamp_s = end1.timestamp_s = std::nan("");
  end0.t_unix = end1.t_unix = 1.7e9 + 0.3;
  write("refused", 0, {{0, message(0, 0, 0, 1.7e9, 0x999)}, {1, message(0, 0, 0, 1.7e9, 0x1234, 1)},
                       {1, message(0, 0, 0, 1.7e9)}});
  write("two_cameras_by_index", 0,
        {{0, message(0, 0, 0, 1.7e9)}, {1, message(1, 0, 0, 1.7e9)}, {0, message(0, 1, 0.1, 1.7e9 + 0.1)},
         {1, message(1, 1, 0.1, 1.7e9 + 0.1)}, {0, message(0, 2, 0.2, 1.7e9 + 0.2)}, {1, message(1, 2, 0.2, 1.7e9 + 0.2)},
         {0, end0}, {1, end1}});
  write("two_cameras_by_timestamp", 1,
        {{0, message(0, 100, 5.0, 1.7e9 + 10)}, {1, message(1, 7, 5.03, 1.7e9 + 0.7)},
         {0, message(0, 101, 5.1, 1.7e9 + 10.1)}, {1, message(1, 8, 5.13, 1.7e9 + 0.8)},
         {0, message(0, 102, 5.2, 1.7e9 + 10.2)}, {0, message(0, 103, 5.3, 1.7e9 + 10.3)},
         {1, message(1, 10, 5.33, 1.7e9 + 1.0)}});
}

}  // namespace
}  // namespace occmap
