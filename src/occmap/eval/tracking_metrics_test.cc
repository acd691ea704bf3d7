#include "occmap/eval/tracking_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <vector>

namespace occmap {
namespace {

using V = Eigen::Vector2d;
using Items = std::vector<IdPosition>;

// Far-apart places: anything at A is more than the 0.5 m gate from anything at B.
const V kA(0, 0), kB(5, 0);

TEST(TrackingEvaluator, PerfectTrackingScoresOneEverywhere) {
  // Two objects followed by two tracks over 3 frames, exactly: 6 TP, nothing else.
  TrackingEvaluator evaluator;
  for (int f = 0; f < 3; ++f) evaluator.AddFrame(Items{{1, kA}, {2, kB}}, Items{{7, kA}, {8, kB}});
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.frames, 3);
  EXPECT_EQ(m.tp, 6);
  EXPECT_EQ(m.fp + m.fn + m.id_switches + m.fragmentations, 0);
  EXPECT_DOUBLE_EQ(m.mota, 1.0);
  EXPECT_DOUBLE_EQ(m.motp_m, 0.0);
  EXPECT_DOUBLE_EQ(m.motp_closeness, 1.0);
  EXPECT_EQ(m.idtp, 6);
  EXPECT_DOUBLE_EQ(m.idf1, 1.0);
  EXPECT_EQ(m.mostly_tracked, 2);
  EXPECT_EQ(m.gt_trajectories, 2);
  EXPECT_EQ(m.track_trajectories, 2);
}

TEST(TrackingEvaluator, AnIdSwitchIsCountedExactlyOnce) {
  // One object at A over 4 frames; track 10 covers frames 0-1, track 20 frames 2-3.
  // Frame 2 matches the object to 20 after 10: one switch; frame 3 keeps 20: none.
  // MOTA = 1 - (0 + 0 + 1) / 4 = 0.75.
  // Identity: the object pairs with one track for 2 frames: IDTP 2, IDFN 4 - 2 = 2,
  // IDFP 4 - 2 = 2, IDF1 = 2 * 2 / (4 + 4) = 0.5.
  TrackingEvaluator evaluator;
  evaluator.AddFrame(Items{{1, kA}}, Items{{10, kA}});
  evaluator.AddFrame(Items{{1, kA}}, Items{{10, kA}});
  evaluator.AddFrame(Items{{1, kA}}, Items{{20, kA}});
  evaluator.AddFrame(Items{{1, kA}}, Items{{20, kA}});
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.id_switches, 1);
  EXPECT_EQ(m.fragmentations, 0);
  EXPECT_DOUBLE_EQ(m.mota, 0.75);
  EXPECT_EQ(m.idtp, 2);
  EXPECT_EQ(m.idfn, 2);
  EXPECT_EQ(m.idfp, 2);
  EXPECT_DOUBLE_EQ(m.idf1, 0.5);
}

TEST(TrackingEvaluator, KeepsThePreviousTrackWhileItIsWithinTheThreshold) {
  // Frame 0: object at the origin, track 10 at 0.3 m: matched.
  // Frame 1: track 10 at 0.4 m and track 20 exactly on the object. The Hungarian method alone
  // would take 20 (0 m); CLEAR MOT keeps 10 (still within 0.5 m): no switch, 20 is an FP.
  // MOTA = 1 - (0 + 1 + 0) / 2 = 0.5; MOTP = (0.3 + 0.4) / 2 = 0.35 m;
  // MOTP' = ((1 - 0.3/0.5) + (1 - 0.4/0.5)) / 2 = (0.4 + 0.2) / 2 = 0.3.
  TrackingEvaluator evaluator;
  evaluator.AddFrame(Items{{1, V(0, 0)}}, Items{{10, V(0.3, 0)}});
  evaluator.AddFrame(Items{{1, V(0, 0)}}, Items{{10, V(0.4, 0)}, {20, V(0, 0)}});
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.id_switches, 0);
  EXPECT_EQ(m.tp, 2);
  EXPECT_EQ(m.fp, 1);
  EXPECT_DOUBLE_EQ(m.mota, 0.5);
  EXPECT_NEAR(m.motp_m, 0.35, 1e-12);
  EXPECT_NEAR(m.motp_closeness, 0.3, 1e-12);
}

TEST(TrackingEvaluator, HandWorkedSwapGivesIdf1OneHalfAndTwoSwitches) {
  // Objects 1 at A and 2 at B over 4 frames. Track 7 is at A in frames 0-1 and at B in 2-3;
  // track 8 the other way round. Every frame matches both objects (8 TP); in frame 2 each
  // object's previous track is at the other place, so both switch: IDSW 2,
  // MOTA = 1 - 2 / 8 = 0.75.
  // Frames within the gate: (1, 7) = 2, (1, 8) = 2, (2, 7) = 2, (2, 8) = 2; any pairing gives
  // IDTP = 4: IDF1 = 2 * 4 / (8 + 8) = 0.5, IDP = 4 / 8, IDR = 4 / 8.
  TrackingEvaluator evaluator;
  for (int f = 0; f < 4; ++f) {
    const bool swapped = f >= 2;
    evaluator.AddFrame(Items{{1, kA}, {2, kB}}, Items{{7, swapped ? kB : kA}, {8, swapped ? kA : kB}});
  }
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.tp, 8);
  EXPECT_EQ(m.id_switches, 2);
  EXPECT_DOUBLE_EQ(m.mota, 0.75);
  EXPECT_EQ(m.idtp, 4);
  EXPECT_DOUBLE_EQ(m.idf1, 0.5);
  EXPECT_DOUBLE_EQ(m.idp, 0.5);
  EXPECT_DOUBLE_EQ(m.idr, 0.5);
}

TEST(TrackingEvaluator, IdentityMatchingIsGlobalNotGreedy) {
  // Objects 1 at A and 2 at B over frames 0-4. Track 7 is at A in frames 0-2 and at B in 3-4;
  // track 8 exists only in frames 3-4, at A.
  // Frames within the gate: (1, 7) = 3, (1, 8) = 2, (2, 7) = 2, (2, 8) = 0.
  // Greedy (largest first) pairs 1-7 (3) and then 2-8 (0): IDTP 3. The optimum pairs 1-8 and
  // 2-7: IDTP 2 + 2 = 4. N_gt = 10, N_pred = 5 + 2 = 7:
  //   IDF1 = 2 * 4 / 17, IDP = 4 / 7, IDR = 4 / 10, IDFN = 6, IDFP = 3.
  // CLEAR MOT: frames 0-2 match 1-7 and miss object 2 (FN 3). Frame 3: 7 has moved to B, so
  // object 1 takes 8 (a switch) and object 2 takes 7 (its first match, no switch). Frame 4
  // keeps both. TP 7, FP 0, IDSW 1: MOTA = 1 - (3 + 0 + 1) / 10 = 0.6.
  // Object 1 is matched 5/5 frames (mostly tracked), object 2 2/5 (partially tracked).
  TrackingEvaluator evaluator;
  for (int f = 0; f < 5; ++f) {
    Items tracks = {{7, f < 3 ? kA : kB}};
    if (f >= 3) tracks.push_back({8, kA});
    evaluator.AddFrame(Items{{1, kA}, {2, kB}}, tracks);
  }
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.idtp, 4);
  EXPECT_EQ(m.idfn, 6);
  EXPECT_EQ(m.idfp, 3);
  EXPECT_DOUBLE_EQ(m.idf1, 8.0 / 17.0);
  EXPECT_DOUBLE_EQ(m.idp, 4.0 / 7.0);
  EXPECT_DOUBLE_EQ(m.idr, 0.4);
  EXPECT_EQ(m.tp, 7);
  EXPECT_EQ(m.fn, 3);
  EXPECT_EQ(m.fp, 0);
  EXPECT_EQ(m.id_switches, 1);
  EXPECT_DOUBLE_EQ(m.mota, 0.6);
  EXPECT_EQ(m.mostly_tracked, 1);
  EXPECT_EQ(m.partially_tracked, 1);
  EXPECT_EQ(m.mostly_lost, 0);
}

TEST(TrackingEvaluator, FragmentationCountsEachInterruptionThatEndsInAMatch) {
  // Object 1 over frames 0-6, matched (M) or missed (-): M M - M - M -.
  // Interruptions followed by a match: after frame 1 and after frame 3: 2. The final miss
  // (frame 6) is not followed by a match and does not count.
  TrackingEvaluator evaluator;
  const bool matched[] = {true, true, false, true, false, true, false};
  for (bool on : matched) evaluator.AddFrame(Items{{1, kA}}, on ? Items{{5, kA}} : Items{});
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.fragmentations, 2);
  EXPECT_EQ(m.id_switches, 0);
  EXPECT_EQ(m.fn, 3);
}

TEST(TrackingEvaluator, SwitchAfterAGapIsComparedWithTheLastMatch) {
  // Object matched to 10 in frame 0, missed in frame 1, matched to 20 in frame 2: one switch
  // (against the last match, two frames back) and one fragmentation.
  TrackingEvaluator evaluator;
  evaluator.AddFrame(Items{{1, kA}}, Items{{10, kA}});
  evaluator.AddFrame(Items{{1, kA}}, Items{});
  evaluator.AddFrame(Items{{1, kA}}, Items{{20, kA}});
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.id_switches, 1);
  EXPECT_EQ(m.fragmentations, 1);
}

TEST(TrackingEvaluator, MotaIsNegativeWithManyFalseTracks) {
  // One object, matched; three tracks far away: MOTA = 1 - (0 + 3 + 0) / 1 = -2.
  TrackingEvaluator evaluator;
  evaluator.AddFrame(Items{{1, kA}}, Items{{1, kA}, {2, kB}, {3, V(0, 5)}, {4, V(5, 5)}});
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.fp, 3);
  EXPECT_DOUBLE_EQ(m.mota, -2.0);
}

TEST(TrackingEvaluator, MostlyTrackedAndMostlyLostFollowTheRatios) {
  // Five frames. Object 1 matched in 4 (0.8: mostly tracked), object 2 in 1 (0.2: not below
  // 0.2, so partially tracked), object 3 in none (mostly lost).
  TrackingEvaluator evaluator;
  const V c(10, 10);
  for (int f = 0; f < 5; ++f) {
    Items tracks;
    if (f < 4) tracks.push_back({1, kA});
    if (f == 0) tracks.push_back({2, kB});
    evaluator.AddFrame(Items{{1, kA}, {2, kB}, {3, c}}, tracks);
  }
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.mostly_tracked, 1);
  EXPECT_EQ(m.partially_tracked, 1);
  EXPECT_EQ(m.mostly_lost, 1);
}

TEST(TrackingEvaluator, EmptySequenceLeavesRatiosUndefined) {
  const TrackingMetrics m = TrackingEvaluator().Metrics();
  EXPECT_EQ(m.frames, 0);
  EXPECT_TRUE(std::isnan(m.mota));
  EXPECT_TRUE(std::isnan(m.motp_m));
  EXPECT_TRUE(std::isnan(m.idf1));
  EXPECT_TRUE(std::isnan(m.idp));
  EXPECT_TRUE(std::isnan(m.idr));
}

TEST(TrackingEvaluator, TracksWithoutGroundTruthAreFalsePositivesAndIdf1Zero) {
  TrackingEvaluator evaluator;
  evaluator.AddFrame(Items{}, Items{{1, kA}});
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.fp, 1);
  EXPECT_TRUE(std::isnan(m.mota));
  EXPECT_DOUBLE_EQ(m.idf1, 0.0);
  EXPECT_DOUBLE_EQ(m.idp, 0.0);
  EXPECT_TRUE(std::isnan(m.idr));
}

TEST(TrackingEvaluator, GroundTruthFrameUsesTheClassFilterAndTrackRecords) {
  // A person and a robot; people only. The track on the robot is an FP, the person missed.
  EvalOptions options;
  options.object_classes = {"person"};
  GroundTruthFrame frame;
  frame.objects.push_back({.id = 1, .object_class = "person", .x_m = 0, .y_m = 0, .footprint_m = {}});
  frame.objects.push_back({.id = 2, .object_class = "robot", .x_m = 5, .y_m = 0, .footprint_m = {}});
  TrackingEvaluator evaluator(options);
  evaluator.AddFrame(frame, std::vector<TrackRecord>{{.id = 4, .x_m = 5, .y_m = 0, .vx_mps = 0, .vy_mps = 0, .object_class = ""}});
  const TrackingMetrics m = evaluator.Metrics();
  EXPECT_EQ(m.gt, 1);
  EXPECT_EQ(m.fp, 1);
  EXPECT_EQ(m.fn, 1);
}

TEST(TrackingEvaluator, IdentityTruePositivesEqualTheBruteForceOptimumOnRandomSequences) {
  // Random short sequences on a few spots (0, 0.4, 1 and 3 m along x, so that some pairs are
  // within 0.5 m of each other and some are not). IDTP must equal the best pairing of object
  // ids with track ids found by trying every injection.
  std::mt19937 rng(7);
  const double spots[] = {0.0, 0.4, 1.0, 3.0};
  for (int trial = 0; trial < 200; ++trial) {
    std::map<std::pair<int64_t, int64_t>, int64_t> within;
    std::set<int64_t> gt_ids, track_ids;
    TrackingEvaluator evaluator;
    for (int f = 0; f < 6; ++f) {
      Items gt, tracks;
      for (int64_t id = 1; id <= 3; ++id) {
        if (rng() % 4 != 0) gt.push_back({id, V(spots[rng() % 4], 0)});
      }
      for (int64_t id = 10; id <= 13; ++id) {
        if (rng() % 3 != 0) tracks.push_back({id, V(spots[rng() % 4], 0)});
      }
      for (const IdPosition& g : gt) {
        gt_ids.insert(g.id);
        for (const IdPosition& h : tracks) {
          if ((g.position_m - h.position_m).norm() <= 0.5) ++within[{g.id, h.id}];
        }
      }
      for (const IdPosition& h : tracks) track_ids.insert(h.id);
      evaluator.AddFrame(gt, tracks);
    }
    const std::vector<int64_t> gs(gt_ids.begin(), gt_ids.end()), hs(track_ids.begin(), track_ids.end());
    std::vector<char> used(hs.size(), 0);
    std::function<int64_t(size_t)> best = [&](size_t k) -> int64_t {
      if (k == gs.size()) return 0;
      int64_t result = best(k + 1);  // object gs[k] unpaired
      for (size_t h = 0; h < hs.size(); ++h) {
        if (used[h]) continue;
        used[h] = 1;
        const auto it = within.find({gs[k], hs[h]});
        result = std::max(result, (it == within.end() ? 0 : it->second) + best(k + 1));
        used[h] = 0;
      }
      return result;
    };
    const TrackingMetrics m = evaluator.Metrics();
    ASSERT_EQ(m.idtp, best(0)) << "trial " << trial;
    ASSERT_EQ(m.idfn + m.idtp, m.gt);
    ASSERT_EQ(m.idfp + m.idtp, m.predictions);
  }
}

TEST(TrackingEvaluatorDeathTest, DuplicateTrackIdInAFrameIsABug) {
  TrackingEvaluator evaluator;
  EXPECT_DEATH(evaluator.AddFrame(Items{}, Items{{3, kA}, {3, kB}}), "track id 3 appears twice in one frame");
}

}  // namespace
}  // namespace occmap
