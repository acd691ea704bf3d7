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
      newest_(cameras, -std::numeric_limits<double>::infinity()),
      left_out_(cameras, 0),
      ended_frame_(cameras, 0),
      late_(cameras, 0),
      duplicates_(cameras, 0) {}

int64_t FrameSetAligner::late() const {
  int64_t total = 0;
  for (const int64_t n : late_) total += n;
  return total;
}

int64_t FrameSetAligner::duplicates() const {
  int64_t total = 0;
  for (const int64_t n : duplicates_) total += n;
  return total;
}

double FrameSetAligner::Key(const EdgeMessage& m) const {
  return options_.sync == FrameSync::kTimestamp ? m.timestamp_s : static_cast<double>(m.frame);
}

void FrameSetAligner::Add(EdgeMessage m, Clock::time_point arrival) {
  const size_t c = m.camera;
  const double key = Key(m);
  auto& q = pending_[c];
  // A copy: dropped. If the first copy was a replay that came early, this one is the camera's
  // own, in order: its stream has reached the key (no evidence that it is alive otherwise).
  if (key == last_taken_[c] || std::any_of(q.begin(), q.end(), [&](const Pending& p) { return p.key == key; })) {
    ++duplicates_[c];
    if (key > newest_[c]) MoveStream(c, key, arrival);
    return;
  }
  last_heard_[c] = arrival;
  heard_[c] = true;
  // Late: its set is fused already (without it), or it is not newer than what the camera gave.
  // It does not revive an ended camera (a replay of an old message would hold sets up).
  if (key <= last_taken_[c] || (last_anchor_ && key <= *last_anchor_ + tolerance() && !in_last_set_[c])) {
    ++late_[c];
    return;
  }
  ended_[c] = false;
  auto at = std::upper_bound(q.begin(), q.end(), key, [](double k, const Pending& p) { return k < p.key; });
  q.insert(at, Pending{std::move(m), key, arrival, std::nullopt});
  MoveStream(c, key, arrival);
}

void FrameSetAligner::MoveStream(size_t c, double key, Clock::time_point arrival) {
  for (Pending& p : pending_[c]) {
    if (p.key > key) {
      p.reached.reset();  // back (a message older than those that came first): not reached yet
    } else if (!p.reached) {
      p.reached = arrival;
    }
  }
  newest_[c] = key;
}

void FrameSetAligner::End(size_t camera, int64_t frame, Clock::time_point arrival) {
  ended_frame_[camera] = frame;
  last_heard_[camera] = arrival;
  heard_[camera] = true;
  ended_[camera] = true;
}

void FrameSetAligner::Resume(Clock::time_point now) {
  for (size_t c = 0; c < pending_.size(); ++c) {
    if (heard_[c]) last_heard_[c] = std::max(last_heard_[c], now);
    for (Pending& p : pending_[c]) {
      if (p.reached) p.reached = std::max(*p.reached, now);
    }
  }
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
  // By index before the first set: the edges' first frame, or start_wait_s.
  const bool first_by_index = sets_ == 0 && options_.sync == FrameSync::kIndex && !everything_ended;
  if (first_by_index && anchor > static_cast<double>(options_.first_frame) && Seconds(now - start_) < options_.start_wait_s) {
    return std::nullopt;
  }
  bool complete = true;
  Clock::time_point first = Clock::time_point::max();
  for (size_t c = 0; c < n; ++c) {
    const auto& q = pending_[c];
    // Its message for the anchor, and its stream has reached it (its last accepted arrival is
    // not older): a message that came before older ones (a copy published early) waits for the
    // camera's own, or for the budget counted from a message that did reach it.
    if (!q.empty() && q.front().key <= anchor + tolerance() && q.front().reached) {
      first = std::min(first, *q.front().reached);
      continue;
    }
    // Its last message is past the anchor: one per topic arrives in order, so the anchor's is
    // lost. Not for the first set by index, where every camera starts at the same frame.
    if (!q.empty() && newest_[c] > anchor + tolerance() && !first_by_index) continue;
    // Silent is not dead before the first set by index (start_wait_s rules): a camera heard
    // only from copies published long before its edge started is waited for.
    const bool waited = first_by_index && Seconds(now - start_) < options_.start_wait_s;
    if (!ended_[c] && (alive(c, now) || waited)) complete = false;
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
