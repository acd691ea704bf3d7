#include "occmap/track/multi_target_tracker.h"

#include <fmt/core.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "occmap/util/hungarian.h"

namespace occmap {
namespace {

// Frame times are sums of steps: compare them with this slack.
constexpr double kTimeSlackS = 1e-9;

}  // namespace

Result<MultiTargetTracker> MultiTargetTracker::Create(const TrackerOptions& options) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  return MultiTargetTracker(options);
}

int MultiTargetTracker::tentative_count() const {
  return static_cast<int>(std::count_if(tracks_.begin(), tracks_.end(), [](const TrackState& t) { return !t.confirmed; }));
}

Eigen::Matrix2d MultiTargetTracker::MeasurementCovariance(const Detection& detection, const FloorGrid& grid) const {
  const double radius_m = options_.person_radius_m();
  const Eigen::Matrix2d excess = detection.spread_m2 - 0.25 * radius_m * radius_m * Eigen::Matrix2d::Identity();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver;
  solver.computeDirect(excess);
  const Eigen::Vector2d clamped = solver.eigenvalues().cwiseMax(0.0);
  const Eigen::Matrix2d positive_excess = solver.eigenvectors() * clamped.asDiagonal() * solver.eigenvectors().transpose();
  double base = options_.measurement_sigma_m * options_.measurement_sigma_m + grid.cell_size_m * grid.cell_size_m / 12.0;
  if (detection.guided) base += options_.guided_split_sigma_m * options_.guided_split_sigma_m;
  return base * Eigen::Matrix2d::Identity() + options_.spread_noise_weight * positive_excess;
}

void MultiTargetTracker::UpdateClass(TrackState& track, const Detection& detection) const {
  const double area_m2 = detection.area_m2;
  track.area_m2 = track.area_m2 <= 0 ? area_m2
                                  : (1.0 - options_.class_area_smoothing) * track.area_m2 +
                                        options_.class_area_smoothing * area_m2;
  const auto& classes = options_.classes;
  if (classes.empty()) return;
  if (!detection.class_hint.empty()) {
    for (size_t k = 0; k < classes.size(); ++k) {
      if (classes[k].name == detection.class_hint) {
        track.class_index = static_cast<int>(k);
        return;
      }
    }
  }
  auto class_of = [&](double area) {
    for (size_t k = 0; k < classes.size(); ++k) {
      if (area <= classes[k].max_area_m2) return static_cast<int>(k);
    }
    return static_cast<int>(classes.size()) - 1;
  };
  if (track.class_index < 0) {
    track.class_index = class_of(track.area_m2);
    return;
  }
  const size_t c = static_cast<size_t>(track.class_index);
  const double lo = c == 0 ? 0.0 : classes[c - 1].max_area_m2;
  const double hi = classes[c].max_area_m2;
  const double h = options_.class_hysteresis;
  if (track.area_m2 > hi * (1.0 + h) || track.area_m2 < lo * (1.0 - h)) track.class_index = class_of(track.area_m2);
}

void MultiTargetTracker::Associate(const std::vector<size_t>& rows, const std::vector<Eigen::Matrix2d>& covariances,
                                   std::vector<uint8_t>& detection_used, double time_s) {
  std::vector<size_t> cols;
  for (size_t d = 0; d < detections_.size(); ++d) {
    if (!detection_used[d]) cols.push_back(d);
  }
  if (rows.empty() || cols.empty()) return;
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> cost(rows.size() * cols.size(), inf);
  for (size_t r = 0; r < rows.size(); ++r) {
    const TrackState& track = tracks_[rows[r]];
    const double max_distance_m =
        options_.max_speed_mps * (time_s - track.last_update_s) + options_.person_radius_m();
    for (size_t c = 0; c < cols.size(); ++c) {
      const Detection& d = detections_[cols[c]];
      const auto innovation = track.filter.Innovate({d.x_m, d.y_m}, covariances[cols[c]]);
      if (innovation.mahalanobis2 > options_.gate_chi2 || innovation.residual_m.norm() > max_distance_m) continue;
      cost[r * cols.size() + c] = innovation.mahalanobis2 + std::log(innovation.covariance_m2.determinant());
    }
  }
  const std::vector<int> match =
      SolveAssignment(cost, static_cast<int>(rows.size()), static_cast<int>(cols.size()));
  for (size_t r = 0; r < rows.size(); ++r) {
    if (match[r] < 0) continue;
    const size_t d = cols[static_cast<size_t>(match[r])];
    TrackState& track = tracks_[rows[r]];
    const Detection& detection = detections_[d];
    track.filter.Update({detection.x_m, detection.y_m}, covariances[d]);
    track.last_update_s = time_s;
    track.updated = true;
    if (!detection.guided) UpdateClass(track, detection);
    ++track.hits;
    detection_used[d] = 1;
  }
}

Track MultiTargetTracker::Report(const TrackState& state, double time_s) const {
  Track track;
  track.id = state.id;
  track.x_m = state.filter.state()(0);
  track.y_m = state.filter.state()(1);
  track.vx_mps = state.filter.state()(2);
  track.vy_mps = state.filter.state()(3);
  track.object_class = state.class_index >= 0 ? options_.classes[static_cast<size_t>(state.class_index)].name : "person";
  track.coasting = !state.updated;
  track.time_since_update_s = time_s - state.last_update_s;
  track.hits = state.hits;
  track.area_m2 = state.area_m2;
  return track;
}

Result<std::vector<Track>> MultiTargetTracker::Update(const ObjectFrame& frame, double time_s) {
  OCCMAP_ASSIGN_OR_RETURN(const double dt_s, clock_.Advance(time_s));
  const FloorGrid& grid = frame.grid;

  // 1. Predict.
  for (TrackState& track : tracks_) {
    if (dt_s > 0) track.filter.Predict(dt_s, options_.acceleration_psd_m2ps3);
    if (!track.confirmed) ++track.frames;
    track.updated = false;
  }

  // 2. The frame's detections, guided by the confirmed tracks' predictions (most hits first).
  std::vector<size_t> confirmed, tentative;
  for (size_t k = 0; k < tracks_.size(); ++k) (tracks_[k].confirmed ? confirmed : tentative).push_back(k);
  std::stable_sort(confirmed.begin(), confirmed.end(),
                   [&](size_t a, size_t b) { return tracks_[a].hits > tracks_[b].hits; });
  std::vector<Eigen::Vector2d> predictions;
  for (size_t k : confirmed) predictions.push_back(tracks_[k].filter.position_m());
  detections_ = GuidedDetections(frame, predictions);
  std::vector<Eigen::Matrix2d> covariances;
  covariances.reserve(detections_.size());
  for (const Detection& d : detections_) covariances.push_back(MeasurementCovariance(d, grid));

  // 3-4. Associate: confirmed tracks first, then tentative ones.
  std::vector<uint8_t> used(detections_.size(), 0);
  Associate(confirmed, covariances, used, time_s);
  Associate(tentative, covariances, used, time_s);

  // Births.
  const double separation2 = options_.birth_min_separation_m * options_.birth_min_separation_m;
  const size_t existing = tracks_.size();
  for (size_t d = 0; d < detections_.size(); ++d) {
    if (used[d]) continue;
    const Eigen::Vector2d position(detections_[d].x_m, detections_[d].y_m);
    bool near_confirmed = false;
    for (size_t k = 0; k < existing; ++k) {
      if (tracks_[k].confirmed && (tracks_[k].filter.position_m() - position).squaredNorm() < separation2) {
        near_confirmed = true;
        break;
      }
    }
    if (near_confirmed) continue;
    TrackState track;
    const Eigen::Matrix2d& r = covariances[d];
    track.filter = ConstantVelocityKalman(position, r, options_.initial_speed_sigma_mps);
    track.last_update_s = time_s;
    track.frames = 1;
    track.updated = true;
    if (!detections_[d].guided) UpdateClass(track, detections_[d]);
    track.hits = 1;
    tracks_.push_back(std::move(track));
  }

  // 5. Confirm, end.
  const int64_t allowed_misses = options_.confirm_frames - options_.confirm_hits;
  std::vector<TrackState> kept;
  kept.reserve(tracks_.size());
  for (TrackState& track : tracks_) {
    if (!track.confirmed) {
      if (track.hits >= options_.confirm_hits) {
        track.confirmed = true;
        track.id = next_id_++;
      } else if (track.frames - track.hits > allowed_misses) {
        continue;
      }
    } else if (time_s - track.last_update_s > options_.max_coast_s + kTimeSlackS) {
      continue;
    } else if (!track.updated && grid.CellAt(track.filter.state()(0), track.filter.state()(1)) < 0) {
      continue;
    }
    kept.push_back(std::move(track));
  }
  tracks_ = std::move(kept);

  std::vector<Track> out;
  for (const TrackState& track : tracks_) {
    if (track.confirmed) out.push_back(Report(track, time_s));
  }
  std::sort(out.begin(), out.end(), [](const Track& a, const Track& b) { return a.id < b.id; });
  return out;
}

}  // namespace occmap
