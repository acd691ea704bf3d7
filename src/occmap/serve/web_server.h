// WebServer: `occmap serve`'s HTTP server (cpp-httplib) over a ServeBackend: the embedded pages,
// the JSON API, Server-Sent Events, JPEG and MJPEG camera pictures and Prometheus metrics
// (docs/formats.md, "Web API").
//
// Every request passes one gate before routing: a target naming anything outside the served
// files ("..", its encodings, backslash, NUL) is refused with 400, and with a token every
// request needs it (Bearer header or ?token=) else 401. A body over 1 MiB gets 413: read and
// dropped by cpp-httplib, or refused before it is sent to a client that asks (Expect:
// 100-continue). A non-loopback address needs a token (Bind refuses it otherwise).
//
// Threads: cpp-httplib 0.11 serves each connection on a pool thread for as long as it lives, so
// every /events or MJPEG client holds one. The pool has `threads` threads and at most
// `max_streams` of them stream at once (more are refused with 503), which leaves the rest for the
// API; idle keep-alive connections are closed after 2 s so that they do not pin threads.
#pragma once

#include <atomic>
#include <memory>
#include <span>
#include <string>
#include <thread>

#include "occmap/serve/serve_session.h"
#include "occmap/serve/web_api.h"
#include "occmap/serve/web_assets.h"
#include "occmap/util/status.h"

namespace httplib {
class Server;
}

namespace occmap {

struct WebServerOptions {
  ListenAddress listen;
  std::string token;               // empty: no token (loopback only)
  int threads = 32;                // the HTTP pool
  int max_streams = 24;            // /events and MJPEG clients at once
  size_t max_body_bytes = size_t{1} << 20;
  double frame_interval_s = 0.1;   // at most this often a `frame` event or MJPEG picture per client
  double state_interval_s = 1.0;   // `state` events
  double ping_interval_s = 15.0;   // `: ping` comments
};

class WebServer {
 public:
  WebServer(WebServerOptions options, ServeBackend& backend, std::span<const WebAsset> assets);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Binds the address; returns the port (the chosen one for port 0). Refuses a non-loopback
  // address without a token.
  Result<int> Bind();
  void Start();  // serves on its own thread
  void Stop();   // streams end, the listener closes, the thread is joined
  int open_streams() const { return streams_.load(); }

 private:
  void Routes();
  bool AcquireStream();

  WebServerOptions options_;
  ServeBackend& backend_;
  std::span<const WebAsset> assets_;
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  std::atomic<bool> stopping_{false};
  std::atomic<int> streams_{0};
};

}  // namespace occmap
