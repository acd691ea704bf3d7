#include "occmap/calib/board_calibration.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "occmap/geometry/rotation.h"

namespace occmap {
namespace {

constexpr int kPxPerSquare = 80;
constexpr int kMargin = 40;

// The true camera: 1280x720, no distortion (warpPerspective cannot bend lines).
struct TrueK {
  double f = 820, cx = 645.5, cy = 355.0;
  int width = 1280, height = 720;
};

// Renders the board picture through the pose (rotation about x, then y, then z, in degrees;
// the board's first inner corner `distance_m` ahead of the camera, shifted by offset_m), 2x
// supersampled, on a mid-grey background, with a little noise.
Image<uint8_t> RenderView(const Image<uint8_t>& board, const BoardOptions& b, double rx_deg, double ry_deg,
                          double rz_deg, double distance_m, Eigen::Vector2d offset_m, uint64_t seed) {
  const TrueK k;
  constexpr double kSs = 2;
  const double deg = std::numbers::pi / 180;
  const Eigen::Matrix3d r = TsaiRotation(rx_deg * deg, ry_deg * deg, rz_deg * deg);
  // The board's centre (metres on the board) sits at (offset, distance) in the camera frame.
  const int squares_x = b.kind == BoardKind::kCheckerboard ? b.cols + 1 : b.cols;
  const int squares_y = b.kind == BoardKind::kCheckerboard ? b.rows + 1 : b.rows;
  const double s = b.square_m;
  // Board metres (X, Y) -> board picture pixel: the picture's square edges lie on pixel edges.
  // Checkerboard: metres from its first inner corner; ChArUco: from its outer corner.
  const double first = b.kind == BoardKind::kCheckerboard ? kPxPerSquare : 0;
  Eigen::Matrix3d picture_from_board;
  picture_from_board << kPxPerSquare / s, 0, kMargin - 0.5 + first, 0, kPxPerSquare / s, kMargin - 0.5 + first, 0,
      0, 1;
  const Eigen::Vector3d centre_on_board(
      (b.kind == BoardKind::kCheckerboard ? (squares_x - 2) : squares_x) * s / 2,
      (b.kind == BoardKind::kCheckerboard ? (squares_y - 2) : squares_y) * s / 2, 0);
  const Eigen::Vector3d t = Eigen::Vector3d(offset_m.x(), offset_m.y(), distance_m) - r * centre_on_board;
  Eigen::Matrix3d kss;
  kss << k.f * kSs, 0, (k.cx + 0.5) * kSs - 0.5, 0, k.f * kSs, (k.cy + 0.5) * kSs - 0.5, 0, 0, 1;
  Eigen::Matrix3d rt;
  rt.col(0) = r.col(0);
  rt.col(1) = r.col(1);
  rt.col(2) = t;
  const Eigen::Matrix3d image_from_picture = kss * rt * picture_from_board.inverse();
  cv::Mat h(3, 3, CV_64F);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) h.at<double>(i, j) = image_from_picture(i, j);
  }
  const cv::Mat src(board.height(), board.width(), CV_8UC1, const_cast<uint8_t*>(board.view().data()),
                    static_cast<size_t>(board.stride_elems()));
  cv::Mat big, small;
  cv::warpPerspective(src, big, h, cv::Size(k.width * 2, k.height * 2), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                      cv::Scalar(110));
  cv::resize(big, small, cv::Size(k.width, k.height), 0, 0, cv::INTER_AREA);
  cv::Mat noise(small.size(), CV_16S);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0, 1.5);
  cv::Mat noisy;
  small.convertTo(noisy, CV_16S);
  noisy += noise;
  noisy.convertTo(small, CV_8U);
  Image<uint8_t> out(k.width, k.height);
  for (int y = 0; y < k.height; ++y) std::memcpy(out.row(y), small.ptr<uint8_t>(y), static_cast<size_t>(k.width));
  return out;
}

struct Pose {
  double rx, ry, rz, distance_m, ox, oy;
};
const Pose kGoodPoses[] = {
    {0, 0, 0, 0.75, 0, 0},          {35, 0, 5, 0.8, 0.05, 0},     {-35, 10, -5, 0.8, -0.05, 0.03},
    {10, 35, 0, 0.85, 0.1, -0.05},  {5, -40, 10, 0.85, -0.1, 0.05}, {25, 25, 30, 0.7, 0.12, 0.08},
    {-20, -25, -20, 0.7, -0.12, -0.08}, {15, -10, 90, 0.9, 0.0, 0.0},
};

struct Rendered {
  std::vector<Image<uint8_t>> images;
  std::vector<BoardImage> views;
};

Rendered RenderSet(const BoardOptions& b, bool with_bad_views) {
  const Image<uint8_t> board = DrawBoard(b, kPxPerSquare, kMargin).value();
  Rendered r;
  std::vector<std::string> names;
  uint64_t seed = 1;
  for (const Pose& p : kGoodPoses) {
    r.images.push_back(RenderView(board, b, p.rx, p.ry, p.rz, p.distance_m, {p.ox, p.oy}, seed++));
    names.push_back(fmt::format("pose{}", seed - 1));
  }
  if (with_bad_views) {
    // Blurred: a good pose through a defocused lens.
    Image<uint8_t> blurred = RenderView(board, b, 20, 15, 0, 0.8, {0, 0}, 100);
    cv::Mat m(blurred.height(), blurred.width(), CV_8UC1, blurred.view().data(),
              static_cast<size_t>(blurred.stride_elems()));
    cv::GaussianBlur(m, m, cv::Size(0, 0), 3.5);
    r.images.push_back(std::move(blurred));
    names.push_back("blurred");
    // Degenerate: the board far away, a speck in the corner of the picture.
    r.images.push_back(RenderView(board, b, 10, 10, 0, 2.7, {-0.9, -0.5}, 101));
    names.push_back("far");
  }
  for (size_t i = 0; i < r.images.size(); ++i) r.views.push_back({names[i], r.images[i].view()});
  return r;
}

TEST(BoardCalibration, CheckerboardRecoversTheIntrinsicsAndRejectsBadViewsWithReasons) {
  BoardOptions b;
  b.cols = 9;
  b.rows = 6;
  b.square_m = 0.03;
  const Rendered r = RenderSet(b, /*with_bad_views=*/true);
  IntrinsicsOptions o;
  o.board = b;
  auto result = CalibrateIntrinsics(r.views, o);
  ASSERT_TRUE(result.ok()) << result.status().message();
  const IntrinsicsCalibration& cal = *result;
  const TrueK k;
  ASSERT_EQ(cal.views.size(), std::size(kGoodPoses) + 2);
  for (size_t i = 0; i < std::size(kGoodPoses); ++i) {
    EXPECT_TRUE(cal.views[i].used) << cal.views[i].name << ": " << cal.views[i].reason;
    EXPECT_EQ(cal.views[i].corners, 54);
    EXPECT_LT(cal.views[i].blur_px, 1.5) << cal.views[i].name;
  }
  const BoardView& blurred = cal.views[std::size(kGoodPoses)];
  EXPECT_FALSE(blurred.used);
  EXPECT_EQ(blurred.reason.rfind("blurred: edges ", 0), 0u) << blurred.reason;
  const BoardView& far = cal.views[std::size(kGoodPoses) + 1];
  EXPECT_FALSE(far.used);
  EXPECT_EQ(far.reason.rfind("too small: the board covers 0.", 0), 0u) << far.reason;
  EXPECT_EQ(cal.views_used, static_cast<int>(std::size(kGoodPoses)));
  EXPECT_LT(cal.rms_px, 0.3);
  EXPECT_NEAR(cal.intrinsics.fx_px, k.f, 0.01 * k.f);
  EXPECT_NEAR(cal.intrinsics.fy_px, k.f, 0.01 * k.f);
  EXPECT_NEAR(cal.intrinsics.cx_px, k.cx, 4.0);
  EXPECT_NEAR(cal.intrinsics.cy_px, k.cy, 4.0);
  EXPECT_NEAR(cal.intrinsics.distortion[0], 0.0, 0.03);
  // The poses keep the board near the middle of the picture: the edges' distortion is unmeasured.
  ASSERT_EQ(cal.warnings.size(), 1u);
  EXPECT_EQ(cal.warnings[0].rfind("the board's corners reach only ", 0), 0u) << cal.warnings[0];
  std::printf("checkerboard: %d of %zu views, RMS %.3f px, fx %.2f fy %.2f cx %.2f cy %.2f k1 %.4f; rejected: %s; %s\n",
              cal.views_used, cal.views.size(), cal.rms_px, cal.intrinsics.fx_px, cal.intrinsics.fy_px,
              cal.intrinsics.cx_px, cal.intrinsics.cy_px, cal.intrinsics.distortion[0], blurred.reason.c_str(),
              far.reason.c_str());
}

TEST(BoardCalibration, TooFewUsableViewsIsAnErrorListingTheReasons) {
  BoardOptions b;
  b.square_m = 0.03;
  const Image<uint8_t> board = DrawBoard(b, kPxPerSquare, kMargin).value();
  Image<uint8_t> good = RenderView(board, b, 20, 10, 0, 0.8, {0, 0}, 3);
  Image<uint8_t> grey(1280, 720, 128);
  std::vector<BoardImage> views = {{"a.png", good.view()}, {"b.png", grey.view()}};
  IntrinsicsOptions o;
  o.board = b;
  auto result = CalibrateIntrinsics(views, o);
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(result.status().message(), "board views: 1 of 2 usable, at least 3 needed\n  b.png: no 9x6 checkerboard found");
}

TEST(BoardCalibration, ViewsOfDifferentSizesAreAnError) {
  Image<uint8_t> a(640, 480, 0), b(320, 240, 0);
  std::vector<BoardImage> views = {{"a.png", a.view()}, {"b.png", b.view()}};
  auto result = CalibrateIntrinsics(views, IntrinsicsOptions{});
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.status().message(), "b.png: 320x240, expected 640x480 as a.png");
}

TEST(BoardCalibration, CharucoRecoversTheIntrinsics) {
  BoardOptions b;
  b.kind = BoardKind::kCharuco;
  b.cols = 7;
  b.rows = 5;
  b.square_m = 0.04;
  b.marker_m = 0.03;
  const Rendered r = RenderSet(b, /*with_bad_views=*/false);
  IntrinsicsOptions o;
  o.board = b;
  auto result = CalibrateIntrinsics(r.views, o);
  ASSERT_TRUE(result.ok()) << result.status().message();
  const TrueK k;
  for (const BoardView& v : result->views) EXPECT_TRUE(v.used) << v.name << ": " << v.reason;
  EXPECT_LT(result->rms_px, 0.5);
  EXPECT_NEAR(result->intrinsics.fx_px, k.f, 0.015 * k.f);
  EXPECT_NEAR(result->intrinsics.cx_px, k.cx, 6.0);
  std::printf("charuco: %d views, RMS %.3f px, fx %.2f cx %.2f cy %.2f\n", result->views_used, result->rms_px,
              result->intrinsics.fx_px, result->intrinsics.cx_px, result->intrinsics.cy_px);
}

TEST(BoardCalibration, OptionsAreValidated) {
  BoardOptions b;
  b.kind = BoardKind::kCharuco;
  b.cols = 7;
  b.rows = 5;
  b.square_m = 0.04;
  b.marker_m = 0.05;
  EXPECT_EQ(b.Validate().message(), "ChArUco marker: expected 0 < marker < square (0.04 m), found 0.05 m");
  b.marker_m = 0.03;
  b.dictionary = "4x4_5";
  EXPECT_EQ(b.Validate().message().rfind("ChArUco dictionary: expected one of 4x4_50, ", 0), 0u);
  b.dictionary = "4x4_50";
  b.cols = 12;
  b.rows = 10;
  EXPECT_EQ(b.Validate().message(), "ChArUco: a 12x10 board needs 60 markers, dictionary 4x4_50 has 50");
  BoardOptions c;
  c.cols = 2;
  EXPECT_EQ(c.Validate().message(), "board size: expected 3..100 inner corners across and down, found 2x6");
}

TEST(BoardCalibration, EdgeBlurOfASharpStepIsAboutOnePixel) {
  Image<uint8_t> step(64, 64, 20);
  for (int y = 0; y < 64; ++y) {
    for (int x = 32; x < 64; ++x) step(x, y) = 220;
  }
  const double sharp = EstimateEdgeBlurPx(step.view(), {});
  EXPECT_GT(sharp, 0.5);
  EXPECT_LT(sharp, 1.2);
  cv::Mat m(64, 64, CV_8UC1, step.view().data(), static_cast<size_t>(step.stride_elems()));
  cv::GaussianBlur(m, m, cv::Size(0, 0), 4.0);
  EXPECT_NEAR(EstimateEdgeBlurPx(step.view(), {}), 4.0, 0.8);
}

}  // namespace
}  // namespace occmap
