// Calibration of one camera from floor points: pixels whose floor position (metres, z = 0) is
// known. With the camera's intrinsics the result is a pinhole camera (a planar-aware pose,
// cv::SOLVEPNP_IPPE, refined by Levenberg-Marquardt); without them a floor homography. Every
// point gets its reprojection error (world point -> pixel, pixels) and its floor error (pixel
// back-projected to the floor with the new model, metres). No file I/O happens here, so that
// the command line (`occmap calibrate`) and a web page can both call it.
//
// Floor-point files (CSV, docs/formats.md): one point a line, `u_px,v_px,x_m,y_m[,label]`,
// an optional header line naming those columns, `#` comments and blank lines ignored. Pixels
// in occmap's convention (geometry/camera_model.h: pixel (c, r) has its centre at (c, r)).
//
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<FloorPoint> pts, ReadFloorPoints("c1_points.csv"));
//   FloorCalibrationOptions o;  o.image_size = {1920, 1080};  o.intrinsics = intr;  // optional
//   OCCMAP_ASSIGN_OR_RETURN(FloorCalibration cal, CalibrateFromFloorPoints(pts, o));
//   fmt::print("RMS {:.2f} px, floor {:.3f} m\n", cal.rms_reprojection_px, cal.rms_floor_m);
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/geometry/camera_model.h"
#include "occmap/geometry/pinhole_camera.h"
#include "occmap/util/status.h"

namespace occmap {

// A camera's intrinsics: OpenCV's camera matrix and k1 k2 p1 p2 k3, for images of image_size.
struct CameraIntrinsics {
  ImageSize image_size;
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0, skew_px = 0;
  std::array<double, 5> distortion = {0, 0, 0, 0, 0};

  Status Validate() const;
  // A pinhole camera with these intrinsics at the world's origin (identity pose).
  PinholeParameters AsPinhole() const;
  // The same camera for images resized to new_size (u' = (u + 0.5) s - 0.5).
  CameraIntrinsics Resized(ImageSize new_size) const;
};

struct FloorPoint {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();    // (u, v), the image's pixel convention
  Eigen::Vector2d floor_m = Eigen::Vector2d::Zero();  // world (x, y) on the floor z = 0
  std::string label;                                  // optional, for reports
  std::string where;  // "file:line" in messages; empty: "point <i>" (1-based)
};

// Parses a floor-point file's text; `file_name` names it in messages. Checks every line (4 or 5
// columns, finite numbers) and the set (ValidateFloorPoints).
Result<std::vector<FloorPoint>> ParseFloorPoints(std::string_view text, const std::string& file_name);
Result<std::vector<FloorPoint>> ReadFloorPoints(const std::filesystem::path& path);

// At least 4 points, finite, no pixel or floor position twice, the floor points and the pixels
// each spread over an area (not on one line; with 4 points no 3 on a line). `source` ("c1.csv")
// starts messages that concern the whole set.
Status ValidateFloorPoints(std::span<const FloorPoint> points, std::string_view source);

struct FloorCalibrationOptions {
  ImageSize image_size;                         // the camera's images (required)
  std::optional<CameraIntrinsics> intrinsics;   // with: pinhole; without: floor homography
  // Without intrinsics: fit the lens too (a pinhole, not a homography): the focal length
  // (fx = fy), radial distortion k1 and k2 and the pose, the principal point at the image's
  // centre. Needs kLensMinPoints points (8 or more spread over the picture are better); wide
  // lenses, whose distortion a homography cannot follow, fit to the pixels' noise this way.
  bool fit_lens = false;
  // Pixels may lie this far outside the image (points clicked on its border).
  double max_outside_px = 2.0;
  // Leave-one-out check (FloorCalibration::outliers): a point is an outlier when the others,
  // fitted without it, put it more than max(outlier_min_px, outlier_ratio x their own RMS) away.
  bool check_outliers = true;
  // Clean points (0.5 px noise, 8 of them) are predicted within 4.5 px at the view's edges,
  // mistyped ones 80 to 400 px off (floor_calibration_test.cc).
  double outlier_min_px = 8.0;
  double outlier_ratio = 10.0;

  Status Validate() const;
};

inline constexpr size_t kLensMinPoints = 6;

struct FloorPointError {
  Eigen::Vector2d reprojected_px = Eigen::Vector2d::Zero();  // the world point through the model
  double reprojection_px = 0;                                // |reprojected - pixel|
  std::optional<Eigen::Vector2d> floor_from_pixel_m;         // the pixel back to the floor
  double floor_m = 0;  // |floor_from_pixel - world point|; +inf when the pixel has no floor point
};

struct FloorCalibration {
  ImageSize image_size;
  // Exactly one of the two.
  std::optional<PinholeParameters> pinhole;          // with intrinsics
  std::optional<Eigen::Matrix3d> floor_from_image;   // without: (u, v, 1) -> (x, y, w), metres
  // fit_lens: the pinhole's focal length and distortion k1, k2 came from the points.
  bool lens_fitted = false;

  std::vector<FloorPointError> errors;  // one per point, in the input's order
  double rms_reprojection_px = 0, max_reprojection_px = 0;
  double rms_floor_m = 0, max_floor_m = 0;
  // Things a person should know that do not make the result wrong (e.g. a camera below z = 0).
  std::vector<std::string> warnings;

  // The leave-one-out check (robust to a mistyped point: x and y swapped, a wrong mark clicked):
  // points removed one at a time, each time the one whose removal leaves the others fitting
  // best, while the others put it beyond the options' threshold. The fit above still uses every
  // point (the file is the user's); these say which to correct.
  bool outliers_checked = false;          // false: too few points to tell (outlier_note says why)
  std::string outlier_note;
  std::vector<size_t> outliers;           // indices into the points, in the order found
  std::vector<double> predicted_error_px; // per point: its error under the fit of the others but
                                          // the outliers (NaN when not left out)
  double rms_without_outliers_px = 0;     // the fit without the outliers: the others' RMS
  double rms_floor_without_outliers_m = 0;

  std::string_view kind() const { return pinhole ? "pinhole" : "homography"; }
  Result<std::unique_ptr<CameraModel>> Model() const;
};

Result<FloorCalibration> CalibrateFromFloorPoints(std::span<const FloorPoint> points,
                                                  const FloorCalibrationOptions& options);

// Why `cal` should not replace a site's calibration: the outliers named ("c1.csv:5 (p6): 215.3 px
// from where the other points put it"), or its RMS over max_rms_px. Empty when neither.
std::vector<std::string> CalibrationConcerns(const FloorCalibration& cal, std::span<const FloorPoint> points,
                                             double max_rms_px);
inline constexpr double kMaxUpdateRmsPx = 4.0;  // `occmap calibrate --update-site`, the page's Save

// Per-point and summary errors of any camera model against the points (the figures above).
void MeasureFloorErrors(const CameraModel& camera, std::span<const FloorPoint> points, FloorCalibration& out);

// The site file's calibration entry for a homography (docs/formats.md), as a YAML flow map:
// {format: homography, floor_from_image: [[...], [...], [...]], unit: m, image_size: [w, h]}.
std::string HomographyCalibrationYaml(const Eigen::Matrix3d& floor_from_image, ImageSize image_size);

}  // namespace occmap
