// What `occmap run`, `occmap serve` and `occmap edge` share: the default cache folder, the stop
// on SIGINT and SIGTERM, and the run's warnings on stderr.
#pragma once

#include <fmt/core.h>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <utility>

#include "occmap/pipeline/run.h"

namespace occmap {

// The default cache folder: $XDG_CACHE_HOME/occmap, else ~/.cache/occmap, else ./.occmap-cache.
inline std::filesystem::path DefaultCacheDir() {
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg != nullptr && *xdg != '\0') return std::filesystem::path(xdg) / "occmap";
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') return std::filesystem::path(home) / ".cache" / "occmap";
  return ".occmap-cache";
}

// RunOptions::warning of a command: "<program>: warning: <line>" on stderr; on a terminal the
// progress bar's line is cleared first (the bar is drawn again below at its next update).
inline WarningCallback PrintWarnings(std::string program) {
  const bool terminal = ::isatty(STDERR_FILENO) == 1;
  return [program = std::move(program), terminal](const std::string& line) {
    std::fputs(fmt::format("{}{}: warning: {}\n", terminal ? "\r\033[K" : "", program, line).c_str(), stderr);
  };
}

// SIGINT and SIGTERM during `occmap run` and `occmap serve`: blocked in every thread (from before the run starts
// any) and taken by one thread with sigwait, so no handler runs inside the pipeline. The first
// asks the run to stop (RunOptions::stop: the frame sets in flight are finished, every output
// closed, exit 0); the second removes this process's temporary files in the output folder and
// exits at once (128 + the signal), the outputs valid up to their last whole line.
class StopOnSignals {
 public:
  explicit StopOnSignals(std::filesystem::path out_dir) : out_dir_(std::move(out_dir)) {
    sigemptyset(&signals_);
    sigaddset(&signals_, SIGINT);
    sigaddset(&signals_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &signals_, nullptr);
    thread_ = std::thread([this] { Loop(); });
  }
  ~StopOnSignals() {
    done_ = true;
    pthread_kill(thread_.native_handle(), SIGTERM);  // wakes the sigwait; pending on that thread only
    thread_.join();
  }
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;
  const std::atomic<bool>* stop() const { return &stop_; }

 private:
  void Loop() {
    int count = 0;
    while (true) {
      int sig = 0;
      if (sigwait(&signals_, &sig) != 0) continue;
      if (done_) return;
      if (++count == 1) {
        stop_ = true;
        std::fputs("\noccmap: stopping: finishing the frame sets in flight (again to quit at once)\n", stderr);
        continue;
      }
      RemoveOwnTemporaries();
      std::fflush(stderr);
      ::_exit(128 + sig);
    }
  }
  // '.tmp-<name>-<pid>-<n>' files of this process (util/file_util.h, io/video_writer.h).
  void RemoveOwnTemporaries() const {
    const std::string mark = fmt::format("-{}-", ::getpid());
    std::error_code ec;
    for (auto it = std::filesystem::recursive_directory_iterator(out_dir_, ec); !ec && it != std::filesystem::recursive_directory_iterator();
         it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (name.rfind(".tmp-", 0) == 0 && name.find(mark) != std::string::npos) ::unlink(it->path().c_str());
    }
  }

  std::filesystem::path out_dir_;
  sigset_t signals_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> done_{false};
  std::thread thread_;
};

}  // namespace occmap
