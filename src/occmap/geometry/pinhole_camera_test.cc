#include "occmap/geometry/pinhole_camera.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <random>
#include <string>
#include <vector>

#include "occmap/geometry/rotation.h"
#include "occmap/util/hash.h"

namespace occmap {
namespace {

using Distortion = std::array<double, 5>;  // k1 k2 p1 p2 k3

// WILDTRACK CVLab1's published calibration (strong barrel distortion, folds at r^2 = 0.68).
constexpr Distortion kWildtrackDistortion = {-0.43248599767684937, 0.6106230020523071,
                                             0.008233999833464622, 0.0018599999602884054,
                                             -0.6923710107803345};
// A GoPro (gopro4 dataset, camera 6.0), wide angle.
constexpr Distortion kGoproDistortion = {-0.25563814319422795, 0.08551936003650386,
                                         0.00012762440797667226, -9.80026900383636e-05,
                                         -0.014760361967297629};
// WILDTRACK CVLab3: positive k3, the radial polynomial never turns back (no fold).
constexpr Distortion kNoFoldDistortion = {-0.2952420115470886, -0.9262599945068359,
                                          0.015855999663472176, -0.0010989999864250422,
                                          4.333065986633301};
constexpr Distortion kNoDistortion = {0, 0, 0, 0, 0};

// A synthetic camera: intrinsics, distortion, and a pose given as OpenCV's rvec/tvec.
struct CameraSpec {
  std::string name;
  double fx, fy, cx, cy;
  Distortion distortion;
  Eigen::Vector3d rvec;
  Eigen::Vector3d tvec_m;
  ImageSize size = {1920, 1080};
};

// WILDTRACK CVLab1's pose (tvec converted from cm).
const Eigen::Vector3d kWildtrackRvec(1.759099006652832, 0.46710100769996643, -0.331699013710022);
const Eigen::Vector3d kWildtrackTvecM(-5.258941650390625, 0.4540763473510742, 9.867235107421875);

std::vector<CameraSpec> ProjectionSpecs() {
  return {
      {"wildtrack_cvlab1", 1743.4478759765625, 1735.1566162109375, 934.5202026367188,
       444.3987731933594, kWildtrackDistortion, kWildtrackRvec, kWildtrackTvecM},
      {"gopro", 970.4719658770618, 971.9647303584877, 951.3696748249695, 551.9352478769354,
       kGoproDistortion, {2.1, -0.3, 0.2}, {0.3, 1.2, 6.0}},
      {"no_fold", 1738.7144775390625, 1752.8876953125, 906.56689453125, 462.0346374511719,
       kNoFoldDistortion, {1.5, 0.9, -0.6}, {-2.0, 0.5, 12.0}},
      {"no_distortion", 1200, 1180, 955.5, 541.25, kNoDistortion, {-1.9, 0.1, 0.4},
       {0.0, -1.0, 5.0}},
  };
}

PinholeParameters ParametersOf(const CameraSpec& spec, int forward_sign = +1) {
  PinholeParameters p;
  p.image_size = spec.size;
  p.fx_px = spec.fx;
  p.fy_px = spec.fy;
  p.cx_px = spec.cx;
  p.cy_px = spec.cy;
  p.distortion = spec.distortion;
  p.cam_from_world_rotation = RotationFromRodrigues(spec.rvec);
  p.cam_from_world_translation_m = spec.tvec_m;
  p.forward_sign = forward_sign;
  return p;
}

PinholeCamera MakeCamera(const PinholeParameters& p) {
  Result<PinholeCamera> cam = PinholeCamera::Create(p);
  EXPECT_TRUE(cam.ok()) << cam.status().message();
  return std::move(cam).value();
}

std::vector<Eigen::Vector2d> OpenCvProjectPoints(
    const std::vector<Eigen::Vector3d>& points_in_world, const CameraSpec& spec) {
  std::vector<cv::Point3d> object;
  for (const Eigen::Vector3d& p : points_in_world) object.emplace_back(p.x(), p.y(), p.z());
  const cv::Matx33d k(spec.fx, 0, spec.cx, 0, spec.fy, spec.cy, 0, 0, 1);
  const std::vector<double> dist(spec.distortion.begin(), spec.distortion.end());
  const cv::Vec3d rvec(spec.rvec.x(), spec.rvec.y(), spec.rvec.z());
  const cv::Vec3d tvec(spec.tvec_m.x(), spec.tvec_m.y(), spec.tvec_m.z());
  std::vector<cv::Point2d> image;
  cv::projectPoints(object, rvec, tvec, k, dist, image);
  std::vector<Eigen::Vector2d> out;
  for (const cv::Point2d& q : image) out.emplace_back(q.x, q.y);
  return out;
}

// Random world points whose camera-frame depth has the sign `depth_sign`, spread over the
// normalised image plane up to r^2 < min(max_r2, 1.5), and over depths 0.5..40 m.
std::vector<Eigen::Vector3d> RandomPointsInView(const PinholeCamera& cam, int depth_sign,
                                                int count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> depth(0.5, 40.0);
  const double r2_limit = std::min(cam.max_valid_r2(), 1.5);
  const Eigen::Matrix3d world_from_cam = cam.params().cam_from_world_rotation.transpose();
  const Eigen::Vector3d t = cam.params().cam_from_world_translation_m;
  std::vector<Eigen::Vector3d> points;
  while (static_cast<int>(points.size()) < count) {
    const double r = std::sqrt(r2_limit);
    const Eigen::Vector2d xy(r * unit(rng), r * unit(rng));
    if (!(xy.squaredNorm() < r2_limit * (1 - 1e-9))) continue;
    const double z = depth_sign * depth(rng);
    const Eigen::Vector3d in_cam(xy.x() * z, xy.y() * z, z);
    points.push_back(world_from_cam * (in_cam - t));
  }
  return points;
}

// ---------------------------------------------------------------------------------------------
// Projection against OpenCV.

// Max error measured (5000 points per camera): wildtrack_cvlab1 4.6e-12 px, gopro 1.0e-12 px,
// no_fold 6.4e-10 px (its k3 = 4.3 sends points to pixels ~1e5 away), no_distortion 2.5e-12 px.
// With forward_sign = -1 (2000 points each): at most 4.8e-10 px, the same pattern.
TEST(PinholeCamera, ProjectMatchesOpenCvProjectPoints) {
  for (const CameraSpec& spec : ProjectionSpecs()) {
    const PinholeCamera cam = MakeCamera(ParametersOf(spec));
    const std::vector<Eigen::Vector3d> points = RandomPointsInView(cam, +1, 5000, 11);
    const std::vector<Eigen::Vector2d> expected = OpenCvProjectPoints(points, spec);
    double max_err_px = 0;
    for (size_t i = 0; i < points.size(); ++i) {
      const std::optional<Eigen::Vector2d> pixel = cam.Project(points[i]);
      ASSERT_TRUE(pixel.has_value()) << spec.name << " point " << points[i].transpose();
      const double err = (*pixel - expected[i]).norm();
      EXPECT_LT(err, 1e-6) << spec.name << " point " << points[i].transpose();
      max_err_px = std::max(max_err_px, err);
    }
    RecordProperty("max_error_px_" + spec.name, fmt::format("{:.3g}", max_err_px));
  }
}

TEST(PinholeCamera, NegativeForwardSignProjectsPointsBehindTheZEqualsZeroPlaneLikeOpenCv) {
  for (const CameraSpec& spec : ProjectionSpecs()) {
    const PinholeCamera cam = MakeCamera(ParametersOf(spec, -1));
    const std::vector<Eigen::Vector3d> behind = RandomPointsInView(cam, -1, 2000, 12);
    const std::vector<Eigen::Vector2d> expected = OpenCvProjectPoints(behind, spec);
    double max_err_px = 0;
    for (size_t i = 0; i < behind.size(); ++i) {
      const std::optional<Eigen::Vector2d> pixel = cam.Project(behind[i]);
      ASSERT_TRUE(pixel.has_value()) << spec.name << " point " << behind[i].transpose();
      const double err = (*pixel - expected[i]).norm();
      EXPECT_LT(err, 1e-6) << spec.name;
      max_err_px = std::max(max_err_px, err);
    }
    RecordProperty("max_error_px_" + spec.name, fmt::format("{:.3g}", max_err_px));
    // Points with positive camera z are behind a forward_sign = -1 camera.
    for (const Eigen::Vector3d& p : RandomPointsInView(cam, +1, 500, 13)) {
      EXPECT_FALSE(cam.Project(p).has_value()) << spec.name << " point " << p.transpose();
    }
  }
}

TEST(PinholeCamera, PointsBehindTheCameraOrOnItsPlaneDoNotProject) {
  for (const CameraSpec& spec : ProjectionSpecs()) {
    const PinholeCamera cam = MakeCamera(ParametersOf(spec));
    for (const Eigen::Vector3d& p : RandomPointsInView(cam, -1, 500, 14)) {
      EXPECT_FALSE(cam.Project(p).has_value()) << spec.name << " point " << p.transpose();
    }
    // Just behind the plane z_c = 0 (the centre computed as -R^T t is only within rounding of
    // that plane, so the plane itself is tested below with an exact pose).
    const Eigen::Matrix3d world_from_cam = cam.params().cam_from_world_rotation.transpose();
    const Eigen::Vector3d t = cam.params().cam_from_world_translation_m;
    EXPECT_FALSE(cam.Project(world_from_cam * (Eigen::Vector3d(0.3, 0.2, -1e-6) - t)).has_value());
    EXPECT_TRUE(cam.Project(world_from_cam * (Eigen::Vector3d(0, 0, 1e-6) - t)).has_value());
  }
  // Identity pose: camera frame = world frame, so z_c = 0 holds exactly.
  CameraSpec spec = ProjectionSpecs()[0];
  spec.rvec.setZero();
  spec.tvec_m.setZero();
  for (int sign : {+1, -1}) {
    const PinholeCamera cam = MakeCamera(ParametersOf(spec, sign));
    EXPECT_FALSE(cam.Project(Eigen::Vector3d::Zero()).has_value());
    EXPECT_FALSE(cam.Project(Eigen::Vector3d(1.0, -2.0, 0.0)).has_value());
    EXPECT_EQ(cam.Project(Eigen::Vector3d(0.0, 0.0, sign * 1.0)),
              Eigen::Vector2d(spec.cx, spec.cy));
    EXPECT_FALSE(cam.Project(Eigen::Vector3d(0.0, 0.0, -sign * 1.0)).has_value());
  }
}

TEST(PinholeCamera, PointsBeyondTheFoldRadiusDoNotProject) {
  const CameraSpec spec = ProjectionSpecs()[0];  // WILDTRACK, folds at r^2 = 0.68
  const PinholeCamera cam = MakeCamera(ParametersOf(spec));
  const double max_r2 = cam.max_valid_r2();
  ASSERT_TRUE(std::isfinite(max_r2));
  const Eigen::Matrix3d world_from_cam = cam.params().cam_from_world_rotation.transpose();
  const Eigen::Vector3d t = cam.params().cam_from_world_translation_m;
  auto point_at_r2 = [&](double r2) {
    const double r = std::sqrt(r2);
    const Eigen::Vector3d in_cam(0.6 * r * 3.0, 0.8 * r * 3.0, 3.0);
    return Eigen::Vector3d(world_from_cam * (in_cam - t));
  };
  EXPECT_TRUE(cam.Project(point_at_r2(0.999 * max_r2)).has_value());
  EXPECT_FALSE(cam.Project(point_at_r2(1.001 * max_r2)).has_value());
  EXPECT_FALSE(cam.Project(point_at_r2(4 * max_r2)).has_value());
}

// ---------------------------------------------------------------------------------------------
// The fold radius and the distortion's Jacobian.

TEST(PinholeCamera, MaxValidR2IsWhereTheRadialPolynomialStopsIncreasing) {
  for (const Distortion& d : {kWildtrackDistortion, kGoproDistortion}) {
    CameraSpec spec = ProjectionSpecs()[0];
    spec.distortion = d;
    const PinholeCamera cam = MakeCamera(ParametersOf(spec));
    const double s = cam.max_valid_r2();
    ASSERT_TRUE(std::isfinite(s));
    const double k1 = d[0], k2 = d[1], k3 = d[4];
    auto slope = [&](double r2) {
      return 1 + 3 * k1 * r2 + 5 * k2 * r2 * r2 + 7 * k3 * r2 * r2 * r2;
    };
    EXPECT_NEAR(slope(s), 0.0, 1e-12);
    EXPECT_GT(slope(s * (1 - 1e-6)), 0.0);
    EXPECT_LT(slope(s * (1 + 1e-6)), 0.0);
    for (double r2 = 1e-3; r2 < s; r2 += 1e-3) EXPECT_GT(slope(r2), 0.0) << r2;
  }
  // Known values: WILDTRACK CVLab1 folds at r^2 = 0.6814, the GoPro at r^2 = 2.7168.
  CameraSpec spec = ProjectionSpecs()[0];
  EXPECT_NEAR(MakeCamera(ParametersOf(spec)).max_valid_r2(), 0.6814, 1e-3);
  spec.distortion = kGoproDistortion;
  EXPECT_NEAR(MakeCamera(ParametersOf(spec)).max_valid_r2(), 2.7168, 1e-3);
}

TEST(PinholeCamera, MaxValidR2IsInfiniteWithoutAFold) {
  CameraSpec spec = ProjectionSpecs()[0];
  spec.distortion = kNoFoldDistortion;
  EXPECT_EQ(MakeCamera(ParametersOf(spec)).max_valid_r2(), std::numeric_limits<double>::infinity());
  spec.distortion = kNoDistortion;
  const PinholeCamera plain = MakeCamera(ParametersOf(spec));
  EXPECT_FALSE(plain.has_distortion());
  EXPECT_EQ(plain.max_valid_r2(), std::numeric_limits<double>::infinity());
  // Tangential terms alone count as distortion.
  spec.distortion = {0, 0, 1e-3, 0, 0};
  EXPECT_TRUE(MakeCamera(ParametersOf(spec)).has_distortion());
}

TEST(PinholeCamera, DistortJacobianMatchesFiniteDifferences) {
  for (const Distortion& d : {kWildtrackDistortion, kGoproDistortion, kNoFoldDistortion}) {
    CameraSpec spec = ProjectionSpecs()[0];
    spec.distortion = d;
    const PinholeCamera cam = MakeCamera(ParametersOf(spec));
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> unit(-0.5, 0.5);
    for (int i = 0; i < 200; ++i) {
      const Eigen::Vector2d xy(unit(rng), unit(rng));
      Eigen::Matrix2d jac;
      cam.Distort(xy, &jac);
      const double h = 1e-6;
      Eigen::Matrix2d numeric;
      const Eigen::Vector2d dx(h, 0), dy(0, h);
      numeric.col(0) = (cam.Distort(xy + dx) - cam.Distort(xy - dx)) / (2 * h);
      numeric.col(1) = (cam.Distort(xy + dy) - cam.Distort(xy - dy)) / (2 * h);
      EXPECT_LT((jac - numeric).cwiseAbs().maxCoeff(), 1e-8) << xy.transpose();
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Undistortion and back-projection.

// Cameras whose whole 1920x1080 image lies inside the fold: WILDTRACK's and the GoPro's
// distortion with focal lengths long enough for that (their real calibrations have corners
// beyond the fold, see below).
std::vector<CameraSpec> WholeImageSpecs() {
  return {
      {"wildtrack_f2000", 2000, 1990, 950.5, 530.25, kWildtrackDistortion, kWildtrackRvec,
       kWildtrackTvecM},
      {"gopro_f1200", 1200, 1201, 951.37, 551.94, kGoproDistortion, kWildtrackRvec,
       kWildtrackTvecM},
      {"no_fold", 1738.7144775390625, 1752.8876953125, 906.56689453125, 462.0346374511719,
       kNoFoldDistortion, kWildtrackRvec, kWildtrackTvecM},
  };
}

// Measured for all three cameras: residual and Project(BackProject) round trip at most 1.0e-9 px
// (Newton stops once below 1e-3 of the 1e-6 px tolerance), at most 5 Newton iterations.
TEST(PinholeCamera, UndistortConvergesForEveryPixelOfTheImage) {
  for (const CameraSpec& spec : WholeImageSpecs()) {
    const PinholeCamera cam = MakeCamera(ParametersOf(spec));
    double max_residual_px = 0, max_round_trip_px = 0;
    int max_iterations = 0;
    for (int v = 0; v < 1080; v += 16) {
      for (int u = 0; u < 1920; u += 16) {
        const Eigen::Vector2d pixel(u, v);
        const UndistortResult r = cam.Undistort(pixel);
        ASSERT_EQ(r.outcome, UndistortOutcome::kConverged)
            << spec.name << " pixel " << u << "," << v;
        EXPECT_LE(r.residual_px, 1e-6);
        EXPECT_LT(r.normalized.squaredNorm(), cam.max_valid_r2());
        max_residual_px = std::max(max_residual_px, r.residual_px);
        max_iterations = std::max(max_iterations, r.iterations);
        // The normalised point distorts back onto the pixel.
        const Eigen::Vector2d d = cam.Distort(r.normalized);
        const Eigen::Vector2d again(spec.fx * d.x() + spec.cx, spec.fy * d.y() + spec.cy);
        EXPECT_LT((again - pixel).norm(), 1e-6);
        // And the ray projects back onto the pixel.
        const std::optional<Ray> ray = cam.BackProject(pixel);
        ASSERT_TRUE(ray.has_value());
        EXPECT_NEAR(ray->direction_in_world.norm(), 1.0, 1e-12);
        const std::optional<Eigen::Vector2d> back =
            cam.Project(ray->origin_in_world + 7.5 * ray->direction_in_world);
        ASSERT_TRUE(back.has_value()) << spec.name << " pixel " << u << "," << v;
        const double err = (*back - pixel).norm();
        EXPECT_LT(err, 1e-6) << spec.name << " pixel " << u << "," << v;
        max_round_trip_px = std::max(max_round_trip_px, err);
      }
    }
    RecordProperty("max_residual_px_" + spec.name, fmt::format("{:.3g}", max_residual_px));
    RecordProperty("max_round_trip_px_" + spec.name, fmt::format("{:.3g}", max_round_trip_px));
    RecordProperty("max_iterations_" + spec.name, max_iterations);
  }
}

TEST(PinholeCamera, UndistortWithoutDistortionIsTheInverseCameraMatrix) {
  PinholeParameters p = ParametersOf(ProjectionSpecs()[3]);
  p.skew_px = 3.5;
  const PinholeCamera cam = MakeCamera(p);
  const UndistortResult r = cam.Undistort({100.0, 900.0});
  EXPECT_EQ(r.outcome, UndistortOutcome::kConverged);
  const double y = (900.0 - p.cy_px) / p.fy_px;
  const double x = (100.0 - p.cx_px - p.skew_px * y) / p.fx_px;
  EXPECT_NEAR(r.normalized.x(), x, 1e-15);
  EXPECT_NEAR(r.normalized.y(), y, 1e-15);
}

TEST(PinholeCamera, SkewIsInvertedByUndistort) {
  PinholeParameters p = ParametersOf(WholeImageSpecs()[0]);
  p.skew_px = 2.5;
  const PinholeCamera cam = MakeCamera(p);
  for (int v = 0; v < 1080; v += 120) {
    for (int u = 0; u < 1920; u += 120) {
      const Eigen::Vector2d pixel(u, v);
      const std::optional<Ray> ray = cam.BackProject(pixel);
      ASSERT_TRUE(ray.has_value());
      const std::optional<Eigen::Vector2d> back =
          cam.Project(ray->origin_in_world + 3.0 * ray->direction_in_world);
      ASSERT_TRUE(back.has_value());
      EXPECT_LT((*back - pixel).norm(), 1e-6) << pixel.transpose();
    }
  }
}

// Strong barrel distortion (k1 = -0.9 folds at r^2 = 1/2.7, distorted radius 0.406) with a
// short focal length: most of a 1920x1080 image lies beyond the fold. Those pixels have no
// ray; the ones inside still converge; and no pixel ever gets a ray that does not project back.
TEST(PinholeCamera, PixelsBeyondTheFoldHaveNoRay) {
  const CameraSpec spec{"strong_barrel", 1000, 1000, 959.5, 539.5, {-0.9, 0, 0, 0, 0},
                        kWildtrackRvec, kWildtrackTvecM};
  const PinholeCamera cam = MakeCamera(ParametersOf(spec));
  const double max_r2 = cam.max_valid_r2();
  EXPECT_NEAR(max_r2, 1.0 / 2.7, 1e-9);
  const double fold_rd = std::sqrt(max_r2) * (1 - 0.9 * max_r2);  // 0.4057
  int converged = 0, beyond = 0, not_converged = 0;
  for (int v = 0; v < 1080; v += 16) {
    for (int u = 0; u < 1920; u += 16) {
      const Eigen::Vector2d pixel(u, v);
      const double rd = std::hypot((u - spec.cx) / spec.fx, (v - spec.cy) / spec.fy);
      const UndistortResult r = cam.Undistort(pixel);
      const std::optional<Ray> ray = cam.BackProject(pixel);
      EXPECT_EQ(ray.has_value(), r.outcome == UndistortOutcome::kConverged);
      switch (r.outcome) {
        case UndistortOutcome::kConverged: {
          ++converged;
          EXPECT_LE(rd, fold_rd * (1 + 1e-9)) << pixel.transpose();
          EXPECT_LE(r.normalized.squaredNorm(), max_r2);
          ASSERT_TRUE(ray.has_value());
          const std::optional<Eigen::Vector2d> back =
              cam.Project(ray->origin_in_world + 4.0 * ray->direction_in_world);
          ASSERT_TRUE(back.has_value()) << pixel.transpose();
          EXPECT_LT((*back - pixel).norm(), 1e-6) << pixel.transpose();
          break;
        }
        case UndistortOutcome::kBeyondValidRadius:
          ++beyond;
          EXPECT_GT(rd, fold_rd * 0.999) << pixel.transpose();
          break;
        case UndistortOutcome::kNotConverged:
          ++not_converged;
          EXPECT_GT(rd, fold_rd * 0.999) << pixel.transpose();
          break;
      }
      // Inside the fold (with a margin for the iteration), every pixel must converge.
      if (rd < 0.99 * fold_rd) {
        EXPECT_EQ(r.outcome, UndistortOutcome::kConverged) << pixel.transpose();
      }
      if (rd > 1.001 * fold_rd) {
        EXPECT_FALSE(ray.has_value()) << pixel.transpose();
      }
    }
  }
  EXPECT_GT(converged, 500);
  EXPECT_GT(beyond + not_converged, 4000);
  RecordProperty("converged", converged);
  RecordProperty("beyond_valid_radius", beyond);
  RecordProperty("not_converged", not_converged);
}

// Pincushion distortion that folds (k1 > 0, k2 < 0): the distorted radius is larger than the
// undistorted one, so near the fold the distorted pixel itself lies beyond the valid radius.
// Newton's iteration must still find the ray of every pixel whose point is inside the fold.
TEST(PinholeCamera, UndistortConvergesForPincushionPixelsNearTheFold) {
  const CameraSpec spec{"pincushion", 500, 500, 959.5, 539.5, {0.2, -0.05, 0, 0, 0},
                        kWildtrackRvec, kWildtrackTvecM};
  const PinholeCamera cam = MakeCamera(ParametersOf(spec));
  const double max_r2 = cam.max_valid_r2();
  // slope 1 + 0.6 s - 0.25 s^2 = 0 at s = 3.5326.
  EXPECT_NEAR(max_r2, (0.6 + std::sqrt(0.36 + 1.0)) / 0.5, 1e-9);
  int start_beyond = 0;
  for (double r : {0.1, 0.5, 1.0, 1.5, 1.7, 1.8, 1.85, 1.87}) {
    for (double angle : {0.0, 0.7, 2.0, 3.9}) {
      const Eigen::Vector2d xy(r * std::cos(angle), r * std::sin(angle));
      ASSERT_LT(xy.squaredNorm(), max_r2);
      const Eigen::Vector2d d = cam.Distort(xy);
      if (d.squaredNorm() > max_r2) ++start_beyond;
      const Eigen::Vector2d pixel(spec.fx * d.x() + spec.cx, spec.fy * d.y() + spec.cy);
      const UndistortResult u = cam.Undistort(pixel);
      EXPECT_EQ(u.outcome, UndistortOutcome::kConverged) << "r = " << r << ", angle " << angle;
      EXPECT_LT((u.normalized - xy).norm(), 1e-9) << "r = " << r << ", angle " << angle;
    }
  }
  EXPECT_GT(start_beyond, 0);
  // Random points anywhere inside the fold.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    const double r = std::sqrt(0.999 * max_r2 * unit(rng));
    const double angle = 2 * std::numbers::pi * unit(rng);
    const Eigen::Vector2d xy(r * std::cos(angle), r * std::sin(angle));
    const Eigen::Vector2d d = cam.Distort(xy);
    const Eigen::Vector2d pixel(spec.fx * d.x() + spec.cx, spec.fy * d.y() + spec.cy);
    const UndistortResult u = cam.Undistort(pixel);
    ASSERT_EQ(u.outcome, UndistortOutcome::kConverged) << "r = " << r << ", angle " << angle;
    EXPECT_LT((u.normalized - xy).norm(), 1e-8) << "r = " << r << ", angle " << angle;
  }
  // Pixels beyond the fold's distorted radius have no ray.
  const double fold_rd = std::sqrt(max_r2) * (1 + 0.2 * max_r2 - 0.05 * max_r2 * max_r2);
  for (double factor : {1.001, 1.1, 2.0}) {
    const Eigen::Vector2d pixel(spec.cx + factor * fold_rd * spec.fx * 0.6,
                                spec.cy + factor * fold_rd * spec.fy * 0.8);
    EXPECT_NE(cam.Undistort(pixel).outcome, UndistortOutcome::kConverged) << factor;
    EXPECT_FALSE(cam.BackProject(pixel).has_value()) << factor;
  }
}

// The real WILDTRACK CVLab1 and GoPro calibrations: their image corners lie beyond the fold.
// Every pixel either converges to a ray that projects back onto it, or has no ray.
TEST(PinholeCamera, RealCalibrationsEitherRoundTripOrHaveNoRay) {
  for (const CameraSpec& spec : {ProjectionSpecs()[0], ProjectionSpecs()[1]}) {
    const PinholeCamera cam = MakeCamera(ParametersOf(spec));
    int without_ray = 0, with_ray = 0;
    for (int v = 0; v < 1080; v += 16) {
      for (int u = 0; u < 1920; u += 16) {
        const Eigen::Vector2d pixel(u, v);
        const std::optional<Ray> ray = cam.BackProject(pixel);
        if (!ray) {
          ++without_ray;
          continue;
        }
        ++with_ray;
        const std::optional<Eigen::Vector2d> back =
            cam.Project(ray->origin_in_world + 5.0 * ray->direction_in_world);
        ASSERT_TRUE(back.has_value()) << spec.name << " " << pixel.transpose();
        EXPECT_LT((*back - pixel).norm(), 1e-6) << spec.name << " " << pixel.transpose();
      }
    }
    // The centre of the image always has rays; some corners do not.
    EXPECT_TRUE(cam.BackProject({spec.cx, spec.cy}).has_value()) << spec.name;
    EXPECT_GT(with_ray, 7000) << spec.name;
    EXPECT_GT(without_ray, 0) << spec.name;
    RecordProperty("pixels_without_ray_" + spec.name, without_ray);
  }
}

// ---------------------------------------------------------------------------------------------
// Pixel -> plane.

TEST(PinholeCamera, PixelToPlaneAgreesWithBackProjectAndIntersectRayWithPlane) {
  for (const CameraSpec& spec : WholeImageSpecs()) {
    for (int sign : {+1, -1}) {
      const PinholeCamera cam = MakeCamera(ParametersOf(spec, sign));
      int hits = 0;
      // forward_sign = -1 turns the camera to the sky: it sees only planes above it.
      const double above_m = cam.CenterInWorld()->z() + 1.5;
      for (double plane_z_m : {0.0, 1.0, -0.5, above_m}) {
        for (int v = 0; v < 1080; v += 40) {
          for (int u = 0; u < 1920; u += 40) {
            const Eigen::Vector2d pixel(u, v);
            const std::optional<Eigen::Vector2d> fast = cam.PixelToPlane(pixel, plane_z_m);
            const std::optional<Ray> ray = cam.BackProject(pixel);
            ASSERT_TRUE(ray.has_value());
            const std::optional<Eigen::Vector2d> reference = IntersectRayWithPlane(*ray, plane_z_m);
            ASSERT_EQ(fast.has_value(), reference.has_value())
                << spec.name << " " << pixel.transpose();
            if (!fast) continue;
            ++hits;
            EXPECT_LT((*fast - *reference).norm(), 1e-9 * std::max(1.0, reference->norm()))
                << spec.name << " " << pixel.transpose();
          }
        }
      }
      EXPECT_GT(hits, 100) << spec.name << " sign " << sign;
    }
  }
}

TEST(PinholeCamera, PixelToPlaneWorksAtAnyPlaneHeight) {
  for (const CameraSpec& spec : WholeImageSpecs()) {
    for (int sign : {+1, -1}) {
      const PinholeCamera cam = MakeCamera(ParametersOf(spec, sign));
      EXPECT_TRUE(cam.SupportsPlaneHeight(1.0));
      double max_err_px = 0;
      int hits = 0;
      const double above_m = cam.CenterInWorld()->z() + 1.5;
      for (double plane_z_m : {0.0, 1.0, 1.8, above_m}) {
        for (int v = 0; v < 1080; v += 20) {
          for (int u = 0; u < 1920; u += 20) {
            const Eigen::Vector2d pixel(u, v);
            const std::optional<Eigen::Vector2d> xy = cam.PixelToPlane(pixel, plane_z_m);
            if (!xy) continue;
            ++hits;
            const std::optional<Eigen::Vector2d> back =
                cam.Project(Eigen::Vector3d(xy->x(), xy->y(), plane_z_m));
            ASSERT_TRUE(back.has_value()) << spec.name << " " << pixel.transpose();
            const double err = (*back - pixel).norm();
            EXPECT_LT(err, 1e-6) << spec.name << " " << pixel.transpose() << " z " << plane_z_m;
            max_err_px = std::max(max_err_px, err);
          }
        }
      }
      EXPECT_GT(hits, 1000) << spec.name << " sign " << sign;
      RecordProperty(fmt::format("max_error_px_{}_sign{}", spec.name, sign),
                     fmt::format("{:.3g}", max_err_px));
    }
  }
}

TEST(PinholeCamera, PixelToPlaneRejectsPlanesBehindTheCamera) {
  // A camera 3 m above the floor looking straight down: the floor is in front of every pixel,
  // a plane above the camera is behind every pixel.
  PinholeParameters p;
  p.image_size = {640, 480};
  p.fx_px = p.fy_px = 500;
  p.cx_px = 319.5;
  p.cy_px = 239.5;
  p.cam_from_world_rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();  // z_c = -z_w
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * Eigen::Vector3d(1, 2, 3);
  const PinholeCamera cam = MakeCamera(p);
  EXPECT_LT((*cam.CenterInWorld() - Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);
  const std::optional<Eigen::Vector2d> below = cam.PixelToPlane({319.5, 239.5}, 0.0);
  ASSERT_TRUE(below.has_value());
  EXPECT_LT((*below - Eigen::Vector2d(1, 2)).norm(), 1e-12);
  EXPECT_FALSE(cam.PixelToPlane({319.5, 239.5}, 4.0).has_value());
  EXPECT_FALSE(cam.PixelToPlane({0, 0}, 3.0).has_value());  // the camera's own height
  // The same camera with forward_sign = -1 looks up: now only the plane above is seen.
  const PinholeCamera up = cam.WithForwardSign(-1);
  EXPECT_FALSE(up.PixelToPlane({319.5, 239.5}, 0.0).has_value());
  const std::optional<Eigen::Vector2d> above = up.PixelToPlane({319.5, 239.5}, 4.0);
  ASSERT_TRUE(above.has_value());
  EXPECT_LT((*above - Eigen::Vector2d(1, 2)).norm(), 1e-12);
}

TEST(PinholeCamera, WithForwardSignEqualsCreatingWithThatSign) {
  const CameraSpec spec = ProjectionSpecs()[0];
  const PinholeCamera plus = MakeCamera(ParametersOf(spec, +1));
  const PinholeCamera minus = MakeCamera(ParametersOf(spec, -1));
  const PinholeCamera flipped = plus.WithForwardSign(-1);
  EXPECT_EQ(flipped.params().forward_sign, -1);
  Hasher a, b, c;
  minus.AppendToHash(a);
  flipped.AppendToHash(b);
  plus.AppendToHash(c);
  EXPECT_EQ(a.Digest(), b.Digest());
  EXPECT_NE(a.Digest(), c.Digest());
  for (const Eigen::Vector3d& p : RandomPointsInView(minus, -1, 100, 21)) {
    EXPECT_EQ(flipped.Project(p), minus.Project(p));
  }
}

// ---------------------------------------------------------------------------------------------
// Resize, clone, hash.

TEST(PinholeCamera, ResizedToQuarterSizeMapsPixelsByTheRescaleFormula) {
  for (const CameraSpec& spec : ProjectionSpecs()) {
    PinholeParameters p = ParametersOf(spec);
    p.skew_px = 1.5;
    const PinholeCamera cam = MakeCamera(p);
    const std::unique_ptr<CameraModel> quarter = cam.Resized({480, 270});
    EXPECT_EQ(quarter->image_size(), (ImageSize{480, 270}));
    EXPECT_EQ(quarter->kind(), "pinhole");
    double max_err_px = 0;
    for (const Eigen::Vector3d& point : RandomPointsInView(cam, +1, 1000, 31)) {
      const std::optional<Eigen::Vector2d> full = cam.Project(point);
      const std::optional<Eigen::Vector2d> small = quarter->Project(point);
      ASSERT_TRUE(full.has_value());
      ASSERT_TRUE(small.has_value());
      const Eigen::Vector2d expected((full->x() + 0.5) * 0.25 - 0.5,
                                     (full->y() + 0.5) * 0.25 - 0.5);
      const double err = (*small - expected).norm();
      EXPECT_LT(err, 1e-9) << spec.name;
      max_err_px = std::max(max_err_px, err);
    }
    // The quarter-size pixel sees the same floor point as the full-size pixel it covers.
    for (double v = 0; v < 270; v += 15) {
      for (double u = 0; u < 480; u += 15) {
        const std::optional<Eigen::Vector2d> a = quarter->PixelToPlane({u, v}, 0.0);
        const std::optional<Eigen::Vector2d> b =
            cam.PixelToPlane({(u + 0.5) * 4 - 0.5, (v + 0.5) * 4 - 0.5}, 0.0);
        ASSERT_EQ(a.has_value(), b.has_value()) << spec.name << " " << u << "," << v;
        if (a) {
          EXPECT_LT((*a - *b).norm(), 1e-6 * std::max(1.0, b->norm())) << spec.name;
        }
      }
    }
  }
}

TEST(PinholeCamera, ResizedKeepsTheForwardSign) {
  const PinholeCamera cam = MakeCamera(ParametersOf(ProjectionSpecs()[0], -1));
  const std::unique_ptr<CameraModel> half = cam.Resized({960, 540});
  const auto* pinhole = dynamic_cast<const PinholeCamera*>(half.get());
  ASSERT_NE(pinhole, nullptr);
  EXPECT_EQ(pinhole->params().forward_sign, -1);
}

TEST(PinholeCamera, CloneProjectsLikeTheOriginal) {
  const CameraSpec spec = ProjectionSpecs()[1];
  const PinholeCamera cam = MakeCamera(ParametersOf(spec));
  const std::unique_ptr<CameraModel> clone = cam.Clone();
  EXPECT_EQ(clone->kind(), "pinhole");
  EXPECT_EQ(clone->image_size(), cam.image_size());
  EXPECT_EQ(clone->CenterInWorld(), cam.CenterInWorld());
  for (const Eigen::Vector3d& p : RandomPointsInView(cam, +1, 50, 41)) {
    EXPECT_EQ(clone->Project(p), cam.Project(p));
  }
  Hasher a, b;
  cam.AppendToHash(a);
  clone->AppendToHash(b);
  EXPECT_EQ(a.Digest(), b.Digest());
}

TEST(PinholeCamera, HashChangesWithEveryGeometricParameter) {
  auto digest = [](const PinholeParameters& p) {
    Hasher h;
    MakeCamera(p).AppendToHash(h);
    return h.Digest();
  };
  const PinholeParameters base = ParametersOf(ProjectionSpecs()[0]);
  const uint64_t base_digest = digest(base);
  std::vector<PinholeParameters> changed(14, base);
  changed[0].image_size.width += 1;
  changed[1].image_size.height += 1;
  changed[2].fx_px += 1;
  changed[3].fy_px += 1;
  changed[4].cx_px += 1;
  changed[5].cy_px += 1;
  changed[6].skew_px += 1;
  changed[7].distortion[0] += 1e-3;
  changed[8].distortion[3] += 1e-3;
  changed[9].distortion[4] += 1e-3;
  changed[10].cam_from_world_rotation = RotationFromRodrigues({1.7, 0.4, -0.3});
  changed[11].cam_from_world_translation_m.z() += 0.01;
  changed[12].forward_sign = -1;
  changed[13].distortion[2] += 1e-3;
  for (size_t i = 0; i < changed.size(); ++i) EXPECT_NE(digest(changed[i]), base_digest) << i;
}

// ---------------------------------------------------------------------------------------------
// The base-class helpers every model relies on (camera_model.h).

TEST(IntersectRayWithPlane, MeetsThePlaneOnlyInFrontOfTheOrigin) {
  const Ray down{{1.0, 2.0, 3.0}, Eigen::Vector3d(0.6, 0.0, -0.8)};
  const std::optional<Eigen::Vector2d> floor = IntersectRayWithPlane(down, 0.0);
  ASSERT_TRUE(floor.has_value());
  EXPECT_LT((*floor - Eigen::Vector2d(1.0 + 0.6 * 3.75, 2.0)).norm(), 1e-15);
  const std::optional<Eigen::Vector2d> at_one = IntersectRayWithPlane(down, 1.0);
  ASSERT_TRUE(at_one.has_value());
  EXPECT_LT((*at_one - Eigen::Vector2d(1.0 + 0.6 * 2.5, 2.0)).norm(), 1e-15);
  // The plane behind the origin, the origin's own plane, and a parallel ray: no point.
  EXPECT_FALSE(IntersectRayWithPlane(down, 4.0).has_value());
  EXPECT_FALSE(IntersectRayWithPlane(down, 3.0).has_value());
  const Ray level{{1.0, 2.0, 3.0}, Eigen::Vector3d(1.0, 0.0, 0.0)};
  EXPECT_FALSE(IntersectRayWithPlane(level, 0.0).has_value());
  // A ray pointing up meets planes above it.
  const Ray up{{0.0, 0.0, 0.0}, Eigen::Vector3d(0.0, 0.6, 0.8)};
  const std::optional<Eigen::Vector2d> ceiling = IntersectRayWithPlane(up, 4.0);
  ASSERT_TRUE(ceiling.has_value());
  EXPECT_LT((*ceiling - Eigen::Vector2d(0.0, 3.0)).norm(), 1e-15);
}

TEST(CameraModel, InImageCoversHalfAPixelAroundTheCentres) {
  const PinholeCamera cam = MakeCamera(ParametersOf(ProjectionSpecs()[3]));  // 1920 x 1080
  EXPECT_TRUE(cam.InImage({-0.5, -0.5}));
  EXPECT_TRUE(cam.InImage({0.0, 0.0}));
  EXPECT_TRUE(cam.InImage({1919.49, 1079.49}));
  EXPECT_FALSE(cam.InImage({1919.5, 500}));
  EXPECT_FALSE(cam.InImage({500, 1079.5}));
  EXPECT_FALSE(cam.InImage({-0.5000001, 500}));
  EXPECT_FALSE(cam.InImage({500, -0.5000001}));
}

TEST(PixelRescale, MapsPixelCentresUnderTheHalfPixelConvention) {
  const PixelRescale quarter = PixelRescale::Between({1920, 1080}, {480, 270});
  EXPECT_EQ(quarter.scale_x, 0.25);
  EXPECT_EQ(quarter.scale_y, 0.25);
  // The image corners map to the image corners; the 4x4 block of pixels 0..3 to pixel 0.
  EXPECT_EQ(quarter.MapU(-0.5), -0.5);
  EXPECT_EQ(quarter.MapV(1079.5), 269.5);
  EXPECT_EQ(quarter.MapU(1.5), 0.0);
  EXPECT_EQ(quarter.MapV(5.5), 1.0);
  const PixelRescale odd = PixelRescale::Between({720, 576}, {1000, 500});
  EXPECT_DOUBLE_EQ(odd.scale_x, 1000.0 / 720.0);
  EXPECT_DOUBLE_EQ(odd.scale_y, 500.0 / 576.0);
  EXPECT_DOUBLE_EQ(odd.MapU(719.5), 999.5);
}

// ---------------------------------------------------------------------------------------------
// Validate: a table of bad parameters, each with its exact message.

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

struct BadPinholeCase {
  std::string name;
  void (*mutate)(PinholeParameters&);
  std::string message;
};

TEST(PinholeParameters, ValidateAcceptsEverySyntheticCamera) {
  for (const CameraSpec& spec : ProjectionSpecs()) {
    EXPECT_TRUE(ParametersOf(spec, +1).Validate().ok()) << spec.name;
    EXPECT_TRUE(ParametersOf(spec, -1).Validate().ok()) << spec.name;
  }
}

TEST(PinholeParameters, ValidateRejectsBadValuesWithTheirMessages) {
  const std::vector<BadPinholeCase> cases = {
      {"zero fx", [](PinholeParameters& p) { p.fx_px = 0; },
       "camera matrix: expected positive focal lengths, found fx = 0, fy = 1735.1566162109375"},
      {"negative fy", [](PinholeParameters& p) { p.fy_px = -5; },
       "camera matrix: expected positive focal lengths, found fx = 1743.4478759765625, fy = -5"},
      {"NaN fx", [](PinholeParameters& p) { p.fx_px = kNaN; },
       "camera matrix: expected finite values, found NaN or infinity"},
      {"infinite cy", [](PinholeParameters& p) { p.cy_px = kInf; },
       "camera matrix: expected finite values, found NaN or infinity"},
      {"NaN skew", [](PinholeParameters& p) { p.skew_px = kNaN; },
       "camera matrix: expected finite values, found NaN or infinity"},
      {"NaN k1", [](PinholeParameters& p) { p.distortion[0] = kNaN; },
       "distortion: expected finite values, found NaN or infinity"},
      {"infinite k3", [](PinholeParameters& p) { p.distortion[4] = -kInf; },
       "distortion: expected finite values, found NaN or infinity"},
      {"NaN in rotation", [](PinholeParameters& p) { p.cam_from_world_rotation(2, 0) = kNaN; },
       "extrinsics: expected finite values, found NaN or infinity"},
      {"NaN in translation",
       [](PinholeParameters& p) { p.cam_from_world_translation_m.y() = kNaN; },
       "extrinsics: expected finite values, found NaN or infinity"},
      {"stretched rotation",
       [](PinholeParameters& p) {
         p.cam_from_world_rotation = Eigen::Vector3d(2, 1, 1).asDiagonal();
       },
       "rotation: expected an orthonormal matrix with determinant +1, found |R R^T - I| = 3, "
       "det = 2"},
      {"reflection",
       [](PinholeParameters& p) {
         p.cam_from_world_rotation = Eigen::Vector3d(1, -1, 1).asDiagonal();
       },
       "rotation: expected an orthonormal matrix with determinant +1, found |R R^T - I| = 0, "
       "det = -1"},
      {"zero forward sign", [](PinholeParameters& p) { p.forward_sign = 0; },
       "forward sign: expected +1 or -1, found 0"},
      {"forward sign 2", [](PinholeParameters& p) { p.forward_sign = 2; },
       "forward sign: expected +1 or -1, found 2"},
      {"zero width", [](PinholeParameters& p) { p.image_size.width = 0; },
       "image size: expected positive, found 0x1080"},
      {"negative height", [](PinholeParameters& p) { p.image_size.height = -3; },
       "image size: expected positive, found 1920x-3"},
  };
  for (const BadPinholeCase& c : cases) {
    PinholeParameters p = ParametersOf(ProjectionSpecs()[0]);
    c.mutate(p);
    const Status status = p.Validate();
    EXPECT_FALSE(status.ok()) << c.name;
    EXPECT_EQ(status.code(), StatusCode::kInvalidInput) << c.name;
    EXPECT_EQ(status.message(), c.message) << c.name;
    const Result<PinholeCamera> cam = PinholeCamera::Create(p);
    EXPECT_FALSE(cam.ok()) << c.name;
    EXPECT_EQ(cam.status().message(), c.message) << c.name;
  }
}

}  // namespace
}  // namespace occmap
