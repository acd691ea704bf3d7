#include "occmap/sim/gt_rasters.h"

#include <algorithm>
#include <cmath>

namespace occmap::sim {

bool PointInPolygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  bool inside = false;
  const size_t n = poly.size();
  for (size_t i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y())) {
      const double x = a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (p.x() < x) inside = !inside;
    }
  }
  return inside;
}

std::vector<uint8_t> FootprintRaster(const FloorGrid& grid, const SceneState& state) {
  std::vector<uint8_t> raster(static_cast<size_t>(grid.num_cells()), 0);
  const double s = grid.cell_size_m;
  for (const ObjectInstance& obj : state.objects) {
    for (const auto& poly : obj.footprint_m) {
      if (poly.size() < 3) continue;
      Eigen::Vector2d lo = poly.front(), hi = poly.front();
      for (const auto& v : poly) {
        lo = lo.cwiseMin(v);
        hi = hi.cwiseMax(v);
      }
      // Cells whose centres may fall inside the polygon's box.
      const int i0 = std::max(0, static_cast<int>(std::floor((lo.x() - grid.origin_x_m) / s - 0.5)));
      const int j0 = std::max(0, static_cast<int>(std::floor((lo.y() - grid.origin_y_m) / s - 0.5)));
      const int i1 = std::min(grid.cells_x - 1, static_cast<int>(std::ceil((hi.x() - grid.origin_x_m) / s - 0.5)));
      const int j1 = std::min(grid.cells_y - 1, static_cast<int>(std::ceil((hi.y() - grid.origin_y_m) / s - 0.5)));
      for (int j = j0; j <= j1; ++j) {
        for (int i = i0; i <= i1; ++i) {
          const int64_t cell = int64_t{j} * grid.cells_x + i;
          if (PointInPolygon(poly, grid.CellCenter(cell))) raster[static_cast<size_t>(cell)] = 1;
        }
      }
    }
  }
  return raster;
}

Image<uint8_t> RasterImage(const FloorGrid& grid, const std::vector<uint8_t>& raster) {
  Image<uint8_t> image(grid.cells_x, grid.cells_y);
  for (int j = 0; j < grid.cells_y; ++j) {
    uint8_t* row = image.row(grid.cells_y - 1 - j);
    const uint8_t* cells = raster.data() + static_cast<size_t>(j) * static_cast<size_t>(grid.cells_x);
    for (int i = 0; i < grid.cells_x; ++i) row[i] = cells[i] != 0 ? 255 : 0;
  }
  return image;
}

bool BlockedByObjects(const SceneState& state, const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  const Eigen::Vector3d v = to - from;
  const double len = v.norm();
  if (!(len > 0)) return false;
  const Eigen::Vector3d d = v / len;
  for (const ObjectInstance& obj : state.objects) {
    // Cull with the bounding sphere, then the bounding cylinder.
    const Eigen::Vector3d w = obj.sphere_centre_m - from;
    const double along = std::clamp(w.dot(d), 0.0, len);
    if ((w - along * d).squaredNorm() > obj.sphere_radius_m * obj.sphere_radius_m) continue;
    const auto interval = RayCylinderInterval(obj.bound, from, d);
    if (!interval || interval->second <= 0 || interval->first >= len) continue;
    for (const Primitive& part : obj.parts) {
      if (SegmentBlocked(part, from, to)) return true;
    }
  }
  return false;
}

HullComputer::HullComputer(const Scene& scene, const std::vector<Image<uint8_t>>& masks, Context& ctx)
    : grid_(scene.grid()) {
  OCCMAP_CHECK(masks.size() == scene.num_cameras(), "one mask per camera");
  const size_t cells = static_cast<size_t>(grid_.num_cells());
  for (size_t c = 0; c < scene.num_cameras(); ++c) {
    const CameraModel& cam = scene.camera(c);
    const ImageSize size = cam.image_size();
    const Image<uint8_t>& mask = masks[c];
    OCCMAP_CHECK(mask.empty() || (mask.width() == size.width && mask.height() == size.height), "mask size");
    centres_.push_back(*cam.CenterInWorld());
    std::vector<uint8_t> seen(cells, 0);
    ParallelFor(ctx, 0, grid_.cells_y, [&](int64_t j0, int64_t j1, int) {
      for (int64_t j = j0; j < j1; ++j) {
        for (int i = 0; i < grid_.cells_x; ++i) {
          const int64_t cell = j * grid_.cells_x + i;
          const Eigen::Vector2d xy = grid_.CellCenter(cell);
          const auto px = cam.Project({xy.x(), xy.y(), 0.0});
          if (!px || !cam.InImage(*px)) continue;
          const int u = std::clamp(static_cast<int>(std::floor(px->x() + 0.5)), 0, size.width - 1);
          const int v = std::clamp(static_cast<int>(std::floor(px->y() + 0.5)), 0, size.height - 1);
          if (mask.empty() || mask(u, v) != 0) seen[static_cast<size_t>(cell)] = 1;
        }
      }
    });
    seen_.push_back(std::move(seen));
  }
}

OccupancyMap HullComputer::Compute(const SceneState& state, Context& ctx) const {
  OccupancyMap map(grid_);
  std::vector<CellState>& out = map.states();
  ParallelFor(ctx, 0, grid_.cells_y, [&](int64_t j0, int64_t j1, int) {
    for (int64_t j = j0; j < j1; ++j) {
      for (int i = 0; i < grid_.cells_x; ++i) {
        const int64_t cell = j * grid_.cells_x + i;
        const Eigen::Vector2d xy = grid_.CellCenter(cell);
        const Eigen::Vector3d p(xy.x(), xy.y(), 0.0);
        bool seen = false, occupied = true;
        for (size_t c = 0; c < seen_.size() && occupied; ++c) {
          if (!seen_[c][static_cast<size_t>(cell)]) continue;
          seen = true;
          if (state.objects.empty() || !BlockedByObjects(state, centres_[c], p)) occupied = false;
        }
        out[static_cast<size_t>(cell)] = !seen ? CellState::kUnseen : occupied ? CellState::kOccupied : CellState::kFree;
      }
    }
  });
  return map;
}

}  // namespace occmap::sim
