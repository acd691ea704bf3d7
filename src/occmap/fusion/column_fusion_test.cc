#include "occmap/fusion/column_fusion.h"

#include <gtest/gtest.h>

#include <random>

#include "occmap/fusion/test_people.h"
#include "occmap/util/simd.h"

namespace occmap {
namespace {

TEST(ChangeRowSumsTest, CountsChangedPixelsOfASpan) {
  Image<uint8_t> im(7, 2);
  const uint8_t rows[2][7] = {{0, 1, 1, 0, 5, 0, 1}, {1, 1, 1, 1, 1, 1, 1}};
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 7; ++x) im(x, y) = rows[y][x];
  ChangeRowSums sums;
  sums.Build(im.view());
  EXPECT_EQ(sums.Count(0, 0, 6), 4);
  EXPECT_EQ(sums.Count(0, 2, 4), 2);
  EXPECT_EQ(sums.Count(1, 3, 3), 1);
}

TEST(ChangeRowSumsTest, EveryCountEqualsThePixelsCountedOneByOne) {
  std::mt19937 rng(3);
  for (const char* kernels : {"portable", "best"})
  for (int width : {1, 63, 64, 65, 127, 128, 200}) {
    ASSERT_TRUE(ForceKernelsForTesting(kernels));
    Image<uint8_t> im(width, 3);
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < width; ++x) im(x, y) = rng() % 3 == 0 ? static_cast<uint8_t>(1 + rng() % 255) : 0;
    ChangeRowSums sums;
    sums.Build(im.view());
    for (int y = 0; y < 3; ++y) {
      for (int x0 = 0; x0 < width; ++x0) {
        int n = 0;
        for (int x1 = x0; x1 < width; ++x1) {
          n += im(x1, y) != 0 ? 1 : 0;
          ASSERT_EQ(sums.Count(y, x0, x1), n) << kernels << " " << width << " " << y << " " << x0 << " " << x1;
        }
      }
    }
  }
  ForceKernelsForTesting("best");
}

TEST(ColumnSpansTest, RowsEqualSpanRowByRow) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  int64_t rows_checked = 0, narrow = 0, clipped = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    ColumnSpans s;
    s.width = 1 + static_cast<int>(rng() % 2000);
    s.height = 1 + static_cast<int>(rng() % 1200);
    s.bottom_row = -300.0f + 1800.0f * u(rng);
    s.axis_bottom = -400.0f + 2800.0f * u(rng);
    s.axis_slope = trial % 7 == 0 ? 0.0f : -3.0f + 6.0f * u(rng);
    // Wide spans, spans under a pixel (Span's rounded axis), widths that go below zero.
    s.half_bottom = trial % 3 == 0 ? 0.6f * u(rng) : 80.0f * u(rng);
    s.half_slope = -0.3f + 0.6f * u(rng);
    if (trial % 11 == 0) s.axis_bottom = (u(rng) < 0.5f ? -1.0f : 1.0f) * 1e6f * u(rng);  // far off the image
    const int step = 1 + static_cast<int>(rng() % 9);
    const int y_first = static_cast<int>(rng() % static_cast<uint32_t>(s.height));
    const int y_last = y_first + static_cast<int>(rng() % static_cast<uint32_t>(s.height - y_first));
    std::vector<RowSpan> rows(static_cast<size_t>((y_last - y_first) / step + 1));
    const int n = s.Rows(y_first, y_last, step, rows.data());
    int i = 0;
    for (int y = y_first; y <= y_last; y += step) {
      int x0, x1;
      if (!s.Span(y, x0, x1)) {
        ++clipped;
        continue;
      }
      ASSERT_LT(i, n) << trial;
      ASSERT_EQ(rows[i].y, y) << trial;
      ASSERT_EQ(rows[i].x0, x0) << trial << " y " << y;
      ASSERT_EQ(rows[i].x1, x1) << trial << " y " << y;
      narrow += x0 == x1 ? 1 : 0;
      ++i;
      ++rows_checked;
    }
    ASSERT_EQ(i, n) << trial;
    // ForEachRow gives the same rows, through its chunks.
    int j = 0;
    s.ForEachRow(y_first, y_last, step, [&](int y, int x0, int x1) {
      ASSERT_LT(j, n);
      EXPECT_EQ(y, rows[j].y);
      EXPECT_EQ(x0, rows[j].x0);
      EXPECT_EQ(x1, rows[j].x1);
      ++j;
    });
    ASSERT_EQ(j, n) << trial;
  }
  // The cases were met: many rows, one-pixel spans, rows off the image.
  EXPECT_GT(rows_checked, 200000);
  EXPECT_GT(narrow, 10000);
  EXPECT_GT(clipped, 10000);
}

TEST(ColumnFusionTest, APersonsColumnIsOccupiedAndTheFloorAroundIsFree) {
  testing::PeopleRoom scene;
  scene.Paint(2.0, 1.5);
  ColumnFusion fusion(scene.columns);
  Context ctx(1);
  OccupancyMap map;
  const std::vector<bool> active(4, true);
  fusion.Fuse(scene.Sums(), active, ColumnFusionOptions{}, ctx, map);
  const FloorGrid& g = scene.columns.candidates();
  EXPECT_EQ(map.state(g.CellAt(2.0, 1.5)), CellState::kOccupied);
  EXPECT_EQ(map.state(g.CellAt(0.5, 0.5)), CellState::kFree);
  EXPECT_EQ(map.state(g.CellAt(3.5, 2.5)), CellState::kFree);
  // Nothing but the person's neighbourhood is occupied.
  for (int64_t k = 0; k < g.num_cells(); ++k) {
    if (map.state(k) != CellState::kOccupied) continue;
    EXPECT_LT((g.CellCenter(k) - Eigen::Vector2d(2.05, 1.55)).norm(), 0.35) << k;
  }
}

TEST(ColumnFusionTest, ACameraHiddenByAnOccluderAbstains) {
  Occluder pillar;
  pillar.shape = Occluder::Shape::kCylinder;
  pillar.centre_m = {1.0, 0.7};
  pillar.size_m = {0.4, 0.4};
  pillar.height_m = 3;
  const std::vector<Occluder> occluders = {pillar};
  for (bool with_occluder : {false, true}) {
    testing::PeopleRoom scene(with_occluder ? std::span<const Occluder>(occluders) : std::span<const Occluder>());
    scene.Paint(2.0, 1.5);
    // Camera 0 sees the pillar, not the person: nothing changed there.
    for (int y = 0; y < 240; ++y) std::fill_n(scene.changes[0].row(y), 320, uint8_t{0});
    ColumnFusion fusion(scene.columns);
    Context ctx(1);
    OccupancyMap map;
    ColumnFusionOptions strict;  // the AND: no view outvoted
    strict.max_free_views = 0;
    fusion.Fuse(scene.Sums(), std::vector<bool>(4, true), strict, ctx, map);
    EXPECT_EQ(map.state(scene.columns.candidates().CellAt(2.0, 1.5)),
              with_occluder ? CellState::kOccupied : CellState::kFree);
  }
}

// The state of `cell`, fused fast and by the reference (which must agree).
CellState FusedState(const ColumnFusion& fusion, testing::PeopleRoom& scene, const ColumnFusionOptions& o,
                     const std::vector<bool>& active, int64_t cell) {
  Context ctx(1);
  OccupancyMap fast, reference;
  fusion.Fuse(scene.Sums(), active, o, ctx, fast);
  fusion.FuseReference(scene.Views(), active, o, reference);
  EXPECT_EQ(fast, reference);
  return fast.state(cell);
}

// A coat of the background's colour leaves a person's torso unchanged in one view: two or more
// views that see it changed outvote it (the default), one does not.
TEST(ColumnFusionTest, OneCamouflagedViewIsOutvotedByTwoThatSeeTheTorso) {
  testing::PeopleRoom scene;
  scene.Paint(2.0, 1.5);
  for (int y = 0; y < 240; ++y) std::fill_n(scene.changes[0].row(y), 320, uint8_t{0});
  ColumnFusion fusion(scene.columns);
  const int64_t cell = scene.columns.candidates().CellAt(2.0, 1.5);
  const auto state = [&](const ColumnFusionOptions& o, const std::vector<bool>& active) {
    return FusedState(fusion, scene, o, active, cell);
  };
  const ColumnFusionOptions vote;
  EXPECT_EQ(vote.max_free_views, 1);
  EXPECT_EQ(state(vote, {true, true, true, true}), CellState::kOccupied);
  // With two cameras off, one changed view is left against the camouflaged one: free.
  EXPECT_EQ(state(vote, {true, true, false, false}), CellState::kFree);
  ColumnFusionOptions strict = vote;
  strict.max_free_views = 0;
  EXPECT_EQ(state(strict, {true, true, true, true}), CellState::kFree);
  // Two views unchanged are too many for the default.
  for (int y = 0; y < 240; ++y) std::fill_n(scene.changes[1].row(y), 320, uint8_t{0});
  EXPECT_EQ(state(vote, {true, true, true, true}), CellState::kFree);
}

// One view cannot place a person: a position only one camera tests is unseen, whatever that
// camera sees, while two or more cameras are active; a site with one active camera left tests
// with it alone.
TEST(ColumnFusionTest, APositionOneCameraTestsIsUnseenWhileOthersAreActive) {
  // Pillars between the person and cameras 1, 2 and 3 (at the room's corners, 2.7 m up).
  std::vector<Occluder> pillars;
  for (const Eigen::Vector2d& at : {Eigen::Vector2d(2.47, 1.13), Eigen::Vector2d(2.47, 1.87), Eigen::Vector2d(1.53, 1.87)}) {
    Occluder pillar;
    pillar.shape = Occluder::Shape::kCylinder;
    pillar.centre_m = at;
    pillar.size_m = {0.4, 0.4};
    pillar.height_m = 3;
    pillars.push_back(pillar);
  }
  testing::PeopleRoom scene(pillars);
  scene.Paint(2.0, 1.5);
  const int64_t cell = scene.columns.candidates().CellAt(2.0, 1.5);
  for (int c = 1; c < 4; ++c) ASSERT_TRUE(scene.columns.view(c, cell).blocked) << c;
  ASSERT_FALSE(scene.columns.view(0, cell).blocked);
  ColumnFusion fusion(scene.columns);
  const auto state = [&](const ColumnFusionOptions& o, const std::vector<bool>& active) {
    return FusedState(fusion, scene, o, active, cell);
  };
  const ColumnFusionOptions defaults;
  EXPECT_EQ(defaults.min_views, 2);
  EXPECT_EQ(state(defaults, {true, true, true, true}), CellState::kUnseen);
  EXPECT_EQ(state(defaults, {true, true, false, false}), CellState::kUnseen);
  EXPECT_EQ(state(defaults, {true, false, false, false}), CellState::kOccupied);  // the one camera left
  ColumnFusionOptions one = defaults;
  one.min_views = 1;
  EXPECT_EQ(state(one, {true, true, true, true}), CellState::kOccupied);
  // Without the pillars every camera tests it: occupied.
  testing::PeopleRoom open;
  open.Paint(2.0, 1.5);
  EXPECT_EQ(FusedState(ColumnFusion(open.columns), open, defaults, std::vector<bool>(4, true), cell), CellState::kOccupied);
}

// A person close to a camera shows it the torso with the feet below the image (the terrace's
// people walking in past a camera): that camera tests the column, it does not abstain.
TEST(ColumnFusionTest, ACameraThatSeesTheTorsoWithTheFeetCutOffTests) {
  testing::PeopleRoom scene;
  const FloorGrid& g = scene.columns.candidates();
  int64_t cell = -1;
  for (int64_t k = 0; k < g.num_cells() && cell < 0; ++k) {
    const ColumnView& v = scene.columns.view(0, k);
    if (!v.feet_cut) continue;
    EXPECT_FALSE(v.seen);
    EXPECT_GE(v.bottom_row, 240.0f);
    EXPECT_GE(v.top_row, 0.0f);
    const ColumnFusionOptions o;
    const double h = scene.columns.options().height_m;
    const ColumnSpans band = MakeColumnSpans(v, o.radius_m, o.band_low_m / h, o.band_high_m / h, {320, 240});
    if (2 * band.visible_rows < band.last_row - band.first_row + 1) continue;  // the band itself cut
    int others = 0;
    for (int c = 1; c < 4; ++c) others += scene.columns.view(c, k).seen;
    if (others >= 2) cell = k;
  }
  ASSERT_GE(cell, 0) << "no position with camera 0's feet cut and two other views";
  const Eigen::Vector2d at = g.CellCenter(cell);
  scene.Paint(at.x(), at.y());
  for (int y = 0; y < 240; ++y) std::fill_n(scene.changes[0].row(y), 320, uint8_t{0});  // camera 0 sees nothing
  ColumnFusion fusion(scene.columns);
  Context ctx(1);
  ColumnFusionOptions strict;  // the AND: camera 0's free vote decides
  strict.max_free_views = 0;
  OccupancyMap fast, reference;
  fusion.Fuse(scene.Sums(), std::vector<bool>(4, true), strict, ctx, fast);
  fusion.FuseReference(scene.Views(), std::vector<bool>(4, true), strict, reference);
  EXPECT_EQ(fast, reference);
  EXPECT_EQ(fast.state(cell), CellState::kFree);
  scene.Paint(at.x(), at.y());  // camera 0 sees the torso: occupied
  fusion.Fuse(scene.Sums(), std::vector<bool>(4, true), strict, ctx, fast);
  EXPECT_EQ(fast.state(cell), CellState::kOccupied);
}

TEST(ColumnFusionTest, FastEqualsReferenceAndOneThreadEqualsTwo) {
  testing::PeopleRoom scene;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(0.3, 3.7), uy(0.3, 2.7);
  for (int p = 0; p < 6; ++p) scene.Paint(ux(rng), uy(rng), 0.15 + 0.05 * (p % 3));
  // Noise: scattered changed pixels and holes.
  std::uniform_int_distribution<int> px(0, 319), py(0, 239);
  for (auto& im : scene.changes)
    for (int n = 0; n < 3000; ++n) im(px(rng), py(rng)) ^= 1;
  ColumnFusion fusion(scene.columns);
  for (const char* kernels : {"portable", "best"})
  for (int max_free_views : {0, 1, 2})
  for (double min_changed : {0.5, 0.25}) {  // lower: more first looks pass, more bands counted
    ASSERT_TRUE(ForceKernelsForTesting(kernels));
    for (bool camera_off : {false, true}) {
      std::vector<bool> active(4, true);
      active[2] = !camera_off;
      ColumnFusionOptions o;
      o.max_free_views = max_free_views;
      o.min_changed = min_changed;
      OccupancyMap fast1, fast2, reference;
      Context one(1), two(2);
      fusion.Fuse(scene.Sums(), active, o, one, fast1);
      fusion.Fuse(scene.Sums(), active, o, two, fast2);
      fusion.FuseReference(scene.Views(), active, o, reference);
      EXPECT_EQ(fast1, reference) << kernels;
      EXPECT_EQ(fast1, fast2) << kernels;
      EXPECT_GT(reference.Count(CellState::kOccupied), 0);
    }
  }
  ForceKernelsForTesting("best");
}

TEST(ColumnFusionTest, OptionsAreChecked) {
  ColumnFusionOptions o;
  EXPECT_TRUE(o.Validate(1.7, 4).ok());
  o.band_high_m = 2.0;
  EXPECT_FALSE(o.Validate(1.7, 4).ok());
  o = {};
  o.min_changed = 0;
  EXPECT_FALSE(o.Validate(1.7, 4).ok());
  o = {};
  o.max_free_views = 4;
  EXPECT_FALSE(o.Validate(1.7, 4).ok());
  o.max_free_views = 1;  // one view may be outvoted whatever the cameras (min_changed_views decides)
  EXPECT_TRUE(o.Validate(1.7, 1).ok());
  o.min_changed_views = 0;
  EXPECT_FALSE(o.Validate(1.7, 4).ok());
  o = {};
  o.min_views = 0;
  EXPECT_FALSE(o.Validate(1.7, 4).ok());
  o.min_views = 5;  // more than the cameras: every active camera must test
  EXPECT_TRUE(o.Validate(1.7, 4).ok());
}

}  // namespace
}  // namespace occmap
