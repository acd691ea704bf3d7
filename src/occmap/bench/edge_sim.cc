#include "occmap/bench/edge_sim.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <thread>

#include "occmap/pipeline/edge_fuse.h"
#include "occmap/pipeline/edge_message.h"
#include "occmap/pipeline/mqtt_link.h"
#include "occmap/util/file_util.h"

namespace occmap::bench {
namespace fs = std::filesystem;
namespace {

using Clock = std::chrono::steady_clock;

std::string Prefix(const Site& site, const std::string& given) {
  return given.empty() ? "occmap/" + TopicSlug(site.name) : given;
}

fs::path CameraFile(const fs::path& dir, size_t camera) { return dir / fmt::format("camera-{}.msgs", camera); }

double UnixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

EdgeExpectation Expectation(const Site& site) {
  EdgeExpectation e{EdgeTableKey(site), EdgeSettingsKey(site), {}};
  for (const SiteCamera& c : site.cameras) e.camera_sizes.push_back(c.camera->image_size());
  return e;
}

Result<std::vector<std::string>> ReadMessages(const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string bytes, ReadFileToString(path));
  std::vector<std::string> out;
  size_t at = 0;
  while (at < bytes.size()) {
    uint32_t n = 0;
    if (bytes.size() - at < 4) return InvalidInput(fmt::format("{}: a message length cut short at byte {}", path.string(), at));
    std::memcpy(&n, bytes.data() + at, 4);
    at += 4;
    if (bytes.size() - at < n) {
      return InvalidInput(fmt::format("{}: byte {}: expected a message of {} bytes, found {}", path.string(), at, n,
                                      bytes.size() - at));
    }
    out.emplace_back(bytes.substr(at, n));
    at += n;
  }
  return out;
}

}  // namespace

Result<EdgeRecording> RecordEdgeMessages(const Site& site, const EdgeRecordOptions& o) {
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(o.dir));
  const std::string prefix = Prefix(site, o.topic_prefix);
  const EdgeExpectation expect = Expectation(site);
  std::map<std::string, size_t> camera_of_topic;
  EdgeRecording rec;
  std::vector<std::ofstream> files;
  std::vector<bool> ended(site.cameras.size(), false);
  for (size_t n = 0; n < site.cameras.size(); ++n) {
    camera_of_topic[EdgeTopic(prefix, site.cameras[n].id)] = n;
    const ImageSize size = site.cameras[n].camera->image_size();
    rec.cameras.push_back({site.cameras[n].id, size.width, size.height});
    files.emplace_back(CameraFile(o.dir, n), std::ios::binary | std::ios::trunc);
    if (!files.back()) return InvalidInput(fmt::format("{}: cannot write", CameraFile(o.dir, n).string()));
  }
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<MqttLink> link,
                          MqttLink::Start(o.broker, "occmap-edge-record-" + TopicSlug(prefix), {prefix + "/edge/+"}));
  while (!link->subscribed()) {
    if (o.stop != nullptr && o.stop->load()) return rec;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (o.on_subscribed) o.on_subscribed();
  auto last = Clock::now();
  while (!std::all_of(ended.begin(), ended.end(), [](bool e) { return e; })) {
    if (o.stop != nullptr && o.stop->load()) break;
    if (o.idle_timeout_s > 0 && std::chrono::duration<double>(Clock::now() - last).count() > o.idle_timeout_s) {
      return InvalidInput(fmt::format("recording {}/edge/+: nothing for {} s and cameras not ended", prefix, o.idle_timeout_s));
    }
    const std::optional<MqttReceived> r = link->Pop(std::chrono::milliseconds(100));
    if (!r) continue;
    last = Clock::now();
    auto topic = camera_of_topic.find(r->topic);
    if (topic == camera_of_topic.end()) continue;
    auto m = DecodeEdgeMessage(r->payload, expect, r->topic);
    if (!m.ok() || m->camera != topic->second) {
      ++rec.refused;
      continue;
    }
    if (m->kind == EdgeMessageKind::kEnd) {
      ended[m->camera] = true;
      continue;
    }
    const auto n = static_cast<uint32_t>(r->payload.size());
    std::ofstream& f = files[m->camera];
    f.write(reinterpret_cast<const char*>(&n), 4);
    f.write(r->payload.data(), n);
    EdgeRecording::Camera& c = rec.cameras[m->camera];
    ++c.messages;
    c.bytes += n;
    uint32_t payload = 0;
    std::memcpy(&payload, r->payload.data() + 72, 4);  // the header's last field
    c.payload_bytes += payload;
  }
  for (size_t n = 0; n < files.size(); ++n) {
    files[n].close();
    if (!files[n]) return InvalidInput(fmt::format("{}: write failed", CameraFile(o.dir, n).string()));
  }
  return rec;
}

Result<EdgeReplaySummary> ReplayEdgeMessages(const Site& site, const EdgeReplayOptions& o) {
  if (!(o.rate_hz > 0) || !(o.seconds > 0)) {
    return InvalidInput(fmt::format("replay: expected a rate and seconds > 0, found {} and {}", o.rate_hz, o.seconds));
  }
  const int n_site = static_cast<int>(site.cameras.size());
  const int count = o.cameras > 0 ? o.cameras : n_site - o.first_camera;
  if (o.first_camera < 0 || count <= 0 || o.first_camera + count > n_site) {
    return InvalidInput(fmt::format("replay: cameras {}..{}: expected within the site's 0..{}", o.first_camera,
                                    o.first_camera + count - 1, n_site - 1));
  }
  std::vector<std::vector<std::string>> recorded;
  for (size_t k = 0; fs::exists(CameraFile(o.dir, k)); ++k) {
    OCCMAP_ASSIGN_OR_RETURN(std::vector<std::string> m, ReadMessages(CameraFile(o.dir, k)));
    if (m.empty()) return InvalidInput(fmt::format("{}: no messages", CameraFile(o.dir, k).string()));
    recorded.push_back(std::move(m));
  }
  if (recorded.empty()) return InvalidInput(fmt::format("{}: expected camera-0.msgs, ..., found none", o.dir.string()));
  const std::string prefix = Prefix(site, o.topic_prefix);
  const uint64_t table_key = EdgeTableKey(site), settings_key = EdgeSettingsKey(site);
  // Each camera's messages rekeyed once; a tick only restamps them.
  struct Sent {
    std::string topic;
    std::vector<std::string> messages;
  };
  std::vector<Sent> sent;
  for (int n = o.first_camera; n < o.first_camera + count; ++n) {
    const std::vector<std::string>& from = recorded[static_cast<size_t>(n) % recorded.size()];
    const ImageSize size = site.cameras[static_cast<size_t>(n)].camera->image_size();
    Sent s{EdgeTopic(prefix, site.cameras[static_cast<size_t>(n)].id), from};
    for (std::string& m : s.messages) {
      uint32_t w = 0, h = 0;
      std::memcpy(&w, m.data() + 36 - 8, 4);
      std::memcpy(&h, m.data() + 36 - 4, 4);
      if (static_cast<int>(w) != size.width || static_cast<int>(h) != size.height) {
        return InvalidInput(fmt::format("replay: camera {} is {}x{}; recorded camera {} sent {}x{}",
                                        site.cameras[static_cast<size_t>(n)].id, size.width, size.height,
                                        static_cast<size_t>(n) % recorded.size(), w, h));
      }
      RekeyEdgeMessage(m, table_key, settings_key, static_cast<uint32_t>(n), o.rate_hz);
    }
    sent.push_back(std::move(s));
  }
  const std::string client_id =
      o.client_id.empty() ? fmt::format("occmap-edge-sim-{}-{}", TopicSlug(site.name), o.first_camera) : o.client_id;
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<MqttLink> link, MqttLink::Start(o.broker, client_id, {}));
  if (!link->WaitConnected(std::chrono::seconds(10))) {
    return InvalidInput(fmt::format("replay: no connection to mqtt://{}:{} after 10 s", o.broker.host, o.broker.port));
  }
  const double start = o.start_unix > 0 ? o.start_unix : UnixNow();
  const auto first = static_cast<int64_t>(std::ceil(start * o.rate_hz));
  const auto end = static_cast<int64_t>(std::ceil((start + o.seconds) * o.rate_hz));
  EdgeReplaySummary summary;
  // The wall clock's ticks on the steady clock (sleeps do not follow clock adjustments).
  const double unix0 = UnixNow();
  const auto steady0 = Clock::now();
  for (int64_t tick = first; tick < end; ++tick) {
    if (o.stop != nullptr && o.stop->load()) break;
    const double t = static_cast<double>(tick) / o.rate_hz;
    std::this_thread::sleep_until(steady0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(t - unix0)));
    const double behind = UnixNow() - t;
    summary.max_behind_s = std::max(summary.max_behind_s, behind);
    if (behind > 0.5 / o.rate_hz) ++summary.late_ticks;
    for (Sent& s : sent) {
      std::string& m = s.messages[static_cast<size_t>(tick) % s.messages.size()];
      RestampEdgeMessage(m, tick, t, t);
      OCCMAP_RETURN_IF_ERROR(link->Publish(s.topic, m));
      ++summary.messages;
    }
    ++summary.ticks;
  }
  EdgeMessage done;
  done.kind = EdgeMessageKind::kEnd;
  done.table_key = table_key;
  done.settings_key = settings_key;
  done.frame = end;
  for (int n = o.first_camera; n < o.first_camera + count; ++n) {
    done.camera = static_cast<uint32_t>(n);
    OCCMAP_RETURN_IF_ERROR(link->Publish(sent[static_cast<size_t>(n - o.first_camera)].topic, EncodeEdgeMessage(done)));
  }
  link->WaitPublished(std::chrono::seconds(10));
  summary.unacked = link->unacked();
  summary.bytes = link->bytes_published();
  return summary;
}

}  // namespace occmap::bench
