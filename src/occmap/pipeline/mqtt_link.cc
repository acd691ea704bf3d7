#include "occmap/pipeline/mqtt_link.h"

#include <fmt/core.h>
#include <mosquitto.h>

#include <thread>

namespace occmap {
namespace {

void InitLibraryOnce() {
  static std::once_flag once;
  std::call_once(once, [] { mosquitto_lib_init(); });
}

}  // namespace

Result<std::unique_ptr<MqttLink>> MqttLink::Start(const MqttBroker& broker, const std::string& client_id,
                                                  std::vector<std::string> subscriptions, bool persistent) {
  InitLibraryOnce();
  std::unique_ptr<MqttLink> link(new MqttLink());
  link->subscriptions_ = std::move(subscriptions);
  link->mosq_ = mosquitto_new(client_id.c_str(), /*clean_session=*/!persistent, link.get());
  if (link->mosq_ == nullptr) return InvalidInput(fmt::format("mqtt: cannot create a client with id '{}'", client_id));
  mosquitto_connect_callback_set(link->mosq_, &MqttLink::OnConnect);
  mosquitto_disconnect_callback_set(link->mosq_, &MqttLink::OnDisconnect);
  mosquitto_publish_callback_set(link->mosq_, &MqttLink::OnPublish);
  mosquitto_message_callback_set(link->mosq_, &MqttLink::OnMessage);
  mosquitto_subscribe_callback_set(link->mosq_, &MqttLink::OnSubscribe);
  mosquitto_reconnect_delay_set(link->mosq_, 1, 5, /*exponential=*/true);
  // Unacknowledged QoS 1 messages: no cap (a broker restart must not lose what was queued).
  mosquitto_max_inflight_messages_set(link->mosq_, 0);
  int rc = mosquitto_connect_async(link->mosq_, broker.host.c_str(), broker.port, /*keepalive=*/10);
  if (rc != MOSQ_ERR_SUCCESS && rc != MOSQ_ERR_ERRNO) {
    return InvalidInput(fmt::format("mqtt://{}:{}: {}", broker.host, broker.port, mosquitto_strerror(rc)));
  }
  rc = mosquitto_loop_start(link->mosq_);  // reconnects by itself, also after a failed first connect
  if (rc != MOSQ_ERR_SUCCESS) return Internal(fmt::format("mqtt: network thread: {}", mosquitto_strerror(rc)));
  return link;
}

MqttLink::~MqttLink() {
  if (mosq_ == nullptr) return;
  mosquitto_disconnect(mosq_);
  mosquitto_loop_stop(mosq_, /*force=*/false);
  mosquitto_destroy(mosq_);
}

void MqttLink::OnConnect(mosquitto* m, void* self, int rc) {
  auto* link = static_cast<MqttLink*>(self);
  if (rc != 0) return;
  for (const std::string& topic : link->subscriptions_) mosquitto_subscribe(m, nullptr, topic.c_str(), 1);
  link->connected_ = true;
  ++link->connects_;
}

void MqttLink::OnSubscribe(mosquitto*, void* self, int, int, const int*) {
  static_cast<MqttLink*>(self)->subscribed_ = true;
}

void MqttLink::OnDisconnect(mosquitto*, void* self, int) {
  auto* link = static_cast<MqttLink*>(self);
  link->subscribed_ = false;
  if (link->connected_.exchange(false)) ++link->disconnects_;
}

void MqttLink::OnPublish(mosquitto*, void* self, int) { --static_cast<MqttLink*>(self)->unacked_; }

void MqttLink::OnMessage(mosquitto*, void* self, const mosquitto_message* msg) {
  auto* link = static_cast<MqttLink*>(self);
  MqttReceived r;
  r.topic = msg->topic;
  r.payload.assign(static_cast<const char*>(msg->payload), static_cast<size_t>(msg->payloadlen));
  r.arrival = std::chrono::steady_clock::now();
  r.retained = msg->retain;
  r.connection = link->connects_.load();
  {
    std::lock_guard lock(link->mutex_);
    link->received_.push_back(std::move(r));
  }
  link->cv_.notify_one();
}

bool MqttLink::WaitConnected(std::chrono::milliseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!connected_.load() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return connected_.load();
}

Status MqttLink::Publish(const std::string& topic, const std::string& payload, bool retain) {
  ++unacked_;
  const int rc = mosquitto_publish(mosq_, nullptr, topic.c_str(), static_cast<int>(payload.size()), payload.data(),
                                   /*qos=*/1, retain);
  if (rc != MOSQ_ERR_SUCCESS && rc != MOSQ_ERR_NO_CONN) {
    --unacked_;
    return InvalidInput(fmt::format("mqtt: topic '{}': {}", topic, mosquitto_strerror(rc)));
  }
  if (rc == MOSQ_ERR_NO_CONN) --unacked_;  // not queued: counted as lost by the caller's frame gap
  bytes_published_ += static_cast<int64_t>(payload.size());
  return Status::Ok();
}

bool MqttLink::WaitPublished(std::chrono::milliseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (unacked_.load() > 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return unacked_.load() <= 0;
}

std::optional<MqttReceived> MqttLink::Pop(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  if (!cv_.wait_for(lock, timeout, [&] { return !received_.empty(); })) return std::nullopt;
  MqttReceived r = std::move(received_.front());
  received_.pop_front();
  return r;
}

}  // namespace occmap
