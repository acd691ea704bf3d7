// ObjectDetector: from an occupancy map to the objects standing on it (ObjectOptions in
// object_options.h), the stage between fusion and tracking:
//   1. occupied fragments closer than 2 * group_radius_m form one group (grouping.h: a
//      person's two feet, a chair's four legs);
//   2. groups whose footprint (the occupied cells of the group, FootprintBlobs) is smaller than
//      min_area_m2 are dropped;
//   3. with split, a group too large for one object is split at the necks of its shape
//      (split.h, on the grown map, with the person size grown by the grouping radius);
//   4. with support_heights_m, flat detections are dropped (the elevated check,
//      elevated_check.h: the planes above the floor, read through each camera's changes at
//      the footprint, show nothing);
//   5. with remove_ghosts, detections that every camera seeing them sees only through other,
//      certainly real detections are dropped, and so are those that two cameras see but fewer
//      than min_clear_views see clear of the others (ghosts.h).
// A detection is placed at the centroid of its footprint (of its part of the group when its
// group was split), with the footprint's area and spread. The output is an ObjectFrame
// (object_frame.h): the detections, what detections.jsonl shows and what the tracker
// measures, and the groups that still hold one, whose splits the tracker may redo along its
// predictions (the guided split).
//
//   ObjectDetector detector(site.objects, site.plane_height_m, views);
//   detector.Detect(map, active, changed, objects);   // objects.detections, .groups, .grown
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/geometry/camera_model.h"
#include "occmap/objects/detection.h"
#include "occmap/objects/elevated_check.h"
#include "occmap/objects/ghosts.h"
#include "occmap/objects/object_frame.h"
#include "occmap/objects/object_options.h"
#include "occmap/objects/split_fast.h"
#include "occmap/util/image.h"

namespace occmap {

// The detector's output: the frame (detections, one per object, and the groups of `grown`
// they come from, each with its split when ObjectOptions::split) and the grown map.
struct DetectedObjects : ObjectFrame {
  OccupancyMap grown;  // the map with fragments grouped
};

class ObjectDetector {
 public:
  // What a camera sees, for the ghost test: its model and its floor mask (empty = all pixels).
  // Both must outlive the detector.
  struct CameraView {
    const CameraModel* camera = nullptr;
    const Image<uint8_t>* mask = nullptr;
  };

  // options must be valid (checked). The splitter's person size is options.person_diameter_m
  // grown by 2 group_radius_m, as the groups are.
  ObjectDetector(const ObjectOptions& options, double plane_height_m, std::vector<CameraView> cameras);

  // The elevated check's changes (elevated_check.h): a lookup (the reference) or buffers.
  using ChangeLookup = ElevatedCheck::ChangeLookup;
  using ChangeBuffer = ElevatedCheck::ChangeBuffer;

  // active[n]: camera n contributed to this map (size = cameras). `changed` (may be empty)
  // answers the elevated check. `buffers` (empty, or one per camera) holds the same changes
  // as `changed` and, when given, is read instead of it (the fast path; `changed` is the
  // reference, equal by test). Reuses out's buffers.
  void Detect(const OccupancyMap& map, const std::vector<bool>& active, const ChangeLookup& changed,
              DetectedObjects& out, std::span<const ChangeBuffer> buffers = {});
  // Without per-pixel changes (no elevated check).
  void Detect(const OccupancyMap& map, const std::vector<bool>& active, DetectedObjects& out) {
    Detect(map, active, ChangeLookup(), out);
  }

 private:
  ObjectOptions settings_;
  ObjectOptions split_options_;           // settings_ with the person grown as the groups are
  double plane_height_m_ = 0;
  std::vector<CameraView> cameras_;
  std::vector<Viewer> viewers_;          // per camera (centre at 0 when it has none)
  std::vector<bool> has_centre_;
  std::vector<Viewer> active_viewers_;     // viewers_ of the cameras active in active_viewers_for_
  std::vector<bool> active_viewers_for_;
  GhostOptions ghost_options_;
  // Per detection: floor points of its occupied cells, for the ghost test (at most kGhostSamples).
  void GhostSamples(const OccupancyMap& map, const std::vector<int>& kept_index, const std::vector<Detection>& detections);
  static constexpr size_t kGhostSamples = 32;
  // The smallest footprint the standing test may keep, as a share of min_area_m2.
  static constexpr double kStandingMinShare = 0.2;
  std::vector<std::vector<Eigen::Vector2d>> ghost_samples_;
  BlobFinder groups_;                     // the groups of the grown map, buffers kept
  std::vector<Blob> footprints_;
  std::vector<Eigen::Matrix2d> footprint_spreads_;
  std::vector<BlobSplit> splits_;         // per kept group, this frame
  SplitScratch split_scratch_;            // SplitBlob's buffers, kept
  ElevatedCheck elevated_;                // after cameras_: made from them
};

}  // namespace occmap
