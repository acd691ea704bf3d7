// Pictures of the floor: the per-cell visibility count with the cameras marked, as a plan view
// (+x right, +y up, see floor_grid.h), scaled so that its longer side is about max_side_px.
//
//   Image<Rgb8> img = RenderVisibility(lut, markers, 1200);
//   OCCMAP_RETURN_IF_ERROR(WritePng(out / "visibility.png", img.view()));
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "occmap/lut/ground_lut.h"
#include "occmap/util/image.h"

namespace occmap {

struct CameraMarker {
  std::string label;
  Eigen::Vector2d position_m;  // the optical centre's (x, y)
};

// Colour of a visibility count: 0 = dark grey (unseen), then a ramp from red (1 camera) to
// green and blue (all cameras).
Rgb8 VisibilityColor(int count, int num_cameras);

// The plan: the grid's cells coloured by view count, the grid outline, the cameras (which may
// stand outside the grid: the picture widens to include them) and a legend.
Image<Rgb8> RenderVisibility(const GroundLut& lut, const std::vector<CameraMarker>& cameras,
                             int max_side_px = 1200);

}  // namespace occmap
