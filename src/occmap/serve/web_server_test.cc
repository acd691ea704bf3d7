#include "occmap/serve/web_server.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>

namespace occmap {
namespace {

using nlohmann::json;

class FakeBackend : public ServeBackend {
 public:
  LiveState& state() override { return state_; }
  int64_t site_version() const override { return 1; }
  json SiteJson() const override { return {{"name", "fake"}, {"cameras", json::array({{{"id", "c1"}, {"width_px", 8}, {"height_px", 6}}})}}; }
  json StatsJson() const override { return {{"frames", 3}}; }
  Result<json> Calibrate(const json& body) override {
    if (!body.contains("camera")) return InvalidInput("camera: missing");
    return json{{"rms_px", 0.1}};
  }
  Result<json> UpdateSite(const json& body) override {
    last_put = body;
    return json{{"ok", true}};
  }
  Result<std::string> GridJpeg(const std::string&, bool) override { return NotFound("no frame"); }
  LiveState state_;
  json last_put;
};

// One HTTP exchange on a raw socket (so that the target goes out exactly as written): the
// whole response until the server closes, or `stop_after` is seen, or 10 s pass.
std::string Exchange(int port, const std::string& request, const std::string& stop_after = "") {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return "";
  }
  timeval tv{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  size_t sent = 0;
  while (sent < request.size()) {
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server may refuse before reading everything
    sent += static_cast<size_t>(n);
  }
  std::string response;
  char buf[4096];
  while (true) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    response.append(buf, static_cast<size_t>(n));
    if (!stop_after.empty() && response.find(stop_after) != std::string::npos) break;
  }
  ::close(fd);
  return response;
}

// Opens a stream and reads its headers: the socket when they say 200, else -1.
int OpenStream(int port, const std::string& target) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  timeval tv{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  const std::string request = "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::send(fd, request.data(), request.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(request.size())) {
    ::close(fd);
    return -1;
  }
  std::string head;
  char c;
  while (head.find("\r\n\r\n") == std::string::npos && ::recv(fd, &c, 1, 0) == 1) head += c;
  if (head.rfind("HTTP/1.1 200", 0) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

std::string Get(int port, const std::string& target, const std::string& headers = "") {
  return Exchange(port, "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n" + headers + "\r\n");
}

int StatusOf(const std::string& response) {
  if (response.size() < 12) return -1;
  return std::atoi(response.substr(9, 3).c_str());
}

class WebServerTest : public ::testing::Test {
 protected:
  void StartServer(const std::string& token) {
    WebServerOptions o;
    o.listen = {"127.0.0.1", 0};
    o.token = token;
    o.threads = 8;
    o.max_streams = 2;
    server_ = std::make_unique<WebServer>(o, backend_, assets_);
    auto port = server_->Bind();
    ASSERT_TRUE(port.ok()) << port.status().message();
    port_ = *port;
    server_->Start();
  }
  void TearDown() override {
    if (server_) server_->Stop();
  }
  void PublishFrame(int64_t frame) {
    auto s = std::make_shared<LiveSnapshot>();
    s->version = backend_.state().next_version();
    s->frame = frame;
    s->camera_ids = {"c1"};
    backend_.state().Publish(s);
  }

  FakeBackend backend_;
  const WebAsset assets_[2] = {{"index.html", "<html>hi</html>"}, {"app.js", "let a = 1;"}};
  std::unique_ptr<WebServer> server_;
  int port_ = 0;
};

TEST_F(WebServerTest, ServesPagesAndApi) {
  StartServer("");
  const std::string index = Get(port_, "/");
  EXPECT_EQ(StatusOf(index), 200) << index;
  EXPECT_NE(index.find("text/html"), std::string::npos);
  EXPECT_NE(index.find("<html>hi</html>"), std::string::npos);
  const std::string js = Get(port_, "/app.js");
  EXPECT_NE(js.find("text/javascript"), std::string::npos);
  EXPECT_EQ(StatusOf(Get(port_, "/missing.js")), 404);
  const std::string site = Get(port_, "/api/site");
  EXPECT_EQ(StatusOf(site), 200);
  EXPECT_NE(site.find("\"name\":\"fake\""), std::string::npos);
  EXPECT_EQ(StatusOf(Get(port_, "/api/state")), 200);
  EXPECT_NE(Get(port_, "/metrics").find("occmap_frames_total 0"), std::string::npos);
  EXPECT_EQ(StatusOf(Get(port_, "/api/cameras/c9/frame.jpg")), 404);
  EXPECT_EQ(StatusOf(Get(port_, "/api/cameras/c1/frame.jpg?overlay=bogus")), 400);
  // A byte that is not UTF-8 echoed in the message: still the 400, the byte as U+FFFD.
  const std::string bad = Get(port_, "/api/cameras/c1/frame.jpg?overlay=%FF");
  EXPECT_EQ(StatusOf(bad), 400) << bad;
  EXPECT_NE(bad.find("found '\xEF\xBF\xBD'"), std::string::npos) << bad;
}

TEST_F(WebServerTest, CoverageOnceTheTablesAreReady) {
  StartServer("");
  EXPECT_EQ(StatusOf(Get(port_, "/api/coverage")), 404);
  EXPECT_EQ(StatusOf(Get(port_, "/api/coverage.png")), 404);
  auto c = std::make_shared<LiveCoverage>();
  c->grid.cells_x = 4;
  c->grid.cells_y = 3;
  c->grid.cell_size_m = 1;
  c->num_cameras = 1;
  c->view_count.assign(12, 1);
  backend_.state().SetCoverage(c);
  const std::string j = Get(port_, "/api/coverage");
  EXPECT_EQ(StatusOf(j), 200) << j;
  EXPECT_NE(j.find("\"version\":1"), std::string::npos) << j;
  const std::string png = Get(port_, "/api/coverage.png");
  EXPECT_EQ(StatusOf(png), 200);
  EXPECT_NE(png.find("image/png"), std::string::npos);
  EXPECT_NE(png.find("\x89PNG"), std::string::npos);
  backend_.state().SetCoverage(nullptr);  // a saved site: the old coverage goes
  EXPECT_EQ(StatusOf(Get(port_, "/api/coverage")), 404);
}

TEST_F(WebServerTest, RefusesTraversal) {
  StartServer("");
  for (const char* target : {"/../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/..%2fapp.js", "/a%5c..%5cb",
                             "/app.js%00.png", "/api/cameras/..%2f..%2fc1/frame.jpg"}) {
    const std::string r = Get(port_, target);
    EXPECT_EQ(StatusOf(r), 400) << target << "\n" << r;
  }
}

TEST_F(WebServerTest, RefusesBodiesOverOneMebibyte) {
  StartServer("");
  const std::string big(size_t{1} << 20 | 1, 'x');
  const std::string r = Exchange(port_, "PUT /api/site HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                                        "Content-Length: " + std::to_string(big.size()) + "\r\nConnection: close\r\n\r\n" + big);
  EXPECT_EQ(StatusOf(r), 413) << r.substr(0, 200);
  EXPECT_TRUE(backend_.last_put.is_null());
  // With "Expect: 100-continue" the refusal comes before the body is sent.
  const std::string e = Exchange(port_, "PUT /api/site HTTP/1.1\r\nHost: 127.0.0.1\r\nExpect: 100-continue\r\n"
                                        "Content-Length: 5000000\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(StatusOf(e), 413) << e;
  const std::string small = R"({"zones": []})";
  const std::string ok = Exchange(port_, "PUT /api/site HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: " +
                                             std::to_string(small.size()) + "\r\nConnection: close\r\n\r\n" + small);
  EXPECT_EQ(StatusOf(ok), 200) << ok;
  EXPECT_EQ(backend_.last_put, json::parse(small));
  const std::string bad = Exchange(port_, "POST /api/calibrate HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                                         "Content-Length: 3\r\nConnection: close\r\n\r\n{x}");
  EXPECT_EQ(StatusOf(bad), 400);
  EXPECT_NE(bad.find("\"error\""), std::string::npos);
}

// cpp-httplib 0.11 capped only a Content-Length body: a chunked one was read whole (256 MiB).
TEST_F(WebServerTest, ChunkedBodiesAreCappedAndLengthlessOnesAreEmpty) {
  StartServer("");
  const std::string head = "PUT /api/site HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                           "Transfer-Encoding: chunked\r\n\r\n";
  std::string chunks;
  const std::string piece(size_t{256} << 10, ' ');
  for (int i = 0; i < 8; ++i) chunks += fmt::format("{:x}\r\n", piece.size()) + piece + "\r\n";  // 2 MiB
  const std::string big = Exchange(port_, head + chunks + "0\r\n\r\n");
  EXPECT_EQ(StatusOf(big), 413) << big.substr(0, 200);
  EXPECT_NE(big.find("Connection: close"), std::string::npos);
  EXPECT_TRUE(backend_.last_put.is_null());
  const std::string small = Exchange(port_, head + "e\r\n{\"zones\": []}\r\n0\r\n\r\n");
  EXPECT_EQ(StatusOf(small), 200) << small;
  EXPECT_EQ(backend_.last_put, json::parse(R"({"zones": []})"));
  // Neither Content-Length nor chunked: no body (was: read until the client closed).
  const std::string none = Exchange(port_, "POST /api/calibrate HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                           "Content-Type: application/json\r\n\r\n", "}");
  EXPECT_EQ(StatusOf(none), 400) << none;
  EXPECT_NE(none.find("body: expected JSON"), std::string::npos) << none;
  EXPECT_EQ(StatusOf(Exchange(port_, "PATCH /api/site HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")), 405);
  EXPECT_EQ(StatusOf(Exchange(port_, "POST /nowhere HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                                     "Transfer-Encoding: chunked\r\n\r\n" + chunks)), 404);
}

TEST_F(WebServerTest, ForeignHostsAndCrossSiteWritesAreRefused) {
  StartServer("");
  const std::string foreign = Exchange(port_, "GET /api/site HTTP/1.1\r\nHost: attacker.example:80\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(StatusOf(foreign), 403) << foreign;
  EXPECT_EQ(foreign.find("\"name\":\"fake\""), std::string::npos);
  EXPECT_EQ(StatusOf(Exchange(port_, "GET /api/site HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")), 200);
  const std::string body = R"({"zones": []})";
  auto put = [&](const std::string& headers) {
    return StatusOf(Exchange(port_, "PUT /api/site HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n" + headers +
                                        "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body));
  };
  EXPECT_EQ(put("Content-Type: text/plain\r\n"), 415);
  EXPECT_EQ(put("Content-Type: application/json\r\nOrigin: http://attacker.example\r\n"), 403);
  EXPECT_EQ(put("Content-Type: application/json\r\nSec-Fetch-Site: cross-site\r\n"), 403);
  EXPECT_TRUE(backend_.last_put.is_null());
  EXPECT_EQ(put("Content-Type: application/json\r\nOrigin: http://127.0.0.1\r\nSec-Fetch-Site: same-origin\r\n"), 200);
}

TEST_F(WebServerTest, TokenOnEveryRequest) {
  StartServer("s3cret");
  for (const char* target : {"/app.js", "/api/site", "/api/state", "/metrics", "/events", "/api/map.png",
                             "/api/cameras/c1/mjpeg", "/api/stats"}) {
    const std::string r = Get(port_, target);
    EXPECT_EQ(StatusOf(r), 401) << target;
    EXPECT_NE(r.find("\"error\""), std::string::npos) << target;
    EXPECT_EQ(StatusOf(Get(port_, std::string(target) + "?token=wrong")), 401) << target;
    EXPECT_EQ(StatusOf(Get(port_, target, "Cookie: occmap_token=77726f6e67\r\n")), 401) << target;
  }
  EXPECT_EQ(StatusOf(Get(port_, "/api/site?token=s3cret")), 200);
  EXPECT_EQ(StatusOf(Get(port_, "/api/site", "Authorization: Bearer s3cret\r\n")), 200);
  EXPECT_EQ(StatusOf(Get(port_, "/api/site", "Cookie: a=b; occmap_token=733363726574\r\n")), 200);
  // The pages send a browser without the token to sign in.
  for (const char* page : {"/", "/system", "/index.html"}) {
    const std::string r = Get(port_, page);
    EXPECT_EQ(StatusOf(r), 303) << page;
    EXPECT_NE(r.find("Location: /login?next=" + std::string(page) + "\r\n"), std::string::npos) << r;
    EXPECT_EQ(r.find("Set-Cookie"), std::string::npos) << r;
    EXPECT_EQ(StatusOf(Get(port_, std::string(page) + "?token=wrong")), 303) << page;
  }
  // An old link with ?token=: the cookie is set and the address loses the token.
  const std::string linked = Get(port_, "/system?token=s3cret");
  EXPECT_EQ(StatusOf(linked), 303);
  EXPECT_NE(linked.find("Location: /system\r\n"), std::string::npos) << linked;
  EXPECT_NE(linked.find("Set-Cookie: occmap_token=733363726574; Path=/; Max-Age=2592000; HttpOnly; SameSite=Strict\r\n"),
            std::string::npos)
      << linked;
  EXPECT_EQ(StatusOf(Get(port_, "/", "Cookie: occmap_token=733363726574\r\n")), 200);
  const std::string system = Get(port_, "/system", "Cookie: occmap_token=733363726574\r\n");
  EXPECT_EQ(StatusOf(system), 200);
  EXPECT_NE(system.find("<html>hi</html>"), std::string::npos) << "the system page is the bundle's index.html";
}

// POST /api/login puts the token in an HttpOnly, SameSite=Strict cookie; every route then takes
// the cookie; /api/logout clears it. The login page and these routes need no token.
TEST_F(WebServerTest, SignInKeepsTheTokenInACookie) {
  StartServer("s3cret;=x,%41");  // characters a cookie value cannot hold, and '%', which headers decode
  const std::string page = Get(port_, "/login?next=/system");
  EXPECT_EQ(StatusOf(page), 200);
  EXPECT_NE(page.find("Content-Type: text/html"), std::string::npos);
  EXPECT_NE(page.find("/api/login"), std::string::npos);
  EXPECT_EQ(page.find("s3cret"), std::string::npos);

  auto post = [this](const std::string& target, const std::string& body, const std::string& headers =
                                                                                 "Content-Type: application/json\r\n") {
    return Exchange(port_, "POST " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n" + headers +
                               "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body);
  };
  const std::string wrong = post("/api/login", R"({"token": "s3cret"})");
  EXPECT_EQ(StatusOf(wrong), 401);
  EXPECT_EQ(wrong.find("Set-Cookie"), std::string::npos);
  EXPECT_EQ(StatusOf(post("/api/login", R"({"token": 5})")), 400);
  EXPECT_EQ(StatusOf(post("/api/login", R"({"token": "s3cret;=x,%41"})", "Content-Type: text/plain\r\n")), 415);
  EXPECT_EQ(StatusOf(post("/api/login", R"({"token": "s3cret;=x,%41"})",
                          "Content-Type: application/json\r\nOrigin: http://evil.example\r\n")),
            403);

  const std::string ok = post("/api/login", R"({"token": "s3cret;=x,%41"})");
  EXPECT_EQ(StatusOf(ok), 200) << ok;
  const std::string cookie = "occmap_token=7333637265743b3d782c253431";
  EXPECT_NE(ok.find("Set-Cookie: " + cookie + "; Path=/; Max-Age=2592000; HttpOnly; SameSite=Strict\r\n"),
            std::string::npos)
      << ok;
  EXPECT_EQ(StatusOf(Get(port_, "/api/state", "Cookie: " + cookie + "\r\n")), 200);
  EXPECT_EQ(StatusOf(Get(port_, "/app.js", "Cookie: " + cookie + "\r\n")), 200);
  EXPECT_EQ(StatusOf(Get(port_, "/", "Cookie: " + cookie + "\r\n")), 200);
  const int fd = OpenStream(port_, "/events?x=1");  // no cookie: refused
  EXPECT_EQ(fd, -1);

  auto session = [this](const std::string& headers) {
    const std::string r = Get(port_, "/api/session", headers);
    return json::parse(r.substr(r.find("\r\n\r\n") + 4));
  };
  EXPECT_EQ(session(""), (json{{"token_required", true}, {"signed_in", false}, {"via", nullptr}}));
  EXPECT_EQ(session("Cookie: " + cookie + "\r\n"), (json{{"token_required", true}, {"signed_in", true}, {"via", "cookie"}}));
  EXPECT_EQ(session("Cookie: occmap_token=6f6c64\r\n")["signed_in"], false);

  const std::string out = post("/api/logout", "{}");
  EXPECT_EQ(StatusOf(out), 200);
  EXPECT_NE(out.find("Set-Cookie: occmap_token=; Path=/; Max-Age=0; HttpOnly; SameSite=Strict\r\n"), std::string::npos)
      << out;
}

TEST_F(WebServerTest, WithoutATokenTheLoginPageSendsHome) {
  StartServer("");
  const std::string r = Get(port_, "/login");
  EXPECT_EQ(StatusOf(r), 303);
  EXPECT_NE(r.find("Location: /\r\n"), std::string::npos) << r;
  EXPECT_EQ(StatusOf(Get(port_, "/system")), 200);
  const std::string s = Get(port_, "/api/session");
  EXPECT_NE(s.find(R"({"signed_in":true,"token_required":false,"via":null})"), std::string::npos) << s;
}

TEST_F(WebServerTest, NonLoopbackNeedsAToken) {
  WebServerOptions o;
  o.listen = {"0.0.0.0", 0};
  WebServer server(o, backend_, assets_);
  auto port = server.Bind();
  ASSERT_FALSE(port.ok());
  EXPECT_NE(port.status().message().find("needs --token"), std::string::npos);
}

TEST_F(WebServerTest, EventsDeliverFramesAndStreamsAreCapped) {
  StartServer("");
  PublishFrame(41);
  const std::string events = Exchange(port_, "GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n", "event: state");
  EXPECT_EQ(StatusOf(events), 200) << events;
  EXPECT_NE(events.find("text/event-stream"), std::string::npos);
  EXPECT_NE(events.find("event: frame\ndata: {"), std::string::npos) << events;
  EXPECT_NE(events.find("\"frame\":41"), std::string::npos) << events;
  // The stream above ends once the server's next writes find the socket closed.
  for (int i = 0; i < 400 && server_->open_streams() > 0; ++i) {
    PublishFrame(100 + i);
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ASSERT_EQ(server_->open_streams(), 0);
  // max_streams 2: two held open, the third refused; one closed, a new one served.
  int held[2];
  for (int& fd : held) {
    fd = OpenStream(port_, "/events");
    ASSERT_GE(fd, 0);
  }
  EXPECT_EQ(StatusOf(Get(port_, "/events")), 503);
  EXPECT_EQ(StatusOf(Get(port_, "/api/state")), 200);  // the API still answers
  ::close(held[0]);
  bool served = false;
  for (int i = 0; i < 100 && !served; ++i) {  // the server notices the closed stream on its next write
    PublishFrame(42 + i);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const int fd = OpenStream(port_, "/events");
    served = fd >= 0;
    if (fd >= 0) ::close(fd);
  }
  EXPECT_TRUE(served);
  ::close(held[1]);
}

}  // namespace
}  // namespace occmap
