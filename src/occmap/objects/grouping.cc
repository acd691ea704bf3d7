#include "occmap/objects/grouping.h"

#include <cmath>
#include <cstdlib>
#include <vector>

#include "occmap/util/status.h"

namespace occmap {

void GrowOccupied(const OccupancyMap& map, double radius_m, OccupancyMap& out) {
  const FloorGrid& g = map.grid();
  out = map;
  const double r = radius_m / g.cell_size_m;
  if (!(r > 0)) return;
  // A free cell becomes occupied when an occupied cell centre lies within r (+1e-4) of its
  // own, as GrowOccupiedReference. Occupied cells are few: each run of them along a row stamps,
  // on every row dj within reach, the span widened by that row's half-width of the disc.
  const int reach = static_cast<int>(std::floor(r + 1e-4));
  std::vector<int> half_width(static_cast<size_t>(reach) + 1);
  for (int dj = 0; dj <= reach; ++dj) {
    int w = 0;
    while (w + 1 <= reach && std::hypot(w + 1, dj) <= r + 1e-4) ++w;
    half_width[static_cast<size_t>(dj)] = w;
  }
  const std::vector<CellState>& s = map.states();
  std::vector<CellState>& o = out.states();
  for (int j = 0; j < g.cells_y; ++j) {
    const CellState* row = s.data() + static_cast<size_t>(j) * g.cells_x;
    for (int i = static_cast<int>(NextOccupied(row, 0, g.cells_x)); i < g.cells_x;
         i = static_cast<int>(NextOccupied(row, i, g.cells_x))) {
      int end = i;
      while (end + 1 < g.cells_x && row[end + 1] == CellState::kOccupied) ++end;
      for (int dj = -reach; dj <= reach; ++dj) {
        const int jj = j + dj;
        if (jj < 0 || jj >= g.cells_y) continue;
        const int w = half_width[static_cast<size_t>(std::abs(dj))];
        const int lo = std::max(0, i - w), hi = std::min(g.cells_x - 1, end + w);
        CellState* target = o.data() + static_cast<size_t>(jj) * g.cells_x;
        // Free -> occupied, the rest kept: written as a select on every cell so that it
        // vectorises (a conditional store does not): lab scene, 300 frames, AMD EPYC 2 threads,
        // perf samples at 4 kHz 133 -> 33.
        for (int ii = lo; ii <= hi; ++ii) {
          target[ii] = target[ii] == CellState::kFree ? CellState::kOccupied : target[ii];
        }
      }
      i = end + 1;
    }
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

void FootprintBlobs(const OccupancyMap& original, const BlobFinder& groups, std::vector<Blob>& out,
                    std::vector<Eigen::Matrix2d>* spreads) {
  const FloorGrid& g = original.grid();
  OCCMAP_CHECK(static_cast<int64_t>(groups.labels().size()) == g.num_cells(), "FootprintBlobs: groups of another grid");
  const auto& s = original.states();
  out = groups.blobs();
  if (spreads != nullptr) spreads->assign(out.size(), Eigen::Matrix2d::Zero());
  for (size_t k = 0; k < out.size(); ++k) {
    int64_t n = 0, sum_i = 0, sum_j = 0;  // exact: the order of the cells does not matter
    for (int64_t c : groups.cells(k)) {
      if (s[static_cast<size_t>(c)] != CellState::kOccupied) continue;
      ++n;
      sum_i += c % g.cells_x;
      sum_j += c / g.cells_x;
    }
    if (n == 0) {  // grown around an unseen gap, away from its source: no footprint
      out[k].cells = 0;
      out[k].area_m2 = 0;
      continue;
    }
    const double cells = static_cast<double>(n);
    out[k].cells = n;
    out[k].area_m2 = cells * g.cell_size_m * g.cell_size_m;
    out[k].x_m = g.origin_x_m + (static_cast<double>(sum_i) / cells + 0.5) * g.cell_size_m;
    out[k].y_m = g.origin_y_m + (static_cast<double>(sum_j) / cells + 0.5) * g.cell_size_m;
    if (spreads == nullptr || n < 2) continue;
    // About the mean index (exact sums), in cells, then scaled: a second pass over the cells.
    const double mean_i = static_cast<double>(sum_i) / cells, mean_j = static_cast<double>(sum_j) / cells;
    double sii = 0, sij = 0, sjj = 0;
    for (int64_t c : groups.cells(k)) {
      if (s[static_cast<size_t>(c)] != CellState::kOccupied) continue;
      const double di = static_cast<double>(c % g.cells_x) - mean_i, dj = static_cast<double>(c / g.cells_x) - mean_j;
      sii += di * di;
      sij += di * dj;
      sjj += dj * dj;
    }
    const double scale = g.cell_size_m * g.cell_size_m / cells;
    (*spreads)[k] << sii * scale, sij * scale, sij * scale, sjj * scale;
  }
}

}  // namespace occmap
