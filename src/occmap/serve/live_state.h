// LiveState: the latest results of a run, for `occmap serve`'s pages and API. LiveStateSink is
// the run's FrameSink that fills it: per frame set it copies what the pages show (map,
// detections, tracks, zone and line counts, the running figures, each camera's frame and change
// mask) into a new immutable snapshot and swaps it in; readers (the HTTP threads) take the
// current snapshot without copying and never block the run. Nothing queues: a reader that is
// slower than the run sees only the newest snapshot (drop to newest).
//
//   auto state = std::make_shared<LiveState>();
//   options.sink_frames = true;  options.sinks.push_back(std::make_shared<LiveStateSink>(state));
//   std::shared_ptr<const LiveSnapshot> s = state->Latest();   // any thread
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "occmap/geometry/camera_model.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/pipeline/frame_sink.h"
#include "occmap/pipeline/mqtt_sink.h"

namespace occmap {

// The cameras that see each cell of the grid, from the run's tables (as visibility.png).
struct LiveCoverage {
  int64_t version = 0;  // increases with every run that opens (a saved site rebuilds the tables)
  FloorGrid grid;
  int num_cameras = 0;
  std::vector<uint8_t> view_count;  // per cell, row-major from the grid's origin
};

// A track as a camera sees it: the box around a column of its footprint's width and its class's
// height (person 1.7 m, anything else 1.0 m), pixels clipped to the image; drawn on the camera's
// tile with "id class".
struct TrackBox {
  int64_t id = 0;
  std::string object_class;
  bool coasting = false;
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // inclusive pixel bounds
};
// The boxes of the tracks the camera sees (every corner in front of it, some of the box in the
// image).
std::vector<TrackBox> TrackBoxesInCamera(const CameraModel& camera, const std::vector<Track>& tracks);

inline constexpr size_t kRecentEvents = 100;  // events.jsonl lines a snapshot keeps for the page

struct LiveSnapshot {
  int64_t version = 0;   // increases with every snapshot (also across restarts of the run)
  int64_t frame = -1;    // the run's frame index; -1 before the first frame set
  double time_s = 0, t_unix = 0;
  OccupancyMap map;
  std::vector<Detection> detections;
  std::vector<Track> tracks;
  std::vector<std::string> zone_names;
  std::vector<int> zone_counts;        // per zone: tracks inside (0 without tracking)
  std::vector<std::string> line_names;
  std::vector<LineCounts> line_counts;  // per line: crossings so far
  RunStats stats;
  std::vector<std::string> camera_ids;
  // Per camera: the latest frame seen (kept when the camera is missing from a frame set).
  std::vector<Image<uint8_t>> frames_gray;
  std::vector<Image<Rgb8>> frames_rgb;  // empty unless the run reads colour
  std::vector<Image<uint8_t>> change_masks;
  // Per camera: the tracks' boxes in its picture (cameras of the site the run has).
  std::vector<std::vector<TrackBox>> track_boxes;
  // The latest events (events.jsonl's lines: zone entries and exits, line crossings), oldest
  // first, at most kRecentEvents; events_total counts every event of the session so far, so that
  // a reader who missed snapshots knows it.
  std::vector<std::string> recent_events;
  int64_t events_total = 0;
  // The MQTT link's figures and state as of this frame set; none when the run has no MQTT.
  std::optional<MqttCounters> mqtt;
};

class LiveState {
 public:
  LiveState();
  std::shared_ptr<const LiveSnapshot> Latest() const;
  // The latest snapshot once its version exceeds `version`, or after `timeout`, or Wake().
  std::shared_ptr<const LiveSnapshot> WaitNewer(int64_t version, std::chrono::milliseconds timeout) const;
  void Publish(std::shared_ptr<const LiveSnapshot> snapshot);
  // Wakes every WaitNewer (the server stopping, the site changed).
  void Wake();

  // The run's life: running between Open and Close; `ended` says why it stopped.
  void SetRunning(bool running, const std::string& ended = "");
  bool running() const;
  // Between the run's start and its first frame set's sinks opening (sources, backgrounds and
  // tables take a while): cleared by SetRunning.
  void SetStarting();
  bool starting() const;
  std::string ended() const;
  double uptime_s() const;
  int64_t next_version();
  // The run's coverage, null before its tables are ready.
  std::shared_ptr<const LiveCoverage> coverage() const;
  void SetCoverage(std::shared_ptr<LiveCoverage> coverage);
  // The run's frame rate (SinkStart::fps), 0 before it opens.
  void SetFps(double fps) { fps_ = fps; }
  double fps() const { return fps_.load(); }
  // The run's MQTT sink, whose counters each snapshot carries (set before the run starts).
  void SetMqtt(std::shared_ptr<const MqttSink> mqtt);
  std::shared_ptr<const MqttSink> mqtt() const;

 private:
  mutable std::mutex mu_;
  mutable std::condition_variable cv_;
  std::shared_ptr<const LiveSnapshot> latest_;
  std::shared_ptr<const LiveCoverage> coverage_;
  std::shared_ptr<const MqttSink> mqtt_;
  int64_t coverage_version_ = 0;
  bool running_ = false;
  bool starting_ = false;
  std::string ended_;
  int64_t version_ = 0;
  int64_t wakes_ = 0;
  std::atomic<double> fps_{0};
  std::chrono::steady_clock::time_point start_;
};

class LiveStateSink : public FrameSink {
 public:
  explicit LiveStateSink(std::shared_ptr<LiveState> state) : state_(std::move(state)) {}
  Status Open(const SinkStart& start) override;
  Status Consume(const FrameRecord& record, const RunStats& stats) override;
  Status Close(const RunStats& stats) override;

 private:
  std::shared_ptr<LiveState> state_;
  std::vector<std::string> camera_ids_, zone_names_, line_names_;
  std::vector<const CameraModel*> cameras_;  // per camera id, null when the site has none
};

}  // namespace occmap
