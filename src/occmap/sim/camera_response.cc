#include "occmap/sim/camera_response.h"

#include <algorithm>
#include <cmath>

namespace occmap::sim {
namespace {

constexpr double kLumaWeights[3] = {0.299, 0.587, 0.114};
constexpr double kMaxWhiteBalanceGain = 4.0;
// A frame darker than this (linear) has no meaningful mean: the gains stay at their limit.
constexpr double kDarkestMean = 1e-6;

}  // namespace

double LumaOf(const Eigen::Vector3d& rgb) {
  return kLumaWeights[0] * rgb[0] + kLumaWeights[1] * rgb[1] + kLumaWeights[2] * rgb[2];
}

CameraResponse::CameraResponse(const CameraResponseSpec& spec, double fps, const Eigen::Vector3d& empty_mean)
    : spec_(spec) {
  target_luma_ = spec.target_luma > 0 ? spec.target_luma / 255.0 : LumaOf(empty_mean);
  step_ = spec.time_constant_s > 0 && fps > 0 ? 1.0 - std::exp(-1.0 / (fps * spec.time_constant_s)) : 1.0;
}

Eigen::Vector3d CameraResponse::SettledGains(const Eigen::Vector3d& mean) const {
  const Eigen::Vector3d m = mean.cwiseMax(kDarkestMean);
  const double y = LumaOf(m);
  Eigen::Vector3d white = Eigen::Vector3d::Ones();
  if (spec_.white_balance > 0) {
    for (int c = 0; c < 3; ++c) {
      white[c] = std::clamp(std::pow(y / m[c], spec_.white_balance), 1.0 / kMaxWhiteBalanceGain, kMaxWhiteBalanceGain);
    }
    white *= y / LumaOf(white.cwiseProduct(m));  // the balance moves colour, not brightness
  }
  double exposure = 1.0;
  if (spec_.auto_exposure && target_luma_ > 0) {
    exposure = std::clamp(target_luma_ / y, 1.0 / spec_.max_gain, spec_.max_gain);
  }
  return exposure * white;
}

Eigen::Vector3d CameraResponse::Update(const Eigen::Vector3d& mean) {
  const Eigen::Vector3d settled = SettledGains(mean);
  if (frames_ == 0) {
    gains_ = settled;
  } else {
    for (int c = 0; c < 3; ++c) gains_[c] = std::exp(std::log(gains_[c]) + step_ * (std::log(settled[c]) - std::log(gains_[c])));
  }
  ++frames_;
  return gains_;
}

}  // namespace occmap::sim
