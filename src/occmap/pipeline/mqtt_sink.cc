#include "occmap/pipeline/mqtt_sink.h"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "occmap/pipeline/output_files.h"
#include "occmap/pipeline/summary_file.h"
#include "occmap/track/track_output.h"

namespace occmap {
namespace {

double WallClockNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace

std::string MqttStatsJson(double t_unix, const RunStats& stats, const std::vector<double>& camera_fps,
                          int64_t line_crossings, const MqttCounters& mqtt) {
  using nlohmann::json;
  json cameras = json::array();
  for (size_t n = 0; n < stats.cameras.size(); ++n) {
    const CameraStats& c = stats.cameras[n];
    cameras.push_back({{"id", c.id},
                       {"active", c.active},
                       {"connected", c.connected},
                       {"frames", c.frames},
                       {"frames_per_second", n < camera_fps.size() ? std::round(camera_fps[n] * 100) / 100 : 0.0},
                       {"dropped", c.dropped},
                       {"reconnects", c.reconnects}});
    if (c.background_cache) cameras.back()["background_cache"] = BackgroundCacheJson(*c.background_cache);
  }
  const json j = {{"t_unix", std::round(t_unix * 1e3) / 1e3},
                  {"frames", stats.frames},
                  {"elapsed_s", std::round(stats.elapsed_s * 1e3) / 1e3},
                  {"frames_per_second", std::round(stats.frames_per_second * 100) / 100},
                  {"cameras", cameras},
                  {"latency_ms",
                   {{"p50", stats.latency.p50_ms}, {"p95", stats.latency.p95_ms}, {"p99", stats.latency.p99_ms},
                    {"max", stats.latency.max_ms}}},
                  {"tracks", stats.tracks},
                  {"zone_events", stats.zone_events},
                  {"line_crossings", line_crossings},
                  {"mqtt",
                   {{"published", mqtt.published},
                    {"dropped", mqtt.dropped},
                    {"connects", mqtt.connects},
                    {"disconnects", mqtt.disconnects}}}};
  return j.dump();
}

std::string MqttMapPng(const OccupancyMap& map, const std::vector<Track>& tracks) {
  const FloorGrid& g = map.grid();
  if (g.num_cells() == 0 || map.states().size() != static_cast<size_t>(g.num_cells())) return {};
  const int scale = std::max(1, 480 / std::max(g.cells_x, g.cells_y));
  cv::Mat bgr(g.cells_y * scale, g.cells_x * scale, CV_8UC3);
  for (int j = 0; j < g.cells_y; ++j) {
    for (int i = 0; i < g.cells_x; ++i) {
      const CellState st = map.state(int64_t{j} * g.cells_x + i);
      const uint8_t v = st == CellState::kFree ? 255 : st == CellState::kOccupied ? 0 : 205;
      bgr(cv::Rect(i * scale, (g.cells_y - 1 - j) * scale, scale, scale)).setTo(cv::Scalar(v, v, v));
    }
  }
  const double px_per_m = scale / g.cell_size_m;
  for (const Track& t : tracks) {
    const cv::Point centre(static_cast<int>(std::lround((t.x_m - g.origin_x_m) * px_per_m)),
                           static_cast<int>(std::lround(g.cells_y * scale - (t.y_m - g.origin_y_m) * px_per_m)));
    cv::circle(bgr, centre, std::max(3, static_cast<int>(0.2 * px_per_m)), cv::Scalar(40, 40, 220), cv::FILLED,
               cv::LINE_AA);
  }
  std::vector<uint8_t> png;
  if (!cv::imencode(".png", bgr, png)) return {};
  return std::string(png.begin(), png.end());
}

std::string CameraStateName(const CameraStats& camera) {
  if (!camera.active) return "ended";
  return camera.connected ? "streaming" : "reconnecting";
}

std::string RunStateAfter(const std::string& stop_reason) {
  for (const char* ended : {"end of streams", "frame limit", "stop requested", "stopped"}) {
    if (stop_reason == ended) return "ended";
  }
  return "failed";
}

Status MqttSink::Open(const SinkStart& start) {
  MqttPublisherInfo info;
  info.site_name = start.site->name;
  info.cameras = start.camera_ids;
  info.on_status = on_status_;
  first_frame_ = true;
  if (start.track) {
    for (const ZoneOptions& z : start.site->tracking.zones) info.zones.push_back(z.name);
    for (const LineOptions& l : start.site->tracking.lines) info.lines.push_back(l.name);
  }
  OCCMAP_ASSIGN_OR_RETURN(publisher_, MqttPublisher::Start(options_, info));
  last_stats_ = std::chrono::steady_clock::now();
  last_camera_frames_.assign(start.camera_ids.size(), 0);
  return Status::Ok();
}

Status MqttSink::Consume(const FrameRecord& r, const RunStats& stats) {
  MqttFrame frame;
  // The lines of tracks.jsonl and events.jsonl, as the run made them.
  frame.tracks_json = r.tracks_line;
  frame.events_json = r.event_lines;
  frame.zone_counts = r.zones.counts;
  frame.line_counts = r.lines.counts;
  frame.people = 0;
  for (const Track& t : r.tracks) frame.people += t.object_class == "person" ? 1 : 0;
  line_crossings_ += static_cast<int64_t>(r.lines.events.size());
  publisher_->PublishFrame(frame);
  const auto now = std::chrono::steady_clock::now();
  if (std::chrono::duration<double>(now - last_stats_).count() >= options_.stats_every_s) {
    SendStats(stats);
    publisher_->PublishMap(MqttMapPng(r.map, r.tracks));
  } else if (first_frame_) {  // the cameras' states and the map at once, their rates with the stats
    std::vector<std::string> states;
    for (const CameraStats& c : stats.cameras) states.push_back(CameraStateName(c));
    publisher_->PublishCameras(states, {});
    publisher_->PublishMap(MqttMapPng(r.map, r.tracks));
  }
  first_frame_ = false;
  return Status::Ok();
}

void MqttSink::SendStats(const RunStats& stats) {
  const auto now = std::chrono::steady_clock::now();
  const double dt_s = std::chrono::duration<double>(now - last_stats_).count();
  std::vector<double> fps(stats.cameras.size(), 0.0);
  last_camera_frames_.resize(stats.cameras.size(), 0);
  for (size_t n = 0; n < stats.cameras.size(); ++n) {
    if (dt_s > 0) fps[n] = static_cast<double>(stats.cameras[n].frames - last_camera_frames_[n]) / dt_s;
    last_camera_frames_[n] = stats.cameras[n].frames;
  }
  last_stats_ = now;
  std::vector<std::string> states;
  for (const CameraStats& c : stats.cameras) states.push_back(CameraStateName(c));
  publisher_->PublishCameras(states, fps);
  publisher_->PublishStats(MqttStatsJson(WallClockNow(), stats, fps, line_crossings_, publisher_->counters()));
}

Status MqttSink::Close(const RunStats& stats) {
  if (!publisher_) return Status::Ok();
  SendStats(stats);
  publisher_->PublishRunState(RunStateAfter(stats.stop_reason), stats.stop_reason);
  publisher_->Stop();
  return Status::Ok();
}

}  // namespace occmap
