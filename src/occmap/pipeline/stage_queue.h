// The plumbing between the stages of a run (pipeline/run.cc): a bounded FIFO (StageQueue) and a
// stage on its own thread fed through one (StageWorker).
//
// StageQueue<T> holds at most `capacity` items: Push blocks while it is full, Pop while it is
// empty, so a fast producer waits for a slow consumer and memory stays flat however long the
// run. Close() ends it: pending Pushes return false, Pop drains what is left, then returns
// nullopt. No busy waits: both sides sleep on condition variables.
//
// StageWorker<T> runs process(item) for each pushed item, in push order, on one thread of its
// own. The first error is kept; the items after it are handed to discard() instead (a stage
// that owns a buffer gives it back there), so an output written after a failed one never
// exists. Finish() closes the queue, waits for the thread and returns the first error.
//
//   StageWorker<FrameOutput> writer(4, [&](FrameOutput& o) { return WriteIt(o); });
//   for (...) if (!writer.Push(std::move(output))) break;  // false once it has failed
//   OCCMAP_RETURN_IF_ERROR(writer.Finish());
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "occmap/util/status.h"

namespace occmap {

template <typename T>
class StageQueue {
 public:
  explicit StageQueue(size_t capacity) : capacity_(capacity < 1 ? 1 : capacity) {}
  StageQueue(const StageQueue&) = delete;
  StageQueue& operator=(const StageQueue&) = delete;

  // Blocks while full; false (the item is dropped) when the queue is closed.
  bool Push(T item) {
    std::unique_lock lock(mutex_);
    not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
    if (closed_) return false;
    items_.push_back(std::move(item));
    high_water_ = std::max(high_water_, items_.size());
    lock.unlock();
    not_empty_.notify_one();
    return true;
  }
  // Blocks while empty and open; nullopt once closed and drained.
  std::optional<T> Pop() {
    std::unique_lock lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    std::optional<T> item(std::move(items_.front()));
    items_.pop_front();
    lock.unlock();
    not_full_.notify_one();
    return item;
  }
  void Close() {
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
    }
    not_full_.notify_all();
    not_empty_.notify_all();
  }
  size_t capacity() const { return capacity_; }
  // The most items it ever held at once (never above capacity()).
  size_t high_water() const {
    std::lock_guard lock(mutex_);
    return high_water_;
  }

 private:
  const size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable not_full_, not_empty_;
  std::deque<T> items_;
  size_t high_water_ = 0;
  bool closed_ = false;
};

template <typename T>
class StageWorker {
 public:
  StageWorker(size_t capacity, std::function<Status(T&)> process, std::function<void(T&)> discard = {})
      : queue_(capacity), process_(std::move(process)), discard_(std::move(discard)), thread_([this] { Loop(); }) {}
  StageWorker(const StageWorker&) = delete;
  StageWorker& operator=(const StageWorker&) = delete;
  ~StageWorker() { (void)Finish(); }

  // Blocks while `capacity` items wait. false when the stage has failed (the item then goes to
  // discard) or is finished: the producer should stop.
  bool Push(T item) {
    if (failed()) {
      if (discard_) discard_(item);
      return false;
    }
    return queue_.Push(std::move(item));
  }
  bool failed() const {
    std::lock_guard lock(mutex_);
    return !error_.ok();
  }
  // No more items: waits for the ones queued, then returns the first error (Ok if none).
  Status Finish() {
    queue_.Close();
    if (thread_.joinable()) thread_.join();
    std::lock_guard lock(mutex_);
    return error_;
  }
  const StageQueue<T>& queue() const { return queue_; }

 private:
  void Loop() {
    while (std::optional<T> item = queue_.Pop()) {
      if (failed()) {
        if (discard_) discard_(*item);
        continue;
      }
      Status status = process_(*item);
      if (!status.ok()) {
        std::lock_guard lock(mutex_);
        error_ = std::move(status);
      }
    }
  }

  StageQueue<T> queue_;
  std::function<Status(T&)> process_;
  std::function<void(T&)> discard_;
  mutable std::mutex mutex_;
  Status error_;
  std::thread thread_;  // last: starts after everything it uses
};

}  // namespace occmap
