// The renderer's real camera (renderer.h, scene.h CameraResponseSpec) and contact shadows
// (ContactShadowSpec): what each effect does to the pixels, and that without them nothing moves.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/renderer.h"
#include "occmap/sim/sim_test_util.h"

namespace occmap::sim {
namespace {

// A person standing still at a point, in dark or given clothes.
MovingObjectSpec StandingPerson(int64_t id, const Eigen::Vector2d& at, const Eigen::Vector3f& clothes) {
  MovingObjectSpec o;
  o.id = id;
  o.object_class = ObjectClass::kPerson;
  o.appearance = RandomAppearance(ObjectClass::kPerson, 1, static_cast<uint64_t>(id), {0.5f, 0.5f, 0.5f}, 0.0);
  o.appearance.top = clothes;
  o.appearance.bottom = clothes;
  o.path = {{0.0, at, false}, {10.0, at, false}};
  return o;
}

// The 4 x 3 m room of sim_testing::OneObjectSpec, no objects, seen by its camera from above.
SceneSpec EmptyRoom() {
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kBox);
  spec.objects.clear();
  return spec;
}

// A crowd of people in `clothes` filling much of the top camera's view.
SceneSpec CrowdedRoom(const Eigen::Vector3f& clothes) {
  SceneSpec spec = EmptyRoom();
  int64_t id = 1;
  for (double x : {1.2, 1.7, 2.2, 2.7}) {
    for (double y : {0.9, 1.5, 2.1}) spec.objects.push_back(StandingPerson(id++, {x, y}, clothes));
  }
  return spec;
}

double MeanOf(const Image<Rgb8>& image, const Image<uint8_t>& where, int channel) {
  double sum = 0, n = 0;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      if (where(x, y) == 0) continue;
      const Rgb8 p = image(x, y);
      sum += channel == 0 ? p.r : channel == 1 ? p.g : p.b;
      n += 1;
    }
  }
  return sum / n;
}

TEST(RealCamera, DarkPeopleFillingTheViewRaiseEveryChannelsGainAndBrightenTheFloor) {
  SceneSpec spec = CrowdedRoom({0.06f, 0.06f, 0.07f});
  spec.photometry.camera.auto_exposure = true;
  const Scene scene = Scene::Create(spec).value();
  Context ctx(2);
  const CameraRenderer renderer(scene, 0, ctx);
  RenderedView view;
  renderer.Render(scene.StateAt(0), ctx, &view, /*noise=*/false);
  const Image<Rgb8> empty = renderer.Background(/*noise=*/false);
  // The floor no one covers, as the empty view shows it and as the crowded frame does.
  Image<uint8_t> free_floor = renderer.floor_mask();
  int64_t covered = 0;
  for (int y = 0; y < free_floor.height(); ++y) {
    for (int x = 0; x < free_floor.width(); ++x) {
      covered += view.ids(x, y) != 0;
      if (view.ids(x, y) != 0) free_floor(x, y) = 0;
    }
  }
  ASSERT_GT(covered, free_floor.width() * free_floor.height() / 8) << "the crowd fills an eighth of the view";
  for (int c = 0; c < 3; ++c) {
    EXPECT_GT(view.gains[c], 1.1) << "channel " << c;
    EXPECT_GT(MeanOf(view.rgb, free_floor, c), 1.08 * MeanOf(empty, free_floor, c)) << "channel " << c;
  }
  // Without automatic exposure the same frame keeps gain 1 and the floor its values.
  SceneSpec fixed = spec;
  fixed.photometry.camera = CameraResponseSpec{};
  const Scene fixed_scene = Scene::Create(fixed).value();
  RenderedView fixed_view;
  CameraRenderer(fixed_scene, 0, ctx).Render(fixed_scene.StateAt(0), ctx, &fixed_view, /*noise=*/false);
  EXPECT_EQ(fixed_view.gains, Eigen::Vector3d::Ones());
  EXPECT_NEAR(MeanOf(fixed_view.rgb, free_floor, 1), MeanOf(empty, free_floor, 1), 0.5);
}

TEST(RealCamera, ColouredClothesMoveTheWhiteBalanceGainsApart) {
  // People in red fill the view: grey world sees too much red and lowers red's gain against
  // blue's, so the grey floor turns bluish - per channel, as the terrace's cameras do.
  SceneSpec spec = CrowdedRoom({0.8f, 0.12f, 0.1f});
  spec.photometry.camera.white_balance = 0.8;
  const Scene scene = Scene::Create(spec).value();
  Context ctx(2);
  const CameraRenderer renderer(scene, 0, ctx);
  const Eigen::Vector3d empty_gains = renderer.NewResponse().SettledGains(Eigen::Vector3d::Constant(1));
  RenderedView view;
  renderer.Render(scene.StateAt(0), ctx, &view, /*noise=*/false);
  EXPECT_LT(view.gains[0], 0.9 * view.gains[2]);
  EXPECT_LT(view.gains[0], view.gains[1]);
  EXPECT_NEAR(empty_gains[0], empty_gains[2], 1e-12);  // a grey mean needs no balance
}

TEST(RealCamera, GainsLagTheContentWhenFramesAreRenderedInOrder) {
  // A crowd walks in at 2 s: with a response carried from frame to frame the gain rises over
  // a few frames; without one each frame is settled at once.
  SceneSpec spec = CrowdedRoom({0.06f, 0.06f, 0.07f});
  for (MovingObjectSpec& o : spec.objects) {
    o.path = {{2.0, o.path.front().position_m, false}, {10.0, o.path.front().position_m, false}};
  }
  spec.num_frames = 40;
  spec.photometry.camera.auto_exposure = true;
  spec.photometry.camera.time_constant_s = 0.5;
  const Scene scene = Scene::Create(spec).value();
  Context ctx(2);
  const CameraRenderer renderer(scene, 0, ctx);
  CameraResponse response = renderer.NewResponse();
  RenderedView view, settled;
  std::vector<double> gains;
  for (int64_t f = 0; f < 40; ++f) {
    renderer.Render(scene.StateAt(f), ctx, &view, /*noise=*/false, false, &response);
    gains.push_back(view.gains[1]);
  }
  renderer.Render(scene.StateAt(39), ctx, &settled, /*noise=*/false);
  EXPECT_NEAR(gains[19], 1.0, 1e-9);  // empty until 2 s
  const double final_gain = settled.gains[1];
  ASSERT_GT(final_gain, 1.1);
  // One frame after the crowd appears: a = 1 - exp(-1 / 5) of the way in log terms.
  EXPECT_NEAR(std::log(gains[20]) / std::log(final_gain), 1 - std::exp(-0.2), 1e-6);
  EXPECT_LT(gains[22], final_gain);
  // After 20 frames with the crowd: 1 - exp(-20 / 5) of the way.
  EXPECT_NEAR(std::log(gains[39]) / std::log(final_gain), 1 - std::exp(-4.0), 1e-6);
}

TEST(RealCamera, NoiseHasTheSetVariancePerChannel) {
  SceneSpec spec = EmptyRoom();
  // A patterned floor: values of every fraction (a plain one would round the same way everywhere).
  spec.floor[0].material.pattern = Pattern::kCarpet;
  spec.floor[0].material.variation = 0.4f;
  spec.photometry.camera.read_noise = 1.5;
  spec.photometry.camera.shot_noise = 0.1;
  const Scene scene = Scene::Create(spec).value();
  Context ctx(2);
  const CameraRenderer renderer(scene, 0, ctx);
  SceneState empty;
  empty.frame = 3;
  RenderedView noisy, clean;
  renderer.Render(empty, ctx, &noisy, /*noise=*/true);
  renderer.Render(empty, ctx, &clean, /*noise=*/false);
  for (int c = 0; c < 3; ++c) {
    double sum = 0, sum2 = 0, expected = 0, n = 0, cross = 0;
    for (int y = 0; y < clean.rgb.height(); ++y) {
      for (int x = 0; x < clean.rgb.width(); ++x) {
        const Rgb8 a = noisy.rgb(x, y), b = clean.rgb(x, y);
        const double va = c == 0 ? a.r : c == 1 ? a.g : a.b, vb = c == 0 ? b.r : c == 1 ? b.g : b.b;
        if (vb < 20 || vb > 235) continue;
        const double d = va - vb;
        sum += d;
        sum2 += d * d;
        expected += 1.5 * 1.5 + 0.1 * vb + 1.0 / 12;  // read, shot, and rounding
        cross += (static_cast<double>(a.r) - b.r) * (static_cast<double>(a.b) - b.b);
        n += 1;
      }
    }
    ASSERT_GT(n, 10000);
    EXPECT_NEAR(sum / n, 0.0, 0.05) << "channel " << c;
    EXPECT_NEAR(sum2 / n, expected / n, 0.04 * expected / n) << "channel " << c;
    if (c == 0) {
      EXPECT_NEAR(cross / n, 0.0, 0.05 * expected / n) << "red and blue noise are independent";
    }
  }
}

TEST(RealCamera, SupersamplingAveragesTheRaysOfEachPixel) {
  // Rendered at 2x and area-averaged: every pixel is the mean of the 2 x 2 pixels the ideal
  // camera renders at twice the size (to rounding), an object is seen where it covers at least
  // two of them, and the floor mask is the majority's.
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kPerson);
  SceneSpec big = spec;
  BuiltinSceneOptions twice;
  twice.image_scale = 2;
  ASSERT_TRUE(ApplyBuiltinOptions(twice, big).ok());
  spec.photometry.camera.supersample = 2;
  const Scene scene = Scene::Create(spec).value(), big_scene = Scene::Create(big).value();
  Context ctx(2);
  for (size_t c = 0; c < scene.num_cameras(); ++c) {
    const CameraRenderer r(scene, c, ctx), rb(big_scene, c, ctx);
    EXPECT_EQ(r.size(), (ImageSize{160, 120}));
    EXPECT_EQ(r.supersample(), 2);
    RenderedView v, vb;
    r.Render(scene.StateAt(1), ctx, &v, /*noise=*/false);
    rb.Render(big_scene.StateAt(1), ctx, &vb, /*noise=*/false);
    ASSERT_EQ(v.rgb.width(), 160);
    int64_t mixed = 0;
    for (int y = 0; y < 120; ++y) {
      for (int x = 0; x < 160; ++x) {
        double mean[3] = {0, 0, 0};
        int covered = 0, floor = 0;
        for (int k = 0; k < 4; ++k) {
          const int bx = 2 * x + (k & 1), by = 2 * y + (k >> 1);
          const Rgb8 p = vb.rgb(bx, by);
          mean[0] += p.r / 4.0;
          mean[1] += p.g / 4.0;
          mean[2] += p.b / 4.0;
          covered += vb.ids(bx, by) != 0;
          floor += rb.floor_mask()(bx, by) != 0;
        }
        const Rgb8 p = v.rgb(x, y);
        ASSERT_NEAR(p.r, mean[0], 1.0) << x << "," << y;
        ASSERT_NEAR(p.g, mean[1], 1.0) << x << "," << y;
        ASSERT_NEAR(p.b, mean[2], 1.0) << x << "," << y;
        ASSERT_EQ(v.ids(x, y), covered >= 2 ? 7 : 0) << x << "," << y;
        ASSERT_EQ(r.floor_mask()(x, y), floor >= 2 ? 255 : 0) << x << "," << y;
        mixed += covered > 0 && covered < 4;
      }
    }
    EXPECT_GT(mixed, 20) << "the person's outline is made of mixed pixels";
  }
}

TEST(RealCamera, ContactShadowDarkensTheFloorAroundTheFeetAndFadesWithDistance) {
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kPerson);  // id 7 at (2, 1.5)
  spec.photometry.lighting.intensity = 0;  // overcast: the sky alone
  spec.photometry.lighting.ambient = 0.9;
  SceneSpec with = spec;
  with.photometry.contact_shadows = ContactShadowSpec{.strength = 0.5, .radius_m = 0.22, .reach_m = 1.5};
  const Scene plain_scene = Scene::Create(spec).value(), scene = Scene::Create(with).value();
  Context ctx(2);
  const CameraRenderer plain_renderer(plain_scene, 0, ctx), renderer(scene, 0, ctx);
  RenderedView plain, shaded;
  plain_renderer.Render(plain_scene.StateAt(0), ctx, &plain, /*noise=*/false, /*shadow_mask=*/true);
  renderer.Render(scene.StateAt(0), ctx, &shaded, /*noise=*/false, /*shadow_mask=*/true);
  // Shadows are not objects: the change mask stays, and so do the person's own pixels.
  ASSERT_TRUE(plain.ids == shaded.ids);
  int64_t plain_marked = 0;
  for (int y = 0; y < plain.rgb.height(); ++y) {
    for (int x = 0; x < plain.rgb.width(); ++x) {
      plain_marked += plain.shadow(x, y) != 0;
      if (plain.ids(x, y) != 0) {
        ASSERT_EQ(plain.rgb(x, y), shaded.rgb(x, y));
      }
    }
  }
  EXPECT_EQ(plain_marked, 0);
  // Along +x from the person (beside it as the camera above sees it), every 5 cm.
  double previous = 0;
  int samples = 0;
  for (double d = 0.3; d <= 1.75; d += 0.05) {
    const auto px = scene.camera(0).Project({2.0 + d, 1.5, 0.0});
    ASSERT_TRUE(px);
    const int x = static_cast<int>(std::lround(px->x())), y = static_cast<int>(std::lround(px->y()));
    if (shaded.ids(x, y) != 0) continue;
    const double ratio = static_cast<double>(shaded.rgb(x, y).g) / plain.rgb(x, y).g;
    if (d < 0.35) {
      EXPECT_LT(ratio, 0.82) << "at the person's side";
      EXPECT_EQ(shaded.shadow(x, y), 255) << "marked where it shows";
    }
    if (d > 1.25) {
      EXPECT_EQ(shaded.shadow(x, y), 0) << "the faint halo is not marked, at " << d << " m";
    }
    if (d > 1.55) {
      EXPECT_EQ(ratio, 1.0) << "nothing beyond the reach, at " << d << " m";
    }
    if (samples > 0) {
      EXPECT_GE(ratio, previous - 0.01) << "fading with distance, at " << d << " m";
      EXPECT_LT(ratio - previous, 0.07) << "no hard edge, at " << d << " m";
    }
    previous = ratio;
    ++samples;
  }
  EXPECT_GT(samples, 20);
}

TEST(RealCamera, NeutralRealCameraGivesTheIdealCamerasBits) {
  // Automatic exposure on an empty frame: gain exactly 1, the same noise: the real camera's
  // path writes the ideal camera's pixels, frames and background alike.
  SceneSpec ideal = EmptyRoom();
  ideal.photometry.noise_sigma = 2;
  SceneSpec real = ideal;
  real.photometry.camera.auto_exposure = true;
  const Scene ideal_scene = Scene::Create(ideal).value(), real_scene = Scene::Create(real).value();
  Context ctx(2);
  for (size_t c = 0; c < ideal_scene.num_cameras(); ++c) {
    const CameraRenderer a(ideal_scene, c, ctx), b(real_scene, c, ctx);
    SceneState empty;
    empty.frame = 2;
    RenderedView va, vb;
    a.Render(empty, ctx, &va);
    b.Render(empty, ctx, &vb);
    EXPECT_EQ(vb.gains, Eigen::Vector3d::Ones());
    EXPECT_TRUE(va.rgb == vb.rgb) << "camera " << c;
    EXPECT_TRUE(va.ids == vb.ids);
    EXPECT_TRUE(a.Background() == b.Background());
    EXPECT_TRUE(a.floor_mask() == b.floor_mask());
  }
}

}  // namespace
}  // namespace occmap::sim
