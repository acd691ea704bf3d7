// WebServer: `occmap serve`'s HTTP server (cpp-httplib) over a ServeBackend: the embedded pages,
// the JSON API, Server-Sent Events, JPEG and MJPEG camera pictures and Prometheus metrics
// (docs/formats.md, "Web API").
//
// Every request passes one gate before routing: a target naming anything outside the served
// files ("..", its encodings, backslash, NUL) is refused with 400; a method other than GET,
// HEAD, POST, PUT, DELETE with 405; a Host that is not this server's (DNS rebinding, web_api.h
// HostAllowed) with 403; with a token every request needs it (Bearer header, the session cookie
// of /login, or ?token=) else 401, a page (/, /system) a redirect to /login, and a page opened
// with ?token= sets the cookie and is sent to its address without it; a write from another site's page (Origin, Sec-Fetch-Site) with 403 and a write whose body
// is not application/json with 415. A body over 1 MiB gets 413, however it is sent: with a
// Content-Length read and dropped by cpp-httplib (or refused before it is sent to a client that
// asks, Expect: 100-continue), chunked cut at the limit and the connection closed. A request
// with neither has no body (RFC 9112) and is not waited for. A non-loopback address needs a
// token (Bind refuses it otherwise).
//
// Threads: cpp-httplib 0.11 serves each connection on a pool thread for as long as it lives, so
// every /events or MJPEG client holds one. The pool has `threads` threads and at most
// `max_streams` of them stream at once (more are refused with 503), which leaves the rest for the
// API; idle keep-alive connections are closed after 2 s so that they do not pin threads. The
// connections are read here, not by cpp-httplib (which times out each read alone: a header line
// a second held a thread for ever): headers and body each have a deadline, shortened for headers
// when the pool is nearly full.
#pragma once

#include <atomic>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

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
  // Host names besides IP addresses, localhost and the listen host that requests may name
  // (--allow-host); checked when the address is loopback or when names are given.
  std::vector<std::string> allowed_hosts;
  int threads = 32;                // the HTTP pool
  int max_streams = 24;            // /events and MJPEG clients at once
  size_t max_body_bytes = size_t{1} << 20;  // however it is sent: Content-Length or chunked
  // A request's line and headers must be in this long after the server waits for them; when
  // fewer than `reserved_threads` pool threads are free, within `pressed_header_timeout_s`
  // (a client sends its headers at once: only a slow one waiting to hold a thread is cut).
  double header_timeout_s = 5.0;
  double pressed_header_timeout_s = 1.0;
  int reserved_threads = 2;
  double body_timeout_s = 30.0;    // the body, from the end of the headers
  double read_timeout_s = 10.0;    // any one read or write
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
