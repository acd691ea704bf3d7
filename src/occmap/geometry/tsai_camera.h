// TsaiCamera: Tsai's camera model exactly as in the paper, equations 6-20.
//
//   world -> camera      P_c = R P_w + T                                   (6)
//   perspective          U_u = f x_c / z_c,  V_u = f y_c / z_c             (7, 8)
//   radial distortion    U_u = U_d (1 + kappa1 r^2), r^2 = U_d^2 + V_d^2   (9, 10, 16, 17)
//   digitisation         U_f = s_x U_d / d'_x + C_x,  V_f = V_d / d_y + C_y (11, 12)
// with d'_x = d_x N_cx / N_fx. Image -> floor (14-20) applies the distortion formula directly;
// world -> image inverts it in closed form (Cardan's method, as Willson's reference code), so
// both directions agree to rounding. Sensor-plane lengths (f, d_x, d_y) stay in millimetres
// as calibrated (they only appear in ratios); T is in metres like every world length.
//
//   TsaiParameters p = ...;                       // calib/tsai_yaml.h reads them
//   OCCMAP_ASSIGN_OR_RETURN(TsaiCamera cam, TsaiCamera::Create(p));
//   auto pixel = cam.Project({1.0, 2.0, 0.0});
#pragma once

#include <Eigen/Core>

#include "occmap/geometry/camera_model.h"
#include "occmap/util/status.h"

namespace occmap {

struct TsaiParameters {
  ImageSize image_size;
  double Ncx = 0;              // sensor elements in x
  double Nfx = 0;              // pixels in a frame-grabber line
  double dx_mm = 0;            // sensor element spacing in x
  double dy_mm = 0;            // sensor element spacing in y
  double sx = 1;               // horizontal scale factor
  double Cx_px = 0;            // image centre (principal point), pixels
  double Cy_px = 0;
  double f_mm = 0;             // effective focal length
  double kappa1_per_mm2 = 0;   // radial distortion, on the distorted sensor radius
  Eigen::Matrix3d cam_from_world_rotation = Eigen::Matrix3d::Identity();  // R
  Eigen::Vector3d cam_from_world_translation_m = Eigen::Vector3d::Zero();  // T

  // All values finite, lengths and f positive, R a rotation, image size positive.
  Status Validate() const;
};

class TsaiCamera final : public CameraModel {
 public:
  static Result<TsaiCamera> Create(const TsaiParameters& params);

  std::string_view kind() const override { return "tsai"; }
  ImageSize image_size() const override { return p_.image_size; }
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point_in_world) const override;
  std::optional<Ray> BackProject(const Eigen::Vector2d& pixel) const override;
  std::unique_ptr<CameraModel> Resized(ImageSize new_size) const override;
  std::unique_ptr<CameraModel> Clone() const override;
  void AppendToHash(Hasher& hasher) const override;
  std::optional<Eigen::Vector3d> CenterInWorld() const override { return center_in_world_; }

  const TsaiParameters& params() const { return p_; }

  // The distorted radius R_d with R_u = R_d (1 + kappa1 R_d^2) (sensor mm), the inversion
  // Willson does by Cardan's method. nullopt beyond the maximum barrel-distortion radius
  // (kappa1 < 0 only), where no distorted radius maps to R_u.
  std::optional<double> DistortedRadius(double undistorted_radius_mm) const;

 private:
  explicit TsaiCamera(const TsaiParameters& p);
  TsaiParameters p_;
  double dpx_mm_ = 0;  // d'_x = d_x N_cx / N_fx
  double max_distorted_radius_mm_ = 0;  // +inf unless kappa1 < 0
  Eigen::Vector3d center_in_world_;
};

}  // namespace occmap
