#include "occmap/objects/object_detector.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "occmap/objects/grouping.h"
#include "occmap/util/status.h"

namespace occmap {
namespace {

std::vector<const CameraModel*> CameraModels(const std::vector<ObjectDetector::CameraView>& views) {
  std::vector<const CameraModel*> out;
  for (const ObjectDetector::CameraView& v : views) out.push_back(v.camera);
  return out;
}

std::vector<const Image<uint8_t>*> Masks(const std::vector<ObjectDetector::CameraView>& views) {
  std::vector<const Image<uint8_t>*> out;
  for (const ObjectDetector::CameraView& v : views) out.push_back(v.mask);
  return out;
}

}  // namespace

ObjectDetector::ObjectDetector(const ObjectOptions& options, double plane_height_m, std::vector<CameraView> cameras)
    : settings_(options), split_options_(options), plane_height_m_(plane_height_m), cameras_(std::move(cameras)),
      elevated_(options, plane_height_m, CameraModels(cameras_), Masks(cameras_)) {
  const Status valid = options.Validate();
  OCCMAP_CHECK(valid.ok(), "ObjectDetector: invalid options: " + valid.message());
  // The groups are footprints grown by r, so one person's size grows with them.
  split_options_.person_diameter_m += 2 * settings_.group_radius_m;
  // Blocked views: within a grown person of another detection (a ghost is called only where it
  // is surely hidden); clear views: past a body (settings_'s person) of every other one.
  ghost_options_ = {.occluder_radius_m = split_options_.person_radius_m(),
                    .occluder_height_m = settings_.occluder_height_m,
                    .min_clear_views = settings_.min_clear_views,
                    .clear_radius_m = settings_.person_radius_m()};
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

void ObjectDetector::GhostSamples(const OccupancyMap& map, const std::vector<int>& kept_index,
                                  const std::vector<Detection>& detections) {
  ghost_samples_.resize(detections.size());
  const double radius_m = split_options_.person_radius_m();
  for (size_t k = 0; k < detections.size(); ++k) {
    std::vector<Eigen::Vector2d>& samples = ghost_samples_[k];
    samples.clear();
    const Detection& d = detections[k];
    if (d.group < 0) continue;
    const Eigen::Vector2d centre(d.x_m, d.y_m);
    // The occupied cells of its group (within a person of it when the group was split).
    const std::span<const int64_t> cells = groups_.cells(static_cast<size_t>(kept_index[static_cast<size_t>(d.group)]));
    for (int64_t cell : cells) {
      if (map.state(cell) != CellState::kOccupied) continue;
      const Eigen::Vector2d p = map.grid().CellCenter(cell);
      if (d.parts > 1 && (p - centre).norm() > radius_m) continue;
      samples.push_back(p);
    }
    // Evenly thinned: the test's cost grows with the samples, its answer hardly.
    if (samples.size() > kGhostSamples) {
      const size_t n = samples.size();
      for (size_t i = 0; i < kGhostSamples; ++i) samples[i] = samples[i * n / kGhostSamples];
      samples.resize(kGhostSamples);
    }
  }
}

void ObjectDetector::Detect(const OccupancyMap& map, const std::vector<bool>& active, const ChangeLookup& changed,
                            DetectedObjects& out, std::span<const ChangeBuffer> buffers) {
  OCCMAP_CHECK(buffers.empty() || buffers.size() == cameras_.size(), "ObjectDetector: one change buffer per camera");
  out.grid = map.grid();
  out.guide_radius_m = split_options_.person_radius_m();
  GrowOccupied(map, settings_.group_radius_m, out.grown);
  const std::vector<Blob>& groups = groups_.Find(out.grown);
  FootprintBlobs(map, groups_, footprints_, &footprint_spreads_);
  const std::vector<Blob>& footprints = footprints_;
  std::vector<Blob> kept_groups, kept_footprints;
  std::vector<int> kept_index;  // the group's index in `groups` (its label)
  // Footprints under min_area_m2 that the planes show standing (ObjectOptions::standing_radius_m).
  const bool standing_test = settings_.standing_radius_m > 0 && !settings_.support_heights_m.empty() &&
                             (changed || !buffers.empty());
  if (standing_test) elevated_.BeginFrame(active);
  for (size_t k = 0; k < footprints.size(); ++k) {
    const Blob& f = footprints[k];
    if (f.cells == 0) continue;
    if (f.area_m2 < settings_.min_area_m2) {
      if (!standing_test || f.area_m2 < kStandingMinShare * settings_.min_area_m2) continue;
      if (elevated_.TallestArea(map.grid(), f.x_m, f.y_m, settings_.standing_radius_m, changed, buffers) <
          settings_.min_area_m2) {
        continue;
      }
    }
    kept_groups.push_back(groups[k]);
    kept_footprints.push_back(footprints[k]);
    kept_index.push_back(static_cast<int>(k));
  }
  // A detection of kept group g with the group's whole footprint.
  auto whole = [&](size_t g, int parts) {
    const Blob& f = kept_footprints[g];
    Detection d;
    d.x_m = f.x_m;
    d.y_m = f.y_m;
    d.area_m2 = f.area_m2;
    d.cells = f.cells;
    d.spread_m2 = footprint_spreads_[static_cast<size_t>(kept_index[g])];
    d.group = static_cast<int>(g);
    d.parts = parts;
    return d;
  };
  std::vector<Detection>& detections = out.detections;
  detections.clear();
  if (settings_.split) {
    // Each group split once (SplitBlob); the tracker gets the splits of the groups kept.
    splits_.clear();
    for (size_t g = 0; g < kept_groups.size(); ++g) {
      splits_.push_back(SplitBlob(kept_groups[g], out.grown, groups_.labels(), kept_index[g], split_options_,
                                  split_scratch_));
    }
    for (const Detection& d : DetectionsFromSplits(kept_groups, splits_, out.grown, split_options_)) {
      if (d.parts == 1) {  // one part: the group's footprint
        detections.push_back(whole(static_cast<size_t>(d.group), 1));
        continue;
      }
      // A part of the grown group: where the split put it, its share of the footprint's area.
      Detection part = d;
      part.area_m2 = d.area_m2 * kept_footprints[static_cast<size_t>(d.group)].area_m2 /
                     kept_groups[static_cast<size_t>(d.group)].area_m2;
      detections.push_back(part);
    }
  } else {
    for (size_t g = 0; g < kept_groups.size(); ++g) detections.push_back(whole(g, 1));
  }
  elevated_.Apply(map, groups_.labels(), active, changed, buffers, kept_index, kept_groups, detections);
  if (settings_.remove_ghosts && detections.size() > 1) {
    // The active cameras' viewers, rebuilt only when the active set changes (copying the
    // std::functions would allocate every frame).
    if (active != active_viewers_for_) {
      active_viewers_for_ = active;
      active_viewers_.clear();
      for (size_t n = 0; n < viewers_.size(); ++n) {
        if (n < active.size() && active[n] && has_centre_[n]) active_viewers_.push_back(viewers_[n]);
      }
    }
    std::vector<Eigen::Vector2d> points;
    for (const Detection& d : detections) points.emplace_back(d.x_m, d.y_m);
    GhostSamples(map, kept_index, detections);
    const std::vector<bool> ghost = FindGhosts(points, active_viewers_, ghost_options_, ghost_samples_);
    size_t kept = 0;
    for (size_t k = 0; k < detections.size(); ++k) {
      if (!ghost[k]) detections[kept++] = std::move(detections[k]);
    }
    detections.resize(kept);
  }
  // The groups that still hold a detection, numbered anew, for the tracker.
  std::vector<int> group_number(kept_groups.size(), -1);
  for (const Detection& d : detections) group_number[static_cast<size_t>(d.group)] = 0;
  out.groups.clear();
  for (size_t g = 0; g < kept_groups.size(); ++g) {
    if (group_number[g] < 0) continue;
    group_number[g] = static_cast<int>(out.groups.size());
    DetectionGroup group{kept_groups[g], kept_footprints[g], {}};
    if (settings_.split) group.split = std::move(splits_[g]);
    out.groups.push_back(std::move(group));
  }
  for (Detection& d : detections) d.group = group_number[static_cast<size_t>(d.group)];
}

}  // namespace occmap
