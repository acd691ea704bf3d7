#include "occmap/track/count_lines.h"

#include <gtest/gtest.h>

#include "occmap/track/track_output.h"

namespace occmap {
namespace {

constexpr double kDt = 0.1;

Track At(int64_t id, double x_m, double y_m, bool coasting = false) {
  Track t;
  t.id = id;
  t.x_m = x_m;
  t.y_m = y_m;
  t.coasting = coasting;
  return t;
}

// The events of running the counter over a path per track: paths[k][f] is track k+1's
// position in frame f (NaN x: not reported that frame).
std::string CrossingsOf(LineCounter& counter, const std::vector<std::vector<Eigen::Vector2d>>& paths) {
  std::string s;
  size_t frames = 0;
  for (const auto& p : paths) frames = std::max(frames, p.size());
  for (size_t f = 0; f < frames; ++f) {
    std::vector<Track> tracks;
    for (size_t k = 0; k < paths.size(); ++k) {
      if (f < paths[k].size() && !std::isnan(paths[k][f].x())) {
        tracks.push_back(At(static_cast<int64_t>(k + 1), paths[k][f].x(), paths[k][f].y()));
      }
    }
    const LineFrame result = counter.Update(static_cast<int64_t>(f), kDt * static_cast<double>(f), tracks);
    for (const LineEvent& e : result.events) {
      s += LineEventJsonLine(e) + "\n";
    }
  }
  return s;
}

LineOptions Line(std::string name, Eigen::Vector2d from_m, Eigen::Vector2d to_m, double hysteresis_m = 0,
                 bool once_per_track = false) {
  LineOptions l;
  l.name = std::move(name);
  l.from_m = from_m;
  l.to_m = to_m;
  l.hysteresis_m = hysteresis_m;
  l.once_per_track = once_per_track;
  return l;
}

// A gate along x = 0 from y = 0 to y = 2: "in" is towards -x (left of the upward line). The
// geometry's tests use no band and count every crossing; the defaults have their own tests.
LineCounter Gate(double hysteresis_m = 0, bool once_per_track = false) {
  Result<LineCounter> created = LineCounter::Create({Line("gate", {0, 0}, {0, 2}, hysteresis_m, once_per_track)});
  EXPECT_TRUE(created.ok()) << created.status().ToString();
  return std::move(created).value();
}

std::vector<Eigen::Vector2d> Walk(Eigen::Vector2d from, Eigen::Vector2d step, int n) {
  std::vector<Eigen::Vector2d> path;
  for (int k = 0; k < n; ++k) path.push_back(from + static_cast<double>(k) * step);
  return path;
}

TEST(SideOfLine, LeftIsPositiveRightNegativeAndTheLineItselfZero) {
  EXPECT_EQ(SideOfLine({0, 0}, {0, 2}, {-0.5, 1}), 1);
  EXPECT_EQ(SideOfLine({0, 0}, {0, 2}, {0.5, 1}), -1);
  EXPECT_EQ(SideOfLine({0, 0}, {0, 2}, {0, 1}), 0);
  EXPECT_EQ(SideOfLine({0, 0}, {0, 2}, {0, 7}), 0) << "the whole line, not only the segment";
  EXPECT_EQ(SideOfLine({0, 2}, {0, 0}, {-0.5, 1}), -1) << "reversing the line swaps the sides";
}

TEST(LineCounter, CountsCrossingsBothWaysWithCumulativeCounts) {
  LineCounter gate = Gate();
  // Track 1 walks from x = 1 to x = -1 at y = 1 (in), track 2 from x = -1 to x = 1 at y = 0.5
  // (out), then track 1 walks back (out): x = 1 - 0.3 f crosses 0 between frames 3 and 4.
  std::vector<Eigen::Vector2d> one = Walk({1, 1}, {-0.3, 0}, 8);
  const std::vector<Eigen::Vector2d> back = Walk({-1.1, 1}, {0.3, 0}, 8);
  one.insert(one.end(), back.begin(), back.end());
  const std::vector<Eigen::Vector2d> two = Walk({-1, 0.5}, {0.25, 0}, 9);
  EXPECT_EQ(CrossingsOf(gate, {one, two}),
            R"({"frame":4,"time_s":0.4,"line":"gate","track_id":1,"event":"cross","direction":"in","in":1,"out":0}
{"frame":5,"time_s":0.5,"line":"gate","track_id":2,"event":"cross","direction":"out","in":1,"out":1}
{"frame":12,"time_s":1.2,"line":"gate","track_id":1,"event":"cross","direction":"out","in":1,"out":2}
)");
  EXPECT_EQ(gate.counts(), (std::vector<LineCounts>{{1, 2}}));
}

TEST(LineCounter, TouchingTheLineAndTurningBackCountsNothing) {
  LineCounter gate = Gate();
  // To x = 0 exactly (on the line), then back to the right.
  const std::vector<Eigen::Vector2d> path = {{0.4, 1}, {0.2, 1}, {0, 1}, {0, 1.2}, {0.2, 1.2}, {0.4, 1.2}};
  EXPECT_EQ(CrossingsOf(gate, {path}), "");
  EXPECT_EQ(gate.counts()[0], (LineCounts{0, 0}));
}

TEST(LineCounter, StoppingOnTheLineThenGoingOnCountsOnce) {
  LineCounter gate = Gate();
  const std::vector<Eigen::Vector2d> path = {{0.4, 1}, {0, 1}, {0, 1}, {0, 1.1}, {-0.2, 1.1}, {-0.4, 1.1}};
  EXPECT_EQ(CrossingsOf(gate, {path}),
            R"({"frame":4,"time_s":0.4,"line":"gate","track_id":1,"event":"cross","direction":"in","in":1,"out":0}
)");
}

TEST(LineCounter, PassingBeyondTheEndsOrStartingOnTheFarSideCountsNothing) {
  LineCounter gate = Gate();
  // Crosses x = 0 at y = 3 and at y = -0.5 (off the segment), and a track first seen on the
  // left that stays there.
  const std::vector<Eigen::Vector2d> above = Walk({1, 3}, {-0.3, 0}, 8);
  const std::vector<Eigen::Vector2d> below = Walk({-1, -0.5}, {0.3, 0}, 8);
  const std::vector<Eigen::Vector2d> stays = Walk({-0.5, 1}, {0, 0.1}, 8);
  EXPECT_EQ(CrossingsOf(gate, {above, below, stays}), "");
}

TEST(LineCounter, AStepThroughAnEndpointCounts) {
  LineCounter gate = Gate();
  // The step from (1, 3) to (-1, 1) meets x = 0 at y = 2: the segment's end.
  EXPECT_EQ(CrossingsOf(gate, {{{1, 3}, {-1, 1}}}),
            R"({"frame":1,"time_s":0.1,"line":"gate","track_id":1,"event":"cross","direction":"in","in":1,"out":0}
)");
}

TEST(LineCounter, CoastingPredictionsNeverCrossAndEndedTracksAreForgotten) {
  LineCounter gate = Gate();
  EXPECT_TRUE(gate.Update(0, 0.0, {At(1, 0.5, 1)}).events.empty());
  // Predicted across the line while coasting: nothing; measured there later: the crossing.
  EXPECT_TRUE(gate.Update(1, 0.1, {At(1, -0.5, 1, /*coasting=*/true)}).events.empty());
  const LineFrame measured = gate.Update(2, 0.2, {At(1, -0.6, 1)});
  ASSERT_EQ(measured.events.size(), 1u);
  EXPECT_EQ(measured.events[0].direction, LineDirection::kIn);
  EXPECT_EQ(measured.counts, (std::vector<LineCounts>{{1, 0}}));
  // A track left out of a frame is forgotten: its next position starts afresh (the trackers
  // never report an id again once it is gone; this only shows the state is dropped).
  EXPECT_TRUE(gate.Update(3, 0.3, {At(2, 0.5, 1)}).events.empty());
  EXPECT_TRUE(gate.Update(4, 0.4, {}).events.empty());
  EXPECT_TRUE(gate.Update(5, 0.5, {At(2, -0.5, 1)}).events.empty());
  EXPECT_EQ(gate.counts()[0], (LineCounts{1, 0}));
}

TEST(LineCounter, LinesCountIndependentlyInTheirOrder) {
  Result<LineCounter> created = LineCounter::Create({Line("b", {0, 0}, {0, 2}), Line("a", {1, 2}, {1, 0})});
  ASSERT_TRUE(created.ok());
  LineCounter lines = std::move(created).value();
  // Line "a" points down: moving towards -x crosses it from left to right ("out").
  const std::string events = CrossingsOf(lines, {Walk({1.5, 1}, {-0.4, 0}, 6)});
  EXPECT_EQ(events,
            R"({"frame":2,"time_s":0.2,"line":"a","track_id":1,"event":"cross","direction":"out","in":0,"out":1}
{"frame":4,"time_s":0.4,"line":"b","track_id":1,"event":"cross","direction":"in","in":1,"out":0}
)");
}

TEST(LineCounter, TheDefaultsAreABandOf20CmAndOneCountPerTrackAndDirection) {
  const LineOptions defaults;
  EXPECT_EQ(defaults.hysteresis_m, 0.2);
  EXPECT_TRUE(defaults.once_per_track);
  EXPECT_EQ(SideOfLine({0, 0}, {0, 2}, {-0.15, 1}, 0.2), 0) << "inside the band";
  EXPECT_EQ(SideOfLine({0, 0}, {0, 2}, {-0.25, 1}, 0.2), 1);
  EXPECT_EQ(SideOfLine({0, 0}, {0, 2}, {0.25, 1}, 0.2), -1);
}

TEST(LineCounter, JitterOnTheLineInsideTheBandCountsNothing) {
  // Someone standing on the gate, their track jittering +-15 cm around x = 0.05 for 3 s, then
  // walking back to where they came from.
  std::vector<Eigen::Vector2d> path = Walk({1, 1}, {-0.2, 0}, 5);
  for (int k = 0; k < 30; ++k) path.push_back({0.05 + (k % 2 == 0 ? 0.15 : -0.15), 1 + 0.01 * k});
  const std::vector<Eigen::Vector2d> back = Walk({0.2, 1.3}, {0.2, 0}, 5);
  path.insert(path.end(), back.begin(), back.end());
  LineCounter banded = Gate(0.2);
  EXPECT_EQ(CrossingsOf(banded, {path}), "");
  LineCounter bare = Gate(0.0);
  EXPECT_EQ(CrossingsOf(bare, {path}).size() > 0, true) << "without the band every jitter across x = 0 counts";
  EXPECT_GE(bare.counts()[0].in, 10);
}

TEST(LineCounter, ABandDelaysACrossingUntilTheFarSide) {
  // 0.1 m per frame from x = 0.55: in the band (|x| <= 0.2) from frame 4 (0.15) to 7 (-0.15),
  // past it at frame 8 (-0.25).
  LineCounter gate = Gate(0.2);
  EXPECT_EQ(CrossingsOf(gate, {Walk({0.55, 1}, {-0.1, 0}, 10)}),
            R"({"frame":8,"time_s":0.8,"line":"gate","track_id":1,"event":"cross","direction":"in","in":1,"out":0}
)");
}

TEST(LineCounter, ATrackWanderingOverTheLineCountsOncePerDirection) {
  // In, out, in, out, in: 1.5 m swings across the gate.
  std::vector<Eigen::Vector2d> path;
  for (int swing = 0; swing < 5; ++swing) {
    const double from = swing % 2 == 0 ? 0.75 : -0.75;
    const std::vector<Eigen::Vector2d> leg = Walk({from, 1}, {from > 0 ? -0.25 : 0.25, 0}, 7);
    path.insert(path.end(), leg.begin(), leg.end());
  }
  LineCounter once = Gate(0.2, /*once_per_track=*/true);
  (void)CrossingsOf(once, {path});
  EXPECT_EQ(once.counts()[0], (LineCounts{1, 1}));
  LineCounter every = Gate(0.2, /*once_per_track=*/false);
  (void)CrossingsOf(every, {path});
  EXPECT_EQ(every.counts()[0], (LineCounts{3, 2}));
  // Another track is counted on its own.
  LineCounter two = Gate(0.2, true);
  (void)CrossingsOf(two, {path, Walk({1, 0.5}, {-0.25, 0}, 9)});
  EXPECT_EQ(two.counts()[0], (LineCounts{2, 1}));
}

TEST(LineCounter, CreateRefusesWhatValidateRefuses) {
  EXPECT_EQ(LineCounter::Create({Line("", {0, 0}, {1, 0})}).status().message(), "tracking.lines[0].name: expected a non-empty name");
  EXPECT_EQ(LineCounter::Create({Line("a", {0, 0}, {0, 0})}).status().message(),
            "tracking.lines[0].to: expected a point at least 1 mm from 'from', found 0 m from it");
  EXPECT_EQ(LineCounter::Create({Line("a", {0, 0}, {1, 0}), Line("a", {0, 1}, {1, 1})}).status().message(),
            "tracking.lines[1].name: duplicate line name 'a'");
  EXPECT_EQ(LineCounter::Create({Line("a", {0, 0}, {1, 0}, -0.1)}).status().message(),
            "tracking.lines[0].hysteresis_m: expected 0..2 m, found -0.1");
}

}  // namespace
}  // namespace occmap
