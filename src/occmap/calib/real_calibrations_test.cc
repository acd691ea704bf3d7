// The OpenCV model against cv::projectPoints on every real camera of the shared datasets.
#include <gtest/gtest.h>

#include <fmt/core.h>

#include <opencv2/calib3d.hpp>

#include "occmap/calib/forward_sign.h"
#include "occmap/calib/gopro_json.h"
#include "occmap/calib/opencv_storage.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

struct Area {
  double x0, y0, x1, y1;
};

std::vector<Eigen::Vector3d> SamplePoints(const Area& a, int steps) {
  std::vector<Eigen::Vector3d> pts;
  for (double z : {0.0, 0.9, 1.8}) {
    for (int i = 0; i <= steps; ++i) {
      for (int j = 0; j <= steps; ++j) {
        pts.emplace_back(a.x0 + (a.x1 - a.x0) * i / steps, a.y0 + (a.y1 - a.y0) * j / steps, z);
      }
    }
  }
  return pts;
}

std::vector<Eigen::Vector3d> Floor(const std::vector<Eigen::Vector3d>& pts) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : pts) {
    if (p.z() == 0) out.push_back(p);
  }
  return out;
}

// Compares occmap's projection with cv::projectPoints on every sample point that the camera
// sees (in front, inside the lens model's valid domain, within the image); returns the count.
// rvec_from_file: the file's Rodrigues vector when it has one (MultiviewX's rotations are
// close to pi, where converting the matrix back to a vector loses digits).
int ExpectMatchesProjectPoints(const PinholeParameters& params, const std::vector<Eigen::Vector3d>& pts,
                               const std::string& name, double* max_error_px,
                               std::optional<Eigen::Vector3d> rvec_from_file = std::nullopt) {
  auto cam = PinholeCamera::Create(params);
  EXPECT_TRUE(cam.ok()) << cam.status().message();
  const auto& p = params;
  cv::Mat k = (cv::Mat_<double>(3, 3) << p.fx_px, p.skew_px, p.cx_px, 0, p.fy_px, p.cy_px, 0, 0, 1);
  cv::Mat dist(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) dist.at<double>(i) = p.distortion[i];
  cv::Mat r(3, 3, CV_64F);
  for (int i = 0; i < 9; ++i) r.at<double>(i / 3, i % 3) = p.cam_from_world_rotation(i / 3, i % 3);
  cv::Mat rvec;
  if (rvec_from_file) {
    rvec = (cv::Mat_<double>(3, 1) << rvec_from_file->x(), rvec_from_file->y(), rvec_from_file->z());
  } else {
    cv::Rodrigues(r, rvec);
  }
  cv::Mat tvec = (cv::Mat_<double>(3, 1) << p.cam_from_world_translation_m.x(), p.cam_from_world_translation_m.y(),
                  p.cam_from_world_translation_m.z());
  std::vector<cv::Point3d> object;
  std::vector<Eigen::Vector2d> ours;
  for (const auto& pw : pts) {
    auto px = cam->Project(pw);
    if (!px || !cam->InImage(*px)) continue;
    object.emplace_back(pw.x(), pw.y(), pw.z());
    ours.push_back(*px);
  }
  if (object.empty()) return 0;
  std::vector<cv::Point2d> theirs;
  cv::projectPoints(object, rvec, tvec, k, dist, theirs);
  for (size_t i = 0; i < object.size(); ++i) {
    const double err = std::hypot(ours[i].x() - theirs[i].x, ours[i].y() - theirs[i].y);
    *max_error_px = std::max(*max_error_px, err);
    EXPECT_LT(err, 1e-6) << name << " point " << object[i];
    // And back: the pixel's ray meets the point's plane at the point.
    auto back = cam->PixelToPlane(ours[i], object[i].z);
    EXPECT_TRUE(back.has_value()) << name;
    if (back) {
      EXPECT_LT(std::hypot(back->x() - object[i].x, back->y() - object[i].y),
                1e-6 * (1 + std::abs(object[i].x) + std::abs(object[i].y)))
          << name;
    }
  }
  return static_cast<int>(object.size());
}

TEST(RealCalibrations, WildtrackMatchesProjectPointsOnEveryCamera) {
  OCCMAP_REQUIRE_DATASETS(root);
  const auto pts = SamplePoints({-3, -9, 9, 27}, 60);
  double max_err = 0;
  for (const char* intr_dir : {"intrinsic_zero", "intrinsic_original"}) {
    for (const char* cam : {"CVLab1", "CVLab2", "CVLab3", "CVLab4", "IDIAP1", "IDIAP2", "IDIAP3"}) {
      const fs::path base = root / "wildtrack" / "calibrations";
      auto p = ReadOpenCvCalibration(base / intr_dir / fmt::format("intr_{}.xml", cam),
                                     base / "extrinsic" / fmt::format("extr_{}.xml", cam), 0.01, ImageSize{1920, 1080});
      ASSERT_TRUE(p.ok()) << p.status().message();
      EXPECT_EQ(*ChooseForwardSign(*p, Floor(pts)), +1) << cam;
      EXPECT_GT(ExpectMatchesProjectPoints(*p, pts, cam, &max_err), 500) << cam << " " << intr_dir;
    }
  }
  RecordProperty("max_error_px", std::to_string(max_err));
}

TEST(RealCalibrations, MultiviewxLooksAlongNegativeZAndMatchesProjectPoints) {
  OCCMAP_REQUIRE_DATASETS(root);
  const auto pts = SamplePoints({0, 0, 25, 16}, 60);
  double max_err = 0;
  for (int k = 1; k <= 6; ++k) {
    const fs::path base = root / "multiviewx" / "calibrations";
    const fs::path extrinsic = base / "extrinsic" / fmt::format("extr_Camera{}.xml", k);
    auto p = ReadOpenCvCalibration(base / "intrinsic" / fmt::format("intr_Camera{}.xml", k), extrinsic, 1.0,
                                   ImageSize{1920, 1080});
    const Eigen::Vector3d rvec = ReadOpenCvExtrinsics(extrinsic)->rvec;
    ASSERT_TRUE(p.ok()) << p.status().message();
    auto sign = ChooseForwardSign(*p, Floor(pts));
    ASSERT_TRUE(sign.ok());
    EXPECT_EQ(*sign, -1) << "Camera" << k;
    p->forward_sign = *sign;
    EXPECT_GT(ExpectMatchesProjectPoints(*p, pts, fmt::format("Camera{}", k), &max_err, rvec), 500);
    // With the ordinary sign the camera would see almost nothing of its floor.
    p->forward_sign = +1;
    double ignored = 0;
    EXPECT_LT(ExpectMatchesProjectPoints(*p, Floor(pts), "wrong sign", &ignored, rvec), 10);
  }
}

TEST(RealCalibrations, GoPro4MatchesProjectPointsOnEveryCamera) {
  OCCMAP_REQUIRE_DATASETS(root);
  const auto pts = SamplePoints({-6, -7, 4, 0}, 60);
  double max_err = 0;
  for (int k = 0; k < 4; ++k) {
    const fs::path base = root / "gopro4" / "calibration";
    auto p = ReadGoProCalibration(base / fmt::format("intrinsics_gopro6.{}.json", k),
                                  base / fmt::format("extrinsics_gopro6.{}.json", k), std::nullopt);
    ASSERT_TRUE(p.ok()) << p.status().message();
    EXPECT_EQ(*ChooseForwardSign(*p, Floor(pts)), +1);
    EXPECT_GT(ExpectMatchesProjectPoints(*p, pts, fmt::format("gopro6.{}", k), &max_err), 500);
  }
}

}  // namespace
}  // namespace occmap
