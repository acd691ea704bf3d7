#include "occmap/fusion/morphology.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "occmap/util/status.h"

namespace occmap {

void GrowOccupied(const OccupancyMap& map, double radius_m, OccupancyMap& out) {
  const FloorGrid& g = map.grid();
  out = map;
  const double r_cells = radius_m / g.cell_size_m;
  if (!(r_cells > 0)) return;
  // Exact Euclidean distance (OpenCV's DIST_MASK_PRECISE) from every cell to the nearest
  // occupied one; rows are cell rows j, columns cells i.
  cv::Mat not_occupied(g.cells_y, g.cells_x, CV_8UC1);
  const auto& s = map.states();
  for (int64_t c = 0; c < g.num_cells(); ++c) not_occupied.data[c] = s[c] == CellState::kOccupied ? 0 : 255;
  cv::Mat dist;
  cv::distanceTransform(not_occupied, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
  const float limit = static_cast<float>(r_cells + 1e-4);
  const float* d = reinterpret_cast<const float*>(dist.data);
  auto& o = out.states();
  for (int64_t c = 0; c < g.num_cells(); ++c) {
    if (s[c] == CellState::kFree && d[c] <= limit) o[c] = CellState::kOccupied;
  }
}

void GrowOccupiedReference(const OccupancyMap& map, double radius_m, OccupancyMap& out) {
  const FloorGrid& g = map.grid();
  out = map;
  const double r = radius_m / g.cell_size_m;
  if (!(r > 0)) return;
  const int reach = static_cast<int>(std::floor(r + 1e-4));
  const auto& s = map.states();
  for (int j = 0; j < g.cells_y; ++j) {
    for (int i = 0; i < g.cells_x; ++i) {
      const size_t c = static_cast<size_t>(j) * g.cells_x + i;
      if (s[c] != CellState::kFree) continue;
      bool near = false;
      for (int dj = -reach; dj <= reach && !near; ++dj) {
        for (int di = -reach; di <= reach && !near; ++di) {
          const int ii = i + di, jj = j + dj;
          if (ii < 0 || jj < 0 || ii >= g.cells_x || jj >= g.cells_y || std::hypot(di, dj) > r + 1e-4) continue;
          near = s[static_cast<size_t>(jj) * g.cells_x + ii] == CellState::kOccupied;
        }
      }
      if (near) out.states()[c] = CellState::kOccupied;
    }
  }
}

std::vector<Blob> FootprintBlobs(const OccupancyMap& original, const std::vector<int32_t>& labels,
                                 const std::vector<Blob>& groups) {
  const FloorGrid& g = original.grid();
  OCCMAP_CHECK(static_cast<int64_t>(labels.size()) == g.num_cells(), "FootprintBlobs: labels of another grid");
  std::vector<Blob> out = groups;
  std::vector<int64_t> n(groups.size(), 0), sum_i(groups.size(), 0), sum_j(groups.size(), 0);
  const auto& s = original.states();
  for (int64_t c = 0; c < g.num_cells(); ++c) {
    const int32_t label = labels[c];
    if (label < 0 || s[c] != CellState::kOccupied) continue;
    ++n[label];
    sum_i[label] += c % g.cells_x;
    sum_j[label] += c / g.cells_x;
  }
  for (size_t k = 0; k < out.size(); ++k) {
    if (n[k] == 0) {  // grown around an unseen gap, away from its source: no footprint
      out[k].cells = 0;
      out[k].area_m2 = 0;
      continue;
    }
    const double cells = static_cast<double>(n[k]);
    out[k].cells = n[k];
    out[k].area_m2 = cells * g.cell_size_m * g.cell_size_m;
    out[k].x_m = g.origin_x_m + (static_cast<double>(sum_i[k]) / cells + 0.5) * g.cell_size_m;
    out[k].y_m = g.origin_y_m + (static_cast<double>(sum_j[k]) / cells + 0.5) * g.cell_size_m;
  }
  return out;
}

}  // namespace occmap
