#include "occmap/pipeline/protection_message.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "occmap/detect/background_model.h"

namespace occmap {
namespace {

ProtectionExpectation Expect() { return {0x1234, 0x5678, 100}; }

ProtectionMessage Sample() {
  ProtectionMessage m;
  m.table_key = 0x1234;
  m.settings_key = 0x5678;
  m.frame = 41;
  m.timestamp_s = 4.1;
  m.t_unix = 1.7e9 + 0.25;
  m.boxes = {{1.5, 2.25, 0.6, BackgroundModel::kObject}, {-3, 7.125, 0.45, BackgroundModel::kPerson},
             {0.1, 0.2, 0.3, BackgroundModel::kWalkedPerson}};
  m.persons_m = {{-3.0, 7.0}, {0.1, 0.2}};
  m.occupied = {{0, 3}, {10, 1}, {97, 3}};
  return m;
}

TEST(ProtectionMessage, RoundTripKeepsEveryField) {
  const ProtectionMessage m = Sample();
  auto back = DecodeProtectionMessage(EncodeProtectionMessage(m), Expect(), "t");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->frame, 41);
  EXPECT_EQ(back->timestamp_s, 4.1);
  EXPECT_EQ(back->t_unix, m.t_unix);
  EXPECT_EQ(back->boxes, m.boxes);
  EXPECT_EQ(back->persons_m, m.persons_m);
  EXPECT_EQ(back->occupied, m.occupied);
}

TEST(ProtectionMessage, AnEmptyMapAndNoTimestampRoundTrip) {
  ProtectionMessage m = Sample();
  m.boxes.clear();
  m.persons_m.clear();
  m.occupied.clear();
  m.timestamp_s = std::nan("");
  const std::string bytes = EncodeProtectionMessage(m);
  EXPECT_EQ(bytes.size(), 60u);
  auto back = DecodeProtectionMessage(bytes, Expect(), "t");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_TRUE(std::isnan(back->timestamp_s));
  EXPECT_TRUE(back->boxes.empty() && back->persons_m.empty() && back->occupied.empty());
}

TEST(ProtectionMessage, OccupiedRunsOfAMapRoundTrip) {
  FloorGrid g;
  g.cells_x = 10;
  g.cells_y = 10;
  g.cell_size_m = 0.1;
  OccupancyMap map(g);
  for (int c : {0, 1, 2, 10, 55, 56, 99}) map.states()[c] = CellState::kOccupied;
  map.states()[3] = CellState::kFree;
  const auto runs = OccupiedRuns(map);
  EXPECT_EQ(runs, (std::vector<std::pair<uint32_t, uint32_t>>{{0, 3}, {10, 1}, {55, 2}, {99, 1}}));
  OccupancyMap back(g);
  MarkOccupied(runs, back);
  for (int c = 0; c < 100; ++c) {
    EXPECT_EQ(back.state(c) == CellState::kOccupied, map.state(c) == CellState::kOccupied) << c;
  }
}

// Each malformed message is refused with a message naming the field (and its topic), never a crash.
TEST(ProtectionMessage, RefusesMalformedMessagesNamingTheField) {
  const std::string good = EncodeProtectionMessage(Sample());
  constexpr size_t kCountsAt = 4 + 2 + 2 + 8 + 8 + 8 + 8 + 8, kBoxesAt = kCountsAt + 12;
  auto with = [&](const std::function<void(ProtectionMessage&)>& f) {
    ProtectionMessage m = Sample();
    f(m);
    return EncodeProtectionMessage(m);
  };
  auto poke = [&](size_t at, const void* v, size_t n) {
    std::string b = good;
    std::memcpy(b.data() + at, v, n);
    return b;
  };
  const uint16_t v9 = 9;
  const uint32_t many = 1000;
  const uint8_t four = 4, zero = 0;
  const size_t kRunsAt = good.size() - 6;  // three runs of two one-byte varints
  const struct {
    std::string bytes;
    std::string words;
  } cases[] = {
      {"", "expected an occmap protection message (\"OCMP\"), found 0 bytes"},
      {"OCME" + good.substr(4), "expected an occmap protection message"},
      {poke(4, &v9, 2), "schema version 9, this occmap reads version 1"},
      {good.substr(0, 30), "header: expected 60 bytes, found 30"},
      {with([](ProtectionMessage& m) { m.table_key = 7; }), "built for other tables"},
      {with([](ProtectionMessage& m) { m.settings_key = 7; }), "other detection settings"},
      {with([](ProtectionMessage& m) { m.frame = -2; }), "frame: expected >= 0, found -2"},
      {poke(kCountsAt, &many, 4), "length: expected at least 25098 bytes for 1000 boxes, 2 persons and 3 runs"},
      {good.substr(0, good.size() - 1), "length: expected at least 173 bytes for 3 boxes, 2 persons and 3 runs, found 172"},
      {good.substr(0, good.size() - 1) + "\x80", "occupied[2]: expected two varints"},
      {good.substr(0, kRunsAt) + std::string("\xff\xff\xff\xff\x7f\x01", 6) + good.substr(kRunsAt + 2),
       "occupied[0]: expected two varints (gap, cells), found the message's end or more than 32 bits"},
      {good + "x", "length: expected 173 bytes for 3 boxes, 2 persons and 3 runs, found 174"},
      {with([](ProtectionMessage& m) { m.boxes[1].x_m = std::nan(""); }), "boxes[1].position: expected finite metres"},
      {with([](ProtectionMessage& m) { m.boxes[2].radius_m = -1; }), "boxes[2].radius_m: expected a finite radius >= 0, found -1"},
      {poke(kBoxesAt + 24, &four, 1), "boxes[0].value: expected 1 (object), 2 (person) or 3 (walked person), found 4"},
      {with([](ProtectionMessage& m) { m.persons_m[0].y() = INFINITY; }), "persons[0]: expected finite metres"},
      {poke(kRunsAt + 1, &zero, 1), "occupied[0]: expected cells 0..99, found 0 cells from 0"},
      {with([](ProtectionMessage& m) { m.occupied[2] = {98, 3}; }), "occupied[2]: expected cells 11..99, found 3 cells from 98"},
  };
  for (const auto& c : cases) {
    auto r = DecodeProtectionMessage(c.bytes, Expect(), "occmap/plaza/protection");
    ASSERT_FALSE(r.ok()) << c.words;
    EXPECT_NE(r.status().message().find(c.words), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find("occmap/plaza/protection: protection message: "), std::string::npos);
  }
}

}  // namespace
}  // namespace occmap
