#include "occmap/sim/primitives.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <random>

#include "occmap/sim/renderer.h"
#include "occmap/sim/sim_test_util.h"

namespace occmap::sim {
namespace {

const Material kGrey;

TEST(Primitives, RayHitsBoxFaceAtItsDistanceWithOutwardNormal) {
  const Primitive box = Primitive::UprightBox({0, 0}, 0.0, 1.0, {0.5, 0.5}, 0.0, kGrey);
  const auto hit = IntersectRay(box, {-3, 0, 0.5}, {1, 0, 0}, 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->t, 2.5, 1e-12);
  EXPECT_NEAR((hit->normal_in_world - Eigen::Vector3d(-1, 0, 0)).norm(), 0, 1e-12);
  const auto top = IntersectRay(box, {0.1, 0.2, 3}, {0, 0, -1}, 100);
  ASSERT_TRUE(top);
  EXPECT_NEAR(top->t, 2.0, 1e-12);
  EXPECT_NEAR(top->normal_in_world.z(), 1.0, 1e-12);
}

TEST(Primitives, RotatedBoxIsHitOnItsRotatedFace) {
  // A 2 x 0.2 box turned by 90 degrees is long in y: a ray along x meets it 0.1 from its centre.
  const Primitive box = Primitive::UprightBox({0, 0}, 0.0, 1.0, {1.0, 0.1}, M_PI / 2, kGrey);
  const auto hit = IntersectRay(box, {-3, 0.9, 0.5}, {1, 0, 0}, 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->t, 2.9, 1e-12);
  EXPECT_FALSE(IntersectRay(box, {-3, 1.1, 0.5}, {1, 0, 0}, 100));
}

TEST(Primitives, RayBesideOrAwayFromAShapeMissesIt) {
  const Primitive sphere = Primitive::Sphere({0, 0, 1}, 0.5, kGrey);
  EXPECT_FALSE(IntersectRay(sphere, {-3, 0.6, 1}, {1, 0, 0}, 100));
  EXPECT_FALSE(IntersectRay(sphere, {-3, 0, 1}, {-1, 0, 0}, 100));  // behind the origin
  EXPECT_FALSE(IntersectRay(sphere, {-3, 0, 1}, {1, 0, 0}, 2.0));    // beyond t_max
}

TEST(Primitives, RayStartingInsideASolidDoesNotSeeIt) {
  EXPECT_FALSE(IntersectRay(Primitive::Sphere({0, 0, 0}, 1, kGrey), {0, 0, 0}, {1, 0, 0}, 100));
  EXPECT_FALSE(IntersectRay(Primitive::UprightBox({0, 0}, -1, 1, {1, 1}, 0, kGrey), {0, 0, 0}, {1, 0, 0}, 100));
}

TEST(Primitives, SphereAndEllipsoidHitsLieOnTheirSurfaces) {
  const Eigen::Matrix3d yaw = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Primitive ell = Primitive::Ellipsoid({1, 2, 1}, yaw, {0.3, 0.6, 0.9}, kGrey);
  const Primitive sph = Primitive::Sphere({1, 2, 1}, 0.4, kGrey);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  int hits = 0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d o(1 + 4 * u(rng), 2 + 4 * u(rng), 1 + 4 * u(rng));
    const Eigen::Vector3d target(1 + 0.5 * u(rng), 2 + 0.5 * u(rng), 1 + 0.5 * u(rng));
    const Eigen::Vector3d d = (target - o).normalized();
    if (auto h = IntersectRay(ell, o, d, 100)) {
      ++hits;
      const Eigen::Vector3d q = yaw.transpose() * (o + h->t * d - Eigen::Vector3d(1, 2, 1));
      EXPECT_NEAR((q.array() / Eigen::Array3d(0.3, 0.6, 0.9)).matrix().squaredNorm(), 1.0, 1e-9);
      EXPECT_LT(h->normal_in_world.dot(d), 0);  // the ray enters
    }
    if (auto h = IntersectRay(sph, o, d, 100)) {
      EXPECT_NEAR((o + h->t * d - Eigen::Vector3d(1, 2, 1)).norm(), 0.4, 1e-9);
      EXPECT_NEAR(h->normal_in_world.norm(), 1.0, 1e-12);
    }
  }
  EXPECT_GT(hits, 500);
}

TEST(Primitives, VerticalCylinderIsHitOnItsSideAndTopCap) {
  const Primitive cyl = Primitive::VerticalCylinder({1, 1}, 0.25, 0.0, 0.4, kGrey);
  const auto side = IntersectRay(cyl, {-1, 1, 0.2}, {1, 0, 0}, 100);
  ASSERT_TRUE(side);
  EXPECT_NEAR(side->t, 1.75, 1e-12);
  EXPECT_NEAR(side->normal_in_world.x(), -1, 1e-12);
  const auto top = IntersectRay(cyl, {1.1, 1.1, 2}, {0, 0, -1}, 100);
  ASSERT_TRUE(top);
  EXPECT_NEAR(top->t, 1.6, 1e-12);
  EXPECT_NEAR(top->normal_in_world.z(), 1, 1e-12);
  EXPECT_FALSE(IntersectRay(cyl, {-1, 1, 0.5}, {1, 0, 0}, 100));  // above it
}

TEST(Primitives, CapsuleIsHitOnItsBodyAndOnItsRoundEnds) {
  const Primitive cap = Primitive::Capsule({0, 0, 0.5}, {0, 0, 1.5}, 0.1, kGrey);
  const auto body = IntersectRay(cap, {-2, 0, 1.0}, {1, 0, 0}, 100);
  ASSERT_TRUE(body);
  EXPECT_NEAR(body->t, 1.9, 1e-12);
  const auto end = IntersectRay(cap, {0, 0, 3}, {0, 0, -1}, 100);
  ASSERT_TRUE(end);
  EXPECT_NEAR(end->t, 3 - 1.6, 1e-12);
  EXPECT_NEAR(end->normal_in_world.z(), 1, 1e-12);
  // A ray that meets the infinite cylinder beyond the segment still finds the lower end.
  const Eigen::Vector3d d = Eigen::Vector3d(1, 0, 1).normalized();
  const auto low = IntersectRay(cap, Eigen::Vector3d(0, 0, 0.5) - 2 * d, d, 100);
  ASSERT_TRUE(low);
  EXPECT_NEAR(low->t, 1.9, 1e-9);
}

TEST(Primitives, HorizontalRectangleIsSeenFromItsFacingSideOnly) {
  const Primitive floor = Primitive::HorizontalRect(0, 0, 4, 3, 0.0, +1, kGrey);
  EXPECT_TRUE(IntersectRay(floor, {1, 1, 2}, {0, 0, -1}, 100));
  EXPECT_FALSE(IntersectRay(floor, {1, 1, -2}, {0, 0, 1}, 100));
  EXPECT_FALSE(IntersectRay(floor, {5, 1, 2}, {0, 0, -1}, 100));  // off the rectangle
}

TEST(Primitives, SegmentIsBlockedOnlyBySomethingBetweenItsEnds) {
  const Primitive box = Primitive::UprightBox({2, 0}, 0.0, 1.0, {0.2, 0.2}, 0.0, kGrey);
  EXPECT_TRUE(SegmentBlocked(box, {0, 0, 0.5}, {4, 0, 0.5}));
  EXPECT_FALSE(SegmentBlocked(box, {0, 0, 0.5}, {1.5, 0, 0.5}));
  // A floor point under the box is blocked from above (the theorem's ray), one beside it not.
  EXPECT_TRUE(SegmentBlocked(box, {0, 0, 2.7}, {2.1, 0.1, 0.0}));
  EXPECT_FALSE(SegmentBlocked(box, {0, 0, 2.7}, {1.7, 0.0, 0.0}));
}

TEST(Primitives, CylinderBoundIntervalContainsEveryHitOfWhatItBounds) {
  const Primitive cap = Primitive::Capsule({1, 1, 0.3}, {1.2, 0.9, 1.4}, 0.12, kGrey);
  Eigen::Vector3d lo, hi;
  cap.Bounds(&lo, &hi);
  CylinderBound bound;
  bound.centre_xy_m = 0.5 * (lo + hi).head<2>();
  bound.radius_m = 0.5 * (hi - lo).head<2>().norm();
  bound.z_min_m = lo.z();
  bound.z_max_m = hi.z();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  int hits = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d o(1 + 3 * u(rng), 1 + 3 * u(rng), 2.7);
    const Eigen::Vector3d d = (Eigen::Vector3d(1.1 + 0.3 * u(rng), 1 + 0.3 * u(rng), 0.8 + 0.6 * u(rng)) - o).normalized();
    if (auto h = IntersectRay(cap, o, d, 100)) {
      ++hits;
      const auto iv = RayCylinderInterval(bound, o, d);
      ASSERT_TRUE(iv);
      EXPECT_LE(iv->first, h->t + 1e-12);
      EXPECT_GE(iv->second, h->t - 1e-12);
    }
  }
  EXPECT_GT(hits, 300);
}

TEST(Primitives, LambertShadingIsAlbedoTimesAmbientPlusCosine) {
  Lighting light;
  light.ambient = 0.4;
  light.intensity = 0.5;
  light.direction_to_light = Eigen::Vector3d(0, 0.6, 0.8);
  Material m;
  m.colour = {0.5f, 0.25f, 1.0f};
  const Eigen::Vector3f c = Shade(m, {0, 0, 0}, {0, 0, 1}, light);
  EXPECT_NEAR(c[0], 0.5 * (0.4 + 0.5 * 0.8), 1e-6);
  EXPECT_NEAR(c[2], 1.0 * (0.4 + 0.5 * 0.8), 1e-6);
  const Eigen::Vector3f back = Shade(m, {0, 0, 0}, {0, 0, -1}, light);  // facing away: ambient only
  EXPECT_NEAR(back[0], 0.5 * 0.4, 1e-6);
}

TEST(Primitives, WhiteLightColoursShadeAndRenderExactlyAsBefore) {
  // Shade with the default (white) colours is albedo * ambient + albedo * (intensity * cos),
  // bit for bit, as it was before the colours existed.
  Lighting light;
  light.ambient = 0.37;
  light.intensity = 0.61;
  light.direction_to_light = Eigen::Vector3d(0.3, -0.2, 0.9).normalized();
  uint64_t h = 99;
  for (int k = 0; k < 1000; ++k) {
    Material m;
    h = Mix64(h);
    m.colour = {static_cast<float>(UnitFromHash(h)), static_cast<float>(UnitFromHash(Mix64(h + 1))),
                static_cast<float>(UnitFromHash(Mix64(h + 2)))};
    const Eigen::Vector3d n = Eigen::Vector3d(UnitFromHash(Mix64(h + 3)) - 0.5, UnitFromHash(Mix64(h + 4)) - 0.5, 1).normalized();
    const double cosine = std::max(0.0, n.dot(light.direction_to_light));
    const Eigen::Vector3f direct = m.colour * static_cast<float>(light.intensity * cosine);
    const Eigen::Vector3f before = m.colour * static_cast<float>(light.ambient) + direct;
    ASSERT_TRUE(Shade(m, {0, 0, 0}, n, light) == before) << k;
  }
  // And a lab frame hashes as rendered before (FNV-1a of the RGB bytes of camera 0, frame 20,
  // scale 0.25, seed 1, noise on; computed with the renderer of the commit before the colours).
  const Scene lab = sim_testing::SmallLab(0.25, 30);
  Context ctx(2);
  RenderedView view;
  CameraRenderer(lab, 0, ctx).Render(lab.StateAt(20), ctx, &view);
  uint64_t fnv = 0xcbf29ce484222325ULL;
  for (int y = 0; y < view.rgb.height(); ++y) {
    for (int x = 0; x < view.rgb.width(); ++x) {
      for (uint8_t byte : {view.rgb(x, y).r, view.rgb(x, y).g, view.rgb(x, y).b}) fnv = (fnv ^ byte) * 0x100000001b3ULL;
    }
  }
  EXPECT_EQ(fnv, 0x2cdc42b5f3de7aa5ULL);
}

}  // namespace
}  // namespace occmap::sim
