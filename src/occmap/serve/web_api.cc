#include "occmap/serve/web_api.h"

#include <fmt/core.h>
#include <yaml-cpp/yaml.h>

#include <arpa/inet.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <charconv>
#include <cmath>
#include "occmap/lut/visibility_image.h"
#include "occmap/util/text_guard.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <utility>

namespace occmap {
namespace {

using nlohmann::json;

json Num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

std::string Lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// Prometheus label values: backslash, quote and newline escaped.
std::string Label(std::string_view v) {
  std::string out;
  for (char c : v) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

std::string Encode(const cv::Mat& bgr, const char* ext, std::vector<int> params) {
  std::vector<uint8_t> buf;
  if (!cv::imencode(ext, bgr, buf, params)) return {};
  return std::string(buf.begin(), buf.end());
}

cv::Mat ToBgr(const Image<Rgb8>& image) {
  cv::Mat bgr(image.height(), image.width(), CV_8UC3);
  for (int y = 0; y < image.height(); ++y) {
    const Rgb8* src = image.row(y);
    uint8_t* dst = bgr.ptr<uint8_t>(y);
    for (int x = 0; x < image.width(); ++x) {
      dst[3 * x] = src[x].b;
      dst[3 * x + 1] = src[x].g;
      dst[3 * x + 2] = src[x].r;
    }
  }
  return bgr;
}

// A camera's frames per second: the run's steady rate times the share of frame sets it took
// part in (frames over the whole run would count the start-up).
double CameraFps(const RunStats& stats, const CameraStats& c) {
  if (stats.frames <= 0) return 0;
  return stats.frames_per_second * static_cast<double>(c.frames) / static_cast<double>(stats.frames);
}

// The stages by name, in the order of a frame set's way through the run.
std::vector<std::pair<const char*, double>> Stages(const StageSeconds& t) {
  return {{"tables", t.tables}, {"decode", t.decode}, {"detect", t.detect}, {"fuse", t.fuse},
          {"people", t.people}, {"background", t.background}, {"blobs", t.blobs}, {"track", t.track},
          {"output", t.output}};
}

json StagesJson(const StageSeconds& t) {
  json j = json::object();
  for (const auto& [name, seconds] : Stages(t)) j[name] = Num(seconds);
  return j;
}

}  // namespace

Result<ListenAddress> ParseListen(std::string_view text, std::string_view option) {
  ListenAddress a;
  std::string_view host = text, port;
  if (!text.empty() && text.front() == '[') {
    const size_t close = text.find(']');
    if (close == std::string_view::npos) {
      return InvalidInput(fmt::format("{}: expected [IPv6]:PORT, found '{}'", option, text));
    }
    host = text.substr(1, close - 1);
    if (close + 1 < text.size()) {
      if (text[close + 1] != ':') return InvalidInput(fmt::format("{}: expected [IPv6]:PORT, found '{}'", option, text));
      port = text.substr(close + 2);
    }
  } else if (const size_t colon = text.rfind(':'); colon != std::string_view::npos) {
    if (text.find(':') != colon) {
      return InvalidInput(fmt::format("{}: an IPv6 address goes in brackets ([::1]:8080), found '{}'", option, text));
    }
    host = text.substr(0, colon);
    port = text.substr(colon + 1);
  }
  if (!host.empty()) a.host = std::string(host);
  if (!port.empty() || text.find(':') != std::string_view::npos) {
    int p = -1;
    const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), p);
    if (ec != std::errc() || end != port.data() + port.size() || p < 0 || p > 65535) {
      return InvalidInput(fmt::format("{}: expected HOST:PORT with a port 0..65535, found '{}'", option, text));
    }
    a.port = p;
  }
  for (char c : a.host) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-' && c != ':') {
      return InvalidInput(fmt::format("{}: expected a host name or address, found '{}'", option, a.host));
    }
  }
  return a;
}

bool IsLoopbackHost(std::string_view host) {
  if (host == "localhost" || host == "::1") return true;
  return host.substr(0, 4) == "127." && host.find_first_not_of("0123456789.") == std::string_view::npos;
}

std::string HostName(std::string_view host_header) {
  std::string_view h = host_header;
  while (!h.empty() && (h.front() == ' ' || h.front() == '\t')) h.remove_prefix(1);
  while (!h.empty() && (h.back() == ' ' || h.back() == '\t' || h.back() == '\r')) h.remove_suffix(1);
  if (!h.empty() && h.front() == '[') {
    const size_t close = h.find(']');
    h = close == std::string_view::npos ? h.substr(1) : h.substr(1, close - 1);
  } else if (const size_t colon = h.rfind(':'); colon != std::string_view::npos && h.find(':') == colon) {
    h = h.substr(0, colon);
  }
  if (!h.empty() && h.back() == '.') h.remove_suffix(1);
  return Lower(h);
}

bool HostAllowed(std::string_view host_header, const ListenAddress& listen, const std::vector<std::string>& allowed) {
  if (host_header.empty()) return true;
  const std::string name = HostName(host_header);
  in6_addr v6{};
  in_addr v4{};
  if (inet_pton(AF_INET, name.c_str(), &v4) == 1 || inet_pton(AF_INET6, name.c_str(), &v6) == 1) return true;
  if (name == "localhost" || name.ends_with(".localhost")) return true;
  if (name == Lower(listen.host)) return true;
  for (const std::string& a : allowed) {
    if (name == HostName(a)) return true;
  }
  return false;
}

std::optional<Refusal> CrossSiteWriteRefusal(std::string_view method, std::string_view host_header,
                                             std::string_view origin, std::string_view sec_fetch_site,
                                             std::string_view content_type) {
  if (method != "POST" && method != "PUT" && method != "PATCH" && method != "DELETE") return std::nullopt;
  const std::string site = Lower(sec_fetch_site);
  if (!site.empty() && site != "same-origin" && site != "none") {
    return Refusal{403, fmt::format("{} from another site refused (Sec-Fetch-Site: {})", method, Excerpt(site, 40))};
  }
  if (!origin.empty()) {
    const std::string o = Lower(origin), host = Lower(host_header);
    if (host.empty() || (o != "http://" + host && o != "https://" + host)) {
      return Refusal{403, fmt::format("{} from another origin refused (Origin: {}, Host: {})", method,
                                      Excerpt(origin, 80), Excerpt(host_header, 80))};
    }
  }
  if (method == "POST" || method == "PUT" || method == "PATCH") {
    std::string_view type = content_type.substr(0, content_type.find(';'));
    while (!type.empty() && type.back() == ' ') type.remove_suffix(1);
    if (Lower(type) != "application/json") {
      return Refusal{415, fmt::format("Content-Type: expected application/json, found '{}'", Excerpt(content_type, 80))};
    }
  }
  return std::nullopt;
}

bool TokenEquals(std::string_view expected, std::string_view given) {
  unsigned diff = expected.size() == given.size() ? 0u : 1u;
  for (size_t i = 0; i < expected.size(); ++i) {
    const char g = i < given.size() ? given[i] : '\0';
    diff |= static_cast<unsigned>(static_cast<unsigned char>(expected[i]) ^ static_cast<unsigned char>(g));
  }
  return diff == 0 && !expected.empty();
}

std::string RequestToken(std::string_view authorization, std::string_view query_token) {
  constexpr std::string_view kBearer = "Bearer ";
  if (authorization.size() > kBearer.size() && Lower(authorization.substr(0, kBearer.size())) == "bearer ") {
    std::string_view t = authorization.substr(kBearer.size());
    while (!t.empty() && t.front() == ' ') t.remove_prefix(1);
    while (!t.empty() && (t.back() == ' ' || t.back() == '\r')) t.remove_suffix(1);
    return std::string(t);
  }
  return std::string(query_token);
}

std::string SessionCookie(std::string_view token, int max_age_s) {
  // Hex: a cookie value may not hold ';', ',', spaces or quotes, and cpp-httplib percent-decodes
  // every header value before the server sees it, so a percent-encoded value would not survive.
  std::string value;
  for (const char ch : token) value += fmt::format("{:02x}", static_cast<unsigned char>(ch));
  return fmt::format("{}={}; Path=/; Max-Age={}; HttpOnly; SameSite=Strict", kSessionCookie, value,
                     token.empty() ? 0 : max_age_s);
}

std::vector<std::string> CookieTokens(std::string_view header) {
  std::vector<std::string> out;
  while (!header.empty()) {
    const size_t end = std::min(header.find(';'), header.size());
    std::string_view pair = header.substr(0, end);
    header.remove_prefix(std::min(end + 1, header.size()));
    while (!pair.empty() && pair.front() == ' ') pair.remove_prefix(1);
    const size_t eq = pair.find('=');
    if (eq == std::string_view::npos || pair.substr(0, eq) != kSessionCookie) continue;
    std::string_view v = pair.substr(eq + 1);
    while (!v.empty() && v.back() == ' ') v.remove_suffix(1);
    if (v.empty() || v.size() % 2 != 0) continue;
    std::string decoded;
    for (size_t i = 0; i < v.size(); i += 2) {
      unsigned byte = 0;
      if (!std::isxdigit(static_cast<unsigned char>(v[i])) || !std::isxdigit(static_cast<unsigned char>(v[i + 1])) ||
          std::from_chars(v.data() + i, v.data() + i + 2, byte, 16).ptr != v.data() + i + 2) {
        decoded.clear();
        break;
      }
      decoded += static_cast<char>(byte);
    }
    if (!decoded.empty()) out.push_back(std::move(decoded));
  }
  return out;
}

TokenSource CheckToken(std::string_view expected, std::string_view authorization, std::string_view cookie_header,
                       std::string_view query_token) {
  bool given = false;
  const std::string bearer = RequestToken(authorization, "");
  if (!bearer.empty()) {
    if (TokenEquals(expected, bearer)) return TokenSource::kBearer;
    given = true;
  }
  for (const std::string& c : CookieTokens(cookie_header)) {
    if (TokenEquals(expected, c)) return TokenSource::kCookie;
    given = true;
  }
  if (!query_token.empty()) {
    if (TokenEquals(expected, query_token)) return TokenSource::kQuery;
    given = true;
  }
  return given ? TokenSource::kWrong : TokenSource::kNone;
}

std::string_view TokenSourceName(TokenSource s) {
  switch (s) {
    case TokenSource::kBearer:
      return "bearer";
    case TokenSource::kCookie:
      return "cookie";
    case TokenSource::kQuery:
      return "query";
    default:
      return "";
  }
}

bool IsPagePath(std::string_view path) { return path == "/" || path == "/index.html" || path == "/system"; }

bool IsOpenPath(std::string_view path) {
  return path == "/login" || path == "/api/login" || path == "/api/logout" || path == "/api/session";
}

std::string LoginPageHtml() {
  return R"html(<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>occmap: sign in</title>
<style>
body { font: 15px/1.4 system-ui, sans-serif; background: #f1f5f9; color: #0f172a; margin: 0;
       display: flex; min-height: 100vh; align-items: center; justify-content: center; }
form { background: #fff; border: 1px solid #cbd5e1; border-radius: 8px; padding: 24px 28px; width: 320px; }
h1 { font-size: 20px; margin: 0 0 4px; }
p { color: #475569; margin: 0 0 16px; font-size: 13px; }
label { display: block; font-size: 13px; margin-bottom: 4px; }
input { width: 100%; box-sizing: border-box; padding: 7px 8px; font: inherit; border: 1px solid #94a3b8; border-radius: 4px; }
button { margin-top: 14px; width: 100%; padding: 8px; font: inherit; font-weight: 600; color: #fff;
         background: #2563eb; border: 0; border-radius: 4px; cursor: pointer; }
.error { color: #b91c1c; min-height: 1.4em; margin: 10px 0 0; font-size: 13px; }
</style>
</head>
<body>
<form id="login" method="post" action="/api/login" autocomplete="on">
  <h1>occmap</h1>
  <p>This server needs its token (<code>--token</code> or <code>--token-file</code> of the command that started it).</p>
  <label for="token">Token</label>
  <input id="token" name="token" type="password" autocomplete="current-password" required autofocus data-testid="login-token">
  <button type="submit" data-testid="login-submit">Sign in</button>
  <p class="error" id="error" data-testid="login-error" role="alert"></p>
</form>
<script>
(function () {
  var next = new URLSearchParams(location.search).get('next') || '/';
  if (['/', '/index.html', '/system'].indexOf(next) < 0) next = '/';
  var go = function () { location.replace(next); };
  // Signed in already (a link from another site does not send the SameSite=Strict cookie; this
  // same-origin request does).
  fetch('/api/session').then(function (r) { return r.json(); }).then(function (s) {
    if (s.signed_in) go();
  }).catch(function () {});
  document.getElementById('login').addEventListener('submit', function (e) {
    e.preventDefault();
    var error = document.getElementById('error');
    error.textContent = '';
    fetch('/api/login', { method: 'POST', headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify({ token: document.getElementById('token').value }) })
      .then(function (r) {
        if (r.ok) return go();
        return r.json().then(function (b) { error.textContent = b.error || ('HTTP ' + r.status); });
      })
      .catch(function (err) { error.textContent = 'cannot reach occmap: ' + err.message; });
  });
})();
</script>
</body>
</html>
)html";
}

bool IsTraversal(std::string_view raw) {
  const std::string t = Lower(raw);
  if (t.find('\0') != std::string::npos || t.find('\\') != std::string::npos) return true;
  for (const char* bad : {"..", "%2e%2e", "%2e.", ".%2e", "%5c", "%00", "%252e", "%255c"}) {
    if (t.find(bad) != std::string::npos) return true;
  }
  return false;
}

std::string StaticFileName(std::string_view path) {
  if (path.empty() || path.front() != '/') return {};
  std::string_view name = path.substr(1);
  if (name.empty()) return "index.html";
  if (name.front() == '.') return {};
  for (char c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '-' && c != '_') return {};
  }
  return std::string(name);
}

std::string ContentTypeFor(std::string_view name) {
  const size_t dot = name.rfind('.');
  const std::string ext = dot == std::string_view::npos ? "" : Lower(name.substr(dot + 1));
  if (ext == "html") return "text/html; charset=utf-8";
  if (ext == "js" || ext == "mjs") return "text/javascript; charset=utf-8";
  if (ext == "css") return "text/css; charset=utf-8";
  if (ext == "json" || ext == "map") return "application/json";
  if (ext == "svg") return "image/svg+xml";
  if (ext == "png") return "image/png";
  if (ext == "jpg" || ext == "jpeg") return "image/jpeg";
  if (ext == "ico") return "image/x-icon";
  if (ext == "woff2") return "font/woff2";
  if (ext == "woff") return "font/woff";
  if (ext == "txt") return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

Result<json> ParseJsonBody(std::string_view body) {
  OCCMAP_RETURN_IF_ERROR(CheckNesting(body, TextSyntax::kJson, kMaxNestingDepth, "body"));
  json j = json::parse(body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return InvalidInput("body: expected JSON");
  return j;
}

Result<std::string> DecodeBase64(std::string_view text, std::string_view field) {
  if (text.substr(0, 5) == "data:") {
    const size_t comma = text.find(',');
    if (comma == std::string_view::npos || text.substr(0, comma).find(";base64") == std::string_view::npos) {
      return InvalidInput(fmt::format("{}: expected a base64 data URL (data:image/png;base64,...)", field));
    }
    text.remove_prefix(comma + 1);
  }
  std::string out;
  out.reserve(text.size() / 4 * 3);
  uint32_t acc = 0;
  int bits = 0;
  size_t pad = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    int v = -1;
    if (c >= 'A' && c <= 'Z') v = c - 'A';
    else if (c >= 'a' && c <= 'z') v = c - 'a' + 26;
    else if (c >= '0' && c <= '9') v = c - '0' + 52;
    else if (c == '+' || c == '-') v = 62;
    else if (c == '/' || c == '_') v = 63;
    else if (c == '=') {
      ++pad;
      continue;
    } else if (c == ' ' || c == '\n' || c == '\r' || c == '\t') {
      continue;
    }
    if (v < 0 || pad > 0) {
      // A byte of a multi-byte character is named by its value: the message must stay UTF-8.
      const auto u = static_cast<unsigned char>(c);
      const std::string found = u >= 0x20 && u < 0x7f ? fmt::format("'{}'", c) : fmt::format("byte 0x{:02X}", u);
      return InvalidInput(fmt::format("{}: expected base64, found {} at character {}", field, found, i + 1));
    }
    acc = (acc << 6) | static_cast<uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out += static_cast<char>((acc >> bits) & 0xff);
    }
  }
  if (bits >= 6 || pad > 2) return InvalidInput(fmt::format("{}: base64 cut short", field));
  return out;
}

std::string SseEvent(std::string_view event, std::string_view data) {
  std::string out = fmt::format("event: {}\n", event);
  size_t start = 0;
  while (true) {
    size_t nl = data.find('\n', start);
    std::string_view line = data.substr(start, nl == std::string_view::npos ? std::string_view::npos : nl - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    out += "data: ";
    out += line;
    out += '\n';
    if (nl == std::string_view::npos) break;
    start = nl + 1;
  }
  out += '\n';
  return out;
}

json FrameEventJson(const LiveSnapshot& s) {
  json dets = json::array();
  for (const Detection& d : s.detections) {
    json j = {{"x_m", Num(d.x_m)}, {"y_m", Num(d.y_m)}, {"area_m2", Num(d.area_m2)}};
    if (!d.class_hint.empty()) j["kind"] = d.class_hint;
    dets.push_back(std::move(j));
  }
  json tracks = json::array();
  for (const Track& t : s.tracks) {
    tracks.push_back({{"id", t.id}, {"x_m", Num(t.x_m)}, {"y_m", Num(t.y_m)}, {"vx_mps", Num(t.vx_mps)},
                      {"vy_mps", Num(t.vy_mps)}, {"kind", t.object_class}, {"coasting", t.coasting}});
  }
  json zones = json::array();
  for (size_t i = 0; i < s.zone_names.size(); ++i) {
    zones.push_back({{"name", s.zone_names[i]}, {"count", i < s.zone_counts.size() ? s.zone_counts[i] : 0}});
  }
  json lines = json::array();
  for (size_t i = 0; i < s.line_names.size(); ++i) {
    const LineCounts c = i < s.line_counts.size() ? s.line_counts[i] : LineCounts{};
    lines.push_back({{"name", s.line_names[i]}, {"in", c.in}, {"out", c.out}});
  }
  return {{"frame", s.frame}, {"time_s", Num(s.time_s)}, {"t_unix", Num(s.t_unix)},
          {"fps", Num(s.stats.frames_per_second)}, {"map_version", s.frame}, {"detections", dets},
          {"tracks", tracks}, {"zones", zones}, {"lines", lines},
          {"events_total", s.events_total}, {"events", EventsJson(s, kFrameEvents)}};
}

json EventsJson(const LiveSnapshot& s, size_t last) {
  json out = json::array();
  const size_t n = s.recent_events.size();
  for (size_t i = n - std::min(n, last); i < n; ++i) {
    json e = json::parse(s.recent_events[i], nullptr, false);
    if (!e.is_discarded()) out.push_back(std::move(e));
  }
  return out;
}

// The MQTT link as /api/state gives it; null without MQTT.
json MqttJson(const LiveSnapshot& s) {
  if (!s.mqtt) return nullptr;
  const MqttCounters& m = *s.mqtt;
  return {{"broker", m.broker},           {"connected", m.connected},     {"error", m.error.empty() ? json(nullptr) : json(m.error)},
          {"published", m.published},     {"dropped", m.dropped},         {"connects", m.connects},
          {"disconnects", m.disconnects}, {"failures", m.failures},       {"cleared", m.cleared}};
}

json StateJson(const LiveSnapshot& s, bool running, double uptime_s, bool starting, std::string_view ended) {
  json cams = json::array();
  for (const CameraStats& c : s.stats.cameras) {
    const double fps = CameraFps(s.stats, c);
    cams.push_back({{"id", c.id}, {"active", c.active}, {"connected", c.connected}, {"fps", Num(fps)},
                    {"frames", c.frames}, {"dropped", c.dropped}, {"reconnects", c.reconnects},
                    {"background_age_s", Num(c.background_age_s)}});
    if (c.background_cache) {  // a live camera whose cached background is refreshed
      const BackgroundCacheFigures& f = *c.background_cache;
      cams.back()["background_cache"] = {
          {"refreshes", f.refreshes},
          {"failures", f.failures},
          {"last_refresh_frame", f.last_refresh_frame ? json(*f.last_refresh_frame) : json(nullptr)},
          {"last_error", f.last_error.empty() ? json(nullptr) : json(f.last_error)}};
    }
  }
  const LatencyFigures& l = s.stats.latency;
  return {{"frame", s.frame},
          {"fps", Num(s.stats.frames_per_second)},
          {"running", running},
          {"starting", starting},
          {"uptime_s", uptime_s},
          {"frames", s.stats.frames},
          {"elapsed_s", Num(s.stats.elapsed_s)},
          {"latency_ms", {{"p50", Num(l.p50_ms)}, {"p95", Num(l.p95_ms)}, {"p99", Num(l.p99_ms)}, {"max", Num(l.max_ms)}}},
          {"cameras", cams},
          {"tracks_total", s.stats.tracks},
          {"zone_events", s.stats.zone_events},
          {"stop_reason", !running && !starting && !ended.empty() ? std::string(ended) : s.stats.stop_reason},
          {"stages_s", StagesJson(s.stats.stages)},
          {"mqtt", MqttJson(s)}};
}

std::vector<std::vector<std::vector<std::array<double, 2>>>> MaskPolygonsFromText(const Site& site,
                                                                                   std::string_view text) {
  std::vector<std::vector<std::vector<std::array<double, 2>>>> out(site.cameras.size());
  YAML::Node root;
  try {
    root = YAML::Load(std::string(text));
  } catch (const YAML::Exception&) {
    return out;
  }
  if (!root.IsMap() || !root["cameras"] || !root["cameras"].IsSequence()) return out;
  auto polygon = [](const YAML::Node& p) {
    std::vector<std::array<double, 2>> pts;
    if (!p.IsSequence()) return pts;
    for (const YAML::Node& v : p) {
      if (v.IsSequence() && v.size() == 2) pts.push_back({v[0].as<double>(0), v[1].as<double>(0)});
    }
    return pts;
  };
  try {
    for (const YAML::Node& cam : root["cameras"]) {
      if (!cam.IsMap() || !cam["id"] || !cam["mask"] || !cam["mask"].IsMap()) continue;
      const std::string id = cam["id"].as<std::string>();
      for (size_t n = 0; n < site.cameras.size(); ++n) {
        if (site.cameras[n].id != id) continue;
        const YAML::Node mask = cam["mask"];
        if (mask["polygon"]) out[n].push_back(polygon(mask["polygon"]));
        if (mask["polygons"] && mask["polygons"].IsSequence()) {
          for (const YAML::Node& p : mask["polygons"]) out[n].push_back(polygon(p));
        }
      }
    }
  } catch (const YAML::Exception&) {
  }
  return out;
}

// Per camera, the mask picture's file as the site names it ("" when none or polygons).
std::vector<std::string> MaskFilesFromText(const Site& site, std::string_view text) {
  std::vector<std::string> out(site.cameras.size());
  try {
    const YAML::Node root = YAML::Load(std::string(text));
    if (!root.IsMap() || !root["cameras"] || !root["cameras"].IsSequence()) return out;
    for (const YAML::Node& cam : root["cameras"]) {
      if (!cam.IsMap() || !cam["id"] || !cam["mask"] || !cam["mask"].IsScalar()) continue;
      const std::string id = cam["id"].as<std::string>();
      for (size_t n = 0; n < site.cameras.size(); ++n) {
        if (site.cameras[n].id == id) out[n] = cam["mask"].as<std::string>();
      }
    }
  } catch (const YAML::Exception&) {
  }
  return out;
}

json SiteJson(const Site& site, std::string_view text) {
  const FloorGrid& g = site.grid;
  const auto polygons = MaskPolygonsFromText(site, text);
  const auto mask_files = MaskFilesFromText(site, text);
  json cams = json::array();
  for (size_t n = 0; n < site.cameras.size(); ++n) {
    const SiteCamera& c = site.cameras[n];
    const ImageSize size = c.camera->image_size();
    cams.push_back({{"id", c.id}, {"width_px", size.width}, {"height_px", size.height},
                    {"has_calibration", c.camera != nullptr}, {"calibration_format", c.calibration_format},
                    {"has_mask", !c.mask.empty()}, {"mask_polygons_px", polygons[n]},
                    {"mask_file", mask_files[n].empty() ? json(nullptr) : json(mask_files[n])}});
  }
  json zones = json::array();
  for (const ZoneOptions& z : site.tracking.zones) {
    json poly = json::array();
    for (const auto& p : z.polygon_m) poly.push_back({p.x(), p.y()});
    json j = {{"name", z.name}, {"polygon_m", poly}};
    if (z.dwell_s) j["dwell_s"] = *z.dwell_s;
    zones.push_back(std::move(j));
  }
  json lines = json::array();
  for (const LineOptions& l : site.tracking.lines) {
    lines.push_back({{"name", l.name}, {"a_m", {l.from_m.x(), l.from_m.y()}}, {"b_m", {l.to_m.x(), l.to_m.y()}},
                     {"hysteresis_m", l.hysteresis_m}, {"once_per_track", l.once_per_track}});
  }
  return {{"name", site.name},
          {"path", site.file.string()},
          {"grid", {{"x_min_m", g.origin_x_m}, {"y_min_m", g.origin_y_m}, {"cell_size_m", g.cell_size_m},
                    {"cols", g.cells_x}, {"rows", g.cells_y}}},
          {"cameras", cams},
          {"zones", zones},
          {"lines", lines},
          {"yaml", std::string(text)}};
}

std::string ProcessMetricsText() {
  std::string o;
  auto head = [&](const char* name, const char* type, const char* help) {
    o += fmt::format("# HELP {} {}\n# TYPE {} {}\n", name, help, name, type);
  };
  // /proc/self/stat: fields after the command's closing parenthesis; utime and stime (14, 15)
  // in clock ticks, starttime (22) in ticks since boot, vsize (23) in bytes, rss (24) in pages.
  std::ifstream stat_file("/proc/self/stat");
  std::string stat((std::istreambuf_iterator<char>(stat_file)), std::istreambuf_iterator<char>());
  const size_t paren = stat.rfind(')');
  if (paren == std::string::npos) return o;
  std::istringstream fields(stat.substr(paren + 2));
  std::vector<std::string> f;
  for (std::string v; fields >> v;) f.push_back(v);
  if (f.size() < 22) return o;
  auto number = [&](int field) { return std::strtod(f[static_cast<size_t>(field - 3)].c_str(), nullptr); };
  const double ticks = static_cast<double>(::sysconf(_SC_CLK_TCK));
  const double page = static_cast<double>(::sysconf(_SC_PAGESIZE));
  head("process_cpu_seconds_total", "counter", "user and system CPU time of the process");
  o += fmt::format("process_cpu_seconds_total {:g}\n", (number(14) + number(15)) / ticks);
  head("process_resident_memory_bytes", "gauge", "resident memory");
  o += fmt::format("process_resident_memory_bytes {:.0f}\n", number(24) * page);
  head("process_virtual_memory_bytes", "gauge", "virtual memory");
  o += fmt::format("process_virtual_memory_bytes {:.0f}\n", number(23));
  std::ifstream uptime_file("/proc/uptime");
  double uptime_s = 0;
  if (uptime_file >> uptime_s) {
    const double now_s = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    head("process_start_time_seconds", "gauge", "start of the process, seconds since 1970");
    o += fmt::format("process_start_time_seconds {:.0f}\n", now_s - uptime_s + number(22) / ticks);
  }
  std::error_code ec;
  int64_t fds = 0;
  for (auto it = std::filesystem::directory_iterator("/proc/self/fd", ec); !ec && it != std::filesystem::directory_iterator();
       it.increment(ec)) {
    ++fds;
  }
  head("process_open_fds", "gauge", "open file descriptors");
  o += fmt::format("process_open_fds {}\n", fds);
  if (rlimit limit{}; ::getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    head("process_max_fds", "gauge", "the limit of open file descriptors");
    o += fmt::format("process_max_fds {}\n", static_cast<uint64_t>(limit.rlim_cur));
  }
  return o;
}

std::string MetricsText(const LiveSnapshot& s, bool running) {
  std::string o;
  auto head = [&](const char* name, const char* type, const char* help) {
    o += fmt::format("# HELP {} {}\n# TYPE {} {}\n", name, help, name, type);
  };
#ifndef OCCMAP_VERSION
#define OCCMAP_VERSION "unknown"
#endif
  head("occmap_build_info", "gauge", "the program's version, as a label (always 1)");
  o += fmt::format("occmap_build_info{{version=\"{}\"}} 1\n", OCCMAP_VERSION);
  head("occmap_up", "gauge", "1 while the pipeline runs");
  o += fmt::format("occmap_up {}\n", running ? 1 : 0);
  head("occmap_frames_total", "counter", "frame sets processed");
  o += fmt::format("occmap_frames_total {}\n", s.stats.frames);
  head("occmap_frames_per_second", "gauge", "steady-state frame sets per second");
  o += fmt::format("occmap_frames_per_second {:g}\n", s.stats.frames_per_second);
  head("occmap_camera_frames_per_second", "gauge", "frames used per second, per camera");
  for (const CameraStats& c : s.stats.cameras) {
    const double fps = CameraFps(s.stats, c);
    o += fmt::format("occmap_camera_frames_per_second{{camera=\"{}\"}} {:g}\n", Label(c.id), fps);
  }
  head("occmap_camera_up", "gauge", "1 while the camera's frames arrive");
  for (const CameraStats& c : s.stats.cameras) {
    o += fmt::format("occmap_camera_up{{camera=\"{}\"}} {}\n", Label(c.id), running && c.active && c.connected ? 1 : 0);
  }
  head("occmap_frames_dropped_total", "counter", "frames a live stream dropped to stay on the newest");
  for (const CameraStats& c : s.stats.cameras) {
    o += fmt::format("occmap_frames_dropped_total{{camera=\"{}\"}} {}\n", Label(c.id), c.dropped);
  }
  head("occmap_camera_reconnects_total", "counter", "times a live stream was opened again");
  for (const CameraStats& c : s.stats.cameras) {
    o += fmt::format("occmap_camera_reconnects_total{{camera=\"{}\"}} {}\n", Label(c.id), c.reconnects);
  }
  head("occmap_latency_seconds", "summary", "frame set arrival to outputs written");
  const LatencyFigures& l = s.stats.latency;
  o += fmt::format("occmap_latency_seconds{{quantile=\"0.5\"}} {:g}\n", l.p50_ms / 1000);
  o += fmt::format("occmap_latency_seconds{{quantile=\"0.95\"}} {:g}\n", l.p95_ms / 1000);
  o += fmt::format("occmap_latency_seconds{{quantile=\"0.99\"}} {:g}\n", l.p99_ms / 1000);
  o += fmt::format("occmap_latency_seconds_sum {:g}\n", l.sum_ms / 1000);
  o += fmt::format("occmap_latency_seconds_count {}\n", l.count);
  head("occmap_camera_background_age_seconds", "gauge", "mean age of the camera's background pixels");
  for (const CameraStats& c : s.stats.cameras) {
    if (std::isfinite(c.background_age_s)) {
      o += fmt::format("occmap_camera_background_age_seconds{{camera=\"{}\"}} {:g}\n", Label(c.id), c.background_age_s);
    }
  }
  head("occmap_background_cache_refreshes_total", "counter", "a live camera's cached background written from its model");
  for (const CameraStats& c : s.stats.cameras) {
    if (c.background_cache) {
      o += fmt::format("occmap_background_cache_refreshes_total{{camera=\"{}\"}} {}\n", Label(c.id), c.background_cache->refreshes);
    }
  }
  head("occmap_background_cache_failures_total", "counter", "writes of a live camera's cached background that failed");
  for (const CameraStats& c : s.stats.cameras) {
    if (c.background_cache) {
      o += fmt::format("occmap_background_cache_failures_total{{camera=\"{}\"}} {}\n", Label(c.id), c.background_cache->failures);
    }
  }
  head("occmap_stage_seconds_total", "counter", "time spent inside each stage of the run");
  for (const auto& [name, seconds] : Stages(s.stats.stages)) {
    o += fmt::format("occmap_stage_seconds_total{{stage=\"{}\"}} {:g}\n", name, seconds);
  }
  head("occmap_tracks", "gauge", "tracks reported in the latest frame set");
  o += fmt::format("occmap_tracks {}\n", s.tracks.size());
  head("occmap_zone_objects", "gauge", "tracks inside each zone");
  for (size_t i = 0; i < s.zone_names.size(); ++i) {
    o += fmt::format("occmap_zone_objects{{zone=\"{}\"}} {}\n", Label(s.zone_names[i]),
                     i < s.zone_counts.size() ? s.zone_counts[i] : 0);
  }
  if (s.mqtt) {
    const MqttCounters& m = *s.mqtt;
    head("occmap_mqtt_connected", "gauge", "1 while the MQTT broker is connected");
    o += fmt::format("occmap_mqtt_connected{{broker=\"{}\"}} {}\n", Label(m.broker), m.connected ? 1 : 0);
    head("occmap_mqtt_messages_published_total", "counter", "MQTT messages handed to the broker's connection");
    o += fmt::format("occmap_mqtt_messages_published_total {}\n", m.published);
    head("occmap_mqtt_messages_dropped_total", "counter", "per-frame MQTT messages dropped: no connection or queue full");
    o += fmt::format("occmap_mqtt_messages_dropped_total {}\n", m.dropped);
    head("occmap_mqtt_connects_total", "counter", "MQTT connections made");
    o += fmt::format("occmap_mqtt_connects_total {}\n", m.connects);
    head("occmap_mqtt_connection_failures_total", "counter", "MQTT connection attempts that failed and connections lost");
    o += fmt::format("occmap_mqtt_connection_failures_total {}\n", m.failures);
  }
  head("occmap_line_crossings_total", "counter", "crossings of each counting line, by direction");
  for (size_t i = 0; i < s.line_names.size(); ++i) {
    const LineCounts c = i < s.line_counts.size() ? s.line_counts[i] : LineCounts{};
    o += fmt::format("occmap_line_crossings_total{{line=\"{}\",direction=\"in\"}} {}\n", Label(s.line_names[i]), c.in);
    o += fmt::format("occmap_line_crossings_total{{line=\"{}\",direction=\"out\"}} {}\n", Label(s.line_names[i]), c.out);
  }
  return o + ProcessMetricsText();
}

std::string MaskOverlayPng(const Image<uint8_t>& mask) {
  if (mask.empty()) return {};
  cv::Mat bgra(mask.height(), mask.width(), CV_8UC4);
  for (int y = 0; y < mask.height(); ++y) {
    const uint8_t* m = mask.row(y);
    uint8_t* row = bgra.ptr<uint8_t>(y);
    for (int x = 0; x < mask.width(); ++x) {
      // Excluded: dark red, 55 % opaque; floor: clear.
      const bool floor = m[x] != 0;
      row[4 * x] = 20;
      row[4 * x + 1] = 20;
      row[4 * x + 2] = 120;
      row[4 * x + 3] = floor ? 0 : 140;
    }
  }
  return Encode(bgra, ".png", {});
}

std::string MapPng(const OccupancyMap& map) {
  const FloorGrid& g = map.grid();
  if (g.num_cells() == 0 || map.states().size() != static_cast<size_t>(g.num_cells())) return {};
  cv::Mat bgr(g.cells_y, g.cells_x, CV_8UC3);
  for (int j = 0; j < g.cells_y; ++j) {
    uint8_t* row = bgr.ptr<uint8_t>(g.cells_y - 1 - j);
    for (int i = 0; i < g.cells_x; ++i) {
      const CellState st = map.state(int64_t{j} * g.cells_x + i);
      const uint8_t v = st == CellState::kFree ? 255 : st == CellState::kOccupied ? 0 : 205;
      row[3 * i] = row[3 * i + 1] = row[3 * i + 2] = v;
    }
  }
  return Encode(bgr, ".png", {});
}

std::string CoveragePng(const LiveCoverage& c) {
  const FloorGrid& g = c.grid;
  if (g.num_cells() == 0 || c.view_count.size() != static_cast<size_t>(g.num_cells())) return {};
  cv::Mat bgr(g.cells_y, g.cells_x, CV_8UC3);
  for (int j = 0; j < g.cells_y; ++j) {
    uint8_t* row = bgr.ptr<uint8_t>(g.cells_y - 1 - j);
    for (int i = 0; i < g.cells_x; ++i) {
      const Rgb8 col = VisibilityColor(c.view_count[static_cast<size_t>(j) * g.cells_x + i], c.num_cameras);
      row[3 * i] = col.b;
      row[3 * i + 1] = col.g;
      row[3 * i + 2] = col.r;
    }
  }
  return Encode(bgr, ".png", {});
}

json CoverageJson(const LiveCoverage& c) {
  std::vector<int64_t> seen_by(static_cast<size_t>(c.num_cameras) + 1, 0);
  for (uint8_t v : c.view_count) ++seen_by[std::min<size_t>(v, seen_by.size() - 1)];
  json colors = json::array();
  for (int k = 0; k <= c.num_cameras; ++k) {
    const Rgb8 col = VisibilityColor(k, c.num_cameras);
    colors.push_back(fmt::format("#{:02x}{:02x}{:02x}", col.r, col.g, col.b));
  }
  return {{"version", c.version}, {"num_cameras", c.num_cameras}, {"cells", c.view_count.size()},
          {"cells_seen_by", seen_by}, {"colors", colors}};
}

Image<Rgb8> CameraRgb(const LiveSnapshot& s, size_t n) {
  if (n < s.frames_rgb.size() && !s.frames_rgb[n].empty()) return s.frames_rgb[n];
  if (n >= s.frames_gray.size() || s.frames_gray[n].empty()) {
    // No frame (a fuse's camera): its changes, light on dark, the overlay's colour added.
    if (n >= s.change_masks.size() || s.change_masks[n].empty()) return {};
    const Image<uint8_t>& m = s.change_masks[n];
    Image<Rgb8> rgb(m.width(), m.height());
    for (int y = 0; y < m.height(); ++y) {
      const uint8_t* src = m.row(y);
      Rgb8* dst = rgb.row(y);
      for (int x = 0; x < m.width(); ++x) dst[x] = src[x] != 0 ? Rgb8{230, 230, 230} : Rgb8{24, 24, 24};
    }
    return rgb;
  }
  const Image<uint8_t>& g = s.frames_gray[n];
  Image<Rgb8> rgb(g.width(), g.height());
  for (int y = 0; y < g.height(); ++y) {
    const uint8_t* src = g.row(y);
    Rgb8* dst = rgb.row(y);
    for (int x = 0; x < g.width(); ++x) dst[x] = {src[x], src[x], src[x]};
  }
  return rgb;
}

std::string EncodeJpeg(const Image<Rgb8>& image, int quality) {
  if (image.empty()) return {};
  return Encode(ToBgr(image), ".jpg", {cv::IMWRITE_JPEG_QUALITY, quality});
}

void DrawTrackBoxes(Image<Rgb8>& rgb, const std::vector<TrackBox>& boxes) {
  static_assert(sizeof(Rgb8) == 3);
  cv::Mat m(rgb.height(), rgb.width(), CV_8UC3, rgb.row(0), static_cast<size_t>(rgb.stride_elems()) * sizeof(Rgb8));
  for (const TrackBox& b : boxes) {
    // The page's colour for the id (api.js colorForId: hue id * 137.508), as RGB: the buffer is RGB.
    cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(std::fmod(static_cast<double>(b.id) * 137.508, 360.0) / 2, 230, 200));
    cv::Mat rgb_colour;
    cv::cvtColor(hsv, rgb_colour, cv::COLOR_HSV2RGB);
    const cv::Vec3b c = rgb_colour.at<cv::Vec3b>(0, 0);
    const cv::Scalar colour(c[0], c[1], c[2]);
    const int thick = std::max(1, rgb.width() / 400);
    cv::rectangle(m, cv::Point(b.x0, b.y0), cv::Point(b.x1, b.y1), colour, thick, b.coasting ? cv::LINE_4 : cv::LINE_8);
    const std::string label = fmt::format("{} {}", b.id, b.object_class);
    const double scale = std::max(0.35, rgb.width() / 1600.0);
    int base = 0;
    const cv::Size ts = cv::getTextSize(label, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &base);
    const int ty = b.y0 - ts.height - 4 >= 0 ? b.y0 - ts.height - 4 : b.y0;
    cv::rectangle(m, cv::Point(b.x0, ty), cv::Point(b.x0 + ts.width + 4, ty + ts.height + 4), colour, cv::FILLED);
    cv::putText(m, label, cv::Point(b.x0 + 2, ty + ts.height + 1), cv::FONT_HERSHEY_SIMPLEX, scale,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
}

std::string CameraJpeg(const LiveSnapshot& s, size_t n, bool change_overlay, int quality) {
  Image<Rgb8> rgb = CameraRgb(s, n);
  if (rgb.empty()) return {};
  if (change_overlay && n < s.change_masks.size()) {
    const Image<uint8_t>& m = s.change_masks[n];
    if (m.width() == rgb.width() && m.height() == rgb.height()) {
      for (int y = 0; y < rgb.height(); ++y) {
        const uint8_t* mr = m.row(y);
        Rgb8* p = rgb.row(y);
        for (int x = 0; x < rgb.width(); ++x) {
          if (mr[x] == 0) continue;
          p[x] = {static_cast<uint8_t>((p[x].r + 255) / 2), static_cast<uint8_t>(p[x].g / 2),
                  static_cast<uint8_t>(p[x].b / 2)};
        }
      }
    }
  }
  // The live view's tiles (overlay=change) show the tracks too.
  if (change_overlay && n < s.track_boxes.size()) DrawTrackBoxes(rgb, s.track_boxes[n]);
  return EncodeJpeg(rgb, quality);
}

}  // namespace occmap
