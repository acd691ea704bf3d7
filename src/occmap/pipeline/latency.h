// LatencyHistogram: percentiles of a long run's latencies in constant memory. Log-spaced bins
// 2 % wide from 10 us to about 10^4 s (a value outside goes to the end bins): a percentile is
// the geometric centre of its bin, within 1 % of the true value, however many samples.
//
//   LatencyHistogram h;  h.Add(0.0123);  h.Percentile(0.95);  // seconds
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace occmap {

class LatencyHistogram {
 public:
  static constexpr double kMinS = 1e-5;
  static constexpr double kGrowth = 1.02;
  static constexpr int kBins = 1400;  // kMinS * 1.02^1400 ~ 1e7 s

  void Add(double seconds) {
    int bin = 0;
    if (seconds > kMinS) bin = static_cast<int>(std::log(seconds / kMinS) / std::log(kGrowth));
    bin = bin < 0 ? 0 : bin >= kBins ? kBins - 1 : bin;
    ++counts_[static_cast<size_t>(bin)];
    ++count_;
    sum_s_ += seconds;
    if (seconds > max_s_) max_s_ = seconds;
  }
  int64_t count() const { return count_; }
  double sum_s() const { return sum_s_; }  // of every sample (a Prometheus summary's _sum)
  double max_s() const { return max_s_; }
  // The q-quantile (0 < q <= 1) in seconds: the centre of the bin holding the ceil(q n)-th
  // smallest sample; 0 without samples.
  double Percentile(double q) const {
    if (count_ == 0) return 0;
    const int64_t rank = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(q * static_cast<double>(count_))));
    int64_t seen = 0;
    for (int b = 0; b < kBins; ++b) {
      seen += counts_[static_cast<size_t>(b)];
      if (seen >= rank) return std::min(max_s_, kMinS * std::pow(kGrowth, b + 0.5));
    }
    return max_s_;
  }

 private:
  std::array<int64_t, kBins> counts_{};
  int64_t count_ = 0;
  double sum_s_ = 0;
  double max_s_ = 0;
};

}  // namespace occmap
