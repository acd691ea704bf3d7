#include "occmap/serve/web_server.h"

#include <fmt/core.h>
#include <httplib.h>

#include <chrono>
#include <string_view>

namespace occmap {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

void JsonReply(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

void ErrorReply(httplib::Response& res, int status, const std::string& message) {
  JsonReply(res, status, json{{"error", message}});
}

int HttpStatusFor(const Status& s) {
  switch (s.code()) {
    case StatusCode::kNotFound:
      return 404;
    case StatusCode::kInvalidInput:
      return 400;
    default:
      return 500;
  }
}

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// A stream's slot in the server's count, released when the stream's provider is destroyed.
struct StreamSlot {
  explicit StreamSlot(std::atomic<int>& n) : count(n) {}
  ~StreamSlot() { --count; }
  std::atomic<int>& count;
};

}  // namespace

WebServer::WebServer(WebServerOptions options, ServeBackend& backend, std::span<const WebAsset> assets)
    : options_(std::move(options)), backend_(backend), assets_(assets), server_(std::make_unique<httplib::Server>()) {
  Routes();
}

WebServer::~WebServer() { Stop(); }

bool WebServer::AcquireStream() {
  if (++streams_ > options_.max_streams) {
    --streams_;
    return false;
  }
  return true;
}

Result<int> WebServer::Bind() {
  if (!IsLoopbackHost(options_.listen.host) && options_.token.empty()) {
    return InvalidInput(fmt::format("--listen {}: a non-loopback address needs --token or --token-file",
                                    options_.listen.host));
  }
  const int threads = options_.threads;
  server_->new_task_queue = [threads] { return new httplib::ThreadPool(static_cast<size_t>(threads)); };
  int port = options_.listen.port;
  if (port == 0) {
    port = server_->bind_to_any_port(options_.listen.host);
    if (port < 0) return IoError(fmt::format("--listen {}:0: cannot bind", options_.listen.host));
  } else if (!server_->bind_to_port(options_.listen.host, port)) {
    return IoError(fmt::format("--listen {}:{}: cannot bind (in use, or not an address of this machine)",
                               options_.listen.host, port));
  }
  return port;
}

void WebServer::Start() {
  thread_ = std::thread([this] { server_->listen_after_bind(); });
}

void WebServer::Stop() {
  if (stopping_.exchange(true)) return;
  backend_.state().Wake();
  server_->stop();
  if (thread_.joinable()) thread_.join();
}

void WebServer::Routes() {
  httplib::Server& svr = *server_;
  svr.set_keep_alive_timeout(2);
  svr.set_payload_max_length(options_.max_body_bytes);
  svr.set_read_timeout(10, 0);
  svr.set_write_timeout(10, 0);

  const size_t max_body = options_.max_body_bytes;
  auto too_large = [max_body](const httplib::Request& req) {
    if (!req.has_header("Content-Length")) return false;
    const std::string v = req.get_header_value("Content-Length");
    char* end = nullptr;
    const unsigned long long n = std::strtoull(v.c_str(), &end, 10);
    return end == v.c_str() || *end != '\0' || n > max_body;
  };
  // A client that waits for "100 Continue" learns of the limit before it sends the body.
  svr.set_expect_100_continue_handler([too_large](const httplib::Request& req, httplib::Response& res) {
    if (too_large(req)) {
      ErrorReply(res, 413, "request body over 1 MiB");
      res.set_header("Connection", "close");
      return 413;
    }
    return 100;
  });
  svr.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (IsTraversal(req.target) || IsTraversal(req.path)) {
      ErrorReply(res, 400, "path not allowed");
      res.set_header("Connection", "close");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (!options_.token.empty()) {
      const std::string given = RequestToken(req.get_header_value("Authorization"), req.get_param_value("token"));
      if (!TokenEquals(options_.token, given)) {
        ErrorReply(res, 401, given.empty() ? "a token is needed: Authorization: Bearer TOKEN or ?token=TOKEN"
                                           : "wrong token");
        res.set_header("WWW-Authenticate", "Bearer");
        res.set_header("Connection", "close");  // its body, if any, is not read
        return httplib::Server::HandlerResponse::Handled;
      }
    }
    // A body over the limit: cpp-httplib reads and drops it, then answers 413 (answering here,
    // before it is read, would reset the connection under a client still sending).
    return httplib::Server::HandlerResponse::Unhandled;
  });
  svr.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.body.empty()) {
      ErrorReply(res, res.status, res.status == 413 ? "request body over 1 MiB"
                                  : res.status == 404 ? "not found"
                                                      : fmt::format("request refused (HTTP {})", res.status));
    }
  });

  svr.Get("/api/site", [this](const httplib::Request&, httplib::Response& res) {
    JsonReply(res, 200, backend_.SiteJson());
  });
  svr.Get("/api/state", [this](const httplib::Request&, httplib::Response& res) {
    LiveState& st = backend_.state();
    JsonReply(res, 200, StateJson(*st.Latest(), st.running(), st.uptime_s(), st.starting(), st.ended()));
  });
  svr.Get("/api/cameras", [this](const httplib::Request&, httplib::Response& res) {
    const json site = backend_.SiteJson();
    json cams = json::array();
    for (const json& c : site["cameras"]) {
      cams.push_back({{"id", c["id"]}, {"width_px", c["width_px"]}, {"height_px", c["height_px"]}});
    }
    JsonReply(res, 200, cams);
  });
  svr.Get("/api/tracks", [this](const httplib::Request&, httplib::Response& res) {
    const json f = FrameEventJson(*backend_.state().Latest());
    JsonReply(res, 200, json{{"frame", f["frame"]}, {"time_s", f["time_s"]}, {"tracks", f["tracks"]}});
  });
  svr.Get("/api/zones", [this](const httplib::Request&, httplib::Response& res) {
    const json f = FrameEventJson(*backend_.state().Latest());
    JsonReply(res, 200, json{{"frame", f["frame"]}, {"zones", f["zones"]}, {"lines", f["lines"]}});
  });
  svr.Get("/api/stats", [this](const httplib::Request&, httplib::Response& res) {
    JsonReply(res, 200, backend_.StatsJson());
  });
  svr.Get("/api/map.png", [this](const httplib::Request&, httplib::Response& res) {
    const std::string png = MapPng(backend_.state().Latest()->map);
    if (png.empty()) return ErrorReply(res, 404, "no map yet");
    res.set_header("Cache-Control", "no-store");
    res.set_content(png, "image/png");
  });
  // The cameras' coverage of the floor (the run's tables): 404 until they are loaded or built.
  svr.Get("/api/coverage", [this](const httplib::Request&, httplib::Response& res) {
    const auto c = backend_.state().coverage();
    if (!c) return ErrorReply(res, 404, "no tables yet");
    JsonReply(res, 200, CoverageJson(*c));
  });
  svr.Get("/api/coverage.png", [this](const httplib::Request&, httplib::Response& res) {
    const auto c = backend_.state().coverage();
    const std::string png = c ? CoveragePng(*c) : std::string();
    if (png.empty()) return ErrorReply(res, 404, "no tables yet");
    res.set_header("Cache-Control", "no-store");
    res.set_content(png, "image/png");
  });
  svr.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    LiveState& st = backend_.state();
    res.set_content(MetricsText(*st.Latest(), st.running()), "text/plain; version=0.0.4; charset=utf-8");
  });
  svr.Post("/api/calibrate", [this](const httplib::Request& req, httplib::Response& res) {
    const json body = json::parse(req.body, nullptr, false);
    if (body.is_discarded()) return ErrorReply(res, 400, "body: expected JSON");
    auto r = backend_.Calibrate(body);
    if (!r.ok()) return ErrorReply(res, HttpStatusFor(r.status()) == 500 ? 500 : 400, r.status().message());
    JsonReply(res, 200, *r);
  });
  // Board views (a camera's intrinsics): ?camera=ID names the camera of GET and DELETE.
  auto board_reply = [](httplib::Response& res, const Result<json>& r) {
    if (!r.ok()) return ErrorReply(res, HttpStatusFor(r.status()), r.status().message());
    // A calibration that failed still lists every view with its reason.
    JsonReply(res, r->contains("error") ? 400 : 200, *r);
  };
  svr.Get("/api/board/views", [this, board_reply](const httplib::Request& req, httplib::Response& res) {
    board_reply(res, backend_.BoardViews(req.get_param_value("camera")));
  });
  svr.Post("/api/board/views", [this, board_reply](const httplib::Request& req, httplib::Response& res) {
    const json body = json::parse(req.body, nullptr, false);
    if (body.is_discarded()) return ErrorReply(res, 400, "body: expected JSON");
    board_reply(res, backend_.AddBoardView(body));
  });
  svr.Delete("/api/board/views", [this, board_reply](const httplib::Request& req, httplib::Response& res) {
    int index = -1;
    if (req.has_param("index")) {
      const std::string v = req.get_param_value("index");
      char* end = nullptr;
      const long n = std::strtol(v.c_str(), &end, 10);
      if (v.empty() || *end != '\0' || n < 0 || n > 1000) return ErrorReply(res, 400, "index: expected a view number 0, 1, ...");
      index = static_cast<int>(n);
    }
    board_reply(res, backend_.RemoveBoardViews(req.get_param_value("camera"), index));
  });
  svr.Post("/api/board/calibrate", [this, board_reply](const httplib::Request& req, httplib::Response& res) {
    const json body = json::parse(req.body, nullptr, false);
    if (body.is_discarded()) return ErrorReply(res, 400, "body: expected JSON");
    board_reply(res, backend_.CalibrateBoard(body));
  });
  svr.Get("/api/board/view.jpg", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string v = req.get_param_value("index");
    char* end = nullptr;
    const long n = std::strtol(v.c_str(), &end, 10);
    if (v.empty() || *end != '\0' || n < 0 || n > 1000) return ErrorReply(res, 400, "index: expected a view number 0, 1, ...");
    auto jpeg = backend_.BoardViewJpeg(req.get_param_value("camera"), static_cast<int>(n));
    if (!jpeg.ok()) return ErrorReply(res, HttpStatusFor(jpeg.status()), jpeg.status().message());
    res.set_header("Cache-Control", "no-store");
    res.set_content(*jpeg, "image/jpeg");
  });
  svr.Put("/api/site", [this](const httplib::Request& req, httplib::Response& res) {
    const json body = json::parse(req.body, nullptr, false);
    if (body.is_discarded()) return ErrorReply(res, 400, "body: expected JSON");
    auto r = backend_.UpdateSite(body);
    if (!r.ok()) return ErrorReply(res, HttpStatusFor(r.status()) == 500 ? 500 : 400, r.status().message());
    JsonReply(res, 200, *r);
  });

  // The camera's index in the latest snapshot, -1 when unknown.
  auto camera_index = [this](const std::string& id) -> int {
    const auto snap = backend_.state().Latest();
    for (size_t i = 0; i < snap->camera_ids.size(); ++i) {
      if (snap->camera_ids[i] == id) return static_cast<int>(i);
    }
    return -1;
  };
  auto camera_picture = [this, camera_index](const httplib::Request& req, const std::string& id) -> Result<std::string> {
    const std::string overlay = req.has_param("overlay") ? req.get_param_value("overlay") : "change";
    if (overlay == "grid") return backend_.GridJpeg(id, req.get_param_value("calibration") == "pending");
    if (overlay != "change" && overlay != "none") {
      return InvalidInput(fmt::format("overlay: expected change, grid or none, found '{}'", overlay));
    }
    const int n = camera_index(id);
    if (n < 0) {
      const json site = backend_.SiteJson();
      for (const json& c : site["cameras"]) {
        if (c["id"] == id) return NotFound(fmt::format("camera '{}' has no frame yet", id));
      }
      return NotFound(fmt::format("no camera '{}'", id));
    }
    std::string jpeg = CameraJpeg(*backend_.state().Latest(), static_cast<size_t>(n), overlay == "change");
    if (jpeg.empty()) return NotFound(fmt::format("camera '{}' has no frame yet", id));
    return jpeg;
  };
  svr.Get(R"(/api/cameras/([A-Za-z0-9_.-]+)/frame\.jpg)",
          [camera_picture](const httplib::Request& req, httplib::Response& res) {
            auto jpeg = camera_picture(req, req.matches[1]);
            if (!jpeg.ok()) return ErrorReply(res, HttpStatusFor(jpeg.status()), jpeg.status().message());
            res.set_header("Cache-Control", "no-store");
            res.set_content(*jpeg, "image/jpeg");
          });
  svr.Get(R"(/api/cameras/([A-Za-z0-9_.-]+)/mjpeg)", [this, camera_picture](const httplib::Request& req,
                                                                           httplib::Response& res) {
    const std::string id = req.matches[1];
    auto first = camera_picture(req, id);
    if (!first.ok() && first.status().code() != StatusCode::kNotFound) {
      return ErrorReply(res, HttpStatusFor(first.status()), first.status().message());
    }
    if (!first.ok() && first.status().message().rfind("no camera", 0) == 0) {
      return ErrorReply(res, 404, first.status().message());
    }
    if (!AcquireStream()) return ErrorReply(res, 503, "too many streams open");
    auto slot = std::make_shared<StreamSlot>(streams_);
    res.set_header("Cache-Control", "no-store");
    const httplib::Request copy = req;
    res.set_chunked_content_provider(
        "multipart/x-mixed-replace; boundary=occmapframe",
        [this, slot, copy, id, camera_picture, last = int64_t{-1}](size_t, httplib::DataSink& sink) mutable {
          if (stopping_) return false;
          const auto t0 = Clock::now();
          const auto snap = backend_.state().WaitNewer(last, std::chrono::milliseconds(500));
          if (stopping_) return false;
          if (snap->version > last) {
            last = snap->version;
            auto jpeg = camera_picture(copy, id);
            if (jpeg.ok()) {
              const std::string head = fmt::format(
                  "--occmapframe\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n", jpeg->size());
              if (!sink.write(head.data(), head.size()) || !sink.write(jpeg->data(), jpeg->size()) ||
                  !sink.write("\r\n", 2)) {
                return false;
              }
            }
            const double wait = options_.frame_interval_s - Seconds(Clock::now() - t0);
            if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
          }
          return sink.is_writable();
        });
  });

  svr.Get("/events", [this](const httplib::Request&, httplib::Response& res) {
    if (!AcquireStream()) return ErrorReply(res, 503, "too many streams open");
    auto slot = std::make_shared<StreamSlot>(streams_);
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Accel-Buffering", "no");
    struct Client {
      int64_t frame_version = -1;
      int64_t site_version = -1;
      Clock::time_point last_frame{}, last_state{}, last_ping = Clock::now();
      bool started = false;
    };
    res.set_chunked_content_provider(
        "text/event-stream", [this, slot, c = Client()](size_t, httplib::DataSink& sink) mutable {
          if (stopping_) return false;
          LiveState& st = backend_.state();
          std::string out;
          if (!c.started) {
            out += "retry: 2000\n\n";
            c.started = true;
          }
          // The next frame event is due at last_frame + interval: wait for news until then at most.
          const auto frame_due = c.last_frame + std::chrono::duration_cast<Clock::duration>(
                                                    std::chrono::duration<double>(options_.frame_interval_s));
          auto now = Clock::now();
          if (now < frame_due) {
            std::this_thread::sleep_for(std::min<Clock::duration>(frame_due - now, std::chrono::milliseconds(250)));
          }
          const auto snap = st.WaitNewer(c.frame_version, std::chrono::milliseconds(250));
          if (stopping_) return false;
          now = Clock::now();
          const int64_t site_version = backend_.site_version();
          if (site_version != c.site_version) {
            if (c.site_version >= 0) out += SseEvent("site", backend_.SiteJson().dump());
            c.site_version = site_version;
          }
          if (snap->version > c.frame_version && snap->frame >= 0 && now >= frame_due) {
            out += SseEvent("frame", FrameEventJson(*snap).dump());
            c.frame_version = snap->version;
            c.last_frame = now;
          }
          if (Seconds(now - c.last_state) >= options_.state_interval_s) {
            out += SseEvent("state", StateJson(*snap, st.running(), st.uptime_s(), st.starting(), st.ended()).dump());
            c.last_state = now;
          }
          if (Seconds(now - c.last_ping) >= options_.ping_interval_s) {
            out += ": ping\n\n";
            c.last_ping = now;
          }
          if (!out.empty() && !sink.write(out.data(), out.size())) return false;
          return sink.is_writable();
        });
  });

  // The pages: "/" is index.html, "/<file>" a file of the bundle.
  svr.Get(R"(/([A-Za-z0-9_.-]*))", [this](const httplib::Request& req, httplib::Response& res) {
    const std::string name = StaticFileName(req.path);
    for (const WebAsset& a : assets_) {
      if (!name.empty() && a.name == name) {
        res.set_header("Cache-Control", name == "index.html" ? "no-cache" : "max-age=300");
        res.set_content(std::string(a.data), ContentTypeFor(name));
        return;
      }
    }
    ErrorReply(res, 404, fmt::format("not found: {}", req.path));
  });
}

}  // namespace occmap
