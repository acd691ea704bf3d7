// Simulated edges for the bench of `occmap edge` and `occmap fuse` (issue 17, item 4;
// scripts/bench-edge-fuse.sh): more cameras than this machine can decode, as the messages of
// real edges recorded once and sent again.
//
// RecordEdgeMessages subscribes to a site's edge topics and keeps, per camera, every message of
// changes its edges publish (the bytes as sent) until every camera has reported the end of its
// source: the sizes are the bench's bytes per camera-frame, the files the replay's input.
// ReplayEdgeMessages sends them again as the cameras of another, larger site (a site file that
// repeats the recorded cameras): camera n gets recorded camera n mod R's messages, with that
// site's keys, its index, and the frame's tick as its timestamp and capture time. The ticks are
// the multiples of 1 / rate on the wall clock, so that replays in several processes (many
// edges) send the same frame set at the same instant, as cameras in step would.
//
// Files: <dir>/camera-<index>.msgs, per message a u32 length (little-endian) and the bytes.
//
//   OCCMAP_ASSIGN_OR_RETURN(EdgeRecording r, RecordEdgeMessages(site, record));
//   OCCMAP_ASSIGN_OR_RETURN(EdgeReplaySummary s, ReplayEdgeMessages(big_site, replay));
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "occmap/publish/mqtt_options.h"
#include "occmap/site/site.h"
#include "occmap/util/status.h"

namespace occmap::bench {

struct EdgeRecordOptions {
  MqttBroker broker;
  std::string topic_prefix;  // empty: occmap/<site slug>
  std::filesystem::path dir;
  // Stop when nothing arrived for this long (an edge that never ends); 0: wait for the ends.
  double idle_timeout_s = 60;
  const std::atomic<bool>* stop = nullptr;
  // Called once subscribed (the edges may start then).
  std::function<void()> on_subscribed;
};

struct EdgeRecording {
  struct Camera {
    std::string id;
    int width = 0, height = 0;
    int64_t messages = 0;       // messages of changes
    int64_t bytes = 0;          // their bytes as sent (header included)
    int64_t payload_bytes = 0;  // their compressed payloads alone
  };
  std::vector<Camera> cameras;
  int64_t refused = 0;  // messages not of this site (keys, sizes)
};

Result<EdgeRecording> RecordEdgeMessages(const Site& site, const EdgeRecordOptions& options);

struct EdgeReplayOptions {
  MqttBroker broker;
  std::string topic_prefix;  // empty: occmap/<site slug>
  std::filesystem::path dir;
  int first_camera = 0;  // this process sends cameras first_camera .. first_camera + cameras - 1
  int cameras = 0;       // 0: all from first_camera
  double rate_hz = 10;
  double start_unix = 0;  // the first tick at or after this time (0: now)
  double seconds = 30;    // ticks in [start, start + seconds)
  std::string client_id;  // empty: occmap-edge-sim-<site slug>-<first camera>
  const std::atomic<bool>* stop = nullptr;
};

struct EdgeReplaySummary {
  int64_t ticks = 0;
  int64_t messages = 0;
  int64_t bytes = 0;
  int64_t late_ticks = 0;     // ticks sent more than half a tick after their time (this process too slow)
  double max_behind_s = 0;    // the latest a tick was sent after its time
  int64_t unacked = 0;        // not acknowledged by the broker at the end
};

Result<EdgeReplaySummary> ReplayEdgeMessages(const Site& site, const EdgeReplayOptions& options);

}  // namespace occmap::bench
