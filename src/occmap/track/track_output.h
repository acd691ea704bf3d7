// Track outputs: one JSON line per frame for tracks.jsonl, one per zone event for
// events.jsonl, MOTChallenge ground-plane CSV rows, and trails (recent positions) to draw.
//
// tracks.jsonl, one line per frame (positions rounded to 0.1 mm, velocities to 0.1 mm/s,
// time to 1 us; tracks as given, the trackers give them in increasing id):
//   {"frame":12,"time_s":1.2,"tracks":[{"id":3,"x_m":1.5,"y_m":2.0,"vx_mps":0.8,"vy_mps":-0.1,"class":"person"}]}
// events.jsonl, one line per event (ZoneEvent; "track_id" is null for "count" events):
//   {"frame":12,"time_s":1.2,"zone":"door","track_id":3,"event":"enter","count":1}
// and one per line crossing (LineEvent; "in"/"out": the line's counts, this crossing included):
//   {"frame":12,"time_s":1.2,"line":"gate","track_id":3,"event":"cross","direction":"in","in":5,"out":2}
// MOTChallenge ground-plane rows: the MOT 3D convention, 10 columns, world metres:
//   frame,id,-1,-1,-1,-1,conf,x,y,z
//   frame  = occmap frame + 1 (MOTChallenge frames count from 1)
//   id     = the track id (> 0)
//   -1 x 4 = the image bounding box (left, top, width, height), unused on the ground plane
//   conf   = 1
//   x, y   = position on the floor in world metres, 4 decimals
//   z      = -1 (unused: the floor plane)
//   e.g.  13,3,-1,-1,-1,-1,1,1.5000,2.0000,-1
//
//   OCCMAP_RETURN_IF_ERROR(tracks_file.Append(TracksJsonLine(frame, time_s, tracks) + "\n"));
//   OCCMAP_RETURN_IF_ERROR(mot_file.Append(MotGroundPlaneRows(frame, tracks)));
//   trails.Update(tracks);  for (const Trail& t : trails.Trails()) DrawPolyline(t.points_m);
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/track/count_lines.h"
#include "occmap/track/track.h"
#include "occmap/track/zones.h"

namespace occmap {

// One line of tracks.jsonl, without the newline.
std::string TracksJsonLine(int64_t frame, double time_s, const std::vector<Track>& tracks);
// One line of events.jsonl, without the newline.
std::string ZoneEventJsonLine(const ZoneEvent& event);
// One line of events.jsonl for a line crossing, without the newline.
std::string LineEventJsonLine(const LineEvent& event);
// `text` as a JSON string literal, quotes included.
std::string JsonQuote(std::string_view text);

// One MOTChallenge ground-plane row, without the newline (columns above).
std::string MotGroundPlaneRow(int64_t frame, const Track& track);
// The rows of all tracks of a frame, each ending with a newline.
std::string MotGroundPlaneRows(int64_t frame, const std::vector<Track>& tracks);

struct Trail {
  int64_t id = 0;
  std::vector<Eigen::Vector2d> points_m;  // oldest first, the current position last
};

// The last max_points positions of each track, for drawing on the map. A track that is not
// reported in a frame has ended: its trail is dropped.
class TrailHistory {
 public:
  explicit TrailHistory(int max_points) : max_points_(max_points < 1 ? 1 : max_points) {}
  void Update(const std::vector<Track>& tracks);
  std::vector<Trail> Trails() const;  // in increasing id

 private:
  size_t max_points_;
  std::map<int64_t, std::deque<Eigen::Vector2d>> trails_;
};

}  // namespace occmap
