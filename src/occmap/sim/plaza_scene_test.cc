#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/scene_yaml.h"

namespace occmap::sim {
namespace {

BuiltinSceneOptions Options(int people = -1, uint64_t seed = 1) {
  BuiltinSceneOptions o;
  o.seed = seed;
  o.people = people;
  return o;
}

bool InsideArea(const FloorGrid& g, const Eigen::Vector2d& p) {
  return p.x() >= g.origin_x_m && p.y() >= g.origin_y_m && p.x() < g.origin_x_m + g.size_x_m() &&
         p.y() < g.origin_y_m + g.size_y_m();
}

int PeopleInArea(const SceneSpec& spec, double t) {
  int n = 0;
  for (const MovingObjectSpec& o : spec.objects) {
    const PathSample s = SamplePath(o.path, t);
    n += s.present && InsideArea(spec.grid, s.position_m);
  }
  return n;
}

TEST(PlazaScene, IsListedValidatesAndIsTheSameForASeed) {
  const std::vector<std::string> names = BuiltinSceneNames();
  EXPECT_NE(std::find(names.begin(), names.end(), "plaza"), names.end());
  auto spec = MakeBuiltinSceneSpec("plaza", Options());
  ASSERT_TRUE(spec.ok()) << spec.status().message();
  EXPECT_TRUE(spec->Validate().ok());
  EXPECT_TRUE(spec->room.outdoor);
  EXPECT_TRUE(spec->photometry.shadows);
  EXPECT_DOUBLE_EQ(spec->photometry.exposure_drift, 0.1);
  EXPECT_EQ(spec->num_frames, 600);  // 60 s at 10 fps
  EXPECT_EQ(spec->grid.cells_x, 400);
  EXPECT_EQ(spec->grid.cells_y, 280);
  EXPECT_EQ(SceneToYaml(*spec), SceneToYaml(MakePlazaSceneSpec(Options())));
  EXPECT_NE(SceneToYaml(*spec), SceneToYaml(MakePlazaSceneSpec(Options(-1, 2))));
  // Its scene.yaml renders the same scene again (lighting colours included).
  auto again = ParseSceneYaml(SceneToYaml(*spec), "scene.yaml");
  ASSERT_TRUE(again.ok()) << again.status().message();
  EXPECT_EQ(again->photometry.lighting.ambient_colour, spec->photometry.lighting.ambient_colour);
  EXPECT_EQ(again->photometry.lighting.direct_colour, spec->photometry.lighting.direct_colour);
  EXPECT_EQ(SceneToYaml(*again), SceneToYaml(*spec));
}

TEST(PlazaScene, HasSixCamerasOf1280x720OnPolesAround) {
  const SceneSpec spec = MakePlazaSceneSpec(Options());
  ASSERT_EQ(spec.cameras.size(), 6u);
  const Scene scene = Scene::Create(spec).value();
  for (size_t c = 0; c < scene.num_cameras(); ++c) {
    EXPECT_EQ(scene.camera(c).image_size(), (ImageSize{1280, 720}));
    const Eigen::Vector3d centre = *scene.camera(c).CenterInWorld();
    EXPECT_GE(centre.z(), 2.4);
    EXPECT_LE(centre.z(), 3.5);
    EXPECT_FALSE(InsideArea(spec.grid, centre.head<2>())) << scene.camera_id(c);
    // It looks across the square: the area's centre is in view, at a low angle.
    const auto px = scene.camera(c).Project({10, 7, 0});
    ASSERT_TRUE(px && scene.camera(c).InImage(*px)) << scene.camera_id(c);
    const double depression = std::atan2(centre.z(), (centre.head<2>() - Eigen::Vector2d(10, 7)).norm());
    EXPECT_LT(depression, 25 * std::numbers::pi / 180) << scene.camera_id(c);
  }
  int pillars = 0, planters = 0, benches = 0, kiosks = 0;
  for (const StaticObjectSpec& s : spec.statics) {
    if (!InsideArea(spec.grid, s.centre_m)) continue;
    pillars += s.name.starts_with("pillar") && s.height_m >= 3 && s.size_m.x() >= 0.4 && s.size_m.x() <= 0.6;
    planters += s.shape == StaticObjectSpec::Shape::kPlanter;
    benches += s.name.starts_with("bench") && s.height_m < 0.6;
    kiosks += s.name == "kiosk";
  }
  EXPECT_GE(pillars, 2);
  EXPECT_GE(planters, 2);
  EXPECT_GE(benches, 2);
  EXPECT_EQ(kiosks, 1);
  // Half scale halves the images.
  BuiltinSceneOptions half = Options();
  half.image_scale = 0.5;
  EXPECT_EQ(MakePlazaSceneSpec(half).cameras[0].image_size(), (ImageSize{640, 360}));
}

TEST(PlazaScene, TheAreaHoldsAboutTheConfiguredNumberOfPeople) {
  for (int people : {3, 16, 30}) {
    const SceneSpec spec = MakePlazaSceneSpec(Options(people));
    for (double t : {0.0, 30.0, 59.0}) {
      const int n = PeopleInArea(spec, t);
      EXPECT_LE(std::abs(n - people), std::max(2, people / 4)) << people << " people at " << t << " s: " << n;
    }
  }
}

TEST(PlazaScene, PeopleEnterLeaveStandAndMeetInGroups) {
  const SceneSpec spec = MakePlazaSceneSpec(Options());
  const Scene scene = Scene::Create(spec).value();
  const double end_s = scene.TimeOf(scene.num_frames() - 1);
  int enter = 0, leave = 0, still_10s = 0;
  for (const MovingObjectSpec& o : spec.objects) {
    const PreparedPath path(o.path);
    bool inside_at_start = false, inside_at_end = false, ever_inside = false;
    double still_since = -1, still_longest = 0;
    Eigen::Vector2d last(1e9, 1e9);
    for (double t = 0; t <= end_s + 1e-9; t += 0.5) {
      const PathSample s = path.Sample(t);
      const bool inside = s.present && InsideArea(spec.grid, s.position_m);
      if (t == 0) inside_at_start = inside;
      inside_at_end = inside;
      ever_inside |= inside;
      if (inside && (s.position_m - last).norm() < 0.01) {
        if (still_since < 0) still_since = t - 0.5;
        still_longest = std::max(still_longest, t - still_since);
      } else {
        still_since = -1;
      }
      last = s.present ? s.position_m : Eigen::Vector2d(1e9, 1e9);
    }
    enter += ever_inside && !inside_at_start;
    leave += ever_inside && !inside_at_end;
    still_10s += still_longest >= 10;
  }
  EXPECT_GE(enter, 5);
  EXPECT_GE(leave, 5);
  EXPECT_GE(still_10s, 4);
  // Groups: at some frame, three or more people stand within 1.3 m of another standing person.
  int most_in_groups = 0;
  for (double t = 0; t <= end_s; t += 5) {
    std::vector<Eigen::Vector2d> standing;
    for (const MovingObjectSpec& o : spec.objects) {
      const PathSample a = SamplePath(o.path, t), b = SamplePath(o.path, t + 0.5);
      if (a.present && b.present && (a.position_m - b.position_m).norm() < 0.01) standing.push_back(a.position_m);
    }
    int in_group = 0;
    for (size_t i = 0; i < standing.size(); ++i) {
      for (size_t j = 0; j < standing.size(); ++j) {
        if (i != j && (standing[i] - standing[j]).norm() < 1.3) {
          ++in_group;
          break;
        }
      }
    }
    most_in_groups = std::max(most_in_groups, in_group);
  }
  EXPECT_GE(most_in_groups, 3);
}

TEST(PlazaScene, NobodyWalksThroughTheStaticObjects) {
  for (uint64_t seed : {1, 2, 3}) {
    const SceneSpec spec = MakePlazaSceneSpec(Options(-1, seed));
    for (const MovingObjectSpec& o : spec.objects) {
      const PreparedPath path(o.path);
      for (double t = 0; t < 60; t += 0.2) {
        const PathSample s = path.Sample(t);
        if (!s.present) continue;
        for (const StaticObjectSpec& st : spec.statics) {
          const double r = st.shape == StaticObjectSpec::Shape::kBox ? 0.5 * st.size_m.norm() : 0.5 * st.size_m.x();
          if (r > 5 || st.base_m > 2) continue;  // buildings far away; the kiosk's roof overhead
          // A person's body reaches about 0.25 m from its centre.
          ASSERT_GT((s.position_m - st.centre_m).norm(), r + 0.2)
              << "seed " << seed << " object " << o.id << " at " << t << " s in " << st.name;
        }
      }
    }
  }
}

TEST(PlazaScene, OptionsSetTheLengthPeopleAndSun) {
  BuiltinSceneOptions o = Options(5);
  o.duration_s = 12.5;
  o.sun_elevation_deg = 60;
  const SceneSpec spec = MakePlazaSceneSpec(o);
  EXPECT_EQ(spec.num_frames, 125);
  EXPECT_NEAR(std::asin(spec.photometry.lighting.direction_to_light.z()) * 180 / std::numbers::pi, 60, 1e-9);
  EXPECT_LE(std::abs(PeopleInArea(spec, 6) - 5), 2);
  // Frames beyond the duration still have people.
  o.num_frames = 300;
  const SceneSpec longer = MakePlazaSceneSpec(o);
  EXPECT_EQ(longer.num_frames, 300);
  EXPECT_GE(PeopleInArea(longer, 29), 3);
}

TEST(PlazaScene, InvalidOptionsAreRejectedWithTheirNameAndValue) {
  struct Case {
    BuiltinSceneOptions options;
    std::string message;
  };
  std::vector<Case> cases;
  BuiltinSceneOptions o;
  o.people = 0;
  cases.push_back({o, "people: expected 1..40 people at a time (or -1 for the scene's default), found 0"});
  o = {};
  o.people = 41;
  cases.push_back({o, "people: expected 1..40 people at a time (or -1 for the scene's default), found 41"});
  o = {};
  o.duration_s = 0.5;
  cases.push_back({o, "duration: expected 1..3600 s (or -1 for the scene's default), found 0.5"});
  o = {};
  o.sun_elevation_deg = 2;
  cases.push_back({o, "sun elevation: expected 5..90 degrees (or -1 for the scene's default), found 2"});
  o = {};
  o.sun_elevation_deg = 95;
  cases.push_back({o, "sun elevation: expected 5..90 degrees (or -1 for the scene's default), found 95"});
  o = {};
  o.exposure_drift = 0.7;
  cases.push_back({o, "exposure drift: expected 0..0.5 (or -1 for the scene's default), found 0.7"});
  o = {};
  o.num_frames = 10'000'001;  // was an internal check (abort, exit 134) in MakeLabSceneSpec
  cases.push_back({o, "frames: expected 1 .. 10000000, found 10000001"});
  for (const Case& c : cases) {
    EXPECT_EQ(c.options.Validate().message(), c.message);
    EXPECT_EQ(MakeBuiltinSceneSpec("plaza", c.options).status().message(), c.message);
  }
  o = {};
  o.num_frames = 10'000'001;
  EXPECT_EQ(MakeBuiltinSceneSpec("lab", o).status().message(), "frames: expected 1 .. 10000000, found 10000001");
}

TEST(PlazaScene, OtherScenesRefuseThePlazasOptions) {
  BuiltinSceneOptions o;
  o.people = 5;
  EXPECT_EQ(MakeBuiltinSceneSpec("lab", o).status().message(),
            "people: only the built-in plaza scene takes a people count, found 5 for scene 'lab'");
  o = {};
  o.duration_s = 20;
  EXPECT_EQ(MakeBuiltinSceneSpec("clemson", o).status().message(),
            "duration: only the built-in plaza scene takes a duration (use frames), found 20 s for scene 'clemson'");
  o = {};
  o.people = 3;
  WildtrackSceneOptions wildtrack;
  wildtrack.dataset_dir = "/nonexistent";  // refused before any file is read
  EXPECT_EQ(MakeWildtrackSceneSpec(o, wildtrack).status().message(),
            "people: only the built-in plaza scene takes a people count, found 3 for scene 'wildtrack'");
  o = {};
  o.sun_elevation_deg = 30;
  SceneSpec lab = MakeLabSceneSpec({});
  EXPECT_EQ(ApplyBuiltinOptions(o, lab).message(),
            "sun elevation: only the built-in plaza scene has a sun, found 30 degrees for scene 'lab'");
}

TEST(PlazaScene, OvercastHasNoSunNoCastShadowsAndContactShadows) {
  BuiltinSceneOptions o = Options();
  o.overcast = true;
  const SceneSpec spec = MakePlazaSceneSpec(o);
  EXPECT_EQ(spec.photometry.lighting.intensity, 0);
  EXPECT_FALSE(spec.photometry.shadows);
  EXPECT_TRUE(spec.photometry.contact_shadows.enabled());
  EXPECT_NE(spec.description.find("overcast"), std::string::npos);
  // The paving as bright as under the sun and sky (0.85 of its albedo, within the sky's tint).
  const Lighting& l = spec.photometry.lighting;
  EXPECT_NEAR(l.ambient * l.ambient_colour[1], 0.85, 1e-6);
  o.sun_elevation_deg = 40;
  EXPECT_EQ(MakeBuiltinSceneSpec("plaza", o).status().message(),
            "overcast: an overcast sky has no sun, found a sun elevation of 40 degrees too");
  BuiltinSceneOptions lab;
  lab.overcast = true;
  EXPECT_EQ(MakeBuiltinSceneSpec("lab", lab).status().message(),
            "overcast: only the built-in plaza scene has a sky to change, found it for scene 'lab'");
}

TEST(PlazaScene, RealCameraOptionTurnsThePresetOnAndIdealCameraOff) {
  BuiltinSceneOptions o = Options();
  o.real_camera = true;
  o.jpeg_quality = 60;
  SceneSpec spec = MakePlazaSceneSpec(o);
  PhotometrySpec preset;
  ApplyRealCameraPreset(preset);
  CameraResponseSpec expected = preset.camera;
  expected.jpeg_quality = 60;  // a knob after the preset
  EXPECT_EQ(spec.photometry.camera, expected);
  EXPECT_EQ(spec.photometry.noise_sigma, 0);
  EXPECT_TRUE(spec.photometry.contact_shadows.enabled());
  BuiltinSceneOptions off;
  off.real_camera = false;
  ASSERT_TRUE(ApplyBuiltinOptions(off, spec).ok());
  EXPECT_EQ(spec.photometry.camera, CameraResponseSpec{});
  EXPECT_FALSE(spec.photometry.contact_shadows.enabled());
  EXPECT_FALSE(spec.photometry.camera.processes_frames());
}

TEST(PlazaScene, ApplyingOptionsKeepsTheScenesShadowsAndDriftUnlessGiven) {
  SceneSpec spec = MakePlazaSceneSpec(Options());
  BuiltinSceneOptions o;
  ASSERT_TRUE(ApplyBuiltinOptions(o, spec).ok());
  EXPECT_TRUE(spec.photometry.shadows);
  EXPECT_DOUBLE_EQ(spec.photometry.exposure_drift, 0.1);
  o.exposure_drift = 0;
  ASSERT_TRUE(ApplyBuiltinOptions(o, spec).ok());
  EXPECT_DOUBLE_EQ(spec.photometry.exposure_drift, 0.0);
  // The other scenes as before: no shadows, no drift unless asked.
  const SceneSpec lab = MakeLabSceneSpec({});
  EXPECT_FALSE(lab.photometry.shadows);
  EXPECT_DOUBLE_EQ(lab.photometry.exposure_drift, 0.0);
}

}  // namespace
}  // namespace occmap::sim
