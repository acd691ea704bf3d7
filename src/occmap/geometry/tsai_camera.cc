#include "occmap/geometry/tsai_camera.h"

#include <Eigen/LU>
#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "occmap/geometry/rotation.h"

namespace occmap {
namespace {

bool AllFinite(const TsaiParameters& p) {
  for (double v : {p.Ncx, p.Nfx, p.dx_mm, p.dy_mm, p.sx, p.Cx_px, p.Cy_px, p.f_mm,
                   p.kappa1_per_mm2}) {
    if (!std::isfinite(v)) return false;
  }
  return p.cam_from_world_rotation.allFinite() && p.cam_from_world_translation_m.allFinite();
}

}  // namespace

Status TsaiParameters::Validate() const {
  if (!AllFinite(*this)) return InvalidInput("expected finite Tsai parameters, found NaN or infinity");
  if (image_size.width <= 0 || image_size.height <= 0) {
    return InvalidInput(fmt::format("image size: expected positive, found {}x{}", image_size.width,
                                    image_size.height));
  }
  auto positive = [](const char* name, double v) -> Status {
    if (v > 0) return Status::Ok();
    return InvalidInput(fmt::format("{}: expected a positive value, found {}", name, v));
  };
  OCCMAP_RETURN_IF_ERROR(positive("f", f_mm));
  OCCMAP_RETURN_IF_ERROR(positive("dx", dx_mm));
  OCCMAP_RETURN_IF_ERROR(positive("dy", dy_mm));
  OCCMAP_RETURN_IF_ERROR(positive("Ncx", Ncx));
  OCCMAP_RETURN_IF_ERROR(positive("Nfx", Nfx));
  OCCMAP_RETURN_IF_ERROR(positive("sx", sx));
  OCCMAP_RETURN_IF_ERROR(ValidateRotation(cam_from_world_rotation));
  return Status::Ok();
}

Result<TsaiCamera> TsaiCamera::Create(const TsaiParameters& params) {
  OCCMAP_RETURN_IF_ERROR(params.Validate());
  return TsaiCamera(params);
}

TsaiCamera::TsaiCamera(const TsaiParameters& p) : p_(p) {
  dpx_mm_ = p_.dx_mm * p_.Ncx / p_.Nfx;
  max_distorted_radius_mm_ = p_.kappa1_per_mm2 < 0 ? std::sqrt(-1.0 / (3.0 * p_.kappa1_per_mm2))
                                                   : std::numeric_limits<double>::infinity();
  center_in_world_ = -p_.cam_from_world_rotation.transpose() * p_.cam_from_world_translation_m;
}

std::optional<double> TsaiCamera::DistortedRadius(double ru) const {
  const double k = p_.kappa1_per_mm2;
  if (ru <= 0) return 0.0;
  if (k == 0) return ru;
  double rd;
  if (k > 0) {
    // k Rd^3 + Rd - Ru = 0 has exactly one real root: Cardan, p = 1/k, q = -Ru/k.
    const double q_half = -ru / (2 * k);
    const double p_third = 1.0 / (3 * k);
    const double disc = std::sqrt(q_half * q_half + p_third * p_third * p_third);
    rd = std::cbrt(-q_half + disc) + std::cbrt(-q_half - disc);
  } else {
    // Barrel distortion: Rd + k Rd^3 rises from 0 to its maximum (2/3) Rd_max at Rd_max; take
    // the smaller positive root (Willson's choice) or report that there is none.
    const double rd_max = max_distorted_radius_mm_;
    const double ru_max = rd_max * (1 + k * rd_max * rd_max);
    if (ru > ru_max) return std::nullopt;
    // g(Rd) = Rd + k Rd^3 - Ru is increasing on [0, Rd_max]: safeguarded Newton (bisection
    // whenever a Newton step leaves the bracket) converges to the root there.
    // The bracket is closed: once Newton has converged, its step no longer moves rd (it stays on
    // the bracket's end), which must end the iteration rather than trigger a bisection away
    // from the root. The stopping test is relative to rd so that small radii keep full relative
    // precision.
    rd = std::min(ru, rd_max);
    double lo = 0, hi = rd_max;
    for (int i = 0; i < 200; ++i) {
      const double g = rd + k * rd * rd * rd - ru;
      if (g == 0) break;
      const double dg = 1 + 3 * k * rd * rd;
      if (g > 0) hi = rd; else lo = rd;
      if (hi - lo <= 2.3e-16 * hi) break;  // the root is bracketed to one ulp
      double next = dg > 0 ? rd - g / dg : 0.5 * (lo + hi);
      if (!(next >= lo && next <= hi)) next = 0.5 * (lo + hi);
      const bool converged = std::abs(next - rd) <= 1e-16 * rd;
      rd = next;
      if (converged) break;
    }
    return rd;
  }
  // One Newton step polishes the closed form to the last bit.
  const double g = rd + k * rd * rd * rd - ru;
  const double dg = 1 + 3 * k * rd * rd;
  if (dg > 0) rd -= g / dg;
  return rd;
}

std::optional<Eigen::Vector2d> TsaiCamera::Project(const Eigen::Vector3d& point_in_world) const {
  // (6)
  const Eigen::Vector3d pc =
      p_.cam_from_world_rotation * point_in_world + p_.cam_from_world_translation_m;
  if (!(pc.z() > 0)) return std::nullopt;
  // (7, 8)
  const double xu = p_.f_mm * pc.x() / pc.z();
  const double yu = p_.f_mm * pc.y() / pc.z();
  // (9, 10), inverted for the distorted radius.
  const double ru = std::hypot(xu, yu);
  const std::optional<double> rd = DistortedRadius(ru);
  if (!rd) return std::nullopt;
  const double scale = ru > 0 ? *rd / ru : 1.0;
  const double xd = xu * scale;
  const double yd = yu * scale;
  // (11, 12)
  return Eigen::Vector2d(p_.sx * xd / dpx_mm_ + p_.Cx_px, yd / p_.dy_mm + p_.Cy_px);
}

std::optional<Ray> TsaiCamera::BackProject(const Eigen::Vector2d& pixel) const {
  // (14, 15)
  const double xd = (pixel.x() - p_.Cx_px) * dpx_mm_ / p_.sx;
  const double yd = (pixel.y() - p_.Cy_px) * p_.dy_mm;
  const double r2 = xd * xd + yd * yd;
  if (r2 > max_distorted_radius_mm_ * max_distorted_radius_mm_) return std::nullopt;
  // (16, 17)
  const double factor = 1 + p_.kappa1_per_mm2 * r2;
  // (18, 19): the ray (0,0,0) + (U_u, V_u, f) d in camera coordinates, taken to the world.
  const Eigen::Vector3d dir_cam(xd * factor, yd * factor, p_.f_mm);
  const Eigen::Vector3d dir_world = p_.cam_from_world_rotation.transpose() * dir_cam;
  return Ray{center_in_world_, dir_world.normalized()};
}

std::unique_ptr<CameraModel> TsaiCamera::Resized(ImageSize new_size) const {
  const PixelRescale s = PixelRescale::Between(p_.image_size, new_size);
  TsaiParameters p = p_;
  p.image_size = new_size;
  p.dx_mm /= s.scale_x;  // bigger pixels: fewer of them per sensor millimetre
  p.dy_mm /= s.scale_y;
  p.Cx_px = s.MapU(p_.Cx_px);
  p.Cy_px = s.MapV(p_.Cy_px);
  return std::make_unique<TsaiCamera>(TsaiCamera(p));
}

std::unique_ptr<CameraModel> TsaiCamera::Clone() const { return std::make_unique<TsaiCamera>(*this); }

void TsaiCamera::AppendToHash(Hasher& h) const {
  h.Add("tsai");
  h.AddPod(p_.image_size.width);
  h.AddPod(p_.image_size.height);
  for (double v : {p_.Ncx, p_.Nfx, p_.dx_mm, p_.dy_mm, p_.sx, p_.Cx_px, p_.Cy_px, p_.f_mm,
                   p_.kappa1_per_mm2}) {
    h.AddPod(v);
  }
  h.AddBytes(p_.cam_from_world_rotation.data(), sizeof(double) * 9);
  h.AddBytes(p_.cam_from_world_translation_m.data(), sizeof(double) * 3);
}

}  // namespace occmap
