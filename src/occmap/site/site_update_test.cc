#include "occmap/site/site_update.h"

#include <gtest/gtest.h>

#include "occmap/calib/floor_calibration.h"
#include "occmap/calib/opencv_storage.h"
#include "occmap/geometry/homography_camera.h"
#include "occmap/geometry/pinhole_camera.h"
#include "occmap/geometry/rotation.h"
#include "occmap/util/file_util.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;

const char* kSite =
    "# a test site\n"
    "name: t\n"
    "floor: {origin_m: [0, 0], cell_size_m: 0.1, cells: [60, 50]}\n"
    "cameras:\n"
    "  - id: A   # the door camera\n"
    "    calibration:\n"
    "      format: homography   # typed in by hand\n"
    "      floor_from_image: [[0.01, 0, 0], [0, 0.01, 0], [0, 0, 1]]\n"
    "\n"
    "      # in metres\n"
    "      unit: m\n"
    "      image_size: [640, 480]\n"
    "    # the mask comes later\n"
    "  - id: B\n"
    "    calibration: {format: homography, floor_from_image: [[0.02, 0, 0], [0, 0.02, 0], [0, 0, 1]],\n"
    "                  unit: m, image_size: [320, 240]}   # B's note\n"
    "    image_size: [640, 480]\n"
    "tracking: {max_speed_mps: 2.0}\n";

Eigen::Matrix3d SomeHomography() {
  Eigen::Matrix3d h;
  h << 0.004, 0.001, -0.5, 0.0002, 0.011, -1.25, 0.00001, 0.0004, 1;
  return h;
}

TEST(SiteUpdate, ReplacesABlockCalibrationAndKeepsEverythingElse) {
  testing::TempDir dir;
  const fs::path site = dir / "site.yaml";
  testing::WriteText(site, kSite);
  const std::string flow = HomographyCalibrationYaml(SomeHomography(), {640, 480});
  auto u = UpdateSiteCameraCalibration(site, "A", flow);
  ASSERT_TRUE(u.ok()) << u.status().message();
  EXPECT_EQ(u->backup, dir / "site.yaml.bak");
  EXPECT_EQ(ReadFileToString(u->backup).value(), kSite);
  const std::string text = ReadFileToString(site).value();
  EXPECT_EQ(text, u->text);
  const std::string expected = std::string("# a test site\nname: t\n") +
                               "floor: {origin_m: [0, 0], cell_size_m: 0.1, cells: [60, 50]}\ncameras:\n"
                               "  - id: A   # the door camera\n    calibration: " + flow + "\n" +
                               // comments inside the old entry go with it, the one after it stays
                               "    # the mask comes later\n  - id: B\n";
  EXPECT_EQ(text.substr(0, expected.size()), expected);
  auto loaded = LoadSite(site);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  const auto& cam = dynamic_cast<const HomographyCamera&>(*loaded->cameras[0].camera);
  EXPECT_TRUE(cam.floor_from_image().isApprox(SomeHomography(), 1e-15));
  EXPECT_EQ(loaded->cameras[1].camera->image_size(), (ImageSize{640, 480}));
}

TEST(SiteUpdate, ReplacesAFlowCalibrationSpanningLines) {
  testing::TempDir dir;
  const fs::path site = dir / "site.yaml";
  testing::WriteText(site, kSite);
  const std::string flow = HomographyCalibrationYaml(SomeHomography(), {320, 240});
  auto u = UpdateSiteCameraCalibration(site, "B", flow);
  ASSERT_TRUE(u.ok()) << u.status().message();
  EXPECT_NE(u->text.find("  - id: B\n    calibration: " + flow + "   # B's note\n    image_size: [640, 480]\n"),
            std::string::npos)
      << u->text;
  auto loaded = LoadSite(site);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  // B runs at 640x480: the homography calibrated at 320x240 is rescaled by the loader.
  EXPECT_EQ(loaded->cameras[1].calibrated_size, (ImageSize{320, 240}));
}

TEST(SiteUpdate, OpenCvFilesWrittenByCalibrateRoundTripThroughTheSiteLoader) {
  testing::TempDir dir;
  const fs::path site = dir / "site.yaml";
  testing::WriteText(site, kSite);
  PinholeParameters p;
  p.image_size = {640, 480};
  p.fx_px = p.fy_px = 520.125;
  p.cx_px = 318.5;
  p.cy_px = 241.25;
  p.distortion = {-0.08, 0.01, 0.0005, -0.0002, 0};
  const Eigen::Vector3d position(-1.0, -1.2, 2.7);
  p.cam_from_world_rotation = LookAtRotation(position, {3.5, 3.0, 0.0});
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * position;
  ASSERT_TRUE(EnsureDirectory(dir / "calib").ok());
  ASSERT_TRUE(WriteOpenCvCalibration(p, 1.0, dir / "calib/intr_A.xml", dir / "calib/extr_A.xml").ok());
  OCCMAP_CHECK(SitePathFor(site, dir / "calib/intr_A.xml").ok(), "");
  EXPECT_EQ(SitePathFor(site, dir / "calib/intr_A.xml").value(), "calib/intr_A.xml");
  EXPECT_EQ(SitePathFor(site, "/elsewhere/intr.xml").value(), "/elsewhere/intr.xml");
  const std::string flow =
      "{format: opencv, intrinsic: calib/intr_A.xml, extrinsic: calib/extr_A.xml, unit: m, forward: +z}";
  auto u = UpdateSiteCameraCalibration(site, "A", flow);
  ASSERT_TRUE(u.ok()) << u.status().message();
  auto loaded = LoadSite(site);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  const auto& cam = dynamic_cast<const PinholeCamera&>(*loaded->cameras[0].camera);
  EXPECT_EQ(cam.params().fx_px, p.fx_px);
  EXPECT_EQ(cam.params().cy_px, p.cy_px);
  EXPECT_EQ(cam.params().distortion, p.distortion);
  EXPECT_TRUE(cam.params().cam_from_world_rotation.isApprox(p.cam_from_world_rotation, 1e-14));
  EXPECT_TRUE(cam.params().cam_from_world_translation_m.isApprox(p.cam_from_world_translation_m, 1e-14));
  const auto px = cam.Project({2.0, 2.0, 0.0});
  const auto truth = PinholeCamera::Create(p).value().Project({2.0, 2.0, 0.0});
  EXPECT_LE((*px - *truth).norm(), 1e-9);
}

TEST(SiteUpdate, AnUnknownCameraIsAnErrorAndNothingIsWritten) {
  testing::TempDir dir;
  const fs::path site = dir / "site.yaml";
  testing::WriteText(site, kSite);
  auto u = UpdateSiteCameraCalibration(site, "C", HomographyCalibrationYaml(SomeHomography(), {640, 480}));
  ASSERT_FALSE(u.ok());
  EXPECT_EQ(u.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(u.status().message(), site.string() + ": no camera 'C' (the site's cameras: A, B)");
  EXPECT_FALSE(fs::exists(dir / "site.yaml.bak"));
  EXPECT_EQ(ReadFileToString(site).value(), kSite);
}

TEST(SiteUpdate, AnEntryTheLoaderRefusesIsNotWritten) {
  testing::TempDir dir;
  const fs::path site = dir / "site.yaml";
  testing::WriteText(site, kSite);
  auto u = UpdateSiteCameraCalibration(site, "A", "{format: opencv, intrinsic: missing.xml, extrinsic: e.xml, unit: m}");
  ASSERT_FALSE(u.ok());
  EXPECT_EQ(ExitCodeFor(u.status()), 2);
  EXPECT_EQ(u.status().message().rfind(
                "the site with camera 'A''s new calibration does not load; nothing written: " + site.string() + ":6: "
                "cameras[0].calibration.intrinsic: file not found: ", 0),
            0u)
      << u.status().message();
  EXPECT_FALSE(fs::exists(dir / "site.yaml.bak"));
  EXPECT_EQ(ReadFileToString(site).value(), kSite);
}


TEST(SiteUpdate, SetsAMaskOnABlockCameraAndKeepsTheRest) {
  testing::TempDir dir;
  const fs::path site = dir / "site.yaml";
  auto text = SetCameraValue(kSite, site, "A", "mask", "{polygons: [[[0, 0], [639, 0], [639, 479]]]}");
  ASSERT_TRUE(text.ok()) << text.status().message();
  // Added after A's last line (its comment stays where it was, B untouched).
  EXPECT_NE(text->find("      image_size: [640, 480]\n    mask: {polygons: [[[0, 0], [639, 0], [639, 479]]]}\n"
                       "    # the mask comes later\n  - id: B\n"),
            std::string::npos)
      << *text;
  auto loaded = ParseSite(*text, site);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  EXPECT_FALSE(loaded->cameras[0].mask.empty());
  EXPECT_TRUE(loaded->cameras[1].mask.empty());
  // Set again: replaced, not added twice.
  auto again = SetCameraValue(*text, site, "A", "mask", "{polygon: [[0, 0], [10, 0], [10, 10]]}");
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->find("polygons"), std::string::npos) << *again;
  EXPECT_TRUE(ParseSite(*again, site).ok());
}

TEST(SiteUpdate, SetsTrackingZonesAndLinesInAFlowMapAndInABlockMap) {
  testing::TempDir dir;
  const fs::path site = dir / "site.yaml";
  const std::string zones = "[{name: \"door\", polygon: [[0, 0], [1, 0], [1, 1]]}]";
  auto flow = SetTrackingValue(kSite, site, "zones", zones);
  ASSERT_TRUE(flow.ok()) << flow.status().message();
  EXPECT_NE(flow->find("tracking: {max_speed_mps: 2.0, zones: " + zones + "}"), std::string::npos) << *flow;
  auto lines = SetTrackingValue(*flow, site, "lines", "[{name: \"gate\", from: [0, 0], to: [0, 2]}]");
  ASSERT_TRUE(lines.ok());
  auto loaded = ParseSite(*lines, site);
  ASSERT_TRUE(loaded.ok()) << loaded.status().message();
  ASSERT_EQ(loaded->tracking.zones.size(), 1u);
  EXPECT_EQ(loaded->tracking.zones[0].name, "door");
  ASSERT_EQ(loaded->tracking.lines.size(), 1u);
  // Replacing the zones keeps one list.
  auto replaced = SetTrackingValue(*lines, site, "zones", "[]");
  ASSERT_TRUE(replaced.ok());
  auto reloaded = ParseSite(*replaced, site);
  ASSERT_TRUE(reloaded.ok()) << reloaded.status().message();
  EXPECT_TRUE(reloaded->tracking.zones.empty());
  EXPECT_EQ(reloaded->tracking.lines.size(), 1u);

  // A block `tracking:` with a block list of zones, then no tracking at all.
  std::string block = kSite;
  block.replace(block.find("tracking: {max_speed_mps: 2.0}\n"), std::string::npos,
                "tracking:\n  max_speed_mps: 2.0\n  zones:\n  - name: old\n    polygon: [[0, 0], [2, 0], [2, 2]]\n"
                "  # end of zones\n  report_coasting_s: 0.5\n");
  auto b = SetTrackingValue(block, site, "zones", zones);
  ASSERT_TRUE(b.ok()) << b.status().message();
  EXPECT_EQ(b->find("name: old"), std::string::npos) << *b;
  EXPECT_NE(b->find("  zones: " + zones + "\n  # end of zones\n  report_coasting_s: 0.5\n"), std::string::npos) << *b;
  ASSERT_TRUE(ParseSite(*b, site).ok()) << ParseSite(*b, site).status().message();
  std::string none = kSite;
  none.erase(none.find("tracking:"));
  auto n = SetTrackingValue(none, site, "zones", zones);
  ASSERT_TRUE(n.ok());
  auto nl = ParseSite(*n, site);
  ASSERT_TRUE(nl.ok()) << nl.status().message() << "\n" << *n;
  EXPECT_EQ(nl->tracking.zones.size(), 1u);
}

TEST(SiteUpdate, WriteSiteTextValidatesThenKeepsABackup) {
  testing::TempDir dir;
  const fs::path site = dir / "site.yaml";
  testing::WriteText(site, kSite);
  // A zone with two points: the loader's message, nothing written.
  auto bad = SetTrackingValue(kSite, site, "zones", "[{name: z, polygon: [[0, 0], [1, 0]]}]");
  ASSERT_TRUE(bad.ok());
  auto w = WriteSiteText(site, kSite, *bad);
  ASSERT_FALSE(w.ok());
  EXPECT_NE(w.status().message().find("site.yaml:"), std::string::npos) << w.status().message();
  EXPECT_NE(w.status().message().find("nothing written"), std::string::npos);
  EXPECT_EQ(ReadFileToString(site).value(), kSite);
  EXPECT_FALSE(fs::exists(dir / "site.yaml.bak"));
  auto good = SetTrackingValue(kSite, site, "zones", "[{name: z, polygon: [[0, 0], [1, 0], [1, 1]]}]");
  ASSERT_TRUE(good.ok());
  auto ok = WriteSiteText(site, kSite, *good);
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  EXPECT_EQ(ReadFileToString(dir / "site.yaml.bak").value(), kSite);
  EXPECT_EQ(ReadFileToString(site).value(), *good);
}

TEST(SiteUpdate, AnEmptyValueRemovesTheKey) {
  const fs::path site = "site.yaml";
  auto with = SetCameraValue(kSite, site, "A", "mask", "{polygon: [[0, 0], [10, 0], [10, 10]]}");
  ASSERT_TRUE(with.ok());
  auto without = SetCameraValue(*with, site, "A", "mask", "");
  ASSERT_TRUE(without.ok()) << without.status().message();
  EXPECT_EQ(*without, kSite);
  // In a flow map, with its comma; a missing key stays missing.
  auto flow = SetCameraValue(kSite, site, "B", "image_size", "");
  ASSERT_TRUE(flow.ok());
  EXPECT_EQ(flow->find("image_size: [640, 480]", flow->find("- id: B")), std::string::npos) << *flow;
  auto unit = SetTrackingValue(kSite, site, "max_speed_mps", "");
  ASSERT_TRUE(unit.ok());
  EXPECT_NE(unit->find("tracking: {}\n"), std::string::npos) << *unit;
  auto speed = SetTrackingValue(kSite, site, "max_speed_mps", "3");
  ASSERT_TRUE(speed.ok());
  EXPECT_NE(speed->find("tracking: {max_speed_mps: 3}\n"), std::string::npos) << *speed;
  auto none = SetCameraValue(kSite, site, "A", "mask", "");
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(*none, kSite);
  EXPECT_TRUE(ParseSite(*flow, site).ok());
}

TEST(SiteUpdate, SetCameraValueNamesAMissingCamera) {
  auto r = SetCameraValue(kSite, "site.yaml", "Z", "mask", "{polygon: [[0, 0], [1, 0], [1, 1]]}");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("no camera 'Z' (the site's cameras: A, B)"), std::string::npos)
      << r.status().message();
}

}  // namespace
}  // namespace occmap
