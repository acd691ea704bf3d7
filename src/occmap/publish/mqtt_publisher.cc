#include "occmap/publish/mqtt_publisher.h"

#include <fmt/core.h>
#include <mosquitto.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
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

// libmosquitto's reason for a return code; MOSQ_ERR_ERRNO's is the system's (connection
// refused, no route).
std::string ErrorText(int rc) {
  if (rc == MOSQ_ERR_ERRNO) return std::strerror(errno);
  return mosquitto_strerror(rc);
}

std::string FpsText(double fps) { return fmt::format("{:.2f}", std::round(fps * 100) / 100); }

void InitLibraryOnce() {
  static std::once_flag once;
  // Never cleaned up: other publishers may still run until the process ends.
  std::call_once(once, [] { mosquitto_lib_init(); });
}

}  // namespace

MqttPublisher::MqttPublisher(const MqttOptions& options, const MqttPublisherInfo& info)
    : options_(options),
      topics_(MqttTopics::For(options.topic_prefix, info.zones, info.lines, info.cameras)),
      on_status_(info.on_status),
      status_topic_(options.discovery_prefix + "/status"),
      zone_counts_(info.zones.size(), 0),
      line_counts_(info.lines.size()),
      camera_states_(info.cameras.size()),
      camera_fps_(info.cameras.size(), std::nan("")) {
  discovery_.discovery_prefix = options.discovery_prefix;
  discovery_.topic_prefix = options.topic_prefix;
  discovery_.site_name = info.site_name;
  discovery_.sw_version = OCCMAP_VERSION;
  discovery_.zones = info.zones;
  discovery_.lines = info.lines;
  discovery_.cameras = info.cameras;
  discovery_.topics = topics_;
  for (const std::string& t : topics_.Retained()) current_.insert(t);
  if (options.discovery) {
    for (const MqttMessage& m : HomeAssistantDiscovery(discovery_)) current_.insert(m.topic);
  }
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
  mosquitto_message_callback_set(p->mosq_, &MqttPublisher::OnMessage);
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
    if (rc != MOSQ_ERR_SUCCESS && !stopped_.load()) {  // Stop()'s own disconnection is no failure
      NoteFailure(connected_.load() ? "connection lost: " + ErrorText(rc) : ErrorText(rc), /*specific=*/false);
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
  Send({topics_.run, run_state_, true, kRetainedQos}, false);
  Send({topics_.run_attributes, nlohmann::json{{"reason", run_reason_}}.dump(), true, kRetainedQos}, false);
  Send({topics_.people, std::to_string(people_), true, kRetainedQos}, false);
  if (!map_png_.empty()) Send({topics_.map, map_png_, true, kRetainedQos}, false);
  for (size_t c = 0; c < camera_states_.size(); ++c) {
    if (!camera_states_[c].empty()) Send({topics_.camera_state[c], camera_states_[c], true, kRetainedQos}, false);
    if (std::isfinite(camera_fps_[c])) Send({topics_.camera_fps[c], FpsText(camera_fps_[c]), true, kRetainedQos}, false);
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
  if (frame.people >= 0 && frame.people != people_) {
    people_ = frame.people;
    Send({topics_.people, std::to_string(people_), true, kRetainedQos}, false);
  }
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

void MqttPublisher::PublishCameras(const std::vector<std::string>& states, const std::vector<double>& fps) {
  if (stopped_) return;
  std::lock_guard<std::mutex> lock(state_mutex_);
  for (size_t c = 0; c < camera_states_.size(); ++c) {
    if (c < states.size() && states[c] != camera_states_[c]) {
      camera_states_[c] = states[c];
      Send({topics_.camera_state[c], states[c], true, kRetainedQos}, false);
    }
    if (c < fps.size() && std::isfinite(fps[c])) {
      camera_fps_[c] = fps[c];
      Send({topics_.camera_fps[c], FpsText(fps[c]), true, kRetainedQos}, false);
    }
  }
}

void MqttPublisher::PublishRunState(const std::string& state, const std::string& reason) {
  if (stopped_) return;
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (state == run_state_ && reason == run_reason_) return;
  run_state_ = state;
  run_reason_ = reason;
  Send({topics_.run_attributes, nlohmann::json{{"reason", run_reason_}}.dump(), true, kRetainedQos}, false);
  Send({topics_.run, run_state_, true, kRetainedQos}, false);
}

void MqttPublisher::PublishMap(std::string png) {
  if (stopped_) return;
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (png == map_png_) return;
  map_png_ = std::move(png);
  Send({topics_.map, map_png_, true, kRetainedQos}, false);
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
  MqttCounters c;
  c.connected = connected_.load();
  c.connects = connects_.load();
  c.disconnects = disconnects_.load();
  c.published = published_.load();
  c.dropped = dropped_.load();
  c.cleared = cleared_.load();
  c.failures = failures_.load();
  c.broker = BrokerUrl();
  std::lock_guard<std::mutex> lock(status_mutex_);
  if (!c.connected) c.error = error_.empty() ? "not connected yet" : error_;
  return c;
}

std::string MqttPublisher::BrokerUrl() const {
  const std::string& host = options_.broker.host;
  return fmt::format("mqtt://{}:{}", host.find(':') != std::string::npos ? "[" + host + "]" : host, options_.broker.port);
}

void MqttPublisher::NoteFailure(const std::string& why, bool specific) {
  ++failures_;
  std::string say;
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    // A refusal's reason is kept over the link closing that follows it.
    if (error_.empty() || specific) error_ = why;
    if (down_) return;
    down_ = true;
    down_since_ = std::chrono::steady_clock::now();
    dropped_at_down_ = dropped_.load();
    say = fmt::format("mqtt: cannot publish to {}: {}; retrying, messages are dropped until it is back",
                      BrokerUrl(), error_);
  }
  if (on_status_) on_status_(say);
}

void MqttPublisher::NoteConnected() {
  std::string say;
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    error_.clear();
    if (!down_) return;
    down_ = false;
    const double down_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - down_since_).count();
    say = fmt::format("mqtt: connected to {} again after {:.0f} s; {} messages dropped meanwhile", BrokerUrl(),
                      down_s, dropped_.load() - dropped_at_down_);
  }
  if (on_status_) on_status_(say);
}

void MqttPublisher::OnConnect(mosquitto* mosq, void* self, int rc) {
  auto* p = static_cast<MqttPublisher*>(self);
  if (rc != 0) {  // refused (bad login, ...): the network thread retries
    ++p->disconnects_;
    p->NoteFailure(mosquitto_connack_string(rc), /*specific=*/true);
    return;
  }
  // Messages queued before a lost connection were dropped with it.
  p->queued_ = 0;
  ++p->connects_;
  p->NoteConnected();
  // The discovery configs earlier runs left under this node_id (the stale ones and their state
  // topics cleared in OnMessage), and Home Assistant's birth message; subscribed before the
  // state goes out, so that whoever sees the state knows the broker has the subscriptions (the
  // broker keeps a client's order).
  for (const std::string& filter : {DiscoveryConfigFilter(p->discovery_), p->status_topic_}) {
    mosquitto_subscribe(mosq, nullptr, filter.c_str(), 0);
  }
  std::lock_guard<std::mutex> lock(p->state_mutex_);
  p->connected_ = true;
  p->SendRetainedState();
}

void MqttPublisher::OnMessage(mosquitto*, void* self, const mosquitto_message* m) {
  auto* p = static_cast<MqttPublisher*>(self);
  const std::string topic = m->topic;
  if (topic == p->status_topic_) {
    const std::string payload(static_cast<const char*>(m->payload), static_cast<size_t>(std::max(m->payloadlen, 0)));
    if (payload == "online" && !p->stopped_) {
      std::lock_guard<std::mutex> lock(p->state_mutex_);
      p->SendRetainedState();
    }
    return;
  }
  // Only what the broker kept from before (the retain flag is set on those alone); this run's
  // own topics and empty payloads (already cleared) are left alone.
  if (!m->retain || m->payloadlen <= 0 || p->current_.contains(topic) || p->stopped_) return;
  // A config this run no longer has: its retained state topics under this run's prefix first
  // (a removed zone's count would stay "2" forever), then the config (the entity goes).
  const nlohmann::json config =
      nlohmann::json::parse(std::string(static_cast<const char*>(m->payload), static_cast<size_t>(m->payloadlen)), nullptr,
                            /*allow_exceptions=*/false);
  if (config.is_object()) {
    for (const char* key : {"state_topic", "json_attributes_topic", "image_topic"}) {
      const auto it = config.find(key);
      if (it == config.end() || !it->is_string()) continue;
      const std::string state = it->get<std::string>();
      if (state.starts_with(p->options_.topic_prefix + "/") && !p->current_.contains(state) &&
          p->Send({state, "", true, kRetainedQos}, false)) {
        ++p->cleared_;
      }
    }
  }
  if (p->Send({topic, "", true, kRetainedQos}, false)) ++p->cleared_;
}

void MqttPublisher::OnDisconnect(mosquitto*, void* self, int rc) {
  auto* p = static_cast<MqttPublisher*>(self);
  if (p->connected_.exchange(false)) {
    ++p->disconnects_;
    if (rc != 0 && !p->stopped_.load()) p->NoteFailure("connection lost: " + ErrorText(rc), /*specific=*/false);
  }
}

void MqttPublisher::OnPublish(mosquitto*, void* self, int) {
  auto* p = static_cast<MqttPublisher*>(self);
  if (p->queued_.load() > 0) --p->queued_;
}

}  // namespace occmap
