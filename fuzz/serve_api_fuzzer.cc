// Fuzz target: the JSON bodies of `occmap serve`'s POST and PUT routes (serve/serve_session.h):
// POST /api/calibrate, POST /api/board/views, POST /api/board/calibrate, PUT /api/site, each
// parsed as serve/web_server.cc parses it, on a session of a small site written afresh per
// input: camera "top" a homography, camera "lens" OpenCV intrinsics and pose (2 m above the
// floor's middle, looking down), both 160x120, no sources (the pipeline a saved site restarts
// stops at once).
//
// Input: requests separated by NUL bytes (at most 6), each "METHOD PATH\nBODY", so that one
// input can add board views and then calibrate, or calibrate and then save the site. Bodies are
// parsed by ParseJsonBody (web_api.h) as the server parses them; fuzz/dict/serve_api.dict holds
// the routes, keys and runs of brackets for depth. The routes that take a camera (and a view)
// from the query have "CAMERA [INDEX]" as their body: GET and DELETE /api/board/views, GET
// /api/board/view.jpg, and the grid picture of a camera's pending calibration (GET
// /api/cameras/ID/frame.jpg?overlay=grid&calibration=pending, written "GET grid.jpg").
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <utility>

#include "fuzz/fuzz_util.h"
#include "occmap/serve/serve_session.h"
#include "occmap/serve/web_api.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::string_view kSite = R"(version: 1
name: fuzz
floor: {origin_m: [0, 0], size_m: [1.6, 1.2], cell_size_m: 0.1}
cameras:
  - id: top
    calibration:
      format: homography
      unit: cm
      image_size: [160, 120]
      floor_from_image: [[1, 0, 0], [0, -1, 119], [0, 0, 1]]
  - id: lens
    calibration: {format: opencv, intrinsic: intr.xml, extrinsic: extr.xml, unit: m}
)";

constexpr std::string_view kIntrinsics = R"(<?xml version="1.0"?>
<opencv_storage>
<camera_matrix type_id="opencv-matrix"><rows>3</rows><cols>3</cols><dt>d</dt>
<data>87.5 0. 79.5 0. 87.5 59.5 0. 0. 1.</data></camera_matrix>
<distortion_coefficients type_id="opencv-matrix"><rows>1</rows><cols>5</cols><dt>d</dt>
<data>-0.16 0.035 0. 0. 0.</data></distortion_coefficients>
<image_width>160</image_width><image_height>120</image_height>
</opencv_storage>
)";

constexpr std::string_view kExtrinsics = R"(<?xml version="1.0"?>
<opencv_storage>
<rvec type_id="opencv-matrix"><rows>3</rows><cols>1</cols><dt>d</dt>
<data>3.14159265358979 0. 0.</data></rvec>
<tvec type_id="opencv-matrix"><rows>3</rows><cols>1</cols><dt>d</dt>
<data>-0.8 0.6 2.</data></tvec>
</opencv_storage>
)";

// What serve/web_server.cc sends back: the result, or {"error": message}, dumped as the server
// dumps it (bytes that are not UTF-8 as U+FFFD: a camera id from the query may hold any).
// OCCMAP_FUZZ_VERBOSE=1 prints them (to check what a seed reaches).
void Reply(const occmap::Result<json>& r) {
  const std::string text =
      (r.ok() ? *r : json{{"error", r.status().message()}}).dump(-1, ' ', false, json::error_handler_t::replace);
  if (std::getenv("OCCMAP_FUZZ_VERBOSE") != nullptr) std::fprintf(stderr, "%.300s\n", text.c_str());
}

// "CAMERA [INDEX]": the camera and the view (-1: none given, or not a number 0..1000 as the
// server requires).
std::pair<std::string, int> CameraAndIndex(std::string_view text) {
  const size_t space = text.find(' ');
  std::string camera(text.substr(0, space));
  if (space == std::string_view::npos) return {camera, -1};
  const std::string number(text.substr(space + 1));
  char* end = nullptr;
  const long n = std::strtol(number.c_str(), &end, 10);
  if (number.empty() || *end != '\0' || n < 0 || n > 1000) return {camera, -1};
  return {camera, static_cast<int>(n)};
}

void ReplyBytes(const occmap::Result<std::string>& r) {
  if (!r.ok()) (void)json{{"error", r.status().message()}}.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // The site as it was: a saved site rewrote it and wrote a backup and calib/ beside it.
  const fs::path dir = occmap::fuzz::ScratchDir() / "serve";
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir);
  occmap::fuzz::WriteScratch("serve/site.yaml", kSite);
  occmap::fuzz::WriteScratch("serve/intr.xml", kIntrinsics);
  occmap::fuzz::WriteScratch("serve/extr.xml", kExtrinsics);

  occmap::ServeSessionOptions options;
  options.site_path = dir / "site.yaml";
  options.run.out_dir = dir / "out";
  options.threads = 1;
  options.pace = false;
  auto session = occmap::ServeSession::Create(options);
  if (!session.ok()) {  // the fixed site loads
    std::fprintf(stderr, "%s\n", session.status().message().c_str());
    std::abort();
  }
  occmap::ServeSession& s = **session;

  std::string_view rest = occmap::fuzz::AsText(data, size);
  for (int n = 0; n < 6 && !rest.empty(); ++n) {
    auto [request, next] = occmap::fuzz::SplitAtNul(rest);
    rest = next;
    const size_t eol = request.find('\n');
    const std::string_view route = request.substr(0, eol);
    const std::string_view body_text = eol == std::string_view::npos ? std::string_view() : request.substr(eol + 1);
    if (route == "GET /api/board/views" || route == "DELETE /api/board/views" || route == "GET /api/board/view.jpg" ||
        route == "GET grid.jpg") {
      const auto [camera, index] = CameraAndIndex(body_text);
      if (route == "GET /api/board/views") {
        Reply(s.BoardViews(camera));
      } else if (route == "DELETE /api/board/views") {
        Reply(s.RemoveBoardViews(camera, index));
      } else if (route == "GET /api/board/view.jpg") {
        if (index >= 0) ReplyBytes(s.BoardViewJpeg(camera, index));
      } else {
        ReplyBytes(s.GridJpeg(camera, /*pending=*/true));
      }
      continue;
    }
    // As the server parses it: nesting over 64 levels is a 400 before json::parse.
    const auto body = occmap::ParseJsonBody(body_text);
    if (!body.ok()) {
      Reply(body.status());
      continue;
    }
    if (route == "POST /api/calibrate") {
      Reply(s.Calibrate(*body));
    } else if (route == "POST /api/board/views") {
      Reply(s.AddBoardView(*body));
    } else if (route == "POST /api/board/calibrate") {
      Reply(s.CalibrateBoard(*body));
    } else if (route == "PUT /api/site") {
      Reply(s.UpdateSite(*body));
    }
    (void)s.SiteJson().dump();  // GET /api/site, as the pages read it after a save
  }
  s.Stop();
  return 0;
}
