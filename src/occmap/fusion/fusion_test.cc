#include "occmap/fusion/fusion.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "occmap/geometry/homography_camera.h"
#include "occmap/lut/test_scene.h"

namespace occmap {
namespace {

// A scene built in code: cameras, their tables, and for ray tests each camera's centre and
// where each pixel's ray meets the floor (by global pixel id).
struct Scene {
  std::vector<std::unique_ptr<CameraModel>> cameras;
  GroundLut lut;
  std::vector<Eigen::Vector3d> centers_m;
  std::vector<std::optional<Eigen::Vector2d>> floor_points_m;
};

// The small room's four corner cameras at width x height. With `fifth`, the floor grid
// reaches 1 m beyond the room's far wall (y up to 4 m) and a fifth camera outside that wall
// looks back at it, with the left half of its image masked out: cells seen by 0 to 5 cameras
// (some of the strip by one camera alone), masked pixels, and at 64 x 48 many coverage-fix
// pairs.
Scene MakeRoom(int width, int height, bool fifth) {
  testing::SmallRoom room(width, height);
  Scene scene;
  for (const auto& cam : room.cameras) scene.cameras.push_back(cam.Clone());
  FloorGrid grid = room.grid;
  if (fifth) {
    grid.cells_y = 80;
    scene.cameras.push_back(testing::LookAtCamera({2.0, 4.6, 1.6}, {2.0, 3.0, 0.0}, 48, 40, 40).Clone());
  }
  Image<uint8_t> mask(48, 40, 255);
  for (int y = 0; y < 40; ++y) {
    for (int x = 0; x < 24; ++x) mask(x, y) = 0;
  }
  std::vector<LutCameraInput> inputs;
  for (size_t n = 0; n < scene.cameras.size(); ++n) {
    inputs.push_back({scene.cameras[n].get(), n == 4 ? mask.view() : ImageView<const uint8_t>()});
  }
  Context ctx(1);
  scene.lut = BuildGroundLut(inputs, grid, {}, ctx).value();
  for (const auto& cam : scene.cameras) {
    scene.centers_m.push_back(cam->CenterInWorld().value());
    const ImageSize size = cam->image_size();
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        scene.floor_points_m.push_back(cam->PixelToPlane(Eigen::Vector2d(x, y), 0.0));
      }
    }
  }
  return scene;
}

// The camera owning a global pixel id.
int CameraOf(const GroundLut& lut, uint32_t pixel) {
  int n = 0;
  while (pixel >= lut.pixel_offset(n + 1)) ++n;
  return n;
}

// The rule of fusion.h written out directly from L2, the oracle: per cell, how many active
// cameras view it and how many of them have an unchanged pixel there...
struct Votes {
  std::vector<int> viewing, say_free;
};

Votes CountVotes(const GroundLut& lut, const std::vector<uint8_t>& changes, const std::vector<bool>& active) {
  Votes votes;
  const size_t num_cameras = static_cast<size_t>(lut.num_cameras());
  std::vector<int> views(num_cameras), unchanged(num_cameras);
  for (int64_t cell = 0; cell < lut.grid().num_cells(); ++cell) {
    std::fill(views.begin(), views.end(), 0);
    std::fill(unchanged.begin(), unchanged.end(), 0);
    for (uint32_t p : lut.l2_pixels_of(cell)) {
      const size_t n = static_cast<size_t>(CameraOf(lut, p));
      ++views[n];
      if (changes[p] == 0) ++unchanged[n];
    }
    int viewing = 0, say_free = 0;
    for (size_t n = 0; n < num_cameras; ++n) {
      if (!active[n] || views[n] == 0) continue;
      ++viewing;
      if (unchanged[n] > 0) ++say_free;
    }
    votes.viewing.push_back(viewing);
    votes.say_free.push_back(say_free);
  }
  return votes;
}

// ...and the decision for k.
OccupancyMap RuleOracle(const GroundLut& lut, const Votes& votes, int k) {
  OccupancyMap map(lut.grid());
  for (size_t cell = 0; cell < votes.viewing.size(); ++cell) {
    const int viewing = votes.viewing[cell], say_free = votes.say_free[cell];
    map.states()[cell] = viewing == 0 ? CellState::kUnseen
                                      : (say_free <= k && say_free < viewing ? CellState::kOccupied : CellState::kFree);
  }
  return map;
}

OccupancyMap Fuse(Fusion& fusion, const std::vector<uint8_t>& changes, const std::vector<bool>& active, int k,
                  FusionMethod method) {
  OccupancyMap map;
  FusionOptions options;
  options.method = method;
  options.max_free_views = k;
  fusion.Fuse(changes, active, options, map);
  return map;
}

// "" when equal, else the first differing cell, for failure messages.
std::string FirstDifference(const OccupancyMap& a, const OccupancyMap& b) {
  if (a.states().size() != b.states().size()) return "sizes differ";
  for (size_t c = 0; c < a.states().size(); ++c) {
    if (a.states()[c] != b.states()[c]) {
      return "cell " + std::to_string(c) + ": " + std::to_string(static_cast<int>(a.states()[c])) + " vs " +
             std::to_string(static_cast<int>(b.states()[c]));
    }
  }
  return "";
}

// One letter per cell: U unseen, F free, O occupied.
std::string Letters(const OccupancyMap& map) {
  std::string s;
  for (CellState state : map.states()) s += state == CellState::kUnseen ? 'U' : state == CellState::kFree ? 'F' : 'O';
  return s;
}

std::vector<uint8_t> RandomChanges(std::mt19937& rng, const GroundLut& lut, double density) {
  std::bernoulli_distribution changed(density);
  std::uniform_int_distribution<int> value(1, 255);
  std::vector<uint8_t> changes(lut.total_pixels());
  for (auto& c : changes) c = changed(rng) ? static_cast<uint8_t>(value(rng)) : 0;  // any non-zero is a change
  return changes;
}

std::vector<bool> RandomActive(std::mt19937& rng, int num_cameras) {
  std::bernoulli_distribution on(0.7);
  std::vector<bool> active(static_cast<size_t>(num_cameras));
  for (size_t n = 0; n < active.size(); ++n) active[n] = on(rng);
  return active;
}

// Distance in the plane from point c to the segment [a, b].
double DistanceToSegment(const Eigen::Vector2d& c, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = ab.squaredNorm() > 0 ? std::clamp((c - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
  return (a + t * ab - c).norm();
}

struct Cylinder {
  double x_m, y_m, radius_m, height_m;  // a vertical cylinder standing on the floor
};

// Marks as changed every pixel whose ray passes through one of the cylinders. A pixel's ray
// is the line from the camera centre C to its floor point F; it enters the slab 0 <= z <= h
// at F + (C - F) h / C_z and leaves it at F, so it meets the cylinder when that segment passes
// within the radius of the axis (cameras are above every h).
void MarkCylinders(const Scene& scene, const std::vector<Cylinder>& cylinders, std::vector<uint8_t>& changes) {
  const GroundLut& lut = scene.lut;
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const Eigen::Vector3d& center = scene.centers_m[static_cast<size_t>(n)];
    for (uint32_t p = lut.pixel_offset(n); p < lut.pixel_offset(n + 1); ++p) {
      const auto& on_floor = scene.floor_points_m[p];
      if (!on_floor) continue;
      for (const Cylinder& c : cylinders) {
        const Eigen::Vector2d top = *on_floor + (center.head<2>() - *on_floor) * (c.height_m / center.z());
        if (DistanceToSegment({c.x_m, c.y_m}, top, *on_floor) <= c.radius_m) changes[p] = 1;
      }
    }
  }
}

// Marks as changed the pixels whose L1 cell's centre lies in the axis-aligned box.
void MarkFloorBox(const GroundLut& lut, double x0, double y0, double x1, double y1, std::vector<uint8_t>& changes) {
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const auto l1 = lut.l1(n);
    for (size_t p = 0; p < l1.size(); ++p) {
      if (l1[p] == lut.sentinel()) continue;
      const Eigen::Vector2d c = lut.grid().CellCenter(l1[p]);
      if (c.x() >= x0 && c.x() <= x1 && c.y() >= y0 && c.y() <= y1) changes[lut.pixel_offset(n) + p] = 1;
    }
  }
}

TEST(Fusion, ImageBasedAndMapBasedAgreeWithTheRuleOnRandomChangesVotesAndActiveSets) {
  for (const bool small : {false, true}) {
    const Scene scene = small ? MakeRoom(64, 48, /*fifth=*/true) : MakeRoom(160, 120, /*fifth=*/false);
    const GroundLut& lut = scene.lut;
    Fusion fusion(lut);  // one object for every frame: exercises the reuse of its buffers
    std::mt19937 rng(small ? 11 : 12);
    for (int seed = 0; seed < 10; ++seed) {
      for (double density : {0.0, 0.05, 0.5, 0.9, 0.99, 1.0}) {
        const std::vector<uint8_t> changes = RandomChanges(rng, lut, density);
        for (int trial = 0; trial < 3; ++trial) {
          const std::vector<bool> active = trial == 0 ? std::vector<bool>(static_cast<size_t>(lut.num_cameras()), true)
                                                      : RandomActive(rng, lut.num_cameras());
          const Votes votes = CountVotes(lut, changes, active);
          for (int k = 0; k < std::min(lut.num_cameras(), 4); ++k) {
            const OccupancyMap image = Fuse(fusion, changes, active, k, FusionMethod::kImageBased);
            const OccupancyMap gather = Fuse(fusion, changes, active, k, FusionMethod::kMapBased);
            const OccupancyMap oracle = RuleOracle(lut, votes, k);
            ASSERT_EQ(FirstDifference(image, gather), "") << "small=" << small << " density=" << density << " k=" << k;
            ASSERT_EQ(FirstDifference(image, oracle), "") << "small=" << small << " density=" << density << " k=" << k;
          }
        }
      }
    }
  }
}

TEST(Fusion, ImageBasedAndMapBasedAgreeOnObjectScenes) {
  const Scene scene = MakeRoom(64, 48, /*fifth=*/true);
  const GroundLut& lut = scene.lut;
  Fusion fusion(lut);
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> x(0.3, 3.7), y(0.3, 3.7), radius(0.05, 0.5), height(0.0, 2.0);
  int64_t occupied_total = 0;
  for (int seed = 0; seed < 30; ++seed) {
    std::vector<uint8_t> changes = RandomChanges(rng, lut, seed % 2 == 0 ? 0.0 : 0.02);  // with some noise
    std::vector<Cylinder> people;
    for (int i = 0; i < 1 + seed % 4; ++i) people.push_back({x(rng), y(rng), radius(rng), height(rng)});
    if (seed % 3 == 0) people.push_back({x(rng), y(rng), radius(rng), 0.0});  // a disc on the floor
    MarkCylinders(scene, people, changes);
    if (seed % 5 == 0) MarkFloorBox(lut, 0.2, 2.0, 1.1, 2.6, changes);
    for (int trial = 0; trial < 3; ++trial) {
      const std::vector<bool> active = trial == 0 ? std::vector<bool>(static_cast<size_t>(lut.num_cameras()), true)
                                                  : RandomActive(rng, lut.num_cameras());
      const Votes votes = CountVotes(lut, changes, active);
      for (int k = 0; k <= 2; ++k) {
        const OccupancyMap image = Fuse(fusion, changes, active, k, FusionMethod::kImageBased);
        const OccupancyMap gather = Fuse(fusion, changes, active, k, FusionMethod::kMapBased);
        ASSERT_EQ(FirstDifference(image, gather), "") << "seed " << seed << " k=" << k;
        ASSERT_EQ(FirstDifference(image, RuleOracle(lut, votes, k)), "") << "seed " << seed << " k=" << k;
        occupied_total += image.Count(CellState::kOccupied);
      }
    }
  }
  EXPECT_GT(occupied_total, 1000);  // the scenes do produce occupied cells
}

TEST(Fusion, ImageBasedAndIsThePapersLoopWithUnseenCellsMapped) {
  for (const bool small : {false, true}) {
    const Scene scene = small ? MakeRoom(64, 48, true) : MakeRoom(160, 120, false);
    const GroundLut& lut = scene.lut;
    Fusion fusion(lut);
    std::mt19937 rng(31);
    const std::vector<bool> all(static_cast<size_t>(lut.num_cameras()), true);
    for (double density : {0.0, 0.3, 0.9, 0.999, 1.0}) {
      std::vector<uint8_t> changes = RandomChanges(rng, lut, density);
      MarkCylinders(scene, {{1.0, 1.0, 0.3, 1.7}, {3.0, 2.0, 0.2, 1.2}}, changes);
      const std::vector<uint8_t> paper = PaperImageBasedLoop(lut, changes);
      ASSERT_EQ(paper.size(), static_cast<size_t>(lut.grid().num_cells()) + 1);
      // The paper's O with the sentinel dropped and unseen cells (O = 1, no view) mapped.
      OccupancyMap expected(lut.grid());
      for (size_t cell = 0; cell + 1 < paper.size(); ++cell) {
        expected.states()[cell] = lut.view_count()[cell] == 0 ? CellState::kUnseen
                                  : paper[cell] != 0         ? CellState::kOccupied
                                                             : CellState::kFree;
      }
      for (FusionMethod method : {FusionMethod::kImageBased, FusionMethod::kMapBased}) {
        ASSERT_EQ(FirstDifference(Fuse(fusion, changes, all, 0, method), expected), "") << "density " << density;
      }
    }
  }
}

// A hand-worked floor of 4 cells of 1 m in a row, seen by three homography cameras of one
// row each:  A (3 pixels) sees cells 0, 1, 2, one pixel each;
//            B (4 pixels) sees cells 0, 1, two pixels each;
//            C (3 pixels) sees cells 1, 2, 3, one pixel each.
// Global pixel ids: A 0..2, B 3..6, C 7..9.
class HandWorkedFusion : public ::testing::Test {
 protected:
  HandWorkedFusion() {
    auto camera = [](double scale, double shift, int width) {
      Eigen::Matrix3d floor_from_image;
      floor_from_image << scale, 0, shift, 0, 1, 0.5, 0, 0, 1;  // x = scale u + shift, y = v + 0.5
      return HomographyCamera::Create(floor_from_image, {width, 1}).value();
    };
    cameras_ = {camera(1.0, 0.5, 3), camera(0.5, 0.25, 4), camera(1.0, 1.5, 3)};
    const FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 4, .cells_y = 1, .cell_size_m = 1};
    Context ctx(1);
    lut_ = BuildGroundLut({{&cameras_[0], {}}, {&cameras_[1], {}}, {&cameras_[2], {}}}, grid, {}, ctx).value();
  }

  // changes as "AAA BBBB CCC" digits; active as three 0/1 flags.
  std::string Fused(const std::string& changes_text, std::vector<bool> active, int k, FusionMethod method) {
    std::vector<uint8_t> changes;
    for (char c : changes_text) {
      if (c != ' ') changes.push_back(static_cast<uint8_t>(c - '0'));
    }
    Fusion fusion(lut_);
    return Letters(Fuse(fusion, changes, active, k, method));
  }

  std::vector<HomographyCamera> cameras_;
  GroundLut lut_;
};

TEST_F(HandWorkedFusion, TablesAreTheOnesDrawnAbove) {
  ASSERT_EQ(lut_.total_pixels(), 10u);
  const std::vector<std::vector<uint32_t>> expected = {{0, 3, 4}, {1, 5, 6, 7}, {2, 8}, {9}};
  for (int64_t cell = 0; cell < 4; ++cell) {
    const auto l2 = lut_.l2_pixels_of(cell);
    EXPECT_EQ(std::vector<uint32_t>(l2.begin(), l2.end()), expected[static_cast<size_t>(cell)]) << cell;
  }
  const auto counts = lut_.view_count();
  EXPECT_EQ(std::vector<uint8_t>(counts.begin(), counts.end()), (std::vector<uint8_t>{2, 3, 2, 1}));
}

TEST_F(HandWorkedFusion, VoteRuleCountsCamerasSayingFreeAndNeedsOneThatDoesNot) {
  const std::vector<bool> all = {true, true, true};
  for (FusionMethod m : {FusionMethod::kImageBased, FusionMethod::kMapBased}) {
    // Only pixel B4 (cell 0) is unchanged: B says free for cell 0 and for nothing else.
    EXPECT_EQ(Fused("111 1011 111", all, 0, m), "FOOO");
    EXPECT_EQ(Fused("111 1011 111", all, 1, m), "OOOO");  // one free vote of two: occupied
    // A says free for cells 0, 1; C for cells 1, 3; B for none. Votes per cell: 1, 2, 0, 1.
    EXPECT_EQ(Fused("001 1111 010", all, 0, m), "FFOF");
    EXPECT_EQ(Fused("001 1111 010", all, 1, m), "OFOF");  // cell 3: its only camera says free
    EXPECT_EQ(Fused("001 1111 010", all, 2, m), "OOOF");  // cell 1: 2 <= 2 and B disagrees
    // A camera with one unchanged pixel among several still says free (cell 1: B6).
    EXPECT_EQ(Fused("111 1110 111", all, 0, m), "OFOO");
    EXPECT_EQ(Fused("111 1110 111", all, 1, m), "OOOO");
    // Nothing changed: free everywhere for every k; everything changed: occupied everywhere.
    for (int k = 0; k <= 2; ++k) {
      EXPECT_EQ(Fused("000 0000 000", all, k, m), "FFFF") << k;
      EXPECT_EQ(Fused("111 1111 111", all, k, m), "OOOO") << k;
    }
  }
}

TEST_F(HandWorkedFusion, InactiveCamerasAreIgnoredAndCellsOnlyTheySeeAreUnseen) {
  for (FusionMethod m : {FusionMethod::kImageBased, FusionMethod::kMapBased}) {
    // C inactive: cell 3 is unseen whatever C's bytes say; cells 1 and 2 lose C's vote.
    for (const char* c_bytes : {"000", "111", "101"}) {
      const std::string changes = std::string("001 1111 ") + c_bytes;
      EXPECT_EQ(Fused(changes, {true, true, false}, 0, m), "FFOU") << c_bytes;
      EXPECT_EQ(Fused(changes, {true, true, false}, 1, m), "OOOU") << c_bytes;
    }
    // A inactive: cell 0 is B's alone (B4 unchanged: free), the rest C's and B's.
    EXPECT_EQ(Fused("000 1011 111", {false, true, true}, 0, m), "FOOO");
    EXPECT_EQ(Fused("000 1011 111", {false, true, true}, 1, m), "FOOO");  // one voter, says free
    // No camera active: nothing is seen.
    EXPECT_EQ(Fused("111 1111 111", {false, false, false}, 0, m), "UUUU");
  }
}

TEST_F(HandWorkedFusion, PapersLoopKeepsTheSentinelCellAtTheEnd) {
  std::vector<uint8_t> changes = {0, 0, 1, 1, 1, 1, 1, 0, 1, 0};
  const std::vector<uint8_t> paper = PaperImageBasedLoop(lut_, changes);
  EXPECT_EQ(paper, (std::vector<uint8_t>{0, 0, 1, 0, 1}));  // 4 cells and the untouched sentinel
}

TEST(Fusion, AllPixelsChangedMakesEverySeenCellOccupiedAndNoChangeMakesEverySeenCellFree) {
  const Scene scene = MakeRoom(64, 48, true);
  const GroundLut& lut = scene.lut;
  Fusion fusion(lut);
  const std::vector<bool> all(static_cast<size_t>(lut.num_cameras()), true);
  const std::vector<uint8_t> changed(lut.total_pixels(), 255), unchanged(lut.total_pixels(), 0);
  int64_t seen = 0;
  for (uint8_t v : lut.view_count()) seen += v > 0;
  ASSERT_GT(seen, 0);
  for (int k = 0; k < lut.num_cameras(); ++k) {
    for (FusionMethod m : {FusionMethod::kImageBased, FusionMethod::kMapBased}) {
      const OccupancyMap full = Fuse(fusion, changed, all, k, m);
      EXPECT_EQ(full.Count(CellState::kOccupied), seen) << k;
      EXPECT_EQ(full.Count(CellState::kUnseen), lut.grid().num_cells() - seen) << k;
      const OccupancyMap empty = Fuse(fusion, unchanged, all, k, m);
      EXPECT_EQ(empty.Count(CellState::kOccupied), 0) << k;
      EXPECT_EQ(empty.Count(CellState::kFree), seen) << k;
      for (size_t c = 0; c < full.states().size(); ++c) {
        ASSERT_EQ(full.states()[c] == CellState::kUnseen, lut.view_count()[c] == 0) << c;
      }
    }
  }
}

TEST(Fusion, InactiveCameraLeavesTheCellsOnlyItSeesUnseenAndItsBytesUnread) {
  const Scene scene = MakeRoom(64, 48, true);
  const GroundLut& lut = scene.lut;
  Fusion fusion(lut);
  std::mt19937 rng(41);
  int64_t cells_seen_alone = 0;
  for (int off = 0; off < lut.num_cameras(); ++off) {
    std::vector<bool> active(static_cast<size_t>(lut.num_cameras()), true);
    active[static_cast<size_t>(off)] = false;
    // Cells that camera `off` alone sees.
    std::vector<uint8_t> only_off(static_cast<size_t>(lut.grid().num_cells()), 0);
    int64_t num_only_off = 0;
    for (int64_t cell = 0; cell < lut.grid().num_cells(); ++cell) {
      bool others = false, mine = false;
      for (uint32_t p : lut.l2_pixels_of(cell)) (CameraOf(lut, p) == off ? mine : others) = true;
      if (mine && !others) {
        only_off[static_cast<size_t>(cell)] = 1;
        ++num_only_off;
      }
    }
    std::vector<uint8_t> changes = RandomChanges(rng, lut, 0.6);
    const uint32_t begin = lut.pixel_offset(off), end = lut.pixel_offset(off + 1);
    for (int k = 0; k <= 1; ++k) {
      for (FusionMethod m : {FusionMethod::kImageBased, FusionMethod::kMapBased}) {
        std::fill(changes.begin() + begin, changes.begin() + end, uint8_t{1});  // all changed
        const OccupancyMap a = Fuse(fusion, changes, active, k, m);
        std::fill(changes.begin() + begin, changes.begin() + end, uint8_t{0});  // all unchanged
        const OccupancyMap b = Fuse(fusion, changes, active, k, m);
        ASSERT_EQ(FirstDifference(a, b), "") << "camera " << off << " k=" << k;
        for (size_t c = 0; c < only_off.size(); ++c) {
          const bool seen_by_others = lut.view_count()[c] > 0 && !only_off[c];
          ASSERT_EQ(a.states()[c] == CellState::kUnseen, !seen_by_others) << c;
        }
      }
    }
    cells_seen_alone += num_only_off;
  }
  EXPECT_GT(cells_seen_alone, 100);  // the strip beyond the far wall has such cells
}

TEST(Fusion, StandingCylinderIsReconstructedOnItsFootprint) {
  // A person-sized cylinder in the middle of the room: every pixel whose ray passes through it
  // is changed, nothing else. Cells well inside its footprint (a margin of half a cell's
  // diagonal plus a pixel's footprint on the floor) must be occupied, and with four corner
  // cameras nothing beyond a thin rim around it is (the visual hull hugs the disc).
  const Scene scene = MakeRoom(160, 120, false);
  const GroundLut& lut = scene.lut;
  const Cylinder person{2.1, 1.4, 0.35, 1.8};
  std::vector<uint8_t> changes(lut.total_pixels(), 0);
  MarkCylinders(scene, {person}, changes);
  Fusion fusion(lut);
  const std::vector<bool> all(4, true);
  for (FusionMethod m : {FusionMethod::kImageBased, FusionMethod::kMapBased}) {
    const OccupancyMap map = Fuse(fusion, changes, all, 0, m);
    int64_t footprint = 0;
    for (int64_t cell = 0; cell < lut.grid().num_cells(); ++cell) {
      const double distance = (lut.grid().CellCenter(cell) - Eigen::Vector2d(person.x_m, person.y_m)).norm();
      const CellState state = map.state(cell);
      if (distance <= person.radius_m - 0.1) {
        ++footprint;
        ASSERT_EQ(state, CellState::kOccupied) << "footprint cell " << cell << " at " << distance << " m";
      }
      if (distance > person.radius_m + 0.1) {
        ASSERT_NE(state, CellState::kOccupied) << "cell " << cell << " at " << distance << " m";
      }
    }
    EXPECT_GT(footprint, 60);
    EXPECT_GE(map.Count(CellState::kOccupied), footprint);
  }
}

TEST(Fusion, ReusesTheMapAndFollowsChangesOfTheActiveSet) {
  const Scene scene = MakeRoom(64, 48, true);
  const GroundLut& lut = scene.lut;
  Fusion fusion(lut);
  std::mt19937 rng(51);
  OccupancyMap map;  // default-constructed: the first call gives it the lut's grid
  const CellState* storage = nullptr;
  for (int frame = 0; frame < 30; ++frame) {
    const std::vector<uint8_t> changes = RandomChanges(rng, lut, 0.7);
    const std::vector<bool> active = frame % 3 == 0 ? std::vector<bool>(5, true) : RandomActive(rng, 5);
    FusionOptions options;
    options.method = frame % 2 == 0 ? FusionMethod::kImageBased : FusionMethod::kMapBased;
    options.max_free_views = frame % 4 == 1 ? 1 : 0;
    fusion.Fuse(changes, active, options, map);
    if (storage == nullptr) storage = map.states().data();
    ASSERT_EQ(map.states().data(), storage) << "frame " << frame;  // no reallocation of the map
    ASSERT_TRUE(map.grid() == lut.grid());
    // A fresh Fusion (no cached view counts) agrees: the cache follows the active set.
    Fusion fresh(lut);
    OccupancyMap expected;
    fresh.Fuse(changes, active, options, expected);
    ASSERT_EQ(FirstDifference(map, expected), "") << "frame " << frame;
  }
}

TEST(FusionOptions, ValidateAcceptsFewerFreeViewsThanCameras) {
  EXPECT_TRUE(FusionOptions{}.Validate(1).ok());
  EXPECT_TRUE((FusionOptions{.method = FusionMethod::kMapBased, .max_free_views = 6}).Validate(7).ok());
  EXPECT_EQ(FusionOptions{.max_free_views = 7}.Validate(7).message(),
            "max_free_views: expected 0..6 (fewer than the 7 cameras), found 7");
  EXPECT_EQ(FusionOptions{.max_free_views = -1}.Validate(4).message(),
            "max_free_views: expected 0..3 (fewer than the 4 cameras), found -1");
  EXPECT_EQ(FusionOptions{.method = static_cast<FusionMethod>(9)}.Validate(4).message(),
            "method: expected image-based or map-based");
}

TEST(OccupancyMap, GrayImageHasOnePixelPerCellWithYUp) {
  const FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 3, .cells_y = 2, .cell_size_m = 0.5};
  OccupancyMap map(grid);
  // Row j = 0 (bottom of the picture): free, occupied, unseen; row j = 1 (top): all occupied.
  map.states() = {CellState::kFree, CellState::kOccupied, CellState::kUnseen,
                  CellState::kOccupied, CellState::kOccupied, CellState::kOccupied};
  const Image<uint8_t> image = map.ToGrayImage();
  ASSERT_EQ(image.width(), 3);
  ASSERT_EQ(image.height(), 2);
  EXPECT_EQ(image(0, 1), 255);
  EXPECT_EQ(image(1, 1), 0);
  EXPECT_EQ(image(2, 1), 128);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(image(i, 0), 0);
  EXPECT_EQ(map.Count(CellState::kOccupied), 4);
  EXPECT_EQ(map.Count(CellState::kFree), 1);
  EXPECT_EQ(map.Count(CellState::kUnseen), 1);
  EXPECT_EQ(OccupancyMap(grid).Count(CellState::kUnseen), 6);  // a new map is all unseen
}

}  // namespace
}  // namespace occmap
