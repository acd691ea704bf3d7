// The picture that shows at once whether a floor calibration fits: the floor grid (lines every
// spacing_m over an area, projected through the camera model) and the world axes from the
// origin over the camera's image, each floor point's given pixel (green ring) and its world
// point reprojected (red cross) joined by a line, numbered as in the report.
//
//   OverlayOptions o;  o.area_min_m = {0, 0};  o.area_max_m = {9, 6.5};
//   Image<Rgb8> pic = DrawCalibrationOverlay(frame.view(), *model, points, o);
#pragma once

#include <Eigen/Core>
#include <span>
#include <string>

#include "occmap/calib/floor_calibration.h"
#include "occmap/geometry/camera_model.h"
#include "occmap/util/image.h"

namespace occmap {

struct OverlayOptions {
  Eigen::Vector2d area_min_m = Eigen::Vector2d::Zero();  // the grid's extent on the floor
  Eigen::Vector2d area_max_m = Eigen::Vector2d::Zero();
  double spacing_m = 1.0;
  std::string caption;  // drawn at the top left (e.g. the errors)
};

// The image at the camera model's size (a different size is drawn over as it is, the model
// rescaled to it).
Image<Rgb8> DrawCalibrationOverlay(ImageView<const Rgb8> image, const CameraModel& camera,
                                   std::span<const FloorPoint> points, const OverlayOptions& options);

// The points' bounding box widened to whole multiples of spacing_m with one more all round.
void OverlayAreaAroundPoints(std::span<const FloorPoint> points, OverlayOptions& options);

}  // namespace occmap
