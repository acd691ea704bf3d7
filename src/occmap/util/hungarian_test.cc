#include "occmap/util/hungarian.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

namespace occmap {
namespace {

// Brute force over all injections of rows into columns (small sizes): the maximal number of
// allowed pairs, then the least cost.
std::pair<int, double> BruteForce(const std::vector<double>& cost, int rows, int cols, double forbidden) {
  std::vector<int> cols_perm(std::max(rows, cols));
  std::iota(cols_perm.begin(), cols_perm.end(), 0);
  int best_pairs = -1;
  double best_cost = 0;
  do {
    int pairs = 0;
    double total = 0;
    for (int i = 0; i < rows; ++i) {
      const int j = cols_perm[i];
      if (j < cols && cost[i * cols + j] < forbidden) {
        ++pairs;
        total += cost[i * cols + j];
      }
    }
    if (pairs > best_pairs || (pairs == best_pairs && total < best_cost - 1e-12)) {
      best_pairs = pairs;
      best_cost = total;
    }
  } while (std::next_permutation(cols_perm.begin(), cols_perm.end()));
  return {best_pairs, best_cost};
}

TEST(SolveAssignment, HandWorkedSquareCase) {
  // Rows are workers, columns jobs; the optimum is 0->1, 1->0, 2->2 with cost 1 + 2 + 2 = 5.
  const std::vector<double> cost = {4, 1, 3,  //
                                    2, 0, 5,  //
                                    3, 2, 2};
  const auto match = SolveAssignment(cost, 3, 3);
  EXPECT_EQ(match, (std::vector<int>{1, 0, 2}));
}

TEST(SolveAssignment, ForbiddenPairsAreNeverMade) {
  const std::vector<double> cost = {0.1, 9, 9, 0.2};
  EXPECT_EQ(SolveAssignment(cost, 2, 2, 0.5), (std::vector<int>{0, 1}));
  const std::vector<double> far = {0.9, 0.8, 0.7, 0.6};
  EXPECT_EQ(SolveAssignment(far, 2, 2, 0.5), (std::vector<int>{-1, -1}));
}

TEST(SolveAssignment, PrefersMorePairsOverACheaperSinglePair) {
  // Row 0 could take column 0 cheaply, but then row 1 (which can only take column 0) is lost.
  const std::vector<double> cost = {0.0, 0.4,  //
                                    0.3, 9.0};
  EXPECT_EQ(SolveAssignment(cost, 2, 2, 0.5), (std::vector<int>{1, 0}));
}

TEST(SolveAssignment, MatchesBruteForceOnRandomRectangularProblems) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 300; ++trial) {
    const int rows = 1 + static_cast<int>(rng() % 6), cols = 1 + static_cast<int>(rng() % 6);
    std::vector<double> cost(rows * cols);
    for (double& c : cost) c = u(rng);
    const double forbidden = trial % 2 == 0 ? 2.0 : 0.6;
    const auto match = SolveAssignment(cost, rows, cols, forbidden);
    int pairs = 0;
    double total = 0;
    std::vector<int> used(cols, 0);
    for (int i = 0; i < rows; ++i) {
      if (match[i] < 0) continue;
      ASSERT_LT(cost[i * cols + match[i]], forbidden);
      ASSERT_EQ(used[match[i]]++, 0);
      ++pairs;
      total += cost[i * cols + match[i]];
    }
    const auto [best_pairs, best_cost] = BruteForce(cost, rows, cols, forbidden);
    ASSERT_EQ(pairs, best_pairs) << "trial " << trial;
    ASSERT_NEAR(total, best_cost, 1e-9) << "trial " << trial;
  }
}

TEST(SolveAssignment, EmptyProblems) {
  EXPECT_TRUE(SolveAssignment({}, 0, 3).empty());
  EXPECT_EQ(SolveAssignment({}, 2, 0), (std::vector<int>{-1, -1}));
}

}  // namespace
}  // namespace occmap
