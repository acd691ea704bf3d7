// Zones: named polygons on the floor (TrackerOptions::zones) and the events of tracks
// entering, leaving and dwelling in them, with a count of the tracks inside each zone.
//
// Per frame (ZoneMonitor::Update), with the tracks a tracker reported (coasting ones count,
// at their predicted position), in each zone's order and within it in this order:
//   leave  a track inside last frame is outside now, or is no longer reported (it ended);
//   enter  a track is inside now and was not last frame (a track first reported inside
//          enters at once);
//   dwell  a track has been inside for at least dwell_s since it entered (once per visit;
//          zones without dwell_s never give it), i.e. at the first frame with
//          time_s - enter time_s >= dwell_s (within 1e-9 s);
//   count  the number of tracks inside after this frame: every frame when count_every_frame,
//          else only when it differs from the last frame's (0 before the first frame).
// Events of one kind are in increasing track id. Each event carries the zone's count after
// the frame; "count" events have track_id -1. Inside is the even-odd rule on the polygon
// (PointInPolygon); a point exactly on an edge may fall either way.
//
//   OCCMAP_ASSIGN_OR_RETURN(ZoneMonitor zones, ZoneMonitor::Create(options.zones, options.zone_count_every_frame));
//   ZoneFrame result = zones.Update(frame, time_s, tracks);
//   for (const ZoneEvent& e : result.events) events_file.Append(ZoneEventJsonLine(e) + "\n");
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/track/track.h"
#include "occmap/track/tracker_options.h"
#include "occmap/util/status.h"

namespace occmap {

enum class ZoneEventKind { kEnter, kLeave, kDwell, kCount };
std::string_view ToString(ZoneEventKind kind);  // "enter", "leave", "dwell", "count"

struct ZoneEvent {
  int64_t frame = 0;
  double time_s = 0;
  std::string zone;
  int64_t track_id = -1;  // -1 for kCount
  ZoneEventKind kind = ZoneEventKind::kEnter;
  int count = 0;  // tracks inside the zone after this frame
  friend bool operator==(const ZoneEvent&, const ZoneEvent&) = default;
};

struct ZoneFrame {
  std::vector<ZoneEvent> events;
  std::vector<int> counts;  // per zone, in the zones' order: tracks inside after this frame
};

// Even-odd rule (crossing number) on the polygon's vertices, either orientation.
bool PointInPolygon(const std::vector<Eigen::Vector2d>& polygon_m, const Eigen::Vector2d& point_m);

class ZoneMonitor {
 public:
  // Fails on zones TrackerOptions::Validate would refuse.
  static Result<ZoneMonitor> Create(const std::vector<ZoneOptions>& zones, bool count_every_frame = false);

  ZoneFrame Update(int64_t frame, double time_s, const std::vector<Track>& tracks);

  const std::vector<ZoneOptions>& zones() const { return zones_; }

 private:
  ZoneMonitor(const std::vector<ZoneOptions>& zones, bool count_every_frame)
      : zones_(zones), count_every_frame_(count_every_frame), visits_(zones.size()), last_counts_(zones.size(), 0) {}

  struct Visit {
    double enter_time_s = 0;
    bool dwell_reported = false;
  };

  std::vector<ZoneOptions> zones_;
  bool count_every_frame_ = false;
  std::vector<std::map<int64_t, Visit>> visits_;  // per zone: tracks inside, by id
  std::vector<int> last_counts_;
};

}  // namespace occmap
