#include "occmap/track/kalman.h"

#include <gtest/gtest.h>

#include <random>

namespace occmap {
namespace {

TEST(ConstantVelocityKalman, PredictAndUpdateMatchAStepComputedByHand) {
  // x = (0, 0, 1, 0), P = I, dt = 1, no process noise.
  ConstantVelocityKalman kf(ConstantVelocityKalman::State(0, 0, 1, 0), Eigen::Matrix4d::Identity());
  kf.Predict(1.0, 0.0);
  // x' = F x = (1, 0, 1, 0); P' = F F' = [2 0 1 0; 0 2 0 1; 1 0 1 0; 0 1 0 1].
  EXPECT_TRUE(kf.state().isApprox(Eigen::Vector4d(1, 0, 1, 0)));
  Eigen::Matrix4d predicted;
  predicted << 2, 0, 1, 0, 0, 2, 0, 1, 1, 0, 1, 0, 0, 1, 0, 1;
  EXPECT_TRUE(kf.covariance().isApprox(predicted));

  // z = (2, 0), R = I: S_x = 3, gain (2/3, 1/3) on x, vx; residual 1.
  const Eigen::Vector2d z(2, 0);
  const auto innovation = kf.Innovate(z, Eigen::Matrix2d::Identity());
  EXPECT_NEAR(innovation.mahalanobis2, 1.0 / 3.0, 1e-12);
  kf.Update(z, Eigen::Matrix2d::Identity());
  EXPECT_NEAR(kf.state()(0), 5.0 / 3.0, 1e-12);
  EXPECT_NEAR(kf.state()(1), 0.0, 1e-12);
  EXPECT_NEAR(kf.state()(2), 4.0 / 3.0, 1e-12);
  EXPECT_NEAR(kf.state()(3), 0.0, 1e-12);
  EXPECT_NEAR(kf.covariance()(0, 0), 2.0 / 3.0, 1e-12);  // 2 - (2/3) 2
  EXPECT_NEAR(kf.covariance()(0, 2), 1.0 / 3.0, 1e-12);  // 1 - (2/3) 1
  EXPECT_NEAR(kf.covariance()(2, 2), 2.0 / 3.0, 1e-12);  // 1 - (1/3) 1
  EXPECT_NEAR(kf.covariance()(1, 1), 2.0 / 3.0, 1e-12);  // y: the same with zero residual
  EXPECT_NEAR(kf.covariance()(0, 1), 0.0, 1e-12);
}

TEST(ConstantVelocityKalman, ProcessNoiseIsTheIntegralOfWhiteAcceleration) {
  // q = 0.5, dt = 2: q dt^3 / 3 = 4/3, q dt^2 / 2 = 1, q dt = 1, per axis, axes independent.
  const Eigen::Matrix4d q = ConstantVelocityKalman::ProcessNoise(2.0, 0.5);
  Eigen::Matrix4d expected;
  expected << 4.0 / 3, 0, 1, 0, 0, 4.0 / 3, 0, 1, 1, 0, 1, 0, 0, 1, 0, 1;
  EXPECT_TRUE(q.isApprox(expected)) << q;
  ConstantVelocityKalman kf(ConstantVelocityKalman::State(0, 0, 0, 0), Eigen::Matrix4d::Zero());
  kf.Predict(2.0, 0.5);
  EXPECT_TRUE(kf.covariance().isApprox(expected));
}

TEST(ConstantVelocityKalman, NoisyPositionsOfAWalkerGiveItsVelocity) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.03);
  ConstantVelocityKalman kf({1.0, 1.0}, 0.03 * 0.03 * Eigen::Matrix2d::Identity(), 1.0);
  const Eigen::Matrix2d r = 0.03 * 0.03 * Eigen::Matrix2d::Identity();
  for (int frame = 1; frame <= 50; ++frame) {
    kf.Predict(0.1, 0.05);
    const double t = 0.1 * frame;
    kf.Update(Eigen::Vector2d(1.0 + 1.2 * t + noise(rng), 1.0 - 0.5 * t + noise(rng)), r);
  }
  EXPECT_NEAR(kf.velocity_mps().x(), 1.2, 0.1);
  EXPECT_NEAR(kf.velocity_mps().y(), -0.5, 0.1);
  EXPECT_NEAR(kf.position_m().x(), 7.0, 0.05);
  EXPECT_NEAR(kf.position_m().y(), -1.5, 0.05);
  EXPECT_TRUE(kf.covariance().isApprox(kf.covariance().transpose()));
}

}  // namespace
}  // namespace occmap
