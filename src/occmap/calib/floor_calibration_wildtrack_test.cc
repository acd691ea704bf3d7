// occmap calibrate's floor-point path on the real WILDTRACK cameras: the annotated people's
// ground positions (annotations_positions/, metres) with the bottom centres of their boxes in
// each view as the pixels, against the dataset's own calibration (intrinsic_zero + extrinsic).
// The box bottoms are where a person's feet are only roughly (the dataset's calibration puts the
// positions 6-7 px from them, median): the figures say how far a calibration from such clicks
// lands from the provided one, not the method's own accuracy (see floor_calibration_test.cc).
#include <gtest/gtest.h>

#include <fmt/core.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <set>

#include "occmap/calib/floor_calibration.h"
#include "occmap/calib/opencv_storage.h"
#include "occmap/util/file_util.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

const char* kCameras[] = {"CVLab1", "CVLab2", "CVLab3", "CVLab4", "IDIAP1", "IDIAP2", "IDIAP3"};

// Floor points of view `view` from the annotation files [first, first + count) (every 5th number).
std::vector<FloorPoint> AnnotatedPoints(const fs::path& dir, int view, int first_file, int files) {
  std::vector<FloorPoint> pts;
  std::set<std::pair<int, int>> seen_pixels;
  std::set<int64_t> seen_positions;
  for (int f = 0; f < files; ++f) {
    const fs::path path = dir / fmt::format("{:08d}.json", (first_file + f) * 5);
    auto text = ReadFileToString(path);
    if (!text.ok()) break;
    const auto people = nlohmann::json::parse(*text);
    for (const auto& person : people) {
      const int64_t pos = person["positionID"].get<int64_t>();
      for (const auto& v : person["views"]) {
        if (v["viewNum"].get<int>() != view) continue;
        const int xmin = v["xmin"], xmax = v["xmax"], ymax = v["ymax"], ymin = v["ymin"];
        // Boxes cut by the image's border or too small to place the feet are left out.
        if (xmin <= 0 || ymin < 0 || xmax >= 1919 || ymax >= 1079 || ymax - ymin < 40) continue;
        const std::pair<int, int> px((xmin + xmax), ymax);
        if (!seen_pixels.insert(px).second || !seen_positions.insert(pos).second) continue;
        FloorPoint p;
        p.pixel = {0.5 * (xmin + xmax), static_cast<double>(ymax)};
        p.floor_m = {0.01 * (-300 + 2.5 * static_cast<double>(pos % 480)),
                     0.01 * (-900 + 2.5 * static_cast<double>(pos / 480))};
        p.where = fmt::format("{} person {}", path.filename().string(), person["personID"].get<int>());
        pts.push_back(p);
      }
    }
  }
  return pts;
}

struct Figures {
  double rms_px = 0;           // the points against the new model
  double provided_rms_px = 0;  // the same points against the provided calibration
  double floor_vs_provided_median_m = 0, floor_vs_provided_p90_m = 0;
  double centre_m = -1;
};

// The new model against the provided one over the floor the points span (25 cm lattice over
// their bounding box): each floor point's pixel in the provided calibration, back-projected.
Figures Compare(const FloorCalibration& cal, const PinholeCamera& provided, const std::vector<FloorPoint>& pts) {
  Figures f;
  f.rms_px = cal.rms_reprojection_px;
  FloorCalibration provided_errors;
  MeasureFloorErrors(provided, pts, provided_errors);
  f.provided_rms_px = provided_errors.rms_reprojection_px;
  const auto model = cal.Model().value();
  Eigen::Vector2d lo = pts[0].floor_m, hi = pts[0].floor_m;
  for (const auto& p : pts) {
    lo = lo.cwiseMin(p.floor_m);
    hi = hi.cwiseMax(p.floor_m);
  }
  std::vector<double> errors;
  for (double x = lo.x(); x <= hi.x(); x += 0.25) {
    for (double y = lo.y(); y <= hi.y(); y += 0.25) {
      const auto px = provided.Project({x, y, 0});
      if (!px || !provided.InImage(*px)) continue;
      const auto back = model->PixelToPlane(*px, 0.0);
      errors.push_back(back ? (*back - Eigen::Vector2d(x, y)).norm() : 1e9);
    }
  }
  std::sort(errors.begin(), errors.end());
  if (!errors.empty()) {
    f.floor_vs_provided_median_m = errors[errors.size() / 2];
    f.floor_vs_provided_p90_m = errors[errors.size() * 9 / 10];
  }
  if (auto c = model->CenterInWorld()) f.centre_m = (*c - *provided.CenterInWorld()).norm();
  return f;
}

TEST(FloorCalibrationWildtrack, AnnotatedFeetAgainstTheProvidedCalibration) {
  OCCMAP_REQUIRE_DATASETS(root);
  const fs::path wt = root / "wildtrack";
  if (!fs::exists(wt / "annotations_positions")) GTEST_SKIP() << "no WILDTRACK annotations under " << wt;
  for (int view = 0; view < 7; ++view) {
    const std::string cam = kCameras[view];
    auto provided_p = ReadOpenCvCalibration(wt / "calibrations/intrinsic_zero" / ("intr_" + cam + ".xml"),
                                            wt / "calibrations/extrinsic" / ("extr_" + cam + ".xml"), 0.01,
                                            ImageSize{1920, 1080});
    ASSERT_TRUE(provided_p.ok()) << provided_p.status().message();
    const PinholeCamera provided = PinholeCamera::Create(*provided_p).value();
    CameraIntrinsics intr;
    intr.image_size = provided_p->image_size;
    intr.fx_px = provided_p->fx_px;
    intr.fy_px = provided_p->fy_px;
    intr.cx_px = provided_p->cx_px;
    intr.cy_px = provided_p->cy_px;
    // One annotated frame (what a person clicks: 10-30 points) and all 400 of them.
    for (int files : {1, 400}) {
      const std::vector<FloorPoint> pts = AnnotatedPoints(wt / "annotations_positions", view, 0, files);
      ASSERT_GE(pts.size(), 4u) << cam;
      FloorCalibrationOptions o;
      o.image_size = intr.image_size;
      o.intrinsics = intr;
      auto pinhole = CalibrateFromFloorPoints(pts, o);
      ASSERT_TRUE(pinhole.ok()) << cam << ": " << pinhole.status().message();
      o.intrinsics.reset();
      auto homography = CalibrateFromFloorPoints(pts, o);
      ASSERT_TRUE(homography.ok()) << cam << ": " << homography.status().message();
      const Figures fp = Compare(*pinhole, provided, pts);
      const Figures fh = Compare(*homography, provided, pts);
      std::printf(
          "wildtrack %s, %3d file(s), %4zu points: provided calibration %.1f px RMS on them; pinhole %.1f px RMS, "
          "floor vs provided median %.3f m p90 %.3f m, centre %.2f m; homography %.1f px, median %.3f m p90 %.3f m\n",
          cam.c_str(), files, pts.size(), fp.provided_rms_px, fp.rms_px, fp.floor_vs_provided_median_m,
          fp.floor_vs_provided_p90_m, fp.centre_m, fh.rms_px, fh.floor_vs_provided_median_m,
          fh.floor_vs_provided_p90_m);
      if (files == 400) {
        // With hundreds of rough clicks the calibration lands near the provided one.
        EXPECT_LE(fp.floor_vs_provided_median_m, 0.15) << cam;
        EXPECT_LE(fp.rms_px, fp.provided_rms_px * 1.05) << cam;  // it fits these points at least as well
      }
    }
  }
}

}  // namespace
}  // namespace occmap
