#include "occmap/lut/visibility_image.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace occmap {

Rgb8 VisibilityColor(int count, int num_cameras) {
  if (count <= 0) return {48, 48, 48};
  // Hue from 0 (red, one camera) to 220 degrees (blue, every camera).
  const double t = num_cameras <= 1 ? 1.0 : static_cast<double>(count - 1) / (num_cameras - 1);
  const double hue = 220.0 * t;
  const double c = 0.85, x = c * (1 - std::abs(std::fmod(hue / 60.0, 2) - 1)), m = 0.1;
  double r = 0, g = 0, b = 0;
  if (hue < 60) { r = c; g = x; }
  else if (hue < 120) { r = x; g = c; }
  else if (hue < 180) { g = c; b = x; }
  else { g = x; b = c; }
  auto u8 = [&](double v) { return static_cast<uint8_t>(std::lround(255 * (v + m))); };
  return {u8(r), u8(g), u8(b)};
}

Image<Rgb8> RenderVisibility(const GroundLut& lut, const std::vector<CameraMarker>& cameras, int max_side_px) {
  const FloorGrid& g = lut.grid();
  // World extent: the grid plus every camera, with a margin.
  double x0 = g.origin_x_m, y0 = g.origin_y_m, x1 = g.origin_x_m + g.size_x_m(), y1 = g.origin_y_m + g.size_y_m();
  for (const auto& cam : cameras) {
    x0 = std::min(x0, cam.position_m.x());
    x1 = std::max(x1, cam.position_m.x());
    y0 = std::min(y0, cam.position_m.y());
    y1 = std::max(y1, cam.position_m.y());
  }
  const double margin = 0.05 * std::max(x1 - x0, y1 - y0);
  x0 -= margin; y0 -= margin; x1 += margin; y1 += margin;
  const int legend_px = 40;
  const double px_per_m = max_side_px / std::max(x1 - x0, y1 - y0);
  const int map_width = std::max(1, static_cast<int>(std::lround((x1 - x0) * px_per_m)));
  // Wide enough for the legend too; a narrow map is centred.
  const int width = std::max(map_width, 50 * (lut.num_cameras() + 1) + 240);
  const int left_px = (width - map_width) / 2;
  const int height = std::max(1, static_cast<int>(std::lround((y1 - y0) * px_per_m)));
  cv::Mat canvas(height + legend_px, width, CV_8UC3, cv::Scalar(255, 255, 255));
  auto to_px = [&](double x, double y) {
    return cv::Point(left_px + static_cast<int>(std::lround((x - x0) * px_per_m)),
                     static_cast<int>(std::lround((y1 - y) * px_per_m)));
  };
  const int n = lut.num_cameras();
  const auto counts = lut.view_count();
  // Each canvas pixel inside the grid takes the colour of the cell under its centre.
  for (int py = 0; py < height; ++py) {
    auto* row = canvas.ptr<cv::Vec3b>(py);
    const double y = y1 - (py + 0.5) / px_per_m;
    for (int px = left_px; px < left_px + map_width; ++px) {
      const double x = x0 + (px - left_px + 0.5) / px_per_m;
      const int64_t cell = g.CellAt(x, y);
      if (cell < 0) continue;
      const Rgb8 c = VisibilityColor(counts[cell], n);
      row[px] = cv::Vec3b(c.b, c.g, c.r);
    }
  }
  cv::rectangle(canvas, to_px(g.origin_x_m, g.origin_y_m + g.size_y_m()), to_px(g.origin_x_m + g.size_x_m(), g.origin_y_m),
                cv::Scalar(0, 0, 0), 1);
  const int radius = std::max(4, max_side_px / 120);
  for (const auto& cam : cameras) {
    const cv::Point p = to_px(cam.position_m.x(), cam.position_m.y());
    cv::circle(canvas, p, radius, cv::Scalar(200, 200, 200), cv::FILLED, cv::LINE_AA);
    cv::circle(canvas, p, radius, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    cv::putText(canvas, cam.label, p + cv::Point(radius + 2, -radius), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  // Legend: one swatch per count.
  int lx = 8;
  const int ly = height + 10;
  for (int k = 0; k <= n; ++k) {
    const Rgb8 c = VisibilityColor(k, n);
    cv::rectangle(canvas, cv::Rect(lx, ly, 18, 18), cv::Scalar(c.b, c.g, c.r), cv::FILLED);
    cv::putText(canvas, std::to_string(k), cv::Point(lx + 22, ly + 14), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    lx += 50;
  }
  cv::putText(canvas, "cameras viewing each cell", cv::Point(lx + 6, ly + 14), cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  Image<Rgb8> out(canvas.cols, canvas.rows);
  for (int y = 0; y < canvas.rows; ++y) {
    const auto* src = canvas.ptr<cv::Vec3b>(y);
    for (int x = 0; x < canvas.cols; ++x) out(x, y) = {src[x][2], src[x][1], src[x][0]};
  }
  return out;
}

}  // namespace occmap
