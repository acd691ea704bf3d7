#include "occmap/track/zones.h"

#include <algorithm>

namespace occmap {
namespace {

constexpr double kTimeSlackS = 1e-9;

}  // namespace

std::string_view ToString(ZoneEventKind kind) {
  switch (kind) {
    case ZoneEventKind::kEnter: return "enter";
    case ZoneEventKind::kLeave: return "leave";
    case ZoneEventKind::kDwell: return "dwell";
    case ZoneEventKind::kCount: return "count";
  }
  return "?";
}

bool PointInPolygon(const std::vector<Eigen::Vector2d>& polygon_m, const Eigen::Vector2d& point_m) {
  bool inside = false;
  const size_t n = polygon_m.size();
  for (size_t k = 0, prev = n - 1; k < n; prev = k++) {
    const Eigen::Vector2d& a = polygon_m[k];
    const Eigen::Vector2d& b = polygon_m[prev];
    if ((a.y() > point_m.y()) != (b.y() > point_m.y())) {
      const double x_cross = a.x() + (point_m.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (point_m.x() < x_cross) inside = !inside;
    }
  }
  return inside;
}

Result<ZoneMonitor> ZoneMonitor::Create(const std::vector<ZoneOptions>& zones, bool count_every_frame) {
  TrackerOptions check;
  check.zones = zones;
  OCCMAP_RETURN_IF_ERROR(check.Validate());
  return ZoneMonitor(zones, count_every_frame);
}

ZoneFrame ZoneMonitor::Update(int64_t frame, double time_s, const std::vector<Track>& tracks) {
  std::vector<const Track*> by_id;
  by_id.reserve(tracks.size());
  for (const Track& t : tracks) by_id.push_back(&t);
  std::sort(by_id.begin(), by_id.end(), [](const Track* a, const Track* b) { return a->id < b->id; });

  ZoneFrame result;
  result.counts.resize(zones_.size(), 0);
  for (size_t z = 0; z < zones_.size(); ++z) {
    const ZoneOptions& zone = zones_[z];
    std::map<int64_t, Visit>& visits = visits_[z];
    std::map<int64_t, Visit> now;
    std::vector<int64_t> entered;
    for (const Track* t : by_id) {
      if (!PointInPolygon(zone.polygon_m, {t->x_m, t->y_m})) continue;
      auto it = visits.find(t->id);
      if (it != visits.end()) {
        now.emplace(t->id, it->second);
      } else {
        now.emplace(t->id, Visit{time_s, false});
        entered.push_back(t->id);
      }
    }
    const int count = static_cast<int>(now.size());
    result.counts[z] = count;
    auto event = [&](int64_t id, ZoneEventKind kind) {
      result.events.push_back(ZoneEvent{frame, time_s, zone.name, id, kind, count});
    };
    for (const auto& [id, visit] : visits) {
      if (!now.contains(id)) event(id, ZoneEventKind::kLeave);
    }
    for (int64_t id : entered) event(id, ZoneEventKind::kEnter);
    if (zone.dwell_s) {
      for (auto& [id, visit] : now) {
        if (!visit.dwell_reported && time_s - visit.enter_time_s >= *zone.dwell_s - kTimeSlackS) {
          visit.dwell_reported = true;
          event(id, ZoneEventKind::kDwell);
        }
      }
    }
    if (count_every_frame_ || count != last_counts_[z]) event(-1, ZoneEventKind::kCount);
    last_counts_[z] = count;
    visits = std::move(now);
  }
  return result;
}

}  // namespace occmap
