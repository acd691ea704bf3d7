#include "occmap/calib/floor_calibration.h"

#include <fmt/core.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <utility>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "occmap/geometry/homography_camera.h"
#include "occmap/geometry/rotation.h"
#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"
#include "occmap/util/text_lines.h"
#include "occmap/util/yaml_util.h"

namespace occmap {
namespace {

constexpr std::string_view kColumns = "u_px,v_px,x_m,y_m[,label]";

std::vector<std::string_view> SplitCommas(std::string_view line) {
  std::vector<std::string_view> out;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    out.push_back(TrimBlanks(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return out;
}

std::string Where(const FloorPoint& p, size_t index) {
  return p.where.empty() ? fmt::format("point {}", index + 1) : p.where;
}

// sqrt of the eigenvalues of the points' covariance: (across the best line, along it).
std::pair<double, double> Spread(const std::vector<Eigen::Vector2d>& pts) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : pts) mean += p;
  mean /= static_cast<double>(pts.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
  cov /= static_cast<double>(pts.size());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  const Eigen::Vector2d ev = eig.eigenvalues().cwiseMax(0.0);  // ascending
  return {std::sqrt(ev(0)), std::sqrt(ev(1))};
}

// A homography (and a planar pose) needs 4 points with no 3 on a line: true when the largest
// set of points within tol of one line leaves at least 2 points off it. Fills `on_line`.
bool HasGeneralPosition(const std::vector<Eigen::Vector2d>& pts, double tol, std::vector<size_t>* on_line) {
  const size_t n = pts.size();
  size_t best = 0;
  std::vector<size_t> best_set;
  for (size_t a = 0; a < n; ++a) {
    for (size_t b = a + 1; b < n; ++b) {
      const Eigen::Vector2d d = pts[b] - pts[a];
      const double len = d.norm();
      if (len <= tol) continue;
      const Eigen::Vector2d normal(-d.y() / len, d.x() / len);
      std::vector<size_t> set;
      for (size_t c = 0; c < n; ++c) {
        if (std::abs(normal.dot(pts[c] - pts[a])) <= tol) set.push_back(c);
      }
      if (set.size() > best) {
        best = set.size();
        best_set = std::move(set);
      }
    }
  }
  *on_line = best_set;
  return n >= best + 2;
}

Status CheckSpread(std::span<const FloorPoint> points, std::string_view source, bool pixels) {
  std::vector<Eigen::Vector2d> pts;
  for (const auto& p : points) pts.push_back(pixels ? p.pixel : p.floor_m);
  const auto [across, along] = Spread(pts);
  const char* what = pixels ? "pixels" : "floor points";
  const char* unit = pixels ? "px" : "m";
  if (!(along > 0) || across < 0.01 * along) {
    return InvalidInput(fmt::format(
        "{}: the {} lie on one line ({:.3g} {} across it, {:.3g} {} along it): a floor calibration needs "
        "points spread over an area, 4 of them with no 3 on a line",
        source, what, across, unit, along, unit));
  }
  // The pair search is cubic; beyond a few hundred points the line fit above suffices.
  if (pts.size() <= 300) {
    std::vector<size_t> on_line;
    const double tol = 0.01 * along;
    if (!HasGeneralPosition(pts, tol, &on_line)) {
      std::string list;
      for (size_t i = 1; i < on_line.size(); ++i) list += (i > 1 ? ", " : "") + Where(points[on_line[i]], on_line[i]);
      return InvalidInput(fmt::format(
          "{}: this {} lies on one line with {} (within {:.3g} {}) and at most one point is off that line: a "
          "floor calibration needs 4 points with no 3 on a line",
          Where(points[on_line[0]], on_line[0]), pixels ? "pixel" : "floor point", list, tol, unit));
    }
  }
  return Status::Ok();
}

// The camera of `intr` at the pose OpenCV found (rvec, tvec: cam_from_world).
Result<PinholeParameters> WithPose(const CameraIntrinsics& intr, ImageSize size, const cv::Mat& rvec,
                                   const cv::Mat& tvec) {
  PinholeParameters p = intr.AsPinhole();
  p.image_size = size;
  p.cam_from_world_rotation = RotationFromRodrigues({rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2)});
  p.cam_from_world_translation_m = {tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)};
  OCCMAP_RETURN_IF_ERROR(p.Validate().WithContext("floor points: the pose found"));
  return p;
}

struct LensFit {
  CameraIntrinsics intrinsics;
  cv::Mat rvec, tvec;
  double rms_px = 0;
  bool holds_over_image = false;
};

// True when every pixel of the image has a ray: the radial polynomial still increases at the
// image's corners (a fit can bend it back inside the picture, where nothing constrains it).
bool DistortionHoldsOverImage(const CameraIntrinsics& in) {
  auto cam = PinholeCamera::Create(in.AsPinhole());
  if (!cam.ok()) return false;
  const double w = in.image_size.width - 1, h = in.image_size.height - 1;
  for (const Eigen::Vector2d& c : {Eigen::Vector2d(0, 0), Eigen::Vector2d(w, 0), Eigen::Vector2d(0, h),
                                   Eigen::Vector2d(w, h)}) {
    if (cam->Undistort(c).outcome != UndistortOutcome::kConverged) return false;
  }
  return true;
}

// One planar view calibrates a camera when the principal point is held at the image's centre
// and fx = fy (Zhang's constraints leave one unknown): cv::calibrateCamera on the floor points,
// started from horizontal fields of view of 50, 90 and 130 degrees; the lowest RMS wins, one
// whose distortion holds over the whole picture before any other.
Result<LensFit> FitLensAndPose(const std::vector<cv::Point3d>& world, const std::vector<cv::Point2d>& image,
                               ImageSize size) {
  std::vector<std::vector<cv::Point3f>> object(1);
  std::vector<std::vector<cv::Point2f>> pixels(1);
  for (const auto& w : world) object[0].emplace_back(static_cast<float>(w.x), static_cast<float>(w.y), 0.f);
  for (const auto& p : image) pixels[0].emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  const int flags = cv::CALIB_USE_INTRINSIC_GUESS | cv::CALIB_FIX_PRINCIPAL_POINT | cv::CALIB_FIX_ASPECT_RATIO |
                    cv::CALIB_ZERO_TANGENT_DIST | cv::CALIB_FIX_K3;
  const cv::TermCriteria stop(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 200, 1e-12);
  std::optional<LensFit> best;
  // k1 and k2 follow a wide lens; from noisy points k2 sometimes bends the lens back inside the
  // picture, where k1 alone (a little less exact) holds.
  for (const int model_flags : {flags, flags | cv::CALIB_FIX_K2})
  for (double fov_deg = 50; fov_deg <= 130; fov_deg += 40) {
    const double f = 0.5 * size.width / std::tan(0.5 * fov_deg * std::numbers::pi / 180.0);
    cv::Mat k = (cv::Mat_<double>(3, 3) << f, 0, (size.width - 1) / 2.0, 0, f, (size.height - 1) / 2.0, 0, 0, 1);
    cv::Mat dist = cv::Mat::zeros(1, 5, CV_64F);
    std::vector<cv::Mat> rvecs, tvecs;
    double rms = 0;
    try {
      rms = cv::calibrateCamera(object, pixels, cv::Size(size.width, size.height), k, dist, rvecs, tvecs, model_flags,
                              stop);
    } catch (const cv::Exception&) {
      continue;  // this start did not converge; the others may
    }
    LensFit fit;
    fit.intrinsics.image_size = size;
    fit.intrinsics.fx_px = k.at<double>(0, 0);
    fit.intrinsics.fy_px = k.at<double>(1, 1);
    fit.intrinsics.cx_px = k.at<double>(0, 2);
    fit.intrinsics.cy_px = k.at<double>(1, 2);
    for (int i = 0; i < 5; ++i) fit.intrinsics.distortion[i] = dist.at<double>(i);
    if (!std::isfinite(rms) || !(fit.intrinsics.fx_px > 0)) continue;
    fit.rvec = rvecs[0];
    fit.tvec = tvecs[0];
    fit.rms_px = rms;
    fit.holds_over_image = DistortionHoldsOverImage(fit.intrinsics);
    // A lens that holds over the whole picture first, then the lower RMS.
    if (!best || std::pair(!fit.holds_over_image, rms) < std::pair(!best->holds_over_image, best->rms_px)) best = fit;
  }
  if (!best) return InvalidInput("floor points: no focal length and distortion fit them (cv::calibrateCamera failed)");
  return *best;
}

// The model alone (no errors, no checks): the pose with intrinsics, the lens and pose, or a
// floor homography, as the options say.
Result<FloorCalibration> FitModel(std::span<const FloorPoint> points, const FloorCalibrationOptions& options) {
  const ImageSize size = options.image_size;
  std::vector<cv::Point2d> image_pts;
  std::vector<cv::Point3d> world_pts;
  std::vector<cv::Point2d> floor_pts;
  for (const FloorPoint& p : points) {
    image_pts.emplace_back(p.pixel.x(), p.pixel.y());
    world_pts.emplace_back(p.floor_m.x(), p.floor_m.y(), 0.0);
    floor_pts.emplace_back(p.floor_m.x(), p.floor_m.y());
  }
  FloorCalibration cal;
  cal.image_size = size;
  try {
    if (options.intrinsics) {
      const CameraIntrinsics intr = options.intrinsics->image_size == size ? *options.intrinsics
                                                                           : options.intrinsics->Resized(size);
      cv::Mat k = (cv::Mat_<double>(3, 3) << intr.fx_px, intr.skew_px, intr.cx_px, 0, intr.fy_px, intr.cy_px, 0, 0, 1);
      cv::Mat dist(1, 5, CV_64F);
      for (int i = 0; i < 5; ++i) dist.at<double>(i) = intr.distortion[i];
      cv::Mat rvec, tvec;
      // IPPE: the pose of a plane, exact for 4 points; LM then minimises the pixel error.
      if (!cv::solvePnP(world_pts, image_pts, k, dist, rvec, tvec, false, cv::SOLVEPNP_IPPE)) {
        return InvalidInput("floor points: no camera pose fits them (solvePnP failed)");
      }
      cv::solvePnPRefineLM(world_pts, image_pts, k, dist, rvec, tvec);
      OCCMAP_ASSIGN_OR_RETURN(PinholeParameters p, WithPose(intr, size, rvec, tvec));
      cal.pinhole = p;
    } else if (options.fit_lens) {
      if (points.size() < kLensMinPoints) {
        return InvalidInput(fmt::format("floor points: fitting the lens (focal length, distortion) with the pose "
                                        "needs at least {} points, found {}", kLensMinPoints, points.size()));
      }
      OCCMAP_ASSIGN_OR_RETURN(LensFit fit, FitLensAndPose(world_pts, image_pts, size));
      OCCMAP_ASSIGN_OR_RETURN(PinholeParameters p, WithPose(fit.intrinsics, size, fit.rvec, fit.tvec));
      cal.pinhole = p;
      cal.lens_fitted = true;
      if (!fit.holds_over_image) {
        cal.warnings.push_back(
            "the fitted lens distortion folds back before the picture's corners, whose pixels get no floor "
            "position: add floor points nearer the picture's edges and corners, or give the camera intrinsics "
            "from a board");
      }
    } else {
      cv::Mat h = cv::findHomography(image_pts, floor_pts, 0);
      if (h.empty()) return InvalidInput("floor points: no homography fits them (findHomography failed)");
      Eigen::Matrix3d hm;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) hm(r, c) = h.at<double>(r, c);
      }
      if (!hm.allFinite()) return InvalidInput("floor points: the homography found is not finite");
      cal.floor_from_image = hm;
    }
  } catch (const cv::Exception& e) {
    return InvalidInput(fmt::format("floor points: OpenCV failed: {}", e.err));
  }
  return cal;
}

// The fewest points whose fit still has one to spare: a point left out must be predicted by a
// fit that could disagree with the others (4 points fit a homography exactly).
size_t RedundantPoints(const FloorCalibrationOptions& o) {
  if (o.intrinsics) return 4;   // 8 equations, 6 unknowns
  if (o.fit_lens) return kLensMinPoints;  // 12 equations, 9 unknowns
  return 5;                     // 10 equations, 8 unknowns
}

// The RMS of `points[subset]` and the error of `points[left_out]` under the fit of the subset;
// nullopt when the subset cannot be fitted (three on a line, a failed fit).
struct LeftOut {
  double error_px = 0, rms_px = 0, rms_floor_m = 0;
};
std::optional<LeftOut> FitWithout(std::span<const FloorPoint> points, const std::vector<size_t>& subset,
                                  size_t left_out, const FloorCalibrationOptions& options) {
  std::vector<FloorPoint> sub;
  for (size_t i : subset) sub.push_back(points[i]);
  if (!ValidateFloorPoints(sub, "").ok()) return std::nullopt;
  auto fit = FitModel(sub, options);
  if (!fit.ok()) return std::nullopt;
  auto model = fit->Model();
  if (!model.ok()) return std::nullopt;
  MeasureFloorErrors(**model, sub, *fit);
  LeftOut out;
  out.rms_px = fit->rms_reprojection_px;
  out.rms_floor_m = fit->rms_floor_m;
  FloorCalibration one;
  MeasureFloorErrors(**model, points.subspan(left_out, 1), one);
  out.error_px = one.errors[0].reprojection_px;
  if (!std::isfinite(out.rms_px)) return std::nullopt;
  return out;
}

// The points of `subset` ordered by their error under the fit of the whole subset, largest
// first; empty when the subset cannot be fitted.
std::vector<size_t> ByErrorUnderFit(std::span<const FloorPoint> points, const std::vector<size_t>& subset,
                                    const FloorCalibrationOptions& options) {
  std::vector<FloorPoint> sub;
  for (size_t i : subset) sub.push_back(points[i]);
  auto fit = FitModel(sub, options);
  if (!fit.ok()) return {};
  auto model = fit->Model();
  if (!model.ok()) return {};
  MeasureFloorErrors(**model, sub, *fit);
  std::vector<size_t> order(subset.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return fit->errors[a].reprojection_px > fit->errors[b].reprojection_px;
  });
  return order;
}

// Backward elimination by leave-one-out: each round, every remaining point is left out in turn;
// the one whose absence leaves the best fit is an outlier when that fit puts it beyond the
// threshold. One wrong point spoils every fit it is part of, so only the fit without it is clean.
// Past kLeaveOneOutAll points a round leaves out only the kLeaveOneOutCandidates worst under
// the fit of all: there one point barely moves the fit, so a wrong one stands out in it, and
// leaving every point out (a fit each, a round per outlier) grows with the cube of the count.
constexpr size_t kLeaveOneOutAll = 40;
constexpr size_t kLeaveOneOutCandidates = 12;
void CheckOutliers(std::span<const FloorPoint> points, const FloorCalibrationOptions& options,
                   FloorCalibration& cal) {
  const size_t need = RedundantPoints(options);
  cal.predicted_error_px.assign(points.size(), std::nan(""));
  cal.rms_without_outliers_px = cal.rms_reprojection_px;
  cal.rms_floor_without_outliers_m = cal.rms_floor_m;
  if (points.size() < need + 1) {
    cal.outlier_note = fmt::format("with {} points a wrong one cannot be told apart ({} or more tell it)",
                                   points.size(), need + 1);
    return;
  }
  cal.outliers_checked = true;
  // A fit that all its points agree with (RMS within a quarter of the outlier threshold) has no
  // wrong point to find: a point at the edge of the points' spread, left out, is only
  // extrapolated to (14 px for a correct corner point of a 1 px fit).
  const double consistent_px = options.outlier_min_px / 4;
  if (cal.rms_reprojection_px <= consistent_px) return;
  std::vector<size_t> active(points.size());
  for (size_t i = 0; i < active.size(); ++i) active[i] = i;
  // At most a third of the points are called wrong: beyond that the rest are no majority.
  while (active.size() >= need + 1 && 3 * (cal.outliers.size() + 1) <= points.size()) {
    std::optional<std::pair<size_t, LeftOut>> best;  // position in active, its fit
    std::vector<size_t> candidates;                  // positions in active
    if (active.size() > kLeaveOneOutAll) {
      candidates = ByErrorUnderFit(points, active, options);
      if (candidates.size() > kLeaveOneOutCandidates) candidates.resize(kLeaveOneOutCandidates);
    } else {
      for (size_t k = 0; k < active.size(); ++k) candidates.push_back(k);
    }
    for (size_t k : candidates) {
      std::vector<size_t> subset = active;
      subset.erase(subset.begin() + static_cast<ptrdiff_t>(k));
      const auto r = FitWithout(points, subset, active[k], options);
      if (!r) continue;
      cal.predicted_error_px[active[k]] = r->error_px;  // the last round's, free of the outliers found
      if (!best || r->rms_px < best->second.rms_px) best = {k, *r};
    }
    if (!best) break;
    const LeftOut& r = best->second;
    const double threshold = std::max(options.outlier_min_px, options.outlier_ratio * r.rms_px);
    if (!(r.error_px > threshold)) break;
    const size_t index = active[best->first];
    cal.predicted_error_px[index] = r.error_px;
    cal.outliers.push_back(index);
    cal.rms_without_outliers_px = r.rms_px;
    cal.rms_floor_without_outliers_m = r.rms_floor_m;
    active.erase(active.begin() + static_cast<ptrdiff_t>(best->first));
    if (r.rms_px <= consistent_px) break;
  }
}

}  // namespace

Status CameraIntrinsics::Validate() const { return AsPinhole().Validate().WithContext("intrinsics"); }

PinholeParameters CameraIntrinsics::AsPinhole() const {
  PinholeParameters p;
  p.image_size = image_size;
  p.fx_px = fx_px;
  p.fy_px = fy_px;
  p.cx_px = cx_px;
  p.cy_px = cy_px;
  p.skew_px = skew_px;
  p.distortion = distortion;
  return p;
}

CameraIntrinsics CameraIntrinsics::Resized(ImageSize new_size) const { return ResizedIntrinsics(*this, new_size); }

Result<std::vector<FloorPoint>> ParseFloorPoints(std::string_view text, const std::string& file_name) {
  std::vector<FloorPoint> points;
  // Spreadsheets write "CSV UTF-8" with a byte-order mark.
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  bool seen_data = false;
  OCCMAP_RETURN_IF_ERROR(ForEachTextLine(text, [&](int64_t line_no, std::string_view line) -> Status {
    const std::string where = fmt::format("{}:{}", file_name, line_no);
    const std::vector<std::string_view> cols = SplitCommas(line);
    if (!seen_data && !cols.empty() && !ParseFiniteDouble(cols[0]) && cols[0] == "u_px") {
      // The header line: the columns' names, in order.
      const bool ok = (cols.size() == 4 || cols.size() == 5) && cols[1] == "v_px" && cols[2] == "x_m" &&
                      cols[3] == "y_m" && (cols.size() == 4 || cols[4] == "label");
      if (!ok) {
        return InvalidInput(fmt::format("{}: header: expected '{}', found '{}'", where, kColumns, line));
      }
      seen_data = true;
      return Status::Ok();
    }
    seen_data = true;
    if (cols.size() != 4 && cols.size() != 5) {
      return InvalidInput(fmt::format("{}: expected 4 or 5 comma-separated columns ({}), found {}", where, kColumns,
                                      cols.size()));
    }
    static constexpr const char* kNames[] = {"u_px", "v_px", "x_m", "y_m"};
    double v[4];
    for (int i = 0; i < 4; ++i) {
      const auto d = ParseFiniteDouble(cols[i]);
      if (!d) {
        return InvalidInput(fmt::format("{}: {} (column {}): expected a finite number, found '{}'", where, kNames[i],
                                        i + 1, cols[i]));
      }
      v[i] = *d;
    }
    FloorPoint p;
    p.pixel = {v[0], v[1]};
    p.floor_m = {v[2], v[3]};
    if (cols.size() == 5) p.label = std::string(cols[4]);
    p.where = where;
    points.push_back(std::move(p));
    return Status::Ok();
  }));
  OCCMAP_RETURN_IF_ERROR(ValidateFloorPoints(points, file_name));
  return points;
}

Result<std::vector<FloorPoint>> ReadFloorPoints(const std::filesystem::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
  return ParseFloorPoints(text, path.string());
}

Status ValidateFloorPoints(std::span<const FloorPoint> points, std::string_view source) {
  if (points.size() < 4) {
    return InvalidInput(fmt::format("{}: expected at least 4 floor points (pixel and floor position), found {}",
                                    source, points.size()));
  }
  for (size_t i = 0; i < points.size(); ++i) {
    if (!points[i].pixel.allFinite() || !points[i].floor_m.allFinite()) {
      return InvalidInput(fmt::format("{}: expected finite numbers", Where(points[i], i)));
    }
    for (size_t j = 0; j < i; ++j) {
      if (points[i].pixel == points[j].pixel) {
        return InvalidInput(fmt::format("{}: pixel ({}, {}) is given twice (also {})", Where(points[i], i),
                                        points[i].pixel.x(), points[i].pixel.y(), Where(points[j], j)));
      }
      if (points[i].floor_m == points[j].floor_m) {
        return InvalidInput(fmt::format("{}: floor point ({}, {}) m is given twice (also {})", Where(points[i], i),
                                        points[i].floor_m.x(), points[i].floor_m.y(), Where(points[j], j)));
      }
    }
  }
  OCCMAP_RETURN_IF_ERROR(CheckSpread(points, source, /*pixels=*/false));
  return CheckSpread(points, source, /*pixels=*/true);
}

Status FloorCalibrationOptions::Validate() const {
  if (image_size.width <= 0 || image_size.height <= 0) {
    return InvalidInput(fmt::format("image size: expected positive, found {}x{}", image_size.width, image_size.height));
  }
  if (intrinsics) {
    OCCMAP_RETURN_IF_ERROR(intrinsics->Validate());
    const double a0 = static_cast<double>(intrinsics->image_size.width) / intrinsics->image_size.height;
    const double a1 = static_cast<double>(image_size.width) / image_size.height;
    if (std::abs(a0 / a1 - 1) > 0.01) {
      return InvalidInput(fmt::format("intrinsics: calibrated for {}x{}, the image is {}x{} (another aspect ratio)",
                                      intrinsics->image_size.width, intrinsics->image_size.height, image_size.width,
                                      image_size.height));
    }
  }
  if (!(max_outside_px >= 0)) return InvalidInput(fmt::format("max_outside_px: expected >= 0, found {}", max_outside_px));
  return Status::Ok();
}

Result<std::unique_ptr<CameraModel>> FloorCalibration::Model() const {
  if (pinhole) {
    OCCMAP_ASSIGN_OR_RETURN(PinholeCamera cam, PinholeCamera::Create(*pinhole));
    return std::unique_ptr<CameraModel>(std::make_unique<PinholeCamera>(std::move(cam)));
  }
  if (floor_from_image) {
    OCCMAP_ASSIGN_OR_RETURN(HomographyCamera cam, HomographyCamera::Create(*floor_from_image, image_size));
    return std::unique_ptr<CameraModel>(std::make_unique<HomographyCamera>(std::move(cam)));
  }
  return Internal("floor calibration without a model");
}

void MeasureFloorErrors(const CameraModel& camera, std::span<const FloorPoint> points, FloorCalibration& out) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  out.errors.clear();
  double sum_px2 = 0, sum_m2 = 0;
  out.max_reprojection_px = out.max_floor_m = 0;
  for (const FloorPoint& p : points) {
    FloorPointError e;
    const auto px = camera.Project({p.floor_m.x(), p.floor_m.y(), 0.0});
    if (px) {
      e.reprojected_px = *px;
      e.reprojection_px = (*px - p.pixel).norm();
    } else {
      e.reprojected_px = Eigen::Vector2d::Constant(std::nan(""));
      e.reprojection_px = kInf;
    }
    e.floor_from_pixel_m = camera.PixelToPlane(p.pixel, 0.0);
    e.floor_m = e.floor_from_pixel_m ? (*e.floor_from_pixel_m - p.floor_m).norm() : kInf;
    sum_px2 += e.reprojection_px * e.reprojection_px;
    sum_m2 += e.floor_m * e.floor_m;
    out.max_reprojection_px = std::max(out.max_reprojection_px, e.reprojection_px);
    out.max_floor_m = std::max(out.max_floor_m, e.floor_m);
    out.errors.push_back(e);
  }
  const double n = static_cast<double>(std::max<size_t>(points.size(), 1));
  out.rms_reprojection_px = std::sqrt(sum_px2 / n);
  out.rms_floor_m = std::sqrt(sum_m2 / n);
}

Result<FloorCalibration> CalibrateFromFloorPoints(std::span<const FloorPoint> points,
                                                  const FloorCalibrationOptions& options) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  OCCMAP_RETURN_IF_ERROR(ValidateFloorPoints(points, "floor points"));
  const ImageSize size = options.image_size;
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d& px = points[i].pixel;
    const double m = options.max_outside_px + 0.5;
    if (px.x() < -m || px.y() < -m || px.x() > size.width - 1 + m || px.y() > size.height - 1 + m) {
      return InvalidInput(fmt::format("{}: pixel ({}, {}) is outside the {}x{} image", Where(points[i], i), px.x(),
                                      px.y(), size.width, size.height));
    }
  }
  OCCMAP_ASSIGN_OR_RETURN(FloorCalibration cal, FitModel(points, options));
  if (cal.pinhole) {
    const PinholeParameters& p = *cal.pinhole;
    const Eigen::Vector3d centre = -p.cam_from_world_rotation.transpose() * p.cam_from_world_translation_m;
    if (centre.z() < 0) {
      cal.warnings.push_back(fmt::format(
          "the camera comes out below the floor (z = {:.2f} m): the floor points' x and y axes are left-handed "
          "seen from above; swap x and y (or negate one) so that z points up, or planes above the floor "
          "(people's heights) will be wrong",
          centre.z()));
    }
  }
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<CameraModel> model, cal.Model());
  MeasureFloorErrors(*model, points, cal);
  for (size_t i = 0; i < points.size(); ++i) {
    if (!std::isfinite(cal.errors[i].floor_m) || !std::isfinite(cal.errors[i].reprojection_px)) {
      cal.warnings.push_back(fmt::format("{}: the new model does not see this point on the floor", Where(points[i], i)));
    }
  }
  if (options.check_outliers) CheckOutliers(points, options, cal);
  return cal;
}

std::vector<std::string> CalibrationConcerns(const FloorCalibration& cal, std::span<const FloorPoint> points,
                                             double max_rms_px) {
  std::vector<std::string> out;
  for (size_t i : cal.outliers) {
    if (i >= points.size()) continue;
    const FloorPoint& p = points[i];
    out.push_back(fmt::format(
        "{}{}: pixel ({:.1f}, {:.1f}) for floor ({:.3f}, {:.3f}) m is {:.1f} px from where the other points put it "
        "(a mistyped position, x and y swapped, or another mark clicked?)",
        Where(p, i), p.label.empty() ? "" : " (" + p.label + ")", p.pixel.x(), p.pixel.y(), p.floor_m.x(),
        p.floor_m.y(), cal.predicted_error_px[i]));
  }
  if (!(cal.rms_reprojection_px <= max_rms_px)) {
    std::string without;
    if (!cal.outliers.empty()) {
      without = fmt::format("; without the {} named: {:.2f} px", cal.outliers.size() == 1 ? "point" : "points",
                            cal.rms_without_outliers_px);
    }
    out.push_back(fmt::format("reprojection RMS {:.2f} px is over {:.2f} px{}", cal.rms_reprojection_px, max_rms_px,
                              without));
  }
  return out;
}

std::string HomographyCalibrationYaml(const Eigen::Matrix3d& h, ImageSize size) {
  auto row = [&](int r) { return fmt::format("[{:.17g}, {:.17g}, {:.17g}]", h(r, 0), h(r, 1), h(r, 2)); };
  return fmt::format("{{format: homography, floor_from_image: [{}, {}, {}], unit: m, image_size: [{}, {}]}}", row(0),
                     row(1), row(2), size.width, size.height);
}

}  // namespace occmap
