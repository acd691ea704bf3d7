// SinkStage: the last stage of a run (pipeline/run.h), on the writer thread. Input: each frame
// set's FrameRecord (detect_track_stage.h), in frame order. Output: every sink's (frame_sink.h:
// the run's files first, then the caller's), the running figures they see (RunStats), and the
// running summary.json (summary_file.h) every RunOptions::summary_every_s. The one place the
// outputs are touched until the run ends.
//
//   SinkStage sinks(sinks, camera_ids, options, &summary_file, t_start, figures);
//   OCCMAP_RETURN_IF_ERROR(sinks.Open(start));
//   OCCMAP_RETURN_IF_ERROR(sinks.Consume(record));   // per frame set
//   OCCMAP_RETURN_IF_ERROR(sinks.Close(stop_reason));
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "occmap/pipeline/frame_sink.h"
#include "occmap/pipeline/latency.h"
#include "occmap/pipeline/output_files.h"
#include "occmap/pipeline/run.h"
#include "occmap/pipeline/summary_file.h"

namespace occmap {

class SinkStage {
 public:
  using Clock = std::chrono::steady_clock;
  // The other stages' running figures, asked for per frame set: stats.stages (the sink stage
  // adds its own seconds to `output`) and per camera its connection, drops, reconnects, whether
  // it is active and its background's age. The record is the frame set being consumed.
  using RunningFigures = std::function<void(const FrameRecord& record, RunStats& stats)>;

  // summary_file: the running summary's (null: none).
  SinkStage(std::vector<std::shared_ptr<FrameSink>> sinks, std::vector<std::string> camera_ids,
            const RunOptions& options, const SummaryFile* summary_file, Clock::time_point t_start,
            RunningFigures running_figures);
  ~SinkStage();  // closes what is still open (errors dropped: Close reports them)
  SinkStage(const SinkStage&) = delete;
  SinkStage& operator=(const SinkStage&) = delete;

  // Opens every sink in order; those opened get Close whatever happens next.
  Status Open(const SinkStart& start);
  Status Consume(FrameRecord& record);
  // Closes every opened sink once (later calls return Ok); the first error.
  Status Close(const std::string& stop_reason);
  const RunStats& stats() const { return stats_; }
  double write_s() const { return write_s_; }
  int64_t blobs_total() const { return blobs_total_; }
  int64_t blobs_max_per_frame() const { return blobs_max_; }

 private:
  std::vector<std::shared_ptr<FrameSink>> sinks_;
  const RunOptions& options_;
  const SummaryFile* summary_file_;
  const Clock::time_point t_start_;
  RunningFigures running_figures_;
  size_t open_ = 0;
  bool closed_ = false;
  RunStats stats_;
  LatencyHistogram latency_;
  double write_s_ = 0;
  // Distinct track ids in constant memory: the trackers give ids in increasing order, at
  // confirmation, when a track is reported at once, so an id above every earlier one is new.
  int64_t max_track_id_ = 0;
  int64_t blobs_total_ = 0, blobs_max_ = 0;
  Clock::time_point t_first_written_, t_summary_written_;
};

// The run's own files (output_files.h) as RunOptions asks for them.
OutputFilesOptions RunFileOptions(const Site& site, const RunOptions& options, ImageSize mosaic_size);
// The run's files first, then the caller's sinks (RunOptions::sinks).
std::vector<std::shared_ptr<FrameSink>> RunSinks(std::shared_ptr<FrameSink> files, const RunOptions& options);
// What every sink learns at the start of a run over these cameras.
SinkStart RunSinkStart(const Site& site, const GroundLut& lut, const RunOptions& options, double fps,
                       const std::vector<std::string>& camera_ids);

}  // namespace occmap
