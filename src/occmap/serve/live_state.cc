#include "occmap/serve/live_state.h"

#include <algorithm>
#include <cmath>

#include "occmap/lut/ground_lut.h"
#include "occmap/site/site.h"

namespace occmap {

LiveState::LiveState() : latest_(std::make_shared<LiveSnapshot>()), start_(std::chrono::steady_clock::now()) {}

std::shared_ptr<const LiveSnapshot> LiveState::Latest() const {
  std::lock_guard lock(mu_);
  return latest_;
}

std::shared_ptr<const LiveSnapshot> LiveState::WaitNewer(int64_t version, std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mu_);
  const int64_t woken = wakes_;
  cv_.wait_for(lock, timeout, [&] { return latest_->version > version || wakes_ != woken; });
  return latest_;
}

void LiveState::Publish(std::shared_ptr<const LiveSnapshot> snapshot) {
  {
    std::lock_guard lock(mu_);
    latest_ = std::move(snapshot);
  }
  cv_.notify_all();
}

void LiveState::Wake() {
  {
    std::lock_guard lock(mu_);
    ++wakes_;
  }
  cv_.notify_all();
}

void LiveState::SetRunning(bool running, const std::string& ended) {
  std::lock_guard lock(mu_);
  running_ = running;
  starting_ = false;
  ended_ = ended;
}

void LiveState::SetStarting() {
  std::lock_guard lock(mu_);
  running_ = false;
  starting_ = true;
}

bool LiveState::starting() const {
  std::lock_guard lock(mu_);
  return starting_;
}

bool LiveState::running() const {
  std::lock_guard lock(mu_);
  return running_;
}

std::string LiveState::ended() const {
  std::lock_guard lock(mu_);
  return ended_;
}

double LiveState::uptime_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

std::shared_ptr<const LiveCoverage> LiveState::coverage() const {
  std::lock_guard lock(mu_);
  return coverage_;
}

void LiveState::SetCoverage(std::shared_ptr<LiveCoverage> coverage) {
  std::lock_guard lock(mu_);
  if (coverage) coverage->version = ++coverage_version_;
  coverage_ = std::move(coverage);
}

int64_t LiveState::next_version() {
  std::lock_guard lock(mu_);
  return ++version_;
}

void LiveState::SetMqtt(std::shared_ptr<const MqttSink> mqtt) {
  std::lock_guard lock(mu_);
  mqtt_ = std::move(mqtt);
}

std::shared_ptr<const MqttSink> LiveState::mqtt() const {
  std::lock_guard lock(mu_);
  return mqtt_;
}

std::vector<TrackBox> TrackBoxesInCamera(const CameraModel& camera, const std::vector<Track>& tracks) {
  std::vector<TrackBox> out;
  const ImageSize size = camera.image_size();
  for (const Track& t : tracks) {
    const double height_m = t.object_class == "person" ? 1.7 : 1.0;
    const double half_m = 0.5 * std::clamp(t.area_m2 > 0 ? std::sqrt(t.area_m2) : 0.5, 0.3, 1.0);
    double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
    bool seen = true;
    for (int k = 0; k < 8 && seen; ++k) {
      const Eigen::Vector3d corner(t.x_m + ((k & 1) ? half_m : -half_m), t.y_m + ((k & 2) ? half_m : -half_m),
                                   (k & 4) ? height_m : 0.0);
      const auto px = camera.Project(corner);
      if (!px || !px->allFinite()) {
        seen = false;
        break;
      }
      u0 = std::min(u0, px->x());
      v0 = std::min(v0, px->y());
      u1 = std::max(u1, px->x());
      v1 = std::max(v1, px->y());
    }
    if (!seen || u1 < 0 || v1 < 0 || u0 > size.width - 1 || v0 > size.height - 1) continue;
    TrackBox b;
    b.id = t.id;
    b.object_class = t.object_class;
    b.coasting = t.coasting;
    b.x0 = static_cast<int>(std::lround(std::max(u0, 0.0)));
    b.y0 = static_cast<int>(std::lround(std::max(v0, 0.0)));
    b.x1 = static_cast<int>(std::lround(std::min(u1, size.width - 1.0)));
    b.y1 = static_cast<int>(std::lround(std::min(v1, size.height - 1.0)));
    out.push_back(std::move(b));
  }
  return out;
}

Status LiveStateSink::Open(const SinkStart& start) {
  camera_ids_ = start.camera_ids;
  cameras_.assign(camera_ids_.size(), nullptr);
  if (start.site != nullptr) {
    for (size_t i = 0; i < camera_ids_.size(); ++i) {
      for (const SiteCamera& c : start.site->cameras) {
        if (c.id == camera_ids_[i]) cameras_[i] = c.camera.get();
      }
    }
  }
  zone_names_.clear();
  line_names_.clear();
  if (start.site != nullptr) {
    for (const auto& z : start.site->tracking.zones) zone_names_.push_back(z.name);
    for (const auto& l : start.site->tracking.lines) line_names_.push_back(l.name);
  }
  if (start.lut != nullptr) {
    auto c = std::make_shared<LiveCoverage>();
    c->grid = start.lut->grid();
    c->num_cameras = start.lut->num_cameras();
    c->view_count.assign(start.lut->view_count().begin(), start.lut->view_count().end());
    state_->SetCoverage(std::move(c));
  }
  state_->SetFps(start.fps);
  state_->SetRunning(true);
  return Status::Ok();
}

Status LiveStateSink::Consume(const FrameRecord& record, const RunStats& stats) {
  // The copy happens here, on the run's writer thread, without the state's lock; the swap is
  // a pointer under it.
  const std::shared_ptr<const LiveSnapshot> previous = state_->Latest();
  auto s = std::make_shared<LiveSnapshot>();
  s->frame = record.frame;
  s->time_s = record.time_s;
  s->t_unix = record.t_unix;
  s->map = record.map;
  s->detections = record.detections;
  s->tracks = record.tracks;
  s->zone_names = zone_names_;
  s->zone_counts = record.zones.counts;
  s->zone_counts.resize(zone_names_.size(), 0);
  s->line_names = line_names_;
  s->line_counts = record.lines.counts;
  s->line_counts.resize(line_names_.size());
  s->stats = stats;
  // On the writer thread, where the MQTT sink changes its publisher (Open, Close).
  if (const auto mqtt = state_->mqtt()) s->mqtt = mqtt->counters();
  s->camera_ids = camera_ids_;
  const size_t n = camera_ids_.size();
  const bool same_cameras = previous->camera_ids == camera_ids_;
  s->frames_gray.resize(n);
  s->frames_rgb.resize(n);
  s->change_masks.resize(n);
  for (size_t i = 0; i < n; ++i) {
    // A fuse's cameras come as their changes alone (no frames).
    const bool here = (i < record.frames_gray.size() && !record.frames_gray[i].empty()) ||
                      (i < record.change_masks.size() && !record.change_masks[i].empty());
    if (here) {
      if (i < record.frames_gray.size()) s->frames_gray[i] = record.frames_gray[i];
      if (i < record.frames_rgb.size()) s->frames_rgb[i] = record.frames_rgb[i];
      if (i < record.change_masks.size()) s->change_masks[i] = record.change_masks[i];
    } else if (same_cameras) {  // the camera missed this set: its last picture stays
      s->frames_gray[i] = previous->frames_gray[i];
      s->frames_rgb[i] = previous->frames_rgb[i];
      s->change_masks[i] = previous->change_masks[i];
    }
  }
  s->track_boxes.resize(n);
  for (size_t i = 0; i < n && i < cameras_.size(); ++i) {
    if (cameras_[i] != nullptr) s->track_boxes[i] = TrackBoxesInCamera(*cameras_[i], record.tracks);
  }
  s->recent_events = previous->recent_events;
  s->events_total = previous->events_total + static_cast<int64_t>(record.event_lines.size());
  s->recent_events.insert(s->recent_events.end(), record.event_lines.begin(), record.event_lines.end());
  if (s->recent_events.size() > kRecentEvents) {
    s->recent_events.erase(s->recent_events.begin(),
                           s->recent_events.end() - static_cast<ptrdiff_t>(kRecentEvents));
  }
  s->version = state_->next_version();
  state_->Publish(std::move(s));
  return Status::Ok();
}

Status LiveStateSink::Close(const RunStats& stats) {
  const std::shared_ptr<const LiveSnapshot> previous = state_->Latest();
  auto s = std::make_shared<LiveSnapshot>(*previous);
  s->stats = stats;
  if (const auto mqtt = state_->mqtt()) s->mqtt = mqtt->counters();
  s->version = state_->next_version();
  state_->Publish(std::move(s));
  state_->SetRunning(false, stats.stop_reason);
  return Status::Ok();
}

}  // namespace occmap
