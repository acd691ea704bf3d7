// MqttPublisher: a run's outputs on MQTT (libmosquitto, its own network thread), under the
// topics of mqtt_topics.h, with Home Assistant discovery (home_assistant.h).
//
// A broker that is down at the start or goes away never stops the run: Start() returns at
// once and the publisher's network thread connects, and reconnects with backoff (1 s doubling
// to 30 s; its own loop over mosquitto_loop, as libmosquitto's loop_start gives up on a first
// connection that fails).
// While it is not connected, the per-frame messages (tracks, events, stats) are dropped and
// counted; the retained state (availability, discovery configs, zone counts and occupancy,
// line counts) is kept and sent again on every connection, so a subscriber always sees the
// latest values. The last will sets <prefix>/available to "offline" when the process dies; Stop()
// sets it itself before a clean disconnect. At most kMaxQueued messages wait for the network
// thread; beyond that per-frame messages are dropped (counted) rather than queued without bound.
// Thread-safe: PublishFrame and PublishStats may be called from any one thread while the
// network thread runs the callbacks.
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
#include <memory>
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

namespace occmap {

struct MqttPublisherInfo {
  std::string site_name;
  std::vector<std::string> zones, lines;  // names in the site's order
};

// One frame set's messages.
struct MqttFrame {
  std::string tracks_json;               // a tracks.jsonl line (no newline); empty: none
  std::vector<std::string> events_json;  // events.jsonl lines (no newlines)
  std::vector<int> zone_counts;          // per zone; empty: unchanged
  std::vector<LineCounts> line_counts;   // per line; empty: unchanged
};

struct MqttCounters {
  bool connected = false;
  int64_t connects = 0;       // successful connections (the first one included)
  int64_t disconnects = 0;    // connections lost (or refused) after the start
  int64_t published = 0;      // messages handed to the client
  int64_t dropped = 0;        // per-frame messages not sent: no connection or queue full
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
  bool stopped_ = false;           // Stop() was called

  std::mutex state_mutex_;  // the retained state and its publication
  std::vector<int> zone_counts_;
  std::vector<LineCounts> line_counts_;

  std::atomic<bool> connected_{false};
  std::atomic<int64_t> connects_{0}, disconnects_{0}, published_{0}, dropped_{0}, queued_{0};
};

}  // namespace occmap
