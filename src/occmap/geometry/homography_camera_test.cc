#include "occmap/geometry/homography_camera.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "occmap/geometry/rotation.h"
#include "occmap/geometry/pinhole_camera.h"
#include "occmap/util/hash.h"

namespace occmap {
namespace {

// A camera 3 m above the floor, pitched 11.3 degrees down: the horizon is the image row
// v = 539.5 - 1000 * 0.2 = 339.5, so the top rows see the sky.
PinholeParameters PitchedCameraParameters() {
  PinholeParameters p;
  p.image_size = {1920, 1080};
  p.fx_px = 1000;
  p.fy_px = 1000;
  p.cx_px = 959.5;
  p.cy_px = 539.5;
  const Eigen::Vector3d centre(1.0, -2.0, 3.0);
  const Eigen::Vector3d forward(0.3, 1.0, -0.2 * std::hypot(0.3, 1.0));
  p.cam_from_world_rotation = LookAtRotation(centre, centre + forward);
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * centre;
  return p;
}

PinholeCamera PitchedPinhole() {
  Result<PinholeCamera> cam = PinholeCamera::Create(PitchedCameraParameters());
  EXPECT_TRUE(cam.ok()) << cam.status().message();
  return std::move(cam).value();
}

// floor_from_image = (K [r1 r2 t])^-1: the floor point (x, y, 0) in metres maps to the pixel
// K (x r1 + y r2 + t).
Eigen::Matrix3d FloorFromImage(const PinholeParameters& p) {
  Eigen::Matrix3d k;
  k << p.fx_px, p.skew_px, p.cx_px, 0, p.fy_px, p.cy_px, 0, 0, 1;
  Eigen::Matrix3d rrt;
  rrt.col(0) = p.cam_from_world_rotation.col(0);
  rrt.col(1) = p.cam_from_world_rotation.col(1);
  rrt.col(2) = p.cam_from_world_translation_m;
  return (k * rrt).inverse();
}

HomographyCamera MakeHomography(const Eigen::Matrix3d& h, ImageSize size = {1920, 1080}) {
  Result<HomographyCamera> cam = HomographyCamera::Create(h, size);
  EXPECT_TRUE(cam.ok()) << cam.status().message();
  return std::move(cam).value();
}

// Measured: 1.9e-14 m for floor points within 20 m of the origin.
TEST(HomographyCamera, PixelToPlaneEqualsTheUndistortedPinholeItWasBuiltFrom) {
  const PinholeCamera pinhole = PitchedPinhole();
  const HomographyCamera homography = MakeHomography(FloorFromImage(pinhole.params()));
  int on_floor = 0, above_horizon = 0;
  double max_err_m = 0;
  for (int v = 0; v < 1080; v += 10) {
    for (int u = 0; u < 1920; u += 10) {
      const Eigen::Vector2d pixel(u, v);
      const std::optional<Eigen::Vector2d> expected = pinhole.PixelToPlane(pixel, 0.0);
      const std::optional<Eigen::Vector2d> actual = homography.PixelToPlane(pixel, 0.0);
      // The horizon is the row v = 339.5; the grid has no pixel on it.
      ASSERT_EQ(actual.has_value(), expected.has_value()) << pixel.transpose();
      if (!expected) {
        ++above_horizon;
        EXPECT_LT(v, 339.5);
        continue;
      }
      ++on_floor;
      EXPECT_GT(v, 339.5);
      // Relative to the distance: 1e-9 m for points within 10 m, more far away.
      const double err = (*actual - *expected).norm();
      EXPECT_LT(err, 1e-9 * std::max(1.0, expected->squaredNorm() / 10.0)) << pixel.transpose();
      if (expected->norm() < 20) max_err_m = std::max(max_err_m, err);
    }
  }
  EXPECT_GT(on_floor, 10000);
  EXPECT_GT(above_horizon, 5000);
  RecordProperty("max_error_m_within_20m", fmt::format("{:.3g}", max_err_m));
}

TEST(HomographyCamera, PixelsAboveTheHorizonHaveNoFloorPoint) {
  const HomographyCamera cam = MakeHomography(FloorFromImage(PitchedCameraParameters()));
  for (double u : {0.0, 959.5, 1919.0}) {
    EXPECT_FALSE(cam.PixelToPlane({u, 0.0}, 0.0).has_value()) << u;
    EXPECT_FALSE(cam.PixelToPlane({u, 339.0}, 0.0).has_value()) << u;
    EXPECT_TRUE(cam.PixelToPlane({u, 340.0}, 0.0).has_value()) << u;
    EXPECT_TRUE(cam.PixelToPlane({u, 1079.0}, 0.0).has_value()) << u;
  }
}

TEST(HomographyCamera, NegatedMatrixIsTheSameCamera) {
  const Eigen::Matrix3d h = FloorFromImage(PitchedCameraParameters());
  const HomographyCamera a = MakeHomography(h);
  const HomographyCamera b = MakeHomography(-2.5 * h);
  for (int v = 0; v < 1080; v += 27) {
    for (int u = 0; u < 1920; u += 27) {
      const std::optional<Eigen::Vector2d> pa = a.PixelToPlane({u, v}, 0.0);
      const std::optional<Eigen::Vector2d> pb = b.PixelToPlane({u, v}, 0.0);
      ASSERT_EQ(pa.has_value(), pb.has_value()) << u << "," << v;
      if (pa) {
        EXPECT_LT((*pa - *pb).norm(), 1e-12 * std::max(1.0, pa->norm()));
      }
    }
  }
  for (double x = -5; x <= 5; x += 1) {
    for (double y = -5; y <= 15; y += 1) {
      const std::optional<Eigen::Vector2d> qa = a.Project({x, y, 0});
      const std::optional<Eigen::Vector2d> qb = b.Project({x, y, 0});
      ASSERT_EQ(qa.has_value(), qb.has_value()) << x << "," << y;
      if (qa) {
        EXPECT_LT((*qa - *qb).norm(), 1e-9 * std::max(1.0, qa->norm() / 1000));
      }
    }
  }
}

TEST(HomographyCamera, ProjectMatchesThePinholeAndInvertsPixelToPlane) {
  const PinholeCamera pinhole = PitchedPinhole();
  const HomographyCamera homography = MakeHomography(FloorFromImage(pinhole.params()));
  int visible = 0, behind = 0;
  for (double x = -20; x <= 20; x += 0.5) {
    for (double y = -20; y <= 40; y += 0.5) {
      const Eigen::Vector3d point(x, y, 0);
      const std::optional<Eigen::Vector2d> expected = pinhole.Project(point);
      const std::optional<Eigen::Vector2d> pixel = homography.Project(point);
      ASSERT_EQ(pixel.has_value(), expected.has_value()) << point.transpose();
      if (!pixel) {
        ++behind;
        continue;
      }
      ++visible;
      EXPECT_LT((*pixel - *expected).norm(), 1e-9 * std::max(1.0, expected->norm() / 1000))
          << point.transpose();
      const std::optional<Eigen::Vector2d> back = homography.PixelToPlane(*pixel, 0.0);
      ASSERT_TRUE(back.has_value()) << point.transpose();
      EXPECT_LT((*back - point.head<2>()).norm(), 1e-9) << point.transpose();
    }
  }
  EXPECT_GT(visible, 1000);
  EXPECT_GT(behind, 1000);
}

TEST(HomographyCamera, SupportsOnlyTheFloor) {
  const HomographyCamera cam = MakeHomography(FloorFromImage(PitchedCameraParameters()));
  EXPECT_TRUE(cam.SupportsPlaneHeight(0.0));
  EXPECT_FALSE(cam.SupportsPlaneHeight(1.0));
  EXPECT_FALSE(cam.SupportsPlaneHeight(-0.1));
  EXPECT_FALSE(cam.PixelToPlane({960, 800}, 1.0).has_value());
  EXPECT_TRUE(cam.PixelToPlane({960, 800}, 0.0).has_value());
  EXPECT_FALSE(cam.Project({1.0, 5.0, 0.5}).has_value());
  EXPECT_TRUE(cam.Project({1.0, 5.0, 0.0}).has_value());
  // Without 3D it has neither rays nor a centre.
  EXPECT_FALSE(cam.BackProject({960, 800}).has_value());
  EXPECT_FALSE(cam.CenterInWorld().has_value());
  EXPECT_EQ(cam.kind(), "homography");
}

TEST(HomographyCamera, ResizedToQuarterSizeMapsPixelsByTheRescaleFormula) {
  const HomographyCamera cam = MakeHomography(FloorFromImage(PitchedCameraParameters()));
  const std::unique_ptr<CameraModel> quarter = cam.Resized({480, 270});
  EXPECT_EQ(quarter->image_size(), (ImageSize{480, 270}));
  EXPECT_EQ(quarter->kind(), "homography");
  int compared = 0;
  for (double x = -10; x <= 10; x += 0.5) {
    for (double y = -5; y <= 30; y += 0.5) {
      const Eigen::Vector3d point(x, y, 0);
      const std::optional<Eigen::Vector2d> full = cam.Project(point);
      const std::optional<Eigen::Vector2d> small = quarter->Project(point);
      ASSERT_EQ(full.has_value(), small.has_value()) << point.transpose();
      if (!full) continue;
      ++compared;
      const Eigen::Vector2d expected((full->x() + 0.5) * 0.25 - 0.5,
                                     (full->y() + 0.5) * 0.25 - 0.5);
      EXPECT_LT((*small - expected).norm(), 1e-9 * std::max(1.0, expected.norm() / 1000))
          << point.transpose();
    }
  }
  EXPECT_GT(compared, 1000);
  for (double v = 0; v < 270; v += 9) {
    for (double u = 0; u < 480; u += 16) {
      const std::optional<Eigen::Vector2d> a = quarter->PixelToPlane({u, v}, 0.0);
      const std::optional<Eigen::Vector2d> b =
          cam.PixelToPlane({(u + 0.5) * 4 - 0.5, (v + 0.5) * 4 - 0.5}, 0.0);
      ASSERT_EQ(a.has_value(), b.has_value()) << u << "," << v;
      if (a) {
        EXPECT_LT((*a - *b).norm(), 1e-9 * std::max(1.0, b->squaredNorm()));
      }
    }
  }
}

TEST(HomographyCamera, ResizedUpAndBackIsTheSameCamera) {
  const HomographyCamera cam = MakeHomography(FloorFromImage(PitchedCameraParameters()));
  const std::unique_ptr<CameraModel> back = cam.Resized({480, 270})->Resized({1920, 1080});
  const auto* h = dynamic_cast<const HomographyCamera*>(back.get());
  ASSERT_NE(h, nullptr);
  const Eigen::Matrix3d diff = h->floor_from_image() - cam.floor_from_image();
  EXPECT_LT(diff.cwiseAbs().maxCoeff(), 1e-15 * cam.floor_from_image().cwiseAbs().maxCoeff() * 100);
}

TEST(HomographyCamera, CloneMatchesTheOriginalAndTheHashFollowsTheMatrix) {
  const HomographyCamera cam = MakeHomography(FloorFromImage(PitchedCameraParameters()));
  const std::unique_ptr<CameraModel> clone = cam.Clone();
  EXPECT_EQ(clone->PixelToPlane({900, 700}, 0.0), cam.PixelToPlane({900, 700}, 0.0));
  Hasher a, b, c, d;
  cam.AppendToHash(a);
  clone->AppendToHash(b);
  cam.Resized({480, 270})->AppendToHash(c);
  Eigen::Matrix3d other = cam.floor_from_image();
  other(0, 2) += 1e-3;
  MakeHomography(other).AppendToHash(d);
  EXPECT_EQ(a.Digest(), b.Digest());
  EXPECT_NE(a.Digest(), c.Digest());
  EXPECT_NE(a.Digest(), d.Digest());
}

// ---------------------------------------------------------------------------------------------
// Create: a table of bad inputs, each with its exact message.

struct BadHomographyCase {
  std::string name;
  Eigen::Matrix3d h;
  ImageSize size;
  std::string message;
};

TEST(HomographyCamera, CreateRejectsBadMatricesWithTheirMessages) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const Eigen::Matrix3d good = FloorFromImage(PitchedCameraParameters());
  Eigen::Matrix3d with_nan = good;
  with_nan(1, 1) = nan;
  Eigen::Matrix3d with_inf = good;
  with_inf(2, 0) = inf;
  Eigen::Matrix3d rank_two;
  rank_two << 1, 0, 0, 0, 1, 0, 1, 1, 0;
  Eigen::Matrix3d nearly_singular = good;
  nearly_singular.row(2) = good.row(0) + good.row(1);
  // w = v - 1079: the bottom row maps to infinity.
  Eigen::Matrix3d bottom_at_infinity;
  bottom_at_infinity << 1, 0, 0, 0, 1, 0, 0, 1, -1079;

  const std::vector<BadHomographyCase> cases = {
      {"NaN entry", with_nan, {1920, 1080},
       "homography: expected finite values, found NaN or infinity"},
      {"infinite entry", with_inf, {1920, 1080},
       "homography: expected finite values, found NaN or infinity"},
      {"zero matrix", Eigen::Matrix3d::Zero(), {1920, 1080},
       "homography: expected an invertible matrix, found determinant 0"},
      {"rank two", rank_two, {1920, 1080},
       "homography: expected an invertible matrix, found determinant 0"},
      {"zero width", good, {0, 1080}, "image size: expected positive, found 0x1080"},
      {"negative height", good, {1920, -1}, "image size: expected positive, found 1920x-1"},
      {"bottom-centre pixel at infinity", bottom_at_infinity, {1920, 1080},
       "homography: the bottom-centre pixel maps to infinity"},
  };
  for (const BadHomographyCase& c : cases) {
    const Result<HomographyCamera> cam = HomographyCamera::Create(c.h, c.size);
    ASSERT_FALSE(cam.ok()) << c.name;
    EXPECT_EQ(cam.status().code(), StatusCode::kInvalidInput) << c.name;
    EXPECT_EQ(cam.status().message(), c.message) << c.name;
  }
  // A row that is the sum of two others up to rounding: singular relative to its scale.
  const Result<HomographyCamera> singular = HomographyCamera::Create(nearly_singular, {1920, 1080});
  ASSERT_FALSE(singular.ok());
  const std::string prefix = "homography: expected an invertible matrix, found determinant ";
  EXPECT_EQ(singular.status().message().rfind(prefix, 0), 0u) << singular.status().message();
}

TEST(HomographyCamera, CreateAcceptsMatricesAtAnyScale) {
  const Eigen::Matrix3d h = FloorFromImage(PitchedCameraParameters());
  for (double scale : {1e-6, 1e-3, 1.0, 1e3, 1e6}) {
    const Result<HomographyCamera> cam = HomographyCamera::Create(scale * h, {1920, 1080});
    ASSERT_TRUE(cam.ok()) << scale << ": " << cam.status().message();
    const std::optional<Eigen::Vector2d> floor = cam->PixelToPlane({960, 800}, 0.0);
    ASSERT_TRUE(floor.has_value());
  }
}

}  // namespace
}  // namespace occmap
