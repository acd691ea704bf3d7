// Counting lines: segments on the floor (TrackerOptions::lines) that count the tracks crossing
// them in each direction, with one event per crossing and cumulative counts per line.
//
// Direction: looking from a line's `from_m` to its `to_m`, "in" is a crossing from the right
// side to the left side, "out" from left to right (for a line from (0, 0) to (0, 1), "in" is
// moving towards -x).
// A crossing, per track: the track was last seen on one side, is now on the other, and the
// straight step between those two positions meets the segment (ends included). A side starts
// LineOptions::hysteresis_m from the line (1 nm with 0): a position within that band is on
// neither side, so a track that enters the band and turns back crosses nothing, one that
// lingers in it and then goes on crosses once, when it leaves on the far side, and a track
// jittering on the line crosses nothing. Going round an end of the segment crosses nothing.
// With LineOptions::once_per_track (the default) a track counts at most once in each direction:
// one who wanders over the line and back is one "in" and one "out", however often.
// Only measured positions count: a coasting track (no detection this frame) keeps its last
// side until it is measured again, so a prediction never crosses a line on its own; a track
// no longer reported is forgotten (memory stays bounded by the live tracks).
//
//   OCCMAP_ASSIGN_OR_RETURN(LineCounter lines, LineCounter::Create(options.lines));
//   LineFrame f = lines.Update(frame, time_s, tracks);
//   for (const LineEvent& e : f.events) events.Append(LineEventJsonLine(e) + "\n");
//   int64_t in = f.counts[0].in;
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

enum class LineDirection { kIn, kOut };
std::string_view ToString(LineDirection direction);  // "in", "out"

struct LineCounts {
  int64_t in = 0;
  int64_t out = 0;
  friend bool operator==(const LineCounts&, const LineCounts&) = default;
};

struct LineEvent {
  int64_t frame = 0;
  double time_s = 0;
  std::string line;
  int64_t track_id = 0;
  LineDirection direction = LineDirection::kIn;
  LineCounts counts;  // the line's cumulative counts, this crossing included
  friend bool operator==(const LineEvent&, const LineEvent&) = default;
};

struct LineFrame {
  std::vector<LineEvent> events;   // this frame's crossings
  std::vector<LineCounts> counts;  // per line, in the lines' order: cumulative after this frame
};

// The side of the directed line through from_m and to_m the point is on: +1 left, -1 right,
// 0 within band_m of the line (at least 1 nm).
int SideOfLine(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m, const Eigen::Vector2d& point_m,
               double band_m = 0);

class LineCounter {
 public:
  // Fails on lines TrackerOptions::Validate would refuse.
  static Result<LineCounter> Create(const std::vector<LineOptions>& lines);

  // The crossings of this frame: line by line in the lines' order, within a line in increasing
  // track id.
  LineFrame Update(int64_t frame, double time_s, const std::vector<Track>& tracks);

  const std::vector<LineOptions>& lines() const { return lines_; }
  const std::vector<LineCounts>& counts() const { return counts_; }  // per line, cumulative

 private:
  explicit LineCounter(const std::vector<LineOptions>& lines)
      : lines_(lines), counts_(lines.size()), sides_(lines.size()) {}

  struct Side {
    int side = 0;                     // of the last position off the line; 0: none yet
    Eigen::Vector2d point_m{0, 0};    // that position
    bool counted_in = false, counted_out = false;  // once_per_track: already counted
  };

  std::vector<LineOptions> lines_;
  std::vector<LineCounts> counts_;
  std::vector<std::map<int64_t, Side>> sides_;  // per line: live tracks by id
};

}  // namespace occmap
