#include "occmap/track/count_lines.h"

#include <algorithm>
#include <cmath>

namespace occmap {
namespace {

constexpr double kOnLineM = 1e-9;

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

// Whether the step from p to q, whose ends are strictly on opposite sides of the line through
// a and b, meets the closed segment [a, b].
bool StepMeetsSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p,
                      const Eigen::Vector2d& q) {
  const Eigen::Vector2d ab = b - a;
  const double sp = Cross(ab, p - a), sq = Cross(ab, q - a);
  const Eigen::Vector2d hit = p + (sp / (sp - sq)) * (q - p);
  const double u = (hit - a).dot(ab) / ab.squaredNorm();
  return u >= 0.0 && u <= 1.0;
}

}  // namespace

std::string_view ToString(LineDirection direction) {
  return direction == LineDirection::kIn ? "in" : "out";
}

int SideOfLine(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m, const Eigen::Vector2d& point_m,
               double band_m) {
  const Eigen::Vector2d ab = to_m - from_m;
  // The cross product over the length is the signed distance from the line.
  const double distance_m = Cross(ab, point_m - from_m) / ab.norm();
  if (std::abs(distance_m) <= std::max(band_m, kOnLineM)) return 0;
  return distance_m > 0 ? 1 : -1;
}

Result<LineCounter> LineCounter::Create(const std::vector<LineOptions>& lines) {
  TrackerOptions check;
  check.lines = lines;
  OCCMAP_RETURN_IF_ERROR(check.Validate());
  return LineCounter(lines);
}

LineFrame LineCounter::Update(int64_t frame, double time_s, const std::vector<Track>& tracks) {
  std::vector<const Track*> by_id;
  by_id.reserve(tracks.size());
  for (const Track& t : tracks) by_id.push_back(&t);
  std::sort(by_id.begin(), by_id.end(), [](const Track* a, const Track* b) { return a->id < b->id; });

  LineFrame result;
  std::vector<LineEvent>& events = result.events;
  for (size_t l = 0; l < lines_.size(); ++l) {
    const LineOptions& line = lines_[l];
    std::map<int64_t, Side> now;
    for (const Track* t : by_id) {
      auto it = sides_[l].find(t->id);
      Side state = it != sides_[l].end() ? it->second : Side{};
      const Eigen::Vector2d point_m(t->x_m, t->y_m);
      const int side = t->coasting ? 0 : SideOfLine(line.from_m, line.to_m, point_m, line.hysteresis_m);
      if (side != 0) {
        if (state.side != 0 && side != state.side && StepMeetsSegment(line.from_m, line.to_m, state.point_m, point_m)) {
          // Right (-1) to left (+1) is "in".
          const bool in = side > 0;
          bool& counted = in ? state.counted_in : state.counted_out;
          if (!counted || !line.once_per_track) {
            (in ? counts_[l].in : counts_[l].out) += 1;
            events.push_back(LineEvent{frame, time_s, line.name, t->id, in ? LineDirection::kIn : LineDirection::kOut,
                                       counts_[l]});
          }
          counted = true;
        }
        state.side = side;
        state.point_m = point_m;
      }
      now.emplace(t->id, state);
    }
    sides_[l] = std::move(now);
  }
  result.counts = counts_;
  return result;
}

}  // namespace occmap
