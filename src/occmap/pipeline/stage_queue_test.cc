#include "occmap/pipeline/stage_queue.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

namespace occmap {
namespace {

TEST(StageQueue, KeepsOrderAndNeverHoldsMoreThanItsCapacity) {
  StageQueue<int> queue(3);
  std::thread producer([&] {
    for (int i = 0; i < 200; ++i) ASSERT_TRUE(queue.Push(i));
    queue.Close();
  });
  std::vector<int> got;
  while (std::optional<int> item = queue.Pop()) {
    got.push_back(*item);
    if (got.size() % 50 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));  // a slow consumer
  }
  producer.join();
  ASSERT_EQ(got.size(), 200u);
  for (int i = 0; i < 200; ++i) EXPECT_EQ(got[i], i);
  EXPECT_EQ(queue.high_water(), 3u);  // the producer waited rather than piling up items
}

TEST(StageQueue, CloseDrainsWhatIsLeftThenEnds) {
  StageQueue<int> queue(4);
  ASSERT_TRUE(queue.Push(1));
  ASSERT_TRUE(queue.Push(2));
  queue.Close();
  EXPECT_FALSE(queue.Push(3));
  EXPECT_EQ(queue.Pop(), 1);
  EXPECT_EQ(queue.Pop(), 2);
  EXPECT_EQ(queue.Pop(), std::nullopt);
}

TEST(StageQueue, CloseWakesABlockedProducer) {
  StageQueue<int> queue(1);
  ASSERT_TRUE(queue.Push(1));
  std::atomic<int> result{-1};
  std::thread producer([&] { result = queue.Push(2) ? 1 : 0; });  // blocks: full
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  queue.Close();
  producer.join();
  EXPECT_EQ(result.load(), 0);
}

TEST(StageWorker, ProcessesItemsInOrderOnItsOwnThread) {
  std::vector<int> seen;
  std::thread::id worker_id;
  StageWorker<int> worker(2, [&](int& i) {
    worker_id = std::this_thread::get_id();
    seen.push_back(i);
    return Status::Ok();
  });
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(worker.Push(i));
  ASSERT_TRUE(worker.Finish().ok());
  ASSERT_EQ(seen.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(seen[i], i);
  EXPECT_NE(worker_id, std::this_thread::get_id());
  EXPECT_LE(worker.queue().high_water(), 2u);
}

TEST(StageWorker, AfterAnErrorLaterItemsAreDiscardedAndTheErrorIsReturned) {
  std::vector<int> processed, discarded;
  std::mutex discarded_mutex;
  StageWorker<int> worker(
      2,
      [&](int& i) -> Status {
        if (i == 5) return IoError("'out/x.png': disk full");
        processed.push_back(i);
        return Status::Ok();
      },
      [&](int& i) {
        std::lock_guard lock(discarded_mutex);
        discarded.push_back(i);
      });
  int pushed = 0;
  for (int i = 0; i < 1000; ++i) {
    if (!worker.Push(i)) break;  // the producer learns of the failure and stops
    ++pushed;
  }
  const Status status = worker.Finish();
  EXPECT_EQ(status.code(), StatusCode::kIoError);
  EXPECT_EQ(status.message(), "'out/x.png': disk full");
  EXPECT_EQ(processed, (std::vector<int>{0, 1, 2, 3, 4}));  // nothing after the failed one
  EXPECT_LT(pushed, 1000);
  // Every item is either processed, the failed one, or discarded: none is lost.
  EXPECT_EQ(processed.size() + 1 + discarded.size(), static_cast<size_t>(pushed) + 1);
}

}  // namespace
}  // namespace occmap
