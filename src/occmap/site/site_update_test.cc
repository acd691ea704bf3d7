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

}  // namespace
}  // namespace occmap
