// Blobs: connected components (8-connected) of occupied cells, with area and centroid in
// metres, so detections can be counted and evaluated. Only kOccupied cells join blobs: free
// and unseen cells both separate them. The flood fill keeps its own stack (no recursion), so
// blobs of any size are fine.
//
//   std::vector<Blob> blobs = FindBlobs(map, {.min_area_m2 = 0.02});
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "occmap/fusion/occupancy_map.h"

namespace occmap {

struct Blob {
  double x_m = 0, y_m = 0;  // centroid: the mean of the cells' FloorGrid::CellCenter
  double area_m2 = 0;       // cells * cell_size_m^2
  int64_t cells = 0;
  int min_i = 0, min_j = 0, max_i = 0, max_j = 0;  // bounding box in cells (inclusive)
};

struct BlobOptions {
  double min_area_m2 = 0.0;  // blobs with area_m2 < min_area_m2 are dropped
};

// Blobs in order of their first cell (row-major from cell 0). With `labels`, also each cell's
// blob: the index into the result, or -1 (not occupied, or in a blob under min_area_m2).
std::vector<Blob> FindBlobs(const OccupancyMap& map, const BlobOptions& options = {},
                            std::vector<int32_t>* labels = nullptr);

// The first index in [from, to) whose state is kOccupied, or `to`: free spans are skipped
// eight cells at a time (kOccupied is the only state with bit 1 set).
int64_t NextOccupied(const CellState* states, int64_t from, int64_t to);

// FindBlobs for maps that are mostly free, run every frame: the same blobs and labels, with
// its buffers kept between calls (no per-call allocation once grown), free spans skipped a
// word at a time, and only the cells labelled by the previous call reset. It also gives each
// blob's cells, so that callers need not scan the map again (FootprintBlobs in
// morphology.h). Results stay valid until the next Find.
//
//   BlobFinder finder;
//   const std::vector<Blob>& blobs = finder.Find(map);   // == FindBlobs(map)
//   for (int64_t cell : finder.cells(0)) ...             // finder.labels()[cell] == 0
class BlobFinder {
 public:
  const std::vector<Blob>& Find(const OccupancyMap& map, const BlobOptions& options = {});

  const std::vector<Blob>& blobs() const { return blobs_; }
  // As FindBlobs' labels: per cell of the last map, its blob or -1.
  const std::vector<int32_t>& labels() const { return labels_; }
  // Blob k's cells (map indices, in the order the fill reached them).
  std::span<const int64_t> cells(size_t k) const {
    return {members_.data() + offsets_[k], static_cast<size_t>(offsets_[k + 1] - offsets_[k])};
  }

 private:
  std::vector<Blob> blobs_;
  std::vector<int32_t> labels_;    // -1 everywhere except the cells in members_ and dropped_
  std::vector<int64_t> members_;   // the kept blobs' cells, blob after blob
  std::vector<int64_t> offsets_;   // blob k's cells: members_[offsets_[k], offsets_[k + 1])
  std::vector<int64_t> dropped_;   // cells of blobs under min_area_m2 (labelled kDropped during Find)
  std::vector<int64_t> stack_;
};

}  // namespace occmap
