// FrameReader: the reader stage of a run (pipeline/run.cc). Each Read fills a FrameSet with
// one frame of every active camera for the next instant: by frame index (the cameras decode side
// by side, one task per camera) or by timestamp (camera 0 is the reference; another camera's
// frame within RunOptions::sync_tolerance_s of it is used, older ones are dropped, a later one
// waits for its instant). A camera that ends or fails stops the run (OnCameraFailure::kStop) or
// is left out. Live streams (`stream:` sources) are read by LiveSource (live_source.h): a frame
// set waits up to 1 s for the first new frame of any live camera, then up to
// RunOptions::live_sync_window_s for the others' (their arrival times within that window are
// the same instant); a camera with no new frame in the window, or reconnecting, is left out of
// that set (its cells unseen) and stays active. With every stream down, a frame set with no
// camera comes every second (an all-unseen map). A live camera without a frame for
// RunOptions::camera_lost_after_s is lost: under kStop the run ends ("camera C lost at frame
// F"); under kContinue it stays, reconnecting. A stream read by timestamp (no reconnection)
// that ends is lost at once.
//
//   FrameReader reader(cams, options, ctx.num_threads());
//   while (reader.Read(set)) ...;
//   if (!reader.failure().ok()) ...;  reader.stop_reason();
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/frame_set.h"
#include "occmap/pipeline/live_source.h"
#include "occmap/pipeline/run.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

class FrameReader {
 public:
  // The cameras decode on min(cameras, num_threads) threads (--threads bounds them too).
  // source_options: as the cameras were opened (live streams are opened again with them).
  FrameReader(std::vector<CameraState>& cams, const RunOptions& options, int num_threads,
              const FrameSourceOptions& source_options);
  // The next frame set; false when the run ends (every stream ended, a camera failed or ended
  // under kStop, the frame limit, a failure()). The reader alone touches the cameras' sources,
  // active flags and infos until it returns false for good.
  bool Read(FrameSet& set);
  // The error that stopped the run (a failed camera under kStop, missing timestamps), else Ok.
  const Status& failure() const { return failure_; }
  // "end of streams", "camera C2 ended at frame 40", or "" (the caller names its own reasons).
  const std::string& stop_reason() const { return stop_reason_; }
  // Time spent reading (any thread may ask while the reader runs).
  double decode_s() const { return decode_s_.load(std::memory_order_relaxed); }
  // A live stream's reader (its counters are atomics: any thread may read them), else null.
  const LiveSource* live(size_t camera) const { return live_[camera].get(); }
  // A live frame's timestamp_s counts seconds from this instant (LiveSourceOptions::epoch).
  std::chrono::steady_clock::time_point live_epoch() const { return live_epoch_; }

 private:
  std::vector<CameraState>& cams_;
  const RunOptions& options_;
  Context decode_ctx_;
  // Live streams (FrameSourceSpec::kStream): read on their own threads, newest frame kept,
  // reconnected after a drop; the camera stays active throughout.
  std::vector<std::unique_ptr<LiveSource>> live_;
  size_t num_live_ = 0;
  std::chrono::steady_clock::time_point live_epoch_;
  std::vector<std::chrono::steady_clock::time_point> last_live_frame_;  // per live camera
  bool ReadLive(FrameSet& set);
  std::vector<size_t> to_read_;
  std::vector<char> read_got_;
  std::vector<Status> read_status_;
  Status failure_;
  std::string stop_reason_;
  std::atomic<double> decode_s_{0};
  int64_t next_frame_index_ = 0;
  int64_t frames_read_ = 0;
};

}  // namespace occmap
