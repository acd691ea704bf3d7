// MqttSink: a run's results on MQTT as a FrameSink (frame_sink.h) over MqttPublisher
// (publish/mqtt_publisher.h): per frame set the tracks (a tracks.jsonl line), the events (zone
// and line events as events.jsonl lines), the people on the floor (tracks of class "person"),
// the zones' counts and occupancy and the lines' counts (retained, on change); every
// stats_every_s of wall-clock time (and at the first frame set) a stats message
// (MqttStatsJson), each camera's state and frame rate and the map as a PNG (MqttMapPng); the
// run's state: running from Open, at Close ended (end of streams, frame limit, stop) or failed
// (any other reason). The broker being away never fails the run: messages are dropped and
// counted (counters()); `on_status` hears of failures and recoveries (MqttPublisherInfo).
//
//   auto mqtt = std::make_shared<MqttSink>(*site.outputs.mqtt, [](const std::string& line) { ... });
//   run_options.sinks.push_back(mqtt);
//   ... RunSite(...);  mqtt->counters().dropped
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "occmap/pipeline/frame_sink.h"
#include "occmap/publish/mqtt_publisher.h"

namespace occmap {

// The <prefix>/stats payload (one line of JSON):
//   {"t_unix", "frames", "elapsed_s", "frames_per_second",
//    "cameras": [{"id", "active", "connected", "frames", "frames_per_second", "dropped", "reconnects",
//                 "background_cache"?: as summary.json's (summary_file.h; live cameras whose cached
//                 background is refreshed)}],
//    "latency_ms": {"p50", "p95", "p99", "max"}, "tracks", "zone_events", "line_crossings",
//    "mqtt": {"published", "dropped", "connects", "disconnects"}}
// camera_fps: per camera, frames per second since the previous stats message.
std::string MqttStatsJson(double t_unix, const RunStats& stats, const std::vector<double>& camera_fps,
                          int64_t line_crossings, const MqttCounters& mqtt);

// The map for Home Assistant's image entity: free white, occupied black, unseen grey (as the
// ROS maps), each cell a square of pixels so that the longer side is about 480 px, row 0 = the
// largest y; the tracks as red dots. Empty before the first map.
std::string MqttMapPng(const OccupancyMap& map, const std::vector<Track>& tracks);
// "streaming", "reconnecting" (a live stream between connections) or "ended".
std::string CameraStateName(const CameraStats& camera);
// The run's state after Close: "ended" for the end of streams, a frame limit or a stop, else
// "failed".
std::string RunStateAfter(const std::string& stop_reason);

class MqttSink : public FrameSink {
 public:
  explicit MqttSink(MqttOptions options, std::function<void(const std::string&)> on_status = {})
      : options_(std::move(options)), on_status_(std::move(on_status)) {}
  Status Open(const SinkStart& start) override;
  Status Consume(const FrameRecord& record, const RunStats& stats) override;
  // A last stats message, "offline", and the disconnection.
  Status Close(const RunStats& stats) override;
  MqttCounters counters() const { return publisher_ ? publisher_->counters() : MqttCounters{}; }

 private:
  void SendStats(const RunStats& stats);

  MqttOptions options_;
  std::function<void(const std::string&)> on_status_;
  std::unique_ptr<MqttPublisher> publisher_;
  bool first_frame_ = true;
  std::chrono::steady_clock::time_point last_stats_;
  std::vector<int64_t> last_camera_frames_;
  int64_t line_crossings_ = 0;
};

}  // namespace occmap
