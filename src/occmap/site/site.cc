#include "occmap/site/site.h"

#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <set>

#include "occmap/calib/forward_sign.h"
#include "occmap/calib/gopro_json.h"
#include "occmap/calib/opencv_storage.h"
#include "occmap/calib/tsai_yaml.h"
#include "occmap/calib/units.h"
#include "occmap/geometry/homography_camera.h"
#include "occmap/geometry/pinhole_camera.h"
#include "occmap/geometry/tsai_camera.h"
#include "occmap/io/frame_times.h"
#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"
#include "occmap/util/text_guard.h"
#include "occmap/util/image_io.h"
#include "occmap/util/yaml_util.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

constexpr int kMaxImageSide = 16384;

struct PathContext {
  fs::path site_dir;
  fs::path data_root;
};

// Wraps an error from a reader (which names its own file) with the YAML location.
Status At(const YamlField& field, const Status& status) {
  if (status.ok()) return status;
  return Status(status.code(), fmt::format("{}: {}", field.Where(), status.message()));
}

Result<fs::path> GetPath(const YamlField& parent, std::string_view key, const PathContext& ctx, bool must_exist = true) {
  OCCMAP_ASSIGN_OR_RETURN(YamlField f, parent.Get(key));
  OCCMAP_ASSIGN_OR_RETURN(std::string text, f.AsString());
  if (text.empty()) return f.Error("expected a path, found an empty text");
  const fs::path path = ResolvePath(ctx.data_root, text);
  std::error_code ec;
  if (must_exist && !fs::exists(path, ec)) {
    return Status(StatusCode::kNotFound, fmt::format("{}: file not found: '{}'", f.Where(), path.string()));
  }
  return path;
}

Result<ImageSize> GetImageSize(const YamlField& field) {
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, field.AsDoubles(2));
  for (double d : v) {
    if (d != std::floor(d) || d < 1 || d > kMaxImageSide) {
      return field.Error(fmt::format("expected [width, height] in whole pixels 1..{}, found [{}, {}]", kMaxImageSide,
                                     v[0], v[1]));
    }
  }
  return ImageSize{static_cast<int>(v[0]), static_cast<int>(v[1])};
}

Result<FloorGrid> ParseFloor(const YamlField& floor, double* plane_height_m) {
  OCCMAP_RETURN_IF_ERROR(floor.CheckKeys({"origin_m", "cell_size_m", "cells", "size_m", "plane_height_m"}));
  OCCMAP_ASSIGN_OR_RETURN(FloorGrid g, ParseFloorGrid(floor));
  OCCMAP_ASSIGN_OR_RETURN(*plane_height_m, floor.GetDouble("plane_height_m", 0.0));
  return g;
}

// Floor points for the forward-sign vote: a lattice over the grid.
std::vector<Eigen::Vector3d> FloorSamples(const FloorGrid& g, double z) {
  std::vector<Eigen::Vector3d> pts;
  constexpr int kSteps = 40;
  for (int i = 0; i <= kSteps; ++i) {
    for (int j = 0; j <= kSteps; ++j) {
      pts.emplace_back(g.origin_x_m + g.size_x_m() * i / kSteps, g.origin_y_m + g.size_y_m() * j / kSteps, z);
    }
  }
  return pts;
}

// Text for a message: cut (a 10 MB name was echoed whole), control bytes, DEL and bytes that
// are not UTF-8 as \xNN (a NUL or an escape sequence would cut or garble the terminal line).
std::string Printable(std::string_view whole) {
  const std::string cut = Excerpt(whole);
  const std::string_view text = cut;
  std::string out;
  for (size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    const size_t len = c < 0x80 ? 1 : c >= 0xF0 ? 4 : c >= 0xE0 ? 3 : 2;
    const bool printable = len == 1 ? c >= 0x20 && c != 0x7F
                                    : i + len <= text.size() && !FindInvalidUtf8(text.substr(i, len)).has_value();
    if (printable) {
      out += text.substr(i, len);
      i += len;
    } else {
      out += fmt::format("\\x{:02x}", c);
      ++i;
    }
  }
  return out;
}

// Whether any point of a kGridSamples^2 lattice over the grid lands in the image (and on the mask's
// floor pixels). Denser than the forward-sign vote: a camera seeing a corner of a big grid passes.
constexpr int kGridSamples = 101;
bool SeesTheGrid(const CameraModel& camera, const Image<uint8_t>& mask, const FloorGrid& g, double z) {
  for (int i = 0; i < kGridSamples; ++i) {
    for (int j = 0; j < kGridSamples; ++j) {
      const Eigen::Vector3d p(g.origin_x_m + g.size_x_m() * i / (kGridSamples - 1),
                              g.origin_y_m + g.size_y_m() * j / (kGridSamples - 1), z);
      const auto px = camera.Project(p);
      if (!px || !camera.InImage(*px)) continue;
      if (mask.empty()) return true;
      const int c = std::clamp(static_cast<int>(std::lround(px->x())), 0, mask.width() - 1);
      const int r = std::clamp(static_cast<int>(std::lround(px->y())), 0, mask.height() - 1);
      if (mask.row(r)[c] != 0) return true;
    }
  }
  return false;
}

Result<std::unique_ptr<CameraModel>> ParsePinholeOptions(const YamlField& calib, PinholeParameters p,
                                                         const FloorGrid& grid, double plane_z) {
  OCCMAP_ASSIGN_OR_RETURN(bool ignore_distortion, calib.GetBool("ignore_distortion", false));
  if (ignore_distortion) p.distortion = {0, 0, 0, 0, 0};
  OCCMAP_ASSIGN_OR_RETURN(std::string forward, calib.GetString("forward", "auto"));
  if (forward == "auto") {
    auto sign = ChooseForwardSign(p, FloorSamples(grid, plane_z));
    if (!sign.ok()) return At(calib, sign.status());
    p.forward_sign = *sign;
  } else if (forward == "+z") {
    p.forward_sign = +1;
  } else if (forward == "-z") {
    p.forward_sign = -1;
  } else {
    return calib.Find("forward")->Error(fmt::format("expected auto, +z or -z, found '{}'", forward));
  }
  auto cam = PinholeCamera::Create(p);
  if (!cam.ok()) return At(calib, cam.status());
  return std::unique_ptr<CameraModel>(std::make_unique<PinholeCamera>(std::move(cam).value()));
}

Status ParseCalibration(const YamlField& calib, const PathContext& ctx, const FloorGrid& grid, double plane_z,
                        SiteCamera& cam) {
  OCCMAP_ASSIGN_OR_RETURN(std::string format, calib.GetString("format"));
  cam.calibration_format = format;
  std::optional<ImageSize> declared_size;
  if (auto f = calib.Find("image_size")) {
    OCCMAP_ASSIGN_OR_RETURN(declared_size, GetImageSize(*f));
  }
  std::optional<double> m_per_unit;
  if (auto f = calib.Find("unit")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string unit, f->AsString());
    auto m = MetresPerUnit(unit);
    if (!m.ok()) return At(*f, m.status());
    m_per_unit = *m;
  }
  if (format == "opencv" || format == "gopro-json") {
    OCCMAP_RETURN_IF_ERROR(calib.CheckKeys({"format", "intrinsic", "extrinsic", "unit", "image_size", "forward",
                                            "ignore_distortion"}));
    OCCMAP_ASSIGN_OR_RETURN(fs::path intr, GetPath(calib, "intrinsic", ctx));
    OCCMAP_ASSIGN_OR_RETURN(fs::path extr, GetPath(calib, "extrinsic", ctx));
    cam.calibration_files = {intr, extr};
    Result<PinholeParameters> p = InvalidInput("unreachable");
    if (format == "opencv") {
      if (!m_per_unit) return calib.Error("missing required field 'unit' (m, cm or mm: the unit of tvec)");
      p = ReadOpenCvCalibration(intr, extr, *m_per_unit, declared_size);
    } else {
      p = ReadGoProCalibration(intr, extr, m_per_unit);
    }
    if (!p.ok()) return At(calib, p.status());
    if (declared_size && *declared_size != p->image_size) {
      return calib.Find("image_size")->Error(fmt::format("the calibration file says {}x{}, the site says {}x{}",
                                                         p->image_size.width, p->image_size.height,
                                                         declared_size->width, declared_size->height));
    }
    OCCMAP_ASSIGN_OR_RETURN(cam.camera, ParsePinholeOptions(calib, *p, grid, plane_z));
  } else if (format == "tsai-yaml") {
    OCCMAP_RETURN_IF_ERROR(calib.CheckKeys({"format", "file", "camera", "unit"}));
    OCCMAP_ASSIGN_OR_RETURN(fs::path file, GetPath(calib, "file", ctx));
    cam.calibration_files = {file};
    OCCMAP_ASSIGN_OR_RETURN(std::string name, calib.GetString("camera", ""));
    auto p = ReadTsaiYaml(file, name, m_per_unit.value_or(0.001));
    if (!p.ok()) return At(calib, p.status());
    auto tsai = TsaiCamera::Create(*p);
    if (!tsai.ok()) return At(calib, tsai.status());
    cam.camera = std::make_unique<TsaiCamera>(std::move(tsai).value());
  } else if (format == "homography") {
    OCCMAP_RETURN_IF_ERROR(calib.CheckKeys({"format", "floor_from_image", "unit", "image_size"}));
    if (!declared_size) return calib.Error("missing required field 'image_size'");
    OCCMAP_ASSIGN_OR_RETURN(YamlField hf, calib.Get("floor_from_image"));
    if (!hf.IsSequence() || hf.size() != 3) return hf.Error("expected a 3x3 matrix (3 rows of 3 numbers)");
    Eigen::Matrix3d h;
    for (size_t r = 0; r < 3; ++r) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField row, hf.At(r));
      OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, row.AsDoubles(3));
      for (int c = 0; c < 3; ++c) h(static_cast<int>(r), c) = v[c];
    }
    // Rows 0 and 1 give floor coordinates in the declared unit: scale them to metres.
    const double m = m_per_unit.value_or(1.0);
    h.row(0) *= m;
    h.row(1) *= m;
    auto hc = HomographyCamera::Create(h, *declared_size);
    if (!hc.ok()) return At(hf, hc.status());
    cam.camera = std::make_unique<HomographyCamera>(std::move(hc).value());
  } else {
    return calib.Find("format")->Error(
        fmt::format("expected opencv, gopro-json, tsai-yaml or homography, found '{}'", format));
  }
  cam.calibrated_size = cam.camera->image_size();
  return Status::Ok();
}

Result<Image<uint8_t>> ParseMask(const YamlField& field, const PathContext& ctx, ImageSize size) {
  if (field.IsScalar()) {
    OCCMAP_ASSIGN_OR_RETURN(std::string text, field.AsString());
    const fs::path path = ResolvePath(ctx.data_root, text);
    auto mask = ReadGrayImage(path);
    if (!mask.ok()) return At(field, mask.status());
    if (mask->width() != size.width || mask->height() != size.height) {
      return field.Error(fmt::format("'{}' is {}x{}, expected the camera's image size {}x{}", path.string(),
                                     mask->width(), mask->height(), size.width, size.height));
    }
    return std::move(mask).value();
  }
  OCCMAP_RETURN_IF_ERROR(field.CheckKeys({"polygon", "polygons"}));
  std::vector<std::vector<Eigen::Vector2d>> polygons;
  auto parse_polygon = [&](const YamlField& poly) -> Status {
    if (!poly.IsSequence() || poly.size() < 3) return poly.Error("expected a polygon of at least 3 [x, y] points");
    std::vector<Eigen::Vector2d> pts;
    for (size_t i = 0; i < poly.size(); ++i) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField p, poly.At(i));
      OCCMAP_ASSIGN_OR_RETURN(std::vector<double> xy, p.AsDoubles(2));
      if (xy[0] < -0.5 || xy[1] < -0.5 || xy[0] > size.width - 0.5 || xy[1] > size.height - 0.5) {
        return p.Error(fmt::format("point ({}, {}) is outside the {}x{} image", xy[0], xy[1], size.width, size.height));
      }
      pts.emplace_back(xy[0], xy[1]);
    }
    polygons.push_back(std::move(pts));
    return Status::Ok();
  };
  // Both would be one mask of their union, not what either key alone says: a mix-up to name.
  if (field.Find("polygon") && field.Find("polygons")) {
    return field.Error("expected 'polygon' or 'polygons', found both (put every polygon under 'polygons')");
  }
  if (auto poly = field.Find("polygon")) OCCMAP_RETURN_IF_ERROR(parse_polygon(*poly));
  if (auto list = field.Find("polygons")) {
    if (!list->IsSequence() || list->size() == 0) return list->Error("expected a list of polygons");
    for (size_t i = 0; i < list->size(); ++i) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField poly, list->At(i));
      OCCMAP_RETURN_IF_ERROR(parse_polygon(poly));
    }
  }
  if (polygons.empty()) return field.Error("expected 'polygon' or 'polygons'");
  return RasterizePolygons(polygons, size);
}

// `timestamps: FILE` (seconds) or `timestamps: {file: FILE, fps: 25}` (frame numbers of that
// rate): io/frame_times.h.
Result<std::vector<double>> ParseTimestamps(const YamlField& field, const PathContext& ctx) {
  std::string file;
  double numbers_fps = 0;
  const YamlField* file_field = &field;
  std::optional<YamlField> inner;
  if (field.IsMap()) {
    OCCMAP_RETURN_IF_ERROR(field.CheckKeys({"file", "fps"}));
    OCCMAP_ASSIGN_OR_RETURN(inner, field.Get("file"));
    file_field = &*inner;
    OCCMAP_ASSIGN_OR_RETURN(numbers_fps, field.GetDouble("fps", 0.0));
    if (!(numbers_fps > 0 && numbers_fps <= 1e6)) {
      return field.Find("fps")->Error(fmt::format("expected the frame numbers' rate, 0 < fps <= 1e6, found {}", numbers_fps));
    }
  }
  OCCMAP_ASSIGN_OR_RETURN(file, file_field->AsString());
  if (file.empty()) return file_field->Error("expected a timestamps file, found an empty text");
  const fs::path path = ResolvePath(ctx.data_root, file);
  auto times = ReadFrameTimes(path, numbers_fps);
  if (!times.ok()) return times.status().WithContext(file_field->Where());
  return std::move(times).value();
}

Result<FrameSourceSpec> ParseSource(const YamlField& field, const PathContext& ctx) {
  OCCMAP_RETURN_IF_ERROR(field.CheckKeys({"images", "video", "stream", "masks", "fps", "timestamps"}));
  const size_t kinds = field.Has("images") + field.Has("video") + field.Has("stream") + field.Has("masks");
  if (kinds != 1) return field.Error("expected exactly one of images, video, stream or masks");
  FrameSourceSpec spec;
  std::string key;
  for (const char* k : {"images", "video", "stream", "masks"}) {
    if (field.Has(k)) key = k;
  }
  OCCMAP_ASSIGN_OR_RETURN(spec.fps, field.GetDouble("fps", 0.0));
  if (!(spec.fps >= 0)) return field.Find("fps")->Error(fmt::format("expected frames per second >= 0, found {}", spec.fps));
  if (spec.fps > 0 && key != "images" && key != "masks") {
    return field.Find("fps")->Error(fmt::format("fps is for images and masks ({} has its own timestamps)", key));
  }
  if (auto t = field.Find("timestamps")) {
    if (key != "images" && key != "masks") {
      return t->Error(fmt::format("timestamps are for images and masks ({} has its own)", key));
    }
    if (spec.fps > 0) return t->Error("expected fps or timestamps, found both");
    OCCMAP_ASSIGN_OR_RETURN(spec.timestamps_s, ParseTimestamps(*t, ctx));
  }
  OCCMAP_ASSIGN_OR_RETURN(std::string value, field.GetString(key));
  if (value.empty()) return field.Error(fmt::format("{}: expected a location, found an empty text", key));
  if (key == "stream") {
    spec.kind = FrameSourceSpec::Kind::kStream;
    spec.location = value;  // a URL or a device, used as is
    // A file played as a stream (a recording standing in for a camera) is found like every
    // other file of the site, beside the site file.
    if (value.find("://") == std::string::npos && !fs::path(value).is_absolute()) {
      std::error_code ec;
      const fs::path file = ResolvePath(ctx.data_root, value);
      if (fs::is_regular_file(file, ec)) spec.location = file.string();
    }
    return spec;
  }
  spec.kind = key == "images" ? FrameSourceSpec::Kind::kImages
              : key == "video" ? FrameSourceSpec::Kind::kVideo
                               : FrameSourceSpec::Kind::kMasks;
  spec.location = ResolvePath(ctx.data_root, value).string();
  // A FIFO would block the run's open forever: refused here, without opening it (issue 39).
  if (key == "video") OCCMAP_RETURN_IF_ERROR(CheckRegularFile(spec.location).WithContext(field.Find(key)->Where()));
  return spec;
}

Status ParseCamera(const YamlField& field, const PathContext& ctx, const FloorGrid& grid, double plane_z, SiteCamera& cam) {
  OCCMAP_RETURN_IF_ERROR(field.CheckKeys({"id", "calibration", "image_size", "mask", "source", "background"}));
  OCCMAP_ASSIGN_OR_RETURN(YamlField id, field.Get("id"));
  OCCMAP_ASSIGN_OR_RETURN(cam.id, id.AsString());
  if (cam.id.empty()) return id.Error("expected a non-empty camera id");
  // The id names files (backgrounds/<id>.png): '../x' would write outside the output folder.
  if (auto bad = CheckSafeFileName(cam.id)) return id.Error(fmt::format("camera id '{}': {}", Printable(cam.id), *bad));
  OCCMAP_ASSIGN_OR_RETURN(YamlField calib, field.Get("calibration"));
  if (!calib.IsMap()) return calib.Error("expected a map with 'format' and its files");
  OCCMAP_RETURN_IF_ERROR(ParseCalibration(calib, ctx, grid, plane_z, cam));
  if (auto f = field.Find("image_size")) {
    OCCMAP_ASSIGN_OR_RETURN(ImageSize run_size, GetImageSize(*f));
    if (run_size != cam.calibrated_size) {
      const double a0 = static_cast<double>(cam.calibrated_size.width) / cam.calibrated_size.height;
      const double a1 = static_cast<double>(run_size.width) / run_size.height;
      if (std::abs(a0 / a1 - 1) > 0.01) {
        return f->Error(fmt::format("expected the calibrated aspect ratio ({}x{}), found {}x{}",
                                    cam.calibrated_size.width, cam.calibrated_size.height, run_size.width,
                                    run_size.height));
      }
      cam.camera = cam.camera->Resized(run_size);
    }
  }
  if (!cam.camera->SupportsPlaneHeight(plane_z)) {
    return calib.Error(fmt::format("a {} calibration only knows the floor; plane_height_m must be 0, found {}",
                                   cam.camera->kind(), plane_z));
  }
  if (auto f = field.Find("mask")) {
    OCCMAP_ASSIGN_OR_RETURN(cam.mask, ParseMask(*f, ctx, cam.camera->image_size()));
  }
  // A camera that sees none of the grid adds nothing but unseen cells (one camera alone: a run
  // of all-unseen maps); it is a wrong calibration, unit, grid or mask, told here, not after a run.
  if (!SeesTheGrid(*cam.camera, cam.mask, grid, plane_z)) {
    return field.Error(fmt::format("the camera sees none of the {} floor sample points {} (calibration, unit, grid "
                                   "or mask wrong?)",
                                   kGridSamples * kGridSamples,
                                   cam.mask.empty() ? "in its image" : "in its image and mask"));
  }
  if (auto f = field.Find("source")) {
    OCCMAP_ASSIGN_OR_RETURN(cam.source, ParseSource(*f, ctx));
  }
  if (field.Has("background")) {
    OCCMAP_ASSIGN_OR_RETURN(fs::path bg, GetPath(field, "background", ctx));
    cam.background = bg;
  }
  return Status::Ok();
}

Status ParseDetection(const YamlField& f, ChangeDetectionOptions& d) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"threshold", "colour", "tolerance_px", "block_px", "block_rule"}));
  OCCMAP_ASSIGN_OR_RETURN(int64_t t, f.GetInt("threshold", d.threshold));
  if (t < 0 || t > 254) return f.Find("threshold")->Error(fmt::format("expected 0..254 grey levels, found {}", t));
  d.threshold = static_cast<int>(t);
  OCCMAP_ASSIGN_OR_RETURN(d.colour, f.GetBool("colour", d.colour));
  OCCMAP_ASSIGN_OR_RETURN(int64_t tol, f.GetInt("tolerance_px", d.tolerance_px));
  if (tol < 0 || tol > 64) return f.Find("tolerance_px")->Error(fmt::format("expected 0..64 pixels, found {}", tol));
  d.tolerance_px = static_cast<int>(tol);
  // block_px: 2 (2x2 blocks) or [width, height], each 1 or 2.
  if (const std::optional<YamlField> b = f.Find("block_px")) {
    std::vector<double> wh;
    if (b->IsSequence()) {
      OCCMAP_ASSIGN_OR_RETURN(wh, b->AsDoubles(2));
    } else {
      OCCMAP_ASSIGN_OR_RETURN(int64_t v, b->AsInt());
      wh = {static_cast<double>(v), static_cast<double>(v)};
    }
    for (const double v : wh) {
      if (v != 1 && v != 2) return b->Error(fmt::format("expected 1 or 2, or [width, height] of 1 or 2 pixels, found {}", v));
    }
    d.block_width_px = static_cast<int>(wh[0]);
    d.block_height_px = static_cast<int>(wh[1]);
  }
  OCCMAP_ASSIGN_OR_RETURN(std::string rule, f.GetString("block_rule", "any"));
  if (rule != "any" && rule != "half") {
    return f.Find("block_rule")->Error(fmt::format("expected any or half, found '{}'", rule));
  }
  d.block_rule = rule == "half" ? BlockRule::kHalf : BlockRule::kAny;
  return Status::Ok();
}

// The `backgrounds:` section (detect/background_model.h); each value checked by Validate(),
// the message placed at the section.
Status ParseBackgrounds(const YamlField& f, BackgroundOptions& b) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"adaptive", "learning", "learn_s", "learn_samples", "refresh_cache_s", "mode_radius", "alternative_min_share", "settle", "adapt_s",
                                      "relight_s", "absorb_s", "person_height_m", "chroma_threshold", "white_balance", "grow_steps_px",
                                      "grow_threshold_share", "grow_seed_share", "shadows"}));
  OCCMAP_ASSIGN_OR_RETURN(b.adaptive, f.GetBool("adaptive", b.adaptive));
  OCCMAP_ASSIGN_OR_RETURN(std::string learning, f.GetString("learning", ToString(b.learning)));
  auto method = ParseBackgroundLearning(learning);
  if (!method.ok()) return f.Find("learning")->Error(method.status().message());
  b.learning = *method;
  OCCMAP_ASSIGN_OR_RETURN(b.learn_s, f.GetDouble("learn_s", b.learn_s));
  OCCMAP_ASSIGN_OR_RETURN(b.refresh_cache_s, f.GetDouble("refresh_cache_s", b.refresh_cache_s));
  OCCMAP_ASSIGN_OR_RETURN(int64_t samples, f.GetInt("learn_samples", b.learn_samples));
  b.learn_samples = static_cast<int>(std::clamp<int64_t>(samples, -1, 1000));
  OCCMAP_ASSIGN_OR_RETURN(int64_t radius, f.GetInt("mode_radius", b.mode_radius));
  b.mode_radius = static_cast<int>(std::clamp<int64_t>(radius, -1, 1000));
  OCCMAP_ASSIGN_OR_RETURN(b.alternative_min_share, f.GetDouble("alternative_min_share", b.alternative_min_share));
  OCCMAP_ASSIGN_OR_RETURN(b.settle, f.GetBool("settle", b.settle));
  OCCMAP_ASSIGN_OR_RETURN(b.adapt_s, f.GetDouble("adapt_s", b.adapt_s));
  OCCMAP_ASSIGN_OR_RETURN(b.relight_s, f.GetDouble("relight_s", b.relight_s));
  OCCMAP_ASSIGN_OR_RETURN(b.absorb_s, f.GetDouble("absorb_s", b.absorb_s));
  OCCMAP_ASSIGN_OR_RETURN(b.person_height_m, f.GetDouble("person_height_m", b.person_height_m));
  OCCMAP_ASSIGN_OR_RETURN(int64_t tc, f.GetInt("chroma_threshold", b.chroma_threshold));
  b.chroma_threshold = static_cast<int>(std::clamp<int64_t>(tc, -1, 1000));
  OCCMAP_ASSIGN_OR_RETURN(b.white_balance, f.GetBool("white_balance", b.white_balance));
  OCCMAP_ASSIGN_OR_RETURN(int64_t steps, f.GetInt("grow_steps_px", b.grow_steps_px));
  b.grow_steps_px = static_cast<int>(std::clamp<int64_t>(steps, -1, 1000));
  OCCMAP_ASSIGN_OR_RETURN(b.grow_threshold_share, f.GetDouble("grow_threshold_share", b.grow_threshold_share));
  OCCMAP_ASSIGN_OR_RETURN(b.grow_seed_share, f.GetDouble("grow_seed_share", b.grow_seed_share));
  if (auto s = f.Find("shadows")) {
    OCCMAP_RETURN_IF_ERROR(s->CheckKeys({"enabled", "min_ratio", "max_ratio", "learn", "ratio_window", "max_channel_spread",
                                         "texture_radius_px",
                                         "min_texture_correlation", "flat_std", "floor_check", "soft", "soft_min_ratio",
                                         "soft_max_ratio"}));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.enabled, s->GetBool("enabled", b.shadows.enabled));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.min_ratio, s->GetDouble("min_ratio", b.shadows.min_ratio));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.max_ratio, s->GetDouble("max_ratio", b.shadows.max_ratio));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.learn, s->GetBool("learn", b.shadows.learn));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.ratio_window, s->GetDouble("ratio_window", b.shadows.ratio_window));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.max_channel_spread, s->GetDouble("max_channel_spread", b.shadows.max_channel_spread));
    OCCMAP_ASSIGN_OR_RETURN(int64_t radius_px, s->GetInt("texture_radius_px", b.shadows.texture_radius_px));
    b.shadows.texture_radius_px = static_cast<int>(std::clamp<int64_t>(radius_px, -1, 1000));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.min_texture_correlation,
                            s->GetDouble("min_texture_correlation", b.shadows.min_texture_correlation));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.flat_std, s->GetDouble("flat_std", b.shadows.flat_std));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.floor_check, s->GetBool("floor_check", b.shadows.floor_check));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.soft, s->GetBool("soft", b.shadows.soft));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.soft_min_ratio, s->GetDouble("soft_min_ratio", b.shadows.soft_min_ratio));
    OCCMAP_ASSIGN_OR_RETURN(b.shadows.soft_max_ratio, s->GetDouble("soft_max_ratio", b.shadows.soft_max_ratio));
  }
  // Validate() names the field ("backgrounds.shadows.min_ratio: ..."): the message goes to its line.
  if (Status v = b.Validate(); !v.ok()) {
    std::string_view what = v.message();
    constexpr std::string_view kPrefix = "backgrounds.";
    const size_t colon = what.find(": ");
    if (what.starts_with(kPrefix) && colon != std::string_view::npos) {
      std::string_view path = what.substr(kPrefix.size(), colon - kPrefix.size());
      std::optional<YamlField> field = f;
      while (field && !path.empty()) {
        const size_t dot = path.find('.');
        field = field->Find(path.substr(0, dot));
        path = dot == std::string_view::npos ? std::string_view() : path.substr(dot + 1);
      }
      if (field) return field->Error(what.substr(colon + 2));
    }
    return f.Error(v.message());
  }
  return Status::Ok();
}

Status ParseFusion(const YamlField& f, size_t num_cameras, FusionOptions& s) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"algorithm", "max_free_views"}));
  OCCMAP_ASSIGN_OR_RETURN(std::string algo, f.GetString("algorithm", "image-based"));
  if (algo == "image-based") {
    s.method = FusionMethod::kImageBased;
  } else if (algo == "map-based") {
    s.method = FusionMethod::kMapBased;
  } else {
    return f.Find("algorithm")->Error(fmt::format("expected image-based or map-based, found '{}'", algo));
  }
  OCCMAP_ASSIGN_OR_RETURN(int64_t k, f.GetInt("max_free_views", 0));
  if (k < 0 || k >= static_cast<int64_t>(std::max<size_t>(1, num_cameras))) {
    return f.Find("max_free_views")
        ->Error(fmt::format("expected 0..{} (fewer than the {} cameras), found {}", std::max<size_t>(1, num_cameras) - 1,
                            num_cameras, k));
  }
  s.max_free_views = static_cast<int>(k);
  return Status::Ok();
}

}  // namespace

const char* ToString(FusionMethod method) {
  return method == FusionMethod::kImageBased ? "image-based" : "map-based";
}

std::vector<LutCameraInput> Site::LutInputs() const {
  std::vector<LutCameraInput> inputs;
  for (const auto& c : cameras) {
    inputs.push_back({c.camera.get(), c.mask.empty() ? ImageView<const uint8_t>() : c.mask.view()});
  }
  return inputs;
}

Image<uint8_t> RasterizePolygons(const std::vector<std::vector<Eigen::Vector2d>>& polygons, ImageSize size) {
  cv::Mat mat(size.height, size.width, CV_8UC1, cv::Scalar(0));
  constexpr int kShift = 8;  // sub-pixel vertices
  std::vector<std::vector<cv::Point>> pts;
  for (const auto& poly : polygons) {
    std::vector<cv::Point> p;
    for (const auto& v : poly) {
      p.emplace_back(static_cast<int>(std::lround(v.x() * (1 << kShift))),
                     static_cast<int>(std::lround(v.y() * (1 << kShift))));
    }
    pts.push_back(std::move(p));
  }
  cv::fillPoly(mat, pts, cv::Scalar(255), cv::LINE_8, kShift);
  Image<uint8_t> mask(size.width, size.height);
  for (int y = 0; y < size.height; ++y) std::memcpy(mask.row(y), mat.ptr<uint8_t>(y), static_cast<size_t>(size.width));
  return mask;
}

Result<Site> ParseSite(std::string_view yaml_text, const fs::path& path, const SiteLoadOptions& options) {
  OCCMAP_ASSIGN_OR_RETURN(YamlField root, ParseYaml(yaml_text, path.string()));
  if (!root.IsMap()) return root.Error("expected a site description (a map with floor and cameras)");
  OCCMAP_RETURN_IF_ERROR(
      root.CheckKeys({"version", "name", "data_root", "floor", "cameras", "detection", "backgrounds", "fusion", "blobs", "lut", "people", "statics",
                      "tracking", "outputs"}));
  OCCMAP_ASSIGN_OR_RETURN(int64_t version, root.GetInt("version", 1));
  if (version != 1) return root.Find("version")->Error(fmt::format("expected site format version 1, found {}", version));
  Site site;
  site.file = path;
  if (auto f = root.Find("name")) {
    // The name names cache files (<name>-<id>-<hash>.png) and MQTT topics, as an id does.
    OCCMAP_ASSIGN_OR_RETURN(site.name, f->AsString());
    if (auto bad = CheckSafeFileName(site.name)) return f->Error(fmt::format("site name '{}': {}", Printable(site.name), *bad));
  } else {
    // Without a name, the file's: its unsafe characters replaced (a file 'my site.yaml' is fine).
    site.name = path.stem().string();
    if (CheckSafeFileName(site.name)) {
      std::string safe;
      for (char c : site.name) safe += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
      site.name = CheckSafeFileName(safe) ? "site" : safe;
    }
  }
  PathContext ctx;
  ctx.site_dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  ctx.data_root = ctx.site_dir;
  if (options.data_root) {
    ctx.data_root = *options.data_root;
  } else if (auto f = root.Find("data_root")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string dr, f->AsString());
    ctx.data_root = ResolvePath(ctx.site_dir, dr);
  }
  if (std::error_code ec; !fs::is_directory(ctx.data_root, ec)) {
    const std::string where = options.data_root ? "--data-root" : root.Has("data_root") ? root.Find("data_root")->Where() : root.Where();
    return Status(StatusCode::kNotFound, fmt::format("{}: data folder not found: '{}'", where, ctx.data_root.string()));
  }

  OCCMAP_ASSIGN_OR_RETURN(YamlField floor, root.Get("floor"));
  OCCMAP_ASSIGN_OR_RETURN(site.grid, ParseFloor(floor, &site.plane_height_m));
  site.lut.plane_height_m = site.plane_height_m;

  OCCMAP_ASSIGN_OR_RETURN(YamlField cams, root.Get("cameras"));
  if (!cams.IsSequence() || cams.size() == 0) return cams.Error("expected a list of at least one camera");
  if (cams.size() > GroundLut::kMaxCameras) {
    return cams.Error(fmt::format("expected at most {} cameras, found {}", GroundLut::kMaxCameras, cams.size()));
  }
  std::set<std::string> ids;
  for (size_t i = 0; i < cams.size(); ++i) {
    OCCMAP_ASSIGN_OR_RETURN(YamlField f, cams.At(i));
    SiteCamera cam;
    OCCMAP_RETURN_IF_ERROR(ParseCamera(f, ctx, site.grid, site.plane_height_m, cam));
    if (!ids.insert(cam.id).second) return f.Find("id")->Error(fmt::format("duplicate camera id '{}'", cam.id));
    site.cameras.push_back(std::move(cam));
  }
  if (auto f = root.Find("detection")) OCCMAP_RETURN_IF_ERROR(ParseDetection(*f, site.detection));
  if (auto f = root.Find("backgrounds")) OCCMAP_RETURN_IF_ERROR(ParseBackgrounds(*f, site.backgrounds));
  if (auto f = root.Find("people")) {
    OCCMAP_RETURN_IF_ERROR(ParsePeopleOptions(*f, static_cast<int>(site.cameras.size()), site.people));
  }
  if (auto f = root.Find("statics")) {
    OCCMAP_ASSIGN_OR_RETURN(site.statics, ParseOccluders(*f));
  }
  if (auto f = root.Find("fusion")) OCCMAP_RETURN_IF_ERROR(ParseFusion(*f, site.cameras.size(), site.fusion));
  if (auto f = root.Find("blobs")) OCCMAP_RETURN_IF_ERROR(ParseObjectOptions(*f, site.objects));
  if (auto f = root.Find("tracking")) {
    OCCMAP_RETURN_IF_ERROR(ParseTrackerOptions(*f, site.tracking, kObjectKeysInTracking));
    OCCMAP_RETURN_IF_ERROR(ParseObjectKeysOfTracking(*f, site.objects));
  }
  if (auto f = root.Find("outputs"); f && !f->IsNull()) {
    OCCMAP_RETURN_IF_ERROR(f->CheckKeys({"mqtt"}));
    if (auto m = f->Find("mqtt")) {
      OCCMAP_ASSIGN_OR_RETURN(site.outputs.mqtt, ParseMqttOptions(*m, ctx.site_dir));
      ResolveMqttDefaults(site.name, *site.outputs.mqtt);
    }
  }
  if (auto f = root.Find("lut")) {
    OCCMAP_RETURN_IF_ERROR(f->CheckKeys({"add_cell_projections"}));
    OCCMAP_ASSIGN_OR_RETURN(site.lut.add_cell_projections, f->GetBool("add_cell_projections", true));
  }
  return site;
}

Result<Site> LoadSite(const fs::path& path, const SiteLoadOptions& options) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
  return ParseSite(text, path, options);
}

}  // namespace occmap
