#include "occmap/lut/ground_lut.h"

#include <gtest/gtest.h>

#include <map>
#include <set>

#include "occmap/geometry/homography_camera.h"
#include "occmap/lut/test_scene.h"

namespace occmap {
namespace {

using testing::LookAtCamera;
using testing::SmallRoom;

std::vector<LutCameraInput> Inputs(const std::vector<PinholeCamera>& cams) {
  std::vector<LutCameraInput> in;
  for (const auto& c : cams) in.push_back({&c, {}});
  return in;
}

TEST(GroundLut, L1IsThePixelRayRoundedToItsCell) {
  SmallRoom room;
  Context ctx(2);
  const GroundLut lut = BuildGroundLut(Inputs(room.cameras), room.grid, {}, ctx).value();
  for (int n = 0; n < 4; ++n) {
    const auto& cam = room.cameras[n];
    const auto l1 = lut.l1(n);
    for (int y = 0; y < 120; ++y) {
      for (int x = 0; x < 160; ++x) {
        const auto on_floor = cam.PixelToPlane(Eigen::Vector2d(x, y), 0.0);
        const int64_t cell = on_floor ? room.grid.CellAt(on_floor->x(), on_floor->y()) : -1;
        ASSERT_EQ(l1[y * 160 + x], cell < 0 ? lut.sentinel() : static_cast<uint32_t>(cell)) << n << " " << x << " " << y;
      }
    }
  }
}

TEST(GroundLut, RayAboveHorizonMapsToSentinel) {
  // A camera looking almost horizontally: the top rows see the sky.
  const PinholeCamera cam = LookAtCamera({0, -5, 1.5}, {0, 20, 0.5}, 64, 48, 50);
  const FloorGrid grid{.origin_x_m = -50, .origin_y_m = -50, .cells_x = 1000, .cells_y = 1000, .cell_size_m = 0.1};
  Context ctx(1);
  const GroundLut lut = BuildGroundLut({{&cam, {}}}, grid, {}, ctx).value();
  EXPECT_EQ(lut.l1(0)[0], lut.sentinel());  // top-left pixel: above the horizon
  EXPECT_NE(lut.l1(0)[47 * 64 + 32], lut.sentinel());  // bottom centre: the floor
  EXPECT_GT(lut.coverage()[0].pixels_no_ray, 64);
  EXPECT_EQ(lut.coverage()[0].pixels_no_ray + lut.coverage()[0].pixels_mapped + lut.coverage()[0].pixels_off_grid, 64 * 48);
}

TEST(GroundLut, MaskedPixelsMapToSentinelAndAreCounted) {
  SmallRoom room;
  Image<uint8_t> mask(160, 120, 255);
  for (int y = 60; y < 120; ++y) {
    for (int x = 0; x < 80; ++x) mask(x, y) = 0;
  }
  Context ctx(2);
  const GroundLut lut = BuildGroundLut({{&room.cameras[0], mask.view()}}, room.grid, {}, ctx).value();
  for (int y = 60; y < 120; ++y) {
    for (int x = 0; x < 80; ++x) ASSERT_EQ(lut.l1(0)[y * 160 + x], lut.sentinel());
  }
  EXPECT_EQ(lut.coverage()[0].pixels_masked, 60 * 80);
  // No added (coverage-fix) pixel is a masked one either.
  for (uint32_t p : lut.extra_pixels(0)) EXPECT_NE(mask(static_cast<int>(p % 160), static_cast<int>(p / 160)), 0);
}

TEST(GroundLut, L2HoldsExactlyThePixelCellPairsOfL1AndTheAddedProjections) {
  SmallRoom room;
  Context ctx(2);
  const GroundLut lut = BuildGroundLut(Inputs(room.cameras), room.grid, {}, ctx).value();
  std::map<uint32_t, std::multiset<uint32_t>> from_l1;
  for (int n = 0; n < 4; ++n) {
    const auto l1 = lut.l1(n);
    for (size_t p = 0; p < l1.size(); ++p) {
      if (l1[p] != lut.sentinel()) from_l1[l1[p]].insert(lut.pixel_offset(n) + static_cast<uint32_t>(p));
    }
    for (size_t e = 0; e < lut.extra_cells(n).size(); ++e) {
      from_l1[lut.extra_cells(n)[e]].insert(lut.pixel_offset(n) + lut.extra_pixels(n)[e]);
    }
  }
  for (int64_t cell = 0; cell < room.grid.num_cells(); ++cell) {
    const auto l2 = lut.l2_pixels_of(cell);
    const std::multiset<uint32_t> got(l2.begin(), l2.end());
    ASSERT_EQ(got, from_l1[static_cast<uint32_t>(cell)]) << "cell " << cell;
    std::set<int> cams;
    for (uint32_t p : l2) {
      for (int n = 0; n < 4; ++n) {
        if (p >= lut.pixel_offset(n) && p < lut.pixel_offset(n + 1)) cams.insert(n);
      }
    }
    ASSERT_EQ(lut.view_count()[cell], cams.size()) << "cell " << cell;
  }
}

// Cells "in view" of a camera: their centre projects onto an unmasked pixel of its image.
void ExpectEveryCellInViewHasAPixel(const GroundLut& lut, const std::vector<const CameraModel*>& cams) {
  for (size_t n = 0; n < cams.size(); ++n) {
    int64_t in_view = 0;
    for (int64_t cell = 0; cell < lut.grid().num_cells(); ++cell) {
      const Eigen::Vector2d c = lut.grid().CellCenter(cell);
      const auto px = cams[n]->Project({c.x(), c.y(), lut.plane_height_m()});
      if (!px || !cams[n]->InImage(*px)) continue;
      ++in_view;
      bool has_pixel = false;
      for (uint32_t p : lut.l2_pixels_of(cell)) has_pixel |= (p >= lut.pixel_offset(static_cast<int>(n)) && p < lut.pixel_offset(static_cast<int>(n) + 1));
      ASSERT_TRUE(has_pixel) << "camera " << n << " sees cell " << cell << " but has no pixel in it";
    }
    EXPECT_GT(in_view, 0);
  }
}

TEST(GroundLut, EveryCellInViewHasAtLeastOnePixelOfThatCamera) {
  SmallRoom room(64, 48);  // low resolution: far cells are much smaller than a pixel
  Context ctx(2);
  const GroundLut lut = BuildGroundLut(Inputs(room.cameras), room.grid, {}, ctx).value();
  std::vector<const CameraModel*> cams;
  for (const auto& c : room.cameras) cams.push_back(&c);
  ExpectEveryCellInViewHasAPixel(lut, cams);
  int64_t added = 0;
  for (const auto& c : lut.coverage()) added += c.cells_added;
  EXPECT_GT(added, 100);  // the fix matters here...
  LutOptions no_fix;
  no_fix.add_cell_projections = false;
  const GroundLut plain = BuildGroundLut(Inputs(room.cameras), room.grid, no_fix, ctx).value();
  int64_t seen_plain = 0, seen_fixed = 0;
  for (int n = 0; n < 4; ++n) {
    seen_plain += plain.coverage()[n].cells_seen;
    seen_fixed += lut.coverage()[n].cells_seen;
  }
  EXPECT_EQ(seen_fixed - seen_plain, added);  // ...and it is exactly the paper's coverage gap
}

TEST(GroundLut, PlaneAboveTheFloorUsesTheSameCode) {
  SmallRoom room;
  Context ctx(2);
  LutOptions chest;
  chest.plane_height_m = 1.2;
  const GroundLut lut = BuildGroundLut(Inputs(room.cameras), room.grid, chest, ctx).value();
  EXPECT_EQ(lut.plane_height_m(), 1.2);
  int checked = 0;
  for (int y = 0; y < 120; y += 7) {
    for (int x = 0; x < 160; x += 7) {
      const uint32_t cell = lut.l1(1)[y * 160 + x];
      if (cell == lut.sentinel()) continue;
      const auto p = room.cameras[1].PixelToPlane(Eigen::Vector2d(x, y), 1.2);
      ASSERT_TRUE(p.has_value());
      EXPECT_EQ(room.grid.CellAt(p->x(), p->y()), cell);
      ++checked;
    }
  }
  EXPECT_GT(checked, 50);
  std::vector<const CameraModel*> cams;
  for (const auto& c : room.cameras) cams.push_back(&c);
  ExpectEveryCellInViewHasAPixel(lut, cams);
  // A plane above the camera is never met in front of a camera looking down.
  chest.plane_height_m = 3.0;
  const GroundLut above = BuildGroundLut(Inputs(room.cameras), room.grid, chest, ctx).value();
  for (const auto& c : above.coverage()) EXPECT_EQ(c.pixels_mapped, 0);
}

TEST(GroundLut, IdenticalOnOneAndTwoThreads) {
  SmallRoom room;
  Context one(1), two(2);
  const GroundLut a = BuildGroundLut(Inputs(room.cameras), room.grid, {}, one).value();
  const GroundLut b = BuildGroundLut(Inputs(room.cameras), room.grid, {}, two).value();
  EXPECT_TRUE(a == b);
}

TEST(GroundLut, BadInputsAreRejectedWithMessages) {
  SmallRoom room;
  Context ctx(1);
  Image<uint8_t> small_mask(10, 10, 255);
  auto r = BuildGroundLut({{&room.cameras[0], small_mask.view()}}, room.grid, {}, ctx);
  EXPECT_EQ(r.status().message(), "camera 0: mask: expected 160x120 pixels (the image size), found 10x10");
  EXPECT_EQ(BuildGroundLut({}, room.grid, {}, ctx).status().message(), "cameras: expected at least one camera, found none");
  FloorGrid huge = room.grid;
  huge.cells_x = huge.cells_y = 1 << 15;
  EXPECT_EQ(BuildGroundLut(Inputs(room.cameras), huge, {}, ctx).status().code(), StatusCode::kResourceExhausted);
  Eigen::Matrix3d h = Eigen::Matrix3d::Identity();
  h(2, 2) = 100;
  const HomographyCamera hc = HomographyCamera::Create(h, {64, 48}).value();
  LutOptions knee;
  knee.plane_height_m = 0.5;
  EXPECT_EQ(BuildGroundLut({{&hc, {}}}, room.grid, knee, ctx).status().message(),
            "camera 0: a homography calibration only knows the floor; cannot build tables for plane_height_m = 0.5");
}

TEST(GroundLut, KeyChangesWithEveryInput) {
  SmallRoom room;
  const auto inputs = Inputs(room.cameras);
  const uint64_t base = GroundLutKey(inputs, room.grid, {});
  EXPECT_EQ(base, GroundLutKey(inputs, room.grid, {}));
  FloorGrid g = room.grid;
  g.cell_size_m = 0.051;
  EXPECT_NE(base, GroundLutKey(inputs, g, {}));
  LutOptions o;
  o.plane_height_m = 0.01;
  EXPECT_NE(base, GroundLutKey(inputs, room.grid, o));
  Image<uint8_t> mask(160, 120, 255);
  auto masked = inputs;
  masked[2].mask = mask.view();
  const uint64_t with_mask = GroundLutKey(masked, room.grid, {});
  EXPECT_NE(base, with_mask);
  mask(5, 5) = 0;
  EXPECT_NE(with_mask, GroundLutKey(masked, room.grid, {}));
  std::vector<PinholeCamera> moved = room.cameras;
  PinholeParameters p = moved[3].params();
  p.cam_from_world_translation_m.x() += 1e-9;
  moved[3] = PinholeCamera::Create(p).value();
  EXPECT_NE(base, GroundLutKey(Inputs(moved), room.grid, {}));
}

}  // namespace
}  // namespace occmap
