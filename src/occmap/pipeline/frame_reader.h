// FrameReader: the reader stage of a run (pipeline/run.cc). Each Read fills a FrameSet with
// one frame of every active camera for the next instant: by frame index (the cameras decode side
// by side, one task per camera) or by timestamp (camera 0 is the reference; another camera's
// frame within RunOptions::sync_tolerance_s of it is used, older ones are dropped, a later one
// waits for its instant). A camera that ends or fails stops the run (OnCameraFailure::kStop) or
// is left out.
//
//   FrameReader reader(cams, options, ctx.num_threads());
//   while (reader.Read(set)) ...;
//   if (!reader.failure().ok()) ...;  reader.stop_reason();
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/frame_set.h"
#include "occmap/pipeline/run.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

class FrameReader {
 public:
  // The cameras decode on min(cameras, num_threads) threads (--threads bounds them too).
  FrameReader(std::vector<CameraState>& cams, const RunOptions& options, int num_threads);
  // The next frame set; false when the run ends (every stream ended, a camera failed or ended
  // under kStop, the frame limit, a failure()). The reader alone touches the cameras' sources,
  // active flags and infos until it returns false for good.
  bool Read(FrameSet& set);
  // The error that stopped the run (a failed camera under kStop, missing timestamps), else Ok.
  const Status& failure() const { return failure_; }
  // "end of streams", "camera C2 ended at frame 40", or "" (the caller names its own reasons).
  const std::string& stop_reason() const { return stop_reason_; }
  double decode_s() const { return decode_s_; }  // time spent reading

 private:
  std::vector<CameraState>& cams_;
  const RunOptions& options_;
  Context decode_ctx_;
  std::vector<size_t> to_read_;
  std::vector<char> read_got_;
  std::vector<Status> read_status_;
  Status failure_;
  std::string stop_reason_;
  double decode_s_ = 0;
  int64_t next_frame_index_ = 0;
  int64_t frames_read_ = 0;
};

}  // namespace occmap
