#include "occmap/geometry/rotation.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <fmt/core.h>
#include <cmath>

namespace occmap {

Eigen::Matrix3d RotationFromRodrigues(const Eigen::Vector3d& rvec) {
  const double angle = rvec.norm();
  if (angle < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, rvec / angle).toRotationMatrix();
}

Eigen::Matrix3d TsaiRotation(double rx, double ry, double rz) {
  const double sa = std::sin(rx), ca = std::cos(rx);
  const double sb = std::sin(ry), cb = std::cos(ry);
  const double sg = std::sin(rz), cg = std::cos(rz);
  Eigen::Matrix3d r;
  r << cb * cg, cg * sa * sb - ca * sg, sa * sg + ca * cg * sb,  //
      cb * sg, sa * sb * sg + ca * cg, ca * sb * sg - cg * sa,   //
      -sb, cb * sa, ca * cb;
  return r;
}

double OrthonormalityError(const Eigen::Matrix3d& r) {
  return (r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
}

Eigen::Matrix3d LookAtRotation(const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m) {
  const Eigen::Vector3d z = (target_m - position_m).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ());
  if (x.norm() < 1e-9) x = Eigen::Vector3d::UnitX();  // looking straight down: image x along world x
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r.row(0) = x.transpose();
  r.row(1) = y.transpose();
  r.row(2) = z.transpose();
  return r;
}

Status ValidateRotation(const Eigen::Matrix3d& r) {
  const double err = OrthonormalityError(r);
  const double det = r.determinant();
  if (err > 1e-6 || !(det > 0)) {
    return InvalidInput(fmt::format(
        "rotation: expected an orthonormal matrix with determinant +1, found |R R^T - I| = {:.3g}, det = {:.6g}", err,
        det));
  }
  return Status::Ok();
}

}  // namespace occmap
