// The elevated check: a detection must stand up. A ghost is the intersection of the floor
// shadows several objects cast in the cameras' views; on a plane above the floor those shadows
// move towards their objects and no longer meet, while a real object rises over its own
// footprint. Equation 5 is applied on the planes support_heights_m above the floor, only at
// the footprint cells of each detection (each given to its group's nearest detection; at most
// 64 of them, evenly spread, each widened by support_slack_m): a detection is dropped when some
// plane saw at least half of those cells and none shows the object over min_support of what it
// saw. Cell -> pixel projections per plane are made on first use and kept; a cell's plane
// state is kept for the rest of the frame.
//
// The cameras' changes come either through a ChangeLookup (the reference: one call per pixel)
// or as ChangeBuffers (the fast path, elevated_check_fast.cc: byte images or ChangeBits'
// unchanged bits read in place); both give the same detections (tested).
//
//   ElevatedCheck check(options, plane_height_m, cameras, masks);
//   check.Apply(map, finder.labels(), active, changed, buffers, kept_index, kept_groups, detections);
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/geometry/camera_model.h"
#include "occmap/objects/detection.h"
#include "occmap/objects/object_options.h"
#include "occmap/util/image.h"

namespace occmap {

class ElevatedCheck {
 public:
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

  // The planes and thresholds from options (support_heights_m, min_support,
  // support_slack_m); per camera its model and its floor mask (null or empty = every pixel),
  // which must outlive the check. Images up to 65536 x 32768 pixels (checked).
  ElevatedCheck(const ObjectOptions& options, double plane_height_m, std::vector<const CameraModel*> cameras,
                std::vector<const Image<uint8_t>*> masks);

  // Drops the detections the planes do not support. detections[k].group indexes kept_index
  // (the group's label in `labels`, the grouped map's) and kept_groups (its box). active[n]:
  // camera n contributed to this frame. Reads `buffers` when given (one per camera), else
  // `changed`; with neither, or without planes, nothing is dropped.
  void Apply(const OccupancyMap& map, std::span<const int32_t> labels, const std::vector<bool>& active,
             const ChangeLookup& changed, std::span<const ChangeBuffer> buffers, const std::vector<int>& kept_index,
             const std::vector<Blob>& kept_groups, std::vector<Detection>& detections);

  // Starts a frame's tests (Apply starts one itself when this was not called since the last).
  void BeginFrame(const std::vector<bool>& active);
  // The largest area (m2) that one plane of support_heights_m shows occupied within radius_m of
  // (x_m, y_m): what stands above a footprint the floor nearly lost. 0 without planes.
  double TallestArea(const FloorGrid& grid, double x_m, double y_m, double radius_m, const ChangeLookup& changed,
                     std::span<const ChangeBuffer> buffers);

 private:
  void PrepareSupport(const FloorGrid& grid);
  // The plane-h occupancy of a cell: 1 occupied (every active camera seeing it changed), 0
  // free, -1 no active camera sees it. Kept (in the cell's last entry of SupportPixels) for
  // the rest of the frame.
  int SupportAt(size_t h, int64_t cell, const ChangeLookup& changed, std::span<const ChangeBuffer> buffers);
  // SupportAt without the memo: the cameras' pixels asked, through `changed` (the reference,
  // elevated_check.cc) or, when given, `buffers` (SupportStateFromBuffers).
  int SupportState(size_t h, int64_t cell, int32_t* pixels, const ChangeLookup& changed,
                   std::span<const ChangeBuffer> buffers);
  // The fast path (elevated_check_fast.cc): the buffers read in place.
  int SupportStateFromBuffers(size_t h, int64_t cell, int32_t* pixels, std::span<const ChangeBuffer> buffers);
  // The cameras' pixels (PackPixel: (row << 16) | column) where the cell's centre at plane h projects
  // (entry n for camera n; -1 when it does not see it, kNotProjected until first used), then
  // the memo of SupportAt (generation * 4 + state + 1, or kNotProjected).
  int32_t* SupportPixels(size_t h, int64_t cell);
  // Camera n's entry of `pixels` (SupportPixels), projected on first use.
  int32_t SupportPixel(size_t h, size_t n, int64_t cell, int32_t* pixels);
  // A projection's pixel as SupportPixels holds it: (y << 16) | x, so the test reads x and y
  // without a division.
  static int32_t PackPixel(int x, int y) {
    return static_cast<int32_t>((static_cast<uint32_t>(y) << 16) | static_cast<uint32_t>(x));
  }
  static size_t PixelX(int32_t p) { return static_cast<uint32_t>(p) & 0xffffu; }
  static size_t PixelY(int32_t p) { return static_cast<uint32_t>(p) >> 16; }
  void RemoveUnsupported(const OccupancyMap& map, std::span<const int32_t> labels, const ChangeLookup& changed,
                         std::span<const ChangeBuffer> buffers, const std::vector<int>& kept_index,
                         const std::vector<Blob>& kept_groups, std::vector<Detection>& blobs);

  std::vector<double> support_heights_m_;
  double min_support_ = 0.2;
  double support_slack_m_ = 0.05;
  double plane_height_m_ = 0;
  std::vector<const CameraModel*> cameras_;
  std::vector<const Image<uint8_t>*> masks_;
  // The projections (SupportPixel), kNotProjected until first used.
  static constexpr int32_t kNotProjected = -2;
  static constexpr int64_t kTileSide = 8;  // cells; a tile is 8 x 8 cells (17 kB at 64 cameras)
  std::optional<FloorGrid> support_grid_;
  size_t support_tiles_x_ = 0;               // tiles per row of the grid
  size_t support_tiles_ = 0;                 // tiles of the grid
  std::vector<int64_t> support_tile_start_;  // [height * tiles + tile]: its start in support_pixel_, -1 none yet
  std::vector<int32_t> support_pixel_;       // per tile: [cell in tile (row-major) * (cameras + 1) + camera or memo]
  int32_t support_generation_ = 0;           // Apply calls that test, the memos' stamp
  bool frame_begun_ = false;                 // BeginFrame called since the last Apply
  std::vector<size_t> active_cameras_;       // this frame's active cameras, in order
  std::vector<std::vector<std::pair<int, int>>> footprint_;  // per detection, its footprint cells (reused)
};

}  // namespace occmap
