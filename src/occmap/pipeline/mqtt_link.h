// MqttLink: the MQTT client of `occmap edge` and `occmap fuse` (libmosquitto, its own network
// thread): connects, reconnects with back-off (1 s to 5 s) whenever the broker goes away, and
// subscribes again on every connection; publishes at QoS 1 and counts what is not acknowledged
// yet; received messages wait in a queue for the caller's thread.
//
//   OCCMAP_ASSIGN_OR_RETURN(auto link, MqttLink::Start(broker, "occmap-fuse-lab", {"occmap/lab/edge/+"}));
//   while (auto m = link->Pop(std::chrono::milliseconds(10))) ...;      // fuse
//   link->Publish(topic, bytes);  link->WaitPublished(std::chrono::seconds(5));   // edge
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "occmap/publish/mqtt_options.h"
#include "occmap/util/status.h"

struct mosquitto;
struct mosquitto_message;

namespace occmap {

struct MqttReceived {
  std::string topic;
  std::string payload;
  std::chrono::steady_clock::time_point arrival;
  // The broker's stored copy given on subscribing (not a message published while subscribed).
  bool retained = false;
  int64_t connection = 0;  // connects() when it arrived: which connection brought it
};

class MqttLink {
 public:
  // persistent: the broker keeps the subscriptions and queues QoS 1 messages while this client
  // is away (a reconnect gets them), for this client id.
  static Result<std::unique_ptr<MqttLink>> Start(const MqttBroker& broker, const std::string& client_id,
                                                 std::vector<std::string> subscriptions, bool persistent = false);
  ~MqttLink();
  MqttLink(const MqttLink&) = delete;
  MqttLink& operator=(const MqttLink&) = delete;

  bool connected() const { return connected_.load(); }
  // The broker has acknowledged the subscriptions (of the current connection).
  bool subscribed() const { return subscribed_.load(); }
  // Waits up to `timeout` for a connection.
  bool WaitConnected(std::chrono::milliseconds timeout) const;
  // QoS 1; queued by libmosquitto while the broker is away. An error only for bad arguments.
  // retain: the broker keeps it as the topic's last message for later subscribers (an empty
  // retained payload clears it).
  Status Publish(const std::string& topic, const std::string& payload, bool retain = false);
  // Waits until every publish is acknowledged (false: some still are not after `timeout`).
  bool WaitPublished(std::chrono::milliseconds timeout) const;
  std::optional<MqttReceived> Pop(std::chrono::milliseconds timeout);
  int64_t connects() const { return connects_.load(); }
  int64_t disconnects() const { return disconnects_.load(); }
  int64_t bytes_published() const { return bytes_published_.load(); }
  int64_t unacked() const { return unacked_.load(); }

 private:
  MqttLink() = default;
  static void OnConnect(mosquitto* m, void* self, int rc);
  static void OnDisconnect(mosquitto* m, void* self, int rc);
  static void OnPublish(mosquitto* m, void* self, int mid);
  static void OnSubscribe(mosquitto* m, void* self, int mid, int qos_count, const int* granted_qos);
  static void OnMessage(mosquitto* m, void* self, const mosquitto_message* msg);

  mosquitto* mosq_ = nullptr;
  std::vector<std::string> subscriptions_;
  std::atomic<bool> connected_{false}, subscribed_{false};
  std::atomic<int64_t> unacked_{0}, connects_{0}, disconnects_{0}, bytes_published_{0};
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<MqttReceived> received_;
};

}  // namespace occmap
