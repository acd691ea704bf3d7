#include "occmap/serve/web_server.h"

#include <fmt/core.h>
#include <httplib.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstring>
#include <optional>
#include <string_view>

#include "occmap/util/text_guard.h"

namespace occmap {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

// The connection a pool thread serves: the deadline of the bytes still to come and whether it
// closes after this answer. cpp-httplib hands its handlers no connection, so they find it
// through the thread (one connection per thread at a time).
struct Connection {
  Clock::time_point deadline;
  bool headers_done = false;
  bool close_after = false;
  bool timed_out = false;
  double body_timeout_s = 30;
};
thread_local Connection* t_connection = nullptr;

// The headers are in: the body's deadline starts.
void HeadersDone() {
  Connection* c = t_connection;
  if (c == nullptr || c->headers_done) return;
  c->headers_done = true;
  c->deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(c->body_timeout_s));
}

// The answer ends the connection (a body left unread must not be taken for the next request).
void CloseAfter(httplib::Response& res) {
  if (t_connection != nullptr) t_connection->close_after = true;
  res.set_header("Connection", "close");
}

int MillisUntil(Clock::time_point t) {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(t - Clock::now()).count();
  return static_cast<int>(std::clamp<int64_t>(ms, 0, 1'000'000));
}

bool Poll(int fd, short events, int timeout_ms) {
  pollfd p{fd, events, 0};
  int r;
  do {
    r = ::poll(&p, 1, timeout_ms);
  } while (r < 0 && errno == EINTR);
  return r > 0 && (p.revents & (events | POLLHUP | POLLERR)) != 0;
}

// A connection's bytes as cpp-httplib's SocketStream reads them, each read bounded by the
// read timeout and by the connection's deadline.
class DeadlineStream final : public httplib::Stream {
 public:
  DeadlineStream(int fd, Connection& conn, int read_timeout_ms) : fd_(fd), conn_(conn), timeout_ms_(read_timeout_ms) {}

  bool buffered() const { return off_ < len_; }
  bool is_readable() const override { return buffered() || WaitReadable(); }
  bool is_writable() const override { return Poll(fd_, POLLOUT, timeout_ms_) && Alive(); }
  ssize_t read(char* ptr, size_t size) override {
    if (!buffered()) {
      if (!WaitReadable()) return -1;
      ssize_t n;
      do {
        n = ::recv(fd_, buf_, sizeof buf_, 0);
      } while (n < 0 && errno == EINTR);
      if (n <= 0) return n;
      off_ = 0;
      len_ = static_cast<size_t>(n);
    }
    const size_t n = std::min(size, len_ - off_);
    std::memcpy(ptr, buf_ + off_, n);
    off_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    if (!Poll(fd_, POLLOUT, timeout_ms_)) return -1;
    ssize_t n;
    do {
      n = ::send(fd_, ptr, size, MSG_NOSIGNAL);
    } while (n < 0 && errno == EINTR);
    return n;
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override { Address(false, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { Address(true, ip, port); }
  socket_t socket() const override { return fd_; }

 private:
  bool WaitReadable() const {
    const int left = MillisUntil(conn_.deadline);
    if (Poll(fd_, POLLIN, std::min(timeout_ms_, left))) return true;
    if (Clock::now() >= conn_.deadline) conn_.timed_out = true;
    return false;
  }
  // Readable with nothing to read: the client closed.
  bool Alive() const {
    if (buffered() || !Poll(fd_, POLLIN, 0)) return true;
    char c;
    return ::recv(fd_, &c, 1, MSG_PEEK | MSG_DONTWAIT) > 0;
  }
  void Address(bool local, std::string& ip, int& port) const {
    sockaddr_storage a{};
    socklen_t n = sizeof a;
    auto* sa = reinterpret_cast<sockaddr*>(&a);
    if ((local ? ::getsockname(fd_, sa, &n) : ::getpeername(fd_, sa, &n)) != 0) return;
    char text[INET6_ADDRSTRLEN] = {};
    if (a.ss_family == AF_INET) {
      const auto* v4 = reinterpret_cast<sockaddr_in*>(&a);
      ::inet_ntop(AF_INET, &v4->sin_addr, text, sizeof text);
      port = ntohs(v4->sin_port);
    } else if (a.ss_family == AF_INET6) {
      const auto* v6 = reinterpret_cast<sockaddr_in6*>(&a);
      ::inet_ntop(AF_INET6, &v6->sin6_addr, text, sizeof text);
      port = ntohs(v6->sin6_port);
    }
    ip = text;
  }

  int fd_;
  Connection& conn_;
  int timeout_ms_;
  char buf_[4096];
  size_t off_ = 0, len_ = 0;
};

Clock::duration Secs(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

// cpp-httplib's server with its connections read by DeadlineStream (its keep-alive loop,
// process_and_close_socket, is a virtual meant to be replaced).
class GuardedHttpServer : public httplib::Server {
 public:
  explicit GuardedHttpServer(const WebServerOptions& options) : options_(options) {}

 private:
  bool process_and_close_socket(socket_t sock) override {
    ++active_;
    Connection conn;
    conn.body_timeout_s = options_.body_timeout_s;
    t_connection = &conn;
    DeadlineStream strm(sock, conn, static_cast<int>(options_.read_timeout_s * 1000));
    bool ret = false;
    for (size_t count = keep_alive_max_count_; count > 0 && svr_sock_ != INVALID_SOCKET; --count) {
      const bool pressed = active_.load() > options_.threads - options_.reserved_threads;
      const auto start = Clock::now();
      conn.deadline = start + Secs(pressed ? options_.pressed_header_timeout_s : options_.header_timeout_s);
      conn.headers_done = conn.close_after = conn.timed_out = false;
      // The next request's first byte: at most the keep-alive time, polled in slices so that a
      // stopping server does not wait for it.
      const auto idle_until = std::min(conn.deadline, start + std::chrono::seconds(keep_alive_timeout_sec_));
      bool readable = strm.buffered();
      while (!readable && svr_sock_ != INVALID_SOCKET && Clock::now() < idle_until) {
        readable = Poll(sock, POLLIN, std::min(100, MillisUntil(idle_until)));
      }
      if (!readable) break;
      bool closed = false;
      ret = process_request(strm, count == 1, closed, nullptr);
      // A request that never reached routing (bad or late headers) ends the connection.
      if (!ret || closed || conn.close_after || !conn.headers_done) break;
    }
    t_connection = nullptr;
    // A lingering close: the answer sent, what the client still sends (a body refused unread) is
    // read and dropped for a moment, so that closing does not reset the connection under the
    // client before it reads the answer.
    ::shutdown(sock, SHUT_WR);
    const auto linger_until = Clock::now() + std::chrono::seconds(conn.close_after ? 1 : 0);
    char sink[16384];
    for (size_t drained = 0; drained < (size_t{4} << 20) && Poll(sock, POLLIN, MillisUntil(linger_until));) {
      const ssize_t n = ::recv(sock, sink, sizeof sink, MSG_DONTWAIT);
      if (n <= 0) break;
      drained += static_cast<size_t>(n);
    }
    ::close(sock);
    --active_;
    return ret;
  }

  const WebServerOptions& options_;
  std::atomic<int> active_{0};
};

void JsonReply(httplib::Response& res, int status, const json& body) {
  res.status = status;
  // Bytes that are not UTF-8 (a query's %FF echoed in a message) become U+FFFD: dump() would
  // throw, and the reply would be a 500 instead of the error it is.
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
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

// A request's body, at most `max_bytes` however it is sent; nothing, with the reply made and the
// connection to be closed, when it is refused. cpp-httplib 0.11 caps only a Content-Length body
// and reads a chunked one, or one with neither header until the client closes, whole.
std::optional<std::string> ReadBody(const httplib::Request& req, httplib::Response& res,
                                    const httplib::ContentReader& reader, size_t max_bytes) {
  std::string te = req.get_header_value("Transfer-Encoding");
  std::transform(te.begin(), te.end(), te.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  // Neither header: no body (RFC 9112 6.3), not a wait for the client to close.
  if (te.find("chunked") == std::string::npos && !req.has_header("Content-Length")) return std::string();
  std::string body;
  bool over = false;
  const bool ok = reader([&](const char* data, size_t n) {
    if (body.size() + n > max_bytes) {
      over = true;
      return false;
    }
    body.append(data, n);
    return true;
  });
  if (ok) return body;
  CloseAfter(res);
  if (over || res.status == 413) {
    ErrorReply(res, 413, "request body over 1 MiB");
  } else if (t_connection != nullptr && t_connection->timed_out) {
    ErrorReply(res, 408, "request body not sent in time");
  } else {
    ErrorReply(res, 400, "request body: cannot read it (cut short or badly chunked)");
  }
  return std::nullopt;
}

// A request's body as JSON (ReadBody, then ParseJsonBody); nothing, with the reply made (400,
// 408, 413), when it cannot be read or is not JSON.
std::optional<json> ReadJsonBody(const httplib::Request& req, httplib::Response& res,
                                 const httplib::ContentReader& reader, size_t max_bytes) {
  const auto text = ReadBody(req, res, reader, max_bytes);
  if (!text) return std::nullopt;
  auto body = ParseJsonBody(*text);
  if (!body.ok()) {
    ErrorReply(res, 400, body.status().message());
    return std::nullopt;
  }
  return std::move(*body);
}

// A stream's slot in the server's count, released when the stream's provider is destroyed.
struct StreamSlot {
  explicit StreamSlot(std::atomic<int>& n) : count(n) {}
  ~StreamSlot() { --count; }
  std::atomic<int>& count;
};

}  // namespace

WebServer::WebServer(WebServerOptions options, ServeBackend& backend, std::span<const WebAsset> assets)
    : options_(std::move(options)), backend_(backend), assets_(assets),
      server_(std::make_unique<GuardedHttpServer>(options_)) {
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
  svr.set_read_timeout(static_cast<time_t>(options_.read_timeout_s), 0);
  svr.set_write_timeout(static_cast<time_t>(options_.read_timeout_s), 0);

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
    HeadersDone();
    if (too_large(req)) {
      ErrorReply(res, 413, "request body over 1 MiB");
      CloseAfter(res);
      return 413;
    }
    return 100;
  });
  // Rebinding matters where a browser on this machine is the way in: a loopback address (beyond
  // it the token is the gate), or wherever the user names the hosts.
  const bool check_host = IsLoopbackHost(options_.listen.host) || !options_.allowed_hosts.empty();
  svr.set_pre_routing_handler([this, check_host](const httplib::Request& req, httplib::Response& res) {
    HeadersDone();
    // Every refusal closes the connection: its body, if any, is not read.
    auto refuse = [&res](int status, const std::string& message) {
      ErrorReply(res, status, message);
      CloseAfter(res);
      return httplib::Server::HandlerResponse::Handled;
    };
    auto redirect = [](httplib::Response& r, const std::string& to) {
      r.set_redirect(to, 303);
      r.set_header("Cache-Control", "no-store");
      return httplib::Server::HandlerResponse::Handled;
    };
    if (IsTraversal(req.target) || IsTraversal(req.path)) return refuse(400, "path not allowed");
    const std::string& method = req.method;
    if (method != "GET" && method != "HEAD" && method != "POST" && method != "PUT" && method != "DELETE" &&
        method != "OPTIONS") {
      res.set_header("Allow", "GET, HEAD, POST, PUT, DELETE, OPTIONS");
      return refuse(405, fmt::format("method '{}' not allowed", Excerpt(method, 20)));
    }
    const std::string host = req.get_header_value("Host");
    if (check_host && !HostAllowed(host, options_.listen, options_.allowed_hosts)) {
      return refuse(403, fmt::format("Host '{}' is not this server's name: use its address or localhost, or start it "
                                     "with --allow-host {}",
                                     Excerpt(host, 80), Excerpt(HostName(host), 80)));
    }
    if (!options_.token.empty() && !IsOpenPath(req.path)) {
      const TokenSource given = CheckToken(options_.token, req.get_header_value("Authorization"),
                                           req.get_header_value("Cookie"), req.get_param_value("token"));
      const bool page = (method == "GET" || method == "HEAD") && IsPagePath(req.path);
      if (given == TokenSource::kNone || given == TokenSource::kWrong) {
        // A browser opening a page signs in first; scripts get 401.
        if (page) return redirect(res, "/login?next=" + req.path);
        res.set_header("WWW-Authenticate", "Bearer");
        return refuse(401, given == TokenSource::kNone
                               ? "a token is needed: sign in at /login, or Authorization: Bearer TOKEN or ?token=TOKEN"
                               : "wrong token");
      }
      // An old link with ?token=: the token goes into the cookie and out of the address bar.
      if (given == TokenSource::kQuery && page) {
        res.set_header("Set-Cookie", SessionCookie(options_.token));
        return redirect(res, req.path);
      }
    }
    if (auto r = CrossSiteWriteRefusal(method, host, req.get_header_value("Origin"),
                                       req.get_header_value("Sec-Fetch-Site"), req.get_header_value("Content-Type"))) {
      return refuse(r->http_status, r->message);
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

  // Signing in (docs/formats.md, "Web API"): open to every visitor, the gate above lets them by.
  svr.Get("/login", [this](const httplib::Request&, httplib::Response& res) {
    if (options_.token.empty()) return res.set_redirect("/", 303);
    res.set_header("Cache-Control", "no-store");
    res.set_content(LoginPageHtml(), "text/html; charset=utf-8");
  });
  svr.Get("/api/session", [this](const httplib::Request& req, httplib::Response& res) {
    const TokenSource given = options_.token.empty()
                                  ? TokenSource::kNone
                                  : CheckToken(options_.token, req.get_header_value("Authorization"),
                                               req.get_header_value("Cookie"), req.get_param_value("token"));
    const std::string_view via = TokenSourceName(given);
    res.set_header("Cache-Control", "no-store");
    JsonReply(res, 200, json{{"token_required", !options_.token.empty()},
                             {"signed_in", options_.token.empty() || !via.empty()},
                             {"via", via.empty() ? json(nullptr) : json(via)}});
  });
  const size_t max_body_bytes = options_.max_body_bytes;
  svr.Post("/api/login", [this, max_body_bytes](const httplib::Request& req, httplib::Response& res,
                                                  const httplib::ContentReader& reader) {
    const auto body = ReadJsonBody(req, res, reader, max_body_bytes);
    if (!body) return;
    if (!body->is_object() || !body->contains("token") || !(*body)["token"].is_string()) {
      return ErrorReply(res, 400, "token: expected a string, {\"token\": \"...\"}");
    }
    if (options_.token.empty()) return JsonReply(res, 200, json{{"signed_in", true}, {"token_required", false}});
    if (!TokenEquals(options_.token, (*body)["token"].get<std::string>())) return ErrorReply(res, 401, "wrong token");
    res.set_header("Set-Cookie", SessionCookie(options_.token));
    res.set_header("Cache-Control", "no-store");
    JsonReply(res, 200, json{{"signed_in", true}, {"token_required", true}});
  });
  svr.Post("/api/logout", [this, max_body_bytes](const httplib::Request& req, httplib::Response& res,
                                                   const httplib::ContentReader& reader) {
    if (!ReadBody(req, res, reader, max_body_bytes)) return;
    res.set_header("Set-Cookie", SessionCookie(""));
    res.set_header("Cache-Control", "no-store");
    JsonReply(res, 200, json{{"signed_in", options_.token.empty()}, {"token_required", !options_.token.empty()}});
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
  svr.Get("/api/events", [this](const httplib::Request&, httplib::Response& res) {
    const auto snap = backend_.state().Latest();
    JsonReply(res, 200, json{{"events_total", snap->events_total}, {"events", EventsJson(*snap, kRecentEvents)}});
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
  svr.Post("/api/calibrate", [this, max_body_bytes](const httplib::Request& req, httplib::Response& res,
                                                    const httplib::ContentReader& reader) {
    const auto body = ReadJsonBody(req, res, reader, max_body_bytes);
    if (!body) return;
    auto r = backend_.Calibrate(*body);
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
  svr.Post("/api/board/views", [this, board_reply, max_body_bytes](const httplib::Request& req, httplib::Response& res,
                                                                   const httplib::ContentReader& reader) {
    const auto body = ReadJsonBody(req, res, reader, max_body_bytes);
    if (!body) return;
    board_reply(res, backend_.AddBoardView(*body));
  });
  svr.Delete("/api/board/views", [this, board_reply, max_body_bytes](const httplib::Request& req,
                                                                     httplib::Response& res,
                                                                     const httplib::ContentReader& reader) {
    if (!ReadBody(req, res, reader, max_body_bytes)) return;  // none expected; read so that none is left
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
  svr.Post("/api/board/calibrate", [this, board_reply, max_body_bytes](const httplib::Request& req,
                                                                       httplib::Response& res,
                                                                       const httplib::ContentReader& reader) {
    const auto body = ReadJsonBody(req, res, reader, max_body_bytes);
    if (!body) return;
    board_reply(res, backend_.CalibrateBoard(*body));
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
  svr.Put("/api/site", [this, max_body_bytes](const httplib::Request& req, httplib::Response& res,
                                              const httplib::ContentReader& reader) {
    const auto body = ReadJsonBody(req, res, reader, max_body_bytes);
    if (!body) return;
    auto r = backend_.UpdateSite(*body);
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
  svr.Get(R"(/api/cameras/([A-Za-z0-9_.-]+)/mask\.png)", [this](const httplib::Request& req, httplib::Response& res) {
    auto png = backend_.MaskPng(req.matches[1]);
    if (!png.ok()) return ErrorReply(res, HttpStatusFor(png.status()), png.status().message());
    res.set_header("Cache-Control", "no-store");
    res.set_content(*png, "image/png");
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

  // Writes to anything else: 404 without reading the body (cpp-httplib would read it whole).
  auto no_such_write = [](const httplib::Request& req, httplib::Response& res, const httplib::ContentReader&) {
    ErrorReply(res, 404, fmt::format("not found: {} {}", req.method, Excerpt(req.path, 80)));
    CloseAfter(res);
  };
  svr.Post(".*", no_such_write);
  svr.Put(".*", no_such_write);
  svr.Delete(".*", no_such_write);

  // The pages: "/" is index.html, "/<file>" a file of the bundle.
  svr.Get(R"(/([A-Za-z0-9_.-]*))", [this](const httplib::Request& req, httplib::Response& res) {
    // The system page is the same bundle: it picks its view by the path.
    const std::string name = req.path == "/system" ? std::string("index.html") : StaticFileName(req.path);
    for (const WebAsset& a : assets_) {
      if (!name.empty() && a.name == name) {
        res.set_header("Cache-Control", name == "index.html" ? "no-cache" : "max-age=300");
        res.set_content(std::string(a.data), ContentTypeFor(name));
        return;
      }
    }
    ErrorReply(res, 404, fmt::format("not found: {}", Excerpt(req.path, 80)));
  });
}

}  // namespace occmap
