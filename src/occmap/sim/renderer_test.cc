#include "occmap/sim/renderer.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <optional>

#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/gt_rasters.h"
#include "occmap/sim/sim_test_util.h"

namespace occmap::sim {
namespace {

TEST(Renderer, FastRenderEqualsThePerPixelReferenceOnEveryPixel) {
  // The perfect change mask (ids != 0) is exactly the set of pixels whose ray meets a moving
  // object before the static scene, and colours are the reference shading.
  const Scene lab = sim_testing::SmallLab();
  Context ctx(2);
  for (size_t c = 0; c < lab.num_cameras(); ++c) {
    const CameraRenderer renderer(lab, c, ctx);
    for (int64_t f : {0, 37, 81}) {
      const SceneState state = lab.StateAt(f);
      RenderedView view;
      renderer.Render(state, ctx, &view, /*noise=*/false);
      int64_t changed = 0;
      for (int y = 0; y < view.ids.height(); ++y) {
        for (int x = 0; x < view.ids.width(); ++x) {
          const PixelTrace ref = TracePixelReference(lab, c, state, Eigen::Vector2d(x, y));
          ASSERT_EQ(view.ids(x, y), ref.id) << "camera " << c << " frame " << f << " pixel " << x << "," << y;
          changed += ref.id != 0;
          const Eigen::Vector3f v = ref.radiance * 255.0f;
          const Rgb8 want{static_cast<uint8_t>(std::clamp(std::nearbyint(v[0]), 0.0f, 255.0f)),
                          static_cast<uint8_t>(std::clamp(std::nearbyint(v[1]), 0.0f, 255.0f)),
                          static_cast<uint8_t>(std::clamp(std::nearbyint(v[2]), 0.0f, 255.0f))};
          ASSERT_EQ(view.rgb(x, y), want) << "pixel " << x << "," << y;
        }
      }
      EXPECT_GT(changed, 50) << "camera " << c << " frame " << f;
    }
  }
}

TEST(Renderer, PixelOfAKnownObjectHasItsIdAndLambertShadedColour) {
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kBox);
  spec.objects[0].appearance.top = {0.2f, 0.6f, 0.9f};
  spec.photometry.lighting.ambient = 0.4;
  spec.photometry.lighting.intensity = 0.5;
  spec.photometry.lighting.direction_to_light = Eigen::Vector3d(0, 0, 1);
  const Scene scene = Scene::Create(spec).value();
  Context ctx(1);
  const CameraRenderer renderer(scene, 0, ctx);
  RenderedView view;
  renderer.Render(scene.StateAt(0), ctx, &view);
  // The centre of the box's top face, seen by the camera above.
  const double h = spec.objects[0].appearance.height_m;
  const auto px = scene.camera(0).Project({2.0, 1.5, h});
  ASSERT_TRUE(px);
  const int x = static_cast<int>(std::lround(px->x())), y = static_cast<int>(std::lround(px->y()));
  EXPECT_EQ(view.ids(x, y), 7);
  const Rgb8 c = view.rgb(x, y);
  // Lit straight from above: albedo * (0.4 + 0.5), within the box texture's 6 %.
  EXPECT_NEAR(c.r, 0.2 * 0.9 * 255, 0.06 * 0.2 * 0.9 * 255 + 1);
  EXPECT_NEAR(c.g, 0.6 * 0.9 * 255, 0.06 * 0.6 * 0.9 * 255 + 1);
  EXPECT_NEAR(c.b, 0.9 * 0.9 * 255, 0.06 * 0.9 * 0.9 * 255 + 1);
  // A floor pixel away from it is static, and floor-coloured.
  const auto floor_px = scene.camera(0).Project({0.5, 0.5, 0.0});
  ASSERT_TRUE(floor_px);
  const int fx = static_cast<int>(std::lround(floor_px->x())), fy = static_cast<int>(std::lround(floor_px->y()));
  EXPECT_EQ(view.ids(fx, fy), 0);
  EXPECT_EQ(renderer.floor_mask()(fx, fy), 255);
  EXPECT_NEAR(view.rgb(fx, fy).r, 0.5 * 0.9 * 255, 1);
}

TEST(Renderer, OutputIsDeterministicForASeedOnAnyNumberOfThreads) {
  const Scene a = sim_testing::SmallLab(0.25, 10, 5), b = sim_testing::SmallLab(0.25, 10, 5), other = sim_testing::SmallLab(0.25, 10, 6);
  Context one(1), two(2);
  const CameraRenderer ra(a, 1, one), rb(b, 1, two), ro(other, 1, two);
  RenderedView va, vb, vo;
  ra.Render(a.StateAt(7), one, &va);
  rb.Render(b.StateAt(7), two, &vb);
  ro.Render(other.StateAt(7), two, &vo);
  EXPECT_TRUE(va.rgb == vb.rgb);
  EXPECT_TRUE(va.ids == vb.ids);
  EXPECT_FALSE(va.rgb == vo.rgb);  // another seed: other noise, clothes and carpet
  EXPECT_TRUE(ra.Background() == rb.Background());
}

TEST(Renderer, NoiseHasTheRequestedSpreadAndBackgroundsTheirOwnStream) {
  const Scene lab = sim_testing::SmallLab(0.25, 3);
  Context ctx(2);
  const CameraRenderer r(lab, 0, ctx);
  SceneState empty;
  empty.frame = 1;
  RenderedView view;
  r.Render(empty, ctx, &view);
  const Image<Rgb8> clean = r.Background(/*noise=*/false), bg = r.Background();
  double sum = 0, sum2 = 0, n = 0;
  int64_t differ_from_bg = 0;
  for (int y = 0; y < clean.height(); ++y) {
    for (int x = 0; x < clean.width(); ++x) {
      const double d = static_cast<double>(view.rgb(x, y).g) - static_cast<double>(clean(x, y).g);
      if (clean(x, y).g < 10 || clean(x, y).g > 245) continue;
      sum += d;
      sum2 += d * d;
      n += 1;
      differ_from_bg += view.rgb(x, y).g != bg(x, y).g;
    }
  }
  EXPECT_NEAR(sum / n, 0.0, 0.1);
  EXPECT_NEAR(std::sqrt(sum2 / n), std::sqrt(2.0 * 2.0 + 1.0 / 12), 0.15);  // sigma 2 plus rounding
  EXPECT_GT(differ_from_bg, n / 2);
}

TEST(Renderer, FloorMaskExcludesThePlanterAndTheWalls) {
  const Scene lab = sim_testing::SmallLab();
  Context ctx(2);
  bool planter_seen = false;
  for (size_t c = 0; c < lab.num_cameras(); ++c) {
    const CameraRenderer r(lab, c, ctx);
    const auto top = lab.camera(c).Project({8.45, 3.3, 1.0});  // in the plant's foliage
    if (top && lab.camera(c).InImage(*top)) {
      planter_seen = true;
      EXPECT_EQ(r.floor_mask()(static_cast<int>(std::lround(top->x())), static_cast<int>(std::lround(top->y()))), 0);
    }
    const auto centre = lab.camera(c).Project({4.5, 3.25, 0.0});
    ASSERT_TRUE(centre);
    EXPECT_EQ(r.floor_mask()(static_cast<int>(std::lround(centre->x())), static_cast<int>(std::lround(centre->y()))), 255);
    const auto wall = lab.camera(c).Project({4.5, lab.camera(c).CenterInWorld()->y() < 3 ? 7.0 : -0.5, 2.5});
    if (wall && lab.camera(c).InImage(*wall)) {
      EXPECT_EQ(r.floor_mask()(static_cast<int>(std::lround(wall->x())), static_cast<int>(std::lround(wall->y()))), 0);
    }
  }
  EXPECT_TRUE(planter_seen);
}

TEST(Renderer, FloorBetweenThePushedChairsLegsIsVisibleFromSomeCamera) {
  const Scene lab = sim_testing::SmallLab(0.5);
  Context ctx(2);
  int64_t visible = 0;
  for (size_t c = 0; c < lab.num_cameras(); ++c) {
    const CameraRenderer r(lab, c, ctx);
    const SceneState state = lab.StateAt(40);
    const ObjectInstance* chair = nullptr;
    for (const auto& o : state.objects) {
      if (o.object_class == ObjectClass::kChair) chair = &o;
    }
    ASSERT_NE(chair, nullptr);
    RenderedView view;
    r.Render(state, ctx, &view, false);
    const Eigen::Matrix2d rot = Eigen::Rotation2Dd(chair->heading_rad).toRotationMatrix();
    // Floor points between the legs (inside the seat's square, away from the legs).
    for (double u = -0.12; u <= 0.12; u += 0.04) {
      for (double v = -0.12; v <= 0.12; v += 0.04) {
        const Eigen::Vector2d p = chair->position_m + rot * Eigen::Vector2d(u, v);
        const auto px = lab.camera(c).Project({p.x(), p.y(), 0.0});
        if (!px || !lab.camera(c).InImage(*px)) continue;
        const int x = static_cast<int>(std::lround(px->x())), y = static_cast<int>(std::lround(px->y()));
        const PixelTrace ref = TracePixelReference(lab, c, state, Eigen::Vector2d(x, y));
        if (ref.hit_anything && ref.surface == Surface::kFloor && view.ids(x, y) == 0) ++visible;
      }
    }
  }
  EXPECT_GT(visible, 0);
}

TEST(Renderer, CastShadowsDarkenTheFloorButNotTheChangeMask) {
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kBox);
  spec.objects[0].appearance.width_m = spec.objects[0].appearance.depth_m = 0.4;
  spec.objects[0].appearance.height_m = 0.5;
  spec.photometry.lighting.direction_to_light = Eigen::Vector3d(1, 0, 1).normalized();
  SceneSpec lit = spec;
  spec.photometry.shadows = true;
  const Scene with = Scene::Create(spec).value(), without = Scene::Create(lit).value();
  Context ctx(1);
  RenderedView a, b;
  CameraRenderer(with, 0, ctx).Render(with.StateAt(0), ctx, &a);
  CameraRenderer(without, 0, ctx).Render(without.StateAt(0), ctx, &b);
  EXPECT_TRUE(a.ids == b.ids);
  // The floor just beyond the box on the side away from the light is darker.
  const auto px = with.camera(0).Project({2.0 - 0.2 - 0.15, 1.5, 0.0});
  ASSERT_TRUE(px);
  const int x = static_cast<int>(std::lround(px->x())), y = static_cast<int>(std::lround(px->y()));
  ASSERT_EQ(a.ids(x, y), 0);
  EXPECT_LT(a.rgb(x, y).g + 20, b.rgb(x, y).g);
}


// The scene of CastShadowsDarkenTheFloorButNotTheChangeMask with a pillar: the light comes
// from +x at 45 degrees, so the pillar's shadow falls towards -x.
SceneSpec PillarSpec(bool shadows) {
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kBox, {3.2, 2.4});
  StaticObjectSpec pillar;
  pillar.name = "pillar";
  pillar.shape = StaticObjectSpec::Shape::kCylinder;
  pillar.centre_m = {2.0, 1.5};
  pillar.size_m = {0.3, 0.3};
  pillar.height_m = 2.0;
  spec.statics.push_back(pillar);
  spec.photometry.lighting.direction_to_light = Eigen::Vector3d(1, 0, 1).normalized();
  spec.photometry.shadows = shadows;
  return spec;
}

Eigen::Vector2i PixelOf(const Scene& scene, size_t camera, const Eigen::Vector3d& point) {
  const auto px = scene.camera(camera).Project(point);
  EXPECT_TRUE(px && scene.camera(camera).InImage(*px));
  return {static_cast<int>(std::lround(px->x())), static_cast<int>(std::lround(px->y()))};
}

TEST(Renderer, StaticObjectsShadowTheFloorAwayFromTheLight) {
  const Scene with = Scene::Create(PillarSpec(true)).value(), without = Scene::Create(PillarSpec(false)).value();
  Context ctx(1);
  const CameraRenderer a(with, 0, ctx), b(without, 0, ctx);
  const Lighting& light = with.spec().photometry.lighting;
  const double floor_albedo = 0.5, cosine = std::sqrt(0.5);
  // 0.8 m behind the pillar (its shadow is 2 m long) and the same floor in the light.
  const Eigen::Vector2i shade = PixelOf(with, 0, {2.0 - 0.15 - 0.8, 1.5, 0.0});
  const Eigen::Vector2i lit = PixelOf(with, 0, {2.0 + 0.8, 1.5, 0.0});
  EXPECT_NEAR(a.StaticRadiance(shade.x(), shade.y())[1], floor_albedo * light.ambient, 1e-5);
  EXPECT_NEAR(a.StaticRadiance(lit.x(), lit.y())[1], floor_albedo * (light.ambient + light.intensity * cosine), 1e-5);
  EXPECT_NEAR(b.StaticRadiance(shade.x(), shade.y())[1], floor_albedo * (light.ambient + light.intensity * cosine), 1e-5);
  // The room's walls and ceiling shade nothing (they are not casters), and the pillar's lit
  // face stays lit.
  EXPECT_TRUE(a.StaticRadiance(lit.x(), lit.y()) == b.StaticRadiance(lit.x(), lit.y()));
  const Eigen::Vector2i face = PixelOf(with, 1, {2.0 + 0.15 * std::cos(0.3), 1.5 - 0.15 * std::sin(0.3), 1.0});
  EXPECT_TRUE(a.StaticRadiance(face.x(), face.y()) == b.StaticRadiance(face.x(), face.y()));
  // A moving object's shadow over the pillar's shadow does not darken it again.
  SceneSpec spec = PillarSpec(true);
  spec.objects[0].path = {{0.0, {1.45, 1.5}, false}, {10.0, {1.45, 1.5}, false}};
  spec.objects[0].appearance.height_m = 0.3;
  const Scene box = Scene::Create(spec).value();
  const CameraRenderer r(box, 0, ctx);
  RenderedView view;
  r.Render(box.StateAt(0), ctx, &view, /*noise=*/false, /*shadow_mask=*/true);
  const Eigen::Vector2i behind = PixelOf(box, 0, {1.0, 1.5, 0.0});  // in both shadows
  ASSERT_EQ(view.ids(behind.x(), behind.y()), 0);
  EXPECT_EQ(view.shadow(behind.x(), behind.y()), 0);
  EXPECT_EQ(view.rgb(behind.x(), behind.y()).g, static_cast<uint8_t>(std::lround(floor_albedo * light.ambient * 255)));
}

TEST(Renderer, ShadowMaskMarksTheFloorAMovingObjectDarkensAndNothingElse) {
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kBox);
  spec.objects[0].appearance.width_m = spec.objects[0].appearance.depth_m = 0.4;
  spec.objects[0].appearance.height_m = 0.5;
  spec.photometry.lighting.direction_to_light = Eigen::Vector3d(1, 0.3, 1).normalized();
  SceneSpec lit = spec;
  spec.photometry.shadows = true;
  const Scene with = Scene::Create(spec).value(), without = Scene::Create(lit).value();
  Context ctx(2);
  for (size_t c = 0; c < with.num_cameras(); ++c) {
    RenderedView a, b;
    CameraRenderer(with, c, ctx).Render(with.StateAt(0), ctx, &a, /*noise=*/false, /*shadow_mask=*/true);
    CameraRenderer(without, c, ctx).Render(without.StateAt(0), ctx, &b, /*noise=*/false, /*shadow_mask=*/true);
    ASSERT_EQ(a.shadow.width(), a.ids.width());
    int64_t marked = 0;
    for (int y = 0; y < a.ids.height(); ++y) {
      for (int x = 0; x < a.ids.width(); ++x) {
        EXPECT_EQ(b.shadow(x, y), 0);  // no shadows: an empty mask
        if (a.ids(x, y) != 0) {
          ASSERT_EQ(a.shadow(x, y), 0) << x << "," << y;
          continue;
        }
        if (a.shadow(x, y) == 255) {
          ++marked;
          ASSERT_LT(a.rgb(x, y).g + 20, b.rgb(x, y).g) << x << "," << y;
        } else {
          ASSERT_EQ(a.shadow(x, y), 0);
          ASSERT_EQ(a.rgb(x, y), b.rgb(x, y)) << x << "," << y;
        }
      }
    }
    EXPECT_GT(marked, 30) << "camera " << c;
  }
  // Without objects the mask is empty.
  RenderedView empty;
  SceneState none;
  CameraRenderer(with, 0, ctx).Render(none, ctx, &empty, false, true);
  for (int y = 0; y < empty.shadow.height(); ++y) {
    for (int x = 0; x < empty.shadow.width(); ++x) ASSERT_EQ(empty.shadow(x, y), 0);
  }
}

TEST(Renderer, ShadowCullingGivesTheSameShadowsAsTestingEveryObject) {
  // The lab (a point light) and clemson (a directional one) with shadows, against
  // TracePixelReference plus a plain shadow test of every part at every floor pixel.
  BuiltinSceneOptions o;
  o.image_scale = 0.25;
  o.num_frames = 60;
  o.shadows = true;
  for (const Scene& lab :
       {Scene::Create(MakeLabSceneSpec(o)).value(), Scene::Create(MakeClemsonSceneSpec(o)).value()}) {
    Context ctx(2);
    for (size_t c = 0; c < lab.num_cameras(); ++c) {
      const CameraRenderer r(lab, c, ctx);
      const SceneState state = lab.StateAt(50);
      RenderedView view;
      r.Render(state, ctx, &view, false, true);
      int64_t shadowed = 0;
      for (int y = 0; y < view.ids.height(); ++y) {
        for (int x = 0; x < view.ids.width(); ++x) {
          const PixelTrace ref = TracePixelReference(lab, c, state, Eigen::Vector2d(x, y));
          if (!ref.hit_anything || ref.id != 0 || ref.surface != Surface::kFloor) continue;
          const std::optional<Ray> ray = lab.camera(c).BackProject(Eigen::Vector2d(x, y));
          const Eigen::Vector3d p = ray->origin_in_world + ref.t * ray->direction_in_world;
          Eigen::Vector3d to_light;
          double intensity = 0, dist = 0;
          lab.spec().photometry.lighting.DirectAt(p, &to_light, &intensity, &dist);
          bool blocked = false;
          for (const ObjectInstance& obj : state.objects) {
            for (const Primitive& part : obj.parts) blocked |= IntersectRay(part, p, to_light, dist).has_value();
          }
          // In a static shadow (the static radiance lacks the direct light): nothing more to darken.
          if ((r.StaticRadiance(x, y) - ref.radiance).norm() > 1e-4) blocked = false;
          ASSERT_EQ(view.shadow(x, y) == 255, blocked)
              << lab.spec().name << " camera " << c << " pixel " << x << "," << y;
          shadowed += blocked;
        }
      }
      EXPECT_GT(shadowed, 0) << lab.spec().name << " camera " << c;
    }
  }
}

}  // namespace
}  // namespace occmap::sim
