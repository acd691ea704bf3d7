// The pieces of `occmap serve`'s HTTP API that need no socket (serve/server.h uses them; the
// tests check them alone): the listen address and the loopback rule, the token check, the
// request targets refused as path traversal, Server-Sent Events framing, the JSON bodies of
// /events and /api (docs/formats.md, "Web API"), the Prometheus text of /metrics, pictures
// (the map as PNG, a camera's frame with its change overlay as JPEG).
#pragma once

#include <cstdint>
#include <optional>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/serve/live_state.h"
#include "occmap/site/site.h"
#include "occmap/util/status.h"

namespace occmap {

struct ListenAddress {
  std::string host = "127.0.0.1";
  int port = 8080;  // 0: an ephemeral port
};

// "HOST:PORT", "[V6]:PORT", ":PORT" (127.0.0.1) or "HOST" (port 8080); `option` names it in messages.
Result<ListenAddress> ParseListen(std::string_view text, std::string_view option = "--listen");
// 127.0.0.0/8, ::1 and "localhost".
bool IsLoopbackHost(std::string_view host);
// The Host header's name (port and IPv6 brackets removed, lower case, a trailing dot dropped).
std::string HostName(std::string_view host_header);
// DNS rebinding: a page of attacker.example whose name is made to resolve to 127.0.0.1 reaches
// the server as its own origin, and the browser lets it read the answers; the Host header still
// says attacker.example. Allowed: no Host (not a browser), IP addresses, "localhost" and its
// subdomains, the listen host and the names in `allowed` (--allow-host).
bool HostAllowed(std::string_view host_header, const ListenAddress& listen, const std::vector<std::string>& allowed);
// A write (POST, PUT, PATCH, DELETE) another site's page may have sent: the reason it is refused
// (with the HTTP status: 403 from another origin, 415 for a body that is not JSON), or nothing.
// Another origin: Sec-Fetch-Site other than same-origin or none, or an Origin other than the
// Host's (http or https). Only application/json bodies: a page can send text/plain or a form
// to any site without asking, JSON only after a CORS preflight, which this server never grants.
struct Refusal {
  int http_status = 403;
  std::string message;
};
std::optional<Refusal> CrossSiteWriteRefusal(std::string_view method, std::string_view host_header,
                                             std::string_view origin, std::string_view sec_fetch_site,
                                             std::string_view content_type);

// Compares in time independent of where they differ.
bool TokenEquals(std::string_view expected, std::string_view given);
// The token of a request: "Authorization: Bearer T", else the query's token= (already decoded).
std::string RequestToken(std::string_view authorization_header, std::string_view query_token);
// The session cookie the login page sets (POST /api/login): its value the token's bytes in hex
// (a token may hold any character but NUL); HttpOnly (no script reads it), SameSite=Strict (no
// other site's page or link sends it), Path=/.
inline constexpr std::string_view kSessionCookie = "occmap_token";
inline constexpr int kSessionCookieMaxAgeS = 30 * 24 * 3600;
// The Set-Cookie value that keeps `token` for `max_age_s`; with an empty token, one that clears it.
std::string SessionCookie(std::string_view token, int max_age_s = kSessionCookieMaxAgeS);
// Every occmap_token value of a Cookie header, decoded (a browser may send several).
std::vector<std::string> CookieTokens(std::string_view cookie_header);
// How a request shows the token: none given, a wrong one, or the first of Bearer header, the
// session cookie, ?token= that matches.
enum class TokenSource { kNone, kWrong, kBearer, kCookie, kQuery };
TokenSource CheckToken(std::string_view expected, std::string_view authorization_header,
                       std::string_view cookie_header, std::string_view query_token);
std::string_view TokenSourceName(TokenSource s);  // "bearer", "cookie", "query", else ""
// The pages a browser opens (they send a visitor without the token to /login): "/", "/index.html",
// "/system".
bool IsPagePath(std::string_view path);
// What a visitor without the token may ask: the login page, login, logout and the session check.
bool IsOpenPath(std::string_view path);
// The login page: one self-contained HTML page (its style and script inline: the bundle's files
// need the token) whose form posts the token to /api/login and then opens ?next= when it is one
// of IsPagePath's (no open redirect), else "/".
std::string LoginPageHtml();
// A request target (path and query as sent, before decoding) that names anything outside the
// served files: "..", its percent-encodings, a backslash (or %5c), NUL (or %00).
bool IsTraversal(std::string_view raw_target);
// A static file's name from a decoded path: "/" -> "index.html", "/app.js" -> "app.js"; empty
// for names with a '/' after the first or any other unsafe character.
std::string StaticFileName(std::string_view path);
std::string ContentTypeFor(std::string_view file_name);

// A request body as JSON: its nesting is checked before it is parsed (a 200 KB array 100,000
// deep overflowed the stack in dump()), so every value of it can be printed and copied. Errors
// are "body: expected JSON ..." and "body:LINE: nesting deeper than 64 levels; ...".
Result<nlohmann::json> ParseJsonBody(std::string_view body);

// Base64 (RFC 4648, padding optional, whitespace ignored) to bytes; a data URL's
// "data:...;base64," prefix is skipped. `field` names it in messages.
Result<std::string> DecodeBase64(std::string_view text, std::string_view field);

// One Server-Sent Event: "event: NAME\ndata: LINE\n...\n\n" (a data line per line of `data`).
std::string SseEvent(std::string_view event, std::string_view data);

// The frame event's JSON; it carries the last kFrameEvents events and events_total (the page
// asks GET /api/events when it missed more).
nlohmann::json FrameEventJson(const LiveSnapshot& s);
inline constexpr size_t kFrameEvents = 20;
// The snapshot's last `last` events as JSON objects (events.jsonl's lines), oldest first.
nlohmann::json EventsJson(const LiveSnapshot& s, size_t last);
// `running`, `uptime_s`, `starting`, `ended`: the run's life (LiveState); `ended` (why the run
// stopped: an error's message) is the stop_reason of a run that is not running.
nlohmann::json StateJson(const LiveSnapshot& s, bool running, double uptime_s, bool starting = false,
                         std::string_view ended = {});
// The site as the pages need it; `site_text` is the file's text (its mask polygons are read
// from it: the loaded site keeps only the rasterised masks).
nlohmann::json SiteJson(const Site& site, std::string_view site_text);
// The mask polygons of each camera in the site text, by camera id (empty for image masks).
std::vector<std::vector<std::vector<std::array<double, 2>>>> MaskPolygonsFromText(const Site& site,
                                                                                   std::string_view site_text);
// Ends with ProcessMetricsText(); starts with occmap_build_info{version}.
std::string MetricsText(const LiveSnapshot& s, bool running);
// The process's own figures under Prometheus's standard names (from /proc/self):
// process_cpu_seconds_total, process_resident_memory_bytes, process_virtual_memory_bytes,
// process_start_time_seconds, process_open_fds, process_max_fds.
std::string ProcessMetricsText();

// A camera's mask as an RGBA PNG of its size to lay over its picture: excluded pixels dark red
// and 55 % opaque, floor pixels clear. Empty string for an empty mask.
std::string MaskOverlayPng(const Image<uint8_t>& mask);
// The map as an RGB PNG, one pixel per cell, row 0 = the largest y: free white, occupied
// black, unseen (205, 205, 205). Empty string before the first map.
std::string MapPng(const OccupancyMap& map);
// The cameras' coverage as visibility.png colours it (lut/visibility_image.h), an RGB PNG with
// a pixel per cell, row 0 = the largest y (as MapPng); and its figures with the colour of each
// count for a legend: {"version", "num_cameras", "cells", "cells_seen_by": [cells seen by
// exactly k cameras, k = 0..N], "colors": ["#rrggbb" for k = 0..N]}.
std::string CoveragePng(const LiveCoverage& coverage);
nlohmann::json CoverageJson(const LiveCoverage& coverage);
// Camera n's latest frame as JPEG, changed pixels tinted red and the tracks' boxes drawn with
// their id and class when `change_overlay`; a camera
// with changes and no frame (occmap fuse's) as its changes; empty when it has neither yet.
std::string CameraJpeg(const LiveSnapshot& s, size_t camera, bool change_overlay, int quality = 80);
std::string EncodeJpeg(const Image<Rgb8>& image, int quality = 80);
// The frame in colour (grey expanded when the run reads grey); without a frame, the changes
// (light on dark).
Image<Rgb8> CameraRgb(const LiveSnapshot& s, size_t camera);

}  // namespace occmap
