#include "occmap/lut/floor_grid.h"

#include <fmt/core.h>

#include <cmath>

namespace occmap {

Status FloorGrid::Validate() const {
  if (!std::isfinite(origin_x_m) || !std::isfinite(origin_y_m)) {
    return InvalidInput("origin_m: expected finite numbers");
  }
  if (!(cell_size_m > 0) || !std::isfinite(cell_size_m)) {
    return InvalidInput(fmt::format("cell_size_m: expected a positive number, found {}", cell_size_m));
  }
  if (cells_x <= 0 || cells_y <= 0) {
    return InvalidInput(fmt::format("grid: expected at least 1 x 1 cells, found {} x {}", cells_x, cells_y));
  }
  if (num_cells() > kMaxCells) {
    return ResourceExhausted(fmt::format(
        "grid: {} x {} = {} cells is too large (at most {} cells); use larger cells or a smaller area",
        cells_x, cells_y, num_cells(), kMaxCells));
  }
  return Status::Ok();
}

void FloorGrid::AppendToHash(Hasher& h) const {
  h.Add("grid");
  h.AddPod(origin_x_m);
  h.AddPod(origin_y_m);
  h.AddPod(cells_x);
  h.AddPod(cells_y);
  h.AddPod(cell_size_m);
}

Result<FloorGrid> ParseFloorGrid(const YamlField& floor) {
  FloorGrid g;
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> origin, floor.GetDoubles("origin_m", 2));
  g.origin_x_m = origin[0];
  g.origin_y_m = origin[1];
  OCCMAP_ASSIGN_OR_RETURN(YamlField cell_field, floor.Get("cell_size_m"));
  OCCMAP_ASSIGN_OR_RETURN(g.cell_size_m, cell_field.AsDouble());
  if (!(g.cell_size_m > 0)) return cell_field.Error(fmt::format("expected a positive number, found {}", g.cell_size_m));
  const bool has_cells = floor.Has("cells"), has_size = floor.Has("size_m");
  if (has_cells == has_size) return floor.Error("expected exactly one of 'cells' or 'size_m'");
  if (has_cells) {
    OCCMAP_ASSIGN_OR_RETURN(YamlField f, floor.Get("cells"));
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> c, f.AsDoubles(2));
    for (double d : c) {
      if (d != std::floor(d) || d < 1 || d > 1e9) {
        return f.Error(fmt::format("expected two positive whole numbers, found [{}, {}]", c[0], c[1]));
      }
    }
    g.cells_x = static_cast<int>(c[0]);
    g.cells_y = static_cast<int>(c[1]);
  } else {
    OCCMAP_ASSIGN_OR_RETURN(YamlField f, floor.Get("size_m"));
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> s, f.AsDoubles(2));
    double n[2];
    for (int i = 0; i < 2; ++i) {
      n[i] = std::round(s[i] / g.cell_size_m);
      if (!(s[i] > 0) || std::abs(n[i] * g.cell_size_m - s[i]) > 1e-6 * s[i] || n[i] > 1e9) {
        return f.Error(fmt::format("expected positive multiples of cell_size_m = {}, found [{}, {}]", g.cell_size_m,
                                   s[0], s[1]));
      }
    }
    g.cells_x = static_cast<int>(n[0]);
    g.cells_y = static_cast<int>(n[1]);
  }
  if (Status s = g.Validate(); !s.ok()) return Status(s.code(), fmt::format("{}: {}", floor.Where(), s.message()));
  return g;
}

}  // namespace occmap
