// The benches' timing: fn(frame index) over `frames` frames, `repetitions` times after one
// warm-up call; each pass's seconds per frame, in pass order. bench.cc reports their median,
// adaptive_bench.cc their fastest (on a shared machine a pass is only ever slowed down).
#pragma once

#include <chrono>
#include <functional>
#include <vector>

namespace occmap::bench {

inline std::vector<double> SecondsPerFrameOfEachPass(int repetitions, int frames, const std::function<void(int)>& fn) {
  fn(0);  // warm-up
  std::vector<double> times;
  for (int r = 0; r < repetitions; ++r) {
    const auto start = std::chrono::steady_clock::now();
    for (int f = 0; f < frames; ++f) fn(f);
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / frames);
  }
  return times;
}

// a / b, 0 when b is not positive (a method that did not run).
inline double Ratio(double a, double b) { return b > 0 ? a / b : 0.0; }

}  // namespace occmap::bench
