// ObjectDetector: from an occupancy map to the objects standing on it (ObjectOptions in
// object_options.h), the stage between fusion and tracking:
//   1. occupied fragments closer than 2 * group_radius_m form one group (grouping.h: a
//      person's two feet, a chair's four legs);
//   2. groups whose footprint (the occupied cells of the group, FootprintBlobs) is smaller than
//      min_area_m2 are dropped;
//   3. with split, a group too large for one object is split at the necks of its shape
//      (split.h, on the grown map, with the person size grown by the grouping radius);
//   4. with support_heights_m, flat detections are dropped (the elevated check: the planes
//      above the floor, read through each camera's changes at the footprint, show nothing);
//   5. with remove_ghosts, detections that every camera seeing them sees only through other,
//      certainly real detections are dropped (ghosts.h).
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
#include "occmap/objects/ghosts.h"
#include "occmap/objects/object_frame.h"
#include "occmap/objects/object_options.h"
#include "occmap/objects/split.h"
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

  // Whether camera n's pixel (column x, row y) shows a change in the current frame.
  using ChangeLookup = std::function<bool(int camera, int x, int y)>;

  // The same changes as a buffer: camera n's pixel (x, y) changed when pixels[y * stride + x]
  // is not 0; or, with unchanged_bits, when bit x % 64 of unchanged_bits[y * row_words + x / 64]
  // is 0 (ChangeBits' layout).
  struct ChangeBuffer {
    const uint8_t* pixels = nullptr;
    size_t stride = 0;
    const uint64_t* unchanged_bits = nullptr;
    size_t row_words = 0;
  };

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
  void PrepareSupport(const FloorGrid& grid);
  // The plane-h occupancy of a cell: 1 occupied (every active camera seeing it changed), 0
  // free, -1 no active camera sees it. Reads `buffers` when not empty, else `changed`; kept
  // (in the cell's last entry of SupportPixels) for the rest of the frame.
  int SupportAt(size_t h, int64_t cell, const ChangeLookup& changed, std::span<const ChangeBuffer> buffers);
  // SupportAt without the memo: the cameras' pixels asked.
  int SupportState(size_t h, int64_t cell, int32_t* pixels, const ChangeLookup& changed,
                   std::span<const ChangeBuffer> buffers);
  // The cameras' pixels (PackPixel: (row << 16) | column) where the cell's centre at plane h projects
  // (entry n for camera n; -1 when it does not see it, kNotProjected until first used), then
  // the memo of SupportAt (generation * 4 + state + 1, or kNotProjected).
  int32_t* SupportPixels(size_t h, int64_t cell);
  // Camera n's entry of `pixels` (SupportPixels), projected on first use.
  int32_t SupportPixel(size_t h, size_t n, int64_t cell, int32_t* pixels);
  // A projection's pixel as SupportPixels holds it: (y << 16) | x, so the test reads x and y
  // without a division (images up to 65536 x 32768, checked by the constructor).
  static int32_t PackPixel(int x, int y) {
    return static_cast<int32_t>((static_cast<uint32_t>(y) << 16) | static_cast<uint32_t>(x));
  }
  static size_t PixelX(int32_t p) { return static_cast<uint32_t>(p) & 0xffffu; }
  static size_t PixelY(int32_t p) { return static_cast<uint32_t>(p) >> 16; }
  // Drops out.detections that the planes above do not support. Their groups index kept_index.
  void RemoveUnsupported(const OccupancyMap& map, const ChangeLookup& changed, std::span<const ChangeBuffer> buffers,
                         const std::vector<int>& kept_index, const std::vector<Blob>& kept_groups,
                         DetectedObjects& out);

  ObjectOptions settings_;
  ObjectOptions split_options_;           // settings_ with the person grown as the groups are
  double plane_height_m_ = 0;
  std::vector<CameraView> cameras_;
  std::vector<Viewer> viewers_;          // per camera (centre at 0 when it has none)
  std::vector<bool> has_centre_;
  std::vector<Viewer> active_viewers_;     // viewers_ of the cameras active in active_viewers_for_
  std::vector<bool> active_viewers_for_;
  GhostOptions ghost_options_;
  BlobFinder groups_;                     // the groups of the grown map, buffers kept
  std::vector<Blob> footprints_;
  std::vector<Eigen::Matrix2d> footprint_spreads_;
  std::vector<BlobSplit> splits_;         // per kept group, this frame
  SplitScratch split_scratch_;            // SplitBlob's buffers, kept
  // The elevated check's projections (SupportPixel), kNotProjected until first used.
  static constexpr int32_t kNotProjected = -2;
  static constexpr int64_t kTileCells = 4096;
  std::optional<FloorGrid> support_grid_;
  size_t support_tiles_ = 0;                 // tiles of the grid
  std::vector<int64_t> support_tile_start_;  // [height * tiles + tile]: its start in support_pixel_, -1 none yet
  std::vector<int32_t> support_pixel_;       // per tile: [cell in tile * (cameras + 1) + camera or memo]
  int32_t support_generation_ = 0;           // Detect calls with an elevated check, the memos' stamp
  std::vector<size_t> active_cameras_;       // this frame's active cameras, in order
  std::vector<std::vector<std::pair<int, int>>> footprint_;  // per detection, its footprint cells (reused)
};

}  // namespace occmap
