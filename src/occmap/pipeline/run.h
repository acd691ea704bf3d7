// The on-line system (paper sections 2.2 and 2.5) over a site's frame sources: per frame,
// difference each camera's image against its background (equation 4, or take a foreground
// mask from another tool), fuse the change masks through the lookup tables into the tri-state
// occupancy map (equation 5), find blobs, and write the outputs.
//
// A run is a pipeline of stages on their own threads joined by bounded queues, each stage a
// class in its own file with one input and one output:
//   FrameReader (frame_reader.h)        sources (camera_inputs.h) -> a FrameSet's frames, in a
//                                       ring of four frame sets
//   FusionStage (fusion_stage.h)        FrameSet -> its changes and fused map (and the people's
//                                       column map), the adaptive backgrounds updated; on the
//                                       calling thread, with ctx's pool
//   DetectTrackStage (detect_track_stage.h)  fused FrameSet -> FrameRecord: detections, tracks,
//                                       zone and line events, pictures
//   SinkStage (sink_stage.h)            FrameRecord -> every FrameSink (frame_sink.h), the run's
//                                       files first (output_files.h); summary.json (summary_file.h)
// How changes are computed and fused is chosen once (RunFusionPlan, fusion_path.h). The stages
// overlap, so over video files the run is limited by decoding, and memory stays flat.
//
// Outputs in out_dir (RunOptions::output_mode; a run that stops early keeps what it finished):
//   detections.jsonl   one line per frame: {"frame", "time_s", "blobs": [{x_m, y_m, area_m2, ...}]}
//   tracks.jsonl       one line per frame: {"frame", "time_s", "tracks": [{id, x_m, y_m, vx_mps, ...}]}
//   tracks_mot.csv     the tracks as MOTChallenge ground-plane rows
//   events.jsonl       zone events (enter, leave, dwell, count) and line crossings (in, out), when the
//                      site has zones or counting lines
//   summary.json       frames, timing, settings, cameras and how each ended
//   occupancy.mp4      the map per frame (white free, black occupied, grey unseen), and/or
//   occupancy/NNNNNN.png
//   mosaic.mp4, mosaic.png   camera tiles with the change overlay beside the map with the
//                      cameras and blobs (like the paper's figures 6 and 8); the PNG is the
//                      frame with the most blobs
//   backgrounds/<camera>.png  the background each camera used (adaptive: as learned or given)
//   changes/<camera>/NNNNNN.png  with change_pngs: changed pixels 255, before the tolerance
//
//   RunOptions options;  options.out_dir = "out";
//   OCCMAP_ASSIGN_OR_RETURN(RunSummary summary, RunSite(site, options, ctx, on_progress));
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/pipeline/frame_sink.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/output_files.h"
#include "occmap/site/site.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

enum class FrameSync { kIndex, kTimestamp };
enum class OnCameraFailure { kStop, kContinue };

// A line for whoever watches the run (the command line prints it on stderr): something went
// wrong that does not stop the run, and is said once, not per frame set. Called on a stage's
// thread.
using WarningCallback = std::function<void(const std::string& line)>;

// A cache entry that could not be written at start-up: said once ("could not write the
// <what> <path>: <error>; going on without it") and the caller goes on. A cache is a head
// start, never an output. `what`: "background cache", "table cache".
void WarnCacheNotWritten(const WarningCallback& warning, std::string_view what, const std::filesystem::path& path,
                         std::string_view error);

struct RunOptions {
  std::filesystem::path out_dir = "occmap-out";
  std::filesystem::path cache_dir;  // lookup tables and estimated backgrounds; empty: none
  int64_t start_frame = 0;          // first frame (of every source) to process
  int64_t max_frames = -1;          // -1: until a source ends
  // Video files and image sequences are read again from their start when they end (io's
  // LoopFrameSource): the run goes on until max_frames or a stop.
  bool loop = false;
  FrameSync sync = FrameSync::kIndex;
  double sync_tolerance_s = 0.020;  // timestamp sync: largest accepted offset from camera 0
  // Live streams (`stream:` sources, pipeline/frame_reader.h): the frames of one frame set
  // arrive within this window after its first one (a frame interval at 10 fps).
  double live_sync_window_s = 0.1;
  // Every line of detections.jsonl, tracks.jsonl and events.jsonl carries "t_unix": the wall-clock
  // time its frame set arrived. Off: the lines depend on the inputs alone (runs compare).
  bool wall_clock_times = true;
  // A camera whose stream ends or whose frame is unreadable: stop the run (default), or go on
  // without it, marking the cells only it could see as unseen.
  OnCameraFailure on_camera_failure = OnCameraFailure::kStop;
  // A live stream without a frame this long (reconnecting all the while) is lost: under kStop
  // that ends the run with an error naming the camera; under kContinue it keeps reconnecting.
  double camera_lost_after_s = 30;
  bool occupancy_video = true;
  bool occupancy_pngs = false;
  bool change_pngs = false;  // changes/<camera>/NNNNNN.png: each camera's changed pixels (255), before the tolerance
  bool mosaic_video = true;
  bool mosaic_picture = true;  // mosaic.png (a run without frames, `occmap fuse`, has none to draw)
  // Every FrameRecord carries each camera's frame and change mask (frames_gray, frames_rgb,
  // change_masks), for a sink that shows them (`occmap serve`). Costs a copy per frame set.
  bool sink_frames = false;
  // Learned backgrounds of file sources are settled before the run (site.backgrounds.settle,
  // pipeline/settle_backgrounds.h); an edge process settles only when it reads every camera of
  // the site (it fuses the window itself then).
  bool settle_learned_backgrounds = true;
  int background_frames = 25;  // K of the median background, when a camera has none
  int background_step = 4;     // take every n-th frame for the median
  bool track = true;  // run the site's tracker and write tracks.jsonl, tracks_mot.csv, events.jsonl
  int mosaic_width_px = 1280;
  // How the files are written (pipeline/output_files.h): kLive appends whole lines per frame
  // set and keeps what was written whatever stops the run; kAtomic commits them at the end.
  OutputMode output_mode = OutputMode::kLive;
  // More sinks (pipeline/frame_sink.h): each gets every frame set after the run's files, on the
  // writer thread.
  std::vector<std::shared_ptr<FrameSink>> sinks;
  // summary.json is rewritten (atomically) with the running figures this often; 0: only at the end.
  double summary_every_s = 5;
  // When set and true, the run stops reading: the frame sets in flight are finished, every
  // output is closed, and RunSite returns the summary (stop_reason "stop requested"). Set it
  // from a signal handler (`occmap run` does, for SIGINT and SIGTERM).
  const std::atomic<bool>* stop = nullptr;
  // Warnings (a live camera's cached background that cannot be written, and when it can
  // again); empty: said to nobody (summary.json counts them all the same).
  WarningCallback warning;
  Status Validate() const;
};

struct RunProgress {
  int64_t frames_done = 0;
  std::optional<int64_t> frames_total;
  double elapsed_s = 0;
};
using ProgressCallback = std::function<void(const RunProgress&)>;

struct CameraRunInfo {
  std::string id;
  std::string source;      // FrameSource::Describe()
  std::string background;  // "given: <path>", "estimated from K frames", "reused: <path>", "none (masks)"
  std::optional<int64_t> ended_at_frame;  // when its stream ended or failed before the run did
  std::string end_reason;
  // occmap fuse: frame sets fused without this camera (late, lost or silent), and its messages
  // dropped: those that came after their frame set was fused, copies of one pending or fused
  // (replays, redeliveries), and those refused (damaged, for another site, broken rows).
  std::optional<int64_t> left_out, late_messages, duplicate_messages, refused_messages;
  // A live camera whose cached background is refreshed: what the refreshes did, the stop's too.
  std::optional<BackgroundCacheFigures> background_cache{};
};

struct RunSummary {
  int64_t frames = 0;
  double seconds = 0;            // the whole call: start-up, frames, finalising the outputs
  double frames_per_second = 0;  // frames / seconds
  // Start-up: from the call until the first frame set reaches the fusion (sources opened,
  // backgrounds, tables, the first frames decoded).
  double startup_s = 0;
  // The steady-state rate: frames completed after the first 10 (warm-up), over the time
  // between the 11th and the last completion (short runs: from the first). 0 below 2 frames.
  int64_t steady_frames = 0;
  double steady_seconds = 0;
  double steady_fps = 0;
  // Time spent inside each stage (wall time of that stage's own thread; the stages overlap, so
  // they do not add up to `seconds`). decode: the reader; detect and fuse: the fusion stage;
  // blobs, track: the post stage; output: formatting (post) and writing (writer).
  double decode_s = 0, detect_s = 0, fuse_s = 0, blobs_s = 0, track_s = 0, output_s = 0;
  double background_s = 0;  // the adaptive backgrounds' update (the fusion stage)
  double people_s = 0;      // column fusion and the explanation of the views (the fusion stage)
  double occluders_s = 0;   // learning static occluders (`people.occluders.learn`; the fusion stage)
  // Learned backgrounds checked across cameras (pipeline/background_maintenance.h).
  int64_t consensus_pixels_checked = 0, consensus_pixels_swapped = 0, consensus_pixels_settled = 0;
  // The settling pass over the learning window (0: none), and its time.
  int64_t settle_frame_sets = 0;
  double settle_s = 0;
  // Frame set arrival (frames decoded) to every sink done (the files written), over the run.
  LatencyFigures latency;
  int max_queued_outputs = 0;  // the most frames whose outputs waited for the writer at once
  std::string stop_reason;  // "end of streams", "frame limit", "camera C2 ended", ...
  std::vector<CameraRunInfo> cameras;
  std::string fusion_path;  // how changes were computed and fused (FusionPlan::Describe)
  std::string lut_cache;    // ToString(LutCacheOutcome)
  double lut_seconds = 0;
  int64_t blobs_total = 0;          // detections over all frame sets
  int64_t blobs_max_per_frame = 0;  // the most in one frame set
  int64_t tracks = 0;                // distinct reported track ids
  int64_t zone_events = 0;
  std::vector<std::string> outputs;  // files written
};

// The FFmpeg threads of each camera's decoder in a run: the cameras decode side by side, one
// thread per camera, so each gets its share of num_threads, at least one.
int DecoderThreadsPerCamera(int num_threads, int num_cameras);

// The one choice of how RunSite computes and fuses changes for these options (the bench's
// end-to-end pass reports it): ChooseFusionPath with the change buffer needed by the outputs
// that draw changes (the mosaic video, change PNGs, frames for the sinks).
FusionPlan RunFusionPlan(const Site& site, const RunOptions& options);

// Runs the site; on a failed frame with OnCameraFailure::kStop, the outputs of the frames
// processed so far are written, then the error is returned.
Result<RunSummary> RunSite(const Site& site, const RunOptions& options, Context& ctx,
                           const ProgressCallback& progress = {});

}  // namespace occmap
