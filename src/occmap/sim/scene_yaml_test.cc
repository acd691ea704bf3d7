#include "occmap/sim/scene_yaml.h"

#include <gtest/gtest.h>

#include "occmap/sim/builtin_scenes.h"
#include "occmap/util/testing.h"

namespace occmap::sim {
namespace {

TEST(SceneYaml, BuiltinScenesRoundTripExactly) {
  for (const SceneSpec& spec : {MakeLabSceneSpec({}), MakeClemsonSceneSpec({})}) {
    const std::string text = SceneToYaml(spec);
    auto back = ParseSceneYaml(text, "scene.yaml");
    ASSERT_TRUE(back.ok()) << back.status().message();
    EXPECT_EQ(SceneToYaml(*back), text);
    EXPECT_EQ(back->name, spec.name);
    EXPECT_EQ(back->num_frames, spec.num_frames);
    EXPECT_EQ(back->grid, spec.grid);
    ASSERT_EQ(back->cameras.size(), spec.cameras.size());
    for (size_t c = 0; c < spec.cameras.size(); ++c) {
      const auto a = spec.cameras[c].Build().value(), b = back->cameras[c].Build().value();
      const auto pa = a->Project({3.0, 2.0, 0.5}), pb = b->Project({3.0, 2.0, 0.5});
      ASSERT_TRUE(pa && pb);
      EXPECT_EQ(*pa, *pb);  // bit-identical parameters
    }
    ASSERT_EQ(back->objects.size(), spec.objects.size());
    for (size_t i = 0; i < spec.objects.size(); ++i) {
      EXPECT_EQ(back->objects[i].appearance.top, spec.objects[i].appearance.top);
      ASSERT_EQ(back->objects[i].path.size(), spec.objects[i].path.size());
      EXPECT_EQ(back->objects[i].path.back().t_s, spec.objects[i].path.back().t_s);
    }
  }
}

constexpr const char* kCustom = R"(name: corridor
seed: 3
frames: 20
floor:
  origin_m: [0, 0]
  size_m: [4, 3]
  cell_size_m: 0.05
cameras:
  - id: a
    image_size: [160, 120]
    position_m: [-0.3, -0.3, 2.6]
    look_at_m: [2, 1.5, 0]
    focal_px: 120
    distortion: [-0.1, 0.02, 0, 0, 0]
  - id: b
    model: tsai
    image_size: [160, 120]
    position_m: [4.3, 3.3, 2.6]
    look_at_m: [2, 1.5, 0]
    f_mm: 3.0
    cell_mm: 0.0296
    kappa1_per_mm2: 0.004
statics:
  - {name: pillar, shape: cylinder, centre_m: [3, 1], size_m: [0.4, 0.4], height_m: 2.6}
objects:
  - id: 1
    class: person
    colours: {top: [0.8, 0.1, 0.1]}
    path:
      - {at_m: [0.5, 0.5]}
      - {at_m: [3.5, 0.5], speed_m_s: 1.5}
      - {wait_s: 1}
      - {at_m: [1, 2.5], t_s: 5, gap: true}
  - id: 2
    class: robot
    path:
      - {at_m: [1, 2], t_s: 0}
lighting:
  ambient: 0.6
  light: {type: point, position_m: [2, 1.5, 2.9], intensity: 0.5}
photometry:
  noise_sigma: 1.5
  shadows: true
  camera: {auto_exposure: true, white_balance: 0.5, supersample: 2, jpeg_quality: 80}
  contact_shadows: {strength: 0.4}
)";

TEST(SceneYaml, CustomSceneReadsWithDefaultsAndTimesFromSpeeds) {
  auto spec = ParseSceneYaml(kCustom, "corridor.yaml");
  ASSERT_TRUE(spec.ok()) << spec.status().message();
  EXPECT_EQ(spec->name, "corridor");
  EXPECT_EQ(spec->num_frames, 20);
  EXPECT_EQ(spec->grid.cells_x, 80);
  ASSERT_EQ(spec->cameras.size(), 2u);
  EXPECT_EQ(spec->cameras[1].model, CameraSpec::Model::kTsai);
  ASSERT_EQ(spec->objects.size(), 2u);
  const auto& path = spec->objects[0].path;
  ASSERT_EQ(path.size(), 4u);
  EXPECT_DOUBLE_EQ(path[1].t_s, 2.0);
  EXPECT_DOUBLE_EQ(path[2].t_s, 3.0);
  EXPECT_TRUE(path[3].gap_before);
  EXPECT_EQ(spec->objects[0].appearance.top, Eigen::Vector3f(0.8f, 0.1f, 0.1f));
  EXPECT_EQ(spec->photometry.lighting.kind, Lighting::Kind::kPoint);
  EXPECT_TRUE(spec->photometry.shadows);
  // The real camera's keys, the others at their defaults.
  const CameraResponseSpec& camera = spec->photometry.camera;
  EXPECT_TRUE(camera.auto_exposure);
  EXPECT_EQ(camera.white_balance, 0.5);
  EXPECT_EQ(camera.supersample, 2);
  EXPECT_EQ(camera.jpeg_quality, 80);
  EXPECT_EQ(camera.video_crf, -1);
  EXPECT_EQ(camera.read_noise, 0);
  EXPECT_EQ(spec->photometry.contact_shadows.strength, 0.4);
  EXPECT_EQ(spec->photometry.contact_shadows.reach_m, ContactShadowSpec{}.reach_m);
  EXPECT_FALSE(spec->room.outdoor);
  EXPECT_DOUBLE_EQ(spec->room.x_min_m, -0.5);
  // And it round-trips.
  auto again = ParseSceneYaml(SceneToYaml(*spec), "again.yaml");
  ASSERT_TRUE(again.ok()) << again.status().message();
  EXPECT_EQ(SceneToYaml(*again), SceneToYaml(*spec));
}

TEST(SceneYaml, FileThatDoesNotExistIsNotFound) {
  occmap::testing::TempDir dir;
  EXPECT_EQ(LoadSceneYaml(dir / "nope.yaml").status().code(), StatusCode::kNotFound);
}

struct BadScene {
  const char* name;
  const char* from;
  const char* to;
  const char* expected;
};

class SceneYamlBadInput : public ::testing::TestWithParam<BadScene> {};

TEST_P(SceneYamlBadInput, IsRejectedWithLineFieldExpectedAndFound) {
  std::string text = kCustom;
  const std::string from = GetParam().from;
  const size_t pos = text.find(from);
  ASSERT_NE(pos, std::string::npos) << from;
  text.replace(pos, from.size(), GetParam().to);
  auto spec = ParseSceneYaml(text, "s.yaml");
  ASSERT_FALSE(spec.ok());
  EXPECT_EQ(ExitCodeFor(spec.status()), 2);
  EXPECT_EQ(spec.status().message(), GetParam().expected);
}

INSTANTIATE_TEST_SUITE_P(
    Table, SceneYamlBadInput,
    ::testing::Values(
        BadScene{"unknown_top_key", "frames: 20", "frame: 20", "s.yaml:3: unknown field 'frame' (did you mean 'frames'?)"},
        BadScene{"bad_size", "size_m: [4, 3]", "size_m: [4.01, 3]",
                 "s.yaml:6: floor.size_m: expected positive multiples of cell_size_m = 0.05, found [4.01, 3]"},
        BadScene{"bad_model", "model: tsai", "model: fisheye",
                 "s.yaml:16: cameras[1].model: expected pinhole or tsai, found 'fisheye'"},
        BadScene{"no_pose", "    position_m: [-0.3, -0.3, 2.6]\n    look_at_m: [2, 1.5, 0]\n    focal_px: 120", "    focal_px: 120",
                 "s.yaml:9: cameras[0]: expected a pose: position_m and look_at_m, or rotation and translation_m"},
        BadScene{"distortion_length", "distortion: [-0.1, 0.02, 0, 0, 0]", "distortion: [-0.1, 0.02]",
                 "s.yaml:14: cameras[0].distortion: expected a list of 5 numbers, found 2"},
        BadScene{"duplicate_camera", "  - id: b", "  - id: a",
                 "s.yaml:15: cameras[1].id: duplicate camera id 'a'"},
        BadScene{"bad_camera_id", "  - id: b", "  - id: b/c",
                 "s.yaml:15: cameras[1].id: expected letters, digits, '_', '-' or '.', found 'b/c'"},
        BadScene{"missing_f", "    f_mm: 3.0\n", "",
                 "s.yaml:15: cameras[1]: missing required field 'f_mm'"},
        BadScene{"bad_shape", "shape: cylinder", "shape: cone",
                 "s.yaml:24: statics[0].shape: expected box, cylinder or planter, found 'cone'"},
        BadScene{"bad_class", "class: robot", "class: dog",
                 "s.yaml:35: objects[1].class: expected person, chair, robot or box, found 'dog'"},
        BadScene{"bad_colour", "top: [0.8, 0.1, 0.1]", "top: [0.8, 0.1, 1.5]",
                 "s.yaml:28: objects[0].colours.top: expected colour values in 0..1, found [0.8, 0.1, 1.5]"},
        BadScene{"speed_too_high", "speed_m_s: 1.5", "speed_m_s: 150",
                 "s.yaml:31: objects[0].path[1].speed_m_s: expected 0 < speed <= 20 m/s, found 150"},
        BadScene{"time_backwards", "t_s: 5, gap: true", "t_s: 2.5, gap: true",
                 "s.yaml:33: objects[0].path[3].t_s: expected a time after the previous waypoint's 3 s, found 2.5"},
        BadScene{"both_timings", "speed_m_s: 1.5}", "speed_m_s: 1.5, t_s: 3}",
                 "s.yaml:31: objects[0].path[1]: expected exactly one of t_s or speed_m_s"},
        BadScene{"duplicate_object", "  - id: 2", "  - id: 1",
                 "s.yaml:34: objects[1].id: duplicate object id 1"},
        BadScene{"bad_light", "type: point", "type: spot",
                 "s.yaml:40: lighting.light.type: expected directional or point, found 'spot'"},
        BadScene{"noise_range", "noise_sigma: 1.5", "noise_sigma: 80",
                 "s.yaml:42: photometry.noise_sigma: expected 0..50 grey levels, found 80"},
        BadScene{"camera_supersample", "supersample: 2", "supersample: 9",
                 "s.yaml:44: photometry.camera.supersample: expected 1..4 rays per pixel along each axis, found 9"},
        BadScene{"camera_unknown_key", "jpeg_quality: 80", "jpg_quality: 80",
                 "s.yaml:44: photometry.camera: unknown field 'jpg_quality' (did you mean 'jpeg_quality'?)"},
        BadScene{"camera_white_balance", "white_balance: 0.5", "white_balance: 1.5",
                 "s.yaml:44: photometry.camera.white_balance: expected a grey-world strength 0..1, found 1.5"},
        BadScene{"contact_reach", "{strength: 0.4}", "{strength: 0.4, radius_m: 0.5, reach_m: 0.3}",
                 "s.yaml:45: photometry.contact_shadows.reach_m: expected radius_m (0.5) < reach <= 10 m, found 0.3"},
        BadScene{"floor_not_covering", "cell_size_m: 0.05\n", "cell_size_m: 0.05\n  pieces:\n    - {area_m: [0, 0, 1, 1]}\n",
                 "s.yaml:1: floor: the floor pieces do not cover the monitored area at (0.004, 1.201)"},
        BadScene{"yaml_syntax", "origin_m: [0, 0]", "origin_m: [0, 0", "s.yaml:6:9: YAML syntax error: end of sequence flow not found"}),
    [](const ::testing::TestParamInfo<BadScene>& p) { return std::string(p.param.name); });

}  // namespace
}  // namespace occmap::sim
