#include "occmap/serve/serve_session.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "occmap/calib/calibration_overlay.h"
#include "occmap/calib/opencv_storage.h"
#include "occmap/geometry/pinhole_camera.h"
#include "occmap/serve/web_api.h"
#include "occmap/site/site_update.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/text_guard.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

Result<double> Number(const json& j, const std::string& where) {
  if (!j.is_number()) return InvalidInput(fmt::format("{}: expected a number, found {}", where, Excerpt(j.dump())));
  const double v = j.get<double>();
  if (!std::isfinite(v)) return InvalidInput(fmt::format("{}: expected a finite number", where));
  return v;
}

Result<std::array<double, 2>> Pair(const json& j, const std::string& where) {
  if (!j.is_array() || j.size() != 2) return InvalidInput(fmt::format("{}: expected [x, y], found {}", where, Excerpt(j.dump())));
  OCCMAP_ASSIGN_OR_RETURN(double a, Number(j[0], where + "[0]"));
  OCCMAP_ASSIGN_OR_RETURN(double b, Number(j[1], where + "[1]"));
  return std::array<double, 2>{a, b};
}

Result<std::string> PolygonFlow(const json& j, const std::string& where) {
  if (!j.is_array()) return InvalidInput(fmt::format("{}: expected a polygon [[x, y], ...], found {}", where, Excerpt(j.dump())));
  std::string out = "[";
  for (size_t i = 0; i < j.size(); ++i) {
    OCCMAP_ASSIGN_OR_RETURN(auto p, Pair(j[i], fmt::format("{}[{}]", where, i)));
    out += fmt::format("{}[{}, {}]", i ? ", " : "", p[0], p[1]);
  }
  return out + "]";
}

Result<std::string> NameFlow(const json& j, const std::string& where) {
  if (!j.is_string() || j.get<std::string>().empty()) {
    return InvalidInput(fmt::format("{}: expected a non-empty string, found {}", where, Excerpt(j.dump())));
  }
  return j.dump();  // a JSON string is a YAML double-quoted scalar
}

Result<std::string> ZonesFlow(const json& zones) {
  if (!zones.is_array()) return InvalidInput(fmt::format("zones: expected a list, found {}", Excerpt(zones.dump())));
  std::string out = "[";
  for (size_t i = 0; i < zones.size(); ++i) {
    const json& z = zones[i];
    const std::string where = fmt::format("zones[{}]", i);
    if (!z.is_object() || !z.contains("name") || !z.contains("polygon_m")) {
      return InvalidInput(fmt::format("{}: expected {{\"name\", \"polygon_m\"}}, found {}", where, Excerpt(z.dump())));
    }
    OCCMAP_ASSIGN_OR_RETURN(std::string name, NameFlow(z["name"], where + ".name"));
    OCCMAP_ASSIGN_OR_RETURN(std::string poly, PolygonFlow(z["polygon_m"], where + ".polygon_m"));
    out += fmt::format("{}{{name: {}, polygon: {}", i ? ", " : "", name, poly);
    if (z.contains("dwell_s") && !z["dwell_s"].is_null()) {
      OCCMAP_ASSIGN_OR_RETURN(double d, Number(z["dwell_s"], where + ".dwell_s"));
      out += fmt::format(", dwell_s: {}", d);
    }
    out += "}";
  }
  return out + "]";
}

Result<std::string> LinesFlow(const json& lines) {
  if (!lines.is_array()) return InvalidInput(fmt::format("lines: expected a list, found {}", Excerpt(lines.dump())));
  std::string out = "[";
  for (size_t i = 0; i < lines.size(); ++i) {
    const json& l = lines[i];
    const std::string where = fmt::format("lines[{}]", i);
    if (!l.is_object() || !l.contains("name") || !l.contains("a_m") || !l.contains("b_m")) {
      return InvalidInput(fmt::format("{}: expected {{\"name\", \"a_m\", \"b_m\"}}, found {}", where, Excerpt(l.dump())));
    }
    OCCMAP_ASSIGN_OR_RETURN(std::string name, NameFlow(l["name"], where + ".name"));
    OCCMAP_ASSIGN_OR_RETURN(auto a, Pair(l["a_m"], where + ".a_m"));
    OCCMAP_ASSIGN_OR_RETURN(auto b, Pair(l["b_m"], where + ".b_m"));
    out += fmt::format("{}{{name: {}, from: [{}, {}], to: [{}, {}]", i ? ", " : "", name, a[0], a[1], b[0], b[1]);
    // Absent: the loader's defaults (tracker_options.h), as a line written by hand.
    if (l.contains("hysteresis_m") && !l["hysteresis_m"].is_null()) {
      OCCMAP_ASSIGN_OR_RETURN(double band, Number(l["hysteresis_m"], where + ".hysteresis_m"));
      out += fmt::format(", hysteresis_m: {}", band);
    }
    if (l.contains("once_per_track") && !l["once_per_track"].is_null()) {
      if (!l["once_per_track"].is_boolean()) {
        return InvalidInput(fmt::format("{}.once_per_track: expected true or false, found {}", where,
                                        Excerpt(l["once_per_track"].dump())));
      }
      out += fmt::format(", once_per_track: {}", l["once_per_track"].get<bool>());
    }
    out += "}";
  }
  return out + "]";
}

json Finite(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

bool SafeId(const std::string& id) {
  if (id.empty()) return false;
  for (char c : id) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-' && c != '.') return false;
  }
  return id.front() != '.';
}

json IntrinsicsJson(const CameraIntrinsics& in) {
  return {{"width_px", in.image_size.width}, {"height_px", in.image_size.height}, {"fx_px", in.fx_px},
          {"fy_px", in.fy_px}, {"cx_px", in.cx_px}, {"cy_px", in.cy_px}, {"distortion", in.distortion}};
}

// The board of a request: {"kind", "cols", "rows", "square_m", "marker_m"?, "dictionary"?,
// "max_blur_px"?}, checked by IntrinsicsOptions::Validate.
Result<IntrinsicsOptions> BoardOptionsFromJson(const json& j) {
  if (!j.is_object()) {
    return InvalidInput(fmt::format("board: expected {{\"kind\", \"cols\", \"rows\", \"square_m\"}}, found {}", Excerpt(j.dump())));
  }
  IntrinsicsOptions o;
  BoardOptions& b = o.board;
  if (j.contains("kind") && !j["kind"].is_string()) {
    return InvalidInput(fmt::format("board.kind: expected \"checkerboard\" or \"charuco\", found {}", Excerpt(j["kind"].dump())));
  }
  const std::string kind = j.value("kind", std::string("checkerboard"));
  if (kind == "charuco") {
    b.kind = BoardKind::kCharuco;
  } else if (kind != "checkerboard") {
    return InvalidInput(fmt::format("board.kind: expected \"checkerboard\" or \"charuco\", found \"{}\"", Excerpt(kind)));
  }
  auto integer = [&](const char* key, int& out) -> Status {
    if (!j.contains(key)) return InvalidInput(fmt::format("board.{}: missing", key));
    if (!j[key].is_number_integer()) return InvalidInput(fmt::format("board.{}: expected a whole number, found {}", key, Excerpt(j[key].dump())));
    out = j[key].get<int>();
    return Status::Ok();
  };
  OCCMAP_RETURN_IF_ERROR(integer("cols", b.cols));
  OCCMAP_RETURN_IF_ERROR(integer("rows", b.rows));
  if (!j.contains("square_m")) return InvalidInput("board.square_m: missing");
  OCCMAP_ASSIGN_OR_RETURN(b.square_m, Number(j["square_m"], "board.square_m"));
  if (j.contains("marker_m") && !j["marker_m"].is_null()) {
    OCCMAP_ASSIGN_OR_RETURN(b.marker_m, Number(j["marker_m"], "board.marker_m"));
  }
  if (j.contains("dictionary")) {
    if (!j["dictionary"].is_string()) return InvalidInput("board.dictionary: expected a name such as \"4x4_50\"");
    b.dictionary = j["dictionary"].get<std::string>();
  }
  if (j.contains("max_blur_px")) {
    OCCMAP_ASSIGN_OR_RETURN(o.max_blur_px, Number(j["max_blur_px"], "board.max_blur_px"));
  }
  OCCMAP_RETURN_IF_ERROR(o.Validate().WithContext("board"));
  return o;
}

json BoardViewJson(const BoardView& v, const Image<uint8_t>& image, bool used) {
  return {{"name", v.name},         {"accepted", v.reason.empty()}, {"used", used},
          {"reason", v.reason},     {"corners", v.corners},          {"blur_px", Finite(v.blur_px)},
          {"board_fraction", Finite(v.board_fraction)}, {"tilt_deg", Finite(v.tilt_deg)},
          {"rms_px", used ? Finite(v.rms_px) : json(nullptr)}, {"width_px", image.width()},
          {"height_px", image.height()}};
}

}  // namespace

ServeSession::ServeSession(ServeSessionOptions options)
    : options_(std::move(options)), state_(std::make_shared<LiveState>()), ctx_(options_.threads) {}

ServeSession::~ServeSession() { Stop(); }

Result<std::unique_ptr<ServeSession>> ServeSession::Create(ServeSessionOptions options) {
  std::unique_ptr<ServeSession> s(new ServeSession(std::move(options)));
  OCCMAP_ASSIGN_OR_RETURN(s->site_, s->LoadCurrentSite());
  OCCMAP_ASSIGN_OR_RETURN(s->site_text_, ReadFileToString(s->options_.site_path));
  return s;
}

Result<std::shared_ptr<const Site>> ServeSession::LoadCurrentSite() const {
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(options_.site_path, options_.load));
  if (options_.adjust_site) OCCMAP_RETURN_IF_ERROR(options_.adjust_site(site));
  return std::make_shared<const Site>(std::move(site));
}

std::shared_ptr<const Site> ServeSession::site() const {
  std::lock_guard lock(mu_);
  return site_;
}

void ServeSession::Start() {
  std::lock_guard lock(run_mu_);
  StartLocked();
}

void ServeSession::Stop() {
  std::lock_guard lock(run_mu_);
  StopLocked();
}

void ServeSession::StopLocked() {
  stop_run_ = true;
  if (thread_.joinable()) thread_.join();
  stop_run_ = false;
}

void ServeSession::StartLocked() {
  std::shared_ptr<const Site> site = this->site();
  state_->SetStarting();
  thread_ = std::thread([this, site] {
    RunOptions o = options_.run;
    o.sink_frames = true;
    o.stop = &stop_run_;
    o.sinks.insert(o.sinks.begin(), std::make_shared<LiveStateSink>(state_));
    // Pacing: the progress callback (the run's post stage) waits for the frame's time, which
    // holds the reader back through the run's bounded queues.
    // Live streams come at their own rate: only files are paced.
    bool files = true;
    for (const SiteCamera& c : site->cameras) files = files && c.source.kind != FrameSourceSpec::Kind::kStream;
    ProgressCallback progress;
    if (options_.pace && files) {
      // From the first frame set on (tables and backgrounds take their time before it).
      progress = [this, t0 = std::optional<std::chrono::steady_clock::time_point>()](const RunProgress& p) mutable {
        const auto now = std::chrono::steady_clock::now();
        if (!t0) t0 = now;
        const double fps = state_->fps() > 0 ? state_->fps() : 10.0;
        const auto due = *t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                   std::chrono::duration<double>(static_cast<double>(p.frames_done - 1) / fps));
        while (!stop_run_.load() && std::chrono::steady_clock::now() < due) {
          std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(
              due - std::chrono::steady_clock::now(), std::chrono::milliseconds(50)));
        }
      };
    }
    auto summary = RunSite(*site, o, ctx_, progress);
    std::lock_guard lock(mu_);
    if (summary.ok()) {
      summary_ = *summary;
      error_ = Status::Ok();
      state_->SetRunning(false, summary->stop_reason);
    } else {
      error_ = summary.status();
      state_->SetRunning(false, "error: " + summary.status().message());
      std::fputs(fmt::format("occmap serve: the pipeline stopped: {}\n", summary.status().message()).c_str(), stderr);
    }
    state_->Wake();
  });
}

std::optional<RunSummary> ServeSession::last_summary() const {
  std::lock_guard lock(mu_);
  return summary_;
}

Status ServeSession::last_error() const {
  std::lock_guard lock(mu_);
  return error_;
}

json ServeSession::SiteJson() const {
  std::lock_guard lock(mu_);
  return occmap::SiteJson(*site_, site_text_);
}

json ServeSession::StatsJson() const {
  auto text = ReadFileToString(options_.run.out_dir / "summary.json");
  if (!text.ok()) return json::object();
  json j = json::parse(*text, nullptr, false);
  return j.is_discarded() ? json::object() : j;
}

Result<json> ServeSession::Calibrate(const json& body) {
  if (!body.is_object()) return InvalidInput("expected a JSON object {\"camera\", \"points\", \"method\"}");
  if (!body.contains("camera") || !body["camera"].is_string()) return InvalidInput("camera: expected a camera id");
  const std::string id = body["camera"].get<std::string>();
  const std::shared_ptr<const Site> site = this->site();
  const SiteCamera* cam = nullptr;
  for (const SiteCamera& c : site->cameras) {
    if (c.id == id) cam = &c;
  }
  if (cam == nullptr) return InvalidInput(fmt::format("camera: no camera '{}' in the site", Excerpt(id)));
  if (!body.contains("points") || !body["points"].is_array()) {
    return InvalidInput("points: expected a list of {\"u_px\", \"v_px\", \"x_m\", \"y_m\"}");
  }
  std::vector<FloorPoint> points;
  for (size_t i = 0; i < body["points"].size(); ++i) {
    const json& p = body["points"][i];
    const std::string where = fmt::format("points[{}]", i);
    if (!p.is_object()) return InvalidInput(fmt::format("{}: expected an object, found {}", where, Excerpt(p.dump())));
    FloorPoint fp;
    double v[4];
    const char* keys[4] = {"u_px", "v_px", "x_m", "y_m"};
    for (int k = 0; k < 4; ++k) {
      if (!p.contains(keys[k])) return InvalidInput(fmt::format("{}.{}: missing", where, keys[k]));
      OCCMAP_ASSIGN_OR_RETURN(v[k], Number(p[keys[k]], fmt::format("{}.{}", where, keys[k])));
    }
    fp.pixel = {v[0], v[1]};
    fp.floor_m = {v[2], v[3]};
    if (p.contains("label") && p["label"].is_string()) fp.label = p["label"].get<std::string>();
    fp.where = where;
    points.push_back(std::move(fp));
  }
  const auto* pinhole = dynamic_cast<const PinholeCamera*>(cam->camera.get());
  // Intrinsics from board views made in the page come before the site's.
  std::optional<CameraIntrinsics> board;
  {
    std::lock_guard lock(mu_);
    if (auto it = boards_.find(id); it != boards_.end() && it->second.calibration) {
      board = it->second.calibration->intrinsics;
    }
  }
  // Without intrinsics a lens fit from 8 points: the wide lenses of cheap cameras defeat a homography.
  std::string method = pinhole != nullptr || board ? "pnp" : points.size() >= 8 ? "lens" : "homography";
  if (body.contains("method")) {
    if (!body["method"].is_string()) return InvalidInput("method: expected \"pnp\", \"lens\" or \"homography\"");
    method = body["method"].get<std::string>();
  }
  FloorCalibrationOptions fo;
  fo.image_size = cam->camera->image_size();
  std::string intrinsics_from;
  if (method == "pnp" && board) {
    fo.intrinsics = *board;
    intrinsics_from = "board";
  } else if (method == "pnp") {
    intrinsics_from = "site";
    if (pinhole == nullptr) {
      return InvalidInput(fmt::format("method: pnp needs the camera's intrinsics; camera '{}' has a {} calibration "
                                      "(calibrate its lens from board views first, or use \"lens\" or \"homography\")",
                                      id, cam->calibration_format));
    }
    const PinholeParameters& p = pinhole->params();
    CameraIntrinsics in;
    in.image_size = p.image_size;
    in.fx_px = p.fx_px;
    in.fy_px = p.fy_px;
    in.cx_px = p.cx_px;
    in.cy_px = p.cy_px;
    in.skew_px = p.skew_px;
    in.distortion = p.distortion;
    fo.intrinsics = in;
  } else if (method == "lens") {
    fo.fit_lens = true;
    intrinsics_from = "points";
  } else if (method != "homography") {
    return InvalidInput(fmt::format("method: expected \"pnp\", \"lens\" or \"homography\", found \"{}\"", Excerpt(method)));
  }
  OCCMAP_ASSIGN_OR_RETURN(FloorCalibration cal, CalibrateFromFloorPoints(points, fo));
  json jp = json::array();
  for (size_t i = 0; i < points.size(); ++i) {
    const FloorPointError& e = cal.errors[i];
    jp.push_back({{"u_px", points[i].pixel.x()}, {"v_px", points[i].pixel.y()}, {"x_m", points[i].floor_m.x()},
                  {"y_m", points[i].floor_m.y()}, {"error_px", Finite(e.reprojection_px)},
                  {"floor_error_m", Finite(e.floor_m)},
                  {"reprojected_px", {Finite(e.reprojected_px.x()), Finite(e.reprojected_px.y())}},
                  {"predicted_error_px", i < cal.predicted_error_px.size() ? Finite(cal.predicted_error_px[i]) : json(nullptr)},
                  {"outlier", std::find(cal.outliers.begin(), cal.outliers.end(), i) != cal.outliers.end()}});
  }
  json outliers = json::array();
  for (size_t i : cal.outliers) outliers.push_back(i);
  const std::vector<std::string> concerns = CalibrationConcerns(cal, points, kMaxUpdateRmsPx);
  json out = {{"camera", id},
              {"method", method},
              {"kind", cal.kind()},
              {"rms_px", Finite(cal.rms_reprojection_px)},
              {"max_px", Finite(cal.max_reprojection_px)},
              {"floor_rms_m", Finite(cal.rms_floor_m)},
              {"floor_max_m", Finite(cal.max_floor_m)},
              {"points", jp},
              {"warnings", cal.warnings},
              {"outliers", outliers},
              {"outliers_checked", cal.outliers_checked},
              {"outlier_note", cal.outlier_note},
              {"rms_without_outliers_px", Finite(cal.rms_without_outliers_px)},
              {"floor_rms_without_outliers_m", Finite(cal.rms_floor_without_outliers_m)},
              // What Save warns of (PUT /api/site refuses it without "force": true).
              {"concerns", concerns},
              {"max_rms_px", kMaxUpdateRmsPx},
              {"lens_fitted", cal.lens_fitted},
              {"intrinsics_from", intrinsics_from.empty() ? json(nullptr) : json(intrinsics_from)},
              {"overlay_url", fmt::format("/api/cameras/{}/frame.jpg?overlay=grid&calibration=pending", id)}};
  if (cal.pinhole) {
    const PinholeParameters& p = *cal.pinhole;
    out["intrinsics"] = {{"fx_px", p.fx_px}, {"fy_px", p.fy_px}, {"cx_px", p.cx_px}, {"cy_px", p.cy_px},
                         {"distortion", p.distortion}};
  }
  std::lock_guard lock(mu_);
  pending_[id] = Pending{std::move(cal), std::move(points)};
  return out;
}

const SiteCamera* ServeSession::FindCamera(const Site& site, const std::string& camera_id) const {
  for (const SiteCamera& c : site.cameras) {
    if (c.id == camera_id) return &c;
  }
  return nullptr;
}

json ServeSession::BoardJsonLocked(const std::string& camera_id, const BoardSet& b) const {
  json views = json::array();
  for (size_t i = 0; i < b.images.size(); ++i) {
    json v = BoardViewJson(b.inspected[i], *b.images[i], b.used[i]);
    const std::optional<ImageSize>& from = b.scaled_from[i];
    v["scaled_from_px"] = from ? json::array({from->width, from->height}) : json(nullptr);
    views.push_back(std::move(v));
  }
  json out = {{"camera", camera_id}, {"views", views}, {"max_views", kMaxBoardViews}, {"calibration", nullptr}};
  if (b.calibration) {
    out["calibration"] = {{"rms_px", Finite(b.calibration->rms_px)}, {"views_used", b.calibration->views_used},
                          {"intrinsics", IntrinsicsJson(b.calibration->intrinsics)},
                          {"warnings", b.calibration->warnings}};
  }
  return out;
}

Result<json> ServeSession::BoardViews(const std::string& camera_id) {
  const std::shared_ptr<const Site> site = this->site();
  if (FindCamera(*site, camera_id) == nullptr) return NotFound(fmt::format("no camera '{}'", Excerpt(camera_id)));
  std::lock_guard lock(mu_);
  auto it = boards_.find(camera_id);
  return BoardJsonLocked(camera_id, it == boards_.end() ? BoardSet{} : it->second);
}

Result<json> ServeSession::AddBoardView(const json& body) {
  if (!body.is_object()) return InvalidInput("expected a JSON object {\"camera\", \"board\", \"capture\" or \"image\"}");
  if (!body.contains("camera") || !body["camera"].is_string()) return InvalidInput("camera: expected a camera id");
  const std::string id = body["camera"].get<std::string>();
  const std::shared_ptr<const Site> site = this->site();
  const SiteCamera* cam = FindCamera(*site, id);
  if (cam == nullptr) return InvalidInput(fmt::format("camera: no camera '{}' in the site", Excerpt(id)));
  const ImageSize camera_size = cam->camera->image_size();
  if (!body.contains("board")) return InvalidInput("board: missing");
  OCCMAP_ASSIGN_OR_RETURN(IntrinsicsOptions options, BoardOptionsFromJson(body["board"]));
  if (body.contains("capture") && !body["capture"].is_boolean()) {
    return InvalidInput(fmt::format("capture: expected true or false, found {}", Excerpt(body["capture"].dump())));
  }
  const bool capture = body.value("capture", false);
  if (capture == body.contains("image")) {
    return InvalidInput("expected either \"capture\": true (the camera's current frame) or \"image\" (base64 PNG or JPEG)");
  }
  auto gray = std::make_shared<Image<uint8_t>>();
  std::string name;
  if (capture) {
    const std::shared_ptr<const LiveSnapshot> snap = state_->Latest();
    size_t n = snap->camera_ids.size();
    for (size_t i = 0; i < snap->camera_ids.size(); ++i) {
      if (snap->camera_ids[i] == id) n = i;
    }
    if (n == snap->camera_ids.size() || n >= snap->frames_gray.size() || snap->frames_gray[n].empty()) {
      return InvalidInput(fmt::format("capture: camera '{}' has no frame yet", id));
    }
    const Image<uint8_t>& f = snap->frames_gray[n];
    *gray = Image<uint8_t>(f.width(), f.height());
    for (int y = 0; y < f.height(); ++y) std::copy(f.row(y), f.row(y) + f.width(), gray->row(y));
    name = fmt::format("frame {}", snap->frame);
  } else {
    if (!body["image"].is_string()) return InvalidInput("image: expected a base64 PNG or JPEG");
    OCCMAP_ASSIGN_OR_RETURN(std::string bytes, DecodeBase64(body["image"].get<std::string>(), "image"));
    // A 1 MB PNG may claim 30000 x 30000 pixels: its header is read before it is decoded.
    if (Status s = CheckEncodedImage(bytes, "image"); !s.ok()) return InvalidInput(s.message());
    cv::Mat decoded;
    try {
      decoded = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, bytes.data()), cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception&) {
      decoded = cv::Mat();
    }
    if (decoded.empty()) return InvalidInput("image: not a picture OpenCV reads (expected PNG or JPEG)");
    *gray = Image<uint8_t>(decoded.cols, decoded.rows);
    for (int y = 0; y < decoded.rows; ++y) std::copy_n(decoded.ptr<uint8_t>(y), decoded.cols, gray->row(y));
    if (body.contains("name") && body["name"].is_string()) name = body["name"].get<std::string>().substr(0, 120);
  }
  // A view of another shape can never calibrate this camera: refused before it is kept, or it
  // would set the size every later view must have (one 1280x720 upload for a 640x480 camera
  // refused every correct view after it).
  const double aspect_view = static_cast<double>(gray->width()) / gray->height();
  const double aspect_camera = static_cast<double>(camera_size.width) / camera_size.height;
  if (std::abs(aspect_view / aspect_camera - 1) > 0.01) {
    return InvalidInput(fmt::format("{}: {}x{}, camera '{}' gives {}x{} pictures (another aspect ratio): a view of "
                                    "this camera's board is needed",
                                    name.empty() ? "image" : Excerpt(name), gray->width(), gray->height(), id,
                                    camera_size.width, camera_size.height));
  }
  // Inspected outside mu_ (corner detection on a large picture takes a while); board_mu_ keeps
  // the board requests one at a time.
  std::lock_guard run_lock(board_mu_);
  int number = 0;
  bool same_board = true;
  std::vector<std::string> names;
  std::vector<std::shared_ptr<const Image<uint8_t>>> images;
  {
    std::lock_guard lock(mu_);
    BoardSet& b = boards_[id];
    if (b.images.size() >= kMaxBoardViews) {
      return InvalidInput(fmt::format("camera '{}' holds {} board views already (the most kept): remove some first",
                                      id, kMaxBoardViews));
    }
    number = b.next_number++;
    const BoardOptions &was = b.options.board, &now = options.board;
    same_board = was.kind == now.kind && was.cols == now.cols && was.rows == now.rows &&
                 was.square_m == now.square_m && was.marker_m == now.marker_m && was.dictionary == now.dictionary &&
                 b.options.max_blur_px == options.max_blur_px;
    names = b.names;
    images = b.images;
  }
  if (name.empty()) name = fmt::format("view {}", number);
  // One size per set (cv::calibrateCamera's): a view of the same shape but another size (a
  // full-resolution photo beside captured frames) is scaled to the set's first view, or to the
  // camera's size when it is the first.
  const ImageSize set_size = images.empty() ? camera_size : ImageSize{images[0]->width(), images[0]->height()};
  std::optional<ImageSize> scaled_from;
  if (gray->width() != set_size.width || gray->height() != set_size.height) {
    scaled_from = ImageSize{gray->width(), gray->height()};
    const cv::Mat src(gray->height(), gray->width(), CV_8UC1, gray->view().data(),
                      static_cast<size_t>(gray->stride_elems()));
    cv::Mat dst;
    cv::resize(src, dst, cv::Size(set_size.width, set_size.height), 0, 0,
               set_size.width < gray->width() ? cv::INTER_AREA : cv::INTER_LINEAR);
    auto scaled = std::make_shared<Image<uint8_t>>(dst.cols, dst.rows);
    for (int y = 0; y < dst.rows; ++y) std::copy_n(dst.ptr<uint8_t>(y), dst.cols, scaled->row(y));
    gray = std::move(scaled);
  }
  const BoardView view = InspectBoardView({name, gray->view()}, options);
  // Another board: every view is inspected again with it.
  std::vector<BoardView> again;
  if (!same_board) {
    for (size_t i = 0; i < images.size(); ++i) again.push_back(InspectBoardView({names[i], images[i]->view()}, options));
  }
  std::lock_guard lock(mu_);
  BoardSet& b = boards_[id];
  if (!same_board) {
    if (b.images != images) return InvalidInput("board views changed meanwhile: add the view again");
    b.inspected = std::move(again);
    b.used.assign(b.images.size(), false);
    b.calibration.reset();
    b.options = options;
  }
  if (!b.images.empty() && (b.images[0]->width() != gray->width() || b.images[0]->height() != gray->height())) {
    return InvalidInput("board views changed meanwhile: add the view again");
  }
  b.names.push_back(name);
  b.images.push_back(std::move(gray));
  b.inspected.push_back(view);
  b.used.push_back(false);
  b.scaled_from.push_back(scaled_from);
  json out = BoardJsonLocked(id, b);
  out["view"] = out["views"].back();
  out["index"] = b.images.size() - 1;
  return out;
}

Result<json> ServeSession::RemoveBoardViews(const std::string& camera_id, int index) {
  const std::shared_ptr<const Site> site = this->site();
  if (FindCamera(*site, camera_id) == nullptr) return NotFound(fmt::format("no camera '{}'", Excerpt(camera_id)));
  std::lock_guard lock(mu_);
  BoardSet& b = boards_[camera_id];
  if (index < 0) {
    b = BoardSet{};
  } else {
    if (static_cast<size_t>(index) >= b.images.size()) {
      return InvalidInput(fmt::format("index: expected 0..{}, found {}", static_cast<int>(b.images.size()) - 1, index));
    }
    const auto at = static_cast<ptrdiff_t>(index);
    b.names.erase(b.names.begin() + at);
    b.images.erase(b.images.begin() + at);
    b.inspected.erase(b.inspected.begin() + at);
    b.used.erase(b.used.begin() + at);
    b.scaled_from.erase(b.scaled_from.begin() + at);
  }
  return BoardJsonLocked(camera_id, b);
}

Result<json> ServeSession::CalibrateBoard(const json& body) {
  if (!body.is_object()) return InvalidInput("expected a JSON object {\"camera\", \"board\"}");
  if (!body.contains("camera") || !body["camera"].is_string()) return InvalidInput("camera: expected a camera id");
  const std::string id = body["camera"].get<std::string>();
  const std::shared_ptr<const Site> site = this->site();
  const SiteCamera* cam = FindCamera(*site, id);
  if (cam == nullptr) return InvalidInput(fmt::format("camera: no camera '{}' in the site", Excerpt(id)));
  if (!body.contains("board")) return InvalidInput("board: missing");
  OCCMAP_ASSIGN_OR_RETURN(IntrinsicsOptions options, BoardOptionsFromJson(body["board"]));
  std::vector<std::string> names;
  std::vector<std::shared_ptr<const Image<uint8_t>>> images;
  {
    std::lock_guard lock(mu_);
    auto it = boards_.find(id);
    if (it == boards_.end() || it->second.images.empty()) {
      return InvalidInput(fmt::format("camera '{}' has no board views: capture or upload some first", id));
    }
    names = it->second.names;
    images = it->second.images;
  }
  std::lock_guard run_lock(board_mu_);
  std::vector<BoardImage> views;
  for (size_t i = 0; i < images.size(); ++i) views.push_back({names[i], images[i]->view()});
  const ImageSize camera_size = cam->camera->image_size();
  const double aspect_views = static_cast<double>(images[0]->width()) / images[0]->height();
  const double aspect_camera = static_cast<double>(camera_size.width) / camera_size.height;
  if (std::abs(aspect_views / aspect_camera - 1) > 0.01) {
    return InvalidInput(fmt::format("board views: {}x{}, the camera's images are {}x{} (another aspect ratio)",
                                    images[0]->width(), images[0]->height(), camera_size.width, camera_size.height));
  }
  auto cal = CalibrateIntrinsics(views, options);
  std::lock_guard lock(mu_);
  BoardSet& b = boards_[id];
  if (b.images != images) return InvalidInput("board views changed meanwhile: calibrate again");
  b.options = options;
  b.used.assign(b.images.size(), false);
  if (!cal.ok()) {
    // Every view's reason still goes back to the page.
    for (size_t i = 0; i < b.images.size(); ++i) b.inspected[i] = InspectBoardView(views[i], options);
    b.calibration.reset();
    json out = BoardJsonLocked(id, b);
    out["error"] = cal.status().message();
    return out;
  }
  for (size_t i = 0; i < b.images.size(); ++i) {
    b.inspected[i] = cal->views[i];
    b.used[i] = cal->views[i].used;
  }
  b.calibration = std::move(*cal);
  return BoardJsonLocked(id, b);
}

Result<std::string> ServeSession::BoardViewJpeg(const std::string& camera_id, int index) {
  std::shared_ptr<const Image<uint8_t>> image;
  BoardView view;
  {
    std::lock_guard lock(mu_);
    auto it = boards_.find(camera_id);
    if (it == boards_.end() || index < 0 || static_cast<size_t>(index) >= it->second.images.size()) {
      return NotFound(fmt::format("camera '{}' has no board view {}", camera_id, index));
    }
    image = it->second.images[static_cast<size_t>(index)];
    view = it->second.inspected[static_cast<size_t>(index)];
  }
  const cv::Mat g(image->height(), image->width(), CV_8UC1, const_cast<uint8_t*>(image->view().data()),
                  static_cast<size_t>(image->stride_elems()));
  cv::Mat bgr;
  cv::cvtColor(g, bgr, cv::COLOR_GRAY2BGR);
  const cv::Scalar colour = view.reason.empty() ? cv::Scalar(60, 200, 60) : cv::Scalar(40, 40, 230);
  const int r = std::max(2, image->width() / 200);
  for (const Eigen::Vector2d& c : view.corners_px) cv::circle(bgr, cv::Point(cvRound(c.x()), cvRound(c.y())), r, colour, -1);
  std::vector<uint8_t> buf;
  if (!cv::imencode(".jpg", bgr, buf, {cv::IMWRITE_JPEG_QUALITY, 80})) return Internal("JPEG encoding failed");
  return std::string(buf.begin(), buf.end());
}

Result<json> ServeSession::UpdateSite(const json& body) {
  if (!body.is_object()) return InvalidInput("expected a JSON object with calibrations, mask_polygons_px, zones, lines");
  for (const auto& [key, value] : body.items()) {
    (void)value;
    if (key != "calibrations" && key != "mask_polygons_px" && key != "zones" && key != "lines" && key != "force") {
      return InvalidInput(fmt::format("{}: unknown key (expected calibrations, mask_polygons_px, zones, lines, force)",
                                      Excerpt(key)));
    }
  }
  if (body.contains("force") && !body["force"].is_boolean()) {
    return InvalidInput(fmt::format("force: expected true or false, found {}", Excerpt(body["force"].dump())));
  }
  const bool force = body.value("force", false);
  std::lock_guard run_lock(run_mu_);  // one edit at a time, and the restart with it
  const fs::path& path = options_.site_path;
  OCCMAP_ASSIGN_OR_RETURN(std::string old_text, ReadFileToString(path));
  std::string text = old_text;
  std::vector<std::string> saved_pending;
  if (body.contains("calibrations")) {
    const json& cals = body["calibrations"];
    if (!cals.is_object()) return InvalidInput("calibrations: expected {\"<camera>\": \"pending\"}");
    for (const auto& [id, what] : cals.items()) {
      if (what != "pending") return InvalidInput(fmt::format("calibrations.{}: expected \"pending\"", Excerpt(id)));
      if (!SafeId(id)) return InvalidInput(fmt::format("calibrations: '{}' is not a camera id", Excerpt(id)));
      std::optional<Pending> p;
      {
        std::lock_guard lock(mu_);
        if (auto it = pending_.find(id); it != pending_.end()) p = it->second;
      }
      if (!p) return InvalidInput(fmt::format("calibrations.{}: no pending calibration (POST /api/calibrate first)", Excerpt(id)));
      // A fit with a wrong point would replace the camera's calibration with a worse one.
      if (const auto concerns = CalibrationConcerns(p->calibration, p->points, kMaxUpdateRmsPx);
          !concerns.empty() && !force) {
        std::string list;
        for (size_t i = 0; i < concerns.size(); ++i) list += (i ? "; " : "") + concerns[i];
        return InvalidInput(fmt::format("calibrations.{}: not saved: {}. Correct the points, or save with \"force\": true",
                                        id, list));
      }
      std::string flow;
      if (p->calibration.pinhole) {
        // Beside the site file, in calib/, as serve_*.xml: the files the previous site (SITE.bak)
        // names stay as they were.
        const fs::path dir = (path.parent_path().empty() ? fs::path(".") : path.parent_path()) / "calib";
        OCCMAP_RETURN_IF_ERROR(EnsureDirectory(dir));
        const fs::path intr = dir / fmt::format("serve_intr_{}.xml", id), extr = dir / fmt::format("serve_extr_{}.xml", id);
        OCCMAP_RETURN_IF_ERROR(WriteOpenCvCalibration(*p->calibration.pinhole, 1.0, intr, extr));
        OCCMAP_ASSIGN_OR_RETURN(std::string ri, SitePathFor(path, intr));
        OCCMAP_ASSIGN_OR_RETURN(std::string re, SitePathFor(path, extr));
        flow = fmt::format("{{format: opencv, intrinsic: {}, extrinsic: {}, unit: m, forward: +z}}", json(ri).dump(),
                           json(re).dump());
      } else {
        flow = HomographyCalibrationYaml(*p->calibration.floor_from_image, p->calibration.image_size);
      }
      OCCMAP_ASSIGN_OR_RETURN(text, SetCameraValue(text, path, id, "calibration", flow));
      saved_pending.push_back(id);
    }
  }
  if (body.contains("mask_polygons_px")) {
    const json& masks = body["mask_polygons_px"];
    if (!masks.is_object()) return InvalidInput("mask_polygons_px: expected {\"<camera>\": [[[u, v], ...], ...]}");
    for (const auto& [id, polys] : masks.items()) {
      const std::string where = "mask_polygons_px." + Excerpt(id);
      if (!polys.is_array()) {
        return InvalidInput(fmt::format("{}: expected a list of polygons [[[u, v], ...], ...]", where));
      }
      if (polys.empty()) {  // no polygon: no mask, every pixel is floor
        OCCMAP_ASSIGN_OR_RETURN(text, SetCameraValue(text, path, id, "mask", ""));
        continue;
      }
      std::string flow = "{polygons: [";
      for (size_t i = 0; i < polys.size(); ++i) {
        OCCMAP_ASSIGN_OR_RETURN(std::string poly, PolygonFlow(polys[i], fmt::format("{}[{}]", where, i)));
        flow += (i ? ", " : "") + poly;
      }
      flow += "]}";
      OCCMAP_ASSIGN_OR_RETURN(text, SetCameraValue(text, path, id, "mask", flow));
    }
  }
  if (body.contains("zones")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string flow, ZonesFlow(body["zones"]));
    OCCMAP_ASSIGN_OR_RETURN(text, SetTrackingValue(text, path, "zones", flow));
  }
  if (body.contains("lines")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string flow, LinesFlow(body["lines"]));
    OCCMAP_ASSIGN_OR_RETURN(text, SetTrackingValue(text, path, "lines", flow));
  }
  OCCMAP_ASSIGN_OR_RETURN(SiteUpdate u, WriteSiteText(path, old_text, text, options_.load));
  OCCMAP_ASSIGN_OR_RETURN(std::shared_ptr<const Site> site, LoadCurrentSite());
  StopLocked();
  state_->SetCoverage(nullptr);  // the new site's tables replace it once they are ready
  {
    std::lock_guard lock(mu_);
    site_ = std::move(site);
    site_text_ = u.text;
    for (const auto& id : saved_pending) pending_.erase(id);
  }
  ++site_version_;
  StartLocked();
  state_->Wake();
  return json{{"ok", true}, {"backup", u.backup.string()}, {"site", SiteJson()}};
}

Result<std::string> ServeSession::MaskPng(const std::string& camera_id) {
  const std::shared_ptr<const Site> site = this->site();
  const SiteCamera* cam = FindCamera(*site, camera_id);
  if (cam == nullptr) return NotFound(fmt::format("no camera '{}'", Excerpt(camera_id)));
  if (cam->mask.empty()) return NotFound(fmt::format("camera '{}' has no mask", camera_id));
  std::string png = MaskOverlayPng(cam->mask);
  if (png.empty()) return Internal("PNG encoding failed");
  return png;
}

Result<std::string> ServeSession::GridJpeg(const std::string& camera_id, bool pending) {
  const std::shared_ptr<const Site> site = this->site();
  size_t n = site->cameras.size();
  for (size_t i = 0; i < site->cameras.size(); ++i) {
    if (site->cameras[i].id == camera_id) n = i;
  }
  if (n == site->cameras.size()) return NotFound(fmt::format("no camera '{}'", Excerpt(camera_id)));
  const std::shared_ptr<const LiveSnapshot> snap = state_->Latest();
  Image<Rgb8> picture = CameraRgb(*snap, n);
  if (picture.empty()) return NotFound(fmt::format("camera '{}' has no frame yet", camera_id));
  std::unique_ptr<CameraModel> model;
  std::vector<FloorPoint> points;
  if (pending) {
    std::optional<Pending> p;
    {
      std::lock_guard lock(mu_);
      if (auto it = pending_.find(camera_id); it != pending_.end()) p = it->second;
    }
    if (!p) return NotFound(fmt::format("camera '{}' has no pending calibration", camera_id));
    OCCMAP_ASSIGN_OR_RETURN(model, p->calibration.Model());
    points = p->points;
  }
  const CameraModel& camera = model ? *model : *site->cameras[n].camera;
  OverlayOptions oo;
  oo.area_min_m = {site->grid.origin_x_m, site->grid.origin_y_m};
  oo.area_max_m = {site->grid.origin_x_m + site->grid.size_x_m(), site->grid.origin_y_m + site->grid.size_y_m()};
  oo.caption = fmt::format("{}{}", camera_id, pending ? " (pending)" : "");
  const Image<Rgb8> drawn = DrawCalibrationOverlay(picture.view(), camera, points, oo);
  return EncodeJpeg(drawn);
}

}  // namespace occmap
