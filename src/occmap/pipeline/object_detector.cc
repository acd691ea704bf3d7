#include "occmap/pipeline/object_detector.h"

#include <algorithm>
#include <cmath>

#include "occmap/fusion/morphology.h"
#include "occmap/track/detections.h"

namespace occmap {

ObjectDetector::ObjectDetector(const BlobSettings& settings, const TrackerOptions& tracker_options,
                               double plane_height_m, std::vector<CameraView> cameras)
    : settings_(settings), tracker_options_(tracker_options), cameras_(std::move(cameras)) {
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

void ObjectDetector::Detect(const OccupancyMap& map, const std::vector<bool>& active, DetectedObjects& out) {
  GrowOccupied(map, settings_.group_radius_m, out.grown);
  const std::vector<Blob> groups = FindBlobs(out.grown, {}, &labels_);
  const std::vector<Blob> footprints = FootprintBlobs(map, labels_, groups);
  std::vector<Blob> kept_groups, kept_footprints;
  for (size_t k = 0; k < footprints.size(); ++k) {
    if (footprints[k].cells == 0 || footprints[k].area_m2 < settings_.min_area_m2) continue;
    kept_groups.push_back(groups[k]);
    kept_footprints.push_back(footprints[k]);
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
  if (settings_.remove_ghosts && blobs.size() > 1) {
    std::vector<Viewer> viewers;
    for (size_t n = 0; n < viewers_.size(); ++n) {
      if (n < active.size() && active[n] && has_centre_[n]) viewers.push_back(viewers_[n]);
    }
    std::vector<Eigen::Vector2d> points;
    for (const Blob& b : blobs) points.emplace_back(b.x_m, b.y_m);
    const std::vector<bool> ghost = FindGhosts(points, viewers, ghost_options_);
    std::vector<Blob> real;
    std::vector<bool> group_real(kept_groups.size(), false);
    for (size_t k = 0; k < blobs.size(); ++k) {
      if (ghost[k]) continue;
      real.push_back(blobs[k]);
      group_real[blob_group[k]] = true;
    }
    blobs = std::move(real);
    std::vector<Blob> real_groups;
    for (size_t k = 0; k < kept_groups.size(); ++k) {
      if (group_real[k]) real_groups.push_back(kept_groups[k]);
    }
    kept_groups = std::move(real_groups);
  }
  out.groups = std::move(kept_groups);
}

}  // namespace occmap
