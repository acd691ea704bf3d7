#include "occmap/pipeline/edge_align.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace occmap {
namespace {
double Seconds(std::chrono::steady_clock::duration d) { return std::chrono::duration<double>(d).count(); }
}  // namespace

FrameSetAligner::FrameSetAligner(size_t cameras, const AlignOptions& options, Clock::time_point start)
    : options_(options),
      start_(start),
      pending_(cameras),
      ended_(cameras, false),
      heard_(cameras, false),
      in_last_set_(cameras, false),
      last_heard_(cameras, start),
      last_taken_(cameras, -std::numeric_limits<double>::infinity()),
      left_out_(cameras, 0),
      ended_frame_(cameras, 0),
      late_(cameras, 0) {}

int64_t FrameSetAligner::late() const {
  int64_t total = 0;
  for (const int64_t n : late_) total += n;
  return total;
}

double FrameSetAligner::Key(const EdgeMessage& m) const {
  return options_.sync == FrameSync::kTimestamp ? m.timestamp_s : static_cast<double>(m.frame);
}

void FrameSetAligner::Add(EdgeMessage m, Clock::time_point arrival) {
  const size_t c = m.camera;
  last_heard_[c] = arrival;
  heard_[c] = true;
  ended_[c] = false;
  const double key = Key(m);
  // Late: its set is fused already (without it), or it is not newer than what the camera gave.
  if (key <= last_taken_[c] || (last_anchor_ && key <= *last_anchor_ + tolerance() && !in_last_set_[c])) {
    ++late_[c];
    return;
  }
  auto& q = pending_[c];
  auto at = std::upper_bound(q.begin(), q.end(), key, [](double k, const Pending& p) { return k < p.key; });
  q.insert(at, Pending{std::move(m), key, arrival});
}

void FrameSetAligner::End(size_t camera, int64_t frame, Clock::time_point arrival) {
  ended_frame_[camera] = frame;
  last_heard_[camera] = arrival;
  heard_[camera] = true;
  ended_[camera] = true;
}

bool FrameSetAligner::all_ended() const { return std::all_of(ended_.begin(), ended_.end(), [](bool e) { return e; }); }

bool FrameSetAligner::idle() const {
  return std::all_of(pending_.begin(), pending_.end(), [](const auto& q) { return q.empty(); });
}

bool FrameSetAligner::alive(size_t camera, Clock::time_point now) const {
  return Seconds(now - std::max(last_heard_[camera], start_)) < options_.dead_after_s;
}

std::optional<AlignedSet> FrameSetAligner::Next(Clock::time_point now) {
  if (idle()) return std::nullopt;
  const size_t n = pending_.size();
  const bool everything_ended = all_ended();
  if (sets_ == 0 && !everything_ended && !std::all_of(heard_.begin(), heard_.end(), [](bool h) { return h; }) &&
      Seconds(now - start_) < options_.start_wait_s) {
    return std::nullopt;
  }
  double anchor = std::numeric_limits<double>::infinity();
  for (const auto& q : pending_) {
    if (!q.empty()) anchor = std::min(anchor, q.front().key);
  }
  bool complete = true;
  Clock::time_point first = Clock::time_point::max();
  for (size_t c = 0; c < n; ++c) {
    if (!pending_[c].empty()) {
      if (pending_[c].front().key <= anchor + tolerance()) first = std::min(first, pending_[c].front().arrival);
      continue;
    }
    if (!ended_[c] && alive(c, now)) complete = false;
  }
  if (!complete && !everything_ended && Seconds(now - first) < options_.latency_budget_s) return std::nullopt;
  AlignedSet set;
  set.frame = options_.sync == FrameSync::kTimestamp ? sets_ : static_cast<int64_t>(anchor);
  set.time = anchor;
  set.first_arrival = first;
  set.cameras.resize(n);
  for (size_t c = 0; c < n; ++c) {
    auto& q = pending_[c];
    in_last_set_[c] = !q.empty() && q.front().key <= anchor + tolerance();
    if (in_last_set_[c]) {
      last_taken_[c] = q.front().key;
      set.cameras[c] = std::move(q.front().message);
      q.pop_front();
    } else if (!ended_[c]) {
      ++left_out_[c];
    }
  }
  last_anchor_ = anchor;
  ++sets_;
  return set;
}

}  // namespace occmap
