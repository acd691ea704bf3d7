#include "occmap/util/hungarian.h"

#include <algorithm>
#include <cmath>

#include "occmap/util/status.h"

namespace occmap {

// Kuhn-Munkres with row/column potentials (the e-maxx formulation) on a square matrix of
// size n = max(rows, cols), padded with zero-cost dummy cells. Forbidden pairs get a cost
// larger than any sum of allowed ones, so the optimum first maximises the number of allowed
// pairs and then minimises their cost; forbidden pairs it still makes are dropped afterwards.
std::vector<int> SolveAssignment(const std::vector<double>& cost, int rows, int cols, double forbidden_cost) {
  OCCMAP_CHECK(static_cast<int64_t>(cost.size()) == static_cast<int64_t>(rows) * cols, "cost matrix size");
  std::vector<int> result(static_cast<size_t>(std::max(rows, 0)), -1);
  if (rows <= 0 || cols <= 0) return result;
  const int n = std::max(rows, cols);
  double max_allowed = 0;
  for (double c : cost) {
    if (c < forbidden_cost && std::isfinite(c)) max_allowed = std::max(max_allowed, std::abs(c));
  }
  const double big = (max_allowed + 1) * (n + 1) * 4;
  auto a = [&](int i, int j) -> double {  // 1-based
    if (i > rows || j > cols) return 0.0;
    const double c = cost[static_cast<size_t>(i - 1) * cols + (j - 1)];
    return (c >= forbidden_cost || !std::isfinite(c)) ? big : c;
  };
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> u(n + 1, 0), v(n + 1, 0), minv(n + 1);
  std::vector<int> p(n + 1, 0), way(n + 1, 0);
  std::vector<char> used(n + 1);
  for (int i = 1; i <= n; ++i) {
    p[0] = i;
    int j0 = 0;
    std::fill(minv.begin(), minv.end(), inf);
    std::fill(used.begin(), used.end(), 0);
    do {
      used[j0] = 1;
      const int i0 = p[j0];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= n; ++j) {
        if (used[j]) continue;
        const double cur = a(i0, j) - u[i0] - v[j];
        if (cur < minv[j]) {
          minv[j] = cur;
          way[j] = j0;
        }
        if (minv[j] < delta) {
          delta = minv[j];
          j1 = j;
        }
      }
      for (int j = 0; j <= n; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {
      const int j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  for (int j = 1; j <= cols; ++j) {
    const int i = p[j];
    if (i >= 1 && i <= rows) {
      const double c = cost[static_cast<size_t>(i - 1) * cols + (j - 1)];
      if (c < forbidden_cost && std::isfinite(c)) result[i - 1] = j - 1;
    }
  }
  return result;
}

}  // namespace occmap
