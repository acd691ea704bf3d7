// SharedFigure: a figure one stage's thread adds to (seconds spent, a background's age) and
// another's reads for the running figures (RunStats). One writer, so a relaxed load and store
// add without a lock.
#pragma once

#include <atomic>

namespace occmap {

class SharedFigure {
 public:
  explicit SharedFigure(double v = 0) : v_(v) {}
  void Add(double d) { v_.store(v_.load(std::memory_order_relaxed) + d, std::memory_order_relaxed); }
  void Set(double v) { v_.store(v, std::memory_order_relaxed); }
  double get() const { return v_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> v_;
};

}  // namespace occmap
