#include "occmap/fusion/view_explainer.h"

#include <gtest/gtest.h>

#include <random>

#include "occmap/fusion/test_people.h"

namespace occmap {
namespace {

struct Found {
  std::vector<ExplainedPerson> people;
  OccupancyMap column_map;
};

Found Explain(testing::PeopleRoom& scene, const ExplainOptions& options = {}, int threads = 1,
              std::vector<bool> active = std::vector<bool>(4, true)) {
  Found f;
  Context ctx(threads);
  ColumnFusionOptions column;
  column.band_low_m = 0.8;
  ColumnFusion(scene.columns).Fuse(scene.Sums(), active, column, ctx, f.column_map);
  ViewExplainer explainer(scene.columns);
  explainer.Explain(scene.Views(), scene.Sums(), active, f.column_map, options, ctx, f.people);
  return f;
}

double Nearest(const std::vector<ExplainedPerson>& people, double x, double y) {
  double best = 1e9;
  for (const auto& p : people) best = std::min(best, std::hypot(p.x_m - x, p.y_m - y));
  return best;
}

TEST(ViewExplainerTest, FindsEachPersonOnceAndNoGhost) {
  testing::PeopleRoom scene;
  const std::vector<Eigen::Vector2d> truth = {{1.0, 1.0}, {2.6, 1.2}, {1.8, 2.3}, {3.2, 2.4}};
  for (const auto& p : truth) scene.Paint(p.x(), p.y());
  const Found f = Explain(scene);
  ASSERT_EQ(f.people.size(), truth.size());
  for (const auto& p : truth) EXPECT_LT(Nearest(f.people, p.x(), p.y()), 0.15) << p.transpose();
  for (const auto& p : f.people) {
    EXPECT_GE(p.gain, ExplainOptions{}.min_gain);
    EXPECT_EQ(p.views, 4);
  }
}

TEST(ViewExplainerTest, PeopleCloseTogetherStayTwo) {
  testing::PeopleRoom scene;
  scene.Paint(1.8, 1.5);
  scene.Paint(2.3, 1.5);
  const Found f = Explain(scene);
  ASSERT_EQ(f.people.size(), 2u);
  EXPECT_LT(Nearest(f.people, 1.8, 1.5), 0.15);
  EXPECT_LT(Nearest(f.people, 2.3, 1.5), 0.15);
}

TEST(ViewExplainerTest, EmptyViewsExplainNobody) {
  testing::PeopleRoom scene;
  EXPECT_TRUE(Explain(scene).people.empty());
}

TEST(ViewExplainerTest, OneThreadEqualsTwoAndACameraMayBeMissing) {
  testing::PeopleRoom scene;
  for (const auto& p : {Eigen::Vector2d(0.8, 0.9), Eigen::Vector2d(1.5, 1.6), Eigen::Vector2d(2.2, 0.7),
                        Eigen::Vector2d(2.9, 2.0), Eigen::Vector2d(3.4, 1.0)})
    scene.Paint(p.x(), p.y());
  std::vector<bool> active(4, true);
  active[1] = false;
  const Found one = Explain(scene, {}, 1, active), two = Explain(scene, {}, 2, active);
  ASSERT_EQ(one.people.size(), two.people.size());
  for (size_t i = 0; i < one.people.size(); ++i) {
    EXPECT_EQ(one.people[i].candidate, two.people[i].candidate);
    EXPECT_EQ(one.people[i].gain, two.people[i].gain);
    EXPECT_EQ(one.people[i].views, 3);
  }
  EXPECT_EQ(one.people.size(), 5u);
}

// `people` of radii radius_m + 0.05 m * (0 .. radii - 1) painted at random at least margin_m
// from the 4 x 3 m room's walls, then `flips` random pixels of every view flipped.
void PaintNoisyCrowd(testing::PeopleRoom& scene, int seed, int people, double margin_m, double radius_m,
                     int radii, int flips) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(margin_m, 4.0 - margin_m), uy(margin_m, 3.0 - margin_m);
  for (int p = 0; p < people; ++p) scene.Paint(ux(rng), uy(rng), radius_m + 0.05 * (p % radii));
  std::uniform_int_distribution<int> px(0, 319), py(0, 239);
  for (auto& im : scene.changes)
    for (int n = 0; n < flips; ++n) im(px(rng), py(rng)) ^= 1;
}

TEST(ViewExplainerTest, FastEqualsReferenceInACrowdWithNoise) {
  for (int seed : {1, 2, 3}) {
    testing::PeopleRoom scene;
    PaintNoisyCrowd(scene, seed, 9, 0.3, 0.15, 3, 2000);
    std::vector<bool> active(4, true);
    active[3] = seed != 2;
    ColumnFusionOptions column;
    column.band_low_m = 0.8;
    Context ctx(seed == 3 ? 2 : 1);
    OccupancyMap column_map;
    ColumnFusion(scene.columns).Fuse(scene.Sums(), active, column, ctx, column_map);
    for (double ground_weight : {0.0, 2.0}) {
      ExplainOptions o;
      o.ground_weight = ground_weight;
      o.max_rows = seed == 1 ? 1000 : 48;
      ViewExplainer explainer(scene.columns);
      std::vector<ExplainedPerson> fast, reference, again;
      explainer.Explain(scene.Views(), scene.Sums(), active, column_map, o, ctx, fast);
      explainer.ExplainReference(scene.Views(), scene.Sums(), active, column_map, o, ctx, reference);
      explainer.Explain(scene.Views(), scene.Sums(), active, column_map, o, ctx, again);
      ASSERT_EQ(fast.size(), reference.size()) << seed;
      EXPECT_GE(fast.size(), 5u) << seed;
      for (size_t i = 0; i < fast.size(); ++i) {
        EXPECT_EQ(fast[i].candidate, reference[i].candidate) << seed << " " << i;
        EXPECT_EQ(fast[i].gain, reference[i].gain) << seed << " " << i;
        EXPECT_EQ(fast[i].views, reference[i].views);
        EXPECT_EQ(fast[i].candidate, again[i].candidate);
      }
    }
  }
}

// A crowd denser than the room holds apart: most people's images overlap in every view, often
// three or more deep, so that the fast path's runs between the chosen people's spans are what
// decides (the rows' counts against the reference's coverage image).
TEST(ViewExplainerTest, FastEqualsReferenceInADenseCrowd) {
  for (int seed : {4, 5, 6, 7}) {
    testing::PeopleRoom scene;
    PaintNoisyCrowd(scene, seed, 24, 0.5, 0.10, 4, 4000);
    const std::vector<bool> active(4, true);
    ColumnFusionOptions column;
    column.band_low_m = 0.8;
    Context ctx(1);
    OccupancyMap column_map;
    ColumnFusion(scene.columns).Fuse(scene.Sums(), active, column, ctx, column_map);
    ExplainOptions o;
    o.min_gain = seed % 2 == 0 ? 0.7 : 0.3;  // lower: more people kept, more overlap
    o.min_separation_m = 0.2;
    o.max_rows = seed == 4 ? 1000 : 48;
    ViewExplainer explainer(scene.columns);
    std::vector<ExplainedPerson> fast, reference;
    explainer.Explain(scene.Views(), scene.Sums(), active, column_map, o, ctx, fast);
    explainer.ExplainReference(scene.Views(), scene.Sums(), active, column_map, o, ctx, reference);
    ASSERT_EQ(fast.size(), reference.size()) << seed;
    EXPECT_GE(fast.size(), 8u) << seed;
    for (size_t i = 0; i < fast.size(); ++i) {
      EXPECT_EQ(fast[i].candidate, reference[i].candidate) << seed << " " << i;
      EXPECT_EQ(fast[i].gain, reference[i].gain) << seed << " " << i;
    }
  }
}

// The fast path keeps each candidate's model rows across frames: one explainer fed frame after
// frame (the crowd moving, the options changing, a camera's views learned blocked and then
// unblocked) finds what a fresh reference finds on each frame.
TEST(ViewExplainerTest, FastEqualsReferenceFrameAfterFrame) {
  testing::PeopleRoom scene;
  ViewExplainer explainer(scene.columns);
  const std::vector<bool> active(4, true);
  Context ctx(2);
  std::vector<int64_t> blocked;
  for (int frame = 0; frame < 9; ++frame) {
    scene.Clear();
    PaintNoisyCrowd(scene, 100 + frame / 2, 8, 0.3, 0.15, 3, 1000 + frame);  // frames in pairs: rows reused
    ColumnFusionOptions column;
    column.band_low_m = 0.8;
    OccupancyMap column_map;
    ColumnFusion(scene.columns).Fuse(scene.Sums(), active, column, ctx, column_map);
    ExplainOptions o;
    if (frame >= 3) o.radius_m = 0.2;  // the kept rows no longer fit
    if (frame >= 4) o.max_rows = 20;
    if (frame >= 5) o.ground_weight = 0;
    if (frame == 6) {  // camera 0 learns that it cannot see most candidates
      for (int64_t k = 0; k < column_map.grid().num_cells(); ++k) {
        if (column_map.state(k) != CellState::kOccupied || k % 3 == 0) continue;
        scene.columns.SetLearnedBlocked(0, k, true);
        blocked.push_back(k);
      }
      ASSERT_FALSE(blocked.empty());
    }
    if (frame == 8)
      for (int64_t k : blocked) scene.columns.SetLearnedBlocked(0, k, false);
    std::vector<ExplainedPerson> fast, reference;
    explainer.Explain(scene.Views(), scene.Sums(), active, column_map, o, ctx, fast);
    ViewExplainer(scene.columns).ExplainReference(scene.Views(), scene.Sums(), active, column_map, o, ctx, reference);
    ASSERT_EQ(fast.size(), reference.size()) << frame;
    EXPECT_GE(fast.size(), 4u) << frame;
    for (size_t i = 0; i < fast.size(); ++i) {
      EXPECT_EQ(fast[i].candidate, reference[i].candidate) << frame << " " << i;
      EXPECT_EQ(fast[i].gain, reference[i].gain) << frame << " " << i;
      EXPECT_EQ(fast[i].views, reference[i].views) << frame << " " << i;
    }
  }
}

TEST(ViewExplainerTest, GainCountsOnlyWhatNobodyCoversYet) {
  testing::PeopleRoom scene;
  scene.Paint(2.0, 1.5);
  ViewExplainer explainer(scene.columns);
  const int64_t k = scene.columns.candidates().CellAt(2.0, 1.5);
  const std::vector<bool> active(4, true);
  // A model inside a painted silhouette that is wider: every pixel changed, one view's worth each.
  EXPECT_NEAR(explainer.Gain(k, scene.Views(), active, ExplainOptions{}, 0), 4.0, 1e-9);
  scene.Clear();
  ExplainOptions o;
  o.unchanged_weight = 0.5;
  EXPECT_NEAR(explainer.Gain(k, scene.Views(), active, o, 0), -2.0, 1e-9);
}

TEST(ViewExplainerTest, ChangedFloorInFrontOfTheFeetCountsAgainst) {
  testing::PeopleRoom scene;
  const int64_t k = scene.columns.candidates().CellAt(2.0, 1.5);
  // Camera 0's rows just below the model's foot row, changed (another person's legs, say).
  const ColumnSpans s = MakeColumnSpans(scene.columns.view(0, k), 0.15, 0.0, 1.0, scene.columns.image_size(0));
  for (int y = s.last_row + 1; y <= s.last_row + 10 && y < 240; ++y)
    for (int x = 0; x < 320; ++x) scene.changes[0](x, y) = 1;
  ViewExplainer explainer(scene.columns);
  const std::vector<bool> active(4, true);
  ExplainOptions without;
  without.ground_weight = 0;
  ExplainOptions with;
  const double g0 = explainer.Gain(k, scene.Views(), active, without, 0);
  const double g1 = explainer.Gain(k, scene.Views(), active, with, 0);
  EXPECT_LT(g1, g0 - 0.1);
  // A person standing there is still found: the other views carry them.
  scene.Paint(2.0, 1.5, 0.2);
  const Found f = Explain(scene);
  ASSERT_EQ(f.people.size(), 1u);
  EXPECT_LT(Nearest(f.people, 2.0, 1.5), 0.15);
}

TEST(ViewExplainerTest, OptionsAreChecked) {
  ExplainOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.radius_m = 0;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.min_gain = -1;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.moves = 11;
  EXPECT_FALSE(o.Validate().ok());
}

}  // namespace
}  // namespace occmap
