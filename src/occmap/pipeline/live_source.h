// LiveSource: a live stream (FrameSourceSpec::kStream) read on a thread of its own, so that a
// run always takes the newest frame and a stream that drops comes back by itself.
//
// The thread reads frames as they arrive and keeps only the newest one not yet taken: a run
// slower than the camera drops to the newest frame instead of falling behind (each frame
// replaced before it was taken counts in dropped()). A read that fails or stalls (no frame
// within FrameSourceOptions::stream_timeout_ms) closes the stream; it is opened again after a
// back-off that doubles from backoff_min_s to backoff_max_s while it keeps failing, and resets
// once a frame arrives. Meanwhile connected() is false and Take() gives nothing, so the run
// leaves the camera out (its cells unseen) and takes it back when frames come again.
//
//   LiveSource live(std::move(opened_source), spec, source_options, {});
//   Frame f;  if (live.Take(f, /*wait_ms=*/200)) ...;  live.dropped();  live.reconnects();
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "occmap/io/frame_source.h"

namespace occmap {

struct LiveSourceOptions {
  // Frame::timestamp_s of a live frame: its arrival, in seconds since this instant (one epoch
  // for all the cameras of a run: their times compare, and do not jump when a stream restarts).
  std::chrono::steady_clock::time_point epoch = std::chrono::steady_clock::now();
  double backoff_min_s = 0.25;  // the first wait before opening a dropped stream again
  double backoff_max_s = 4.0;   // the longest wait while it keeps failing
};

class LiveSource {
 public:
  // `opened`: the stream as first opened (its size is every later frame's); spec and options
  // open it again after a drop.
  LiveSource(std::unique_ptr<FrameSource> opened, FrameSourceSpec spec, FrameSourceOptions options,
             LiveSourceOptions live = {});
  ~LiveSource();  // stops the thread (a blocked read is cancelled)
  LiveSource(const LiveSource&) = delete;
  LiveSource& operator=(const LiveSource&) = delete;

  // The newest frame not taken yet, waiting up to wait_ms for one (0: no wait); false when none
  // came. Frame::index counts the frames taken and dropped over every connection.
  bool Take(Frame& frame, int wait_ms);
  bool connected() const { return connected_.load(); }
  int64_t dropped() const { return dropped_.load(); }
  int64_t reconnects() const { return reconnects_.load(); }
  std::string last_error() const;

 private:
  void Loop();

  FrameSourceSpec spec_;
  FrameSourceOptions options_;
  LiveSourceOptions live_;
  std::unique_ptr<FrameSource> source_;  // the thread's; null while reconnecting
  ImageSize size_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> connected_{true};
  std::atomic<int64_t> dropped_{0}, reconnects_{0};
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  Frame newest_, back_;  // newest_: the mutex's; back_: the thread's
  bool has_new_ = false;
  int64_t next_index_ = 0;
  std::string last_error_;
  std::thread thread_;  // last: starts after everything it uses
};

}  // namespace occmap
