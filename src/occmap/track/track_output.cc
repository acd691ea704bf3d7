#include "occmap/track/track_output.h"

#include <fmt/core.h>

#include <cmath>

namespace occmap {
namespace {

// Rounded to a multiple of 1 / scale, without "-0".
double Rounded(double value, double scale) { return std::round(value * scale) / scale + 0.0; }

}  // namespace

std::string JsonQuote(std::string_view text) {
  std::string out = "\"";
  for (const char ch : text) {
    switch (ch) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(ch) < 0x20) {
          out += fmt::format("\\u{:04x}", static_cast<unsigned>(static_cast<unsigned char>(ch)));
        } else {
          out += ch;
        }
    }
  }
  out += '"';
  return out;
}

std::string TracksJsonLine(int64_t frame, double time_s, const std::vector<Track>& tracks) {
  std::string line = fmt::format(R"({{"frame":{},"time_s":{},"tracks":[)", frame, Rounded(time_s, 1e6));
  for (size_t k = 0; k < tracks.size(); ++k) {
    const Track& t = tracks[k];
    if (k > 0) line += ',';
    line += fmt::format(R"({{"id":{},"x_m":{},"y_m":{},"vx_mps":{},"vy_mps":{},"class":{}}})", t.id,
                        Rounded(t.x_m, 1e4), Rounded(t.y_m, 1e4), Rounded(t.vx_mps, 1e4), Rounded(t.vy_mps, 1e4),
                        JsonQuote(t.object_class));
  }
  line += "]}";
  return line;
}

std::string ZoneEventJsonLine(const ZoneEvent& event) {
  return fmt::format(R"({{"frame":{},"time_s":{},"zone":{},"track_id":{},"event":"{}","count":{}}})", event.frame,
                     Rounded(event.time_s, 1e6), JsonQuote(event.zone),
                     event.kind == ZoneEventKind::kCount ? std::string("null") : fmt::format("{}", event.track_id),
                     ToString(event.kind), event.count);
}

std::string LineEventJsonLine(const LineEvent& event) {
  return fmt::format(R"({{"frame":{},"time_s":{},"line":{},"track_id":{},"event":"cross","direction":"{}","in":{},"out":{}}})",
                     event.frame, Rounded(event.time_s, 1e6), JsonQuote(event.line), event.track_id,
                     ToString(event.direction), event.counts.in, event.counts.out);
}

std::string MotGroundPlaneRow(int64_t frame, const Track& track) {
  return fmt::format("{},{},-1,-1,-1,-1,1,{:.4f},{:.4f},-1", frame + 1, track.id, Rounded(track.x_m, 1e4),
                     Rounded(track.y_m, 1e4));
}

std::string MotGroundPlaneRows(int64_t frame, const std::vector<Track>& tracks) {
  std::string rows;
  for (const Track& t : tracks) rows += MotGroundPlaneRow(frame, t) + "\n";
  return rows;
}

void TrailHistory::Update(const std::vector<Track>& tracks) {
  std::map<int64_t, std::deque<Eigen::Vector2d>> next;
  for (const Track& t : tracks) {
    auto it = trails_.find(t.id);
    std::deque<Eigen::Vector2d> points = it != trails_.end() ? std::move(it->second) : std::deque<Eigen::Vector2d>{};
    points.emplace_back(t.x_m, t.y_m);
    while (points.size() > max_points_) points.pop_front();
    next[t.id] = std::move(points);
  }
  trails_ = std::move(next);
}

std::vector<Trail> TrailHistory::Trails() const {
  std::vector<Trail> out;
  out.reserve(trails_.size());
  for (const auto& [id, points] : trails_) out.push_back({id, {points.begin(), points.end()}});
  return out;
}

Result<double> FrameClock::Advance(double time_s) {
  if (!std::isfinite(time_s)) return InvalidInput(fmt::format("tracker: frame time is not finite: {}", time_s));
  if (has_time_ && !(time_s > last_time_s_)) {
    return InvalidInput(
        fmt::format("tracker: frame time {} s is not after the previous frame's {} s", time_s, last_time_s_));
  }
  const double dt_s = has_time_ ? time_s - last_time_s_ : 0.0;
  has_time_ = true;
  last_time_s_ = time_s;
  return dt_s;
}

}  // namespace occmap
