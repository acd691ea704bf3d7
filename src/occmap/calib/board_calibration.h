// A camera's intrinsics from pictures of a calibration board: a checkerboard
// (cv::findChessboardCorners + cv::cornerSubPix) or a ChArUco board (OpenCV's aruco module,
// Debian's libopencv-contrib-dev, which libopencv-dev pulls in), then cv::calibrateCamera.
// Each view is checked before it is used and rejected with a reason: the board not found,
// blurred (the edges' blur, estimated as a Gaussian's sigma from contrast / steepest gradient),
// too small in the image, seen nearly edge-on, too few ChArUco corners. The result gives the
// reprojection RMS over every used corner and per view. No file I/O: images come in as views.
//
//   BoardOptions board;  board.cols = 9;  board.rows = 6;  board.square_m = 0.025;
//   IntrinsicsOptions o;  o.board = board;
//   std::vector<BoardImage> views = {{"a.png", a.view()}, {"b.png", b.view()}, ...};
//   OCCMAP_ASSIGN_OR_RETURN(IntrinsicsCalibration cal, CalibrateIntrinsics(views, o));
//   // cal.intrinsics, cal.rms_px, cal.views[i].reason ("" when used)
#pragma once

#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

#include "occmap/calib/floor_calibration.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

enum class BoardKind { kCheckerboard, kCharuco };

struct BoardOptions {
  BoardKind kind = BoardKind::kCheckerboard;
  // Checkerboard: inner corners across and down (a board of 10 x 7 squares has 9 x 6).
  // ChArUco: squares across and down.
  int cols = 9;
  int rows = 6;
  double square_m = 0.025;   // side of a square
  double marker_m = 0.0;     // ChArUco: side of a marker (< square_m)
  std::string dictionary = "4x4_50";  // ChArUco: 4x4_50, 4x4_100, 4x4_250, 5x5_..., 6x6_..., 7x7_...

  Status Validate() const;
  // Corners of a complete view: cols x rows (checkerboard) or (cols - 1) x (rows - 1) (ChArUco).
  int CornerCount() const;
};

struct IntrinsicsOptions {
  BoardOptions board;
  double max_blur_px = 2.0;          // views whose edges are blurrier (Gaussian sigma) are rejected
  double min_board_fraction = 0.01;  // the corners' outline must cover this share of the image
  double max_tilt_deg = 75.0;        // boards seen more nearly edge-on are rejected
  int min_charuco_corners = 8;       // ChArUco: fewer visible corners reject the view
  int min_views = 3;                 // usable views needed
  bool estimate_k3 = false;          // k3 only for wide-angle lenses; it overfits otherwise

  Status Validate() const;
};

struct BoardImage {
  std::string name;  // for messages (the file, or "frame 120")
  ImageView<const uint8_t> gray;
};

struct BoardView {
  std::string name;
  bool used = false;
  std::string reason;  // why it was rejected ("" when used)
  int corners = 0;     // corners found
  double blur_px = 0;  // estimated edge blur (sigma), where the board was found
  double board_fraction = 0;  // share of the image inside the corners' outline
  double tilt_deg = 0;        // board plane against the image plane (from the corners' shape;
                              //   from the calibrated pose for used views)
  double rms_px = 0;          // used views: reprojection RMS of its corners
  std::vector<Eigen::Vector2d> corners_px;
};

struct IntrinsicsCalibration {
  CameraIntrinsics intrinsics;
  double rms_px = 0;  // over every corner of every used view (cv::calibrateCamera's figure)
  int views_used = 0;
  std::vector<BoardView> views;  // one per input image, in order
  std::vector<std::string> warnings;
};

Result<IntrinsicsCalibration> CalibrateIntrinsics(std::span<const BoardImage> images, const IntrinsicsOptions& options);

// Detection and checks of one view alone (what CalibrateIntrinsics does before calibrating).
BoardView InspectBoardView(const BoardImage& image, const IntrinsicsOptions& options,
                           std::vector<Eigen::Vector3d>* object_points_m = nullptr);

// The board as an image to print: px_per_square pixels a square, a white margin around.
Result<Image<uint8_t>> DrawBoard(const BoardOptions& board, int px_per_square, int margin_px);

// Edge blur of a grey image inside a mask (non-zero), as a Gaussian's sigma in pixels:
// contrast / (sqrt(2 pi) * steepest gradient). About 0.8 for a sharp step edge.
double EstimateEdgeBlurPx(ImageView<const uint8_t> gray, ImageView<const uint8_t> mask);

}  // namespace occmap
