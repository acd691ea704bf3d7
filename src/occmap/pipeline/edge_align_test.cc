#include "occmap/pipeline/edge_align.h"

#include <gtest/gtest.h>

namespace occmap {
namespace {

using Clock = FrameSetAligner::Clock;
using std::chrono::milliseconds;

EdgeMessage Message(uint32_t camera, int64_t frame, double t) {
  EdgeMessage m;
  m.camera = camera;
  m.frame = frame;
  m.timestamp_s = t;
  return m;
}

std::vector<int> Cameras(const AlignedSet& s) {
  std::vector<int> out;
  for (size_t c = 0; c < s.cameras.size(); ++c) {
    if (s.cameras[c]) out.push_back(static_cast<int>(c));
  }
  return out;
}

AlignOptions Options(FrameSync sync) {
  AlignOptions o;
  o.sync = sync;
  o.tolerance_s = 0.03;
  o.latency_budget_s = 0.2;
  o.dead_after_s = 1.0;
  o.start_wait_s = 5.0;
  return o;
}

TEST(FrameSetAligner, ByIndexWaitsForEveryCameraThenFusesInOrder) {
  const auto t0 = Clock::now();
  FrameSetAligner a(3, Options(FrameSync::kIndex), t0);
  a.Add(Message(0, 1, 0.1), t0);
  a.Add(Message(0, 0, 0.0), t0);  // out of order: still the oldest first
  a.Add(Message(1, 0, 0.0), t0);
  EXPECT_FALSE(a.Next(t0 + milliseconds(10)));  // camera 2 not heard yet
  a.Add(Message(2, 0, 0.0), t0);
  auto s = a.Next(t0 + milliseconds(10));
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frame, 0);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0, 1, 2}));
  EXPECT_FALSE(a.Next(t0 + milliseconds(10)));  // frame 1: cameras 1 and 2 undecided
  a.Add(Message(1, 1, 0.1), t0);
  a.Add(Message(2, 2, 0.2), t0);  // camera 2's frame 1 is lost: a later one decides it
  // Camera 0's frame 1 came before its frame 0 (as a copy published early would): it counts
  // once the camera's stream is past it.
  EXPECT_FALSE(a.Next(t0 + milliseconds(10)));
  a.Add(Message(0, 2, 0.2), t0);
  s = a.Next(t0 + milliseconds(10));
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frame, 1);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0, 1}));
  EXPECT_EQ(a.left_out(2), 1);
}

TEST(FrameSetAligner, TheBudgetLeavesALateCameraOutAndDropsItsMessage) {
  const auto t0 = Clock::now();
  FrameSetAligner a(2, Options(FrameSync::kIndex), t0);
  a.Add(Message(0, 0, 0), t0);
  a.Add(Message(1, 0, 0), t0);
  ASSERT_TRUE(a.Next(t0));
  a.Add(Message(0, 1, 0), t0 + milliseconds(100));
  EXPECT_FALSE(a.Next(t0 + milliseconds(250)));  // 150 ms of the 200 ms budget
  auto s = a.Next(t0 + milliseconds(301));
  ASSERT_TRUE(s);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0}));
  a.Add(Message(1, 1, 0), t0 + milliseconds(310));  // too late for its set
  EXPECT_EQ(a.late(), 1);
  EXPECT_TRUE(a.idle());
}

TEST(FrameSetAligner, ADeadCameraHoldsNothingUpAndRejoinsWhenItSendsAgain) {
  const auto t0 = Clock::now();
  AlignOptions o = Options(FrameSync::kIndex);
  o.latency_budget_s = 100;  // only the dead rule may release a set
  FrameSetAligner a(2, o, t0);
  a.Add(Message(0, 0, 0), t0);
  a.Add(Message(1, 0, 0), t0);
  ASSERT_TRUE(a.Next(t0));
  a.Add(Message(0, 1, 0), t0 + milliseconds(500));
  EXPECT_FALSE(a.Next(t0 + milliseconds(900)));
  EXPECT_TRUE(a.alive(1, t0 + milliseconds(900)));
  auto s = a.Next(t0 + milliseconds(1001));  // camera 1 silent for 1 s: dead
  ASSERT_TRUE(s);
  EXPECT_FALSE(a.alive(1, t0 + milliseconds(1001)));
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0}));
  a.Add(Message(0, 2, 0), t0 + milliseconds(1100));
  s = a.Next(t0 + milliseconds(1100));
  ASSERT_TRUE(s);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0}));
  a.Add(Message(1, 3, 0), t0 + milliseconds(1200));  // back
  EXPECT_TRUE(a.alive(1, t0 + milliseconds(1200)));
  EXPECT_FALSE(a.Next(t0 + milliseconds(1200)));  // frame 3 waits for camera 0 again
  a.Add(Message(0, 3, 0), t0 + milliseconds(1210));
  s = a.Next(t0 + milliseconds(1210));
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frame, 3);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0, 1}));
}

TEST(FrameSetAligner, AfterAnOutageOfTheFusesLinkTheCamerasAreWaitedForAgain) {
  const auto t0 = Clock::now();
  AlignOptions o = Options(FrameSync::kIndex);
  FrameSetAligner a(2, o, t0);
  a.Add(Message(0, 0, 0), t0);
  a.Add(Message(1, 0, 0), t0);
  ASSERT_TRUE(a.Next(t0));
  a.Add(Message(0, 1, 0), t0 + milliseconds(100));
  // The broker away for 2 s: camera 1 silent past dead_after_s (1 s) and the budget (0.2 s) spent.
  const auto back = t0 + milliseconds(2100);
  a.Resume(back);
  EXPECT_TRUE(a.alive(1, back));
  EXPECT_FALSE(a.Next(back));  // frame 1 waits for camera 1 again, the budget counted from now
  EXPECT_FALSE(a.Next(back + milliseconds(150)));
  a.Add(Message(1, 1, 0), back + milliseconds(160));  // sent again by its edge
  auto s = a.Next(back + milliseconds(160));
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frame, 1);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0, 1}));
  EXPECT_EQ(a.late(), 0);
  // Without word from camera 1 the budget from the resume still releases the set.
  a.Add(Message(0, 2, 0), back + milliseconds(200));
  a.Resume(back + milliseconds(300));
  EXPECT_FALSE(a.Next(back + milliseconds(450)));
  s = a.Next(back + milliseconds(501));
  ASSERT_TRUE(s);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0}));
}

TEST(FrameSetAligner, ByTimestampGroupsFramesWithinTheTolerance) {
  const auto t0 = Clock::now();
  FrameSetAligner a(3, Options(FrameSync::kTimestamp), t0);
  // Unrelated frame indexes; times 100 ms apart, camera 1 20 ms behind, camera 2 45 ms behind
  // (outside the 30 ms tolerance of camera 0's frames, inside it of camera 1's).
  for (int k = 0; k < 3; ++k) {
    a.Add(Message(0, 500 + k, 10.0 + 0.1 * k), t0);
    a.Add(Message(1, 7 + k, 10.02 + 0.1 * k), t0);
    a.Add(Message(2, k, 10.045 + 0.1 * k), t0);
  }
  auto s = a.Next(t0);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frame, 0);
  EXPECT_DOUBLE_EQ(s->time, 10.0);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0, 1}));
  s = a.Next(t0);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frame, 1);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{2}));  // anchored at 10.045: camera 0's 10.1 is 55 ms off
  EXPECT_EQ(a.left_out(0), 1);
}

TEST(FrameSetAligner, ByTimestampJitterStaysInOneSet) {
  const auto t0 = Clock::now();
  FrameSetAligner a(2, Options(FrameSync::kTimestamp), t0);
  const double jitter[] = {0.01, -0.02, 0.025, 0.0, -0.005};
  for (int k = 0; k < 5; ++k) {
    a.Add(Message(0, k, 0.1 * k), t0);
    a.Add(Message(1, 1000 + k, 0.1 * k + jitter[k]), t0);
  }
  for (int k = 0; k < 5; ++k) {
    auto s = a.Next(t0);
    ASSERT_TRUE(s) << k;
    EXPECT_EQ(Cameras(*s), (std::vector<int>{0, 1})) << k;
    EXPECT_EQ(s->cameras[0]->frame, k);
    EXPECT_EQ(s->cameras[1]->frame, 1000 + k);
  }
  a.Add(Message(1, 999, 0.05), t0);  // older than what camera 1 gave: dropped
  EXPECT_EQ(a.late(), 1);
}

TEST(FrameSetAligner, EndedCamerasAreDecidedAndAllEndedFlushes) {
  const auto t0 = Clock::now();
  AlignOptions o = Options(FrameSync::kIndex);
  o.latency_budget_s = 100;
  o.dead_after_s = 100;
  FrameSetAligner a(2, o, t0);
  a.Add(Message(0, 0, 0), t0);
  a.End(1, 1, t0);
  auto s = a.Next(t0);
  ASSERT_TRUE(s);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0}));
  EXPECT_EQ(a.left_out(1), 0);  // ended: not left out
  a.Add(Message(0, 1, 0), t0);
  a.End(0, 2, t0);
  EXPECT_TRUE(a.all_ended());
  EXPECT_TRUE(a.Next(t0));
  EXPECT_TRUE(a.idle());
}

// Every set fused from `a` at `now`: its frame and cameras.
std::vector<std::pair<int64_t, std::vector<int>>> Drain(FrameSetAligner& a, Clock::time_point now) {
  std::vector<std::pair<int64_t, std::vector<int>>> out;
  while (auto s = a.Next(now)) out.emplace_back(s->frame, Cameras(*s));
  return out;
}

std::vector<std::pair<int64_t, std::vector<int>>> Whole(int64_t first, int64_t last, std::vector<int> cameras) {
  std::vector<std::pair<int64_t, std::vector<int>>> out;
  for (int64_t f = first; f <= last; ++f) out.emplace_back(f, cameras);
  return out;
}

// Issue 39: a copy of camera 1's frame 3 published before the edges start fused frame set 3 twice.
TEST(FrameSetAligner, ACopyPublishedBeforeTheEdgesStartIsDroppedNotFusedTwice) {
  const auto t0 = Clock::now();
  AlignOptions o = Options(FrameSync::kIndex);
  o.latency_budget_s = 100;
  FrameSetAligner a(3, o, t0);
  a.Add(Message(1, 3, 0.3), t0);  // the replay
  std::vector<std::pair<int64_t, std::vector<int>>> fused;
  auto t = t0 + milliseconds(10);
  // The edges, camera 1's the slowest: its frame 0 comes after the others' frames 0 and 1.
  for (int f = 0; f < 6; ++f) {
    a.Add(Message(0, f, 0.1 * f), t);
    a.Add(Message(2, f, 0.1 * f), t);
    for (auto& s : Drain(a, t)) fused.push_back(s);
    if (f >= 1) a.Add(Message(1, f - 1, 0.1 * (f - 1)), t);
    for (auto& s : Drain(a, t)) fused.push_back(s);
  }
  a.Add(Message(1, 5, 0.5), t);
  for (auto& s : Drain(a, t)) fused.push_back(s);
  EXPECT_EQ(fused, Whole(0, 5, {0, 1, 2}));
  EXPECT_EQ(a.duplicates(1), 1);
  EXPECT_EQ(a.duplicates(), 1);
  EXPECT_EQ(a.late(), 0);
  EXPECT_EQ(a.left_out(1), 0);
}

// Issue 39: copies of every camera's frames 5-9 sent first made the fuse begin at frame 5 and
// count the genuine frames 0-4 late.
TEST(FrameSetAligner, LaterFramesSentBeforeTheEdgesStartCostNoGenuineFrame) {
  const auto t0 = Clock::now();
  AlignOptions o = Options(FrameSync::kIndex);
  o.latency_budget_s = 0.1;
  FrameSetAligner a(2, o, t0);
  for (int f = 5; f < 10; ++f) {
    a.Add(Message(0, f, 0.1 * f), t0);
    a.Add(Message(1, f, 0.1 * f), t0);
  }
  // Every camera heard, the budget long past: the set of frame 5 still waits for the first frame.
  EXPECT_FALSE(a.Next(t0 + milliseconds(4000)));
  std::vector<std::pair<int64_t, std::vector<int>>> fused;
  const auto t = t0 + milliseconds(4100);
  for (int f = 0; f < 12; ++f) {
    a.Add(Message(0, f, 0.1 * f), t);
    for (auto& s : Drain(a, t)) fused.push_back(s);
    a.Add(Message(1, f, 0.1 * f), t);
    for (auto& s : Drain(a, t)) fused.push_back(s);
  }
  EXPECT_EQ(fused, Whole(0, 11, {0, 1}));
  EXPECT_EQ(a.duplicates(0), 5);
  EXPECT_EQ(a.duplicates(1), 5);
  EXPECT_EQ(a.late(), 0);
}

TEST(FrameSetAligner, TheFirstSetByIndexGoesOnAfterTheStartWaitWhenTheFirstFrameNeverComes) {
  const auto t0 = Clock::now();
  FrameSetAligner a(2, Options(FrameSync::kIndex), t0);  // start_wait_s 5
  a.Add(Message(0, 40, 4.0), t0);  // a fuse started after its edges: their frames go on from 40
  a.Add(Message(1, 40, 4.0), t0);
  EXPECT_FALSE(a.Next(t0 + milliseconds(4900)));
  auto s = a.Next(t0 + milliseconds(5001));
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frame, 40);
  EXPECT_EQ(Cameras(*s), (std::vector<int>{0, 1}));
}

TEST(FrameSetAligner, AReplayedLaterFrameDecidesNothingAndACopyOfAFusedOneIsADuplicate) {
  const auto t0 = Clock::now();
  AlignOptions o = Options(FrameSync::kIndex);
  o.latency_budget_s = 100;
  o.dead_after_s = 100;
  FrameSetAligner a(2, o, t0);
  for (int f = 0; f < 3; ++f) {
    a.Add(Message(0, f, 0), t0);
    a.Add(Message(1, f, 0), t0);
  }
  EXPECT_EQ(Drain(a, t0), Whole(0, 2, {0, 1}));
  a.Add(Message(0, 3, 0), t0);
  // A replay of camera 1's frame 8, then its genuine frame 3.
  a.Add(Message(1, 8, 0), t0);
  a.Add(Message(1, 3, 0), t0);
  EXPECT_EQ(Drain(a, t0), Whole(3, 3, {0, 1}));
  a.Add(Message(1, 2, 0), t0);  // a copy of a fused frame: an old one, dropped
  a.Add(Message(1, 3, 0), t0);  // a copy of the one just fused: a duplicate
  EXPECT_EQ(a.duplicates(1), 1);
  EXPECT_EQ(a.late(1), 1);
  // Frame 4: camera 1's last accepted arrival is frame 3 (its 8 pending is no evidence that its 4
  // is lost): undecided until its 4 comes.
  a.Add(Message(0, 4, 0), t0);
  EXPECT_FALSE(a.Next(t0 + milliseconds(50)));
  a.Add(Message(1, 4, 0), t0);
  EXPECT_EQ(Drain(a, t0), Whole(4, 4, {0, 1}));
}

}  // namespace
}  // namespace occmap
