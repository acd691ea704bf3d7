// CameraResponse: a real camera's automatic exposure and white balance (scene.h
// CameraResponseSpec), the gains that turn a frame's linear radiance into grey levels, following
// the frame's content with a time constant.
//
// Settled gains for a frame whose mean linear radiance per channel is m (0..1, over the pixels
// with a ray): g_c = e * w_c, with
//   Y   = 0.299 m_R + 0.587 m_G + 0.114 m_B                 (BT.601 luma, util/yuv.h's weights)
//   w_c = (Y / m_c)^strength * Y / sum_k k_k (Y / m_k)^strength m_k   (grey world; keeps the luma;
//                                                           1 without white balance)
//   e   = target / Y, clamped to [1 / max_gain, max_gain]   (1 without automatic exposure)
// where target is target_luma / 255, or the empty view's Y when target_luma is 0. White balance
// gains are clamped to [1/4, 4] (a black channel). Frame by frame the gains move towards the
// settled ones in the log domain, log g += a (log g* - log g), a = 1 - exp(-1 / (fps tau));
// the first frame starts settled (the camera has been looking at the scene for a while).
//
// The renderer (renderer.h) measures m, asks for the gains and applies them; with no
// CameraResponse given it uses the settled gains of each frame alone (random access).
//
//   sim::CameraResponse response = renderer.NewResponse();
//   for (int64_t f = 0; f < n; ++f) renderer.Render(scene.StateAt(f), ctx, &view, true, false, &response);
#pragma once

#include <Eigen/Core>

#include "occmap/sim/scene.h"

namespace occmap::sim {

class CameraResponse {
 public:
  // empty_mean: the empty view's mean linear radiance per channel (the target when target_luma
  // is 0); fps: the frame rate the time constant is counted in.
  CameraResponse(const CameraResponseSpec& spec, double fps, const Eigen::Vector3d& empty_mean);

  // The gains the camera settles on for a frame of this mean radiance.
  Eigen::Vector3d SettledGains(const Eigen::Vector3d& mean) const;
  // The next frame's gains: a step of the filter towards SettledGains(mean).
  Eigen::Vector3d Update(const Eigen::Vector3d& mean);
  const Eigen::Vector3d& gains() const { return gains_; }
  int64_t frames() const { return frames_; }

 private:
  CameraResponseSpec spec_;
  double target_luma_ = 0;  // linear, 0..1
  double step_ = 1;         // a, the filter's step per frame
  Eigen::Vector3d gains_ = Eigen::Vector3d::Ones();
  int64_t frames_ = 0;
};

// Luma of a linear RGB mean with BT.601's weights.
double LumaOf(const Eigen::Vector3d& rgb);

}  // namespace occmap::sim
