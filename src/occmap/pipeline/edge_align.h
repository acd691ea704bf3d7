// FrameSetAligner: how `occmap fuse` groups the edges' messages (edge_message.h) into frame
// sets. By frame index (files: every edge starts at the same frame, the sets are exact) or by
// timestamp within a tolerance (live streams: no common frame index; the edges' wall clocks,
// kept in step by NTP or PTP, time each frame's arrival).
//
// A set is anchored at the oldest pending message; each camera gives its oldest message within
// the tolerance of the anchor (by index: the same frame). The set is fused as soon as every
// camera is decided: it has a message pending (one per topic arrives in order, so a later one
// means the anchor's is lost), it has reported the end of its source, or it has been silent for
// dead_after_s (dead until it sends again: a restarted edge rejoins by itself). Otherwise it is
// fused when latency_budget_s has passed since its first message arrived: the cameras missing
// then are left out (their cells unseen) and their messages for it, arriving later, are dropped
// and counted. Before the first set every camera is waited for up to start_wait_s.
//
// The broker is not trusted to deliver each message once and in order (issue 39): a copy of a
// message pending or just taken (a replay, a QoS 1 redelivery) is dropped and counted as a
// duplicate, so no frame set is fused twice. A camera's stream is where its last accepted
// arrival is (a copy of a pending message moves it there too): a pending message counts for a
// set once the stream has reached it, and "a later message decides a camera" once the stream
// is past the anchor (copies of later frames that arrived first decide nothing). By index, the
// first set waits for the edges' first frame (every camera's own message, up to start_wait_s):
// copies of later frames published before the edges started cost no genuine frame.
//
//   FrameSetAligner a(n_cams, options, Clock::now());
//   a.Add(std::move(message), arrival);           // or a.End(camera, frame, arrival)
//   while (auto set = a.Next(Clock::now())) fuse(*set);
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include "occmap/pipeline/edge_message.h"
#include "occmap/pipeline/run.h"

namespace occmap {

struct AlignOptions {
  FrameSync sync = FrameSync::kIndex;
  // kTimestamp: the largest offset of a camera's frame from the anchor. Unsynchronised cameras
  // have any phase: most of a frame interval pairs each camera's next frame with the anchor.
  double tolerance_s = 0.09;
  double latency_budget_s = 1.0;
  double dead_after_s = 3.0;
  double start_wait_s = 30.0;
  // kIndex: the frame the edges start at (the run's start_frame). Before the first set, a set
  // anchored after it waits until start_wait_s from the start.
  int64_t first_frame = 0;
};

struct AlignedSet {
  int64_t frame = 0;      // kIndex: the frame index; kTimestamp: the sets counted from 0
  double time = 0;        // kIndex: the frame index; kTimestamp: the anchor's timestamp
  std::vector<std::optional<EdgeMessage>> cameras;  // absent: left out (cells unseen)
  std::chrono::steady_clock::time_point first_arrival;
};

class FrameSetAligner {
 public:
  using Clock = std::chrono::steady_clock;
  FrameSetAligner(size_t cameras, const AlignOptions& options, Clock::time_point start);

  // A kChanges message of camera m.camera (checked by the caller); a late one or a copy of one
  // pending or last taken (a duplicate) is dropped.
  void Add(EdgeMessage m, Clock::time_point arrival);
  // The camera reported the end of its source (a message it sends after that revives it).
  void End(size_t camera, int64_t frame, Clock::time_point arrival);
  // The fuse's link to the broker is back after an outage: the cameras' silence meanwhile was
  // the broker's, not theirs. Every camera heard counts as heard at `now` and the pending sets'
  // budget counts from `now`, so that what the edges send again joins its set.
  void Resume(Clock::time_point now);
  // Before the first set: the tolerance once the frame rate is known.
  void set_tolerance(double tolerance_s) { options_.tolerance_s = tolerance_s; }
  // The next set ready at `now`, oldest first.
  std::optional<AlignedSet> Next(Clock::time_point now);

  bool all_ended() const;
  bool idle() const;  // nothing pending
  bool ended(size_t camera) const { return ended_[camera]; }
  bool heard(size_t camera) const { return heard_[camera]; }
  int64_t ended_at(size_t camera) const { return ended_frame_[camera]; }  // the frame its End named
  // Heard from within dead_after_s at `now`.
  bool alive(size_t camera, Clock::time_point now) const;
  int64_t late() const;
  int64_t late(size_t camera) const { return late_[camera]; }
  int64_t duplicates() const;
  int64_t duplicates(size_t camera) const { return duplicates_[camera]; }
  // Sets fused without the camera (left out: late, lost, dead; not after its end).
  int64_t left_out(size_t camera) const { return left_out_[camera]; }

 private:
  double Key(const EdgeMessage& m) const;
  double tolerance() const { return options_.sync == FrameSync::kTimestamp ? options_.tolerance_s : 0.0; }

  struct Pending {
    EdgeMessage message;
    double key;
    Clock::time_point arrival;
    // When the camera's stream reached it (its last accepted arrival not older); none while it
    // has not: the budget counts from here.
    std::optional<Clock::time_point> reached;
  };
  // The camera's stream is at `key` (a message accepted, or a copy of a pending one past it).
  void MoveStream(size_t camera, double key, Clock::time_point arrival);
  AlignOptions options_;
  Clock::time_point start_;
  std::vector<std::deque<Pending>> pending_;
  std::vector<bool> ended_, heard_, in_last_set_;
  std::vector<Clock::time_point> last_heard_;
  std::vector<double> last_taken_;
  std::vector<double> newest_;  // the key of each camera's last accepted message (in arrival order)
  std::vector<int64_t> left_out_, ended_frame_;
  std::optional<double> last_anchor_;
  int64_t sets_ = 0;
  std::vector<int64_t> late_, duplicates_;
};

}  // namespace occmap
