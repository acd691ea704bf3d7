#include "occmap/site/site.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include "occmap/calib/opencv_storage.h"
#include "occmap/lut/test_scene.h"
#include "occmap/site/demo_scene.h"
#include "occmap/site/site_lut.h"
#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

// A folder with two calibrated cameras of the small room (OpenCV files in millimetres), a
// mask PNG, and a valid site file.
class SiteFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    testing::SmallRoom room;
    for (int i = 0; i < 2; ++i) {
      PinholeParameters p = room.cameras[i].params();
      ASSERT_TRUE(WriteOpenCvCalibration(p, 0.001, dir_ / ("intr" + std::to_string(i) + ".xml"),
                                         dir_ / ("extr" + std::to_string(i) + ".xml"))
                      .ok());
    }
    Image<uint8_t> mask(160, 120, 255);
    ASSERT_TRUE(WritePng(dir_ / "mask.png", mask.view()).ok());
    Image<uint8_t> small(80, 60, 255);
    ASSERT_TRUE(WritePng(dir_ / "small.png", small.view()).ok());
    testing::WriteText(dir_ / "not_png.png", "garbage");
    Image<uint8_t> black(160, 120, 0);
    ASSERT_TRUE(WritePng(dir_ / "black.png", black.view()).ok());
  }

  std::string Valid() const {
    return R"(version: 1
name: room
floor:
  origin_m: [0, 0]
  size_m: [4, 3]
  cell_size_m: 0.05
cameras:
  - id: a
    calibration:
      format: opencv
      intrinsic: intr0.xml
      extrinsic: extr0.xml
      unit: mm
    mask: mask.png
  - id: b
    calibration:
      format: opencv
      intrinsic: intr1.xml
      extrinsic: extr1.xml
      unit: mm
    image_size: [80, 60]
    mask:
      polygon: [[0, 30], [79, 30], [79, 59], [0, 59]]
detection:
  threshold: 25
  tolerance_px: 2
fusion:
  algorithm: map-based
  max_free_views: 1
blobs:
  group_radius_m: 0.2
  min_area_m2: 0.015
  support_heights_m: [0.35, 1.0]
  min_support: 0.3
  support_slack_m: 0.04
)";
  }

  Result<Site> Parse(const std::string& text) const {
    testing::WriteText(dir_ / "site.yaml", text);
    return LoadSite(dir_ / "site.yaml");
  }

  testing::TempDir dir_;
};

TEST_F(SiteFixture, LoadsAValidSite) {
  auto site = Parse(Valid());
  ASSERT_TRUE(site.ok()) << site.status().message();
  EXPECT_EQ(site->name, "room");
  EXPECT_EQ(site->grid.cells_x, 80);
  EXPECT_EQ(site->grid.cells_y, 60);
  ASSERT_EQ(site->cameras.size(), 2u);
  EXPECT_EQ(site->cameras[0].camera->image_size(), (ImageSize{160, 120}));
  EXPECT_EQ(site->cameras[1].camera->image_size(), (ImageSize{80, 60}));
  EXPECT_EQ(site->cameras[1].calibrated_size, (ImageSize{160, 120}));
  EXPECT_EQ(site->cameras[1].mask(10, 10), 0);
  EXPECT_EQ(site->cameras[1].mask(10, 40), 255);
  EXPECT_EQ(site->detection.threshold, 25);
  EXPECT_EQ(site->detection.tolerance_px, 2);
  EXPECT_EQ(site->fusion.method, FusionMethod::kMapBased);
  EXPECT_EQ(site->fusion.max_free_views, 1);
  EXPECT_EQ(site->objects.group_radius_m, 0.2);
  EXPECT_EQ(site->objects.min_area_m2, 0.015);
  EXPECT_EQ(site->objects.support_heights_m, (std::vector<double>{0.35, 1.0}));
  EXPECT_EQ(site->objects.min_support, 0.3);
  EXPECT_EQ(site->objects.support_slack_m, 0.04);
  EXPECT_FALSE(site->backgrounds.adaptive);  // the paper's fixed background unless asked
  EXPECT_TRUE(site->backgrounds.settle);       // learned backgrounds of files are settled
  EXPECT_FALSE(site->detection.blocks());      // changes per pixel unless asked
}

TEST_F(SiteFixture, ReadsTheBackgroundsSection) {
  auto site = Parse(Valid() +
                    "backgrounds:\n  adaptive: true\n  learning: knn\n  learn_s: 90\n  learn_samples: 45\n"
                    "  absorb_s: 12\n  person_height_m: 1.1\n  settle: false\n"
                    "  shadows: {enabled: false, min_ratio: 0.3, learn: false, ratio_window: 0.2, max_channel_spread: 0.05}\n");
  ASSERT_TRUE(site.ok()) << site.status().message();
  EXPECT_TRUE(site->backgrounds.adaptive);
  EXPECT_EQ(site->backgrounds.learning, BackgroundLearning::kKnn);
  EXPECT_EQ(site->backgrounds.learn_s, 90);
  EXPECT_EQ(site->backgrounds.learn_samples, 45);
  EXPECT_FALSE(site->backgrounds.settle);
  EXPECT_EQ(site->backgrounds.absorb_s, 12);
  EXPECT_EQ(site->backgrounds.person_height_m, 1.1);
  EXPECT_FALSE(site->backgrounds.shadows.enabled);
  EXPECT_EQ(site->backgrounds.shadows.min_ratio, 0.3);
  EXPECT_EQ(site->backgrounds.shadows.max_ratio, ShadowOptions{}.max_ratio);
  EXPECT_FALSE(site->backgrounds.shadows.learn);
  EXPECT_EQ(site->backgrounds.shadows.ratio_window, 0.2);
  EXPECT_EQ(site->backgrounds.shadows.max_channel_spread, 0.05);
}

TEST_F(SiteFixture, ReadsTheOutputsSectionsMqttBlockWithDefaultsFromTheSiteName) {
  testing::WriteText(dir_ / "mqtt.secret", "pw\n");
  auto site = Parse(Valid() + "outputs:\n  mqtt:\n    url: mqtt://127.0.0.1:1884\n    username: occmap\n"
                              "    password_file: mqtt.secret\n");
  ASSERT_TRUE(site.ok()) << site.status().message();
  ASSERT_TRUE(site->outputs.mqtt.has_value());
  EXPECT_EQ(site->outputs.mqtt->broker, (MqttBroker{"127.0.0.1", 1884}));
  EXPECT_EQ(site->outputs.mqtt->topic_prefix, "occmap/room");
  EXPECT_EQ(site->outputs.mqtt->client_id, "occmap-room");
  EXPECT_EQ(site->outputs.mqtt->password_file, dir_ / "mqtt.secret") << "relative to the site file";
  EXPECT_FALSE(Parse(Valid())->outputs.mqtt.has_value());

  auto bad = Parse(Valid() + "outputs:\n  mqtt:\n    url: mqtt://127.0.0.1:99999\n");
  EXPECT_EQ(ExitCodeFor(bad.status()), 2);
  EXPECT_EQ(bad.status().message(), (dir_ / "site.yaml").string() +
                                        ":38: outputs.mqtt.url: expected mqtt://HOST[:PORT] (a port in 1..65535), found "
                                        "'mqtt://127.0.0.1:99999'");
  bad = Parse(Valid() + "outputs:\n  mqt: {}\n");
  EXPECT_EQ(bad.status().message(), (dir_ / "site.yaml").string() + ":37: outputs: unknown field 'mqt' (did you mean 'mqtt'?)");
}

TEST_F(SiteFixture, ResizedCameraProjectsToScaledPixels) {
  auto site = Parse(Valid());
  ASSERT_TRUE(site.ok()) << site.status().message();
  testing::SmallRoom room;
  const Eigen::Vector3d p(2.0, 1.0, 0.0);
  const auto full = room.cameras[1].Project(p);
  const auto half = site->cameras[1].camera->Project(p);
  ASSERT_TRUE(full && half);
  EXPECT_NEAR(half->x(), (full->x() + 0.5) * 0.5 - 0.5, 1e-9);
  EXPECT_NEAR(half->y(), (full->y() + 0.5) * 0.5 - 0.5, 1e-9);
}

TEST_F(SiteFixture, DataRootOptionRedirectsRelativePaths) {
  testing::TempDir other;
  std::string text = Valid();
  testing::WriteText(other / "site.yaml", text);
  EXPECT_EQ(LoadSite(other / "site.yaml").status().code(), StatusCode::kNotFound);
  SiteLoadOptions options;
  options.data_root = dir_.path();
  auto site = LoadSite(other / "site.yaml", options);
  EXPECT_TRUE(site.ok()) << site.status().message();
}

// A stream that names a file beside the site file (a recording played as a live camera) is
// that file; a URL, an absolute device and a name that is no file are used as they are.
TEST_F(SiteFixture, AStreamNamingAFileBesideTheSiteIsThatFile) {
  testing::WriteText(dir_ / "clip.mp4", "not decoded here");
  std::string text = Valid();
  const std::string mask_line = "    mask: mask.png\n";
  text.replace(text.find(mask_line), mask_line.size(), mask_line + "    source: {stream: clip.mp4}\n");
  const std::string polygon = "      polygon: [[0, 30], [79, 30], [79, 59], [0, 59]]\n";
  text.replace(text.find(polygon), polygon.size(), polygon + "    source: {stream: 'rtsp://cam-b/live'}\n");
  auto site = Parse(text);
  ASSERT_TRUE(site.ok()) << site.status().message();
  EXPECT_EQ(site->cameras[0].source.kind, FrameSourceSpec::Kind::kStream);
  EXPECT_EQ(site->cameras[0].source.location, (dir_ / "clip.mp4").lexically_normal().string());
  EXPECT_EQ(site->cameras[1].source.location, "rtsp://cam-b/live");
  for (const char* as_is : {"/dev/video7", "missing.mp4"}) {
    std::string t = text;
    t.replace(t.find("stream: clip.mp4"), 16, fmt::format("stream: {}", as_is));
    auto s = Parse(t);
    ASSERT_TRUE(s.ok()) << s.status().message();
    EXPECT_EQ(s->cameras[0].source.location, as_is);
  }
}

struct BadSite {
  const char* name;
  const char* from;  // text of the valid site to replace, or kAppend
  const char* to;
  const char* expected;  // the message, after "<dir>/site.yaml"
};

// BadSite::from for a section added at the end of the valid site.
constexpr const char* kAppend = nullptr;

class SiteBadInput : public SiteFixture, public ::testing::WithParamInterface<BadSite> {};

TEST_P(SiteBadInput, IsRejectedWithFileLineFieldExpectedAndFound) {
  std::string text = Valid();
  if (GetParam().from == kAppend) {
    text += GetParam().to;
  } else {
    const std::string from = GetParam().from;
    const auto pos = text.find(from);
    ASSERT_NE(pos, std::string::npos) << from;
    text.replace(pos, from.size(), GetParam().to);
  }
  auto site = Parse(text);
  ASSERT_FALSE(site.ok());
  EXPECT_EQ(ExitCodeFor(site.status()), 2);
  std::string message = site.status().message();
  const std::string prefix = (dir_ / "site.yaml").string();
  ASSERT_EQ(message.rfind(prefix, 0), 0u) << message;
  message = message.substr(prefix.size());
  // Absolute paths in messages are shown relative to the fixture folder.
  for (size_t p; (p = message.find(dir_.path().string() + "/")) != std::string::npos;) {
    message.erase(p, dir_.path().string().size() + 1);
  }
  EXPECT_EQ(message, GetParam().expected);
}

INSTANTIATE_TEST_SUITE_P(
    Table, SiteBadInput,
    ::testing::Values(
        BadSite{"missing_calibration_file", "intrinsic: intr0.xml", "intrinsic: intr9.xml",
                ":11: cameras[0].calibration.intrinsic: file not found: 'intr9.xml'"},
        BadSite{"unknown_field", "    mask: mask.png", "    maks: mask.png",
                ":14: cameras[0]: unknown field 'maks' (did you mean 'mask'?)"},
        BadSite{"nan_cell_size", "cell_size_m: 0.05", "cell_size_m: .nan",
                ":6: floor.cell_size_m: expected a finite number, found '.nan'"},
        BadSite{"zero_cell_size", "cell_size_m: 0.05", "cell_size_m: 0",
                ":6: floor.cell_size_m: expected a positive number, found 0"},
        BadSite{"size_not_multiple", "size_m: [4, 3]", "size_m: [4.01, 3]",
                ":5: floor.size_m: expected positive multiples of cell_size_m = 0.05, found [4.01, 3]"},
        BadSite{"grid_too_large", "size_m: [4, 3]", "size_m: [40000, 30000]",
                ":4: floor: grid: 800000 x 600000 = 480000000000 cells is too large (at most 268435456 cells); "
                "use larger cells or a smaller area"},
        BadSite{"both_cells_and_size", "size_m: [4, 3]", "size_m: [4, 3]\n  cells: [80, 60]",
                ":4: floor: expected exactly one of 'cells' or 'size_m'"},
        BadSite{"origin_wrong_size", "origin_m: [0, 0]", "origin_m: [0, 0, 0]",
                ":4: floor.origin_m: expected a list of 2 numbers, found 3"},
        BadSite{"bad_unit", "      unit: mm\n    mask", "      unit: inch\n    mask",
                ":13: cameras[0].calibration.unit: unit: expected m, cm or mm, found 'inch'"},
        BadSite{"missing_unit", "      unit: mm\n    mask", "\n    mask",
                ":10: cameras[0].calibration: missing required field 'unit' (m, cm or mm: the unit of tvec)"},
        BadSite{"wrong_unit_sees_nothing", "      unit: mm\n    mask", "      unit: m\n    mask",
                ":10: cameras[0].calibration: the camera sees none of the 1681 floor sample points (calibration, "
                "unit or grid wrong?)"},
        BadSite{"bad_format", "format: opencv\n      intrinsic: intr0", "format: matlab\n      intrinsic: intr0",
                ":10: cameras[0].calibration.format: expected opencv, gopro-json, tsai-yaml or homography, found "
                "'matlab'"},
        BadSite{"mask_wrong_size", "mask: mask.png", "mask: small.png",
                ":14: cameras[0].mask: 'small.png' is 80x60, expected the camera's image size 160x120"},
        BadSite{"mask_not_an_image", "mask: mask.png", "mask: not_png.png",
                ":14: cameras[0].mask: 'not_png.png': cannot decode image (not a PNG/JPEG/... or truncated)"},
        BadSite{"polygon_outside_image", "[[0, 30], [79, 30]", "[[0, 30], [200, 30]",
                ":23: cameras[1].mask.polygon[1]: point (200, 30) is outside the 80x60 image"},
        BadSite{"aspect_ratio", "image_size: [80, 60]", "image_size: [80, 80]",
                ":21: cameras[1].image_size: expected the calibrated aspect ratio (160x120), found 80x80"},
        BadSite{"duplicate_id", "id: b", "id: a", ":15: cameras[1].id: duplicate camera id 'a'"},
        BadSite{"threshold_range", "threshold: 25", "threshold: 300",
                ":25: detection.threshold: expected 0..254 grey levels, found 300"},
        BadSite{"block_size", "tolerance_px: 2", "tolerance_px: 2\n  block_px: [2, 3]",
                ":27: detection.block_px: expected 1 or 2, or [width, height] of 1 or 2 pixels, found 3"},
        BadSite{"block_rule", "tolerance_px: 2", "tolerance_px: 2\n  block_rule: most",
                ":27: detection.block_rule: expected any or half, found 'most'"},
        BadSite{"vote_range", "max_free_views: 1", "max_free_views: 2",
                ":29: fusion.max_free_views: expected 0..1 (fewer than the 2 cameras), found 2"},
        BadSite{"algorithm", "algorithm: map-based", "algorithm: fastest",
                ":28: fusion.algorithm: expected image-based or map-based, found 'fastest'"},
        BadSite{"version", "version: 1", "version: 2", ":1: version: expected site format version 1, found 2"},
        BadSite{"tracking_speed", kAppend, "tracking:\n  max_speed_mps: -1\n",
                ":37: tracking.max_speed_mps: expected a number > 0, found -1"},
        BadSite{"background_learning", kAppend, "backgrounds:\n  learning: gmm\n",
                ":37: backgrounds.learning: expected median, mode, mog2 or knn, found 'gmm'"},
        BadSite{"background_settle", kAppend, "backgrounds:\n  settle: maybe\n", ":37: backgrounds.settle: expected true or false, found 'maybe'"},
        BadSite{"background_absorb", kAppend, "backgrounds:\n  absorb_s: -3\n",
                ":37: backgrounds.absorb_s: expected > 0, found -3"},
        BadSite{"shadow_ratio", kAppend,
                "backgrounds:\n  shadows: {min_ratio: 0.5, max_ratio: 0.4}\n", ":37: backgrounds.shadows: expected 0 < min_ratio < max_ratio < 1, found min_ratio 0.5 and max_ratio 0.4"},
        BadSite{"shadow_key", kAppend,
                "backgrounds:\n  shadows: {min_ration: 0.5}\n", ":37: backgrounds.shadows: unknown field 'min_ration' (did you mean 'min_ratio'?)"},
        BadSite{"source_fps", "mask: mask.png", "mask: mask.png\n    source: {video: v.mp4, fps: 5}",
                ":15: cameras[0].source.fps: fps is for images and masks (video has its own timestamps)"},
        BadSite{"source_timestamps_video", "mask: mask.png", "mask: mask.png\n    source: {video: v.mp4, timestamps: t.txt}",
                ":15: cameras[0].source.timestamps: timestamps are for images and masks (video has its own)"},
        BadSite{"source_timestamps_and_fps", "mask: mask.png",
                "mask: mask.png\n    source: {images: f_%d.png, fps: 5, timestamps: t.txt}",
                ":15: cameras[0].source.timestamps: expected fps or timestamps, found both"},
        BadSite{"source_timestamps_rate", "mask: mask.png",
                "mask: mask.png\n    source: {images: f_%d.png, timestamps: {file: t.txt, fps: 0}}",
                ":15: cameras[0].source.timestamps.fps: expected the frame numbers' rate, 0 < fps <= 1e6, found 0"},
        BadSite{"source_timestamps_missing", "mask: mask.png",
                "mask: mask.png\n    source: {images: f_%d.png, timestamps: none.txt}",
                ":15: cameras[0].source.timestamps: file not found: 'none.txt'"},
        BadSite{"support_height", "support_heights_m: [0.35, 1.0]", "support_heights_m: [0.35, -1]",
                ":33: blobs.support_heights_m: expected heights in (0, 10) m, found -1"},
        BadSite{"support_heights_not_a_list", "support_heights_m: [0.35, 1.0]", "support_heights_m: high",
                ":33: blobs.support_heights_m: expected a list of numbers, found 'high'"},
        BadSite{"min_support", "min_support: 0.3", "min_support: 1.5",
                ":34: blobs.min_support: expected a fraction in [0, 1], found 1.5"},
        BadSite{"support_slack", "support_slack_m: 0.04", "support_slack_m: -0.1",
                ":35: blobs.support_slack_m: expected >= 0 m, found -0.1"},
        BadSite{"no_cameras", "cameras:\n  - id: a", "cameras: []\nx:\n  - id: a",
                ":8: unknown field 'x' (expected one of: version, name, data_root, floor, cameras, detection, backgrounds, fusion, blobs, lut, people, statics, tracking, outputs)"},
        BadSite{"id_escapes_the_folder", "id: a", "id: x/../../escaped",
                ":8: cameras[0].id: camera id 'x/../../escaped': character '/' (U+002F) at position 2 is not allowed "
                "(letters, digits, '_', '-', '.')"},
        BadSite{"id_dot_dot", "id: a", "id: ..",
                ":8: cameras[0].id: camera id '..': character '.' (U+002E) at position 1 is not allowed first "
                "(letters, digits, '_', '-', '.')"},
        BadSite{"id_tab", "id: a", "id: \"a\\tb\"",
                ":8: cameras[0].id: camera id 'a\\x09b': character (U+0009) at position 2 is not allowed "
                "(letters, digits, '_', '-', '.')"},
        BadSite{"id_nul", "id: a", "id: \"a\\0\"",
                ":8: cameras[0].id: camera id 'a\\x00': character (U+0000) at position 2 is not allowed "
                "(letters, digits, '_', '-', '.')"},
        BadSite{"id_invalid_utf8", "id: a", "id: a\xff", ":8:10: expected UTF-8 text, found the byte 0xff"},
        BadSite{"name_invalid_utf8", "name: room", "name: r\xc3\x28om", ":2:8: expected UTF-8 text, found the byte 0xc3"},
        BadSite{"name_with_slash", "name: room", "name: ro/om",
                ":2: name: site name 'ro/om': character '/' (U+002F) at position 3 is not allowed "
                "(letters, digits, '_', '-', '.')"},
        BadSite{"duplicate_key", "threshold: 25", "threshold: 25\n  threshold: 30",
                ":26: detection: duplicate key 'threshold' (first at line 25; YAML keys must be unique)"},
        BadSite{"duplicate_top_key", "version: 1", "version: 1\nversion: 1",
                ":2: duplicate key 'version' (first at line 1; YAML keys must be unique)"},
        BadSite{"camera_sees_nothing", "mask: mask.png", "mask: black.png",
                ":8: cameras[0]: the camera sees none of the 10201 floor sample points in its image and mask "
                "(calibration, unit, grid or mask wrong?)"},
        BadSite{"yaml_syntax", "origin_m: [0, 0]", "origin_m: [0, 0",
                ":5:9: YAML syntax error: end of sequence flow not found"}),
    [](const ::testing::TestParamInfo<BadSite>& param_info) { return std::string(param_info.param.name); });

TEST_F(SiteFixture, MissingSiteFileIsNotFound) {
  auto site = LoadSite(dir_ / "nope.yaml");
  EXPECT_EQ(site.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(ExitCodeFor(site.status()), 2);
}

TEST_F(SiteFixture, BadCalibrationContentIsReportedWithSiteLocation) {
  testing::WriteText(dir_ / "intr0.xml", R"(<?xml version="1.0"?>
<opencv_storage><camera_matrix type_id="opencv-matrix"><rows>3</rows><cols>3</cols><dt>d</dt>
<data>-5 0 80 0 100 60 0 0 1</data></camera_matrix></opencv_storage>
)");
  auto site = Parse(Valid());
  ASSERT_FALSE(site.ok());
  const std::string m = site.status().message();
  EXPECT_NE(m.find("site.yaml:10: cameras[0].calibration: '"), std::string::npos) << m;
  EXPECT_NE(m.find("intr0.xml': camera_matrix: expected positive focal lengths, found fx = -5, fy = 100"),
            std::string::npos)
      << m;
}

TEST(RasterizePolygons, FillsPixelCentresInside) {
  const Image<uint8_t> m = RasterizePolygons({{{1.5, 1.5}, {5.5, 1.5}, {5.5, 3.5}, {1.5, 3.5}}}, {8, 6});
  int inside = 0;
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 8; ++x) inside += m(x, y) != 0;
  }
  EXPECT_EQ(m(3, 2), 255);
  EXPECT_EQ(m(0, 0), 0);
  EXPECT_EQ(m(7, 5), 0);
  EXPECT_GE(inside, 8);   // the 4 x 2 pixel centres strictly inside
  EXPECT_LE(inside, 15);  // plus at most the boundary ones
}

TEST(DemoSite, BuildsTablesThatSeeTheWholeLab) {
  const Site site = MakeDemoLabSite();
  Context ctx(2);
  auto cached = LoadOrBuildSiteLut(site, {}, ctx);
  ASSERT_TRUE(cached.ok()) << cached.status().message();
  const GridCoverage g = SummarizeCoverage(cached->lut);
  EXPECT_EQ(g.cells_seen_by_at_least[2], g.cells);  // every cell of the lab by at least 2 cameras
  EXPECT_GT(g.cells_seen_by_at_least[4], g.cells / 3);
  EXPECT_NE(CoverageTable(site, cached->lut).find("cam4"), std::string::npos);
}

}  // namespace
}  // namespace occmap
