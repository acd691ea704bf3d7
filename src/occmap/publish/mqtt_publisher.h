// MqttPublisher: a run's outputs on MQTT (libmosquitto, its own network thread), under the
// topics of mqtt_topics.h, with Home Assistant discovery (home_assistant.h).
//
// A broker that is down at the start or goes away never stops the run: Start() returns at
// once and the publisher's network thread connects, and reconnects with backoff (1 s doubling
// to 30 s; its own loop over mosquitto_loop, as libmosquitto's loop_start gives up on a first
// connection that fails).
// While it is not connected, the per-frame messages (tracks, events, stats) are dropped and
// counted; the retained state (availability, discovery configs, the run's state, the people
// count, the map, the cameras' states and rates, zone counts and occupancy, line counts) is
// kept and sent again on every connection, so a subscriber always sees the latest values. The
// last will sets <prefix>/available to "offline" when the process dies; Stop() sets it itself
// before a clean disconnect. At most kMaxQueued messages wait for the network thread; beyond
// that per-frame messages are dropped (counted) rather than queued without bound.
// What an earlier run left retained and this one no longer has (a removed zone's discovery
// config and state, a renamed camera's) is cleared with an empty retained payload, as
// Zigbee2MQTT does: on connecting the publisher subscribes to the configs under its node_id,
// and clears every retained one it did not publish itself, with the state topics under its
// prefix that the config names. "online" on <discovery_prefix>/status (Home Assistant restarted) sends the
// discovery and the state again.
// Failures are told once: the first failed or lost connection of a streak (the reason: the
// name lookup, the refusal, the lost link) and the recovery go to MqttPublisherInfo::on_status;
// counters() has the reason until it connects.
// Thread-safe: PublishFrame, PublishStats, PublishCameras, PublishRunState and PublishMap may be
// called from any one thread while the network thread runs the callbacks.
//
//   OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<MqttPublisher> mqtt,
//                           MqttPublisher::Start(options, {.site_name = "lab", .zones = {"door"}}));
//   mqtt->PublishFrame({.tracks_json = line, .events_json = events, .zone_counts = {1}});
//   mqtt->Stop();
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <set>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "occmap/publish/home_assistant.h"
#include "occmap/publish/mqtt_options.h"
#include "occmap/publish/mqtt_topics.h"
#include "occmap/track/count_lines.h"
#include "occmap/util/status.h"

struct mosquitto;
struct mosquitto_message;

namespace occmap {

struct MqttPublisherInfo {
  std::string site_name;
  std::vector<std::string> zones, lines;  // names in the site's order
  std::vector<std::string> cameras;       // camera ids in the site's order
  // A line for the terminal, called from the network thread: the first failure of a streak
  // (with its reason) and the recovery. Null: nothing said.
  std::function<void(const std::string&)> on_status;
};

// One frame set's messages.
struct MqttFrame {
  std::string tracks_json;               // a tracks.jsonl line (no newline); empty: none
  std::vector<std::string> events_json;  // events.jsonl lines (no newlines)
  std::vector<int> zone_counts;          // per zone; empty: unchanged
  std::vector<LineCounts> line_counts;   // per line; empty: unchanged
  int people = -1;                       // people on the floor; -1: unchanged
};

struct MqttCounters {
  bool connected = false;
  int64_t connects = 0;       // successful connections (the first one included)
  int64_t disconnects = 0;    // connections lost (or refused) after the start
  int64_t published = 0;      // messages handed to the client
  int64_t dropped = 0;        // per-frame messages not sent: no connection or queue full
  int64_t failures = 0;       // connection attempts that failed and connections lost
  int64_t cleared = 0;        // retained topics of an earlier run cleared (removed zones, ...)
  std::string broker;         // mqtt://HOST:PORT
  std::string error;          // why it is not connected (empty while connected)
};

class MqttPublisher {
 public:
  static constexpr int64_t kMaxQueued = 1000;

  // Fails only on bad options (a bad client id, an unreadable password file): exit code 2.
  static Result<std::unique_ptr<MqttPublisher>> Start(const MqttOptions& options, const MqttPublisherInfo& info);
  ~MqttPublisher();
  MqttPublisher(const MqttPublisher&) = delete;
  MqttPublisher& operator=(const MqttPublisher&) = delete;

  void PublishFrame(const MqttFrame& frame);
  void PublishStats(const std::string& json);
  // Per camera (the site's order): "streaming", "reconnecting" or "ended" (sent on change) and
  // frames per second (sent every call).
  void PublishCameras(const std::vector<std::string>& states, const std::vector<double>& fps);
  // "running" (from the start), "ended" or "failed", and why.
  void PublishRunState(const std::string& state, const std::string& reason);
  // The floor map as a PNG (retained; not sent again when unchanged).
  void PublishMap(std::string png);
  // "offline" (retained), waits up to `timeout` for the queue to drain, disconnects and stops
  // the network thread. Called by the destructor; a second call does nothing.
  void Stop(std::chrono::milliseconds timeout = std::chrono::milliseconds(1000));

  // Waits until the client is connected (tests, and a run that wants its first frames out).
  bool WaitConnected(std::chrono::milliseconds timeout) const;
  MqttCounters counters() const;
  const MqttTopics& topics() const { return topics_; }
  const MqttOptions& options() const { return options_; }

 private:
  MqttPublisher(const MqttOptions& options, const MqttPublisherInfo& info);
  static void OnConnect(mosquitto* mosq, void* self, int rc);
  static void OnDisconnect(mosquitto* mosq, void* self, int rc);
  static void OnPublish(mosquitto* mosq, void* self, int mid);
  static void OnMessage(mosquitto* mosq, void* self, const mosquitto_message* message);
  // The connection failed or was lost: remember why, say it once per streak.
  void NoteFailure(const std::string& why, bool specific);
  void NoteConnected();
  std::string BrokerUrl() const;

  // Sends one message; per-frame ones (`droppable`) are dropped when not connected or the
  // queue is full. Returns whether it was handed to the client.
  bool Send(const MqttMessage& message, bool droppable);
  // The retained state, all of it (under state_mutex_).
  void SendRetainedState();
  // The network thread: connect, run mosquitto_loop, back off and reconnect, until stop_.
  void NetworkLoop();

  MqttOptions options_;
  MqttTopics topics_;
  DiscoveryInput discovery_;
  mosquitto* mosq_ = nullptr;
  std::thread network_;
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  std::atomic<bool> stop_{false};  // the network thread ends
  std::atomic<bool> stopped_{false};  // Stop() was called

  std::function<void(const std::string&)> on_status_;
  std::set<std::string> current_;  // every retained topic this run publishes (configs included)
  std::string status_topic_;       // <discovery_prefix>/status

  std::mutex state_mutex_;  // the retained state and its publication
  std::vector<int> zone_counts_;
  std::vector<LineCounts> line_counts_;
  int people_ = 0;
  std::string run_state_ = "running", run_reason_;
  std::string map_png_;
  std::vector<std::string> camera_states_;  // empty entries: not known yet
  std::vector<double> camera_fps_;          // NaN: not known yet

  mutable std::mutex status_mutex_;  // error_, down_
  std::string error_;
  bool down_ = false;  // a failure was said and no connection since
  std::chrono::steady_clock::time_point down_since_;
  int64_t dropped_at_down_ = 0;

  std::atomic<bool> connected_{false};
  std::atomic<int64_t> connects_{0}, disconnects_{0}, published_{0}, dropped_{0}, queued_{0}, cleared_{0}, failures_{0};
};

}  // namespace occmap
