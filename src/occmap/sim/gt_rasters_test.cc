#include "occmap/sim/gt_rasters.h"

#include <gtest/gtest.h>

#include "occmap/sim/renderer.h"
#include "occmap/sim/sim_test_util.h"

namespace occmap::sim {
namespace {

std::vector<Image<uint8_t>> Masks(const Scene& scene, Context& ctx) {
  std::vector<Image<uint8_t>> masks;
  for (size_t c = 0; c < scene.num_cameras(); ++c) masks.push_back(CameraRenderer(scene, c, ctx).floor_mask());
  return masks;
}

TEST(GroundTruthRasters, FootprintRasterMarksTheCellsWhoseCentresAreInside) {
  const FloorGrid grid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 10, .cells_y = 10, .cell_size_m = 0.1};
  ObjectInstance box;
  box.footprint_m = {{{0.12, 0.12}, {0.38, 0.12}, {0.38, 0.28}, {0.12, 0.28}}};
  const std::vector<uint8_t> r = FootprintRaster(grid, SceneState{0, 0, {box}});
  int count = 0;
  for (uint8_t v : r) count += v;
  EXPECT_EQ(count, 3 * 2);  // centres x = 0.15, 0.25, 0.35 and y = 0.15, 0.25
  EXPECT_EQ(r[1 * 10 + 1], 1);
  const Image<uint8_t> img = RasterImage(grid, r);
  EXPECT_EQ(img(1, 10 - 1 - 1), 255);  // +y up: cell row 1 is image row 8
  EXPECT_EQ(img(1, 1), 0);
}

TEST(GroundTruthRasters, HullOccupiesEveryBoundaryFootprintCellThatSomeCameraSees) {
  // The paper's theorem (section 2.1): visible points on the boundary of an object's contact
  // with the floor are exactly reconstructed by volume intersection in the plane.
  const Scene lab = sim_testing::SmallLab();
  Context ctx(2);
  const HullComputer hull(lab, Masks(lab, ctx), ctx);
  const FloorGrid& g = lab.grid();
  int64_t boundary_seen = 0;
  for (int64_t f = 0; f < lab.num_frames(); f += 9) {
    const SceneState state = lab.StateAt(f);
    const std::vector<uint8_t> feet = FootprintRaster(g, state);
    const OccupancyMap map = hull.Compute(state, ctx);
    for (int j = 1; j + 1 < g.cells_y; ++j) {
      for (int i = 1; i + 1 < g.cells_x; ++i) {
        const int64_t cell = int64_t{j} * g.cells_x + i;
        if (!feet[static_cast<size_t>(cell)]) continue;
        const bool boundary = !feet[static_cast<size_t>(cell - 1)] || !feet[static_cast<size_t>(cell + 1)] ||
                              !feet[static_cast<size_t>(cell - g.cells_x)] || !feet[static_cast<size_t>(cell + g.cells_x)];
        bool seen = false;
        for (size_t c = 0; c < lab.num_cameras(); ++c) seen |= hull.seen_by(c)[static_cast<size_t>(cell)] != 0;
        if (!boundary || !seen) continue;
        ++boundary_seen;
        ASSERT_EQ(map.state(cell), CellState::kOccupied) << "frame " << f << " cell " << i << "," << j;
      }
    }
    // The hull contains the footprint but is larger (occlusion), and most of the floor is free.
    EXPECT_GT(map.Count(CellState::kOccupied), std::count(feet.begin(), feet.end(), 1) / 2);
    EXPECT_GT(map.Count(CellState::kFree), g.num_cells() / 2);
  }
  EXPECT_GT(boundary_seen, 100);
}

TEST(GroundTruthRasters, CellsUnderThePlanterAreUnseenAndEmptyFloorIsFree) {
  const Scene lab = sim_testing::SmallLab();
  Context ctx(2);
  const HullComputer hull(lab, Masks(lab, ctx), ctx);
  const OccupancyMap empty = hull.Compute(SceneState{}, ctx);
  EXPECT_EQ(empty.Count(CellState::kOccupied), 0);
  EXPECT_EQ(empty.state(lab.grid().CellAt(8.45, 3.3)), CellState::kUnseen);
  EXPECT_EQ(empty.state(lab.grid().CellAt(4.5, 3.0)), CellState::kFree);
}

TEST(GroundTruthRasters, HullMatchesTheRenderedChangeMasksThroughCellCentres) {
  // With perfect change detection, a cell is occupied iff every camera seeing it sees a change
  // at the cell centre's pixel -- up to pixels whose centre ray differs from the ray to the cell
  // centre (silhouette edges): on the lab at full size the two agree on almost every cell.
  const Scene lab = sim_testing::SmallLab(1.0, 40);
  Context ctx(2);
  std::vector<Image<uint8_t>> masks;
  std::vector<RenderedView> views(lab.num_cameras());
  const SceneState state = lab.StateAt(30);
  for (size_t c = 0; c < lab.num_cameras(); ++c) {
    const CameraRenderer r(lab, c, ctx);
    masks.push_back(r.floor_mask());
    r.Render(state, ctx, &views[c], false);
  }
  const HullComputer hull(lab, masks, ctx);
  const OccupancyMap map = hull.Compute(state, ctx);
  const FloorGrid& g = lab.grid();
  int64_t agree = 0, occupied_cells = 0;
  for (int64_t cell = 0; cell < g.num_cells(); ++cell) {
    if (map.state(cell) == CellState::kUnseen) continue;
    const Eigen::Vector2d xy = g.CellCenter(cell);
    bool all_changed = true;
    for (size_t c = 0; c < lab.num_cameras(); ++c) {
      if (!hull.seen_by(c)[static_cast<size_t>(cell)]) continue;
      const auto px = *lab.camera(c).Project({xy.x(), xy.y(), 0.0});
      all_changed &= views[c].ids(static_cast<int>(std::floor(px.x() + 0.5)), static_cast<int>(std::floor(px.y() + 0.5))) != 0;
    }
    occupied_cells += map.state(cell) == CellState::kOccupied;
    agree += (map.state(cell) == CellState::kOccupied) == all_changed;
  }
  EXPECT_GT(occupied_cells, 300);
  EXPECT_GT(static_cast<double>(agree), 0.999 * static_cast<double>(map.Count(CellState::kFree) + occupied_cells));
}

}  // namespace
}  // namespace occmap::sim
