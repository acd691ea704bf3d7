#include "occmap/calib/board_calibration.h"

#include <fmt/core.h>

#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "occmap/geometry/rotation.h"

namespace occmap {
namespace {

struct DictionaryName {
  const char* name;
  cv::aruco::PREDEFINED_DICTIONARY_NAME id;
};
constexpr DictionaryName kDictionaries[] = {
    {"4x4_50", cv::aruco::DICT_4X4_50},     {"4x4_100", cv::aruco::DICT_4X4_100},
    {"4x4_250", cv::aruco::DICT_4X4_250},   {"4x4_1000", cv::aruco::DICT_4X4_1000},
    {"5x5_50", cv::aruco::DICT_5X5_50},     {"5x5_100", cv::aruco::DICT_5X5_100},
    {"5x5_250", cv::aruco::DICT_5X5_250},   {"5x5_1000", cv::aruco::DICT_5X5_1000},
    {"6x6_50", cv::aruco::DICT_6X6_50},     {"6x6_100", cv::aruco::DICT_6X6_100},
    {"6x6_250", cv::aruco::DICT_6X6_250},   {"6x6_1000", cv::aruco::DICT_6X6_1000},
    {"7x7_50", cv::aruco::DICT_7X7_50},     {"7x7_100", cv::aruco::DICT_7X7_100},
    {"7x7_250", cv::aruco::DICT_7X7_250},   {"7x7_1000", cv::aruco::DICT_7X7_1000},
};

const DictionaryName* FindDictionary(std::string_view name) {
  for (const auto& d : kDictionaries) {
    if (name == d.name) return &d;
  }
  return nullptr;
}

cv::Ptr<cv::aruco::CharucoBoard> MakeCharuco(const BoardOptions& b) {
  auto dict = cv::aruco::getPredefinedDictionary(FindDictionary(b.dictionary)->id);
  return cv::aruco::CharucoBoard::create(b.cols, b.rows, static_cast<float>(b.square_m),
                                         static_cast<float>(b.marker_m), dict);
}

cv::Mat AsMat(ImageView<const uint8_t> v) {
  return cv::Mat(v.height(), v.width(), CV_8UC1, const_cast<uint8_t*>(v.data()),
                 static_cast<size_t>(v.stride_elems()));
}

// Percentile of the values (q in 0..1), by partial sort.
double Percentile(std::vector<float>& v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<ptrdiff_t>(k), v.end());
  return v[k];
}

// Tilt of the board from its corners' shape alone: the least-squares affine map board -> image;
// its singular values' ratio is cos(tilt) under an affine camera with square pixels.
double AffineTiltDeg(const std::vector<Eigen::Vector3d>& obj, const std::vector<Eigen::Vector2d>& img) {
  const size_t n = obj.size();
  Eigen::Vector2d mo = Eigen::Vector2d::Zero(), mi = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mo += obj[i].head<2>();
    mi += img[i];
  }
  mo /= static_cast<double>(n);
  mi /= static_cast<double>(n);
  Eigen::Matrix2d soo = Eigen::Matrix2d::Zero(), sio = Eigen::Matrix2d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d o = obj[i].head<2>() - mo, m = img[i] - mi;
    soo += o * o.transpose();
    sio += m * o.transpose();
  }
  const Eigen::Matrix2d a = sio * soo.inverse();
  Eigen::JacobiSVD<Eigen::Matrix2d> svd(a);
  const Eigen::Vector2d s = svd.singularValues();
  if (!(s(0) > 0)) return 90;
  return std::acos(std::clamp(s(1) / s(0), 0.0, 1.0)) * 180 / std::numbers::pi;
}

}  // namespace

Status BoardOptions::Validate() const {
  if (cols < 3 || rows < 3 || cols > 100 || rows > 100) {
    return InvalidInput(fmt::format("board size: expected 3..100 {} across and down, found {}x{}",
                                    kind == BoardKind::kCheckerboard ? "inner corners" : "squares", cols, rows));
  }
  if (!(square_m > 0) || !std::isfinite(square_m)) {
    return InvalidInput(fmt::format("board square: expected a positive length in metres, found {}", square_m));
  }
  if (kind == BoardKind::kCharuco) {
    if (!(marker_m > 0) || !(marker_m < square_m)) {
      return InvalidInput(fmt::format("ChArUco marker: expected 0 < marker < square ({} m), found {} m", square_m,
                                      marker_m));
    }
    const DictionaryName* d = FindDictionary(dictionary);
    if (d == nullptr) {
      std::string names;
      for (const auto& e : kDictionaries) names += (names.empty() ? "" : ", ") + std::string(e.name);
      return InvalidInput(fmt::format("ChArUco dictionary: expected one of {}, found '{}'", names, dictionary));
    }
    // A board needs one marker per white square; the dictionary must hold that many.
    const int markers = cols * rows / 2;
    const int size = std::stoi(std::string(d->name).substr(4));
    if (markers > size) {
      return InvalidInput(fmt::format("ChArUco: a {}x{} board needs {} markers, dictionary {} has {}", cols, rows,
                                      markers, dictionary, size));
    }
  }
  return Status::Ok();
}

int BoardOptions::CornerCount() const {
  return kind == BoardKind::kCheckerboard ? cols * rows : (cols - 1) * (rows - 1);
}

Status IntrinsicsOptions::Validate() const {
  OCCMAP_RETURN_IF_ERROR(board.Validate());
  if (!(max_blur_px > 0)) return InvalidInput(fmt::format("max blur: expected > 0 px, found {}", max_blur_px));
  if (!(min_board_fraction >= 0 && min_board_fraction < 1)) {
    return InvalidInput(fmt::format("min board fraction: expected 0..1, found {}", min_board_fraction));
  }
  if (!(max_tilt_deg > 0 && max_tilt_deg <= 90)) {
    return InvalidInput(fmt::format("max tilt: expected 0..90 degrees, found {}", max_tilt_deg));
  }
  if (min_charuco_corners < 6) {
    return InvalidInput(fmt::format("min ChArUco corners: expected >= 6, found {}", min_charuco_corners));
  }
  if (min_views < 1) return InvalidInput(fmt::format("min views: expected >= 1, found {}", min_views));
  return Status::Ok();
}

double EstimateEdgeBlurPx(ImageView<const uint8_t> gray, ImageView<const uint8_t> mask) {
  const cv::Mat g = AsMat(gray);
  cv::Mat gx, gy;
  cv::Sobel(g, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(g, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  std::vector<float> grad, level;
  for (int y = 1; y + 1 < gray.height(); ++y) {
    for (int x = 1; x + 1 < gray.width(); ++x) {
      if (!mask.empty() && mask(x, y) == 0) continue;
      const float a = gx.at<float>(y, x), b = gy.at<float>(y, x);
      grad.push_back(std::sqrt(a * a + b * b));
      level.push_back(gray(x, y));
    }
  }
  if (grad.size() < 16) return 0;
  const double contrast = Percentile(level, 0.95) - Percentile(level, 0.05);
  const double steepest = Percentile(grad, 0.99);
  if (contrast < 8 || !(steepest > 0)) return 0;  // flat: no edges to judge
  return contrast / (std::sqrt(2 * std::numbers::pi) * steepest);
}

BoardView InspectBoardView(const BoardImage& image, const IntrinsicsOptions& o,
                           std::vector<Eigen::Vector3d>* object_points_m) {
  BoardView view;
  view.name = image.name;
  const cv::Mat g = AsMat(image.gray);
  std::vector<cv::Point2f> corners;
  std::vector<Eigen::Vector3d> obj;
  try {
    if (o.board.kind == BoardKind::kCheckerboard) {
      const cv::Size pattern(o.board.cols, o.board.rows);
      const bool found = cv::findChessboardCorners(
          g, pattern, corners, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
      if (!found) {
        view.reason = fmt::format("no {}x{} checkerboard found", o.board.cols, o.board.rows);
        view.blur_px = EstimateEdgeBlurPx(image.gray, {});
        if (view.blur_px > o.max_blur_px) view.reason += fmt::format(" (image blurred: {:.1f} px)", view.blur_px);
        return view;
      }
      // Refinement window: under half the corners' spacing, so it never reaches the next one.
      double spacing = 1e9;
      for (int r = 0; r < o.board.rows; ++r) {
        for (int c = 0; c + 1 < o.board.cols; ++c) {
          const cv::Point2f d = corners[r * o.board.cols + c + 1] - corners[r * o.board.cols + c];
          spacing = std::min(spacing, static_cast<double>(std::hypot(d.x, d.y)));
        }
      }
      const int win = std::clamp(static_cast<int>(spacing * 0.4), 2, 11);
      cv::cornerSubPix(g, corners, cv::Size(win, win), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
      for (int r = 0; r < o.board.rows; ++r) {
        for (int c = 0; c < o.board.cols; ++c) obj.emplace_back(c * o.board.square_m, r * o.board.square_m, 0.0);
      }
    } else {
      const auto board = MakeCharuco(o.board);
      std::vector<std::vector<cv::Point2f>> marker_corners;
      std::vector<int> marker_ids;
      cv::aruco::detectMarkers(g, board->dictionary, marker_corners, marker_ids);
      std::vector<int> ids;
      if (!marker_ids.empty()) {
        cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, g, board, corners, ids);
      }
      if (static_cast<int>(corners.size()) < o.min_charuco_corners) {
        view.corners = static_cast<int>(corners.size());
        view.reason = fmt::format("too few ChArUco corners: {} ({} markers), at least {} needed", corners.size(),
                                  marker_ids.size(), o.min_charuco_corners);
        return view;
      }
      for (int id : ids) {
        const cv::Point3f p = board->chessboardCorners[id];
        obj.emplace_back(p.x, p.y, p.z);
      }
    }
  } catch (const cv::Exception& e) {
    view.reason = fmt::format("OpenCV failed: {}", e.err);
    return view;
  }
  view.corners = static_cast<int>(corners.size());
  for (const auto& c : corners) view.corners_px.emplace_back(c.x, c.y);

  // The corners' outline: its area, and the mask the blur is measured in.
  std::vector<cv::Point2f> hull;
  cv::convexHull(corners, hull);
  const double area = cv::contourArea(hull);
  view.board_fraction = area / (static_cast<double>(image.gray.width()) * image.gray.height());
  Image<uint8_t> mask(image.gray.width(), image.gray.height(), 0);
  {
    cv::Mat m(mask.height(), mask.width(), CV_8UC1, mask.view().data(), static_cast<size_t>(mask.stride_elems()));
    std::vector<cv::Point> poly;
    for (const auto& p : hull) poly.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::fillConvexPoly(m, poly, cv::Scalar(255));
  }
  view.blur_px = EstimateEdgeBlurPx(image.gray, mask.view());
  view.tilt_deg = AffineTiltDeg(obj, view.corners_px);
  if (view.blur_px > o.max_blur_px) {
    view.reason = fmt::format("blurred: edges {:.1f} px wide (Gaussian sigma), at most {:.1f} allowed", view.blur_px,
                              o.max_blur_px);
  } else if (view.board_fraction < o.min_board_fraction) {
    view.reason = fmt::format("too small: the board covers {:.2f}% of the image, at least {:.2f}% needed",
                              100 * view.board_fraction, 100 * o.min_board_fraction);
  } else if (view.tilt_deg > o.max_tilt_deg) {
    view.reason = fmt::format("seen nearly edge-on: tilted about {:.0f} degrees, at most {:.0f} allowed",
                              view.tilt_deg, o.max_tilt_deg);
  }
  if (object_points_m) *object_points_m = std::move(obj);
  return view;
}

Result<IntrinsicsCalibration> CalibrateIntrinsics(std::span<const BoardImage> images, const IntrinsicsOptions& o) {
  OCCMAP_RETURN_IF_ERROR(o.Validate());
  if (images.empty()) return InvalidInput("board views: expected at least one image, found none");
  const int width = images[0].gray.width(), height = images[0].gray.height();
  for (const BoardImage& im : images) {
    if (im.gray.width() != width || im.gray.height() != height) {
      return InvalidInput(fmt::format("{}: {}x{}, expected {}x{} as {}", im.name, im.gray.width(), im.gray.height(),
                                      width, height, images[0].name));
    }
  }
  IntrinsicsCalibration cal;
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  std::vector<size_t> used;
  for (size_t i = 0; i < images.size(); ++i) {
    std::vector<Eigen::Vector3d> obj;
    BoardView v = InspectBoardView(images[i], o, &obj);
    if (v.reason.empty()) {
      v.used = true;
      std::vector<cv::Point3f> op;
      std::vector<cv::Point2f> ip;
      for (size_t k = 0; k < obj.size(); ++k) {
        op.emplace_back(static_cast<float>(obj[k].x()), static_cast<float>(obj[k].y()), 0.f);
        ip.emplace_back(static_cast<float>(v.corners_px[k].x()), static_cast<float>(v.corners_px[k].y()));
      }
      object_points.push_back(std::move(op));
      image_points.push_back(std::move(ip));
      used.push_back(i);
    }
    cal.views.push_back(std::move(v));
  }
  cal.views_used = static_cast<int>(used.size());
  if (cal.views_used < o.min_views) {
    std::string why;
    for (const BoardView& v : cal.views) {
      if (!v.used) why += fmt::format("\n  {}: {}", v.name, v.reason);
    }
    return InvalidInput(fmt::format("board views: {} of {} usable, at least {} needed{}", cal.views_used,
                                    images.size(), o.min_views, why));
  }
  cv::Mat k, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  int flags = o.estimate_k3 ? 0 : cv::CALIB_FIX_K3;
  try {
    cal.rms_px = cv::calibrateCamera(object_points, image_points, cv::Size(width, height), k, dist, rvecs, tvecs,
                                     flags);
  } catch (const cv::Exception& e) {
    return InvalidInput(fmt::format("board views: cv::calibrateCamera failed: {}", e.err));
  }
  CameraIntrinsics& in = cal.intrinsics;
  in.image_size = {width, height};
  in.fx_px = k.at<double>(0, 0);
  in.fy_px = k.at<double>(1, 1);
  in.cx_px = k.at<double>(0, 2);
  in.cy_px = k.at<double>(1, 2);
  in.skew_px = 0;
  for (int i = 0; i < 5 && i < static_cast<int>(dist.total()); ++i) in.distortion[i] = dist.at<double>(i);
  OCCMAP_RETURN_IF_ERROR(in.Validate().WithContext("board views: the calibration found"));
  double max_tilt = 0;
  for (size_t u = 0; u < used.size(); ++u) {
    BoardView& v = cal.views[used[u]];
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object_points[u], rvecs[u], tvecs[u], k, dist, projected);
    double sum = 0;
    for (size_t j = 0; j < projected.size(); ++j) {
      const cv::Point2f d = projected[j] - image_points[u][j];
      sum += d.x * d.x + d.y * d.y;
    }
    v.rms_px = std::sqrt(sum / static_cast<double>(std::max<size_t>(projected.size(), 1)));
    const Eigen::Matrix3d r = RotationFromRodrigues(
        {rvecs[u].at<double>(0), rvecs[u].at<double>(1), rvecs[u].at<double>(2)});
    v.tilt_deg = std::acos(std::clamp(std::abs(r(2, 2)), 0.0, 1.0)) * 180 / std::numbers::pi;
    max_tilt = std::max(max_tilt, v.tilt_deg);
  }
  // Distortion is only measured where corners were seen: which of 8 x 8 image tiles hold any.
  std::vector<bool> tiles(64, false);
  for (size_t u = 0; u < used.size(); ++u) {
    for (const auto& c : image_points[u]) {
      const int tx = std::clamp(static_cast<int>(c.x * 8.0 / width), 0, 7);
      const int ty = std::clamp(static_cast<int>(c.y * 8.0 / height), 0, 7);
      tiles[static_cast<size_t>(ty * 8 + tx)] = true;
    }
  }
  const int covered = static_cast<int>(std::count(tiles.begin(), tiles.end(), true));
  if (covered < 32) {
    cal.warnings.push_back(fmt::format(
        "the board's corners reach only {} of the image's 8 x 8 tiles: the lens distortion is poorly determined "
        "where they did not go; add views with the board near the image's edges and corners",
        covered));
  }
  if (max_tilt < 20) {
    cal.warnings.push_back(fmt::format(
        "every view faces the camera (largest tilt {:.0f} degrees): the focal length is poorly determined; add views "
        "with the board tilted by 30-45 degrees",
        max_tilt));
  }
  return cal;
}

Result<Image<uint8_t>> DrawBoard(const BoardOptions& b, int px_per_square, int margin_px) {
  OCCMAP_RETURN_IF_ERROR(b.Validate());
  if (px_per_square < 4 || margin_px < 0) {
    return InvalidInput(fmt::format("board picture: expected >= 4 px a square and a margin >= 0, found {} and {}",
                                    px_per_square, margin_px));
  }
  const int squares_x = b.kind == BoardKind::kCheckerboard ? b.cols + 1 : b.cols;
  const int squares_y = b.kind == BoardKind::kCheckerboard ? b.rows + 1 : b.rows;
  const int w = squares_x * px_per_square + 2 * margin_px, h = squares_y * px_per_square + 2 * margin_px;
  Image<uint8_t> out(w, h, 255);
  cv::Mat m(h, w, CV_8UC1, out.view().data(), static_cast<size_t>(out.stride_elems()));
  if (b.kind == BoardKind::kCheckerboard) {
    for (int j = 0; j < squares_y; ++j) {
      for (int i = 0; i < squares_x; ++i) {
        if ((i + j) % 2 == 0) {
          m(cv::Rect(margin_px + i * px_per_square, margin_px + j * px_per_square, px_per_square, px_per_square)) = 0;
        }
      }
    }
  } else {
    cv::Mat drawn;
    MakeCharuco(b)->draw(cv::Size(w, h), drawn, margin_px, 1);
    drawn.copyTo(m);
  }
  return out;
}

}  // namespace occmap
