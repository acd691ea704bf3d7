// PinholeCamera: OpenCV's pinhole model with Brown-Conrady distortion (k1 k2 p1 p2 k3).
//
//   x = X_c / Z_c, y = Y_c / Z_c, r^2 = x^2 + y^2
//   x' = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y' = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y
//   u = fx x' + skew y' + cx,  v = fy y' + cy
// identical to cv::projectPoints (which has no skew term; skew is 0 in every OpenCV
// calibration). Undistortion (pixel -> ray) runs Newton's method with the exact Jacobian until
// the re-distorted point is within 1e-6 px of the pixel; where it does not converge, or
// converges beyond the radius where the radial polynomial stops increasing (the lens model
// folds back there), the pixel has no ray and Undistort says why.
//
// forward_sign: +1 for ordinary calibrations. MultiviewX was calibrated in a left-handed world
// and the points its cameras see have Z_c < 0; its cameras get forward_sign = -1 (decided from
// where the floor projects, see calib/), and "in front" means forward_sign * Z_c > 0.
//
//   PinholeParameters p;  p.fx = p.fy = 1000; p.cx = 960; p.cy = 540; ...
//   OCCMAP_ASSIGN_OR_RETURN(PinholeCamera cam, PinholeCamera::Create(p));
#pragma once

#include <Eigen/Core>
#include <array>

#include "occmap/geometry/camera_model.h"
#include "occmap/util/status.h"

namespace occmap {

struct PinholeParameters {
  ImageSize image_size;
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0, skew_px = 0;
  std::array<double, 5> distortion = {0, 0, 0, 0, 0};  // k1 k2 p1 p2 k3 (OpenCV order)
  Eigen::Matrix3d cam_from_world_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d cam_from_world_translation_m = Eigen::Vector3d::Zero();
  int forward_sign = +1;

  Status Validate() const;
};

enum class UndistortOutcome { kConverged, kNotConverged, kBeyondValidRadius };

struct UndistortResult {
  UndistortOutcome outcome = UndistortOutcome::kNotConverged;
  Eigen::Vector2d normalized = Eigen::Vector2d::Zero();  // (x, y) on the plane Z_c = 1
  double residual_px = 0;
  int iterations = 0;
};

class PinholeCamera final : public CameraModel {
 public:
  static constexpr double kUndistortTolerancePx = 1e-6;
  static constexpr int kMaxUndistortIterations = 50;

  static Result<PinholeCamera> Create(const PinholeParameters& params);

  std::string_view kind() const override { return "pinhole"; }
  ImageSize image_size() const override { return p_.image_size; }
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point_in_world) const override;
  std::optional<Ray> BackProject(const Eigen::Vector2d& pixel) const override;
  std::optional<Eigen::Vector2d> PixelToPlane(const Eigen::Vector2d& pixel,
                                              double plane_z_m) const override;
  std::unique_ptr<CameraModel> Resized(ImageSize new_size) const override;
  std::unique_ptr<CameraModel> Clone() const override;
  void AppendToHash(Hasher& hasher) const override;
  std::optional<Eigen::Vector3d> CenterInWorld() const override { return center_in_world_; }

  const PinholeParameters& params() const { return p_; }
  bool has_distortion() const { return has_distortion_; }
  // Largest undistorted r^2 where the radial distortion is still increasing (+inf if always).
  double max_valid_r2() const { return max_valid_r2_; }

  // Normalised (x, y) -> distorted normalised (x', y'), with the Jacobian d(x', y')/d(x, y).
  Eigen::Vector2d Distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* jacobian = nullptr) const;
  // Pixel -> undistorted normalised coordinates, by Newton's method.
  UndistortResult Undistort(const Eigen::Vector2d& pixel) const;

  // A copy with a different forward sign (MultiviewX).
  PinholeCamera WithForwardSign(int sign) const;

 private:
  explicit PinholeCamera(const PinholeParameters& p);
  PinholeParameters p_;
  bool has_distortion_ = false;
  double max_valid_r2_ = 0;
  Eigen::Matrix3d world_from_cam_rotation_;
  Eigen::Vector3d center_in_world_;
};

}  // namespace occmap
