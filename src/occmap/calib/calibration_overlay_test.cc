#include "occmap/calib/calibration_overlay.h"

#include <gtest/gtest.h>

#include "occmap/geometry/rotation.h"

namespace occmap {
namespace {

PinholeCamera Camera() {
  PinholeParameters p;
  p.image_size = {640, 480};
  p.fx_px = p.fy_px = 520;
  p.cx_px = 319.5;
  p.cy_px = 239.5;
  const Eigen::Vector3d position(-1.0, -1.2, 2.7);
  p.cam_from_world_rotation = LookAtRotation(position, {3.5, 3.0, 0.0});
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * position;
  return PinholeCamera::Create(p).value();
}

bool IsGrey(const Rgb8& c) { return c.r == c.g && c.g == c.b; }

TEST(CalibrationOverlay, DrawsTheGridThePointsAndTheirReprojections) {
  const PinholeCamera cam = Camera();
  const Image<Rgb8> grey(640, 480, Rgb8{100, 100, 100});
  std::vector<FloorPoint> pts(1);
  pts[0].floor_m = {3, 3};
  pts[0].pixel = *cam.Project({3, 3, 0}) + Eigen::Vector2d(15, 0);  // 15 px off
  OverlayOptions o;
  OverlayAreaAroundPoints(pts, o);
  EXPECT_EQ(o.area_min_m, Eigen::Vector2d(2, 2));
  EXPECT_EQ(o.area_max_m, Eigen::Vector2d(4, 4));
  const Image<Rgb8> pic = DrawCalibrationOverlay(grey.view(), cam, pts, o);
  ASSERT_EQ(pic.width(), 640);
  // A grid line crosses the image at (2, 2.5) m; the untouched background is dimmed grey.
  const Eigen::Vector2d on_line = *cam.Project({2, 2.5, 0});
  const Rgb8 line = pic(static_cast<int>(std::lround(on_line.x())), static_cast<int>(std::lround(on_line.y())));
  EXPECT_GT(line.r, 150);
  EXPECT_LT(line.b, 60);
  EXPECT_EQ(pic(5, 470), (Rgb8{75, 75, 75}));
  // The reprojection (red cross) at the world point's pixel; the ring 7 px around the given pixel.
  const Eigen::Vector2d re = *cam.Project({3, 3, 0});
  const Rgb8 cross = pic(static_cast<int>(std::lround(re.x())), static_cast<int>(std::lround(re.y())));
  EXPECT_GT(cross.r, 200);
  EXPECT_LT(cross.g, 120);
  const Rgb8 ring = pic(static_cast<int>(std::lround(pts[0].pixel.x())), static_cast<int>(std::lround(pts[0].pixel.y() + 7)));
  EXPECT_GT(ring.g, 150);
  EXPECT_FALSE(IsGrey(ring));
}

TEST(CalibrationOverlay, AnImageOfAnotherSizeGetsTheRescaledModel) {
  const PinholeCamera cam = Camera();
  const Image<Rgb8> grey(320, 240, Rgb8{100, 100, 100});
  std::vector<FloorPoint> pts(1);
  pts[0].floor_m = {3, 3};
  pts[0].pixel = *cam.Project({3, 3, 0});
  OverlayOptions o;
  OverlayAreaAroundPoints(pts, o);
  const Image<Rgb8> pic = DrawCalibrationOverlay(grey.view(), cam, pts, o);
  ASSERT_EQ(pic.width(), 320);
  const Eigen::Vector2d re = *cam.Resized({320, 240})->Project({3, 3, 0});
  const Rgb8 cross = pic(static_cast<int>(std::lround(re.x())), static_cast<int>(std::lround(re.y())));
  EXPECT_GT(cross.r, 200);
}

}  // namespace
}  // namespace occmap
