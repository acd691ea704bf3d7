#include "occmap/track/zones.h"

#include <gtest/gtest.h>

namespace occmap {
namespace {

constexpr double kDt = 0.1;

Track At(int64_t id, double x_m, double y_m) {
  Track t;
  t.id = id;
  t.x_m = x_m;
  t.y_m = y_m;
  return t;
}

ZoneEvent Event(int64_t frame, const char* zone, int64_t id, ZoneEventKind kind, int count) {
  return ZoneEvent{frame, kDt * static_cast<double>(frame), zone, id, kind, count};
}

std::string Describe(const std::vector<ZoneEvent>& events) {
  std::string s;
  for (const ZoneEvent& e : events) {
    s += std::to_string(e.frame) + " " + e.zone + " " + std::to_string(e.track_id) + " " + std::string(ToString(e.kind)) +
         " " + std::to_string(e.count) + "\n";
  }
  return s;
}

TEST(PointInPolygon, UsesTheEvenOddRuleOnConvexAndConcavePolygons) {
  const std::vector<Eigen::Vector2d> square = {{0, 0}, {2, 0}, {2, 2}, {0, 2}};
  EXPECT_TRUE(PointInPolygon(square, {1, 1}));
  EXPECT_FALSE(PointInPolygon(square, {3, 1}));
  EXPECT_FALSE(PointInPolygon(square, {1, -0.1}));
  // An L (clockwise): the notch at (1.5, 1.5) is outside.
  const std::vector<Eigen::Vector2d> ell = {{0, 0}, {0, 2}, {1, 2}, {1, 1}, {2, 1}, {2, 0}};
  EXPECT_TRUE(PointInPolygon(ell, {0.5, 1.5}));
  EXPECT_TRUE(PointInPolygon(ell, {1.5, 0.5}));
  EXPECT_FALSE(PointInPolygon(ell, {1.5, 1.5}));
}

TEST(ZoneMonitor, ScriptedPathGivesEnterDwellAndLeaveAtTheExpectedFrames) {
  // Zone "door": x in [2, 3], y in [0, 2], dwell 0.5 s. Zone "hall": x in [2.5, 6], y in
  // [0, 2], no dwell.
  ZoneOptions door{"door", {{2, 0}, {3, 0}, {3, 2}, {2, 2}}, 0.5};
  ZoneOptions hall{"hall", {{2.5, 0}, {6, 0}, {6, 2}, {2.5, 2}}, std::nullopt};
  Result<ZoneMonitor> created = ZoneMonitor::Create({door, hall});
  ASSERT_TRUE(created.ok()) << created.status().ToString();
  ZoneMonitor zones = std::move(created).value();

  // Track 1 walks along y = 1 at 1 m/s from x = 1.55: x = 2.05 (in door) at frame 5, 2.55 (in
  // hall) at 10, 3.05 (out of door) at 15. Track 2 stands in the door from frame 8 and
  // disappears at frame 12 (it ended: it leaves).
  std::vector<ZoneEvent> events;
  for (int64_t f = 0; f < 20; ++f) {
    std::vector<Track> tracks{At(1, 1.55 + 0.1 * static_cast<double>(f), 1.0)};
    if (f >= 8 && f < 12) tracks.push_back(At(2, 2.2, 0.5));
    const ZoneFrame result = zones.Update(f, kDt * static_cast<double>(f), tracks);
    ASSERT_EQ(result.counts.size(), 2u);
    if (f == 10) {
      EXPECT_EQ(result.counts[0], 2);
      EXPECT_EQ(result.counts[1], 1);
    }
    events.insert(events.end(), result.events.begin(), result.events.end());
  }
  const std::vector<ZoneEvent> expected = {
      Event(5, "door", 1, ZoneEventKind::kEnter, 1),
      Event(5, "door", -1, ZoneEventKind::kCount, 1),
      Event(8, "door", 2, ZoneEventKind::kEnter, 2),
      Event(8, "door", -1, ZoneEventKind::kCount, 2),
      Event(10, "door", 1, ZoneEventKind::kDwell, 2),  // entered at 0.5 s, 1.0 s now
      Event(10, "hall", 1, ZoneEventKind::kEnter, 1),
      Event(10, "hall", -1, ZoneEventKind::kCount, 1),
      Event(12, "door", 2, ZoneEventKind::kLeave, 1),  // ended after 0.4 s: no dwell
      Event(12, "door", -1, ZoneEventKind::kCount, 1),
      Event(15, "door", 1, ZoneEventKind::kLeave, 0),
      Event(15, "door", -1, ZoneEventKind::kCount, 0),
  };
  EXPECT_EQ(Describe(events), Describe(expected));
  EXPECT_EQ(events, expected);
}

TEST(ZoneMonitor, DwellIsReportedOncePerVisitAndAgainAfterReentering) {
  Result<ZoneMonitor> created = ZoneMonitor::Create({{"spot", {{0, 0}, {1, 0}, {1, 1}, {0, 1}}, 0.3}});
  ASSERT_TRUE(created.ok());
  ZoneMonitor zones = std::move(created).value();
  std::vector<int64_t> dwell_frames;
  for (int64_t f = 0; f < 30; ++f) {
    const bool inside = f < 10 || f >= 15;  // out for frames 10-14
    const ZoneFrame result = zones.Update(f, kDt * static_cast<double>(f), {At(7, inside ? 0.5 : 2.0, 0.5)});
    for (const ZoneEvent& e : result.events) {
      if (e.kind == ZoneEventKind::kDwell) dwell_frames.push_back(e.frame);
    }
  }
  EXPECT_EQ(dwell_frames, (std::vector<int64_t>{3, 18}));
}

TEST(ZoneMonitor, CountsEveryFrameWhenAsked) {
  Result<ZoneMonitor> created = ZoneMonitor::Create({{"a", {{0, 0}, {1, 0}, {1, 1}}, std::nullopt}}, true);
  ASSERT_TRUE(created.ok());
  ZoneMonitor zones = std::move(created).value();
  for (int64_t f = 0; f < 3; ++f) {
    const ZoneFrame result = zones.Update(f, 0.1 * static_cast<double>(f), {});
    ASSERT_EQ(result.events.size(), 1u);
    EXPECT_EQ(result.events[0].kind, ZoneEventKind::kCount);
    EXPECT_EQ(result.events[0].count, 0);
  }
}

TEST(ZoneMonitor, CreateRefusesADegeneratePolygon) {
  const auto created = ZoneMonitor::Create({{"line", {{0, 0}, {1, 1}, {2, 2}}, std::nullopt}});
  ASSERT_FALSE(created.ok());
  EXPECT_EQ(created.status().message(), "tracking.zones[0].polygon: expected a polygon with a non-zero area");
}

}  // namespace
}  // namespace occmap
