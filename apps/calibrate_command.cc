#include "calibrate_command.h"

#include <fmt/core.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

#include "occmap/calib/board_calibration.h"
#include "occmap/calib/calibration_overlay.h"
#include "occmap/calib/floor_calibration.h"
#include "occmap/calib/opencv_storage.h"
#include "occmap/io/frame_source.h"
#include "occmap/site/site.h"
#include "occmap/site/site_update.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/yaml_util.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

Result<ImageSize> ParseSize(const std::string& text, std::string_view option) {
  const size_t x = text.find('x');
  if (x != std::string::npos) {
    const auto w = ParseInt(std::string_view(text).substr(0, x));
    const auto h = ParseInt(std::string_view(text).substr(x + 1));
    if (w && h && *w > 0 && *h > 0 && *w <= 100000 && *h <= 100000) {
      return ImageSize{static_cast<int>(*w), static_cast<int>(*h)};
    }
  }
  return InvalidInput(fmt::format("{}: expected WIDTHxHEIGHT (e.g. 1920x1080), found '{}'", option, text));
}

json Vec(const Eigen::Vector2d& v) {
  if (!v.allFinite()) return nullptr;
  return json::array({v.x(), v.y()});
}
json Finite(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

CameraIntrinsics FromOpenCv(const OpenCvIntrinsics& in, ImageSize size) {
  CameraIntrinsics c;
  c.image_size = in.image_size.value_or(size);
  c.fx_px = in.fx_px;
  c.fy_px = in.fy_px;
  c.cx_px = in.cx_px;
  c.cy_px = in.cy_px;
  c.skew_px = in.skew_px;
  c.distortion = in.distortion;
  return c;
}

OpenCvIntrinsics ToOpenCv(const CameraIntrinsics& c) {
  OpenCvIntrinsics in;
  in.fx_px = c.fx_px;
  in.fy_px = c.fy_px;
  in.cx_px = c.cx_px;
  in.cy_px = c.cy_px;
  in.skew_px = c.skew_px;
  in.distortion = c.distortion;
  in.image_size = c.image_size;
  return in;
}

Result<BoardOptions> BoardFrom(const CalibrateCommand& cmd) {
  BoardOptions b;
  if (cmd.board == "checkerboard") {
    b.kind = BoardKind::kCheckerboard;
  } else if (cmd.board == "charuco") {
    b.kind = BoardKind::kCharuco;
  } else {
    return InvalidInput(fmt::format("--board: expected checkerboard or charuco, found '{}'", cmd.board));
  }
  OCCMAP_ASSIGN_OR_RETURN(ImageSize s, ParseSize(cmd.board_size, "--board-size"));
  b.cols = s.width;
  b.rows = s.height;
  if (!(cmd.square_m > 0)) return InvalidInput("--square-m: expected the side of a board square in metres (> 0)");
  b.square_m = cmd.square_m;
  b.marker_m = cmd.marker_m > 0 ? cmd.marker_m : 0.75 * cmd.square_m;
  b.dictionary = cmd.dictionary;
  OCCMAP_RETURN_IF_ERROR(b.Validate().WithContext("--board"));
  return b;
}

// Intrinsics from board views (images or every frame_step-th frame of a video).
Result<IntrinsicsCalibration> CalibrateFromBoard(const CalibrateCommand& cmd, json& report) {
  OCCMAP_ASSIGN_OR_RETURN(BoardOptions board, BoardFrom(cmd));
  std::vector<Image<uint8_t>> images;
  std::vector<std::string> names;
  for (const std::string& path : cmd.board_images) {
    OCCMAP_ASSIGN_OR_RETURN(Image<uint8_t> g, ReadGrayImage(path));
    images.push_back(std::move(g));
    names.push_back(path);
  }
  if (!cmd.board_video.empty()) {
    if (cmd.frame_step < 1) return InvalidInput(fmt::format("--frame-step: expected >= 1, found {}", cmd.frame_step));
    FrameSourceSpec spec;
    spec.kind = FrameSourceSpec::Kind::kVideo;
    spec.location = cmd.board_video;
    OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> source, OpenFrameSource(spec, {}));
    Frame frame;
    for (int64_t n = 0; static_cast<int>(images.size()) < cmd.max_views; ++n) {
      OCCMAP_ASSIGN_OR_RETURN(bool got, source->Read(frame));
      if (!got) break;
      if (n % cmd.frame_step != 0) continue;
      images.push_back(frame.gray);
      names.push_back(fmt::format("{} frame {}", cmd.board_video, n));
    }
  }
  std::vector<BoardImage> views;
  for (size_t i = 0; i < images.size(); ++i) views.push_back({names[i], images[i].view()});
  IntrinsicsOptions o;
  o.board = board;
  o.max_blur_px = cmd.max_blur_px;
  o.estimate_k3 = cmd.estimate_k3;
  OCCMAP_ASSIGN_OR_RETURN(IntrinsicsCalibration cal, CalibrateIntrinsics(views, o));
  if (!cmd.json_to_stdout) {
    fmt::print("board views: {} of {} used\n", cal.views_used, cal.views.size());
    for (const BoardView& v : cal.views) {
      if (v.used) {
        fmt::print("  {:<28} used      {:3d} corners, RMS {:.3f} px, blur {:.1f} px, tilt {:.0f} deg\n", v.name,
                   v.corners, v.rms_px, v.blur_px, v.tilt_deg);
      } else {
        fmt::print("  {:<28} rejected  {}\n", v.name, v.reason);
      }
    }
    const CameraIntrinsics& in = cal.intrinsics;
    fmt::print("intrinsics: {}x{}, fx {:.2f} fy {:.2f} cx {:.2f} cy {:.2f}, k1 {:.5f} k2 {:.5f} p1 {:.5f} p2 {:.5f} k3 "
               "{:.5f}; reprojection RMS {:.3f} px\n",
               in.image_size.width, in.image_size.height, in.fx_px, in.fy_px, in.cx_px, in.cy_px, in.distortion[0],
               in.distortion[1], in.distortion[2], in.distortion[3], in.distortion[4], cal.rms_px);
    for (const auto& w : cal.warnings) fmt::print("warning: {}\n", w);
  }
  json jv = json::array();
  for (const BoardView& v : cal.views) {
    jv.push_back({{"name", v.name}, {"used", v.used}, {"reason", v.reason}, {"corners", v.corners},
                  {"blur_px", Finite(v.blur_px)}, {"board_fraction", v.board_fraction}, {"tilt_deg", v.tilt_deg},
                  {"rms_px", v.used ? json(v.rms_px) : json(nullptr)}});
  }
  const CameraIntrinsics& in = cal.intrinsics;
  report["intrinsics"] = {{"source", "board"},
                          {"image_size", {in.image_size.width, in.image_size.height}},
                          {"fx_px", in.fx_px}, {"fy_px", in.fy_px}, {"cx_px", in.cx_px}, {"cy_px", in.cy_px},
                          {"distortion", in.distortion}, {"rms_px", cal.rms_px}, {"views_used", cal.views_used},
                          {"views", jv}, {"warnings", cal.warnings}};
  return cal;
}

std::string CalibrationFlowYaml(const FloorCalibration& cal, const fs::path& site, const fs::path& intr,
                                const fs::path& extr) {
  if (cal.floor_from_image) return HomographyCalibrationYaml(*cal.floor_from_image, cal.image_size);
  auto i = SitePathFor(site, intr);
  auto e = SitePathFor(site, extr);
  if (!i.ok() || !e.ok()) {
    i = fs::absolute(intr).generic_string();
    e = fs::absolute(extr).generic_string();
  }
  return fmt::format("{{format: opencv, intrinsic: {}, extrinsic: {}, unit: m, forward: +z}}", *i, *e);
}

bool ValidId(const std::string& id) {
  if (id.empty()) return false;
  for (char c : id) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-' && c != '.') return false;
  }
  return true;
}

}  // namespace

CLI::App* AddCalibrateCommand(CLI::App& app, CalibrateCommand& cmd) {
  CLI::App* c = app.add_subcommand(
      "calibrate",
      "calibrate a camera: intrinsics from board views, the camera from known floor points, the site file updated");
  c->add_option("--camera", cmd.camera_id, "camera id: names the files, and the site's camera with --update-site")
      ->capture_default_str();
  c->add_option("--out", cmd.out_dir,
                "folder for the calibration files and the report (files already there are replaced only with "
                "--update-site or --force)")
      ->capture_default_str();
  c->add_option("--board-images", cmd.board_images, "pictures of the board (intrinsics)");
  c->add_option("--board-video", cmd.board_video, "a video of the board (intrinsics): every --frame-step-th frame");
  c->add_option("--frame-step", cmd.frame_step, "board video: use every N-th frame")->capture_default_str();
  c->add_option("--max-views", cmd.max_views, "board video: at most this many frames")->capture_default_str();
  c->add_option("--board", cmd.board, "checkerboard or charuco")->capture_default_str();
  c->add_option("--board-size", cmd.board_size,
                "checkerboard: inner corners across x down (10 x 7 squares: 9x6); charuco: squares")
      ->capture_default_str();
  c->add_option("--square-m", cmd.square_m, "side of a board square, metres");
  c->add_option("--marker-m", cmd.marker_m, "charuco: side of a marker, metres (default 0.75 of a square)");
  c->add_option("--dictionary", cmd.dictionary, "charuco: 4x4_50 ... 7x7_1000")->capture_default_str();
  c->add_option("--max-blur-px", cmd.max_blur_px, "reject board views whose edges are blurrier (Gaussian sigma, px)")
      ->capture_default_str();
  c->add_flag("--estimate-k3", cmd.estimate_k3, "also estimate k3 (wide-angle lenses)");
  c->add_option("--print-board", cmd.print_board, "write the board as a PNG to print (100 px a square)");
  c->add_option("--intrinsics", cmd.intrinsics_file, "the camera's intrinsics (OpenCV FileStorage) instead of a board");
  c->add_flag("--fit-lens", cmd.fit_lens,
              "no intrinsics: fit the focal length and distortion k1, k2 to the floor points too (6 at least, "
              "better 8+ spread over the picture) instead of a floor homography");
  c->add_option("--points", cmd.points_file, "floor-point file (CSV: u_px,v_px,x_m,y_m[,label]; docs/formats.md)");
  c->add_option("--image", cmd.image, "the camera's picture: its size, and what --overlay draws on");
  c->add_option("--image-size", cmd.image_size, "the camera's image size WxH, without --image");
  c->add_option("--update-site", cmd.update_site, "replace --camera's calibration in this site file (backup SITE.bak)");
  c->add_option("--overlay", cmd.overlay, "draw the floor grid and the points on --image into this PNG");
  c->add_option("--max-rms-px", cmd.max_rms_px,
                "refuse a fit whose reprojection RMS is over this (no files written, the site left as it is)")
      ->capture_default_str();
  c->add_flag("--force", cmd.force,
              "write the calibration (and --update-site) even with points named as outliers or an RMS over "
              "--max-rms-px, and replace calibration files already in --out");
  c->add_flag("--json", cmd.json_to_stdout, "print the report as JSON");
  return c;
}

Status RunCalibrate(const CalibrateCommand& cmd, const std::string& data_root) {
  const bool board = !cmd.board_images.empty() || !cmd.board_video.empty();
  const bool points = !cmd.points_file.empty();
  if (!cmd.print_board.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(BoardOptions b, BoardFrom(cmd));
    OCCMAP_ASSIGN_OR_RETURN(Image<uint8_t> pic, DrawBoard(b, 100, 50));
    OCCMAP_RETURN_IF_ERROR(WritePng(cmd.print_board, pic.view()));
    if (!cmd.json_to_stdout) {
      fmt::print("{}: the board, {}x{} px at 100 px a square: print it so that a square measures {} m\n",
                 cmd.print_board, pic.width(), pic.height(), b.square_m);
    }
  }
  if (!board && !points) {
    if (!cmd.print_board.empty()) return Status::Ok();
    return InvalidInput("calibrate: give board views (--board-images, --board-video) and/or --points");
  }
  if (!ValidId(cmd.camera_id)) {
    return InvalidInput(fmt::format("--camera: expected letters, digits, '_', '-' or '.', found '{}'", cmd.camera_id));
  }
  if (board && !cmd.intrinsics_file.empty()) {
    return InvalidInput("--intrinsics: give either board views or an intrinsics file, not both");
  }
  if (cmd.fit_lens && (board || !cmd.intrinsics_file.empty() || !points)) {
    return InvalidInput("--fit-lens: needs --points, and neither board views nor --intrinsics (which give the lens)");
  }
  if (!cmd.update_site.empty() && !points) return InvalidInput("--update-site: needs --points (the camera's pose)");
  if (!cmd.overlay.empty() && (cmd.image.empty() || !points)) {
    return InvalidInput("--overlay: needs --points and --image (the camera's picture to draw on)");
  }
  const fs::path out(cmd.out_dir);
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out));
  const fs::path intr_path = out / fmt::format("intr_{}.xml", cmd.camera_id);
  const fs::path extr_path = out / fmt::format("extr_{}.xml", cmd.camera_id);
  const fs::path h_path = out / fmt::format("homography_{}.yaml", cmd.camera_id);
  const fs::path report_path = out / fmt::format("calibration_{}.json", cmd.camera_id);
  // The calibration files already in --out may be those a site names (--out its own calib/):
  // replaced only with --update-site (which points the site at them) or --force. Checked
  // before the board's views are read, so a refusal costs nothing and writes nothing.
  if (!cmd.force && cmd.update_site.empty()) {
    std::vector<fs::path> to_write;
    if (board) to_write.push_back(intr_path);
    if (points && (board || !cmd.intrinsics_file.empty() || cmd.fit_lens)) {
      to_write.insert(to_write.end(), {intr_path, extr_path});
    } else if (points) {
      to_write.push_back(h_path);
    }
    for (const fs::path& f : to_write) {
      std::error_code ec;
      if (fs::exists(f, ec)) {
        return InvalidInput(fmt::format(
            "--out {}: '{}' exists and a site may name it: give --force to replace it, --update-site SITE to "
            "replace it and point the site at it, or another --out",
            cmd.out_dir, f.string()));
      }
    }
  }
  json report = {{"camera", cmd.camera_id}};
  json files = json::object();
  // A calibration file replaced (--update-site or --force) is kept as FILE.bak first: with
  // SITE.bak it restores what the site read before.
  json kept = json::array();
  auto keep_previous = [&](const fs::path& f) -> Status {
    std::error_code ec;
    if (!fs::exists(f, ec)) return Status::Ok();
    OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(f));
    const fs::path backup = f.string() + ".bak";
    OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(backup, text));
    kept.push_back(backup.string());
    return Status::Ok();
  };

  std::optional<CameraIntrinsics> intrinsics;
  if (board) {
    OCCMAP_ASSIGN_OR_RETURN(IntrinsicsCalibration cal, CalibrateFromBoard(cmd, report));
    intrinsics = cal.intrinsics;
    OCCMAP_RETURN_IF_ERROR(keep_previous(intr_path));
    OCCMAP_RETURN_IF_ERROR(WriteOpenCvIntrinsics(ToOpenCv(cal.intrinsics), intr_path));
    files["intrinsic"] = intr_path.string();
  }

  std::optional<Image<Rgb8>> picture;
  std::optional<ImageSize> size;
  if (!cmd.image.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(Image<Rgb8> pic, ReadRgbImage(cmd.image));
    size = ImageSize{pic.width(), pic.height()};
    picture = std::move(pic);
  }
  if (!cmd.image_size.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(ImageSize s, ParseSize(cmd.image_size, "--image-size"));
    if (size && *size != s) {
      return InvalidInput(fmt::format("--image-size {}x{}: the image '{}' is {}x{}", s.width, s.height, cmd.image,
                                      size->width, size->height));
    }
    size = s;
  }
  if (!cmd.intrinsics_file.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(OpenCvIntrinsics in, ReadOpenCvIntrinsics(cmd.intrinsics_file));
    if (!in.image_size && !size) {
      return InvalidInput(fmt::format("'{}': no image_width/image_height; give --image or --image-size",
                                      cmd.intrinsics_file));
    }
    intrinsics = FromOpenCv(in, *size);
    OCCMAP_RETURN_IF_ERROR(intrinsics->Validate().WithContext(fmt::format("'{}'", cmd.intrinsics_file)));
    report["intrinsics"] = {{"source", cmd.intrinsics_file}};
  }
  if (!points) {
    OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(report_path, report.dump(2) + "\n"));
    if (cmd.json_to_stdout) fmt::print("{}\n", report.dump(2));
    else fmt::print("wrote {}, {}\n", intr_path.string(), report_path.string());
    return Status::Ok();
  }

  OCCMAP_ASSIGN_OR_RETURN(std::vector<FloorPoint> pts, ReadFloorPoints(cmd.points_file));
  if (!size && intrinsics) size = intrinsics->image_size;
  if (!size) {
    return InvalidInput("--points: the camera's image size is unknown; give --image, --image-size or intrinsics");
  }
  FloorCalibrationOptions fo;
  fo.image_size = *size;
  fo.intrinsics = intrinsics;
  fo.fit_lens = cmd.fit_lens;
  auto calibrated = CalibrateFromFloorPoints(pts, fo);
  if (!calibrated.ok()) return calibrated.status().WithContext(cmd.points_file);
  const FloorCalibration& cal = *calibrated;
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<CameraModel> model, cal.Model());
  if (!(cmd.max_rms_px > 0)) return InvalidInput(fmt::format("--max-rms-px: expected > 0, found {}", cmd.max_rms_px));
  // A wrong point or a poor fit writes nothing a site reads: the files of --out may be the ones
  // the site names, and --update-site would replace a good calibration.
  const std::vector<std::string> concerns = CalibrationConcerns(cal, pts, cmd.max_rms_px);
  const bool refused = !concerns.empty() && !cmd.force;

  // The files the site reads.
  if (refused) {
  } else if (cal.pinhole) {
    // The board's intrinsics just written are not a previous file.
    if (!files.contains("intrinsic")) OCCMAP_RETURN_IF_ERROR(keep_previous(intr_path));
    OCCMAP_RETURN_IF_ERROR(keep_previous(extr_path));
    OCCMAP_RETURN_IF_ERROR(WriteOpenCvCalibration(*cal.pinhole, 1.0, intr_path, extr_path));
    files["intrinsic"] = intr_path.string();
    files["extrinsic"] = extr_path.string();
  } else {
    OCCMAP_RETURN_IF_ERROR(keep_previous(h_path));
    OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(
        h_path, fmt::format("# occmap calibrate: camera {} from {} ({} floor points); a site file's camera entry\n"
                            "calibration: {}\n",
                            cmd.camera_id, cmd.points_file, pts.size(),
                            HomographyCalibrationYaml(*cal.floor_from_image, cal.image_size))));
    files["homography"] = h_path.string();
  }

  report["kind"] = cal.kind();
  report["image_size"] = {cal.image_size.width, cal.image_size.height};
  report["points_file"] = cmd.points_file;
  report["rms_reprojection_px"] = Finite(cal.rms_reprojection_px);
  report["max_reprojection_px"] = Finite(cal.max_reprojection_px);
  report["rms_floor_m"] = Finite(cal.rms_floor_m);
  report["max_floor_m"] = Finite(cal.max_floor_m);
  report["warnings"] = cal.warnings;
  report["outliers_checked"] = cal.outliers_checked;
  if (!cal.outlier_note.empty()) report["outlier_note"] = cal.outlier_note;
  json jo = json::array();
  for (size_t i : cal.outliers) jo.push_back(i);
  report["outliers"] = jo;
  report["rms_without_outliers_px"] = Finite(cal.rms_without_outliers_px);
  report["rms_floor_without_outliers_m"] = Finite(cal.rms_floor_without_outliers_m);
  report["concerns"] = concerns;
  report["refused"] = refused;
  report["kept_as"] = kept;
  json jp = json::array();
  for (size_t i = 0; i < pts.size(); ++i) {
    const FloorPointError& e = cal.errors[i];
    jp.push_back({{"where", pts[i].where}, {"label", pts[i].label}, {"pixel", Vec(pts[i].pixel)},
                  {"floor_m", Vec(pts[i].floor_m)}, {"reprojected_px", Vec(e.reprojected_px)},
                  {"reprojection_px", Finite(e.reprojection_px)},
                  {"floor_from_pixel_m", e.floor_from_pixel_m ? Vec(*e.floor_from_pixel_m) : json(nullptr)},
                  {"floor_error_m", Finite(e.floor_m)},
                  {"predicted_error_px", i < cal.predicted_error_px.size() ? Finite(cal.predicted_error_px[i]) : json(nullptr)},
                  {"outlier", std::find(cal.outliers.begin(), cal.outliers.end(), i) != cal.outliers.end()}});
  }
  report["points"] = jp;
  if (cal.pinhole) {
    const PinholeParameters& p = *cal.pinhole;
    const Eigen::AngleAxisd aa(p.cam_from_world_rotation);
    const Eigen::Vector3d rvec = aa.axis() * aa.angle();
    const Eigen::Vector3d centre = *model->CenterInWorld();
    report["pinhole"] = {{"fx_px", p.fx_px}, {"fy_px", p.fy_px}, {"cx_px", p.cx_px}, {"cy_px", p.cy_px},
                         {"distortion", p.distortion},
                         {"rvec", {rvec.x(), rvec.y(), rvec.z()}},
                         {"tvec_m", {p.cam_from_world_translation_m.x(), p.cam_from_world_translation_m.y(),
                                     p.cam_from_world_translation_m.z()}},
                         {"camera_centre_m", {centre.x(), centre.y(), centre.z()}},
                         {"lens_fitted", cal.lens_fitted}};
  } else {
    const Eigen::Matrix3d& h = *cal.floor_from_image;
    report["floor_from_image"] = {{h(0, 0), h(0, 1), h(0, 2)}, {h(1, 0), h(1, 1), h(1, 2)}, {h(2, 0), h(2, 1), h(2, 2)}};
  }

  std::optional<Site> site;
  if (!cmd.update_site.empty() && !refused) {
    SiteLoadOptions so;
    if (!data_root.empty()) so.data_root = data_root;
    const std::string flow = CalibrationFlowYaml(cal, cmd.update_site, intr_path, extr_path);
    OCCMAP_ASSIGN_OR_RETURN(SiteUpdate u, UpdateSiteCameraCalibration(cmd.update_site, cmd.camera_id, flow, so));
    OCCMAP_ASSIGN_OR_RETURN(Site loaded, LoadSite(cmd.update_site, so));
    site = std::move(loaded);
    report["site"] = {{"file", cmd.update_site}, {"backup", u.backup.string()}, {"calibration", flow}};
  }
  if (!cmd.overlay.empty()) {
    OverlayOptions oo;
    if (site) {
      oo.area_min_m = {site->grid.origin_x_m, site->grid.origin_y_m};
      oo.area_max_m = {site->grid.origin_x_m + site->grid.size_x_m(), site->grid.origin_y_m + site->grid.size_y_m()};
    } else {
      OverlayAreaAroundPoints(pts, oo);
    }
    oo.caption = fmt::format("{} ({}): RMS {:.2f} px, floor RMS {:.3f} m, {} points", cmd.camera_id, cal.kind(),
                             cal.rms_reprojection_px, cal.rms_floor_m, pts.size());
    const Image<Rgb8> pic = DrawCalibrationOverlay(picture->view(), *model, pts, oo);
    OCCMAP_RETURN_IF_ERROR(WritePng(cmd.overlay, pic.view()));
    files["overlay"] = cmd.overlay;
  }
  files["report"] = report_path.string();
  report["files"] = files;
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(report_path, report.dump(2) + "\n"));

  std::string refusal;
  if (refused) {
    refusal = fmt::format("{}: not used{}: ", cmd.points_file, cmd.update_site.empty() ? "" : fmt::format(
                                                                   " ({} left as it is)", cmd.update_site));
    for (size_t i = 0; i < concerns.size(); ++i) refusal += (i ? "; " : "") + concerns[i];
    refusal += ". Correct or remove the points named, or give --force to use the fit anyway";
  }
  if (cmd.json_to_stdout) {
    fmt::print("{}\n", report.dump(2));
    return refused ? InvalidInput(refusal) : Status::Ok();
  }
  fmt::print("camera {}: {} from {} floor points ({}x{})\n", cmd.camera_id, cal.kind(), pts.size(),
             cal.image_size.width, cal.image_size.height);
  // "others px": the point's error under the fit of all the others (leave-one-out).
  fmt::print("  #  {:<24} {:>18} {:>18} {:>10} {:>10} {:>10}\n", "point", "pixel", "floor (m)", "error px", "floor m",
             "others px");
  for (size_t i = 0; i < pts.size(); ++i) {
    const FloorPointError& e = cal.errors[i];
    const double loo = i < cal.predicted_error_px.size() ? cal.predicted_error_px[i] : std::nan("");
    const bool outlier = std::find(cal.outliers.begin(), cal.outliers.end(), i) != cal.outliers.end();
    fmt::print("{:3d}  {:<24} {:>18} {:>18} {:>10.2f} {:>10.3f} {:>10}{}\n", i + 1,
               pts[i].label.empty() ? pts[i].where : pts[i].where + " " + pts[i].label,
               fmt::format("({:.1f}, {:.1f})", pts[i].pixel.x(), pts[i].pixel.y()),
               fmt::format("({:.3f}, {:.3f})", pts[i].floor_m.x(), pts[i].floor_m.y()), e.reprojection_px, e.floor_m,
               std::isfinite(loo) ? fmt::format("{:.2f}", loo) : "-", outlier ? "  OUTLIER" : "");
  }
  fmt::print("reprojection RMS {:.2f} px (max {:.2f}); floor RMS {:.3f} m (max {:.3f})\n", cal.rms_reprojection_px,
             cal.max_reprojection_px, cal.rms_floor_m, cal.max_floor_m);
  if (cal.pinhole) {
    const Eigen::Vector3d c = *model->CenterInWorld();
    fmt::print("camera centre ({:.3f}, {:.3f}, {:.3f}) m\n", c.x(), c.y(), c.z());
    if (cal.lens_fitted) {
      fmt::print("lens fitted to the points: focal length {:.1f} px, k1 {:.4f}, k2 {:.4f}\n", cal.pinhole->fx_px,
                 cal.pinhole->distortion[0], cal.pinhole->distortion[1]);
    }
  }
  if (!cal.outliers.empty()) {
    fmt::print("without the {} outlier{}: reprojection RMS {:.2f} px, floor RMS {:.3f} m\n", cal.outliers.size(),
               cal.outliers.size() == 1 ? "" : "s", cal.rms_without_outliers_px, cal.rms_floor_without_outliers_m);
  }
  if (!cal.outlier_note.empty()) fmt::print("note: {}\n", cal.outlier_note);
  for (const auto& w : cal.warnings) fmt::print("warning: {}\n", w);
  if (!refused) {
    for (const auto& c : concerns) fmt::print("warning (--force): {}\n", c);
  }
  for (const auto& [k, v] : files.items()) fmt::print("wrote {}: {}\n", k, v.get<std::string>());
  for (const auto& b : kept) fmt::print("kept the file replaced as {}\n", b.get<std::string>());
  if (refused) return InvalidInput(refusal);
  if (report.contains("site")) {
    fmt::print("{}: camera {}'s calibration replaced (previous file: {})\n", cmd.update_site, cmd.camera_id,
               report["site"]["backup"].get<std::string>());
  }
  return Status::Ok();
}

}  // namespace occmap
