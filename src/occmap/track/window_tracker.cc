#include "occmap/track/window_tracker.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace occmap {
namespace {

constexpr double kTimeSlackS = 1e-9;

}  // namespace

Result<WindowTracker> WindowTracker::Create(const TrackerOptions& options) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  return WindowTracker(options);
}

int64_t WindowTracker::WindowCentroid(const OccupancyMap& map, const Eigen::Vector2d& centre_m, double half_size_m,
                                      Eigen::Vector2d& centroid_m) {
  const FloorGrid& grid = map.grid();
  // Cell i's centre is origin + (i + 0.5) s: in [c - h, c + h] for i in [lo, hi] below.
  auto range = [&](double centre, double origin, int cells, int& lo, int& hi) {
    const double a = std::ceil((centre - half_size_m - origin) / grid.cell_size_m - 0.5);
    const double b = std::floor((centre + half_size_m - origin) / grid.cell_size_m - 0.5);
    lo = static_cast<int>(std::clamp(a, 0.0, static_cast<double>(cells)));
    hi = static_cast<int>(std::clamp(b, -1.0, static_cast<double>(cells) - 1.0));
  };
  int i_lo = 0, i_hi = -1, j_lo = 0, j_hi = -1;
  range(centre_m.x(), grid.origin_x_m, grid.cells_x, i_lo, i_hi);
  range(centre_m.y(), grid.origin_y_m, grid.cells_y, j_lo, j_hi);
  int64_t count = 0, sum_i = 0, sum_j = 0;
  for (int j = j_lo; j <= j_hi; ++j) {
    for (int i = i_lo; i <= i_hi; ++i) {
      if (map.state(int64_t{j} * grid.cells_x + i) != CellState::kOccupied) continue;
      ++count;
      sum_i += i;
      sum_j += j;
    }
  }
  if (count > 0) {
    const double n = static_cast<double>(count);
    centroid_m = {grid.origin_x_m + (static_cast<double>(sum_i) / n + 0.5) * grid.cell_size_m,
                  grid.origin_y_m + (static_cast<double>(sum_j) / n + 0.5) * grid.cell_size_m};
  }
  return count;
}

Result<std::vector<Track>> WindowTracker::Update(const std::vector<Blob>& blobs, const OccupancyMap& map,
                                                 double time_s) {
  OCCMAP_ASSIGN_OR_RETURN(const double dt_s, clock_.Advance(time_s));
  const double half_size_m = options_.max_speed_mps * dt_s + options_.window_object_radius_m;
  const double cell_area_m2 = map.grid().cell_size_m * map.grid().cell_size_m;

  // 1-2. Each object: centroid in its window, or lost after the timeout.
  std::vector<Eigen::Vector2d> windows;  // centres of the windows searched, of the objects kept
  std::vector<Object> kept;
  for (Object& object : objects_) {
    Eigen::Vector2d centroid_m;
    const int64_t count = WindowCentroid(map, object.position_m, half_size_m, centroid_m);
    object.seen = count > 0;
    if (object.seen) {
      object.velocity_mps = dt_s > 0 ? Eigen::Vector2d((centroid_m - object.position_m) / dt_s) : Eigen::Vector2d::Zero();
      windows.push_back(object.position_m);
      object.position_m = centroid_m;
      object.last_seen_s = time_s;
      object.area_m2 = static_cast<double>(count) * cell_area_m2;
      ++object.hits;
    } else {
      object.velocity_mps.setZero();
      if (time_s - object.last_seen_s > options_.window_lost_timeout_s + kTimeSlackS) continue;
      windows.push_back(object.position_m);
    }
    kept.push_back(object);
  }
  objects_ = std::move(kept);

  // 3. New objects from blobs outside every window.
  for (const Blob& blob : blobs) {
    if (blob.area_m2 < options_.window_min_new_area_m2) continue;
    const bool covered = std::any_of(windows.begin(), windows.end(), [&](const Eigen::Vector2d& c) {
      return std::abs(blob.x_m - c.x()) <= half_size_m && std::abs(blob.y_m - c.y()) <= half_size_m;
    });
    if (covered) continue;
    Object object;
    object.id = next_id_++;
    object.position_m = {blob.x_m, blob.y_m};
    object.last_seen_s = time_s;
    object.hits = 1;
    object.area_m2 = blob.area_m2;
    object.seen = true;
    objects_.push_back(object);
  }

  std::vector<Track> out;
  out.reserve(objects_.size());
  for (const Object& object : objects_) {
    Track track;
    track.id = object.id;
    track.x_m = object.position_m.x();
    track.y_m = object.position_m.y();
    track.vx_mps = object.velocity_mps.x();
    track.vy_mps = object.velocity_mps.y();
    track.object_class = "object";
    track.coasting = !object.seen;
    track.time_since_update_s = time_s - object.last_seen_s;
    track.hits = object.hits;
    track.area_m2 = object.area_m2;
    out.push_back(std::move(track));
  }
  return out;
}

}  // namespace occmap
