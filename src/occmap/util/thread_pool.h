// Context and ThreadPool: the one place that owns worker threads (Ceres' ContextImpl idea).
//
// Threads are created once, with the Context, and reused: no thread creation per frame.
// ParallelFor splits [begin, end) into contiguous chunks, one task per chunk, runs them on the
// pool plus the calling thread, and returns when all are done. The functor gets
// (chunk_begin, chunk_end, worker_index) with worker_index < ctx.num_threads(), so each worker
// can write its own partial result without locks.
//
//   Context ctx(/*num_threads=*/0);  // 0 = all hardware threads
//   ParallelFor(ctx, 0, n, [&](int64_t b, int64_t e, int worker) { ... });
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace occmap {

class ThreadPool {
 public:
  explicit ThreadPool(int num_workers);  // background workers; the caller also works
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int num_workers() const { return static_cast<int>(workers_.size()); }

  // Runs fn(task_index) for task_index in [0, num_tasks), using the caller as one worker.
  // fn receives the index of the thread that runs it (0 = caller, 1.. = pool workers).
  void Run(int num_tasks, const std::function<void(int task, int thread)>& fn);

  // Inside a Burst (several Runs microseconds apart, e.g. the phases of one frame's fusion),
  // idle workers and the waiting caller spin for up to kSpin before they sleep, so that the
  // next Run needs no futex wake-up; outside one they sleep at once and leave the cores to
  // other work (decoders on a loaded machine: spinning there costs them CPU).
  class Burst {
   public:
    explicit Burst(ThreadPool& pool) : pool_(pool) { pool_.bursts_.fetch_add(1); }
    ~Burst() { pool_.bursts_.fetch_sub(1); }
    Burst(const Burst&) = delete;
    Burst& operator=(const Burst&) = delete;

   private:
    ThreadPool& pool_;
  };
  static constexpr std::chrono::microseconds kSpin{30};

 private:
  void WorkerLoop(int thread_index);

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  const std::function<void(int, int)>* job_ = nullptr;
  int num_tasks_ = 0;
  int next_task_ = 0;
  std::atomic<int> pending_{0};
  std::atomic<uint64_t> generation_{0};
  std::atomic<bool> stop_{false};
  std::atomic<int> bursts_{0};
};

class Context {
 public:
  // num_threads <= 0 means all hardware threads.
  explicit Context(int num_threads = 0);
  int num_threads() const { return num_threads_; }
  ThreadPool& pool() { return pool_; }

 private:
  int num_threads_;
  ThreadPool pool_;
};

// fn(chunk_begin, chunk_end, thread_index); thread_index in [0, ctx.num_threads()).
void ParallelFor(Context& ctx, int64_t begin, int64_t end,
                 const std::function<void(int64_t, int64_t, int)>& fn,
                 int64_t min_chunk = 1);

}  // namespace occmap
