#include "occmap/pipeline/frame_reader.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <thread>
#include <utility>

namespace occmap {
using Clock = std::chrono::steady_clock;

namespace {
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

// One decoding thread per camera (the reader and cameras - 1 more), at most --threads:
// decoders without frame threads, side by side, cost less CPU per frame than frame-threaded
// ones taking turns (lab bench, 4 x 640x480 H.264 on 2 cores: 2.6 against 3.3 ms of CPU per
// frame set).
FrameReader::FrameReader(std::vector<CameraState>& cams, const RunOptions& options, int num_threads,
                         const FrameSourceOptions& source_options)
    : cams_(cams),
      options_(options),
      decode_ctx_(std::max(1, std::min(static_cast<int>(cams.size()), num_threads))),
      read_got_(cams.size(), 0),
      read_status_(cams.size()),
      next_frame_index_(options.start_frame) {
  live_.resize(cams.size());
  last_live_frame_.assign(cams.size(), Clock::now());
  LiveSourceOptions live_options;
  live_epoch_ = live_options.epoch;
  for (size_t n = 0; n < cams.size(); ++n) {
    CameraState& c = cams[n];
    if (c.cam->source.kind != FrameSourceSpec::Kind::kStream || options.sync != FrameSync::kIndex) continue;
    FrameSourceOptions reopen = source_options;
    reopen.decoder_threads = 1;
    // A stream silent this long is dropped and opened again (a key frame every 2 s or so must
    // arrive within it to open).
    reopen.stream_timeout_ms = std::min(reopen.stream_timeout_ms, 3000);
    live_[n] = std::make_unique<LiveSource>(std::move(c.source), c.cam->source, reopen, live_options);
    ++num_live_;
  }
}

// Live streams: the first new frame of any live camera (1 s at most), then the others' within
// the sync window; frames taken by arrival, the newest of each camera.
bool FrameReader::ReadLive(FrameSet& set) {
  using std::chrono::duration;
  const auto t_start = Clock::now();
  auto stopped = [&] { return options_.stop != nullptr && options_.stop->load(); };
  std::optional<Clock::time_point> window_end;
  size_t got = 0;
  while (got < num_live_) {
    for (size_t n = 0; n < cams_.size(); ++n) {
      if (!live_[n] || cams_[n].present) continue;
      if (live_[n]->Take(set.frames[n], 0)) {
        cams_[n].present = true;
        ++got;
        if (!window_end) {
          window_end = Clock::now() + std::chrono::duration_cast<Clock::duration>(duration<double>(options_.live_sync_window_s));
        }
      }
    }
    if (got == num_live_ || stopped()) break;
    const auto now = Clock::now();
    if (window_end ? now >= *window_end : now - t_start >= std::chrono::seconds(1)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return !stopped();
}

bool FrameReader::Read(FrameSet& set) {
  if (options_.max_frames >= 0 && frames_read_ >= options_.max_frames) return false;
  auto t0 = Clock::now();
  std::vector<std::pair<size_t, Status>> ended;  // camera, status (ok = end of stream)
  for (size_t n = 0; n < cams_.size(); ++n) cams_[n].present = false;
  if (num_live_ > 0 && !ReadLive(set)) {
    stop_reason_ = "stop requested";
    return false;
  }
  // Lost live cameras: silent for camera_lost_after_s (they end the run under kStop only).
  std::vector<char> lost(cams_.size(), 0);
  if (num_live_ > 0) {
    const auto now = Clock::now();
    for (size_t n = 0; n < cams_.size(); ++n) {
      if (!live_[n] || !cams_[n].active) continue;
      if (cams_[n].present) {
        last_live_frame_[n] = now;
        continue;
      }
      const double silent_s = std::chrono::duration<double>(now - last_live_frame_[n]).count();
      if (options_.on_camera_failure == OnCameraFailure::kStop && silent_s > options_.camera_lost_after_s) {
        const std::string error = live_[n]->last_error();
        ended.emplace_back(n, IoError(fmt::format("no frame for {:.0f} s{}", silent_s,
                                                  error.empty() ? "" : fmt::format(" ({})", error))));
        lost[n] = 1;
      }
    }
  }
  // The cameras read by index (all of them, or camera 0 under timestamp sync) decode in
  // parallel, one task per camera on decode_ctx's threads.
  to_read_.clear();
  for (size_t n = 0; n < cams_.size(); ++n) {
    if (cams_[n].active && !live_[n] && !(options_.sync == FrameSync::kTimestamp && n > 0)) to_read_.push_back(n);
  }
  decode_ctx_.pool().Run(static_cast<int>(to_read_.size()), [&](int task, int) {
    const size_t n = to_read_[task];
    auto got = cams_[n].source->Read(set.frames[n]);
    read_got_[n] = got.ok() && *got;
    read_status_[n] = !got.ok() ? got.status() : read_got_[n] ? CheckFrameSize(cams_[n], set.frames[n]) : Status::Ok();
  });
  for (const size_t n : to_read_) {
    if (!read_got_[n] || !read_status_[n].ok()) {
      ended.emplace_back(n, read_status_[n]);
      continue;
    }
    cams_[n].present = true;
  }
  if (options_.sync == FrameSync::kTimestamp && cams_[0].present) {
    const double t_ref = set.frames[0].timestamp_s;
    if (std::isnan(t_ref)) {
      failure_ = InvalidInput(fmt::format("camera {}: {} has no timestamps; synchronise by frame index", cams_[0].cam->id,
                                         cams_[0].source->Describe()));
      return false;
    }
    for (size_t n = 1; n < cams_.size(); ++n) {
      CameraState& c = cams_[n];
      if (!c.active) continue;
      while (true) {
        if (!c.has_lookahead) {
          auto got = c.source->Read(c.lookahead);
          if (!got.ok() || !*got) {
            ended.emplace_back(n, got.ok() ? Status::Ok() : got.status());
            break;
          }
          if (std::isnan(c.lookahead.timestamp_s)) {
            ended.emplace_back(n, InvalidInput(fmt::format("camera {}: {} has no timestamps; synchronise by frame index",
                                                           c.cam->id, c.source->Describe())));
            break;
          }
          c.has_lookahead = true;
        }
        const double dt = c.lookahead.timestamp_s - t_ref;
        if (dt < -options_.sync_tolerance_s) {  // too old: drop it
          c.has_lookahead = false;
          continue;
        }
        if (dt <= options_.sync_tolerance_s) {  // close enough: use it for this instant
          std::swap(set.frames[n], c.lookahead);
          c.has_lookahead = false;
          if (Status s = CheckFrameSize(c, set.frames[n]); !s.ok()) {
            ended.emplace_back(n, s);
            break;
          }
          c.present = true;
        }
        break;  // in the future: no frame of this camera for this instant
      }
    }
  }
  decode_s_.store(decode_s_.load(std::memory_order_relaxed) + Since(t0), std::memory_order_relaxed);
  // A stream read directly (timestamp sync) that ends or fails is lost: it does not come back.
  for (auto& [n, status] : ended) {
    if (cams_[n].cam->source.kind != FrameSourceSpec::Kind::kStream || lost[n]) continue;
    lost[n] = 1;
    if (status.ok()) status = IoError("the stream ended");
  }
  if (!ended.empty()) {
    size_t active_left = 0;
    for (const auto& c : cams_) active_left += c.active;
    bool stop = ended.size() == active_left || options_.on_camera_failure == OnCameraFailure::kStop;
    const bool all_ended = ended.size() == active_left;
    for (const auto& [n, status] : ended) {
      CameraState& c = cams_[n];
      if (!all_ended || !status.ok()) {  // a normal end of every stream is not news
        c.info.ended_at_frame = next_frame_index_;
        c.info.end_reason = status.ok() ? "end of stream" : lost[n] ? "lost: " + status.message() : status.message();
      }
      if (!status.ok() && options_.on_camera_failure == OnCameraFailure::kStop && failure_.ok()) {
        failure_ = lost[n] ? IoError(fmt::format("camera {} lost at frame {}: {}", c.cam->id, next_frame_index_,
                                                 status.message()))
                           : status.WithContext(fmt::format("camera {} at frame {}", c.cam->id, next_frame_index_));
      }
      c.active = false;
      c.present = false;
    }
    if (options_.sync == FrameSync::kTimestamp && !cams_[0].active) stop = true;  // the reference ended
    if (stop) {
      if (all_ended) {
        stop_reason_ = "end of streams";
      } else {
        const size_t first = ended[0].first;
        stop_reason_ = fmt::format("camera {} {} at frame {}", cams_[first].cam->id, lost[first] ? "lost" : "ended",
                                   next_frame_index_);
      }
      return false;
    }
  }
  set.frame_index = next_frame_index_++;
  set.timestamp_s = std::nan("");
  for (size_t n = 0; n < cams_.size(); ++n) {
    set.active[n] = cams_[n].active && cams_[n].present;
    // Stream time from the first camera with a frame (camera 0 may have ended).
    if (set.active[n] && std::isnan(set.timestamp_s)) set.timestamp_s = set.frames[n].timestamp_s;
  }
  set.arrival = Clock::now();
  set.t_unix = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  ++frames_read_;
  return true;
}
}  // namespace occmap
