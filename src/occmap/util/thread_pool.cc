#include "occmap/util/thread_pool.h"

#include <algorithm>

#include "occmap/util/simd.h"

namespace occmap {
namespace {

// Spins (with the CPU's spin-wait hint) while `bursts` > 0, until done() or kSpin has passed; true when done().
template <typename Done>
bool SpinUntil(const std::atomic<int>& bursts, Done done) {
  if (bursts.load(std::memory_order_relaxed) == 0) return done();
  const auto until = std::chrono::steady_clock::now() + ThreadPool::kSpin;
  while (true) {
    for (int i = 0; i < 64; ++i) {
      if (done()) return true;
      CpuRelax();
    }
    if (bursts.load(std::memory_order_relaxed) == 0 || std::chrono::steady_clock::now() >= until) return done();
  }
}

}  // namespace

ThreadPool::ThreadPool(int num_workers) {
  for (int i = 0; i < num_workers; ++i) workers_.emplace_back([this, i] { WorkerLoop(i + 1); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& t : workers_) t.join();
}

void ThreadPool::Run(int num_tasks, const std::function<void(int, int)>& fn) {
  if (num_tasks <= 0) return;
  if (workers_.empty() || num_tasks == 1) {
    for (int t = 0; t < num_tasks; ++t) fn(t, 0);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    job_ = &fn;
    num_tasks_ = num_tasks;
    next_task_ = 0;
    pending_ = num_tasks;
    ++generation_;
  }
  wake_.notify_all();
  // The caller works too.
  while (true) {
    int task;
    {
      std::lock_guard lock(mutex_);
      if (next_task_ >= num_tasks_) break;
      task = next_task_++;
    }
    fn(task, 0);
    std::lock_guard lock(mutex_);
    if (--pending_ == 0) done_.notify_all();
  }
  SpinUntil(bursts_, [this] { return pending_.load(std::memory_order_acquire) == 0; });
  std::unique_lock lock(mutex_);
  done_.wait(lock, [this] { return pending_ == 0; });
  job_ = nullptr;
}

void ThreadPool::WorkerLoop(int thread_index) {
  uint64_t seen = 0;
  std::unique_lock lock(mutex_);
  while (true) {
    if (!stop_ && generation_ == seen) {
      lock.unlock();
      SpinUntil(bursts_, [&] { return stop_.load(std::memory_order_relaxed) || generation_.load(std::memory_order_acquire) != seen; });
      lock.lock();
    }
    wake_.wait(lock, [&] { return stop_ || (generation_ != seen && job_ != nullptr); });
    if (stop_) return;
    seen = generation_;
    while (job_ != nullptr && next_task_ < num_tasks_) {
      const int task = next_task_++;
      const auto* job = job_;
      lock.unlock();
      (*job)(task, thread_index);
      lock.lock();
      if (--pending_ == 0) done_.notify_all();
    }
  }
}

Context::Context(int num_threads)
    : num_threads_(num_threads > 0
                       ? num_threads
                       : std::max(1, static_cast<int>(std::thread::hardware_concurrency()))),
      pool_(num_threads_ - 1) {}

void ParallelFor(Context& ctx, int64_t begin, int64_t end,
                 const std::function<void(int64_t, int64_t, int)>& fn, int64_t min_chunk) {
  const int64_t n = end - begin;
  if (n <= 0) return;
  const int64_t max_tasks = std::max<int64_t>(1, n / std::max<int64_t>(1, min_chunk));
  const int num_tasks = static_cast<int>(std::min<int64_t>(ctx.num_threads(), max_tasks));
  if (num_tasks == 1) {
    fn(begin, end, 0);
    return;
  }
  ctx.pool().Run(num_tasks, [&](int task, int thread) {
    const int64_t b = begin + n * task / num_tasks;
    const int64_t e = begin + n * (task + 1) / num_tasks;
    fn(b, e, thread);
  });
}

}  // namespace occmap
