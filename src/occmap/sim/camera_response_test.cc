#include "occmap/sim/camera_response.h"

#include <gtest/gtest.h>

#include <cmath>

namespace occmap::sim {
namespace {

CameraResponseSpec AutoExposure() {
  CameraResponseSpec spec;
  spec.auto_exposure = true;
  return spec;
}

TEST(CameraResponse, EmptyViewKeepsGainOneAndADarkerFrameRaisesIt) {
  const Eigen::Vector3d empty(0.5, 0.45, 0.4);
  CameraResponse response(AutoExposure(), 10, empty);
  const Eigen::Vector3d settled = response.SettledGains(empty);
  EXPECT_EQ(settled, Eigen::Vector3d::Ones());  // exactly: the target is the empty view's own luma
  // Dark people fill a third of the view: the luma falls to 2/3, the gain rises by 3/2.
  const Eigen::Vector3d crowded = empty * (2.0 / 3.0);
  const Eigen::Vector3d gains = response.SettledGains(crowded);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(gains[c], 1.5, 1e-9);
  // A brighter frame lowers it.
  EXPECT_LT(response.SettledGains(empty * 1.2)[1], 1.0);
}

TEST(CameraResponse, AbsoluteTargetSetsTheMeanLuma) {
  CameraResponseSpec spec = AutoExposure();
  spec.target_luma = 100;
  const CameraResponse response(spec, 10, Eigen::Vector3d::Constant(0.5));
  const Eigen::Vector3d mean(0.2, 0.3, 0.25);
  const Eigen::Vector3d gains = response.SettledGains(mean);
  EXPECT_NEAR(LumaOf(gains.cwiseProduct(mean)) * 255, 100, 1e-9);
}

TEST(CameraResponse, WhiteBalanceGainsDifferPerChannelUnderAColouredScene) {
  CameraResponseSpec spec;
  spec.white_balance = 1;
  const CameraResponse full(spec, 10, Eigen::Vector3d::Constant(0.5));
  // Warm light: red high, blue low.
  const Eigen::Vector3d warm(0.6, 0.5, 0.3);
  const Eigen::Vector3d g = full.SettledGains(warm);
  EXPECT_LT(g[0], g[1]);
  EXPECT_LT(g[1], g[2]);
  // Full grey world: the balanced means are equal, and the luma is kept.
  const Eigen::Vector3d balanced = g.cwiseProduct(warm);
  EXPECT_NEAR(balanced[0], balanced[1], 1e-12);
  EXPECT_NEAR(balanced[1], balanced[2], 1e-12);
  EXPECT_NEAR(LumaOf(balanced), LumaOf(warm), 1e-12);
  // Half strength corrects half as much (in log terms, before the luma's normalisation).
  spec.white_balance = 0.5;
  const Eigen::Vector3d h = CameraResponse(spec, 10, Eigen::Vector3d::Constant(0.5)).SettledGains(warm);
  EXPECT_NEAR(std::log(h[2] / h[0]), 0.5 * std::log(g[2] / g[0]), 1e-12);
  // A grey scene needs no balance.
  const Eigen::Vector3d grey = full.SettledGains(Eigen::Vector3d::Constant(0.4));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(grey[c], 1.0, 1e-12);
}

TEST(CameraResponse, GainsFollowTheContentWithTheTimeConstant) {
  CameraResponseSpec spec = AutoExposure();
  spec.time_constant_s = 0.4;
  const Eigen::Vector3d empty = Eigen::Vector3d::Constant(0.5);
  CameraResponse response(spec, 10, empty);
  // The first frame starts settled, on whatever it sees.
  EXPECT_NEAR(response.Update(empty * 0.5)[0], 2.0, 1e-12);
  // Back to the empty view: after tau (4 frames at 10 fps) the log gain has gone 1 - 1/e of
  // the way from log 2 to log 1.
  for (int f = 0; f < 4; ++f) response.Update(empty);
  EXPECT_NEAR(std::log(response.gains()[0]), std::log(2.0) * std::exp(-1.0), 1e-9);
  for (int f = 0; f < 60; ++f) response.Update(empty);
  EXPECT_NEAR(response.gains()[0], 1.0, 1e-6);
  EXPECT_EQ(response.frames(), 65);
  // No time constant: every frame settled.
  spec.time_constant_s = 0;
  CameraResponse instant(spec, 10, empty);
  instant.Update(empty);
  EXPECT_NEAR(instant.Update(empty * 0.8)[1], 1.25, 1e-12);
}

TEST(CameraResponse, GainsStayWithinTheirLimits) {
  CameraResponseSpec spec = AutoExposure();
  spec.max_gain = 3;
  spec.white_balance = 1;
  const CameraResponse response(spec, 10, Eigen::Vector3d::Constant(0.5));
  const Eigen::Vector3d black = response.SettledGains(Eigen::Vector3d::Zero());
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(black[c], 3.0, 1e-9);
  const Eigen::Vector3d bright = response.SettledGains(Eigen::Vector3d::Constant(50));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(bright[c], 1.0 / 3, 1e-9);
  // A channel without light: its balance gain stops at 4.
  const Eigen::Vector3d no_blue = response.SettledGains(Eigen::Vector3d(0.5, 0.5, 0.0));
  EXPECT_TRUE(no_blue.allFinite());
  EXPECT_LE(no_blue[2] / no_blue[1], 4.0 * 4.0 + 1e-9);
}

}  // namespace
}  // namespace occmap::sim
