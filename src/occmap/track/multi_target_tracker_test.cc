#include "occmap/track/multi_target_tracker.h"

#include <gtest/gtest.h>

#include <map>
#include <set>

#include "occmap/track/test_tracking.h"

namespace occmap {
namespace {

using testing::FindTrack;
using testing::kNoisy;
using testing::NearestTrack;
using testing::RunTracker;
using testing::Walk;

constexpr double kDt = 0.1;  // 10 frames per second

MultiTargetTracker MakeTracker(const TrackerOptions& options = {}) {
  Result<MultiTargetTracker> tracker = MultiTargetTracker::Create(options);
  EXPECT_TRUE(tracker.ok()) << tracker.status().ToString();
  return std::move(tracker).value();
}

Eigen::Vector2d Position(const Track& t) { return {t.x_m, t.y_m}; }

// Two walkers: checks that from `from_frame` on, the track that was nearest each walker at
// from_frame stays within max_error_m of that walker in every frame (identities kept).
void ExpectIdentitiesKept(const std::vector<std::vector<Track>>& tracks, const Walk& a, const Walk& b,
                          int from_frame, double max_error_m) {
  const Track* ta = NearestTrack(tracks[from_frame], a.At(kDt * from_frame));
  const Track* tb = NearestTrack(tracks[from_frame], b.At(kDt * from_frame));
  ASSERT_TRUE(ta && tb);
  const int64_t id_a = ta->id, id_b = tb->id;
  ASSERT_NE(id_a, id_b);
  for (size_t f = static_cast<size_t>(from_frame); f < tracks.size(); ++f) {
    const double t = kDt * static_cast<double>(f);
    const Track* now_a = FindTrack(tracks[f], id_a);
    const Track* now_b = FindTrack(tracks[f], id_b);
    ASSERT_TRUE(now_a && now_b) << "frame " << f << ": a track ended";
    EXPECT_LT((Position(*now_a) - a.At(t)).norm(), max_error_m) << "frame " << f << ", walker A";
    EXPECT_LT((Position(*now_b) - b.At(t)).norm(), max_error_m) << "frame " << f << ", walker B";
    EXPECT_EQ(tracks[f].size(), 2u) << "frame " << f;
  }
}

struct CrossingCase {
  const char* name;
  Walk a, b;
  int frames;
};

TEST(MultiTargetTracker, TwoPeopleCrossingPathsKeepTheirIdentitiesThroughMergedBlobs) {
  const CrossingCase cases[] = {
      // Perpendicular paths meeting at (4, 3) at t = 2.5 s.
      {"perpendicular", {{1.0, 3.0}, {1.2, 0.0}}, {{4.0, 0.0}, {0.0, 1.2}}, 45},
      // Head-on, 0.15 m apart sideways: the footprints overlap almost entirely.
      {"head-on", {{1.0, 3.0}, {1.2, 0.0}}, {{7.0, 3.15}, {-1.2, 0.0}}, 45},
      // Paths at 40 degrees, walkers side by side at the crossing (relative speed 0.85 m/s).
      {"40 degrees", {{1.0, 2.0}, {1.2, 0.44}}, {{1.0, 4.2}, {1.2, -0.44}}, 48},
  };
  for (const CrossingCase& c : cases) {
    SCOPED_TRACE(c.name);
    for (unsigned seed : {1u, 2u, 3u}) {
      SCOPED_TRACE(seed);
      MultiTargetTracker tracker = MakeTracker();
      std::vector<int> blob_counts;
      const auto tracks = RunTracker(
          tracker, c.frames, kDt, [&](int f) { return std::vector<Eigen::Vector2d>{c.a.At(kDt * f), c.b.At(kDt * f)}; },
          kNoisy, seed, 0.25, &blob_counts);
      EXPECT_GE(std::count(blob_counts.begin(), blob_counts.end(), 1), 3) << "the blobs should merge at the crossing";
      ExpectIdentitiesKept(tracks, c.a, c.b, 4, 0.3);
      EXPECT_EQ(tracker.confirmed_count(), 2);
    }
  }
}

TEST(MultiTargetTracker, BirthNeedsConfirmHitsBeforeATrackIsReported) {
  MultiTargetTracker tracker = MakeTracker();  // confirm_hits 3 of confirm_frames 5
  const Walk walk{{1.0, 3.0}, {1.0, 0.0}};
  const auto tracks = RunTracker(tracker, 6, kDt, [&](int f) { return std::vector<Eigen::Vector2d>{walk.At(kDt * f)}; });
  EXPECT_TRUE(tracks[0].empty());
  EXPECT_TRUE(tracks[1].empty());
  ASSERT_EQ(tracks[2].size(), 1u);
  EXPECT_EQ(tracks[2][0].id, 1);
  EXPECT_EQ(tracks[2][0].hits, 3);
  EXPECT_EQ(tracks[2][0].object_class, "person");
  EXPECT_NEAR(tracks[5][0].x_m, walk.At(0.5).x(), 0.05);
  EXPECT_NEAR(tracks[5][0].vx_mps, 1.0, 0.3);
}

TEST(MultiTargetTracker, SingleFrameFalseBlobNeverBecomesAConfirmedTrack) {
  MultiTargetTracker tracker = MakeTracker();
  const Walk walk{{1.0, 3.0}, {1.0, 0.0}};
  const Eigen::Vector2d ghost(6.0, 1.0);
  const auto tracks = RunTracker(tracker, 30, kDt, [&](int f) {
    std::vector<Eigen::Vector2d> people{walk.At(kDt * f)};
    // A ghost for one frame at 10, and flickering for 2 frames of 5 at 20 and 23.
    if (f == 10 || f == 20 || f == 23) people.push_back(ghost);
    return people;
  });
  for (size_t f = 0; f < tracks.size(); ++f) {
    for (const Track& t : tracks[f]) EXPECT_GT((Position(t) - ghost).norm(), 1.0) << "frame " << f;
  }
  EXPECT_EQ(tracker.confirmed_count(), 1);
  EXPECT_EQ(tracker.tentative_count(), 0);
}

TEST(MultiTargetTracker, TrackCoastsThroughAHalfSecondMissAndKeepsItsId) {
  MultiTargetTracker tracker = MakeTracker();  // max_coast_s 1.0
  const Walk walk{{1.0, 3.0}, {1.0, 0.3}};
  // No detection at frames 15-19 (0.5 s): last seen at 1.4 s, back at 2.0 s.
  const auto tracks = RunTracker(tracker, 40, kDt, [&](int f) {
    return f >= 15 && f < 20 ? std::vector<Eigen::Vector2d>{} : std::vector<Eigen::Vector2d>{walk.At(kDt * f)};
  }, kNoisy, 5);
  for (int f = 2; f < 40; ++f) {
    ASSERT_EQ(tracks[f].size(), 1u) << "frame " << f;
    const Track& t = tracks[f][0];
    EXPECT_EQ(t.id, 1) << "frame " << f;
    EXPECT_EQ(t.coasting, f >= 15 && f < 20) << "frame " << f;
    EXPECT_LT((Position(t) - walk.At(kDt * f)).norm(), 0.15) << "frame " << f;
  }
  EXPECT_NEAR(tracks[19][0].time_since_update_s, 0.5, 1e-9);
}

TEST(MultiTargetTracker, TrackEndsOnceMaxCoastHasPassedSinceItsLastDetection) {
  TrackerOptions options;
  options.max_coast_s = 1.0;
  MultiTargetTracker tracker = MakeTracker(options);
  const Walk walk{{1.0, 3.0}, {1.0, 0.0}};
  // Last detection at frame 14 (1.4 s).
  const auto tracks = RunTracker(tracker, 30, kDt, [&](int f) {
    return f < 15 ? std::vector<Eigen::Vector2d>{walk.At(kDt * f)} : std::vector<Eigen::Vector2d>{};
  });
  ASSERT_EQ(tracks[24].size(), 1u) << "1.0 s after the last detection the track still coasts";
  EXPECT_TRUE(tracks[24][0].coasting);
  EXPECT_NEAR(tracks[24][0].x_m, walk.At(2.4).x(), 0.1);
  EXPECT_TRUE(tracks[25].empty()) << "1.1 s after it has ended";
  // A person appearing there later is a new track.
  const Eigen::Vector2d later = walk.At(2.4);
  for (int f = 30; f < 35; ++f) {
    const OccupancyMap map = testing::FloorWithDiscs(testing::TestGrid(), {later});
    auto now = tracker.Update(testing::DetectObjects(map), kDt * f);
    ASSERT_TRUE(now.ok());
    for (const Track& t : *now) EXPECT_EQ(t.id, 2);
  }
}

TEST(MultiTargetTracker, IdsAreNeverReused) {
  MultiTargetTracker tracker = MakeTracker();
  // People come and go at the same two places: each is there for 1 s, then away for 1.5 s.
  const auto tracks = RunTracker(tracker, 130, kDt, [&](int f) {
    std::vector<Eigen::Vector2d> people;
    if (f % 25 < 10) people.emplace_back(2.0, 3.0);
    if ((f + 12) % 25 < 10) people.emplace_back(5.0, 3.0);
    return people;
  }, kNoisy, 9);
  std::map<int64_t, std::pair<size_t, size_t>> span;  // id -> first and last frame
  std::set<int64_t> seen_before;
  for (size_t f = 0; f < tracks.size(); ++f) {
    for (const Track& t : tracks[f]) {
      EXPECT_GT(t.id, 0);
      auto [it, is_new] = span.emplace(t.id, std::make_pair(f, f));
      if (!is_new) {
        EXPECT_EQ(it->second.second, f - 1) << "id " << t.id << " came back at frame " << f;
        it->second.second = f;
      }
    }
  }
  // 6 visits at (2, 3) (frames 0, 25, ..., 125) and 5 at (5, 3): 11 tracks, ids 1..11 in
  // order of appearance.
  ASSERT_EQ(span.size(), 11u);
  EXPECT_EQ(span.begin()->first, 1);
  EXPECT_EQ(span.rbegin()->first, 11);
  size_t previous_first = 0;
  for (const auto& [id, frames] : span) {
    EXPECT_GE(frames.first, previous_first) << "id " << id;
    previous_first = frames.first;
  }
}

TEST(MultiTargetTracker, ClassesFollowTheFootprintAreaWithHysteresis) {
  TrackerOptions options;
  options.classes = {{"robot", 0.14}, {"person", 0.45}, {"cart"}};
  MultiTargetTracker tracker = MakeTracker(options);
  // A still object: radius 0.24 m (0.18 m^2, person), then 0.2 m (0.126 m^2: below 0.14 but
  // within the 15% band, still a person), then 0.17 m (0.09 m^2: robot).
  const Eigen::Vector2d at(3.0, 3.0);
  std::vector<std::string> classes;
  for (int f = 0; f < 60; ++f) {
    const double radius_m = f < 20 ? 0.24 : f < 40 ? 0.2 : 0.17;
    const OccupancyMap map = testing::FloorWithDiscs(testing::TestGrid(), {at}, radius_m);
    auto tracks = tracker.Update(testing::DetectObjects(map), kDt * f);
    ASSERT_TRUE(tracks.ok());
    classes.push_back(tracks->empty() ? "" : tracks->front().object_class);
  }
  EXPECT_EQ(classes[19], "person");
  EXPECT_EQ(classes[39], "person") << "inside the hysteresis band";
  EXPECT_EQ(classes[59], "robot");
  EXPECT_EQ(tracker.confirmed_count(), 1);
}

TEST(MultiTargetTracker, FrameTimesMustIncrease) {
  MultiTargetTracker tracker = MakeTracker();
  const OccupancyMap map = testing::FloorWithDiscs(testing::TestGrid(), {{2.0, 2.0}});
  const ObjectFrame frame = testing::DetectObjects(map);
  ASSERT_TRUE(tracker.Update(frame, 1.0).ok());
  const auto again = tracker.Update(frame, 1.0);
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.status().message(), "tracker: frame time 1 s is not after the previous frame's 1 s");
  EXPECT_TRUE(tracker.Update(frame, 1.1).ok());
}

TEST(MultiTargetTracker, TracksDetectionsFromADetectorWithoutGroups) {
  // Positions, areas and spreads only (as a multi-view person detector gives them): tracked as
  // any other; two close predictions never cut anything (no group to guide).
  MultiTargetTracker tracker = MakeTracker();
  const Walk a{{2.0, 3.0}, {1.0, 0.0}}, b{{2.0, 3.6}, {1.0, 0.0}};
  std::vector<Track> last;
  for (int f = 0; f < 20; ++f) {
    ObjectFrame frame;
    frame.grid = testing::TestGrid();
    for (const Walk& w : {a, b}) {
      Detection d;
      d.x_m = w.At(kDt * f).x();
      d.y_m = w.At(kDt * f).y();
      d.area_m2 = 0.2;
      d.spread_m2 = 0.01 * Eigen::Matrix2d::Identity();
      frame.detections.push_back(d);
    }
    auto tracks = tracker.Update(frame, kDt * f);
    ASSERT_TRUE(tracks.ok());
    last = *tracks;
    for (const Detection& d : tracker.detections()) EXPECT_FALSE(d.guided);
  }
  ASSERT_EQ(last.size(), 2u);
  EXPECT_LT((Position(*NearestTrack(last, a.At(1.9))) - a.At(1.9)).norm(), 0.05);
  EXPECT_LT((Position(*NearestTrack(last, b.At(1.9))) - b.At(1.9)).norm(), 0.05);
}

TEST(MultiTargetTracker, AClassHintThatNamesAClassWinsOverTheArea) {
  TrackerOptions options;
  options.classes = {{"robot", 0.14}, {"person", 0.45}, {"cart"}};
  MultiTargetTracker tracker = MakeTracker(options);
  std::vector<Track> last;
  for (int f = 0; f < 5; ++f) {
    // 0.3 m^2 would be a person; the detector says robot (and "dog", no class here, is ignored).
    ObjectFrame frame;
    frame.grid = testing::TestGrid();
    for (const auto& [x_m, hint] : {std::pair<double, const char*>{2.0, "robot"}, {5.0, "dog"}}) {
      Detection d;
      d.x_m = x_m;
      d.y_m = 2.0;
      d.area_m2 = 0.3;
      d.class_hint = hint;
      frame.detections.push_back(d);
    }
    auto tracks = tracker.Update(frame, kDt * f);
    ASSERT_TRUE(tracks.ok());
    last = *tracks;
  }
  ASSERT_EQ(last.size(), 2u);
  EXPECT_EQ(NearestTrack(last, {2.0, 2.0})->object_class, "robot");
  EXPECT_EQ(NearestTrack(last, {5.0, 2.0})->object_class, "person");
}

TEST(MultiTargetTracker, CreateRefusesInvalidOptions) {
  TrackerOptions options;
  options.max_speed_mps = 0;
  const auto tracker = MultiTargetTracker::Create(options);
  ASSERT_FALSE(tracker.ok());
  EXPECT_EQ(tracker.status().message(), "tracking.max_speed_mps: expected a number > 0, found 0");
}

}  // namespace
}  // namespace occmap
