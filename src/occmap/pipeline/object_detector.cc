#include "occmap/pipeline/object_detector.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "occmap/fusion/morphology.h"
#include "occmap/track/detections.h"

namespace occmap {

ObjectDetector::ObjectDetector(const BlobSettings& settings, const TrackerOptions& tracker_options,
                               double plane_height_m, std::vector<CameraView> cameras)
    : settings_(settings), tracker_options_(tracker_options), plane_height_m_(plane_height_m),
      cameras_(std::move(cameras)) {
  ghost_options_ = {.occluder_radius_m = tracker_options_.person_radius_m(),
                    .occluder_height_m = settings_.occluder_height_m};
  for (const CameraView& v : cameras_) {
    const CameraModel* model = v.camera;
    const Image<uint8_t>* mask = v.mask;
    const double z = plane_height_m;
    const std::optional<Eigen::Vector3d> centre = model->CenterInWorld();
    has_centre_.push_back(centre.has_value());
    // Whether the camera sees a floor point: in front, on the image, on an unmasked pixel.
    viewers_.push_back({centre.value_or(Eigen::Vector3d::Zero()), [model, mask, z](const Eigen::Vector2d& p) {
                          const auto px = model->Project(Eigen::Vector3d(p.x(), p.y(), z));
                          if (!px || !model->InImage(*px)) return false;
                          if (mask == nullptr || mask->empty()) return true;
                          const int x = std::clamp(static_cast<int>(std::lround(px->x())), 0, mask->width() - 1);
                          const int y = std::clamp(static_cast<int>(std::lround(px->y())), 0, mask->height() - 1);
                          return (*mask)(x, y) != 0;
                        }});
  }
}

void ObjectDetector::PrepareSupport(const FloorGrid& grid) {
  if (support_grid_ && *support_grid_ == grid) return;
  support_grid_ = grid;
  support_pixel_.assign(settings_.support_heights_m.size(), std::vector<std::vector<int32_t>>(cameras_.size()));
  for (size_t h = 0; h < settings_.support_heights_m.size(); ++h) {
  const double z = plane_height_m_ + settings_.support_heights_m[h];
  for (size_t n = 0; n < cameras_.size(); ++n) {
    const CameraModel& model = *cameras_[n].camera;
    const Image<uint8_t>* mask = cameras_[n].mask;
    std::vector<int32_t>& pixel = support_pixel_[h][n];
    pixel.assign(static_cast<size_t>(grid.num_cells()), -1);
    for (int64_t i = 0; i < grid.num_cells(); ++i) {
      const Eigen::Vector2d c = grid.CellCenter(i);
      const auto px = model.Project(Eigen::Vector3d(c.x(), c.y(), z));
      if (!px || !model.InImage(*px)) continue;
      const int x = static_cast<int>(std::lround(px->x()));
      const int y = static_cast<int>(std::lround(px->y()));
      const ImageSize size = model.image_size();
      if (x < 0 || y < 0 || x >= size.width || y >= size.height) continue;
      // A masked pixel (outside the floor, or a static object in front) tells nothing.
      if (mask != nullptr && !mask->empty() && (*mask)(x, y) == 0) continue;
      pixel[static_cast<size_t>(i)] = y * size.width + x;
    }
  }
  }
}

int ObjectDetector::SupportAt(size_t h, int64_t cell, const std::vector<bool>& active,
                              const ChangeLookup& changed) const {
  int seeing = 0;
  for (size_t n = 0; n < cameras_.size(); ++n) {
    if (n >= active.size() || !active[n]) continue;
    const int32_t p = support_pixel_[h][n][static_cast<size_t>(cell)];
    if (p < 0) continue;
    ++seeing;
    const int width = cameras_[n].camera->image_size().width;
    if (!changed(static_cast<int>(n), p % width, p / width)) return 0;
  }
  return seeing > 0 ? 1 : -1;
}

void ObjectDetector::RemoveUnsupported(const OccupancyMap& map, const std::vector<bool>& active,
                                       const ChangeLookup& changed, std::vector<int>& blob_group,
                                       const std::vector<int>& kept_index, DetectedObjects& out) {
  const FloorGrid& grid = map.grid();
  PrepareSupport(grid);
  std::vector<Blob>& blobs = out.detections;
  // The detections of each kept group, to give each footprint cell to the nearest one.
  std::vector<int> group_of_label(static_cast<size_t>(labels_max_ + 1), -1);
  for (size_t g = 0; g < kept_index.size(); ++g) group_of_label[static_cast<size_t>(kept_index[g])] = static_cast<int>(g);
  std::vector<std::vector<int>> detections_of(kept_index.size());
  for (size_t d = 0; d < blobs.size(); ++d) detections_of[static_cast<size_t>(blob_group[d])].push_back(static_cast<int>(d));
  const size_t heights = settings_.support_heights_m.size();
  std::vector<int> cells(blobs.size(), 0), seen(blobs.size() * heights, 0), supported(blobs.size() * heights, 0);
  const int reach = std::max(0, static_cast<int>(std::lround(settings_.support_slack_m / grid.cell_size_m)));
  for (int j = 0; j < grid.cells_y; ++j) {
    for (int i = 0; i < grid.cells_x; ++i) {
      const int64_t cell = int64_t{j} * grid.cells_x + i;
      const int32_t label = labels_[static_cast<size_t>(cell)];
      if (label < 0 || map.state(cell) != CellState::kOccupied) continue;
      const int g = group_of_label[static_cast<size_t>(label)];
      if (g < 0) continue;
      const Eigen::Vector2d c = grid.CellCenter(cell);
      int best = -1;
      double best_d2 = std::numeric_limits<double>::infinity();
      for (int d : detections_of[static_cast<size_t>(g)]) {
        const double d2 = (Eigen::Vector2d(blobs[d].x_m, blobs[d].y_m) - c).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best = d;
        }
      }
      if (best < 0) continue;
      ++cells[best];
      // Per plane: occupied when the plane shows the object over this cell or beside it
      // (within the slack: legs lean, a foot is ahead of the knee); free when some camera
      // sees that neighbourhood free; unknown when no camera sees it.
      for (size_t h = 0; h < heights; ++h) {
        int state = -1;
        for (int dj = -reach; dj <= reach && state < 1; dj += std::max(1, reach)) {
          for (int di = -reach; di <= reach && state < 1; di += std::max(1, reach)) {
            const int ii = i + di, jj = j + dj;
            if (ii < 0 || jj < 0 || ii >= grid.cells_x || jj >= grid.cells_y) continue;
            state = std::max(state, SupportAt(h, int64_t{jj} * grid.cells_x + ii, active, changed));
          }
        }
        const size_t k = static_cast<size_t>(best) * heights + h;
        seen[k] += state >= 0;
        supported[k] += state == 1;
      }
    }
  }
  // A detection is dropped when some plane saw enough of it and none of those planes
  // supports it; with no plane seeing it, nothing speaks against it.
  std::vector<Blob> kept;
  std::vector<int> kept_group;
  for (size_t d = 0; d < blobs.size(); ++d) {
    bool evidence = false, support = false;
    for (size_t h = 0; h < heights; ++h) {
      const size_t k = d * heights + h;
      // A plane counts when it sees at least half of the footprint.
      if (2 * seen[k] < cells[d] || seen[k] == 0) continue;
      evidence = true;
      support |= supported[k] >= settings_.min_support * seen[k];
    }
    if (evidence && !support) continue;
    kept.push_back(blobs[d]);
    kept_group.push_back(blob_group[d]);
  }
  blobs = std::move(kept);
  blob_group = std::move(kept_group);
}

void ObjectDetector::Detect(const OccupancyMap& map, const std::vector<bool>& active, const ChangeLookup& changed,
                            DetectedObjects& out) {
  GrowOccupied(map, settings_.group_radius_m, out.grown);
  const std::vector<Blob> groups = FindBlobs(out.grown, {}, &labels_);
  labels_max_ = static_cast<int32_t>(groups.size()) - 1;
  const std::vector<Blob> footprints = FootprintBlobs(map, labels_, groups);
  std::vector<Blob> kept_groups, kept_footprints;
  std::vector<int> kept_index;  // the group's index in `groups` (its label)
  for (size_t k = 0; k < footprints.size(); ++k) {
    if (footprints[k].cells == 0 || footprints[k].area_m2 < settings_.min_area_m2) continue;
    kept_groups.push_back(groups[k]);
    kept_footprints.push_back(footprints[k]);
    kept_index.push_back(static_cast<int>(k));
  }
  std::vector<Blob>& blobs = out.detections;
  blobs.clear();
  std::vector<int> blob_group;
  if (settings_.split) {
    for (const Detection& d : DetectionsFromBlobs(kept_groups, out.grown, tracker_options_)) {
      Blob b = kept_footprints[d.blob_index];  // one part: the group's footprint
      if (d.parts > 1) {
        b.x_m = d.x_m;
        b.y_m = d.y_m;
        b.area_m2 = d.area_m2 * kept_footprints[d.blob_index].area_m2 / kept_groups[d.blob_index].area_m2;
        b.cells = d.cells;
      }
      blobs.push_back(b);
      blob_group.push_back(d.blob_index);
    }
  } else {
    blobs = kept_footprints;
    for (size_t k = 0; k < blobs.size(); ++k) blob_group.push_back(static_cast<int>(k));
  }
  if (!settings_.support_heights_m.empty() && changed && !blobs.empty()) {
    RemoveUnsupported(map, active, changed, blob_group, kept_index, out);
  }
  if (settings_.remove_ghosts && blobs.size() > 1) {
    std::vector<Viewer> viewers;
    for (size_t n = 0; n < viewers_.size(); ++n) {
      if (n < active.size() && active[n] && has_centre_[n]) viewers.push_back(viewers_[n]);
    }
    std::vector<Eigen::Vector2d> points;
    for (const Blob& b : blobs) points.emplace_back(b.x_m, b.y_m);
    const std::vector<bool> ghost = FindGhosts(points, viewers, ghost_options_);
    std::vector<Blob> real;
    std::vector<int> real_group;
    for (size_t k = 0; k < blobs.size(); ++k) {
      if (ghost[k]) continue;
      real.push_back(blobs[k]);
      real_group.push_back(blob_group[k]);
    }
    blobs = std::move(real);
    blob_group = std::move(real_group);
  }
  // The groups that still hold a detection, for the tracker.
  std::vector<bool> group_real(kept_groups.size(), false);
  for (int g : blob_group) group_real[static_cast<size_t>(g)] = true;
  out.groups.clear();
  for (size_t k = 0; k < kept_groups.size(); ++k) {
    if (group_real[k]) out.groups.push_back(kept_groups[k]);
  }
}

}  // namespace occmap
