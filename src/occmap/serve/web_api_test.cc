#include "occmap/serve/web_api.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "occmap/lut/visibility_image.h"

namespace occmap {
namespace {

using nlohmann::json;

TEST(WebApi, ParsesListenAddresses) {
  auto a = ParseListen("127.0.0.1:0");
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->host, "127.0.0.1");
  EXPECT_EQ(a->port, 0);
  auto b = ParseListen("[::1]:9000");
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->host, "::1");
  EXPECT_EQ(b->port, 9000);
  auto c = ParseListen(":8081");
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->host, "127.0.0.1");
  EXPECT_EQ(c->port, 8081);
  auto d = ParseListen("0.0.0.0");
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->port, 8080);
  for (const char* bad : {"host:", "host:70000", "host:x", "::1:80", "[::1", "a b:80", "h:-1"}) {
    auto r = ParseListen(bad);
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_NE(r.status().message().find("--listen"), std::string::npos);
  }
}

TEST(WebApi, DecodesBase64AndDataUrls) {
  EXPECT_EQ(DecodeBase64("b2NjbWFw", "image").value(), "occmap");
  EXPECT_EQ(DecodeBase64("b2NjbWFwIQ==", "image").value(), "occmap!");
  EXPECT_EQ(DecodeBase64("b2NjbWFwIQ", "image").value(), "occmap!");  // padding optional
  EXPECT_EQ(DecodeBase64("data:image/png;base64,b2Nj\nbWFw", "image").value(), "occmap");
  EXPECT_EQ(DecodeBase64("", "image").value(), "");
  const auto bad = DecodeBase64("b2Nj*bWFw", "image");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().message(), "image: expected base64, found '*' at character 5");
  // A non-ASCII character: named by its first byte's value, the message still valid UTF-8
  // (it goes back in a JSON reply; found by the serve_api fuzzer).
  const auto accented = DecodeBase64("b2Nj\u00e9bWFw", "image");
  ASSERT_FALSE(accented.ok());
  EXPECT_EQ(accented.status().message(), "image: expected base64, found byte 0xC3 at character 5");
  EXPECT_NO_THROW((void)json({{"error", accented.status().message()}}).dump());
  EXPECT_FALSE(DecodeBase64("b", "image").ok());                       // cut short
  EXPECT_FALSE(DecodeBase64("b2==Nj", "image").ok());                  // data after the padding
  EXPECT_FALSE(DecodeBase64("data:image/png,b2Nj", "image").ok());     // not a base64 data URL
}

TEST(WebApi, LoopbackHosts) {
  EXPECT_TRUE(IsLoopbackHost("127.0.0.1"));
  EXPECT_TRUE(IsLoopbackHost("127.1.2.3"));
  EXPECT_TRUE(IsLoopbackHost("::1"));
  EXPECT_TRUE(IsLoopbackHost("localhost"));
  EXPECT_FALSE(IsLoopbackHost("0.0.0.0"));
  EXPECT_FALSE(IsLoopbackHost("::"));
  EXPECT_FALSE(IsLoopbackHost("192.168.1.2"));
  EXPECT_FALSE(IsLoopbackHost("127.example.com"));
}

// DNS rebinding: attacker.example resolving to 127.0.0.1 still says attacker.example in Host.
TEST(WebApi, HostsThisServerAnswersTo) {
  const ListenAddress listen{"127.0.0.1", 8080};
  const std::vector<std::string> allowed = {"occmap.lan"};
  for (const char* ok : {"", "127.0.0.1:8080", "127.0.0.1", "localhost:8080", "LOCALHOST", "localhost.", "app.localhost:1",
                         "[::1]:8080", "::1", "192.168.1.20:8080", "occmap.lan:8080", "Occmap.Lan"}) {
    EXPECT_TRUE(HostAllowed(ok, listen, allowed)) << ok;
  }
  for (const char* bad : {"attacker.example", "attacker.example:8080", "127.0.0.1.nip.io:8080", "localhost.attacker.example",
                          "occmap.lan.attacker.example", "x"}) {
    EXPECT_FALSE(HostAllowed(bad, listen, allowed)) << bad;
  }
  EXPECT_TRUE(HostAllowed("myhost:80", ListenAddress{"myhost", 80}, {}));
}

TEST(WebApi, CrossSiteWritesAreRefused) {
  const auto refusal = [](std::string_view method, std::string_view origin, std::string_view site,
                          std::string_view type) {
    return CrossSiteWriteRefusal(method, "127.0.0.1:8080", origin, site, type);
  };
  EXPECT_FALSE(refusal("GET", "http://evil.example", "cross-site", "").has_value());  // reads: the Host check's
  EXPECT_FALSE(refusal("POST", "", "", "application/json").has_value());               // curl, scripts
  EXPECT_FALSE(refusal("POST", "http://127.0.0.1:8080", "same-origin", "application/json; charset=utf-8").has_value());
  EXPECT_FALSE(refusal("DELETE", "", "same-origin", "").has_value());
  auto r = refusal("POST", "http://evil.example", "", "application/json");
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->http_status, 403);
  EXPECT_EQ(r->message, "POST from another origin refused (Origin: http://evil.example, Host: 127.0.0.1:8080)");
  EXPECT_EQ(refusal("PUT", "", "same-site", "application/json")->message,
            "PUT from another site refused (Sec-Fetch-Site: same-site)");
  EXPECT_EQ(refusal("DELETE", "null", "", "")->http_status, 403);
  EXPECT_EQ(refusal("POST", "http://127.0.0.1:9999", "", "application/json")->http_status, 403);
  const auto plain = refusal("POST", "", "", "text/plain");
  ASSERT_TRUE(plain.has_value());
  EXPECT_EQ(plain->http_status, 415);
  EXPECT_EQ(plain->message, "Content-Type: expected application/json, found 'text/plain'");
  EXPECT_EQ(refusal("PUT", "", "", "")->http_status, 415);
}

TEST(WebApi, JsonBodiesAreCheckedForDepthBeforeParsing) {
  EXPECT_TRUE(ParseJsonBody(R"({"zones": [{"polygon_m": [[0, 0], [1, 0], [1, 1]]}]})").ok());
  const std::string deep = R"({"points": [)" + std::string(100000, '[') + std::string(100000, ']') + "]}";
  const auto r = ParseJsonBody(deep);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "body:1: nesting deeper than 64 levels; refused before parsing");
  EXPECT_EQ(ParseJsonBody("{").status().message(), "body: expected JSON");
}

TEST(WebApi, TokensFromHeaderOrQuery) {
  EXPECT_TRUE(TokenEquals("s3cret", "s3cret"));
  EXPECT_FALSE(TokenEquals("s3cret", "s3cre"));
  EXPECT_FALSE(TokenEquals("s3cret", "s3cret2"));
  EXPECT_FALSE(TokenEquals("s3cret", ""));
  EXPECT_FALSE(TokenEquals("", ""));  // no token configured never matches (the gate is off then)
  EXPECT_EQ(RequestToken("Bearer abc", ""), "abc");
  EXPECT_EQ(RequestToken("bearer  abc ", "zzz"), "abc");
  EXPECT_EQ(RequestToken("", "q"), "q");
  EXPECT_EQ(RequestToken("Basic xyz", "q"), "q");
}

TEST(WebApi, SessionCookieCarriesAnyTokenAndIsFoundAmongOthers) {
  EXPECT_EQ(SessionCookie("Ab9"), "occmap_token=416239; Path=/; Max-Age=2592000; HttpOnly; SameSite=Strict");
  EXPECT_EQ(SessionCookie(""), "occmap_token=; Path=/; Max-Age=0; HttpOnly; SameSite=Strict");
  // Characters a cookie cannot hold, and '%', which cpp-httplib would decode in a header.
  const std::string odd = "a b;c,d=\"e\"%41\xc3\xa9";
  const std::string set = SessionCookie(odd, 60);
  const std::string value = set.substr(0, set.find(';'));
  EXPECT_EQ(value, "occmap_token=6120623b632c643d226522253431c3a9");
  EXPECT_EQ(CookieTokens("x=1; " + value + "; y=2"), std::vector<std::string>{odd});
  EXPECT_EQ(CookieTokens("occmap_token=6f6c64;occmap_token=6E6577"), (std::vector<std::string>{"old", "new"}));
  EXPECT_TRUE(CookieTokens("occmap_tokenx=61; xoccmap_token=61; occmap_token=; occmap_token=616").empty());
  EXPECT_TRUE(CookieTokens("occmap_token=zz").empty());
  EXPECT_TRUE(CookieTokens("occmap_token=+1").empty());
}

TEST(WebApi, TokenFromBearerCookieOrQuery) {
  EXPECT_EQ(CheckToken("s3cret", "", "", ""), TokenSource::kNone);
  EXPECT_EQ(CheckToken("s3cret", "Bearer s3cret", "", ""), TokenSource::kBearer);
  EXPECT_EQ(CheckToken("s3cret", "", "occmap_token=733363726574", ""), TokenSource::kCookie);
  EXPECT_EQ(CheckToken("s3cret", "", "", "s3cret"), TokenSource::kQuery);
  // A stale cookie does not spoil a right token given otherwise.
  EXPECT_EQ(CheckToken("s3cret", "", "occmap_token=6f6c64", "s3cret"), TokenSource::kQuery);
  EXPECT_EQ(CheckToken("s3cret", "", "occmap_token=6f6c64; occmap_token=733363726574", ""), TokenSource::kCookie);
  EXPECT_EQ(CheckToken("s3cret", "Bearer no", "occmap_token=6f6c64", "no"), TokenSource::kWrong);
  EXPECT_EQ(CheckToken("s3cret", "", "occmap_token=s3cret", ""), TokenSource::kNone) << "not hex: no cookie";
  EXPECT_EQ(TokenSourceName(TokenSource::kCookie), "cookie");
  EXPECT_EQ(TokenSourceName(TokenSource::kWrong), "");
  EXPECT_TRUE(IsOpenPath("/login"));
  EXPECT_FALSE(IsOpenPath("/login.html"));
  EXPECT_TRUE(IsPagePath("/system"));
  EXPECT_FALSE(IsPagePath("/app.js"));
}

TEST(WebApi, RefusesTraversalInEveryEncoding) {
  for (const char* bad : {"/../etc/passwd", "/a/..", "/%2e%2e/x", "/%2E%2E/x", "/.%2e/x", "/%2e./x", "/a\\b",
                          "/a%5cb", "/a%00b", "/%252e%252e/x", "/api/cameras/..%2fc1/frame.jpg"}) {
    EXPECT_TRUE(IsTraversal(bad)) << bad;
  }
  EXPECT_TRUE(IsTraversal(std::string_view("/a\0b", 4)));
  for (const char* good : {"/", "/app.js", "/api/site", "/?token=a.b", "/api/cameras/c.1/frame.jpg?overlay=grid"}) {
    EXPECT_FALSE(IsTraversal(good)) << good;
  }
}

TEST(WebApi, StaticFileNames) {
  EXPECT_EQ(StaticFileName("/"), "index.html");
  EXPECT_EQ(StaticFileName("/app.js"), "app.js");
  EXPECT_EQ(StaticFileName("/a/b.js"), "");
  EXPECT_EQ(StaticFileName("/.env"), "");
  EXPECT_EQ(StaticFileName("app.js"), "");
  EXPECT_EQ(ContentTypeFor("index.html"), "text/html; charset=utf-8");
  EXPECT_EQ(ContentTypeFor("app.JS"), "text/javascript; charset=utf-8");
  EXPECT_EQ(ContentTypeFor("app.css"), "text/css; charset=utf-8");
  EXPECT_EQ(ContentTypeFor("x.png"), "image/png");
  EXPECT_EQ(ContentTypeFor("blob"), "application/octet-stream");
}

TEST(WebApi, SseFraming) {
  EXPECT_EQ(SseEvent("frame", "{\"a\":1}"), "event: frame\ndata: {\"a\":1}\n\n");
  // A line break in the data cannot end the event early: each line gets its own data field.
  EXPECT_EQ(SseEvent("site", "a\nb\r\nc"), "event: site\ndata: a\ndata: b\ndata: c\n\n");
  EXPECT_EQ(SseEvent("x", ""), "event: x\ndata: \n\n");
}

LiveSnapshot TestSnapshot() {
  LiveSnapshot s;
  s.version = 7;
  s.frame = 12;
  s.time_s = 1.2;
  s.t_unix = 1.7e9;
  FloorGrid g;
  g.origin_x_m = -1;
  g.origin_y_m = 0;
  g.cells_x = 3;
  g.cells_y = 2;
  g.cell_size_m = 0.5;
  s.map = OccupancyMap(g);
  s.map.states()[0] = CellState::kFree;      // cell (0, 0): bottom-left of the picture
  s.map.states()[5] = CellState::kOccupied;  // cell (2, 1): top-right
  Detection d;
  d.x_m = 1;
  d.y_m = 2;
  d.class_hint = "person";
  s.detections.push_back(d);
  Track t;
  t.id = 3;
  t.x_m = 1.5;
  t.vx_mps = 0.5;
  t.object_class = "person";
  s.tracks.push_back(t);
  s.zone_names = {"door", "desk \"A\""};
  s.zone_counts = {2, 0};
  s.line_names = {"gate"};
  s.line_counts = {LineCounts{4, 1}};
  s.stats.frames = 13;
  s.stats.elapsed_s = 2;
  s.stats.frames_per_second = 6.5;
  s.stats.cameras = {CameraStats{"c1", true, true, 13, 2, 1}, CameraStats{"c2", true, false, 10, 0, 3}};
  s.stats.latency = {13, 20, 40, 50, 60, 520};
  s.stats.cameras[0].background_age_s = 42.5;  // c2 gives masks: no background (NaN)
  s.stats.cameras[0].background_cache = BackgroundCacheFigures{"/cache/c1-y.png", 4, 2, 30, "disk full"};  // a live camera
  s.stats.stages.decode = 1.5;
  s.stats.stages.fuse = 0.25;
  s.stats.stages.tables = 3;
  s.camera_ids = {"c1", "c2"};
  return s;
}

TEST(WebApi, FrameAndStateJson) {
  const LiveSnapshot s = TestSnapshot();
  const json f = FrameEventJson(s);
  EXPECT_EQ(f["frame"], 12);
  EXPECT_EQ(f["map_version"], 12);
  EXPECT_EQ(f["detections"][0]["kind"], "person");
  EXPECT_EQ(f["tracks"][0]["id"], 3);
  EXPECT_EQ(f["tracks"][0]["vx_mps"], 0.5);
  EXPECT_EQ(f["zones"][0], (json{{"name", "door"}, {"count", 2}}));
  EXPECT_EQ(f["lines"][0], (json{{"name", "gate"}, {"in", 4}, {"out", 1}}));
  const json st = StateJson(s, true, 5);
  EXPECT_EQ(st["running"], true);
  EXPECT_EQ(st["starting"], false);
  EXPECT_EQ(StateJson(s, false, 5, true)["starting"], true);
  // A run that stopped on an error says so; a running one keeps its stats' reason.
  EXPECT_EQ(StateJson(s, false, 5, false, "error: c1: no frames")["stop_reason"], "error: c1: no frames");
  EXPECT_EQ(StateJson(s, true, 5, false, "error: old")["stop_reason"], s.stats.stop_reason);
  EXPECT_EQ(st["cameras"][1]["connected"], false);
  EXPECT_EQ(st["cameras"][0]["fps"], 6.5);
  EXPECT_EQ(st["cameras"][1]["fps"], 5.0);  // in 10 of the 13 frame sets
  EXPECT_EQ(st["cameras"][0]["dropped"], 2);
  EXPECT_EQ(st["latency_ms"]["p95"], 40);
  EXPECT_EQ(st["cameras"][0]["background_age_s"], 42.5);
  EXPECT_TRUE(st["cameras"][1]["background_age_s"].is_null());
  EXPECT_EQ(st["cameras"][0]["background_cache"],
            (json{{"refreshes", 4}, {"failures", 2}, {"last_refresh_frame", 30}, {"last_error", "disk full"}}));
  EXPECT_FALSE(st["cameras"][1].contains("background_cache"));
  EXPECT_EQ(st["stages_s"]["decode"], 1.5);
  EXPECT_EQ(st["stages_s"]["fuse"], 0.25);
  EXPECT_EQ(st["stages_s"]["tables"], 3);
  EXPECT_EQ(st["stages_s"]["track"], 0);
  EXPECT_EQ(st["stages_s"].size(), 9u);
  EXPECT_TRUE(st["mqtt"].is_null()) << "no MQTT in this run";
}

TEST(WebApi, TheMqttLinkInStateAndMetrics) {
  LiveSnapshot s = TestSnapshot();
  MqttCounters m;
  m.connected = false;
  m.connects = 1;
  m.disconnects = 1;
  m.failures = 3;
  m.published = 120;
  m.dropped = 7;
  m.broker = "mqtt://broker.lan:1883";
  m.error = "Connection refused";
  s.mqtt = m;
  EXPECT_EQ(StateJson(s, true, 5)["mqtt"], (json{{"broker", "mqtt://broker.lan:1883"},
                                                {"connected", false},
                                                {"error", "Connection refused"},
                                                {"published", 120},
                                                {"dropped", 7},
                                                {"connects", 1},
                                                {"disconnects", 1},
                                                {"failures", 3},
                                                {"cleared", 0}}));
  const std::string text = MetricsText(s, true);
  for (const char* line : {"occmap_mqtt_connected{broker=\"mqtt://broker.lan:1883\"} 0\n",
                           "occmap_mqtt_messages_published_total 120\n", "occmap_mqtt_messages_dropped_total 7\n",
                           "occmap_mqtt_connects_total 1\n", "occmap_mqtt_connection_failures_total 3\n"}) {
    EXPECT_NE(text.find(line), std::string::npos) << line << "\n" << text;
  }
  EXPECT_EQ(MetricsText(TestSnapshot(), true).find("occmap_mqtt"), std::string::npos) << "no MQTT: no MQTT figures";
  s.mqtt->connected = true;
  s.mqtt->error.clear();
  EXPECT_TRUE(StateJson(s, true, 5)["mqtt"]["error"].is_null());
}

TEST(WebApi, MetricsText) {
  const std::string m = MetricsText(TestSnapshot(), true);
  for (const char* line :
       {"occmap_frames_total 13\n", "occmap_camera_frames_per_second{camera=\"c1\"} 6.5\n",
        "occmap_camera_up{camera=\"c1\"} 1\n", "occmap_camera_up{camera=\"c2\"} 0\n",
        "occmap_frames_dropped_total{camera=\"c1\"} 2\n", "occmap_latency_seconds{quantile=\"0.95\"} 0.04\n",
        "occmap_zone_objects{zone=\"door\"} 2\n", "occmap_zone_objects{zone=\"desk \\\"A\\\"\"} 0\n",
        "occmap_line_crossings_total{line=\"gate\",direction=\"in\"} 4\n",
        "occmap_line_crossings_total{line=\"gate\",direction=\"out\"} 1\n",
        "occmap_camera_background_age_seconds{camera=\"c1\"} 42.5\n", "occmap_stage_seconds_total{stage=\"decode\"} 1.5\n",
        "occmap_stage_seconds_total{stage=\"tables\"} 3\n", "# TYPE occmap_latency_seconds summary\n",
        "occmap_background_cache_refreshes_total{camera=\"c1\"} 4\n",
        "occmap_background_cache_failures_total{camera=\"c1\"} 2\n"}) {
    EXPECT_NE(m.find(line), std::string::npos) << line << "\n" << m;
  }
  // The summary's sum (13 frame sets of 20-60 ms, set below as 0.52 s), the build, the process.
  for (const char* line : {"occmap_latency_seconds_sum 0.52\n", "occmap_latency_seconds_count 13\n",
                           "occmap_build_info{version=\"0.1.0\"} 1\n", "# TYPE process_cpu_seconds_total counter\n",
                           "# TYPE process_resident_memory_bytes gauge\n", "# TYPE process_open_fds gauge\n"}) {
    EXPECT_NE(m.find(line), std::string::npos) << line << "\n" << m;
  }
  auto value = [&](const std::string& name) {
    const size_t at = m.find("\n" + name + " ");
    return at == std::string::npos ? -1.0 : std::stod(m.substr(at + name.size() + 2));
  };
  EXPECT_GT(value("process_resident_memory_bytes"), 1e6);
  EXPECT_GE(value("process_open_fds"), 3);
  EXPECT_GT(value("process_start_time_seconds"), 1.7e9);
  EXPECT_GE(value("process_cpu_seconds_total"), 0);
  EXPECT_EQ(m.find("occmap_camera_background_age_seconds{camera=\"c2\"}"), std::string::npos) << "no background: no sample";
  EXPECT_EQ(m.find("occmap_background_cache_failures_total{camera=\"c2\"}"), std::string::npos) << "no cache refreshed";
  // Every sample line: name{labels} value.
  size_t start = 0;
  while (start < m.size()) {
    const size_t end = m.find('\n', start);
    ASSERT_NE(end, std::string::npos);
    const std::string l = m.substr(start, end - start);
    if (l[0] != '#') {
      EXPECT_TRUE(l.rfind("occmap_", 0) == 0 || l.rfind("process_", 0) == 0) << l;
    }
    start = end + 1;
  }
}

TEST(WebApi, MapPngIsNorthUp) {
  const std::string png = MapPng(TestSnapshot().map);
  ASSERT_FALSE(png.empty());
  const cv::Mat img = cv::imdecode(std::vector<uint8_t>(png.begin(), png.end()), cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, 3);
  ASSERT_EQ(img.rows, 2);
  EXPECT_EQ(img.at<cv::Vec3b>(1, 0), cv::Vec3b(255, 255, 255));  // cell (0, 0), free: bottom row
  EXPECT_EQ(img.at<cv::Vec3b>(0, 2), cv::Vec3b(0, 0, 0));        // cell (2, 1), occupied: top row
  EXPECT_EQ(img.at<cv::Vec3b>(0, 0), cv::Vec3b(205, 205, 205));  // unseen
  EXPECT_TRUE(MapPng(OccupancyMap()).empty());
}

// The mask editor's overlay: excluded pixels shaded, floor clear, the mask's own size.
TEST(WebApi, MaskOverlayPngShadesExcludedPixels) {
  Image<uint8_t> mask(4, 3);
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) mask.row(y)[x] = x >= 2 ? 255 : 0;
  }
  const std::string png = MaskOverlayPng(mask);
  ASSERT_FALSE(png.empty());
  const cv::Mat img = cv::imdecode(std::vector<uint8_t>(png.begin(), png.end()), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(img.type(), CV_8UC4);
  ASSERT_EQ(img.cols, 4);
  ASSERT_EQ(img.rows, 3);
  EXPECT_EQ(img.at<cv::Vec4b>(1, 0)[3], 140);  // excluded
  EXPECT_EQ(img.at<cv::Vec4b>(1, 3)[3], 0);    // floor
  EXPECT_TRUE(MaskOverlayPng(Image<uint8_t>()).empty());
}

// The coverage picture: visibility.png's colours, a pixel per cell, north up; its figures.
TEST(WebApi, CoveragePngAndJson) {
  LiveCoverage c;
  c.version = 4;
  c.grid.cells_x = 3;
  c.grid.cells_y = 2;
  c.grid.cell_size_m = 0.5;
  c.num_cameras = 2;
  c.view_count = {0, 1, 2, 2, 2, 1};  // bottom row 0 1 2, top row 2 2 1
  const std::string png = CoveragePng(c);
  ASSERT_FALSE(png.empty());
  const cv::Mat img = cv::imdecode(std::vector<uint8_t>(png.begin(), png.end()), cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, 3);
  ASSERT_EQ(img.rows, 2);
  auto bgr = [&](int k) {
    const Rgb8 v = VisibilityColor(k, 2);
    return cv::Vec3b(v.b, v.g, v.r);
  };
  EXPECT_EQ(img.at<cv::Vec3b>(1, 0), bgr(0));  // cell (0, 0): bottom left, unseen
  EXPECT_EQ(img.at<cv::Vec3b>(1, 2), bgr(2));
  EXPECT_EQ(img.at<cv::Vec3b>(0, 2), bgr(1));  // cell (2, 1): top right
  EXPECT_NE(bgr(1), bgr(2));
  const json j = CoverageJson(c);
  EXPECT_EQ(j["version"], 4);
  EXPECT_EQ(j["num_cameras"], 2);
  EXPECT_EQ(j["cells"], 6);
  EXPECT_EQ(j["cells_seen_by"], (json{1, 2, 3}));
  ASSERT_EQ(j["colors"].size(), 3u);
  const Rgb8 one = VisibilityColor(1, 2);
  EXPECT_EQ(j["colors"][1], fmt::format("#{:02x}{:02x}{:02x}", one.r, one.g, one.b));
  c.view_count.pop_back();
  EXPECT_TRUE(CoveragePng(c).empty()) << "counts that do not fit the grid";
}

TEST(WebApi, CameraJpegTintsChanges) {
  LiveSnapshot s = TestSnapshot();
  s.frames_gray.assign(2, Image<uint8_t>());
  s.frames_rgb.assign(2, Image<Rgb8>());
  s.change_masks.assign(2, Image<uint8_t>());
  s.frames_gray[0] = Image<uint8_t>(64, 48, 100);
  s.change_masks[0] = Image<uint8_t>(64, 48, 0);
  for (int y = 0; y < 24; ++y) {
    for (int x = 0; x < 64; ++x) s.change_masks[0].row(y)[x] = 1;
  }
  EXPECT_TRUE(CameraJpeg(s, 1, true).empty());  // no frame yet
  const std::string jpeg = CameraJpeg(s, 0, true, 95);
  ASSERT_FALSE(jpeg.empty());
  const cv::Mat img = cv::imdecode(std::vector<uint8_t>(jpeg.begin(), jpeg.end()), cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, 64);
  const cv::Vec3b top = img.at<cv::Vec3b>(5, 30), bottom = img.at<cv::Vec3b>(40, 30);  // BGR
  EXPECT_NEAR(top[2], 177, 4);
  EXPECT_NEAR(top[1], 50, 4);
  EXPECT_NEAR(bottom[2], 100, 4);
  EXPECT_NEAR(bottom[1], 100, 4);
  const std::string plain = CameraJpeg(s, 0, false, 95);
  const cv::Mat p = cv::imdecode(std::vector<uint8_t>(plain.begin(), plain.end()), cv::IMREAD_COLOR);
  EXPECT_NEAR(p.at<cv::Vec3b>(5, 30)[2], 100, 4);
}

// The live tiles: each track's box in its colour, with "id class" on a filled label.
TEST(WebApi, CameraJpegDrawsTrackBoxes) {
  LiveSnapshot s = TestSnapshot();
  s.frames_gray.assign(1, Image<uint8_t>(160, 120, 100));
  s.frames_rgb.assign(1, Image<Rgb8>());
  s.change_masks.assign(1, Image<uint8_t>());
  s.track_boxes.assign(1, {TrackBox{7, "person", false, 40, 50, 100, 110}});
  auto decode = [](const std::string& jpeg) {
    return cv::imdecode(std::vector<uint8_t>(jpeg.begin(), jpeg.end()), cv::IMREAD_COLOR);
  };
  const cv::Mat img = decode(CameraJpeg(s, 0, true, 95));
  const cv::Mat plain = decode(CameraJpeg(s, 0, false, 95));
  auto grey = [](const cv::Vec3b& c) { return std::abs(c[0] - 100) < 6 && std::abs(c[1] - 100) < 6 && std::abs(c[2] - 100) < 6; };
  EXPECT_FALSE(grey(img.at<cv::Vec3b>(80, 40))) << "the box's left side";
  EXPECT_FALSE(grey(img.at<cv::Vec3b>(110, 70))) << "its bottom";
  EXPECT_TRUE(grey(img.at<cv::Vec3b>(80, 70))) << "inside: the picture";
  EXPECT_FALSE(grey(img.at<cv::Vec3b>(45, 42))) << "the label above the box";
  EXPECT_TRUE(grey(plain.at<cv::Vec3b>(80, 40))) << "overlay=none: no boxes";
}

TEST(WebApi, FrameEventCarriesTheLatestEvents) {
  LiveSnapshot s = TestSnapshot();
  for (int i = 0; i < 30; ++i) s.recent_events.push_back(fmt::format(R"({{"frame":{},"line":"gate","event":"cross"}})", i));
  s.recent_events.push_back("not json");
  s.events_total = 131;
  const json f = FrameEventJson(s);
  EXPECT_EQ(f["events_total"], 131);
  ASSERT_EQ(f["events"].size(), kFrameEvents - 1);  // the unreadable line left out
  EXPECT_EQ(f["events"].back()["frame"], 29);
  EXPECT_EQ(f["events"].back()["line"], "gate");
  EXPECT_EQ(EventsJson(s, kRecentEvents).size(), 30u);
}

TEST(WebApi, ACameraWithChangesAndNoFrameShowsItsChanges) {
  // occmap fuse's cameras: the changes their edges sent, no frames.
  LiveSnapshot s = TestSnapshot();
  s.frames_gray.assign(1, Image<uint8_t>());
  s.frames_rgb.assign(1, Image<Rgb8>());
  s.change_masks.assign(1, Image<uint8_t>(64, 48, 0));
  for (int y = 0; y < 24; ++y) {
    for (int x = 0; x < 64; ++x) s.change_masks[0].row(y)[x] = 1;
  }
  const Image<Rgb8> rgb = CameraRgb(s, 0);
  ASSERT_EQ(rgb.width(), 64);
  EXPECT_EQ(rgb(30, 5).g, 230);   // changed: light
  EXPECT_EQ(rgb(30, 40).g, 24);   // not: dark
  const std::string jpeg = CameraJpeg(s, 0, /*change_overlay=*/false, 95);
  ASSERT_FALSE(jpeg.empty());
  const cv::Mat img = cv::imdecode(std::vector<uint8_t>(jpeg.begin(), jpeg.end()), cv::IMREAD_COLOR);
  EXPECT_NEAR(img.at<cv::Vec3b>(5, 30)[1], 230, 4);
  EXPECT_NEAR(img.at<cv::Vec3b>(40, 30)[1], 24, 4);
  s.change_masks[0] = Image<uint8_t>();
  EXPECT_TRUE(CameraJpeg(s, 0, false).empty());  // neither yet
}

}  // namespace
}  // namespace occmap
