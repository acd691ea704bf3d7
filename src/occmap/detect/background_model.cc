#include "occmap/detect/background_model.h"

#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/background_segm.hpp>

#include "occmap/detect/adaptive_change_kernels.h"
#include "occmap/util/simd.h"

namespace occmap {
namespace {

constexpr int kBinLevels = 8;  // background levels per bin of the transfer fit
constexpr int kBins = 256 / kBinLevels;
constexpr double kFitOutlierLevels = 12;
constexpr int kModeWindow = 9;
constexpr double kMinWhiteBalanceShift = 3;  // chroma levels on grey floor
constexpr double kMinFitShare = 0.5;  // of the grid's samples left by the map's protection

uint8_t Clamp8(double v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); }
int ClampInt(double v, int lo, int hi) { return static_cast<int>(std::clamp(std::lround(v), static_cast<long>(lo), static_cast<long>(hi))); }

constexpr double kLookDecay = 0.95;      // per frame
constexpr double kLookMinMass = 2000;    // pixels before a look is trusted
constexpr double kLookMinPeakShare = 0.15; // of them within the mode's three bins
constexpr double kLookJumpFactor = 2;      // a new mode this many times the look's own moves it
constexpr int64_t kWarmUpLookLessons = 3;  // lessons without shadows that drop the warm-up's look,
constexpr double kWarmUpLookMinMass = kLookMinMass / 4;  // when they taught fewer pixels than this

// 8.8 fixed point to 8 bits, rounded, saturated.
[[gnu::always_inline]] inline void RoundRowBody(const uint16_t* src, int width, uint8_t* dst) {
  for (int x = 0; x < width; ++x) {
    const int v = (src[x] + 128) >> 8;
    dst[x] = static_cast<uint8_t>(v > 255 ? 255 : v);
  }
}

#if OCCMAP_X86_KERNELS
__attribute__((target("avx2"))) void RoundRowAvx2(const uint16_t* src, int width, uint8_t* dst) {
  RoundRowBody(src, width, dst);
}
#endif

void RoundRow(const uint16_t* src, int width, uint8_t* dst) {
#if OCCMAP_X86_KERNELS
  if (ActiveKernels() >= KernelSet::kAvx2) return RoundRowAvx2(src, width, dst);
#endif
  RoundRowBody(src, width, dst);
}

// The frame/background ratios of R, G and B (from full-range Y'CbCr) less their mean, and that
// mean. Background channels under 8 levels count as 8 (their ratio is noise).
float ChannelPattern(int y, int u, int v, int ey, int eu, int ev, float q[3]) {
  const float cb = static_cast<float>(u - 128), cr = static_cast<float>(v - 128);
  const float ecb = static_cast<float>(eu - 128), ecr = static_cast<float>(ev - 128);
  const float fy = static_cast<float>(y), by = static_cast<float>(ey);
  const float f[3] = {fy + 1.402f * cr, fy - 0.344136f * cb - 0.714136f * cr, fy + 1.772f * cb};
  const float b[3] = {by + 1.402f * ecr, by - 0.344136f * ecb - 0.714136f * ecr, by + 1.772f * ecb};
  float mean = 0;
  for (int c = 0; c < 3; ++c) {
    q[c] = std::max(0.0f, f[c]) / std::max(8.0f, b[c]);
    mean += q[c] / 3;
  }
  for (int c = 0; c < 3; ++c) q[c] -= mean;
  return mean;
}

// Weighted least squares of y = a x + b; false when the xs do not spread.
bool FitLine(const std::vector<std::array<double, 3>>& points, double* a, double* b) {
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const auto& [x, y, w] : points) {
    sw += w;
    sx += w * x;
    sy += w * y;
    sxx += w * x * x;
    sxy += w * x * y;
  }
  const double det = sw * sxx - sx * sx;
  if (sw <= 0 || det <= 1e-9 * sw * sw) return false;
  *a = (sw * sxy - sx * sy) / det;
  *b = (sy - *a * sx) / sw;
  return true;
}

// The lower median of n values (copied).
uint8_t MedianOf(uint8_t* values, size_t n) {
  const size_t rank = (n - 1) / 2;
  std::nth_element(values, values + rank, values + n);
  return values[rank];
}

}  // namespace

YuvImage YuvFromRgb(ImageView<const Rgb8> rgb) {
  YuvImage out;
  LumaFromRgb(rgb, out.y);
  ChromaFromRgb(rgb, out.u, out.v);
  return out;
}

Image<Rgb8> RgbFromYuv(const YuvView& yuv) {
  Image<Rgb8> out(yuv.y.width(), yuv.y.height());
  for (int y = 0; y < out.height(); ++y) {
    for (int x = 0; x < out.width(); ++x) {
      const double l = yuv.y(x, y);
      const double cb = yuv.has_chroma() ? yuv.u(x / 2, y / 2) - 128.0 : 0.0;
      const double cr = yuv.has_chroma() ? yuv.v(x / 2, y / 2) - 128.0 : 0.0;
      out(x, y) = {Clamp8(l + 1.402 * cr), Clamp8(l - 0.344136 * cb - 0.714136 * cr), Clamp8(l + 1.772 * cb)};
    }
  }
  return out;
}

const char* ToString(BackgroundLearning method) {
  switch (method) {
    case BackgroundLearning::kMedian: return "median";
    case BackgroundLearning::kMode: return "mode";
    case BackgroundLearning::kMog2: return "mog2";
    case BackgroundLearning::kKnn: return "knn";
  }
  return "?";
}

Result<BackgroundLearning> ParseBackgroundLearning(std::string_view name) {
  for (BackgroundLearning m : {BackgroundLearning::kMedian, BackgroundLearning::kMode, BackgroundLearning::kMog2,
                               BackgroundLearning::kKnn}) {
    if (name == ToString(m)) return m;
  }
  return InvalidInput(fmt::format("expected median, mode, mog2 or knn, found '{}'", name));
}

Status ShadowOptions::Validate() const {
  if (!(min_ratio > 0 && min_ratio < max_ratio && max_ratio < 1)) {
    return InvalidInput(fmt::format("backgrounds.shadows: expected 0 < min_ratio < max_ratio < 1, found min_ratio {} and max_ratio {}",
                                    min_ratio, max_ratio));
  }
  if (!(ratio_window > 0 && ratio_window <= 1)) {
    return InvalidInput(fmt::format("backgrounds.shadows.ratio_window: expected 0 < w <= 1, found {}", ratio_window));
  }
  if (!(max_channel_spread >= 0 && max_channel_spread <= 1)) {
    return InvalidInput(fmt::format("backgrounds.shadows.max_channel_spread: expected 0..1, found {}", max_channel_spread));
  }
  if (texture_radius_px < 0 || texture_radius_px > 8) {
    return InvalidInput(fmt::format("backgrounds.shadows.texture_radius_px: expected 0..8, found {}", texture_radius_px));
  }
  if (!(min_texture_correlation >= -1 && min_texture_correlation <= 1)) {
    return InvalidInput(fmt::format("backgrounds.shadows.min_texture_correlation: expected -1..1, found {}",
                                    min_texture_correlation));
  }
  if (!(flat_std >= 0)) return InvalidInput(fmt::format("backgrounds.shadows.flat_std: expected >= 0, found {}", flat_std));
  if (!(soft_min_ratio > 0 && soft_min_ratio < soft_max_ratio && soft_max_ratio < 1)) {
    return InvalidInput(fmt::format(
        "backgrounds.shadows: expected 0 < soft_min_ratio < soft_max_ratio < 1, found soft_min_ratio {} and soft_max_ratio {}",
        soft_min_ratio, soft_max_ratio));
  }
  return Status::Ok();
}

Status BackgroundOptions::Validate() const {
  if (!(learn_s > 0)) return InvalidInput(fmt::format("backgrounds.learn_s: expected > 0, found {}", learn_s));
  if (learn_samples < 1 || learn_samples > 255) {
    return InvalidInput(fmt::format("backgrounds.learn_samples: expected 1..255, found {}", learn_samples));
  }
  if (mode_radius < 1 || mode_radius > 64) {
    return InvalidInput(fmt::format("backgrounds.mode_radius: expected 1..64 grey levels, found {}", mode_radius));
  }
  if (!(alternative_min_share >= 0 && alternative_min_share <= 1)) {
    return InvalidInput(fmt::format("backgrounds.alternative_min_share: expected 0..1, found {}", alternative_min_share));
  }
  if (!(refresh_cache_s >= 0)) {
    return InvalidInput(fmt::format("backgrounds.refresh_cache_s: expected >= 0 (0: never), found {}", refresh_cache_s));
  }
  if (!(adapt_s > 0)) return InvalidInput(fmt::format("backgrounds.adapt_s: expected > 0, found {}", adapt_s));
  if (!(relight_s > 0)) return InvalidInput(fmt::format("backgrounds.relight_s: expected > 0, found {}", relight_s));
  if (!(absorb_s > 0)) return InvalidInput(fmt::format("backgrounds.absorb_s: expected > 0, found {}", absorb_s));
  if (!(person_height_m > 0 && person_height_m < 3)) {
    return InvalidInput(fmt::format("backgrounds.person_height_m: expected 0 < h < 3 m, found {}", person_height_m));
  }
  if (chroma_threshold < 0 || chroma_threshold > 255) {
    return InvalidInput(fmt::format("backgrounds.chroma_threshold: expected 0..255, found {}", chroma_threshold));
  }
  if (grow_steps_px < 0 || grow_steps_px > 16) {
    return InvalidInput(fmt::format("backgrounds.grow_steps_px: expected 0..16 pixels, found {}", grow_steps_px));
  }
  if (!(grow_seed_share >= 0 && grow_seed_share <= 1)) {
    return InvalidInput(fmt::format("backgrounds.grow_seed_share: expected 0..1, found {}", grow_seed_share));
  }
  if (!(grow_threshold_share > 0 && grow_threshold_share <= 1)) {
    return InvalidInput(fmt::format("backgrounds.grow_threshold_share: expected 0 < s <= 1, found {}", grow_threshold_share));
  }
  return shadows.Validate();
}

namespace {

// Pairs of background and frame levels, per background bin a histogram of the frame's levels.
// sum_b: per bin and frame level, the sum of the background levels of those pairs.
struct LevelPairs {
  std::vector<uint32_t> hist = std::vector<uint32_t>(static_cast<size_t>(kBins) * 256, 0);
  std::vector<uint32_t> sum_b = std::vector<uint32_t>(static_cast<size_t>(kBins) * 256, 0);
  std::array<uint32_t, kBins> counts{};
  int total = 0;
  // Background levels under 8 or over 247 say nothing of the slope (clipped).
  void Add(int background, int frame) {
    if (background < 8 || background > 247) return;
    const size_t at = static_cast<size_t>(background / kBinLevels) * 256 + static_cast<size_t>(frame);
    ++hist[at];
    sum_b[at] += static_cast<uint32_t>(background);
    ++counts[static_cast<size_t>(background / kBinLevels)];
    ++total;
  }
};

// The line frame = a background + b through the bins' densest levels (weighted by their counts),
// refitted twice without the bins further than kFitOutlierLevels from it; false when fewer than
// two bins have enough pairs, or the slope is not a photometric change.
bool FitDensestLine(const LevelPairs& pairs, double* a_out, double* b_out) {
  const uint32_t min_count = std::max<uint32_t>(16, static_cast<uint32_t>(pairs.total / 500));
  std::vector<std::array<double, 3>> points;  // background level, frame median, weight
  for (int bin = 0; bin < kBins; ++bin) {
    const uint32_t n = pairs.counts[static_cast<size_t>(bin)];
    if (n < min_count) continue;
    // The densest window of kModeWindow levels, not the median: the floor of one level stays
    // the densest where people of many shades cover more than half of its bin.
    const uint32_t* h = pairs.hist.data() + static_cast<size_t>(bin) * 256;
    const uint32_t* sb = pairs.sum_b.data() + static_cast<size_t>(bin) * 256;
    uint32_t in_window = 0, best = 0;
    int last = 0;  // the densest window's last level
    for (int level = 0; level < 256; ++level) {
      in_window += h[level];
      if (level >= kModeWindow) in_window -= h[level - kModeWindow];
      if (in_window > best) {
        best = in_window;
        last = level;
      }
    }
    // The point is the window's pairs' means, frame and background alike: the bin's mean
    // background against the window's centre is off wherever the bin's levels are uneven or the
    // gain spreads them over more levels than the window (ties went to the lowest).
    double sum_frame = 0, sum_background = 0;
    for (int level = std::max(0, last - kModeWindow + 1); level <= last; ++level) {
      sum_frame += static_cast<double>(level) * h[level];
      sum_background += sb[level];
    }
    const double frame_level = sum_frame / best;
    // A clipped level says nothing of the slope (the frame saturates there).
    if (frame_level <= 4 || frame_level >= 251) continue;
    points.push_back({sum_background / best, frame_level, static_cast<double>(n)});
  }
  if (points.size() < 2) return false;
  double a = 1, b = 0;
  if (!FitLine(points, &a, &b)) return false;
  // Bins far from the line (a crowd of one colour over one floor level) are left out, twice.
  for (int round = 0; round < 2; ++round) {
    std::vector<std::array<double, 3>> inliers;
    for (const auto& p : points) {
      if (std::abs(a * p[0] + b - p[1]) <= kFitOutlierLevels) inliers.push_back(p);
    }
    if (inliers.size() < 2 || inliers.size() == points.size()) break;
    if (!FitLine(inliers, &a, &b)) break;
    points = std::move(inliers);
  }
  if (!(a > 0.2 && a < 5)) return false;  // not a photometric change: leave it to the change test
  *a_out = a;
  *b_out = b;
  return true;
}

// Full-range BT.601 (util/yuv.h): RGB from (Y, Cb - 128, Cr - 128) and back.
constexpr double kRgbFromYcc[3][3] = {{1, 0, 1.402}, {1, -0.344136, -0.714136}, {1, 1.772, 0}};
constexpr double kYccFromRgb[3][3] = {
    {0.299, 0.587, 0.114}, {-0.168736, -0.331264, 0.5}, {0.5, -0.418688, -0.081312}};

}  // namespace

PhotometricTransfer EstimateTransfer(ImageView<const uint8_t> background_y, ImageView<const uint8_t> frame_y,
                                     int step_px, ImageView<const uint8_t> exclude) {
  OCCMAP_CHECK(background_y.width() == frame_y.width() && background_y.height() == frame_y.height(),
               "transfer: sizes differ");
  OCCMAP_CHECK(step_px >= 1, "transfer: step must be >= 1");
  OCCMAP_CHECK(exclude.empty() || (exclude.width() == frame_y.width() && exclude.height() == frame_y.height()),
               "transfer: exclusion size");
  LevelPairs pairs;
  for (int y = step_px / 2; y < frame_y.height(); y += step_px) {
    const uint8_t* b = background_y.row(y);
    const uint8_t* f = frame_y.row(y);
    const uint8_t* e = exclude.empty() ? nullptr : exclude.row(y);
    for (int x = step_px / 2; x < frame_y.width(); x += step_px) {
      if (e == nullptr || e[x] == 0) pairs.Add(b[x], f[x]);
    }
  }
  PhotometricTransfer t;
  t.samples = pairs.total;
  double a = 1, b = 0;
  if (!FitDensestLine(pairs, &a, &b)) return t;
  t.gain = a;
  t.offset = b;
  return t;
}

void ColourTransfer::DeriveChroma() {
  // chroma rows of kYccFromRgb diag(gain) kRgbFromYcc, and of kYccFromRgb offset.
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < 3; ++j) {
      double sum = 0;
      for (int c = 0; c < 3; ++c) sum += kYccFromRgb[k + 1][c] * gain[static_cast<size_t>(c)] * kRgbFromYcc[c][j];
      chroma[static_cast<size_t>(k)][static_cast<size_t>(j)] = sum;
    }
    double o = 0;
    for (int c = 0; c < 3; ++c) o += kYccFromRgb[k + 1][c] * offset[static_cast<size_t>(c)];
    chroma_offset[static_cast<size_t>(k)] = o;
  }
}

std::array<int32_t, 2> ColourTransfer::InvertChroma(int background_y, int u, int v, double luma_gain) const {
  if (!fitted) {
    return {ClampInt((128 + (u - 128) / luma_gain) * 256, 0, 65535), ClampInt((128 + (v - 128) / luma_gain) * 256, 0, 65535)};
  }
  // Solve the chroma rows for the background's Cb, Cr given its luma.
  const double ru = (u - 128) - chroma_offset[0] - chroma[0][0] * background_y;
  const double rv = (v - 128) - chroma_offset[1] - chroma[1][0] * background_y;
  const double a = chroma[0][1], b = chroma[0][2], c = chroma[1][1], d = chroma[1][2];
  const double det = a * d - b * c;
  if (std::abs(det) < 1e-6) return {ClampInt(u * 256.0, 0, 65535), ClampInt(v * 256.0, 0, 65535)};
  const double bu = (d * ru - b * rv) / det, bv = (-c * ru + a * rv) / det;
  return {ClampInt((128 + bu) * 256, 0, 65535), ClampInt((128 + bv) * 256, 0, 65535)};
}

ColourTransfer EstimateColourTransfer(ImageView<const uint8_t> background_y, ImageView<const uint8_t> background_u,
                                      ImageView<const uint8_t> background_v, const YuvView& frame,
                                      ImageView<const uint8_t> exclude, int step_px) {
  OCCMAP_CHECK(frame.has_chroma(), "colour transfer: the frame has no chroma");
  OCCMAP_CHECK(step_px >= 2 && step_px % 2 == 0, "colour transfer: step must be even");
  std::array<LevelPairs, 3> pairs;
  const int cw = background_u.width(), chh = background_u.height();
  const int cstep = step_px / 2;
  for (int cy = cstep / 2; cy < chh; cy += cstep) {
    const int y = 2 * cy;
    const uint8_t* by = background_y.row(y);
    const uint8_t* fy = frame.y.row(y);
    const uint8_t* e = exclude.empty() ? nullptr : exclude.row(y);
    for (int cx = cstep / 2; cx < cw; cx += cstep) {
      const int x = 2 * cx;
      if (e != nullptr && e[x] != 0) continue;
      const double bcb = background_u(cx, cy) - 128.0, bcr = background_v(cx, cy) - 128.0;
      const double fcb = frame.u(cx, cy) - 128.0, fcr = frame.v(cx, cy) - 128.0;
      for (int c = 0; c < 3; ++c) {
        const double b = by[x] + kRgbFromYcc[c][1] * bcb + kRgbFromYcc[c][2] * bcr;
        const double f = fy[x] + kRgbFromYcc[c][1] * fcb + kRgbFromYcc[c][2] * fcr;
        pairs[static_cast<size_t>(c)].Add(ClampInt(b, 0, 255), ClampInt(f, 0, 255));
      }
    }
  }
  ColourTransfer t;
  t.samples = pairs[1].total;
  for (int c = 0; c < 3; ++c) {
    if (!FitDensestLine(pairs[static_cast<size_t>(c)], &t.gain[static_cast<size_t>(c)], &t.offset[static_cast<size_t>(c)])) {
      return ColourTransfer{};
    }
  }
  t.fitted = true;
  t.DeriveChroma();
  // The richer model only where the data asks for it: channels that moved alike (exposure alone)
  // leave grey floor's chroma where the luma's gain puts it, and the fit's noise is not taken.
  double shift = 0;
  for (double level : {64.0, 128.0, 192.0}) {
    for (size_t k = 0; k < 2; ++k) shift = std::max(shift, std::abs(t.chroma[k][0] * level + t.chroma_offset[k]));
  }
  if (shift < kMinWhiteBalanceShift) return ColourTransfer{};
  return t;
}

// ---------------------------------------------------------------------------------------------
// Learning.

BackgroundLearner::BackgroundLearner(int width, int height, bool chroma, int expected_samples)
    : width_(width), height_(height), cw_(ChromaPlaneSize(width)), ch_(ChromaPlaneSize(height)), chroma_(chroma) {
  OCCMAP_CHECK(width > 0 && height > 0, "background learner: empty size");
  const size_t n = static_cast<size_t>(std::clamp(expected_samples, 1, 255));
  y_.reserve(n * static_cast<size_t>(width_) * height_);
  if (chroma_) {
    u_.reserve(n * static_cast<size_t>(cw_) * ch_);
    v_.reserve(n * static_cast<size_t>(cw_) * ch_);
  }
}

void BackgroundLearner::Add(const YuvView& frame) {
  OCCMAP_CHECK(frame.y.width() == width_ && frame.y.height() == height_, "background learner: frame size differs");
  OCCMAP_CHECK(count_ < 255, "background learner: more than 255 frames");
  auto append = [](std::vector<uint8_t>& dst, ImageView<const uint8_t> plane) {
    const size_t w = static_cast<size_t>(plane.width());
    const size_t at = dst.size();
    dst.resize(at + w * static_cast<size_t>(plane.height()));
    for (int y = 0; y < plane.height(); ++y) std::memcpy(dst.data() + at + w * y, plane.row(y), w);
  };
  append(y_, frame.y);
  if (chroma_) {
    OCCMAP_CHECK(frame.has_chroma() && frame.u.width() == cw_ && frame.u.height() == ch_ && frame.v.width() == cw_ &&
                     frame.v.height() == ch_,
                 "background learner: chroma planes missing or of the wrong size");
    append(u_, frame.u);
    append(v_, frame.v);
  }
  ++count_;
}

YuvView BackgroundLearner::Sample(int k) const {
  OCCMAP_CHECK(k >= 0 && k < count_, "background learner: no such sample");
  const size_t np = static_cast<size_t>(width_) * height_, nc = static_cast<size_t>(cw_) * ch_;
  YuvView v;
  v.y = ImageView<const uint8_t>(y_.data() + static_cast<size_t>(k) * np, width_, height_, width_);
  if (chroma_) {
    v.u = ImageView<const uint8_t>(u_.data() + static_cast<size_t>(k) * nc, cw_, ch_, cw_);
    v.v = ImageView<const uint8_t>(v_.data() + static_cast<size_t>(k) * nc, cw_, ch_, cw_);
  }
  return v;
}

YuvImage BackgroundLearner::Learn(BackgroundLearning method, int mode_radius, Alternative* alternative) const {
  OCCMAP_CHECK(count_ > 0, "background learner: no frames");
  const size_t k = static_cast<size_t>(count_);
  const size_t np = static_cast<size_t>(width_) * height_, nc = static_cast<size_t>(cw_) * ch_;
  // 1. A provisional median of luma, and each sample's transfer to it.
  Image<uint8_t> provisional(width_, height_);
  std::vector<uint8_t> column(k);
  for (size_t p = 0; p < np; ++p) {
    for (size_t f = 0; f < k; ++f) column[f] = y_[f * np + p];
    provisional(static_cast<int>(p % width_), static_cast<int>(p / width_)) = MedianOf(column.data(), k);
  }
  // 2. Samples normalised to the provisional background's photometry.
  std::vector<uint8_t> ny(y_.size()), nu(u_.size()), nv(v_.size());
  for (size_t f = 0; f < k; ++f) {
    const ImageView<const uint8_t> frame(y_.data() + f * np, width_, height_, width_);
    const PhotometricTransfer t = EstimateTransfer(provisional.view(), frame);
    std::array<uint8_t, 256> luma{}, chroma{};
    for (int level = 0; level < 256; ++level) {
      luma[static_cast<size_t>(level)] = Clamp8(t.Invert(level));
      chroma[static_cast<size_t>(level)] = Clamp8(128 + (level - 128) / t.gain);
    }
    for (size_t p = 0; p < np; ++p) ny[f * np + p] = luma[y_[f * np + p]];
    if (chroma_) {
      for (size_t p = 0; p < nc; ++p) {
        nu[f * nc + p] = chroma[u_[f * nc + p]];
        nv[f * nc + p] = chroma[v_[f * nc + p]];
      }
    }
  }
  YuvImage out;
  out.y = Image<uint8_t>(width_, height_);
  if (chroma_) {
    out.u = Image<uint8_t>(cw_, ch_);
    out.v = Image<uint8_t>(cw_, ch_);
  }
  if (alternative != nullptr) {
    alternative->levels = YuvImage{};
    alternative->levels.y = Image<uint8_t>(width_, height_, 0);
    if (chroma_) {
      alternative->levels.u = Image<uint8_t>(cw_, ch_, 128);
      alternative->levels.v = Image<uint8_t>(cw_, ch_, 128);
    }
    alternative->support = Image<uint8_t>(width_, height_, 0);
  }
  switch (method) {
    case BackgroundLearning::kMedian: {
      for (size_t p = 0; p < np; ++p) {
        for (size_t f = 0; f < k; ++f) column[f] = ny[f * np + p];
        out.y(static_cast<int>(p % width_), static_cast<int>(p / width_)) = MedianOf(column.data(), k);
      }
      for (size_t p = 0; p < nc && chroma_; ++p) {
        for (size_t f = 0; f < k; ++f) column[f] = nu[f * nc + p];
        out.u(static_cast<int>(p % cw_), static_cast<int>(p / cw_)) = MedianOf(column.data(), k);
        for (size_t f = 0; f < k; ++f) column[f] = nv[f * nc + p];
        out.v(static_cast<int>(p % cw_), static_cast<int>(p / cw_)) = MedianOf(column.data(), k);
      }
      break;
    }
    case BackgroundLearning::kMode: {
      // Per pixel: the samples sorted by level (packed with their frame), the widest run within
      // 2 * mode_radius levels; its mean. Chroma: the mean of the same frames' samples at the
      // block's top-left pixel.
      std::vector<uint16_t> packed(k);
      for (int y = 0; y < height_; ++y) {
        for (int x = 0; x < width_; ++x) {
          const size_t p = static_cast<size_t>(y) * width_ + x;
          for (size_t f = 0; f < k; ++f) packed[f] = static_cast<uint16_t>((ny[f * np + p] << 8) | f);
          std::sort(packed.begin(), packed.end());
          size_t best_i = 0, best_n = 0, i = 0;
          for (size_t j = 0; j < k; ++j) {
            while ((packed[j] >> 8) - (packed[i] >> 8) > 2 * mode_radius) ++i;
            if (j - i + 1 > best_n) {
              best_n = j - i + 1;
              best_i = i;
            }
          }
          // A run's mean level into `to` at (x, y), and its frames' mean chroma at the block's
          // top-left pixel.
          auto write_run = [&](size_t first, size_t n, YuvImage& to) {
            int sum = 0;
            for (size_t q = first; q < first + n; ++q) sum += packed[q] >> 8;
            to.y(x, y) = Clamp8(static_cast<double>(sum) / static_cast<double>(n));
            if (!chroma_ || x % 2 != 0 || y % 2 != 0) return;
            const size_t c = static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2);
            int su = 0, sv = 0;
            for (size_t q = first; q < first + n; ++q) {
              const size_t f = packed[q] & 0xff;
              su += nu[f * nc + c];
              sv += nv[f * nc + c];
            }
            to.u(x / 2, y / 2) = Clamp8(static_cast<double>(su) / static_cast<double>(n));
            to.v(x / 2, y / 2) = Clamp8(static_cast<double>(sv) / static_cast<double>(n));
          };
          write_run(best_i, best_n, out);
          if (alternative != nullptr) {
            // The densest run among the samples more than 2 * mode_radius from the first run's
            // mean.
            const int mean = out.y(x, y);
            size_t alt_i = 0, alt_n = 0;
            for (size_t j = 0, i2 = 0; j < k; ++j) {
              if (std::abs((packed[j] >> 8) - mean) <= 2 * mode_radius) {
                i2 = j + 1;
                continue;
              }
              while ((packed[j] >> 8) - (packed[i2] >> 8) > 2 * mode_radius) ++i2;
              if (j - i2 + 1 > alt_n) {
                alt_n = j - i2 + 1;
                alt_i = i2;
              }
            }
            if (alt_n > 0) {
              write_run(alt_i, alt_n, alternative->levels);
              alternative->support(x, y) = static_cast<uint8_t>(alt_n);
            }
          }
        }
      }
      break;
    }
    case BackgroundLearning::kMog2:
    case BackgroundLearning::kKnn: {
      // OpenCV's subtractors over the normalised samples (luma, and chroma brought to full size).
      cv::Ptr<cv::BackgroundSubtractor> model;
      if (method == BackgroundLearning::kMog2) {
        model = cv::createBackgroundSubtractorMOG2(static_cast<int>(k), 16, false);
      } else {
        model = cv::createBackgroundSubtractorKNN(static_cast<int>(k), 400, false);
      }
      cv::Mat sample(height_, width_, chroma_ ? CV_8UC3 : CV_8UC1), mask;
      for (size_t f = 0; f < k; ++f) {
        for (int y = 0; y < height_; ++y) {
          uint8_t* dst = sample.ptr<uint8_t>(y);
          for (int x = 0; x < width_; ++x) {
            const size_t p = static_cast<size_t>(y) * width_ + x;
            if (!chroma_) {
              dst[x] = ny[f * np + p];
              continue;
            }
            const size_t c = static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2);
            dst[3 * x] = ny[f * np + p];
            dst[3 * x + 1] = nu[f * nc + c];
            dst[3 * x + 2] = nv[f * nc + c];
          }
        }
        model->apply(sample, mask);
      }
      cv::Mat bg;
      model->getBackgroundImage(bg);
      OCCMAP_CHECK(bg.rows == height_ && bg.cols == width_, "background subtractor: unexpected image size");
      for (int y = 0; y < height_; ++y) {
        const uint8_t* src = bg.ptr<uint8_t>(y);
        for (int x = 0; x < width_; ++x) {
          out.y(x, y) = chroma_ ? src[3 * x] : src[x];
          if (chroma_ && x % 2 == 0 && y % 2 == 0) {
            out.u(x / 2, y / 2) = src[3 * x + 1];
            out.v(x / 2, y / 2) = src[3 * x + 2];
          }
        }
      }
      break;
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// The model.

BackgroundModel::BackgroundModel(const BackgroundOptions& options, double fps) : options_(options), fps_(fps) {
  OCCMAP_CHECK(fps > 0, "background model: fps must be > 0");
  for (int level = 0; level < 256; ++level) {
    pred_[level] = level;
    shadow_lo_[level] = 256;
    shadow_hi_[level] = -1;
  }
}

void BackgroundModel::Reset(const YuvImage& background) {
  width_ = background.y.width();
  height_ = background.y.height();
  cw_ = ChromaPlaneSize(width_);
  ch_ = ChromaPlaneSize(height_);
  chroma_ = background.has_chroma();
  const size_t np = static_cast<size_t>(width_) * height_, nc = static_cast<size_t>(cw_) * ch_;
  by_.resize(np);
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) by_[static_cast<size_t>(y) * width_ + x] = static_cast<uint16_t>(background.y(x, y) << 8);
  }
  bu_.clear();
  bv_.clear();
  if (chroma_) {
    OCCMAP_CHECK(background.u.width() == cw_ && background.u.height() == ch_, "background model: chroma size");
    bu_.resize(nc);
    bv_.resize(nc);
    for (int y = 0; y < ch_; ++y) {
      for (int x = 0; x < cw_; ++x) {
        bu_[static_cast<size_t>(y) * cw_ + x] = static_cast<uint16_t>(background.u(x, y) << 8);
        bv_[static_cast<size_t>(y) * cw_ + x] = static_cast<uint16_t>(background.v(x, y) << 8);
      }
    }
  }
  class_.assign(np, kBackground);
  ratio_.assign(np, 0);
  prev_y_.assign(np, 0);
  alt_y_.assign(np, 0);
  alt_valid_.assign(np, 0);
  alt_frames_.assign(np, 0);
  steady_frames_.assign(np, 0);
  set_frame_.assign(np, -1);
  stats_ = BackgroundStats{};
  first_frame_ = -1;
  pixels_updated_ = 0;
  stats_.pixels = static_cast<int64_t>(np);
  transfer_ = PhotometricTransfer{};
  look_ = ShadowLook{};
  ratio_histogram_.assign(kRatioBins, 0.0);
  learning_ = ShadowLearning{};
  shadow_lessons_ = 0;
  colour_ = ColourTransfer{};
  have_exclude_ = false;
}

bool BackgroundModel::BackgroundIsShadowOfAlternative(int x, int y) const {
  const size_t i = Index(x, y);
  if (!alt_valid_[i] || !options_.shadows.enabled) return false;
  const double lit = alt_y_[i], shaded = BackgroundLevel(x, y);
  if (lit < 1 || shaded < options_.shadows.min_ratio * lit || shaded > options_.shadows.max_ratio * lit) return false;
  if (!chroma_ || alt_u_.empty()) return true;
  const size_t c = static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2);
  const int u = (bu_[c] + 128) >> 8, v = (bv_[c] + 128) >> 8;
  const int limit = std::max(1, options_.chroma_threshold);
  return std::abs(u - alt_u_[c]) <= limit && std::abs(v - alt_v_[c]) <= limit;
}

int64_t BackgroundModel::PreferLitAlternatives() {
  int64_t swapped = 0;
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      if (!BackgroundIsShadowOfAlternative(x, y)) continue;
      SwapWithAlternative(x, y);
      ++swapped;
    }
  }
  return swapped;
}

void BackgroundModel::SetAlternative(const BackgroundLearner::Alternative& alternative, int min_support) {
  OCCMAP_CHECK(alternative.levels.y.width() == width_ && alternative.levels.y.height() == height_ &&
                   alternative.support.width() == width_ && alternative.support.height() == height_,
               "background model: alternative of another size");
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      const size_t i = static_cast<size_t>(y) * width_ + x;
      alt_y_[i] = alternative.levels.y(x, y);
      alt_valid_[i] = alternative.support(x, y) >= min_support && min_support > 0 ? 1 : 0;
    }
  }
  alt_u_.assign(static_cast<size_t>(cw_) * ch_, 128);
  alt_v_.assign(alt_u_.size(), 128);
  if (chroma_ && alternative.levels.has_chroma()) {
    for (int y = 0; y < ch_; ++y) {
      for (int x = 0; x < cw_; ++x) {
        alt_u_[static_cast<size_t>(y) * cw_ + x] = alternative.levels.u(x, y);
        alt_v_[static_cast<size_t>(y) * cw_ + x] = alternative.levels.v(x, y);
      }
    }
  }
}

std::array<int, 2> BackgroundModel::BackgroundChroma(int x, int y) const {
  if (!chroma_) return {128, 128};
  const size_t c = static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2);
  return {std::min(255, (bu_[c] + 128) >> 8), std::min(255, (bv_[c] + 128) >> 8)};
}

std::array<int, 2> BackgroundModel::AlternativeChroma(int x, int y) const {
  if (!chroma_ || alt_u_.empty()) return {128, 128};
  const size_t c = static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2);
  return {alt_u_[c], alt_v_[c]};
}

void BackgroundModel::SwapWithAlternative(int x, int y) {
  const size_t i = static_cast<size_t>(y) * width_ + x;
  if (!alt_valid_[i]) return;
  const uint8_t old = static_cast<uint8_t>(std::min(255, (by_[i] + 128) >> 8));
  by_[i] = static_cast<uint16_t>(alt_y_[i] << 8);
  alt_y_[i] = old;
  if (chroma_ && !alt_u_.empty() && x % 2 == 0 && y % 2 == 0) {
    const size_t c = static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2);
    const uint8_t old_u = static_cast<uint8_t>(std::min(255, (bu_[c] + 128) >> 8));
    const uint8_t old_v = static_cast<uint8_t>(std::min(255, (bv_[c] + 128) >> 8));
    bu_[c] = static_cast<uint16_t>(alt_u_[c] << 8);
    bv_[c] = static_cast<uint16_t>(alt_v_[c] << 8);
    alt_u_[c] = old_u;
    alt_v_[c] = old_v;
  }
}

YuvImage BackgroundModel::Current() const {
  YuvImage out;
  out.y = Image<uint8_t>(width_, height_);
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) out.y(x, y) = static_cast<uint8_t>(std::min(255, (by_[static_cast<size_t>(y) * width_ + x] + 128) >> 8));
  }
  if (chroma_) {
    out.u = Image<uint8_t>(cw_, ch_);
    out.v = Image<uint8_t>(cw_, ch_);
    for (int y = 0; y < ch_; ++y) {
      for (int x = 0; x < cw_; ++x) {
        const size_t i = static_cast<size_t>(y) * cw_ + x;
        out.u(x, y) = static_cast<uint8_t>(std::min(255, (bu_[i] + 128) >> 8));
        out.v(x, y) = static_cast<uint8_t>(std::min(255, (bv_[i] + 128) >> 8));
      }
    }
  }
  return out;
}

BackgroundLearner::Alternative BackgroundModel::CurrentAlternative(uint8_t support) const {
  BackgroundLearner::Alternative out;
  out.levels.y = Image<uint8_t>(width_, height_);
  out.support = Image<uint8_t>(width_, height_);
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      const size_t i = static_cast<size_t>(y) * width_ + x;
      out.levels.y(x, y) = alt_y_[i];
      out.support(x, y) = alt_valid_[i] ? support : 0;
    }
  }
  if (chroma_) {
    out.levels.u = Image<uint8_t>(cw_, ch_);
    out.levels.v = Image<uint8_t>(cw_, ch_);
    for (int y = 0; y < ch_; ++y) {
      for (int x = 0; x < cw_; ++x) {
        const size_t c = static_cast<size_t>(y) * cw_ + x;
        out.levels.u(x, y) = alt_u_.empty() ? 128 : alt_u_[c];
        out.levels.v(x, y) = alt_v_.empty() ? 128 : alt_v_[c];
      }
    }
  }
  return out;
}

// The class of one pixel from its frame values and its background's 8-bit levels, under the
// current transfer (the reference's formulas; DetectChanges reads the same from tables).
uint8_t BackgroundModel::Classify(int y, int u, int v, int by, int eu, int ev, int threshold) const {
  const int expected = ExpectedLuma(by);
  const int d = y - expected;
  bool changed = std::abs(d) > threshold;
  if (chroma_) {
    if (options_.chroma_threshold > 0) {
      changed |= std::abs(u - eu) > options_.chroma_threshold || std::abs(v - ev) > options_.chroma_threshold;
    }
  }
  if (!changed) return kBackground;
  const ShadowOptions& s = options_.shadows;
  if (!s.enabled || d >= 0 || expected <= 0) return kChanged;
  const bool cast =
      y >= static_cast<int>(std::ceil(s.min_ratio * expected)) && y <= static_cast<int>(std::floor(s.max_ratio * expected));
  if (cast && FitsShadowLook(y, u, v, expected, eu, ev, nullptr)) return kShadow;
  const bool soft = s.soft && chroma_ && y >= static_cast<int>(std::ceil(s.soft_min_ratio * expected)) &&
                    y <= static_cast<int>(std::floor(s.soft_max_ratio * expected));
  return soft && FitsSoftShadow(y, u, v, expected, eu, ev) ? kSoftShadow : kChanged;
}

bool BackgroundModel::FitsSoftShadow(int y, int u, int v, int ey, int eu, int ev) const {
  float q[3] = {0, 0, 0};
  ChannelPattern(y, u, v, ey, eu, ev, q);
  const bool learned = options_.shadows.learn && look_.ratio > 0;
  float distance = 0;
  for (int c = 0; c < 3; ++c)
    distance = std::max(distance, std::abs(q[c] - (learned ? look_.pattern[static_cast<size_t>(c)] : 0.0f)));
  return distance <= static_cast<float>(options_.shadows.max_channel_spread);
}

bool BackgroundModel::FitsShadowLook(int y, int u, int v, int ey, int eu, int ev, ShadowLearning* learn) const {
  const ShadowOptions& s = options_.shadows;
  const double ratio = static_cast<double>(y) / static_cast<double>(ey);
  const bool learned = s.learn && look_.ratio > 0;
  float q[3] = {0, 0, 0};
  float distance = 0;
  if (chroma_) {
    ChannelPattern(y, u, v, ey, eu, ev, q);
    for (int c = 0; c < 3; ++c) distance = std::max(distance, std::abs(q[c] - look_.pattern[static_cast<size_t>(c)]));
  }
  if (learn != nullptr && distance <= 2.5f * static_cast<float>(s.max_channel_spread)) {
    learn->histogram[static_cast<size_t>(std::clamp(static_cast<int>(ratio * kRatioBins), 0, kRatioBins - 1))] += 1;
    if (!learned || std::abs(ratio - look_.ratio) <= s.ratio_window) {
      // Mean shift towards the densest pattern: weights fall to 0 at twice the tolerance.
      const float gate = 2.0f * static_cast<float>(s.max_channel_spread);
      const float w = std::max(0.0f, 1.0f - (distance / gate) * (distance / gate));
      for (int c = 0; c < 3; ++c) learn->pattern_sum[static_cast<size_t>(c)] += w * q[c];
      learn->pattern_count += w;
    }
  }
  // Learning, nothing is a shadow until the scene has shown its shadows' ratio.
  if (s.learn && !learned) return false;
  if (learned && std::abs(ratio - look_.ratio) > s.ratio_window) return false;
  return distance <= static_cast<float>(s.max_channel_spread);
}

void BackgroundModel::LearnShadowLook(const ShadowLearning& frame) {
  if (ratio_histogram_.size() != kRatioBins) ratio_histogram_.assign(kRatioBins, 0.0);
  double mass = 0;
  for (int b = 0; b < kRatioBins; ++b) {
    ratio_histogram_[static_cast<size_t>(b)] = kLookDecay * ratio_histogram_[static_cast<size_t>(b)] + frame.histogram[static_cast<size_t>(b)];
    mass += ratio_histogram_[static_cast<size_t>(b)];
  }
  look_.mass = mass;
  const bool settled = shadow_lessons_ >= static_cast<int64_t>(std::lround(1 / (1 - kLookDecay)));
  if (mass < kLookMinMass) {
    // The warm-up's look (clothing may have taught it) stands until the map has had its say:
    // a few frames in which the teachers find next to no shadows drop it.
    if (settled || (shadow_lessons_ >= kWarmUpLookLessons && mass < kWarmUpLookMinMass)) look_.ratio = 0;
    return;
  }
  // The mode over three bins: over all ratios, and within the window of the look learned.
  const double window_bins = options_.shadows.ratio_window * kRatioBins;
  int best = 0, near = -1;
  double best_v = -1, near_v = -1;
  for (int b = 0; b < kRatioBins; ++b) {
    double v = ratio_histogram_[static_cast<size_t>(b)];
    if (b > 0) v += ratio_histogram_[static_cast<size_t>(b - 1)];
    if (b + 1 < kRatioBins) v += ratio_histogram_[static_cast<size_t>(b + 1)];
    if (v > best_v) {
      best_v = v;
      best = b;
    }
    if (look_.ratio > 0 && std::abs(b + 0.5 - look_.ratio * kRatioBins) <= window_bins && v > near_v) {
      near_v = v;
      near = b;
    }
  }
  // Shadows move slowly (the sun, a lamp dimmed): a learned look jumps to another ratio only
  // when that one clearly dominates, not for a passer-by whose dark clothes outnumber the
  // shadows in view for a moment.
  // The rule holds once the map has taught the look for a while (the warm-up's may be clothing).
  if (settled && near >= 0 && best_v < kLookJumpFactor * near_v) {
    best = near;
    best_v = near_v;
  }
  // Shadows share a ratio; dark clothing alone spreads over all of them (a scene without cast
  // shadows): a peak too flat is no shadow look. Once learned, a flat spell (a crowd in dark
  // clothes, few shadows in view) keeps the look.
  look_.peak_share = best_v / mass;
  if (look_.peak_share >= kLookMinPeakShare) look_.ratio = (best + 0.5) / kRatioBins;
  if (chroma_ && frame.pattern_count >= 100) {
    std::array<float, 3> p{};
    float mean = 0;
    for (int c = 0; c < 3; ++c) {
      p[static_cast<size_t>(c)] = static_cast<float>(frame.pattern_sum[static_cast<size_t>(c)] / frame.pattern_count);
      mean += p[static_cast<size_t>(c)] / 3;
    }
    for (int c = 0; c < 3; ++c) {
      const float target = p[static_cast<size_t>(c)] - mean;
      look_.pattern[static_cast<size_t>(c)] += static_cast<float>(1 - kLookDecay) * 2 * (target - look_.pattern[static_cast<size_t>(c)]);
    }
  }
}

bool BackgroundModel::TextureLikeBackground(ImageView<const uint8_t> frame_y, int x, int y) const {
  const int r = options_.shadows.texture_radius_px;
  if (r == 0) return true;
  int64_t n = 0, si = 0, sb = 0, sii = 0, sbb = 0, sib = 0;
  for (int yy = std::max(0, y - r); yy <= std::min(height_ - 1, y + r); ++yy) {
    const uint8_t* fi = frame_y.row(yy);
    const uint16_t* fb = by_.data() + static_cast<size_t>(yy) * width_;
    for (int xx = std::max(0, x - r); xx <= std::min(width_ - 1, x + r); ++xx) {
      const int64_t i = fi[xx], b = std::min(255, (fb[xx] + 128) >> 8);
      ++n;
      si += i;
      sb += b;
      sii += i * i;
      sbb += b * b;
      sib += i * b;
    }
  }
  const double nn = static_cast<double>(n);
  const double var_i = static_cast<double>(n * sii - si * si) / (nn * nn);
  const double var_b = static_cast<double>(n * sbb - sb * sb) / (nn * nn);
  const double flat = options_.shadows.flat_std;
  // A flat floor says nothing (and a shadow's edge crossing the window is not flat either).
  if (var_b < flat * flat) return true;
  if (var_i <= 0) return false;
  const double cov = static_cast<double>(n * sib - si * sb) / (nn * nn);
  return cov / std::sqrt(var_i * var_b) >= options_.shadows.min_texture_correlation;
}

BackgroundModel::PixelLevels BackgroundModel::LevelsAt(const YuvView& frame, int x, int y) const {
  const size_t i = static_cast<size_t>(y) * width_ + x;
  const size_t c = static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2);
  PixelLevels p{frame.y(x, y), 128, 128, std::min(255, (by_[i] + 128) >> 8), 128, 128};
  if (chroma_) {
    p.u = frame.u(x / 2, y / 2);
    p.v = frame.v(x / 2, y / 2);
    const size_t top_left = static_cast<size_t>(y & ~1) * width_ + static_cast<size_t>(x & ~1);
    const auto e = ExpectedChroma(std::min(255, (by_[top_left] + 128) >> 8), std::min(255, (bu_[c] + 128) >> 8),
                                  std::min(255, (bv_[c] + 128) >> 8));
    p.eu = e[0];
    p.ev = e[1];
  }
  return p;
}

void BackgroundModel::DetectChangesReference(const YuvView& frame, int threshold, ImageView<uint8_t> changes) const {
  OCCMAP_CHECK(frame.y.width() == width_ && frame.y.height() == height_, "background model: frame size differs");
  OCCMAP_CHECK(!chroma_ || frame.has_chroma(), "background model: the frame has no chroma");
  Image<uint8_t> classes(width_, height_);
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      const PixelLevels p = LevelsAt(frame, x, y);
      uint8_t cls = Classify(p.y, p.u, p.v, p.by, p.eu, p.ev, threshold);
      if ((cls == kShadow || cls == kSoftShadow) && !TextureLikeBackground(frame.y, x, y)) cls = kChanged;
      changes(x, y) = cls == kChanged ? 1 : 0;
      classes(x, y) = cls;
    }
  }
  if (options_.grow_steps_px == 0) return;
  // The hysteresis: the pixels classed background that are changes at its thresholds grow from
  // the changes of at least GrowSeedMinPixels() pixels (a flood fill in the reference).
  const int tl = GrowThreshold(threshold), tcl = chroma_ ? GrowThreshold(options_.chroma_threshold) : 0;
  Image<uint8_t> weak(width_, height_, 0);
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      if (classes(x, y) != kBackground) continue;
      const PixelLevels p = LevelsAt(frame, x, y);
      weak(x, y) = WeakChange(p.y, p.u, p.v, p.by, p.eu, p.ev, tl, tcl) ? 1 : 0;
    }
  }
  GrowChangesFromWeakReference(changes, weak.view(), classes.view(), options_.grow_steps_px, GrowSeedMinPixels());
}

int64_t BackgroundModel::GrowSeedMinPixels() const {
  return std::max<int64_t>(1, std::llround(options_.grow_seed_share * static_cast<double>(width_) * height_));
}

int BackgroundModel::GrowThreshold(int threshold) const {
  if (threshold <= 0) return 0;
  return std::max(1, static_cast<int>(std::lround(options_.grow_threshold_share * threshold)));
}

bool BackgroundModel::WeakChange(int y, int u, int v, int by, int eu, int ev, int tl, int tcl) const {
  if (std::abs(y - ExpectedLuma(by)) > tl) return true;
  if (tcl <= 0) return false;
  return std::abs(u - eu) > tcl || std::abs(v - ev) > tcl;
}

std::array<int, 2> BackgroundModel::ExpectedChroma(int block_y, int bu, int bv) const {
  if (!colour_.fitted) {
    return {ClampInt(128 + transfer_.gain * (bu - 128), 0, 255), ClampInt(128 + transfer_.gain * (bv - 128), 0, 255)};
  }
  std::array<int, 2> e{};
  for (size_t k = 0; k < 2; ++k) {
    const auto& r = colour_.chroma[k];
    e[k] = ClampInt(128 + r[0] * block_y + r[1] * (bu - 128) + r[2] * (bv - 128) + colour_.chroma_offset[k], 0, 255);
  }
  return e;
}

void BackgroundModel::ExpectChroma() {
  expected_u_.resize(static_cast<size_t>(cw_) * ch_);
  expected_v_.resize(static_cast<size_t>(cw_) * ch_);
  if (!colour_.fitted) {
    // The luma's gain alone: each plane's expected chroma depends on its own level only, one
    // table of ExpectedChroma's values (the same doubles, rounded once per level, not per block).
    std::array<uint8_t, 256> table{};
    for (int level = 0; level < 256; ++level) table[static_cast<size_t>(level)] = static_cast<uint8_t>(ExpectedChroma(0, level, level)[0]);
    const int cw = cw_;  // a local, as in Update's exclusion
    for (int cy = 0; cy < ch_; ++cy) {
      const uint8_t* bu = bgu8_.row(cy);
      const uint8_t* bv = bgv8_.row(cy);
      uint8_t* eu = expected_u_.data() + static_cast<size_t>(cy) * cw_;
      uint8_t* ev = expected_v_.data() + static_cast<size_t>(cy) * cw_;
      for (int cx = 0; cx < cw; ++cx) {
        eu[cx] = table[bu[cx]];
        ev[cx] = table[bv[cx]];
      }
    }
    return;
  }
  for (int cy = 0; cy < ch_; ++cy) {
    const uint8_t* b8 = bg8_.row(2 * cy);
    const uint8_t* bu = bgu8_.row(cy);
    const uint8_t* bv = bgv8_.row(cy);
    uint8_t* eu = expected_u_.data() + static_cast<size_t>(cy) * cw_;
    uint8_t* ev = expected_v_.data() + static_cast<size_t>(cy) * cw_;
    for (int cx = 0; cx < cw_; ++cx) {
      const auto e = ExpectedChroma(b8[2 * cx], bu[cx], bv[cx]);
      eu[cx] = static_cast<uint8_t>(e[0]);
      ev[cx] = static_cast<uint8_t>(e[1]);
    }
  }
}

int64_t BackgroundModel::GrowChanges(ImageView<uint8_t> changes) {
  // On the change test's masks alone: its weak pixels (classed background, changed at the
  // hysteresis' thresholds) were marked in its pass (adaptive_change_kernels.h).
  return GrowChangesFromWeak(changes, grow_weak_.view(), {class_.data(), width_, height_, width_}, options_.grow_steps_px,
                             GrowSeedMinPixels(), grow_seeds_, grow_band_);
}

void BackgroundModel::WarmUp(const std::vector<YuvView>& frames, int threshold) {
  Image<uint8_t> scratch(width_, height_);
  warming_up_ = true;
  for (const YuvView& f : frames) DetectChanges(f, threshold, scratch.view());
  warming_up_ = false;
}

void BackgroundModel::LearnShadows(const YuvView& frame, ImageView<const uint8_t> teach) {
  OCCMAP_CHECK(frame.y.width() == width_ && frame.y.height() == height_, "background model: frame size differs");
  OCCMAP_CHECK(teach.width() == width_ && teach.height() == height_, "background model: teachers' size");
  const ShadowOptions& s = options_.shadows;
  if (!s.enabled || !s.learn) return;
  if (shadow_lessons_ == 0) {
    // What the warm-up taught (every darker pixel, clothing too) gives way to the map's teachers.
    ratio_histogram_.assign(kRatioBins, 0.0);
    learning_.pending = false;
  }
  ++shadow_lessons_;
  if (learning_.pending) return;  // DetectChanges was not called since the last lesson
  learning_ = ShadowLearning{};
  learning_.pending = true;
  for (int y = 0; y < height_; ++y) {
    const uint8_t* t = teach.row(y);
    const uint8_t* cls = class_.data() + static_cast<size_t>(y) * width_;
    const uint8_t* fy = frame.y.row(y);
    for (int x = 0; x < width_; ++x) {
      if (t[x] == 0 || cls[x] == kBackground) continue;
      const int b = bg8_(x, y);
      const int expected = pred_[b];
      if (fy[x] >= expected || fy[x] < shadow_lo_[b] || fy[x] > shadow_hi_[b]) continue;
      int eu = 0, ev = 0, u = 0, v = 0;
      if (chroma_) {
        const size_t c = static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2);
        eu = expected_u_[c];
        ev = expected_v_[c];
        u = frame.u(x / 2, y / 2);
        v = frame.v(x / 2, y / 2);
      }
      FitsShadowLook(fy[x], u, v, expected, eu, ev, &learning_);
    }
  }
}

void BackgroundModel::DetectChanges(const YuvView& frame, int threshold, ImageView<uint8_t> changes) {
  OCCMAP_CHECK(!empty(), "background model: no background");
  OCCMAP_CHECK(frame.y.width() == width_ && frame.y.height() == height_, "background model: frame size differs");
  OCCMAP_CHECK(!chroma_ || frame.has_chroma(), "background model: the frame has no chroma");
  OCCMAP_CHECK(changes.width() == width_ && changes.height() == height_, "background model: change mask size");
  // The transfer against the current background's luma (8-bit).
  if (bg8_.width() != width_ || bg8_.height() != height_) bg8_ = Image<uint8_t>(width_, height_);
  for (int y = 0; y < height_; ++y) RoundRow(by_.data() + static_cast<size_t>(y) * width_, width_, bg8_.row(y));
  const ImageView<const uint8_t> exclude = have_exclude_ ? fit_exclude_.view() : ImageView<const uint8_t>{};
  transfer_ = EstimateTransfer(bg8_.view(), frame.y, 4, exclude);
  // A map that protects most of the view (or wrongly, after a bad fit) must not starve the fit.
  if (!exclude.empty() && transfer_.samples < kMinFitShare * (width_ / 4) * (height_ / 4)) transfer_ = EstimateTransfer(bg8_.view(), frame.y, 4);
  colour_ = ColourTransfer{};
  if (chroma_) {
    if (bgu8_.width() != cw_ || bgu8_.height() != ch_) {
      bgu8_ = Image<uint8_t>(cw_, ch_);
      bgv8_ = Image<uint8_t>(cw_, ch_);
    }
    for (int y = 0; y < ch_; ++y) {
      RoundRow(bu_.data() + static_cast<size_t>(y) * cw_, cw_, bgu8_.row(y));
      RoundRow(bv_.data() + static_cast<size_t>(y) * cw_, cw_, bgv8_.row(y));
    }
    if (options_.white_balance) {
      colour_ = EstimateColourTransfer(bg8_.view(), bgu8_.view(), bgv8_.view(), frame, exclude);
      if (!exclude.empty() && colour_.samples < kMinFitShare * (cw_ / 2) * (ch_ / 2)) {
        colour_ = EstimateColourTransfer(bg8_.view(), bgu8_.view(), bgv8_.view(), frame, {});
      }
    }
    ExpectChroma();
  }
  threshold_ = threshold;
  if (learning_.pending) {  // the previous frame's shadows
    LearnShadowLook(learning_);
    learning_.pending = false;
  }
  const ShadowOptions& s = options_.shadows;
  gain_q16_ = static_cast<int32_t>(std::lround(transfer_.gain * 65536));
  offset_q16_ = static_cast<int32_t>(std::lround(transfer_.offset * 65536)) + 32768;
  for (int level = 0; level < 256; ++level) {
    const int expected = ExpectedLuma(level);
    pred_[level] = expected;
    shadow_lo_[level] = static_cast<int>(std::ceil(s.min_ratio * expected));
    shadow_hi_[level] = static_cast<int>(std::floor(s.max_ratio * expected));
    soft_lo_[level] = static_cast<int>(std::ceil(s.soft_min_ratio * expected));
    soft_hi_[level] = static_cast<int>(std::floor(s.soft_max_ratio * expected));
    if (!s.enabled || expected <= 0) {
      shadow_lo_[level] = 256;
      shadow_hi_[level] = -1;
    }
    if (!s.enabled || !s.soft || !chroma_ || expected <= 0) {
      soft_lo_[level] = 256;
      soft_hi_[level] = -1;
    }
  }
  const int tc = chroma_ ? options_.chroma_threshold : 0;
  int64_t changed = 0, shadow = 0;
  ShadowLearning* learn = nullptr;
  // In a run the look is taught after the fusion (LearnShadows); warming up, by every pixel.
  if (warming_up_ && options_.shadows.enabled && options_.shadows.learn) {
    learning_ = ShadowLearning{};
    learning_.pending = true;
    learn = &learning_;
  }
  // Per row: the chroma test once per chroma row (spread over the row's pixels), the luma test
  // over the whole row in a loop the compiler vectorises, then the shadow test on the changed
  // pixels only (a few percent).
  chroma_changed_.assign(static_cast<size_t>(width_), 0);
  const int32_t gq = gain_q16_, cq = offset_q16_;
  // The hysteresis' weak test in the same pass (adaptive_change_kernels.h).
  const int tl = GrowThreshold(threshold), tcl = chroma_ ? GrowThreshold(options_.chroma_threshold) : 0;
  if (grow_weak_.width() != width_ || grow_weak_.height() != height_) grow_weak_ = Image<uint8_t>(width_, height_);
  for (int y = 0; y < height_; ++y) {
    const uint8_t* fy = frame.y.row(y);
    const uint8_t* b8 = bg8_.row(y);
    const uint8_t* fu = chroma_ ? frame.u.row(y / 2) : nullptr;
    const uint8_t* fv = chroma_ ? frame.v.row(y / 2) : nullptr;
    const uint8_t* reu = chroma_ ? expected_u_.data() + static_cast<size_t>(y / 2) * cw_ : nullptr;
    const uint8_t* rev = chroma_ ? expected_v_.data() + static_cast<size_t>(y / 2) * cw_ : nullptr;
    uint8_t* cls = class_.data() + static_cast<size_t>(y) * width_;
    uint8_t* rat = ratio_.data() + static_cast<size_t>(y) * width_;
    uint8_t* out = changes.row(y);
    uint8_t* cc = chroma_changed_.data();
    if (tc > 0 && y % 2 == 0) ChromaFlagsRow(width_, fu, fv, reu, rev, tc, tcl, cc);
    int row_changed = ChangeTestRow({.width = width_, .frame_y = fy, .background_y = b8, .chroma_flags = cc,
                                     .gain_q16 = gq, .offset_q16 = cq, .threshold = threshold, .weak_threshold = tl,
                                     .classes = cls, .changes = out, .weak = grow_weak_.row(y)});
    if (!options_.shadows.enabled || row_changed == 0) {
      changed += row_changed;
      continue;
    }
    for (int x = 0; x < width_; ++x) {
      // Eight pixels at a time past unchanged runs.
      if (x + 8 <= width_) {
        uint64_t word;
        std::memcpy(&word, cls + x, 8);
        if (word == 0) {
          x += 7;
          continue;
        }
      }
      if (cls[x] == kBackground) continue;
      const int b = b8[x];
      const int expected = pred_[b];
      const bool cast = fy[x] < expected && fy[x] >= shadow_lo_[b] && fy[x] <= shadow_hi_[b];
      const bool soft = fy[x] < expected && fy[x] >= soft_lo_[b] && fy[x] <= soft_hi_[b];
      rat[x] = cast ? static_cast<uint8_t>(std::min(255, (fy[x] * 255 + expected / 2) / expected)) : 0;
      if (!cast && !soft) continue;
      int eu = 0, ev = 0, u = 0, v = 0;
      if (chroma_) {
        eu = reu[x >> 1];
        ev = rev[x >> 1];
        u = fu[x >> 1];
        v = fv[x >> 1];
      }
      const bool cast_fits = cast && FitsShadowLook(fy[x], u, v, expected, eu, ev, learn);
      const bool fits = cast_fits || (soft && FitsSoftShadow(fy[x], u, v, expected, eu, ev));
      if (fits && TextureLikeBackground(frame.y, x, y)) {
        cls[x] = cast_fits ? kShadow : kSoftShadow;
        out[x] = 0;
        --row_changed;
        ++shadow;
      }
    }
    changed += row_changed;
  }
  if (options_.grow_steps_px > 0 && changed > 0) changed += GrowChanges(changes);
  const double np = static_cast<double>(width_) * height_;
  stats_.changed_fraction = static_cast<double>(changed) / np;
  stats_.shadow_fraction = static_cast<double>(shadow) / np;
  stats_.transfer = transfer_;
}

void BackgroundModel::Update(const YuvView& frame, ImageView<const uint8_t> protection, int64_t frame_index) {
  OCCMAP_CHECK(frame.y.width() == width_ && frame.y.height() == height_, "background model: frame size differs");
  OCCMAP_CHECK(protection.width() == width_ && protection.height() == height_, "background model: protection size");
  // Frame levels brought back to the background's photometry, in 8.8.
  std::array<int32_t, 256> inv_y{}, inv_c{};
  for (int level = 0; level < 256; ++level) {
    inv_y[static_cast<size_t>(level)] = ClampInt(transfer_.Invert(level) * 256, 0, 65535);
    inv_c[static_cast<size_t>(level)] = ClampInt((128 + (level - 128) / transfer_.gain) * 256, 0, 65535);
  }
  // A chroma block's frame chroma brought back to the background's (the block's top-left pixel
  // reads it, before that pixel's luma is updated).
  const auto back = [&](size_t i, int u, int v) -> std::array<int32_t, 2> {
    if (!colour_.fitted) return {inv_c[static_cast<size_t>(u)], inv_c[static_cast<size_t>(v)]};
    return colour_.InvertChroma(std::min(255, (by_[i] + 128) >> 8), u, v, transfer_.gain);
  };
  // What the map protects stays out of the next frame's transfer fits.
  if (fit_exclude_.width() != width_ || fit_exclude_.height() != height_) fit_exclude_ = Image<uint8_t>(width_, height_);
  const int w = width_;  // a local: a store to e could alias width_, which would be reloaded per pixel
  for (int y = 0; y < height_; ++y) {
    const uint8_t* prot = protection.row(y);
    uint8_t* e = fit_exclude_.row(y);
    for (int x = 0; x < w; ++x) e[x] = prot[x] != kFree;
  }
  have_exclude_ = true;
  // Exponential forgetting with time constant adapt_s, in 1/65536.
  const int32_t alpha = std::max<int32_t>(1, static_cast<int32_t>(std::lround(65536.0 / std::max(1.0, options_.adapt_s * fps_))));
  const int relight = std::max(1, static_cast<int>(std::lround(options_.relight_s * fps_)));
  const int absorb = std::max(1, static_cast<int>(std::lround(options_.absorb_s * fps_)));
  const int steady_levels = 8;  // frame-to-frame change of a steady pixel (noise, compression)
  const int32_t f = static_cast<int32_t>(frame_index);
  if (first_frame_ < 0) first_frame_ = frame_index;
  int64_t absorbed = 0;
  // The free background pixels (most of them) in the row kernel (adaptive_change_kernels.h),
  // the others in the loop below.
  update_rest_.assign(static_cast<size_t>(width_), 1);
  const bool row_kernel = alpha <= 32767;
  for (int y = 0; y < height_; ++y) {
    const uint8_t* fy = frame.y.row(y);
    const uint8_t* prot = protection.row(y);
    const bool chroma_row = chroma_ && y % 2 == 0;
    const uint8_t* fu = chroma_row ? frame.u.row(y / 2) : nullptr;
    const uint8_t* fv = chroma_row ? frame.v.row(y / 2) : nullptr;
    const size_t row = static_cast<size_t>(y) * width_;
    const uint8_t* rest = update_rest_.data();
    if (row_kernel) {
      const size_t crow = chroma_row ? static_cast<size_t>(y / 2) * cw_ : 0;
      pixels_updated_ += UpdateFreeBackgroundRow(
          {.width = width_, .frame_y = fy, .protection = prot, .classes = class_.data() + row,
           .background_y = by_.data() + row, .previous_y = prev_y_.data() + row,
           .steady_frames = steady_frames_.data() + row, .set_frame = set_frame_.data() + row, .inv_y = inv_y.data(),
           .alpha = alpha, .frame = f, .frame_u = fu, .frame_v = fv,
           .background_u = chroma_row ? bu_.data() + crow : nullptr, .background_v = chroma_row ? bv_.data() + crow : nullptr,
           .inv_c = colour_.fitted ? nullptr : inv_c.data(), .rest = update_rest_.data()});
    }
    for (int x = 0; x < width_; ++x) {
      if (x + 8 <= width_) {  // past the kernel's pixels eight at a time
        uint64_t word;
        std::memcpy(&word, rest + x, 8);
        if (word == 0) {
          x += 7;
          continue;
        }
      }
      if (rest[x] == 0) continue;
      const size_t i = row + x;
      const uint8_t cls = class_[i];
      const int level = fy[x];
      const int prev = prev_y_[i];
      prev_y_[i] = static_cast<uint8_t>(level);
      const bool chroma_here = chroma_row && x % 2 == 0;
      const size_t c = chroma_here ? static_cast<size_t>(y / 2) * cw_ + static_cast<size_t>(x / 2) : 0;
      if (prot[x] == kWalkedPerson) {
        alt_frames_[i] = 0;
        steady_frames_[i] = 0;
        continue;
      }
      if (cls == kChanged && alt_valid_[i]) {
        // Back to the alternative (the floor a learned-in person stood on): swap them.
        if (std::abs(level - pred_[alt_y_[i]]) <= threshold_) {
          if (++alt_frames_[i] >= relight) {
            const uint8_t old = static_cast<uint8_t>(std::min(255, (by_[i] + 128) >> 8));
            by_[i] = static_cast<uint16_t>(inv_y[static_cast<size_t>(level)]);
            if (chroma_here && !alt_u_.empty()) {
              alt_u_[c] = static_cast<uint8_t>(std::min(255, (bu_[c] + 128) >> 8));
              alt_v_[c] = static_cast<uint8_t>(std::min(255, (bv_[c] + 128) >> 8));
            }
            if (chroma_here) {
              const auto b = back(i, fu[x >> 1], fv[x >> 1]);
              bu_[c] = static_cast<uint16_t>(b[0]);
              bv_[c] = static_cast<uint16_t>(b[1]);
            }
            alt_y_[i] = old;
            alt_frames_[i] = 0;
            steady_frames_[i] = 0;
            MarkSet(i, f);
            ++absorbed;
            continue;
          }
        } else {
          alt_frames_[i] = 0;
        }
      }
      if (prot[x] >= kPerson || cls == kShadow || cls == kSoftShadow) {
        steady_frames_[i] = 0;
        continue;
      }
      if (cls == kBackground) {
        steady_frames_[i] = 0;
        if (prot[x] != kFree) continue;
        by_[i] = static_cast<uint16_t>(by_[i] + ((inv_y[static_cast<size_t>(level)] - by_[i]) * alpha + 32768) / 65536);
        if (chroma_here) {
          const auto b = back(i, fu[x >> 1], fv[x >> 1]);
          bu_[c] = static_cast<uint16_t>(bu_[c] + ((b[0] - bu_[c]) * alpha + 32768) / 65536);
          bv_[c] = static_cast<uint16_t>(bv_[c] + ((b[1] - bv_[c]) * alpha + 32768) / 65536);
        }
        MarkSet(i, f);
        continue;
      }
      // Changed: count the frames it stays steady; taken as background after relight_s (no
      // object there) or absorb_s (an object that is not a person).
      const int steady = std::abs(level - prev) <= steady_levels ? steady_frames_[i] + 1 : 0;
      steady_frames_[i] = static_cast<uint16_t>(std::min(steady, 65535));
      if (steady >= (prot[x] == kFree ? relight : absorb)) {
        // The look it replaces becomes the alternative: what was absorbed (a person the map
        // lost, a box) shows it again when it leaves, and is swapped out in relight_s.
        alt_y_[i] = static_cast<uint8_t>(std::min(255, (by_[i] + 128) >> 8));
        alt_valid_[i] = 1;
        alt_frames_[i] = 0;
        if (chroma_here && !alt_u_.empty()) {
          alt_u_[c] = static_cast<uint8_t>(std::min(255, (bu_[c] + 128) >> 8));
          alt_v_[c] = static_cast<uint8_t>(std::min(255, (bv_[c] + 128) >> 8));
        }
        by_[i] = static_cast<uint16_t>(inv_y[static_cast<size_t>(level)]);
        if (chroma_here) {
          const auto b = back(i, fu[x >> 1], fv[x >> 1]);
          bu_[c] = static_cast<uint16_t>(b[0]);
          bv_[c] = static_cast<uint16_t>(b[1]);
        }
        steady_frames_[i] = 0;
        MarkSet(i, f);
        ++absorbed;
      }
    }
  }
  ++stats_.frames;
  stats_.pixels_absorbed += absorbed;
  stats_.pixels_updated = pixels_updated_;
}

double BackgroundModel::MeanAgeS(int64_t frame_index) const {
  if (set_frame_.empty()) return 0;
  double sum = 0;
  const int64_t start = first_frame_ < 0 ? frame_index : first_frame_;
  for (int32_t s : set_frame_) sum += static_cast<double>(frame_index - (s < 0 ? start : s));
  return sum / static_cast<double>(set_frame_.size()) / fps_;
}

}  // namespace occmap
