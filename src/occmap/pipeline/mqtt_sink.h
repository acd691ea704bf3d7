// MqttSink: a run's results on MQTT as a FrameSink (frame_sink.h) over MqttPublisher
// (publish/mqtt_publisher.h): per frame set the tracks (a tracks.jsonl line), the events (zone
// and line events as events.jsonl lines), the zones' counts and occupancy and the lines' counts
// (retained, on change); every stats_every_s of wall-clock time a stats message (MqttStatsJson).
// The broker being away never fails the run: messages are dropped and counted (counters()).
//
//   auto mqtt = std::make_shared<MqttSink>(*site.outputs.mqtt);
//   run_options.sinks.push_back(mqtt);
//   ... RunSite(...);  mqtt->counters().dropped
#pragma once

#include <chrono>
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

class MqttSink : public FrameSink {
 public:
  explicit MqttSink(MqttOptions options) : options_(std::move(options)) {}
  Status Open(const SinkStart& start) override;
  Status Consume(const FrameRecord& record, const RunStats& stats) override;
  // A last stats message, "offline", and the disconnection.
  Status Close(const RunStats& stats) override;
  MqttCounters counters() const { return publisher_ ? publisher_->counters() : MqttCounters{}; }

 private:
  void SendStats(const RunStats& stats);

  MqttOptions options_;
  std::unique_ptr<MqttPublisher> publisher_;
  std::chrono::steady_clock::time_point last_stats_;
  std::vector<int64_t> last_camera_frames_;
  int64_t line_crossings_ = 0;
};

}  // namespace occmap
