#include "occmap/track/track_output.h"

#include <gtest/gtest.h>

namespace occmap {
namespace {

Track MakeTrack(int64_t id, double x, double y, double vx, double vy, std::string object_class) {
  Track t;
  t.id = id;
  t.x_m = x;
  t.y_m = y;
  t.vx_mps = vx;
  t.vy_mps = vy;
  t.object_class = std::move(object_class);
  return t;
}

TEST(TracksJsonLine, WritesOneLinePerFrameWithRoundedValues) {
  const std::vector<Track> tracks = {MakeTrack(3, 1.23456789, -2.0, 0.8, -0.000001, "person"),
                                     MakeTrack(12, 0.5, 4.25, 0, 1.5, "cart \"big\"")};
  EXPECT_EQ(TracksJsonLine(12, 1.2000000001, tracks),
            R"({"frame":12,"time_s":1.2,"tracks":[{"id":3,"x_m":1.2346,"y_m":-2,"vx_mps":0.8,"vy_mps":0,"class":"person"},)"
            R"({"id":12,"x_m":0.5,"y_m":4.25,"vx_mps":0,"vy_mps":1.5,"class":"cart \"big\""}]})");
  EXPECT_EQ(TracksJsonLine(0, 0, {}), R"({"frame":0,"time_s":0,"tracks":[]})");
}

TEST(LineEventJsonLine, WritesTheDirectionAndTheLinesCounts) {
  EXPECT_EQ(LineEventJsonLine({12, 1.2, "gate \"A\"", 3, LineDirection::kOut, {5, 2}}),
            R"({"frame":12,"time_s":1.2,"line":"gate \"A\"","track_id":3,"event":"cross","direction":"out","in":5,"out":2})");
}

TEST(ZoneEventJsonLine, WritesTheEventAndNullTrackForCounts) {
  EXPECT_EQ(ZoneEventJsonLine({5, 0.5, "door", 1, ZoneEventKind::kEnter, 2}),
            R"({"frame":5,"time_s":0.5,"zone":"door","track_id":1,"event":"enter","count":2})");
  EXPECT_EQ(ZoneEventJsonLine({7, 0.7, "hall\\west", -1, ZoneEventKind::kCount, 0}),
            R"({"frame":7,"time_s":0.7,"zone":"hall\\west","track_id":null,"event":"count","count":0})");
  EXPECT_EQ(ZoneEventJsonLine({9, 0.9, "a", 4, ZoneEventKind::kDwell, 1}),
            R"({"frame":9,"time_s":0.9,"zone":"a","track_id":4,"event":"dwell","count":1})");
  EXPECT_EQ(ZoneEventJsonLine({9, 0.9, "a", 4, ZoneEventKind::kLeave, 0}),
            R"({"frame":9,"time_s":0.9,"zone":"a","track_id":4,"event":"leave","count":0})");
}

TEST(JsonQuote, EscapesQuotesBackslashesAndControlCharacters) {
  EXPECT_EQ(JsonQuote("a\"b\\c\nd\x01"), "\"a\\\"b\\\\c\\nd\\u0001\"");
  EXPECT_EQ(JsonQuote("zone é"), "\"zone é\"");
}

TEST(MotGroundPlaneRow, WritesTheTenMotColumnsWithOneBasedFrames) {
  EXPECT_EQ(MotGroundPlaneRow(12, MakeTrack(3, 1.5, 2.0, 0.1, 0, "person")), "13,3,-1,-1,-1,-1,1,1.5000,2.0000,-1");
  EXPECT_EQ(MotGroundPlaneRow(0, MakeTrack(1, -0.123456, 10.00004, 0, 0, "person")),
            "1,1,-1,-1,-1,-1,1,-0.1235,10.0000,-1");
  EXPECT_EQ(MotGroundPlaneRow(0, MakeTrack(1, -0.00001, 0, 0, 0, "person")), "1,1,-1,-1,-1,-1,1,0.0000,0.0000,-1");
  EXPECT_EQ(MotGroundPlaneRows(4, {MakeTrack(1, 1, 2, 0, 0, "a"), MakeTrack(2, 3, 4, 0, 0, "b")}),
            "5,1,-1,-1,-1,-1,1,1.0000,2.0000,-1\n5,2,-1,-1,-1,-1,1,3.0000,4.0000,-1\n");
}

TEST(TrailHistory, KeepsTheLastPointsOfLiveTracksOnly) {
  TrailHistory trails(3);
  for (int f = 0; f < 5; ++f) {
    std::vector<Track> tracks = {MakeTrack(1, f, 0, 0, 0, "person")};
    if (f < 2) tracks.push_back(MakeTrack(2, 0, f, 0, 0, "person"));
    trails.Update(tracks);
    if (f == 1) {
      ASSERT_EQ(trails.Trails().size(), 2u);
      EXPECT_EQ(trails.Trails()[1].points_m.size(), 2u);
    }
  }
  const std::vector<Trail> now = trails.Trails();
  ASSERT_EQ(now.size(), 1u) << "track 2 ended";
  EXPECT_EQ(now[0].id, 1);
  EXPECT_EQ(now[0].points_m, (std::vector<Eigen::Vector2d>{{2, 0}, {3, 0}, {4, 0}}));
}

}  // namespace
}  // namespace occmap
