#include "occmap/pipeline/mosaic.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace occmap {

namespace {

// A stable, distinct colour per track id (BGR).
cv::Scalar TrackColor(int64_t id) {
  static const cv::Scalar kPalette[] = {{255, 128, 0}, {0, 200, 0},   {255, 0, 255}, {0, 165, 255},
                                        {255, 255, 0}, {128, 0, 255}, {0, 128, 128}, {200, 100, 100}};
  return kPalette[static_cast<size_t>(id) % (sizeof(kPalette) / sizeof(kPalette[0]))];
}

}  // namespace

MosaicRenderer::MosaicRenderer(const Site& site, int width_px) : grid_(site.grid), zones_(site.tracking.zones) {
  const int n = static_cast<int>(site.cameras.size());
  cols_ = std::max(1, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n)))));
  const int rows = (n + cols_ - 1) / cols_;
  width_ = std::max(320, width_px) / 2 * 2;
  left_w_ = width_ * 55 / 100;
  tile_w_ = left_w_ / cols_;
  const ImageSize first = site.cameras.empty() ? ImageSize{4, 3} : site.cameras[0].camera->image_size();
  tile_h_ = std::max(1, tile_w_ * first.height / first.width);
  height_ = std::max(rows * tile_h_, 240);
  height_ = (height_ + 1) / 2 * 2;

  // The map panel: the grid plus every camera, with a margin, fitted into the right part.
  double x0 = grid_.origin_x_m, y0 = grid_.origin_y_m;
  double x1 = x0 + grid_.size_x_m(), y1 = y0 + grid_.size_y_m();
  for (const auto& c : site.cameras) {
    if (auto p = c.camera->CenterInWorld()) {
      markers_.push_back({c.id, p->x(), p->y()});
      x0 = std::min(x0, p->x());
      x1 = std::max(x1, p->x());
      y0 = std::min(y0, p->y());
      y1 = std::max(y1, p->y());
    }
  }
  const double margin = 0.04 * std::max(x1 - x0, y1 - y0);
  x0 -= margin;
  y0 -= margin;
  x1 += margin;
  y1 += margin;
  const int panel_w = width_ - left_w_ - 8, panel_h = height_ - 30;
  px_per_m_ = std::min(panel_w / (x1 - x0), panel_h / (y1 - y0));
  x0_ = x0;
  y1_ = y1;
  panel_x_ = left_w_ + 4 + static_cast<int>((panel_w - (x1 - x0) * px_per_m_) / 2);
  panel_y_ = 24 + static_cast<int>((panel_h - (y1 - y0) * px_per_m_) / 2);
}

Image<Rgb8> MosaicRenderer::Render(const std::vector<MosaicCamera>& cameras, const OccupancyMap& map,
                                   const std::vector<Detection>& blobs, int64_t frame, double time_s,
                                   const std::vector<Track>& tracks, const std::vector<Trail>& trails) const {
  Image<Rgb8> out;
  Render(cameras, map, blobs, frame, time_s, tracks, trails, out);
  return out;
}

void MosaicRenderer::Render(const std::vector<MosaicCamera>& cameras, const OccupancyMap& map,
                            const std::vector<Detection>& blobs, int64_t frame, double time_s,
                            const std::vector<Track>& tracks, const std::vector<Trail>& trails, Image<Rgb8>& out) const {
  canvas_.resize(static_cast<size_t>(width_) * static_cast<size_t>(height_) * 3);
  tile_gray_.resize(static_cast<size_t>(tile_w_) * static_cast<size_t>(tile_h_));
  tile_changes_.resize(tile_gray_.size());
  cv::Mat canvas(height_, width_, CV_8UC3, canvas_.data());
  canvas.setTo(cv::Scalar(40, 40, 40));
  // Camera tiles.
  for (size_t i = 0; i < cameras.size(); ++i) {
    const MosaicCamera& cam = cameras[i];
    const cv::Rect tile(static_cast<int>(i % cols_) * tile_w_, static_cast<int>(i / cols_) * tile_h_, tile_w_, tile_h_);
    cv::Mat roi = canvas(tile);
    if (cam.active && !cam.gray.empty()) {
      const cv::Mat gray(cam.gray.height(), cam.gray.width(), CV_8UC1, const_cast<uint8_t*>(cam.gray.data()),
                         static_cast<size_t>(cam.gray.stride_elems()));
      cv::Mat small_gray(tile_h_, tile_w_, CV_8UC1, tile_gray_.data());
      cv::resize(gray, small_gray, tile.size(), 0, 0, cv::INTER_AREA);
      cv::cvtColor(small_gray, roi, cv::COLOR_GRAY2BGR);
      if (!cam.changes.empty()) {
        const cv::Mat changes(cam.changes.height(), cam.changes.width(), CV_8UC1,
                              const_cast<uint8_t*>(cam.changes.data()), static_cast<size_t>(cam.changes.stride_elems()));
        cv::Mat small_changes(tile_h_, tile_w_, CV_8UC1, tile_changes_.data());
        cv::resize(changes, small_changes, tile.size(), 0, 0, cv::INTER_NEAREST);
        for (int y = 0; y < roi.rows; ++y) {
          auto* px = roi.ptr<cv::Vec3b>(y);
          const uint8_t* ch = small_changes.ptr<uint8_t>(y);
          for (int x = 0; x < roi.cols; ++x) {
            if (ch[x] != 0) px[x] = cv::Vec3b(px[x][0] / 2, px[x][1] / 2, static_cast<uint8_t>(128 + px[x][2] / 2));
          }
        }
      }
    } else {
      roi.setTo(cv::Scalar(20, 20, 20));
      cv::putText(roi, "no frame", cv::Point(10, tile_h_ / 2), cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(180, 180, 180),
                  1, cv::LINE_AA);
    }
    cv::rectangle(canvas, tile, cv::Scalar(0, 0, 0), 1);
    cv::putText(canvas, cam.id, tile.tl() + cv::Point(6, 18), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 255, 255), 1,
                cv::LINE_AA);
  }
  // Map panel: one colour per cell state, drawn cell by cell into the panel's pixels.
  auto to_px = [&](double x, double y) {
    return cv::Point(panel_x_ + static_cast<int>(std::lround((x - x0_) * px_per_m_)),
                     panel_y_ + static_cast<int>(std::lround((y1_ - y) * px_per_m_)));
  };
  const cv::Point g0 = to_px(grid_.origin_x_m, grid_.origin_y_m + grid_.size_y_m());
  const cv::Point g1 = to_px(grid_.origin_x_m + grid_.size_x_m(), grid_.origin_y_m);
  for (int py = std::max(0, g0.y); py < std::min(height_, g1.y); ++py) {
    auto* row = canvas.ptr<cv::Vec3b>(py);
    const double y = y1_ - (py - panel_y_ + 0.5) / px_per_m_;
    for (int px = std::max(left_w_, g0.x); px < std::min(width_, g1.x); ++px) {
      const double x = x0_ + (px - panel_x_ + 0.5) / px_per_m_;
      const int64_t cell = grid_.CellAt(x, y);
      if (cell < 0) continue;
      switch (map.state(cell)) {
        case CellState::kFree: row[px] = cv::Vec3b(255, 255, 255); break;
        case CellState::kOccupied: row[px] = cv::Vec3b(0, 0, 0); break;
        case CellState::kUnseen: row[px] = cv::Vec3b(128, 128, 128); break;
      }
    }
  }
  cv::rectangle(canvas, g0, g1, cv::Scalar(90, 90, 90), 1);
  for (const auto& m : markers_) {
    const cv::Point p = to_px(m.x_m, m.y_m);
    cv::circle(canvas, p, 6, cv::Scalar(190, 190, 190), cv::FILLED, cv::LINE_AA);
    cv::putText(canvas, m.label, p + cv::Point(8, -6), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(220, 220, 220), 1,
                cv::LINE_AA);
  }
  for (const auto& b : blobs) {
    const cv::Point p = to_px(b.x_m, b.y_m);
    const int r = std::max(5, static_cast<int>(std::lround(std::sqrt(b.area_m2 / M_PI) * px_per_m_)) + 3);
    cv::circle(canvas, p, r, cv::Scalar(0, 0, 255), 2, cv::LINE_AA);
  }
  for (const auto& zone : zones_) {
    std::vector<cv::Point> pts;
    for (const auto& p : zone.polygon_m) pts.push_back(to_px(p.x(), p.y()));
    cv::polylines(canvas, pts, true, cv::Scalar(0, 200, 255), 1, cv::LINE_AA);
    if (!pts.empty()) {
      cv::putText(canvas, zone.name, pts[0] + cv::Point(3, -3), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 200, 255), 1,
                  cv::LINE_AA);
    }
  }
  for (const auto& trail : trails) {
    std::vector<cv::Point> pts;
    for (const auto& p : trail.points_m) pts.push_back(to_px(p.x(), p.y()));
    if (pts.size() >= 2) cv::polylines(canvas, pts, false, TrackColor(trail.id), 2, cv::LINE_AA);
  }
  for (const auto& t : tracks) {
    const cv::Point p = to_px(t.x_m, t.y_m);
    cv::circle(canvas, p, 3, TrackColor(t.id), cv::FILLED, cv::LINE_AA);
    cv::putText(canvas, std::to_string(t.id), p + cv::Point(6, 12), cv::FONT_HERSHEY_SIMPLEX, 0.45, TrackColor(t.id), 1,
                cv::LINE_AA);
  }
  cv::putText(canvas,
              tracks.empty() ? fmt::format("frame {}  t = {:.2f} s  blobs {}", frame, time_s, blobs.size())
                             : fmt::format("frame {}  t = {:.2f} s  blobs {}  tracks {}", frame, time_s, blobs.size(),
                                           tracks.size()),
              cv::Point(left_w_ + 8, 17), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  if (out.width() != width_ || out.height() != height_) out = Image<Rgb8>(width_, height_);
  for (int y = 0; y < height_; ++y) {
    const auto* src = canvas.ptr<cv::Vec3b>(y);
    Rgb8* dst = out.row(y);
    for (int x = 0; x < width_; ++x) dst[x] = {src[x][2], src[x][1], src[x][0]};
  }
}

}  // namespace occmap
