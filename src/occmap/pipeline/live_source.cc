#include "occmap/pipeline/live_source.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <utility>

namespace occmap {

LiveSource::LiveSource(std::unique_ptr<FrameSource> opened, FrameSourceSpec spec, FrameSourceOptions options,
                       LiveSourceOptions live)
    : spec_(std::move(spec)),
      options_(options),
      live_(live),
      source_(std::move(opened)),
      size_(source_->size()),
      thread_([this] { Loop(); }) {}

LiveSource::~LiveSource() {
  stop_ = true;
  cv_.notify_all();
  thread_.join();
}

std::string LiveSource::last_error() const {
  std::lock_guard lock(mutex_);
  return last_error_;
}

bool LiveSource::Take(Frame& frame, int wait_ms) {
  std::unique_lock lock(mutex_);
  if (!has_new_ && wait_ms > 0) {
    cv_.wait_for(lock, std::chrono::milliseconds(wait_ms), [&] { return has_new_ || stop_.load(); });
  }
  if (!has_new_) return false;
  std::swap(frame, newest_);
  has_new_ = false;
  return true;
}

void LiveSource::Loop() {
  // Reads of this thread are cancelled at once by the destructor.
  options_.cancel = &stop_;
  double backoff_s = live_.backoff_min_s;
  auto fail = [&](const Status& status) {
    connected_ = false;
    source_.reset();
    std::lock_guard lock(mutex_);
    last_error_ = status.message();
  };
  while (!stop_) {
    if (!source_) {
      {  // back off, waking at once for a stop
        std::unique_lock lock(mutex_);
        cv_.wait_for(lock, std::chrono::duration<double>(backoff_s), [&] { return stop_.load(); });
      }
      if (stop_) break;
      backoff_s = std::min(live_.backoff_max_s, 2 * backoff_s);
      auto opened = OpenFrameSource(spec_, options_);
      if (!opened.ok()) {
        fail(opened.status());
        continue;
      }
      if ((*opened)->size() != size_) {
        fail(InvalidInput(fmt::format("{} came back at {}x{}, expected {}x{}", (*opened)->Describe(),
                                      (*opened)->size().width, (*opened)->size().height, size_.width, size_.height)));
        continue;
      }
      source_ = std::move(opened).value();
      ++reconnects_;
    }
    auto got = source_->Read(back_);
    if (!got.ok() || !*got) {
      fail(got.ok() ? IoError(fmt::format("{}: the stream ended", RedactUrl(spec_.location))) : got.status());
      continue;
    }
    if (back_.gray.width() != size_.width || back_.gray.height() != size_.height) {
      fail(InvalidInput(fmt::format("{}: a {}x{} frame, expected {}x{}", RedactUrl(spec_.location), back_.gray.width(),
                                    back_.gray.height(), size_.width, size_.height)));
      continue;
    }
    connected_ = true;
    backoff_s = live_.backoff_min_s;
    {
      std::lock_guard lock(mutex_);
      back_.index = next_index_++;
      back_.timestamp_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - live_.epoch).count();
      if (has_new_) ++dropped_;  // the run did not take the previous one: the newest wins
      std::swap(newest_, back_);
      has_new_ = true;
    }
    cv_.notify_all();
  }
}

}  // namespace occmap
