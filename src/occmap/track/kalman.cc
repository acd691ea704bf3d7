#include "occmap/track/kalman.h"

#include <Eigen/LU>

namespace occmap {

ConstantVelocityKalman::ConstantVelocityKalman(const Eigen::Vector2d& position_m,
                                               const Eigen::Matrix2d& position_covariance_m2,
                                               double speed_sigma_mps) {
  x_ << position_m, 0.0, 0.0;
  p_.setZero();
  p_.topLeftCorner<2, 2>() = position_covariance_m2;
  p_.bottomRightCorner<2, 2>() = speed_sigma_mps * speed_sigma_mps * Eigen::Matrix2d::Identity();
}

Eigen::Matrix4d ConstantVelocityKalman::Transition(double dt_s) {
  Eigen::Matrix4d f = Eigen::Matrix4d::Identity();
  f(0, 2) = dt_s;
  f(1, 3) = dt_s;
  return f;
}

ConstantVelocityKalman::Covariance ConstantVelocityKalman::ProcessNoise(double dt_s, double acceleration_psd_m2ps3) {
  const double q = acceleration_psd_m2ps3;
  const double pp = q * dt_s * dt_s * dt_s / 3.0, pv = q * dt_s * dt_s / 2.0, vv = q * dt_s;
  Covariance noise = Covariance::Zero();
  for (int axis = 0; axis < 2; ++axis) {
    noise(axis, axis) = pp;
    noise(axis, axis + 2) = pv;
    noise(axis + 2, axis) = pv;
    noise(axis + 2, axis + 2) = vv;
  }
  return noise;
}

void ConstantVelocityKalman::Predict(double dt_s, double acceleration_psd_m2ps3) {
  const Eigen::Matrix4d f = Transition(dt_s);
  x_ = f * x_;
  p_ = f * p_ * f.transpose() + ProcessNoise(dt_s, acceleration_psd_m2ps3);
}

ConstantVelocityKalman::Innovation ConstantVelocityKalman::Innovate(const Eigen::Vector2d& measurement_m,
                                                                    const Eigen::Matrix2d& measurement_covariance_m2) const {
  Innovation innovation;
  innovation.residual_m = measurement_m - x_.head<2>();
  innovation.covariance_m2 = p_.topLeftCorner<2, 2>() + measurement_covariance_m2;
  innovation.mahalanobis2 = innovation.residual_m.dot(innovation.covariance_m2.inverse() * innovation.residual_m);
  return innovation;
}

void ConstantVelocityKalman::Update(const Eigen::Vector2d& measurement_m,
                                    const Eigen::Matrix2d& measurement_covariance_m2) {
  const Innovation innovation = Innovate(measurement_m, measurement_covariance_m2);
  // H = [I 0]: P H' is the left 4x2 block of P.
  const Eigen::Matrix<double, 4, 2> gain = p_.leftCols<2>() * innovation.covariance_m2.inverse();
  x_ += gain * innovation.residual_m;
  Eigen::Matrix4d i_kh = Eigen::Matrix4d::Identity();
  i_kh.leftCols<2>() -= gain;
  p_ = i_kh * p_ * i_kh.transpose() + gain * measurement_covariance_m2 * gain.transpose();
  p_ = 0.5 * (p_ + p_.transpose());
}

}  // namespace occmap
