#include "occmap/publish/mqtt_publisher.h"

#include <fmt/core.h>
#include <mosquitto.h>

#include <algorithm>
#include <thread>

namespace occmap {
namespace {

#ifndef OCCMAP_VERSION
#define OCCMAP_VERSION "unknown"
#endif

// QoS 0 for everything sent: the whole retained state is sent again on every connection, and
// libmosquitto would resend an unacknowledged QoS 1 message after a reconnection, after the
// newer state (a stale zone count retained). The will is QoS 1 (the broker sends it).
constexpr int kRetainedQos = 0;
constexpr int kFrameQos = 0;
constexpr int kWillQos = 1;

void InitLibraryOnce() {
  static std::once_flag once;
  // Never cleaned up: other publishers may still run until the process ends.
  std::call_once(once, [] { mosquitto_lib_init(); });
}

}  // namespace

MqttPublisher::MqttPublisher(const MqttOptions& options, const MqttPublisherInfo& info)
    : options_(options),
      topics_(MqttTopics::For(options.topic_prefix, info.zones, info.lines)),
      zone_counts_(info.zones.size(), 0),
      line_counts_(info.lines.size()) {
  discovery_.discovery_prefix = options.discovery_prefix;
  discovery_.topic_prefix = options.topic_prefix;
  discovery_.site_name = info.site_name;
  discovery_.sw_version = OCCMAP_VERSION;
  discovery_.zones = info.zones;
  discovery_.lines = info.lines;
  discovery_.topics = topics_;
}

Result<std::unique_ptr<MqttPublisher>> MqttPublisher::Start(const MqttOptions& given, const MqttPublisherInfo& info) {
  MqttOptions options = given;
  ResolveMqttDefaults(info.site_name, options);
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  std::string password;
  if (!options.password_file.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(password, ReadMqttPassword(options.password_file));
  }
  InitLibraryOnce();
  std::unique_ptr<MqttPublisher> p(new MqttPublisher(options, info));
  p->mosq_ = mosquitto_new(options.client_id.c_str(), /*clean_session=*/true, p.get());
  if (p->mosq_ == nullptr) return InvalidInput(fmt::format("mqtt: cannot create a client with id '{}'", options.client_id));
  mosquitto_connect_callback_set(p->mosq_, &MqttPublisher::OnConnect);
  mosquitto_disconnect_callback_set(p->mosq_, &MqttPublisher::OnDisconnect);
  mosquitto_publish_callback_set(p->mosq_, &MqttPublisher::OnPublish);
  constexpr std::string_view kOffline = "offline";
  int rc = mosquitto_will_set(p->mosq_, p->topics_.available.c_str(), static_cast<int>(kOffline.size()), kOffline.data(),
                              kWillQos, /*retain=*/true);
  if (rc != MOSQ_ERR_SUCCESS) {
    return InvalidInput(fmt::format("mqtt: topic '{}': {}", p->topics_.available, mosquitto_strerror(rc)));
  }
  if (!options.username.empty()) {
    rc = mosquitto_username_pw_set(p->mosq_, options.username.c_str(), password.empty() ? nullptr : password.c_str());
    if (rc != MOSQ_ERR_SUCCESS) return InvalidInput(fmt::format("mqtt.username: {}", mosquitto_strerror(rc)));
  }
  // Publishing happens on the caller's thread while the network thread runs the loop.
  mosquitto_threaded_set(p->mosq_, true);
  p->network_ = std::thread([raw = p.get()] { raw->NetworkLoop(); });
  return p;
}

MqttPublisher::~MqttPublisher() { Stop(); }

void MqttPublisher::Stop(std::chrono::milliseconds timeout) {
  if (stopped_ || mosq_ == nullptr) {
    stopped_ = true;
    return;
  }
  stopped_ = true;
  if (connected_.load()) {
    Send({topics_.available, "offline", true, kRetainedQos}, false);
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (queued_.load() > 0 && connected_.load() && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  mosquitto_disconnect(mosq_);  // sent by the network thread's next loop
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(200);
  while (connected_.load() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    stop_ = true;
  }
  stop_cv_.notify_all();
  if (network_.joinable()) network_.join();
  mosquitto_destroy(mosq_);
  mosq_ = nullptr;
  connected_ = false;
}

void MqttPublisher::NetworkLoop() {
  int delay_s = 1;
  bool first = true;
  while (!stop_.load()) {
    // Non-blocking connects (a name lookup may still block): the loop completes them.
    int rc = first ? mosquitto_connect_async(mosq_, options_.broker.host.c_str(), options_.broker.port, options_.keepalive_s)
                   : mosquitto_reconnect_async(mosq_);
    first = false;
    if (rc == MOSQ_ERR_SUCCESS) {
      while (!stop_.load()) {
        rc = mosquitto_loop(mosq_, /*timeout_ms=*/100, 1);
        if (rc != MOSQ_ERR_SUCCESS) break;
        if (connected_.load()) delay_s = 1;
      }
    }
    if (connected_.exchange(false)) ++disconnects_;
    std::unique_lock<std::mutex> lock(stop_mutex_);
    if (stop_cv_.wait_for(lock, std::chrono::seconds(delay_s), [&] { return stop_.load(); })) break;
    delay_s = std::min(delay_s * 2, 30);
  }
}

bool MqttPublisher::Send(const MqttMessage& m, bool droppable) {
  if (!connected_.load() || (droppable && queued_.load() >= kMaxQueued)) {
    if (droppable) ++dropped_;
    return false;
  }
  ++queued_;
  const int rc = mosquitto_publish(mosq_, nullptr, m.topic.c_str(), static_cast<int>(m.payload.size()),
                                   m.payload.data(), m.qos, m.retain);
  if (rc != MOSQ_ERR_SUCCESS) {
    --queued_;
    if (droppable) ++dropped_;
    return false;
  }
  ++published_;
  return true;
}

void MqttPublisher::SendRetainedState() {
  Send({topics_.available, "online", true, kRetainedQos}, false);
  if (options_.discovery) {
    for (const MqttMessage& m : HomeAssistantDiscovery(discovery_)) Send(m, false);
  }
  for (size_t z = 0; z < zone_counts_.size(); ++z) {
    Send({topics_.zone_count[z], std::to_string(zone_counts_[z]), true, kRetainedQos}, false);
    Send({topics_.zone_occupied[z], zone_counts_[z] > 0 ? "ON" : "OFF", true, kRetainedQos}, false);
  }
  for (size_t l = 0; l < line_counts_.size(); ++l) {
    Send({topics_.line_in[l], std::to_string(line_counts_[l].in), true, kRetainedQos}, false);
    Send({topics_.line_out[l], std::to_string(line_counts_[l].out), true, kRetainedQos}, false);
  }
}

void MqttPublisher::PublishFrame(const MqttFrame& frame) {
  if (stopped_) return;
  if (!frame.tracks_json.empty()) Send({topics_.tracks, frame.tracks_json, false, kFrameQos}, true);
  for (const std::string& e : frame.events_json) Send({topics_.events, e, false, kFrameQos}, true);
  std::lock_guard<std::mutex> lock(state_mutex_);
  for (size_t z = 0; z < frame.zone_counts.size() && z < zone_counts_.size(); ++z) {
    const int before = zone_counts_[z], now = frame.zone_counts[z];
    if (now == before) continue;
    zone_counts_[z] = now;
    Send({topics_.zone_count[z], std::to_string(now), true, kRetainedQos}, false);
    if ((before > 0) != (now > 0)) Send({topics_.zone_occupied[z], now > 0 ? "ON" : "OFF", true, kRetainedQos}, false);
  }
  for (size_t l = 0; l < frame.line_counts.size() && l < line_counts_.size(); ++l) {
    const LineCounts before = line_counts_[l], now = frame.line_counts[l];
    line_counts_[l] = now;
    if (now.in != before.in) Send({topics_.line_in[l], std::to_string(now.in), true, kRetainedQos}, false);
    if (now.out != before.out) Send({topics_.line_out[l], std::to_string(now.out), true, kRetainedQos}, false);
  }
}

void MqttPublisher::PublishStats(const std::string& json) {
  if (stopped_) return;
  Send({topics_.stats, json, false, kFrameQos}, true);
}

bool MqttPublisher::WaitConnected(std::chrono::milliseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!connected_.load()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

MqttCounters MqttPublisher::counters() const {
  return {connected_.load(), connects_.load(), disconnects_.load(), published_.load(), dropped_.load()};
}

void MqttPublisher::OnConnect(mosquitto*, void* self, int rc) {
  auto* p = static_cast<MqttPublisher*>(self);
  if (rc != 0) {  // refused (bad login, ...): the network thread retries
    ++p->disconnects_;
    return;
  }
  // Messages queued before a lost connection were dropped with it.
  p->queued_ = 0;
  ++p->connects_;
  std::lock_guard<std::mutex> lock(p->state_mutex_);
  p->connected_ = true;
  p->SendRetainedState();
}

void MqttPublisher::OnDisconnect(mosquitto*, void* self, int) {
  auto* p = static_cast<MqttPublisher*>(self);
  if (p->connected_.exchange(false)) ++p->disconnects_;
}

void MqttPublisher::OnPublish(mosquitto*, void* self, int) {
  auto* p = static_cast<MqttPublisher*>(self);
  if (p->queued_.load() > 0) --p->queued_;
}

}  // namespace occmap
