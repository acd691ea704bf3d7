#include "occmap/util/thread_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <vector>

namespace occmap {
namespace {

TEST(ParallelFor, CoversEveryIndexExactlyOnce) {
  for (int threads : {1, 2, 4}) {
    Context ctx(threads);
    std::vector<std::atomic<int>> hits(10007);
    ParallelFor(ctx, 0, 10007, [&](int64_t b, int64_t e, int worker) {
      EXPECT_LT(worker, ctx.num_threads());
      for (int64_t i = b; i < e; ++i) hits[i]++;
    });
    for (auto& h : hits) ASSERT_EQ(h.load(), 1);
  }
}

TEST(ParallelFor, PerWorkerPartialsReduceToTheSerialSum) {
  Context ctx(2);
  for (int round = 0; round < 200; ++round) {  // reuse the pool many times
    std::vector<int64_t> partial(ctx.num_threads(), 0);
    ParallelFor(ctx, 0, 1000, [&](int64_t b, int64_t e, int worker) {
      for (int64_t i = b; i < e; ++i) partial[worker] += i;
    });
    ASSERT_EQ(std::accumulate(partial.begin(), partial.end(), int64_t{0}), 999 * 1000 / 2);
  }
}

TEST(ParallelFor, EmptyRangeDoesNothing) {
  Context ctx(2);
  bool called = false;
  ParallelFor(ctx, 5, 5, [&](int64_t, int64_t, int) { called = true; });
  EXPECT_FALSE(called);
}

}  // namespace
}  // namespace occmap
