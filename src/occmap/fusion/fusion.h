// Fusion, the paper's equation 5, into a tri-state occupancy map, with both of its algorithms.
//
// Input: one change buffer for all cameras, indexed by global pixel id (GroundLut: camera n's
// pixel (c, r) is pixel_offset(n) + r * width + c), 1 = changed, 0 = unchanged; and which
// cameras are active (a camera whose stream ended is inactive: its pixels say nothing, and the
// cells only it could see become unseen).
//
// Rule. A camera "says free" for a cell when at least one of its pixels that view the cell is
// unchanged (changes[pixel] == 0; any non-zero byte is a change). With max_free_views = k, a
// cell seen by at least one active camera is occupied when at most k of those cameras say free
// and at least one does not; otherwise it is free. A cell no active camera sees is kUnseen.
// k = 0 is the paper's AND: occupied only when every viewing pixel of every camera changed.
// k >= (active viewing cameras) - 1 is the OR: occupied when some camera sees a change in all
// of its pixels of the cell. Inactive cameras are ignored entirely (their bytes may be garbage).
//
// Image-based: the paper's scan of L1 in pixel order, scattering "free" into the map through a
// sentinel cell one past the end (plus the coverage-fix pairs), then the tri-state from the
// active view counts. For k = 0 that is one byte array for all cameras (active ones scanned);
// for k > 0 each active camera marks the cells it says free and the marks are summed into
// per-cell votes. Map-based: the gather over L2 per cell, with early exit as soon as the
// answer is known (the first free view for k = 0; k + 1 free cameras otherwise), counting
// distinct cameras since L2 entries are grouped by camera. Both give identical maps (tests).
//
// Single-threaded for now; the speed issue adds a Context overload (ParallelFor over cells
// for map-based, over pixels with per-worker maps for image-based).
//
//   Fusion fusion(lut);                       // per-camera views of each cell, built once
//   fusion.Fuse(changes, active, options, map);
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

enum class FusionMethod { kImageBased, kMapBased };

struct FusionOptions {
  FusionMethod method = FusionMethod::kImageBased;
  int max_free_views = 0;  // k above, 0..num_cameras - 1; 0 = the paper's AND
  Status Validate(int num_cameras) const;
};

class Fusion {
 public:
  // lut must outlive this object. Builds camera_sees_ (one byte per camera and cell) from L2.
  explicit Fusion(const GroundLut& lut);

  // changes.size() == lut.total_pixels(); active.size() == lut.num_cameras(); options valid
  // for lut.num_cameras() (all CHECKs). `map` is reset to the lut's grid when it has another
  // grid (e.g. default-constructed); every cell is written. Allocates nothing after the first
  // call with the same map (the per-cell active view counts are recomputed only when the
  // active set changes).
  void Fuse(std::span<const uint8_t> changes, const std::vector<bool>& active, const FusionOptions& options,
            OccupancyMap& map);

  const GroundLut& lut() const { return lut_; }

 private:
  void FuseImageBased(std::span<const uint8_t> changes, const std::vector<bool>& active, int k, OccupancyMap& map);
  void FuseMapBased(std::span<const uint8_t> changes, const std::vector<bool>& active, int k, OccupancyMap& map);
  void CountActiveViews(const std::vector<bool>& active);

  // Per cell: kUnseen when no active camera views it, else the rule on the free votes.
  static CellState Decide(int active_views, int free_votes, int k) {
    if (active_views == 0) return CellState::kUnseen;
    return free_votes <= k && free_votes < active_views ? CellState::kOccupied : CellState::kFree;
  }

  const GroundLut& lut_;
  std::vector<std::vector<uint8_t>> camera_sees_;  // [camera][cell] 1 when the camera views it
  std::vector<uint8_t> active_views_;              // per cell, for the current active set
  std::vector<bool> active_for_counts_;            // the active set active_views_ was counted for
  std::vector<uint8_t> camera_active_;             // per camera, 1 / 0 (this call's active set)
  std::vector<uint8_t> scratch_;                   // per cell (+ sentinel)
  std::vector<uint8_t> free_votes_;                // per cell
};

// The paper's image-based loop exactly as printed (sentinel version, AND only, all cameras
// active): O = 1 everywhere, then O[L1[p]] = 0 for every unchanged pixel. Returns O with the
// sentinel cell at the end (num_cells + 1 bytes; 1 = occupied, also for cells no camera sees).
// Kept as the oracle and the benchmark baseline; the coverage-fix pairs are applied the same
// way, after each camera's L1.
std::vector<uint8_t> PaperImageBasedLoop(const GroundLut& lut, std::span<const uint8_t> changes);

}  // namespace occmap
