#include "occmap/geometry/pinhole_camera.h"

#include <Eigen/LU>
#include <fmt/core.h>

#include <cmath>
#include <limits>

#include "occmap/geometry/rotation.h"

namespace occmap {
namespace {

// Smallest s = r^2 > 0 where d/dr [r (1 + k1 r^2 + k2 r^4 + k3 r^6)] = 1 + 3 k1 s + 5 k2 s^2 +
// 7 k3 s^3 reaches zero; +inf when it stays positive up to s = 1e4 (an 89.4 degree field angle).
double MaxValidR2(double k1, double k2, double k3) {
  auto slope = [&](double s) { return 1 + s * (3 * k1 + s * (5 * k2 + s * 7 * k3)); };
  double prev = 0;
  double s = 1e-4;
  while (s <= 1e4) {
    if (slope(s) <= 0) {
      double lo = prev, hi = s;
      for (int i = 0; i < 200; ++i) {
        const double mid = 0.5 * (lo + hi);
        (slope(mid) > 0 ? lo : hi) = mid;
      }
      return lo;
    }
    prev = s;
    s *= 1.01;
  }
  return std::numeric_limits<double>::infinity();
}

}  // namespace

Status PinholeParameters::Validate() const {
  if (image_size.width <= 0 || image_size.height <= 0) {
    return InvalidInput(fmt::format("image size: expected positive, found {}x{}", image_size.width,
                                    image_size.height));
  }
  for (double v : {fx_px, fy_px, cx_px, cy_px, skew_px}) {
    if (!std::isfinite(v)) return InvalidInput("camera matrix: expected finite values, found NaN or infinity");
  }
  for (double v : distortion) {
    if (!std::isfinite(v)) return InvalidInput("distortion: expected finite values, found NaN or infinity");
  }
  if (!(fx_px > 0) || !(fy_px > 0)) {
    return InvalidInput(fmt::format("camera matrix: expected positive focal lengths, found fx = {}, fy = {}",
                                    fx_px, fy_px));
  }
  if (!cam_from_world_rotation.allFinite() || !cam_from_world_translation_m.allFinite()) {
    return InvalidInput("extrinsics: expected finite values, found NaN or infinity");
  }
  OCCMAP_RETURN_IF_ERROR(ValidateRotation(cam_from_world_rotation));
  if (forward_sign != 1 && forward_sign != -1) {
    return InvalidInput(fmt::format("forward sign: expected +1 or -1, found {}", forward_sign));
  }
  return Status::Ok();
}

Result<PinholeCamera> PinholeCamera::Create(const PinholeParameters& params) {
  OCCMAP_RETURN_IF_ERROR(params.Validate());
  return PinholeCamera(params);
}

PinholeCamera::PinholeCamera(const PinholeParameters& p) : p_(p) {
  has_distortion_ = false;
  for (double v : p_.distortion) has_distortion_ |= (v != 0);
  max_valid_r2_ = has_distortion_ ? MaxValidR2(p_.distortion[0], p_.distortion[1], p_.distortion[4])
                                  : std::numeric_limits<double>::infinity();
  world_from_cam_rotation_ = p_.cam_from_world_rotation.transpose();
  center_in_world_ = -world_from_cam_rotation_ * p_.cam_from_world_translation_m;
}

PinholeCamera PinholeCamera::WithForwardSign(int sign) const {
  OCCMAP_CHECK(sign == 1 || sign == -1, "forward sign must be +1 or -1");
  PinholeParameters p = p_;
  p.forward_sign = sign;
  return PinholeCamera(p);
}

Eigen::Vector2d PinholeCamera::Distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* jacobian) const {
  const double k1 = p_.distortion[0], k2 = p_.distortion[1], p1 = p_.distortion[2],
               p2 = p_.distortion[3], k3 = p_.distortion[4];
  const double x = xy.x(), y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  if (jacobian != nullptr) {
    const double dradial_dr2 = k1 + r2 * (2 * k2 + 3 * k3 * r2);
    const double dr_dx = 2 * x * dradial_dr2;  // d radial / dx
    const double dr_dy = 2 * y * dradial_dr2;
    (*jacobian)(0, 0) = radial + x * dr_dx + 2 * p1 * y + 6 * p2 * x;
    (*jacobian)(0, 1) = x * dr_dy + 2 * p1 * x + 2 * p2 * y;
    (*jacobian)(1, 0) = y * dr_dx + 2 * p1 * x + 2 * p2 * y;
    (*jacobian)(1, 1) = radial + y * dr_dy + 6 * p1 * y + 2 * p2 * x;
  }
  return {xd, yd};
}

std::optional<Eigen::Vector2d> PinholeCamera::Project(const Eigen::Vector3d& point_in_world) const {
  const Eigen::Vector3d pc =
      p_.cam_from_world_rotation * point_in_world + p_.cam_from_world_translation_m;
  if (!(p_.forward_sign * pc.z() > 0)) return std::nullopt;
  const Eigen::Vector2d xy(pc.x() / pc.z(), pc.y() / pc.z());
  Eigen::Vector2d d = xy;
  if (has_distortion_) {
    if (xy.squaredNorm() > max_valid_r2_) return std::nullopt;
    d = Distort(xy);
  }
  return Eigen::Vector2d(p_.fx_px * d.x() + p_.skew_px * d.y() + p_.cx_px,
                         p_.fy_px * d.y() + p_.cy_px);
}

UndistortResult PinholeCamera::Undistort(const Eigen::Vector2d& pixel) const {
  UndistortResult result;
  const double yd = (pixel.y() - p_.cy_px) / p_.fy_px;
  const double xd = (pixel.x() - p_.cx_px - p_.skew_px * yd) / p_.fx_px;
  const Eigen::Vector2d target(xd, yd);
  if (!has_distortion_) {
    result.outcome = UndistortOutcome::kConverged;
    result.normalized = target;
    return result;
  }
  // Residual in pixels: the normalised error scaled by the focal lengths.
  auto residual_px = [&](const Eigen::Vector2d& e) {
    return std::hypot(e.x() * p_.fx_px, e.y() * p_.fy_px);
  };
  // Start at the distorted point itself; but when that lies beyond the valid radius (pincushion
  // distortion near the fold: the distorted radius exceeds the undistorted one) the damping
  // below would pin the iteration out there, so start halfway to the fold in that direction.
  Eigen::Vector2d xy = target;
  const double target_r2 = target.squaredNorm();
  if (target_r2 > max_valid_r2_) xy = target * (0.5 * std::sqrt(max_valid_r2_ / target_r2));
  Eigen::Matrix2d jac;
  for (int it = 0; it < kMaxUndistortIterations; ++it) {
    const Eigen::Vector2d err = Distort(xy, &jac) - target;
    result.iterations = it;
    result.residual_px = residual_px(err);
    if (result.residual_px < 1e-3 * kUndistortTolerancePx) break;
    const double det = jac.determinant();
    if (!(std::abs(det) > 1e-12)) break;
    Eigen::Vector2d step = jac.inverse() * err;
    // Damp steps that leave the valid radius so the iteration stays on the right branch.
    Eigen::Vector2d next = xy - step;
    for (int halve = 0; halve < 30 && next.squaredNorm() > max_valid_r2_; ++halve) {
      step *= 0.5;
      next = xy - step;
    }
    xy = next;
  }
  const Eigen::Vector2d final_err = Distort(xy, &jac) - target;
  result.residual_px = residual_px(final_err);
  result.normalized = xy;
  if (!(result.residual_px <= kUndistortTolerancePx)) {
    result.outcome = UndistortOutcome::kNotConverged;
  } else if (xy.squaredNorm() > max_valid_r2_ || !(jac.determinant() > 0)) {
    result.outcome = UndistortOutcome::kBeyondValidRadius;
  } else {
    result.outcome = UndistortOutcome::kConverged;
  }
  return result;
}

std::optional<Ray> PinholeCamera::BackProject(const Eigen::Vector2d& pixel) const {
  const UndistortResult u = Undistort(pixel);
  if (u.outcome != UndistortOutcome::kConverged) return std::nullopt;
  const Eigen::Vector3d dir_cam(u.normalized.x(), u.normalized.y(), 1.0);
  const Eigen::Vector3d dir_world = world_from_cam_rotation_ * (p_.forward_sign * dir_cam);
  return Ray{center_in_world_, dir_world.normalized()};
}

std::optional<Eigen::Vector2d> PinholeCamera::PixelToPlane(const Eigen::Vector2d& pixel,
                                                           double plane_z_m) const {
  // Same as the base class but without normalising the direction (hot in table building).
  const UndistortResult u = Undistort(pixel);
  if (u.outcome != UndistortOutcome::kConverged) return std::nullopt;
  const Eigen::Vector3d dir_world =
      world_from_cam_rotation_ *
      Eigen::Vector3d(p_.forward_sign * u.normalized.x(), p_.forward_sign * u.normalized.y(),
                      p_.forward_sign);
  return IntersectRayWithPlane(Ray{center_in_world_, dir_world}, plane_z_m);
}

std::unique_ptr<CameraModel> PinholeCamera::Resized(ImageSize new_size) const {
  return std::make_unique<PinholeCamera>(PinholeCamera(ResizedIntrinsics(p_, new_size)));
}

std::unique_ptr<CameraModel> PinholeCamera::Clone() const {
  return std::make_unique<PinholeCamera>(*this);
}

void PinholeCamera::AppendToHash(Hasher& h) const {
  h.Add("pinhole");
  h.AddPod(p_.image_size.width);
  h.AddPod(p_.image_size.height);
  for (double v : {p_.fx_px, p_.fy_px, p_.cx_px, p_.cy_px, p_.skew_px}) h.AddPod(v);
  for (double v : p_.distortion) h.AddPod(v);
  h.AddBytes(p_.cam_from_world_rotation.data(), sizeof(double) * 9);
  h.AddBytes(p_.cam_from_world_translation_m.data(), sizeof(double) * 3);
  h.AddPod(p_.forward_sign);
}

}  // namespace occmap
