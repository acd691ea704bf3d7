// FrameSink: where a run's per-frame results go. The run (pipeline/run.h) calls every sink once
// per frame set, in frame order, on its writer thread, after the frame set is fused, detected
// and tracked; the files of out_dir (detections.jsonl, tracks.jsonl, ...: pipeline/output_files.h)
// are one sink, and a caller adds its own (an MQTT publisher, a robot map writer) through
// RunOptions::sinks.
//
// Lifetime, all on the writer thread (one thread: a sink needs no lock for its own state):
//   Open(start)                   once, before the first frame set (out_dir exists by then)
//   Consume(record, stats)        per frame set, in increasing frame order; the record and the
//                                 stats are valid only during the call (copy what is kept)
//   Close(stats)                  once, when the run ends for any reason (end of streams, a
//                                 frame limit, a stop request, a failure), after the last Consume
// A sink's error (a Status that is not ok) stops the run: the other sinks still get Close, and
// the run returns the first error. A sink must not block for long: the writer queue holds a few
// frame sets, then the run waits for it (a network sink keeps its own queue or drops).
//
//   class CountSink : public FrameSink {
//     Status Consume(const FrameRecord& r, const RunStats&) override { n_ += r.detections.size(); return Status::Ok(); }
//   };
//   options.sinks.push_back(std::make_shared<CountSink>());
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/objects/detection.h"
#include "occmap/site/site.h"
#include "occmap/track/count_lines.h"
#include "occmap/track/track.h"
#include "occmap/track/zones.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

class GroundLut;

// What a sink learns when the run starts.
struct SinkStart {
  const Site* site = nullptr;         // the site as run (grid, zones, cameras); outlives the sink calls
  const GroundLut* lut = nullptr;     // the run's tables (view_count: the cameras that see each cell)
  std::filesystem::path out_dir;      // the run's output folder
  double fps = 10;                    // frame rate of the run (camera 0's, 10 without one)
  std::vector<std::string> camera_ids;
  bool track = true;                  // the tracker runs (tracks and events are filled)
  bool wall_clock_times = true;       // lines carry "t_unix" (RunOptions::wall_clock_times)
};

// What refreshing a live camera's cached background did (pipeline/camera_inputs.h,
// BackgroundCacheRefresh): summary.json's cameras[].background_cache, the edge's last lines.
// A write that fails leaves the entry as it was and never stops the run (a cache is a head
// start for the next one, not an output).
struct BackgroundCacheFigures {
  std::string entry;        // the entry's `-y` plane
  int64_t refreshes = 0;    // writes of the entry that worked (every refresh_cache_s, the stop)
  int64_t failures = 0;     // writes that failed
  std::optional<int64_t> last_refresh_frame{};  // the frame set of the last write that worked
  std::string last_error;   // why the last write failed; empty once one works again
};

// One camera's running figures.
struct CameraStats {
  std::string id;
  bool active = true;        // its stream has not ended or failed (a live stream that reconnects stays active)
  bool connected = true;     // frames arrive (false while a live stream is reconnecting)
  int64_t frames = 0;        // frames used in frame sets
  int64_t dropped = 0;       // frames a live stream's reader dropped to stay on the newest
  int64_t reconnects = 0;    // times a live stream was opened again after dropping
  // Mean over its pixels of the stream seconds since each was last set: an adaptive background
  // as it updates (sampled about once a second), a fixed one (given or estimated at the start)
  // ages with the run. NaN for a camera that gives masks.
  double background_age_s = std::numeric_limits<double>::quiet_NaN();
  // A live camera whose cached background is refreshed (none for the others).
  std::optional<BackgroundCacheFigures> background_cache{};
};

// Seconds spent inside each stage so far (as RunSummary's, pipeline/run.h; the stages overlap,
// so they do not add up to the run's time).
struct StageSeconds {
  double decode = 0, detect = 0, fuse = 0, blobs = 0, track = 0, output = 0, background = 0, people = 0;
  double tables = 0;  // loading or building the tables, before the first frame set
};

// Latency from a frame set's arrival (its frames decoded) to its outputs written by every sink
// before: percentiles over the run so far, in milliseconds (0 before the first frame set).
struct LatencyFigures {
  int64_t count = 0;
  double p50_ms = 0, p95_ms = 0, p99_ms = 0, max_ms = 0;
  double sum_ms = 0;  // of every frame set's latency
};

// The run's figures so far, as of the frame set being consumed (or the end, for Close).
struct RunStats {
  int64_t frames = 0;          // frame sets done, this one included
  double elapsed_s = 0;        // since the run started
  double frames_per_second = 0;  // the steady-state rate so far (0 before 2 frame sets)
  std::vector<CameraStats> cameras;
  LatencyFigures latency;
  StageSeconds stages;
  int64_t tracks = 0;          // distinct reported track ids so far
  int64_t zone_events = 0;     // events so far
  std::vector<LineCounts> lines;  // per counting line (site.tracking.lines): crossings so far
  std::string stop_reason;     // Close only: "end of streams", "frame limit", "stop requested", ...
};

// One frame set's results. Owned by the run; valid during Consume only.
struct FrameRecord {
  int64_t frame = 0;
  double time_s = 0;    // stream time: camera timestamps (the first camera with a frame), else frame / fps
  double t_unix = 0;    // wall-clock time the frame set arrived (seconds since 1970, UTC)
  std::chrono::steady_clock::time_point arrival;  // the same instant on the steady clock (latency)
  std::vector<bool> active;              // per camera: its frame took part
  OccupancyMap map;                      // the fused tri-state map
  std::vector<Detection> detections;     // the frame's objects
  std::vector<Track> tracks;             // the reported tracks (empty without tracking)
  ZoneFrame zones;                       // zone events and per-zone counts (empty without zones)
  LineFrame lines;                       // line crossings and per-line counts (empty without lines)
  // The lines of tracks.jsonl and events.jsonl for this frame set (no newlines; "t_unix" first
  // with RunOptions::wall_clock_times), made once by the run (MakeJsonLines) for every sink.
  std::string tracks_line;
  std::vector<std::string> event_lines;  // zone events, then line crossings
  // Pictures drawn by the run when an output asks for them, else empty.
  Image<Rgb8> mosaic;                          // the mosaic (RunOptions::mosaic_video)
  std::vector<Image<uint8_t>> change_pictures;  // per camera, 255 changed (RunOptions::change_pngs)
  // Per camera with RunOptions::sink_frames (empty images for a camera not in this set): the
  // frame as decoded (grey; colour only when the run reads colour) and its changes after the
  // tolerance (non-zero changed, at the frame's size).
  std::vector<Image<uint8_t>> frames_gray;
  std::vector<Image<Rgb8>> frames_rgb;
  std::vector<Image<uint8_t>> change_masks;
};

class FrameSink {
 public:
  virtual ~FrameSink() = default;
  virtual Status Open(const SinkStart& start) {
    (void)start;
    return Status::Ok();
  }
  virtual Status Consume(const FrameRecord& record, const RunStats& stats) = 0;
  virtual Status Close(const RunStats& stats) {
    (void)stats;
    return Status::Ok();
  }
};

}  // namespace occmap
