// ConstantVelocityKalman: a Kalman filter over the state (x, y, vx, vy) in metres and metres
// per second, with a white-noise acceleration of spectral density q (m^2/s^3) and position
// measurements. Over a step dt, per axis (x or y with its velocity):
//   F = [1 dt; 0 1],   Q = q [dt^3/3  dt^2/2; dt^2/2  dt]
// The update uses the Joseph form, so the covariance stays symmetric positive definite.
//
//   ConstantVelocityKalman kf({1.0, 2.0}, 0.01 * Eigen::Matrix2d::Identity(), /*speed_sigma_mps=*/1.0);
//   kf.Predict(/*dt_s=*/0.1, /*acceleration_psd_m2ps3=*/1.0);
//   if (kf.Innovate(z, R).mahalanobis2 < 13.8) kf.Update(z, R);
#pragma once

#include <Eigen/Core>

namespace occmap {

class ConstantVelocityKalman {
 public:
  using State = Eigen::Vector4d;       // x_m, y_m, vx_mps, vy_mps
  using Covariance = Eigen::Matrix4d;  // in the same order

  ConstantVelocityKalman() = default;
  // At rest at `position_m`, position covariance as given, velocity sigma per axis.
  ConstantVelocityKalman(const Eigen::Vector2d& position_m, const Eigen::Matrix2d& position_covariance_m2,
                         double speed_sigma_mps);
  ConstantVelocityKalman(const State& state, const Covariance& covariance) : x_(state), p_(covariance) {}

  static Eigen::Matrix4d Transition(double dt_s);
  static Covariance ProcessNoise(double dt_s, double acceleration_psd_m2ps3);

  void Predict(double dt_s, double acceleration_psd_m2ps3);

  struct Innovation {
    Eigen::Vector2d residual_m;      // z - H x
    Eigen::Matrix2d covariance_m2;   // S = H P H' + R
    double mahalanobis2 = 0;         // residual' S^-1 residual
  };
  Innovation Innovate(const Eigen::Vector2d& measurement_m, const Eigen::Matrix2d& measurement_covariance_m2) const;
  void Update(const Eigen::Vector2d& measurement_m, const Eigen::Matrix2d& measurement_covariance_m2);

  const State& state() const { return x_; }
  const Covariance& covariance() const { return p_; }
  Eigen::Vector2d position_m() const { return x_.head<2>(); }
  Eigen::Vector2d velocity_mps() const { return x_.tail<2>(); }

 private:
  State x_ = State::Zero();
  Covariance p_ = Covariance::Identity();
};

}  // namespace occmap
