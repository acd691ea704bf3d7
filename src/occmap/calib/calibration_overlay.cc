#include "occmap/calib/calibration_overlay.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>

namespace occmap {
namespace {

// Pixel (OpenCV's convention, centres on integers) to cv::Point with 4 fractional bits.
constexpr int kShift = 4;
cv::Point Fixed(const Eigen::Vector2d& p) {
  return {static_cast<int>(std::lround(p.x() * (1 << kShift))), static_cast<int>(std::lround(p.y() * (1 << kShift)))};
}

// A floor line as a polyline of short segments; pieces off the picture or bent by the lens
// beyond its valid domain are left out.
void DrawFloorLine(cv::Mat& m, const CameraModel& cam, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                   const cv::Scalar& colour, int thickness) {
  const double length = (b - a).norm();
  const int steps = std::max(1, static_cast<int>(std::ceil(length / 0.05)));
  const double diagonal = std::hypot(m.cols, m.rows);
  std::optional<Eigen::Vector2d> prev;
  for (int i = 0; i <= steps; ++i) {
    const Eigen::Vector2d p = a + (b - a) * (static_cast<double>(i) / steps);
    std::optional<Eigen::Vector2d> px = cam.Project({p.x(), p.y(), 0.0});
    if (px && (px->x() < -diagonal || px->y() < -diagonal || px->x() > 2 * diagonal || px->y() > 2 * diagonal)) {
      px.reset();
    }
    if (px && prev && (*px - *prev).norm() < 0.25 * diagonal) {
      cv::line(m, Fixed(*prev), Fixed(*px), colour, thickness, cv::LINE_AA, kShift);
    }
    prev = px;
  }
}

}  // namespace

void OverlayAreaAroundPoints(std::span<const FloorPoint> points, OverlayOptions& o) {
  if (points.empty()) return;
  Eigen::Vector2d lo = points[0].floor_m, hi = points[0].floor_m;
  for (const auto& p : points) {
    lo = lo.cwiseMin(p.floor_m);
    hi = hi.cwiseMax(p.floor_m);
  }
  const double s = o.spacing_m;
  o.area_min_m = {std::floor(lo.x() / s) * s - s, std::floor(lo.y() / s) * s - s};
  o.area_max_m = {std::ceil(hi.x() / s) * s + s, std::ceil(hi.y() / s) * s + s};
}

Image<Rgb8> DrawCalibrationOverlay(ImageView<const Rgb8> image, const CameraModel& camera_in,
                                   std::span<const FloorPoint> points, const OverlayOptions& o) {
  const ImageSize size{image.width(), image.height()};
  std::unique_ptr<CameraModel> resized;
  const CameraModel* cam = &camera_in;
  if (camera_in.image_size() != size) {
    resized = camera_in.Resized(size);
    cam = resized.get();
  }
  const PixelRescale rescale = PixelRescale::Between(camera_in.image_size(), size);
  Image<Rgb8> out(size.width, size.height);
  for (int y = 0; y < size.height; ++y) std::memcpy(out.row(y), image.row(y), sizeof(Rgb8) * size.width);
  cv::Mat m(size.height, size.width, CV_8UC3, out.view().data(), sizeof(Rgb8) * static_cast<size_t>(out.stride_elems()));
  // Dim the picture a little so that the drawing stands out.
  m.convertTo(m, -1, 0.75, 0);
  const int thick = std::max(1, static_cast<int>(std::lround(size.width / 800.0)));
  const double s = o.spacing_m > 0 ? o.spacing_m : 1.0;
  const cv::Scalar grid_colour(255, 220, 0);  // R, G, B: the image is RGB
  for (double x = o.area_min_m.x(); x <= o.area_max_m.x() + 1e-9; x += s) {
    DrawFloorLine(m, *cam, {x, o.area_min_m.y()}, {x, o.area_max_m.y()}, grid_colour, thick);
  }
  for (double y = o.area_min_m.y(); y <= o.area_max_m.y() + 1e-9; y += s) {
    DrawFloorLine(m, *cam, {o.area_min_m.x(), y}, {o.area_max_m.x(), y}, grid_colour, thick);
  }
  // The world axes from the origin, one grid step long: x red, y green (their turn shows handedness).
  DrawFloorLine(m, *cam, {0, 0}, {s, 0}, cv::Scalar(255, 40, 40), 3 * thick);
  DrawFloorLine(m, *cam, {0, 0}, {0, s}, cv::Scalar(40, 255, 40), 3 * thick);
  const double font = 0.45 * thick;
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d given(rescale.MapU(points[i].pixel.x()), rescale.MapV(points[i].pixel.y()));
    const auto re = cam->Project({points[i].floor_m.x(), points[i].floor_m.y(), 0.0});
    if (re) {
      cv::line(m, Fixed(given), Fixed(*re), cv::Scalar(255, 255, 255), thick, cv::LINE_AA, kShift);
      const int arm = 6 * thick << kShift;
      const cv::Point c = Fixed(*re);
      cv::line(m, c - cv::Point(arm, arm), c + cv::Point(arm, arm), cv::Scalar(255, 40, 40), 2 * thick, cv::LINE_AA, kShift);
      cv::line(m, c - cv::Point(arm, -arm), c + cv::Point(arm, -arm), cv::Scalar(255, 40, 40), 2 * thick, cv::LINE_AA,
               kShift);
    }
    cv::circle(m, Fixed(given), 7 * thick << kShift, cv::Scalar(40, 255, 40), 2 * thick, cv::LINE_AA, kShift);
    const std::string label = std::to_string(i + 1);
    const cv::Point at(static_cast<int>(given.x()) + 9 * thick, static_cast<int>(given.y()) - 9 * thick);
    cv::putText(m, label, at, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(0, 0, 0), 3 * thick, cv::LINE_AA);
    cv::putText(m, label, at, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(255, 255, 255), thick, cv::LINE_AA);
  }
  if (!o.caption.empty()) {
    const cv::Point at(8 * thick, 20 * thick);
    cv::putText(m, o.caption, at, cv::FONT_HERSHEY_SIMPLEX, font * 1.2, cv::Scalar(0, 0, 0), 4 * thick, cv::LINE_AA);
    cv::putText(m, o.caption, at, cv::FONT_HERSHEY_SIMPLEX, font * 1.2, cv::Scalar(255, 255, 255), thick, cv::LINE_AA);
  }
  return out;
}

}  // namespace occmap
