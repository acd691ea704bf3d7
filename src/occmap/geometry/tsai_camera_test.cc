#include "occmap/geometry/tsai_camera.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "occmap/geometry/rotation.h"
#include "occmap/util/hash.h"
#include "occmap/util/testing.h"
#include "occmap/util/yaml_util.h"

namespace occmap {
namespace {

// ---------------------------------------------------------------------------------------------
// Reference data: EPFL terrace cameras, projections by Willson's Tsai 3.0b3 code.

struct TerraceCamera {
  TsaiParameters params;
  Eigen::Matrix3d willson_rotation;    // r1..r9
  Eigen::Vector3d willson_centre_mm;   // camera_centre_world
};

std::map<std::string, TerraceCamera> LoadTerraceCameras(const std::filesystem::path& file) {
  if (!std::filesystem::exists(file)) {
    ADD_FAILURE() << "missing reference file " << file;
    return {};
  }
  const YAML::Node root = YAML::LoadFile(file.string());
  std::map<std::string, TerraceCamera> cameras;
  for (const auto& entry : root) {
    const std::string name = entry.first.as<std::string>();
    const YAML::Node& c = entry.second;
    auto num = [&](const char* key) { return c[key].as<double>(); };
    TerraceCamera cam;
    TsaiParameters& p = cam.params;
    p.image_size = {c["image_width"].as<int>(), c["image_height"].as<int>()};
    p.Ncx = num("Ncx");
    p.Nfx = num("Nfx");
    p.dx_mm = num("dx");
    p.dy_mm = num("dy");
    p.sx = num("sx");
    p.Cx_px = num("Cx");
    p.Cy_px = num("Cy");
    p.f_mm = num("f");
    p.kappa1_per_mm2 = num("kappa1");
    p.cam_from_world_rotation = TsaiRotation(num("Rx"), num("Ry"), num("Rz"));
    p.cam_from_world_translation_m = Eigen::Vector3d(num("Tx"), num("Ty"), num("Tz")) / 1000.0;
    cam.willson_rotation << num("r1"), num("r2"), num("r3"), num("r4"), num("r5"), num("r6"),
        num("r7"), num("r8"), num("r9");
    const YAML::Node centre = c["camera_centre_world"];
    cam.willson_centre_mm = Eigen::Vector3d(centre[0].as<double>(), centre[1].as<double>(),
                                            centre[2].as<double>());
    cameras.emplace(name, cam);
  }
  return cameras;
}

// A CSV table with a header line: column name -> index, and rows of text fields.
struct CsvTable {
  std::map<std::string, size_t> columns;
  std::vector<std::vector<std::string>> rows;

  double Number(size_t row, const std::string& column) const {
    const std::string& text = rows[row].at(columns.at(column));
    const std::optional<double> v = ParseFiniteDouble(text);
    EXPECT_TRUE(v.has_value()) << "row " << row << ", column " << column << ": '" << text << "'";
    return v.value_or(std::numeric_limits<double>::quiet_NaN());
  }
  const std::string& Text(size_t row, const std::string& column) const {
    return rows[row].at(columns.at(column));
  }
};

std::vector<std::string> SplitCommas(const std::string& line) {
  std::vector<std::string> fields;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return fields;
}

CsvTable LoadCsv(const std::filesystem::path& file) {
  CsvTable table;
  std::ifstream in(file);
  EXPECT_TRUE(in.good()) << "cannot read reference file " << file;
  std::string line;
  if (!std::getline(in, line)) return table;
  const std::vector<std::string> header = SplitCommas(line);
  for (size_t i = 0; i < header.size(); ++i) table.columns[header[i]] = i;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    table.rows.push_back(SplitCommas(line));
    EXPECT_EQ(table.rows.back().size(), header.size()) << file << ": " << line;
  }
  return table;
}

std::map<std::string, TsaiCamera> CreateTerraceCameras(
    const std::map<std::string, TerraceCamera>& terrace) {
  std::map<std::string, TsaiCamera> cameras;
  for (const auto& [name, cam] : terrace) {
    Result<TsaiCamera> created = TsaiCamera::Create(cam.params);
    EXPECT_TRUE(created.ok()) << name << ": " << created.status().message();
    if (created.ok()) cameras.emplace(name, std::move(created).value());
  }
  return cameras;
}

TEST(TsaiCamera, TsaiRotationReproducesWillsonRotationMatrices) {
  OCCMAP_REQUIRE_DATASETS(root);
  const auto terrace = LoadTerraceCameras(root / "tsai-terrace" / "terrace_cameras.yaml");
  ASSERT_EQ(terrace.size(), 4u);
  double max_err = 0;
  for (const auto& [name, cam] : terrace) {
    const double err =
        (cam.params.cam_from_world_rotation - cam.willson_rotation).cwiseAbs().maxCoeff();
    EXPECT_LT(err, 1e-12) << name;
    max_err = std::max(max_err, err);
  }
  // Measured: 0 (bit-identical to Willson's r1..r9).
  RecordProperty("max_error", fmt::format("{:.3g}", max_err));
}

TEST(TsaiCamera, CenterInWorldMatchesWillsonCameraCentre) {
  OCCMAP_REQUIRE_DATASETS(root);
  const auto terrace = LoadTerraceCameras(root / "tsai-terrace" / "terrace_cameras.yaml");
  const auto cameras = CreateTerraceCameras(terrace);
  ASSERT_EQ(cameras.size(), 4u);
  double max_err_m = 0;
  for (const auto& [name, cam] : cameras) {
    const std::optional<Eigen::Vector3d> centre = cam.CenterInWorld();
    ASSERT_TRUE(centre.has_value()) << name;
    const Eigen::Vector3d expected_m = terrace.at(name).willson_centre_mm / 1000.0;
    const double err = (*centre - expected_m).cwiseAbs().maxCoeff();
    EXPECT_LT(err, 1e-9) << name;
    max_err_m = std::max(max_err_m, err);
  }
  // Measured: 4.6e-13 m (the reference prints 1e-9 mm).
  RecordProperty("max_error_m", fmt::format("{:.3g}", max_err_m));
}

// Max error measured over all 4412 rows: 5.0e-7 px, i.e. the rounding of the file (it prints
// Xf, Yf with 6 decimals), not a difference between the models.
TEST(TsaiCamera, ReproducesWillsonWorldToImageReference) {
  OCCMAP_REQUIRE_DATASETS(root);
  const auto cameras = CreateTerraceCameras(
      LoadTerraceCameras(root / "tsai-terrace" / "terrace_cameras.yaml"));
  ASSERT_EQ(cameras.size(), 4u);
  const CsvTable table = LoadCsv(root / "tsai-terrace" / "world_to_image.csv");
  ASSERT_EQ(table.rows.size(), 4412u);

  double max_err_px = 0;
  int in_image_disagreements = 0;
  for (size_t i = 0; i < table.rows.size(); ++i) {
    const TsaiCamera& cam = cameras.at(table.Text(i, "camera"));
    const Eigen::Vector3d point_m =
        Eigen::Vector3d(table.Number(i, "xw"), table.Number(i, "yw"), table.Number(i, "zw")) /
        1000.0;
    const Eigen::Vector2d expected(table.Number(i, "Xf"), table.Number(i, "Yf"));
    const std::optional<Eigen::Vector2d> pixel = cam.Project(point_m);
    ASSERT_TRUE(pixel.has_value()) << "row " << i + 2;
    const double err = (*pixel - expected).cwiseAbs().maxCoeff();
    EXPECT_LT(err, 1e-3) << "row " << i + 2 << ": " << pixel->transpose() << " vs "
                         << expected.transpose();
    max_err_px = std::max(max_err_px, err);
    // in_image uses [0, 720) x [0, 576); InImage uses [-0.5, 719.5) x [-0.5, 575.5).
    const bool in_image = table.Number(i, "in_image") == 1.0;
    if (cam.InImage(*pixel) != in_image) ++in_image_disagreements;
  }
  RecordProperty("max_error_px", fmt::format("{:.3g}", max_err_px));
  // The README counts exactly 3 rows that change between the two pixel conventions.
  EXPECT_EQ(in_image_disagreements, 3);
}

// Max error measured over all 611 rows: 5.0e-10 m = 5.0e-7 mm, again the rounding of the file
// (xw, yw printed with 6 decimals in mm), for floor points up to 434 m away.
TEST(TsaiCamera, ReproducesWillsonImageToFloorReference) {
  OCCMAP_REQUIRE_DATASETS(root);
  const auto cameras = CreateTerraceCameras(
      LoadTerraceCameras(root / "tsai-terrace" / "terrace_cameras.yaml"));
  ASSERT_EQ(cameras.size(), 4u);
  const CsvTable table = LoadCsv(root / "tsai-terrace" / "image_to_floor.csv");
  ASSERT_EQ(table.rows.size(), 611u);

  double max_err_m = 0;
  for (size_t i = 0; i < table.rows.size(); ++i) {
    const TsaiCamera& cam = cameras.at(table.Text(i, "camera"));
    const Eigen::Vector2d pixel(table.Number(i, "Xf"), table.Number(i, "Yf"));
    const Eigen::Vector2d expected_m =
        Eigen::Vector2d(table.Number(i, "xw"), table.Number(i, "yw")) / 1000.0;
    const std::optional<Eigen::Vector2d> floor_m = cam.PixelToPlane(pixel, 0.0);
    ASSERT_TRUE(floor_m.has_value()) << "row " << i + 2;
    const double err = (*floor_m - expected_m).cwiseAbs().maxCoeff();
    EXPECT_LT(err, 1e-6) << "row " << i + 2 << ": " << floor_m->transpose() << " vs "
                         << expected_m.transpose();
    max_err_m = std::max(max_err_m, err);
  }
  RecordProperty("max_error_m", fmt::format("{:.3g}", max_err_m));
}

TEST(TsaiCamera, PixelsLeftOutOfTheImageToFloorReferenceAreAboveTheHorizon) {
  // The reference leaves out the pixel rows whose floor point is behind the camera (c0: rows
  // Yf = 0.5 and 48.5; c1..c3: row Yf = 0.5). PixelToPlane must reject exactly those.
  OCCMAP_REQUIRE_DATASETS(root);
  const auto cameras = CreateTerraceCameras(
      LoadTerraceCameras(root / "tsai-terrace" / "terrace_cameras.yaml"));
  ASSERT_EQ(cameras.size(), 4u);
  const std::map<std::string, std::vector<double>> rows_above = {
      {"c0", {0.5, 48.5}}, {"c1", {0.5}}, {"c2", {0.5}}, {"c3", {0.5}}};
  for (const auto& [name, cam] : cameras) {
    for (int k = 0; k <= 12; ++k) {
      const double xf = k < 12 ? 0.5 + 60.0 * k : 719.5;
      for (int j = 0; j <= 12; ++j) {
        const double yf = j < 12 ? 0.5 + 48.0 * j : 575.5;
        const auto& above = rows_above.at(name);
        const bool expected_above = std::find(above.begin(), above.end(), yf) != above.end();
        EXPECT_EQ(cam.PixelToPlane({xf, yf}, 0.0).has_value(), !expected_above)
            << name << " pixel (" << xf << ", " << yf << ")";
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Built-in fixtures: a camera like terrace c0, about 2 m above the floor, looking down at it.

TsaiParameters SyntheticParameters(double kappa1_per_mm2) {
  TsaiParameters p;
  p.image_size = {720, 576};
  p.Ncx = 576;
  p.Nfx = 576;
  p.dx_mm = 0.023;
  p.dy_mm = 0.023;
  p.sx = 1;
  p.Cx_px = 366.514507;
  p.Cy_px = 305.832552;
  p.f_mm = 20.16192;
  p.kappa1_per_mm2 = kappa1_per_mm2;
  p.cam_from_world_rotation = TsaiRotation(1.9007833770, 0.49730769727, 0.18415452559);
  p.cam_from_world_translation_m = Eigen::Vector3d(-4.8441913843, 0.55109448682, 4.9667438357);
  return p;
}

TsaiCamera SyntheticCamera(double kappa1_per_mm2) {
  Result<TsaiCamera> cam = TsaiCamera::Create(SyntheticParameters(kappa1_per_mm2));
  EXPECT_TRUE(cam.ok()) << cam.status().message();
  return std::move(cam).value();
}

class TsaiCameraKappa : public ::testing::TestWithParam<double> {};

INSTANTIATE_TEST_SUITE_P(PincushionNoneAndBarrel, TsaiCameraKappa,
                         ::testing::Values(5.720865e-04, 0.0, -5.720865e-04, -2e-3));

TEST_P(TsaiCameraKappa, ProjectInvertsPixelToPlaneOverTheImage) {
  const TsaiCamera cam = SyntheticCamera(GetParam());
  int on_floor = 0, above_horizon = 0;
  double max_err_px = 0;
  for (double plane_z_m : {0.0, 1.0}) {
    for (double v = -0.5; v <= 575.5; v += 12.0) {
      for (double u = -0.5; u <= 719.5; u += 12.0) {
        const Eigen::Vector2d pixel(u, v);
        const std::optional<Eigen::Vector2d> xy = cam.PixelToPlane(pixel, plane_z_m);
        if (!xy) {
          ++above_horizon;
          continue;
        }
        ++on_floor;
        const std::optional<Eigen::Vector2d> back =
            cam.Project(Eigen::Vector3d(xy->x(), xy->y(), plane_z_m));
        ASSERT_TRUE(back.has_value()) << "pixel " << pixel.transpose();
        const double err = (*back - pixel).norm();
        EXPECT_LT(err, 1e-9) << "pixel " << pixel.transpose() << " plane " << plane_z_m;
        max_err_px = std::max(max_err_px, err);
      }
    }
  }
  // The camera sees the floor in most of its picture and the sky in its top rows.
  EXPECT_GT(on_floor, 3000);
  EXPECT_GT(above_horizon, 0);
  RecordProperty("max_error_px", fmt::format("{:.3g}", max_err_px));
}

TEST_P(TsaiCameraKappa, BackProjectedRayPassesThroughTheProjectedPoint) {
  const TsaiCamera cam = SyntheticCamera(GetParam());
  const Eigen::Vector3d centre = *cam.CenterInWorld();
  for (double x = 0; x <= 6; x += 1.5) {
    for (double y = 0; y <= 8; y += 2) {
      for (double z : {0.0, 0.9, 1.8}) {
        const Eigen::Vector3d point(x, y, z);
        const std::optional<Eigen::Vector2d> pixel = cam.Project(point);
        if (!pixel) continue;
        const std::optional<Ray> ray = cam.BackProject(*pixel);
        ASSERT_TRUE(ray.has_value()) << point.transpose();
        EXPECT_LT((ray->origin_in_world - centre).norm(), 1e-12);
        EXPECT_NEAR(ray->direction_in_world.norm(), 1.0, 1e-15);
        const Eigen::Vector3d to_point = (point - centre).normalized();
        EXPECT_LT((ray->direction_in_world - to_point).norm(), 1e-12) << point.transpose();
      }
    }
  }
}

TEST_P(TsaiCameraKappa, DistortedRadiusInvertsTheRadialDistortion) {
  const double k = GetParam();
  const TsaiCamera cam = SyntheticCamera(k);
  EXPECT_EQ(cam.DistortedRadius(0.0), 0.0);
  // Up to just below the maximum barrel radius for k < 0 (at it the root is double), up to
  // 200 mm (a huge field angle) otherwise.
  const double ru_end = k < 0 ? 0.999999 * (2.0 / 3.0) * std::sqrt(-1.0 / (3.0 * k)) : 200.0;
  const double rd_max =
      k < 0 ? std::sqrt(-1.0 / (3.0 * k)) : std::numeric_limits<double>::infinity();
  for (int i = 1; i <= 2000; ++i) {
    const double ru = ru_end * i / 2000.0;
    const std::optional<double> rd = cam.DistortedRadius(ru);
    ASSERT_TRUE(rd.has_value()) << "ru = " << ru;
    EXPECT_GE(*rd, 0);
    // The smaller positive root: on the increasing branch for barrel distortion.
    EXPECT_LE(*rd, rd_max * (1 + 1e-12)) << "ru = " << ru;
    const double ru_again = *rd * (1 + k * *rd * *rd);
    EXPECT_NEAR(ru_again, ru, 1e-14 * std::max(1.0, ru)) << "ru = " << ru;
  }
  // Tiny radii, where Cardan's formula cancels.
  for (double ru : {1e-12, 1e-9, 1e-6, 1e-3}) {
    const std::optional<double> rd = cam.DistortedRadius(ru);
    ASSERT_TRUE(rd.has_value());
    EXPECT_NEAR(*rd * (1 + k * *rd * *rd), ru, 1e-15 * ru) << "ru = " << ru;
  }
}

TEST(TsaiCamera, DistortedRadiusIsNulloptBeyondTheMaximumBarrelRadius) {
  const double k = -2e-3;
  const TsaiCamera cam = SyntheticCamera(k);
  const double rd_max = std::sqrt(-1.0 / (3.0 * k));
  const double ru_max = rd_max * (1 + k * rd_max * rd_max);  // = 2/3 rd_max
  EXPECT_NEAR(ru_max, 2.0 / 3.0 * rd_max, 1e-14);
  const std::optional<double> at_max = cam.DistortedRadius(ru_max * (1 - 1e-12));
  ASSERT_TRUE(at_max.has_value());
  // Near the double root rd_max - rd ~ sqrt(2 * 1e-12 * ru_max / |6 k rd_max|) = 1.05e-5.
  EXPECT_LT(*at_max, rd_max);
  EXPECT_NEAR(*at_max, rd_max, 2e-5);
  EXPECT_NEAR(*at_max * (1 + k * *at_max * *at_max), ru_max * (1 - 1e-12), 1e-14);
  const std::optional<double> exactly_at_max = cam.DistortedRadius(ru_max);
  ASSERT_TRUE(exactly_at_max.has_value());
  EXPECT_NEAR(*exactly_at_max, rd_max, 1e-6);
  EXPECT_FALSE(cam.DistortedRadius(ru_max * (1 + 1e-9)).has_value());
  EXPECT_FALSE(cam.DistortedRadius(2 * ru_max).has_value());
  EXPECT_FALSE(cam.DistortedRadius(1e6).has_value());
}

TEST(TsaiCamera, PointsBeyondTheMaximumBarrelRadiusDoNotProject) {
  const double k = -2e-3;
  const TsaiCamera cam = SyntheticCamera(k);
  const TsaiParameters& p = cam.params();
  const double ru_max = (2.0 / 3.0) * std::sqrt(-1.0 / (3.0 * k));
  const Eigen::Matrix3d world_from_cam = p.cam_from_world_rotation.transpose();
  const Eigen::Vector3d centre = *cam.CenterInWorld();
  // Camera-frame points at depth 2 m whose undistorted sensor radius is just inside / outside.
  auto point_at_sensor_radius = [&](double ru_mm) {
    const Eigen::Vector3d in_cam(2.0 * ru_mm / p.f_mm * 0.6, 2.0 * ru_mm / p.f_mm * 0.8, 2.0);
    return Eigen::Vector3d(world_from_cam * in_cam + centre);
  };
  EXPECT_TRUE(cam.Project(point_at_sensor_radius(0.99 * ru_max)).has_value());
  EXPECT_FALSE(cam.Project(point_at_sensor_radius(1.01 * ru_max)).has_value());
  // Pixels farther from the centre than the maximum distorted radius have no ray.
  const double rd_max = std::sqrt(-1.0 / (3.0 * k));
  const double dpx = p.dx_mm * p.Ncx / p.Nfx;
  const Eigen::Vector2d inside(p.Cx_px + 0.99 * rd_max * p.sx / dpx, p.Cy_px);
  const Eigen::Vector2d outside(p.Cx_px, p.Cy_px + 1.01 * rd_max / p.dy_mm);
  EXPECT_TRUE(cam.BackProject(inside).has_value());
  EXPECT_FALSE(cam.BackProject(outside).has_value());
  EXPECT_FALSE(cam.PixelToPlane(outside, 0.0).has_value());
}

TEST(TsaiCamera, PointsBehindTheCameraDoNotProject) {
  for (double k : {5.720865e-04, 0.0, -5.720865e-04}) {
    const TsaiCamera cam = SyntheticCamera(k);
    const Eigen::Matrix3d world_from_cam = cam.params().cam_from_world_rotation.transpose();
    const Eigen::Vector3d centre = *cam.CenterInWorld();
    const Eigen::Vector3d axis = world_from_cam.col(2);  // optical axis in the world
    EXPECT_TRUE(cam.Project(centre + 3.0 * axis).has_value());
    EXPECT_FALSE(cam.Project(centre - 3.0 * axis).has_value());
    // Behind the camera but off-axis: the mirror image of a visible point.
    const Eigen::Vector3d visible = centre + world_from_cam * Eigen::Vector3d(0.5, -0.3, 2.0);
    ASSERT_TRUE(cam.Project(visible).has_value());
    EXPECT_FALSE(cam.Project(2 * centre - visible).has_value());
    // Just behind the camera's own plane z_c = 0.
    const Eigen::Vector3d just_behind = centre + world_from_cam * Eigen::Vector3d(0.3, 0.2, -1e-6);
    EXPECT_FALSE(cam.Project(just_behind).has_value());
  }
  // Identity pose: camera frame = world frame, so z_c = 0 holds exactly.
  TsaiParameters p = SyntheticParameters(5.720865e-04);
  p.cam_from_world_rotation.setIdentity();
  p.cam_from_world_translation_m.setZero();
  const Result<TsaiCamera> cam = TsaiCamera::Create(p);
  ASSERT_TRUE(cam.ok());
  EXPECT_FALSE(cam->Project(Eigen::Vector3d::Zero()).has_value());
  EXPECT_FALSE(cam->Project(Eigen::Vector3d(1.0, -2.0, 0.0)).has_value());
  EXPECT_FALSE(cam->Project(Eigen::Vector3d(0.0, 0.0, -1.0)).has_value());
  EXPECT_EQ(cam->Project(Eigen::Vector3d(0.0, 0.0, 1.0)), Eigen::Vector2d(p.Cx_px, p.Cy_px));
}

TEST(TsaiCamera, PixelAboveTheHorizonHasNoFloorPoint) {
  const TsaiCamera cam = SyntheticCamera(5.720865e-04);
  // Terrace c0 sees the sky in its top rows (the reference leaves out Yf = 0.5 and 48.5).
  EXPECT_FALSE(cam.PixelToPlane({360, 0.5}, 0.0).has_value());
  EXPECT_TRUE(cam.PixelToPlane({360, 500}, 0.0).has_value());
  // A plane above the camera centre is met only by rays going up: the top rows.
  const double above_m = cam.CenterInWorld()->z() + 1.0;
  EXPECT_TRUE(cam.PixelToPlane({360, 0.5}, above_m).has_value());
  EXPECT_FALSE(cam.PixelToPlane({360, 500}, above_m).has_value());
}

TEST(TsaiCamera, ResizedToQuarterSizeMapsPixelsByTheRescaleFormula) {
  for (double k : {5.720865e-04, 0.0, -5.720865e-04}) {
    const TsaiCamera cam = SyntheticCamera(k);
    const std::unique_ptr<CameraModel> quarter = cam.Resized({180, 144});
    ASSERT_NE(quarter, nullptr);
    EXPECT_EQ(quarter->image_size(), (ImageSize{180, 144}));
    EXPECT_EQ(quarter->kind(), "tsai");
    EXPECT_LT((*quarter->CenterInWorld() - *cam.CenterInWorld()).norm(), 1e-15);
    int compared = 0;
    for (double x = -1; x <= 7; x += 0.5) {
      for (double y = -2; y <= 10; y += 0.5) {
        for (double z : {0.0, 0.9, 1.8}) {
          const Eigen::Vector3d point(x, y, z);
          const std::optional<Eigen::Vector2d> full = cam.Project(point);
          const std::optional<Eigen::Vector2d> small = quarter->Project(point);
          ASSERT_EQ(full.has_value(), small.has_value()) << point.transpose();
          if (!full) continue;
          ++compared;
          const Eigen::Vector2d expected((full->x() + 0.5) * 0.25 - 0.5,
                                         (full->y() + 0.5) * 0.25 - 0.5);
          EXPECT_LT((*small - expected).norm(), 1e-9) << point.transpose();
          EXPECT_EQ(quarter->InImage(*small), cam.InImage(*full)) << point.transpose();
        }
      }
    }
    EXPECT_GT(compared, 1000);
    // And the other way: a quarter-size pixel sees the same floor point as its full-size twin.
    for (double v = 40; v < 144; v += 10) {
      for (double u = 0; u < 180; u += 10) {
        const std::optional<Eigen::Vector2d> a = quarter->PixelToPlane({u, v}, 0.0);
        const std::optional<Eigen::Vector2d> b =
            cam.PixelToPlane({(u + 0.5) * 4.0 - 0.5, (v + 0.5) * 4.0 - 0.5}, 0.0);
        ASSERT_EQ(a.has_value(), b.has_value());
        if (a) {
          EXPECT_LT((*a - *b).norm(), 1e-9 * std::max(1.0, b->norm()));
        }
      }
    }
  }
}

TEST(TsaiCamera, CloneProjectsLikeTheOriginal) {
  const TsaiCamera cam = SyntheticCamera(5.720865e-04);
  const std::unique_ptr<CameraModel> clone = cam.Clone();
  EXPECT_EQ(clone->kind(), "tsai");
  EXPECT_EQ(clone->image_size(), cam.image_size());
  const Eigen::Vector3d point(2.0, 3.0, 0.5);
  EXPECT_EQ(*clone->Project(point), *cam.Project(point));
  Hasher a, b;
  cam.AppendToHash(a);
  clone->AppendToHash(b);
  EXPECT_EQ(a.Digest(), b.Digest());
}

TEST(TsaiCamera, HashChangesWithEveryGeometricParameter) {
  auto digest = [](const TsaiParameters& p) {
    Hasher h;
    Result<TsaiCamera> cam = TsaiCamera::Create(p);
    EXPECT_TRUE(cam.ok()) << cam.status().message();
    cam->AppendToHash(h);
    return h.Digest();
  };
  const TsaiParameters base = SyntheticParameters(5.720865e-04);
  const uint64_t base_digest = digest(base);
  std::vector<TsaiParameters> changed(13, base);
  changed[0].image_size.width += 1;
  changed[1].image_size.height += 1;
  changed[2].Ncx += 1;
  changed[3].Nfx += 1;
  changed[4].dx_mm *= 1.001;
  changed[5].dy_mm *= 1.001;
  changed[6].sx *= 1.001;
  changed[7].Cx_px += 0.1;
  changed[8].Cy_px += 0.1;
  changed[9].f_mm += 0.1;
  changed[10].kappa1_per_mm2 *= 1.1;
  changed[11].cam_from_world_rotation = TsaiRotation(1.9, 0.5, 0.18);
  changed[12].cam_from_world_translation_m.x() += 0.01;
  for (size_t i = 0; i < changed.size(); ++i) EXPECT_NE(digest(changed[i]), base_digest) << i;
}

// ---------------------------------------------------------------------------------------------
// Validate: a table of bad parameters, each with its exact message.

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

struct BadTsaiCase {
  std::string name;
  void (*mutate)(TsaiParameters&);
  std::string message;
};

TEST(TsaiParameters, ValidateAcceptsTheSyntheticCamera) {
  EXPECT_TRUE(SyntheticParameters(5.720865e-04).Validate().ok());
  EXPECT_TRUE(SyntheticParameters(0.0).Validate().ok());
  EXPECT_TRUE(SyntheticParameters(-5.720865e-04).Validate().ok());
}

TEST(TsaiParameters, ValidateRejectsBadValuesWithTheirMessages) {
  const std::vector<BadTsaiCase> cases = {
      {"zero f", [](TsaiParameters& p) { p.f_mm = 0; }, "f: expected a positive value, found 0"},
      {"negative f", [](TsaiParameters& p) { p.f_mm = -20.5; },
       "f: expected a positive value, found -20.5"},
      {"zero dx", [](TsaiParameters& p) { p.dx_mm = 0; }, "dx: expected a positive value, found 0"},
      {"negative dy", [](TsaiParameters& p) { p.dy_mm = -0.023; },
       "dy: expected a positive value, found -0.023"},
      {"zero Ncx", [](TsaiParameters& p) { p.Ncx = 0; }, "Ncx: expected a positive value, found 0"},
      {"zero Nfx", [](TsaiParameters& p) { p.Nfx = 0; }, "Nfx: expected a positive value, found 0"},
      {"zero sx", [](TsaiParameters& p) { p.sx = 0; }, "sx: expected a positive value, found 0"},
      {"NaN f", [](TsaiParameters& p) { p.f_mm = kNaN; },
       "expected finite Tsai parameters, found NaN or infinity"},
      {"NaN kappa1", [](TsaiParameters& p) { p.kappa1_per_mm2 = kNaN; },
       "expected finite Tsai parameters, found NaN or infinity"},
      {"infinite Cx", [](TsaiParameters& p) { p.Cx_px = kInf; },
       "expected finite Tsai parameters, found NaN or infinity"},
      {"NaN in rotation", [](TsaiParameters& p) { p.cam_from_world_rotation(1, 2) = kNaN; },
       "expected finite Tsai parameters, found NaN or infinity"},
      {"NaN in translation", [](TsaiParameters& p) { p.cam_from_world_translation_m.z() = kNaN; },
       "expected finite Tsai parameters, found NaN or infinity"},
      {"zero width", [](TsaiParameters& p) { p.image_size.width = 0; },
       "image size: expected positive, found 0x576"},
      {"negative height", [](TsaiParameters& p) { p.image_size.height = -1; },
       "image size: expected positive, found 720x-1"},
      {"stretched rotation",
       [](TsaiParameters& p) { p.cam_from_world_rotation = Eigen::Vector3d(2, 1, 1).asDiagonal(); },
       "rotation: expected an orthonormal matrix with determinant +1, found |R R^T - I| = 3, "
       "det = 2"},
      {"reflection",
       [](TsaiParameters& p) {
         p.cam_from_world_rotation = Eigen::Vector3d(1, 1, -1).asDiagonal();
       },
       "rotation: expected an orthonormal matrix with determinant +1, found |R R^T - I| = 0, "
       "det = -1"},
      {"slightly off rotation",
       [](TsaiParameters& p) { p.cam_from_world_rotation = 1.001 * Eigen::Matrix3d::Identity(); },
       "rotation: expected an orthonormal matrix with determinant +1, found |R R^T - I| = "
       "0.002, det = 1.003"},
  };
  for (const BadTsaiCase& c : cases) {
    TsaiParameters p = SyntheticParameters(5.720865e-04);
    c.mutate(p);
    const Status status = p.Validate();
    EXPECT_FALSE(status.ok()) << c.name;
    EXPECT_EQ(status.code(), StatusCode::kInvalidInput) << c.name;
    EXPECT_EQ(status.message(), c.message) << c.name;
    const Result<TsaiCamera> cam = TsaiCamera::Create(p);
    EXPECT_FALSE(cam.ok()) << c.name;
    EXPECT_EQ(cam.status().message(), c.message) << c.name;
  }
}

}  // namespace
}  // namespace occmap
