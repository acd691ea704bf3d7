#include "occmap/sim/scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "occmap/sim/gt_rasters.h"
#include "occmap/sim/sim_test_util.h"

namespace occmap::sim {
namespace {

double PolygonArea(const std::vector<Eigen::Vector2d>& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const auto& u = p[i];
    const auto& v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return 0.5 * a;
}

TEST(ScenePath, PositionsAreInterpolatedLinearlyBetweenWaypoints) {
  const std::vector<Waypoint> path = {{0.0, {0, 0}, false}, {2.0, {2, 0}, false}, {4.0, {2, 2}, false}};
  const PathSample s = SamplePath(path, 0.5);
  ASSERT_TRUE(s.present);
  EXPECT_NEAR((s.position_m - Eigen::Vector2d(0.5, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR(s.speed_m_s, 1.0, 1e-12);
  EXPECT_NEAR(s.heading_rad, 0.0, 1e-12);
  const PathSample t = SamplePath(path, 3.0);
  EXPECT_NEAR((t.position_m - Eigen::Vector2d(2, 1)).norm(), 0, 1e-12);
  EXPECT_NEAR(t.heading_rad, M_PI / 2, 1e-12);
  EXPECT_NEAR(t.distance_m, 3.0, 1e-12);
  EXPECT_FALSE(SamplePath(path, -0.1).present);
  EXPECT_FALSE(SamplePath(path, 4.1).present);
}

TEST(ScenePath, ObjectIsAbsentDuringAGapAndPresentAtItsEnds) {
  const std::vector<Waypoint> path = {{0.0, {0, 0}, false}, {1.0, {1, 0}, false}, {3.0, {5, 5}, true}, {4.0, {6, 5}, false}};
  EXPECT_TRUE(SamplePath(path, 1.0).present);
  EXPECT_FALSE(SamplePath(path, 1.5).present);
  EXPECT_FALSE(SamplePath(path, 2.9).present);
  const PathSample back = SamplePath(path, 3.0);
  ASSERT_TRUE(back.present);
  EXPECT_NEAR((back.position_m - Eigen::Vector2d(5, 5)).norm(), 0, 1e-12);
  EXPECT_NEAR(back.heading_rad, 0.0, 1e-12);  // it faces where it goes next
}

TEST(ScenePerson, LegsAlternateWhileWalkingAndOneFootIsAlwaysOnTheFloor) {
  MovingObjectSpec person;
  person.object_class = ObjectClass::kPerson;
  person.appearance.height_m = 1.75;
  person.path = {{0.0, {0, 0}, false}, {10.0, {13, 0}, false}};
  double left_ahead_max = 0, right_ahead_max = 0;
  for (int i = 0; i < 60; ++i) {
    const PathSample pose = SamplePath(person.path, 0.05 * i);
    const ObjectInstance inst = MakeInstance(person, pose);
    ASSERT_FALSE(inst.footprint_m.empty()) << "no foot on the floor at " << 0.05 * i << " s";
    // Feet are the upright boxes: parts 2 (left) and 5 (right); their centres' x relative to the body.
    const double left = inst.parts[2].a.x() - pose.position_m.x();
    const double right = inst.parts[5].a.x() - pose.position_m.x();
    left_ahead_max = std::max(left_ahead_max, left - right);
    right_ahead_max = std::max(right_ahead_max, right - left);
    // The person faces +x and is about as tall as asked.
    EXPECT_NEAR(inst.heading_rad, 0.0, 1e-9);
    EXPECT_NEAR(inst.bound.z_max_m, 1.75, 0.08);
  }
  EXPECT_GT(left_ahead_max, 0.4);
  EXPECT_GT(right_ahead_max, 0.4);
}

TEST(SceneChair, FootprintIsFourLegsWithFloorBetweenThem) {
  MovingObjectSpec chair;
  chair.object_class = ObjectClass::kChair;
  chair.appearance.height_m = 0.9;
  chair.appearance.width_m = chair.appearance.depth_m = 0.46;
  chair.path = {{0.0, {2, 2}, false}};
  const ObjectInstance inst = MakeInstance(chair, SamplePath(chair.path, 0.0));
  ASSERT_EQ(inst.footprint_m.size(), 4u);
  double area = 0;
  for (const auto& leg : inst.footprint_m) {
    EXPECT_GT(PolygonArea(leg), 0);  // counter-clockwise
    area += PolygonArea(leg);
    EXPECT_FALSE(PointInPolygon(leg, {2, 2}));
  }
  // Concave: the legs cover a small part of the square they span.
  EXPECT_LT(area, 0.05 * 0.46 * 0.46);
  const GroundTruthFrame gt = ToGroundTruth(SceneState{0, 0.0, {inst}});
  ASSERT_EQ(gt.objects.size(), 1u);
  EXPECT_NEAR(PolygonArea(gt.objects[0].footprint_m), area, 1e-12);  // bridges have no area
  for (const auto& leg : inst.footprint_m) {
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (const auto& v : leg) c += v / static_cast<double>(leg.size());
    EXPECT_TRUE(PointInPolygon(gt.objects[0].footprint_m, c));
  }
  EXPECT_FALSE(PointInPolygon(gt.objects[0].footprint_m, {2, 2}));
}

TEST(SceneChair, EveryFootprintPointIsUnderTheObjectFromAnyCameraAbove) {
  for (ObjectClass c : {ObjectClass::kChair, ObjectClass::kRobot, ObjectClass::kBox, ObjectClass::kPerson}) {
    MovingObjectSpec o;
    o.object_class = c;
    o.appearance = RandomAppearance(c, 3, 4, {0.5f, 0.5f, 0.5f});
    o.path = {{0.0, {1, 1}, false}, {2.0, {3, 1.5}, false}};
    const ObjectInstance inst = MakeInstance(o, SamplePath(o.path, 0.7));
    const SceneState state{0, 0.7, {inst}};
    for (const auto& poly : inst.footprint_m) {
      for (const auto& v : poly) {
        const Eigen::Vector2d inside = v + 1e-3 * (poly[0] + poly[poly.size() / 2] - 2 * v).normalized();
        for (const Eigen::Vector3d& cam : {Eigen::Vector3d(-3, -2, 2.7), Eigen::Vector3d(6, 5, 2.5)}) {
          EXPECT_TRUE(BlockedByObjects(state, cam, {inside.x(), inside.y(), 0.0})) << ToString(c);
        }
      }
    }
  }
}

TEST(SceneLab, MovingObjectsNeverOverlapOnTheFloor) {
  const Scene lab = sim_testing::SmallLab();
  for (int64_t f = 0; f < lab.num_frames(); f += 3) {
    const SceneState state = lab.StateAt(f);
    EXPECT_EQ(state.objects.size(), 5u);
    std::vector<int> owner(static_cast<size_t>(lab.grid().num_cells()), 0);
    for (const ObjectInstance& obj : state.objects) {
      const std::vector<uint8_t> feet = FootprintRaster(lab.grid(), SceneState{f, 0, {obj}});
      for (size_t i = 0; i < feet.size(); ++i) {
        if (!feet[i]) continue;
        EXPECT_EQ(owner[i], 0) << "objects " << owner[i] << " and " << obj.id << " at frame " << f;
        owner[i] = static_cast<int>(obj.id);
      }
    }
  }
}

TEST(SceneSpecValidation, RejectsDuplicateIdsAndBadPaths) {
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kBox);
  EXPECT_TRUE(spec.Validate().ok());
  SceneSpec dup = spec;
  dup.objects.push_back(dup.objects[0]);
  EXPECT_EQ(dup.Validate().message(), "object id 7: duplicate");
  SceneSpec back = spec;
  back.objects[0].path[1].t_s = -1;
  EXPECT_EQ(back.Validate().message(), "object 7: waypoint 1: expected times in increasing order, found -1 after 0");
  SceneSpec cam = spec;
  cam.cameras[1].id = "top";
  EXPECT_EQ(cam.Validate().message(), "camera id 'top': duplicate");
}

}  // namespace
}  // namespace occmap::sim
