// Blobs: connected components (8-connected) of occupied cells, with area and centroid in
// metres, so detections can be counted and evaluated. Only kOccupied cells join blobs: free
// and unseen cells both separate them. The flood fill keeps its own stack (no recursion), so
// blobs of any size are fine.
//
//   std::vector<Blob> blobs = FindBlobs(map, {.min_area_m2 = 0.02});
#pragma once

#include <cstdint>
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

}  // namespace occmap
