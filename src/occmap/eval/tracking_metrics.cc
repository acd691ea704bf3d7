#include "occmap/eval/tracking_metrics.h"

#include <fmt/core.h>

#include <cmath>
#include <limits>
#include <set>

#include "occmap/eval/detection_metrics.h"
#include "occmap/util/hungarian.h"

namespace occmap {
namespace {

void CheckUniqueIds(std::span<const IdPosition> items, const char* what) {
  std::set<int64_t> ids;
  for (const IdPosition& p : items) {
    OCCMAP_CHECK(ids.insert(p.id).second, fmt::format("{} id {} appears twice in one frame", what, p.id));
  }
}

// Identity true positives. The cost of pairing trajectory g with track h, frames not matched
// (len g + len h - 2 within(g, h)), and of leaving either unpaired (its length), sum to
// N_gt + N_pred - 2 IDTP: the min-cost matching of Ristani et al. maximises IDTP, the sum of
// within(g, h) over the pairs. Only ids with some frame within t can add to it, and the
// matching splits into the connected components of the graph of such pairs, solved apart
// (a fragmenting tracker makes many ids; one dense matrix would be O(ids^3)).
int64_t IdentityTruePositives(const std::map<std::pair<int64_t, int64_t>, int64_t>& frames_within) {
  // Union-find over nodes: object ids first, then track ids.
  std::map<int64_t, size_t> node_of_gt, node_of_track;
  for (const auto& [pair, frames] : frames_within) {
    node_of_gt.emplace(pair.first, 0);
    node_of_track.emplace(pair.second, 0);
  }
  size_t nodes = 0;
  for (auto& [id, node] : node_of_gt) node = nodes++;
  for (auto& [id, node] : node_of_track) node = nodes++;
  std::vector<size_t> parent(nodes);
  for (size_t k = 0; k < nodes; ++k) parent[k] = k;
  auto find = [&](size_t k) {
    while (parent[k] != k) k = parent[k] = parent[parent[k]];
    return k;
  };
  for (const auto& [pair, frames] : frames_within) parent[find(node_of_gt[pair.first])] = find(node_of_track[pair.second]);

  struct Component {
    std::map<int64_t, int> row_of_gt, col_of_track;
    std::vector<std::pair<std::pair<int64_t, int64_t>, int64_t>> pairs;
  };
  std::map<size_t, Component> components;
  for (const auto& entry : frames_within) {
    Component& c = components[find(node_of_gt[entry.first.first])];
    c.row_of_gt.emplace(entry.first.first, 0);
    c.col_of_track.emplace(entry.first.second, 0);
    c.pairs.push_back(entry);
  }
  int64_t idtp = 0;
  for (auto& [root, c] : components) {
    int rows = 0, cols = 0;
    for (auto& [id, row] : c.row_of_gt) row = rows++;
    for (auto& [id, col] : c.col_of_track) col = cols++;
    // Cost -within(g, h), no pair forbidden: the optimum is a maximum-weight matching (pairs
    // with within = 0 add nothing, as if unpaired).
    std::vector<double> cost(static_cast<size_t>(rows) * static_cast<size_t>(cols), 0.0);
    for (const auto& [pair, frames] : c.pairs) {
      cost[static_cast<size_t>(c.row_of_gt[pair.first]) * static_cast<size_t>(cols) +
           static_cast<size_t>(c.col_of_track[pair.second])] = -static_cast<double>(frames);
    }
    const std::vector<int> match = SolveAssignment(cost, rows, cols);
    for (int r = 0; r < rows; ++r) {
      const int col = match[static_cast<size_t>(r)];
      if (col >= 0) idtp += std::llround(-cost[static_cast<size_t>(r) * static_cast<size_t>(cols) + static_cast<size_t>(col)]);
    }
  }
  return idtp;
}

}  // namespace

TrackingEvaluator::TrackingEvaluator(const EvalOptions& options) : options_(options) {
  OCCMAP_CHECK(options_.Validate().ok(), options_.Validate().message());
}

void TrackingEvaluator::AddFrame(const GroundTruthFrame& gt, const std::vector<TrackRecord>& tracks) {
  std::vector<IdPosition> gt_items, track_items;
  for (const GroundTruthObject& o : gt.objects) {
    if (options_.EvaluatesClass(o.object_class)) gt_items.push_back({o.id, {o.x_m, o.y_m}});
  }
  for (const TrackRecord& t : tracks) track_items.push_back({t.id, {t.x_m, t.y_m}});
  AddFrame(gt_items, track_items);
}

void TrackingEvaluator::AddFrame(std::span<const IdPosition> gt, std::span<const IdPosition> tracks) {
  CheckUniqueIds(gt, "ground-truth");
  CheckUniqueIds(tracks, "track");
  const double t = options_.match_threshold_m;
  const size_t n_gt = gt.size(), n_tracks = tracks.size();
  auto distance = [&](size_t g, size_t h) { return (gt[g].position_m - tracks[h].position_m).norm(); };

  // Identity measures: every (object, track) pair within t in this frame (through the grid of
  // PairsWithinDistance, not all n_gt x n_tracks pairs).
  {
    std::vector<Eigen::Vector2d> gt_m, tracks_m;
    for (const IdPosition& g : gt) gt_m.push_back(g.position_m);
    for (const IdPosition& h : tracks) tracks_m.push_back(h.position_m);
    for (const PointPair& p : PairsWithinDistance(gt_m, tracks_m, t)) {
      ++frames_within_[{gt[static_cast<size_t>(p.i)].id, tracks[static_cast<size_t>(p.j)].id}];
    }
  }

  // CLEAR MOT step 1: keep the latest correspondences still within t.
  std::vector<int> track_of_gt(n_gt, -1);
  std::vector<char> track_taken(n_tracks, 0);
  std::unordered_map<int64_t, size_t> track_index;
  for (size_t h = 0; h < n_tracks; ++h) track_index[tracks[h].id] = h;
  for (size_t g = 0; g < n_gt; ++g) {
    const auto last = last_track_of_gt_.find(gt[g].id);
    if (last == last_track_of_gt_.end()) continue;
    const auto h = track_index.find(last->second);
    if (h == track_index.end() || last_gt_of_track_.at(last->second) != gt[g].id) continue;
    if (distance(g, h->second) <= t) {
      track_of_gt[g] = static_cast<int>(h->second);
      track_taken[h->second] = 1;
    }
  }
  // Step 2: the Hungarian method on the objects and tracks left.
  std::vector<size_t> free_gt, free_tracks;
  for (size_t g = 0; g < n_gt; ++g) {
    if (track_of_gt[g] < 0) free_gt.push_back(g);
  }
  for (size_t h = 0; h < n_tracks; ++h) {
    if (!track_taken[h]) free_tracks.push_back(h);
  }
  std::vector<Eigen::Vector2d> free_gt_m, free_tracks_m;
  for (size_t g : free_gt) free_gt_m.push_back(gt[g].position_m);
  for (size_t h : free_tracks) free_tracks_m.push_back(tracks[h].position_m);
  const std::vector<int> match = MatchWithinDistance(free_gt_m, free_tracks_m, t);
  for (size_t k = 0; k < free_gt.size(); ++k) {
    if (match[k] < 0) continue;
    const size_t g = free_gt[k], h = free_tracks[static_cast<size_t>(match[k])];
    track_of_gt[g] = static_cast<int>(h);
    const auto last = last_track_of_gt_.find(gt[g].id);
    if (last != last_track_of_gt_.end() && last->second != tracks[h].id) ++id_switches_;
  }

  // Counts, correspondences and trajectory states.
  ++frames_;
  gt_ += static_cast<int64_t>(n_gt);
  predictions_ += static_cast<int64_t>(n_tracks);
  for (const IdPosition& h : tracks) ++track_lengths_[h.id];
  for (size_t g = 0; g < n_gt; ++g) {
    Trajectory& traj = gt_trajectories_[gt[g].id];
    ++traj.frames_present;
    if (track_of_gt[g] < 0) {
      if (traj.ever_matched) traj.in_gap = true;
      continue;
    }
    const auto h = static_cast<size_t>(track_of_gt[g]);
    const double d = distance(g, h);
    ++tp_;
    distance_sum_m_ += d;
    closeness_sum_ += 1.0 - d / t;
    ++traj.frames_matched;
    if (traj.in_gap) ++traj.fragmentations;
    traj.ever_matched = true;
    traj.in_gap = false;
    last_track_of_gt_[gt[g].id] = tracks[h].id;
    last_gt_of_track_[tracks[h].id] = gt[g].id;
  }
}

TrackingMetrics TrackingEvaluator::Metrics() const {
  TrackingMetrics m;
  m.frames = frames_;
  m.gt = gt_;
  m.predictions = predictions_;
  m.tp = tp_;
  m.fn = gt_ - tp_;
  m.fp = predictions_ - tp_;
  m.id_switches = id_switches_;
  m.gt_trajectories = static_cast<int64_t>(gt_trajectories_.size());
  m.track_trajectories = static_cast<int64_t>(track_lengths_.size());
  for (const auto& [id, traj] : gt_trajectories_) {
    m.fragmentations += traj.fragmentations;
    const double ratio = static_cast<double>(traj.frames_matched) / static_cast<double>(traj.frames_present);
    if (ratio >= options_.mostly_tracked_ratio) {
      ++m.mostly_tracked;
    } else if (ratio < options_.mostly_lost_ratio) {
      ++m.mostly_lost;
    } else {
      ++m.partially_tracked;
    }
  }
  const auto gt = static_cast<double>(m.gt), tp = static_cast<double>(m.tp);
  m.mota = m.gt == 0 ? std::numeric_limits<double>::quiet_NaN()
                     : 1.0 - static_cast<double>(m.fn + m.fp + m.id_switches) / gt;
  m.motp_m = RatioOrNaN(distance_sum_m_, tp);
  m.motp_closeness = RatioOrNaN(closeness_sum_, tp);

  m.idtp = IdentityTruePositives(frames_within_);
  m.idfn = m.gt - m.idtp;
  m.idfp = m.predictions - m.idtp;
  m.idf1 = RatioOrNaN(2.0 * static_cast<double>(m.idtp), static_cast<double>(m.gt + m.predictions));
  m.idp = RatioOrNaN(static_cast<double>(m.idtp), static_cast<double>(m.predictions));
  m.idr = RatioOrNaN(static_cast<double>(m.idtp), gt);
  return m;
}

}  // namespace occmap
