#include "edge_fuse_command.h"

#include <fmt/core.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <thread>

#include "occmap/bench/edge_sim.h"
#include "occmap/serve/live_state.h"
#include "occmap/serve/view_backend.h"
#include "occmap/serve/web_assets.h"
#include "occmap/serve/web_server.h"
#include "occmap/site/site.h"
#include "occmap/util/file_util.h"
#include "occmap/util/thread_pool.h"
#include "run_support.h"
#include "serve_command.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

void AddCommonOptions(CLI::App& cmd, EdgeFuseCommon& c) {
  cmd.add_option("site", c.site_path, "site file (YAML), the same for every edge and the fuse")->required();
  cmd.add_option("--broker", c.broker, "MQTT broker: mqtt://HOST[:PORT]")->capture_default_str();
  cmd.add_option("--topic-prefix", c.topic_prefix, "topic prefix (default occmap/<site>); messages on <prefix>/edge/<camera>");
  cmd.add_option("--cache-dir", c.cache_dir, "folder of cached tables and backgrounds (default: ~/.cache/occmap)");
  cmd.add_flag("--no-cache", c.no_cache, "never read or write cached tables or backgrounds");
}

Result<Site> Load(const EdgeFuseCommon& c, const std::string& data_root) {
  SiteLoadOptions load;
  if (!data_root.empty()) load.data_root = fs::path(data_root);
  return LoadSite(c.site_path, load);
}

fs::path CacheDir(const EdgeFuseCommon& c) {
  return c.no_cache ? fs::path() : c.cache_dir.empty() ? DefaultCacheDir() : fs::path(c.cache_dir);
}

}  // namespace

CLI::App* AddEdgeCommand(CLI::App& app, EdgeCommand& cmd) {
  CLI::App* c = app.add_subcommand(
      "edge", "read some of the site's cameras and publish their changes per frame on MQTT for `occmap fuse`");
  AddCommonOptions(*c, cmd.common);
  c->add_option("--cameras", cmd.cameras, "camera ids of the site this edge reads, comma-separated (default: all)");
  c->add_option("--frames", cmd.options.run.max_frames, "process at most N frames")
      ->check(CLI::Range(int64_t{1}, int64_t{1'000'000'000'000}));
  c->add_option("--start", cmd.options.run.start_frame, "first frame of every source")
      ->capture_default_str()
      ->check(CLI::Range(int64_t{0}, int64_t{1'000'000'000'000}));
  c->add_option("--background-frames", cmd.options.run.background_frames,
                "K: frames in the median background of a camera without one")
      ->capture_default_str();
  c->add_option("--protection-lag", cmd.options.protection_lag_frames,
                "adaptive backgrounds over files: update frame t with the fuse's protection of frame t - N at the "
                "oldest (waited for)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  c->add_option("--protection-wait-s", cmd.options.protection_wait_s,
                "adaptive backgrounds over files: wait this long for the due protection, then protect changed pixels")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  c->add_option("--protection-stale-s", cmd.options.protection_stale_s,
                "adaptive backgrounds over live streams: apply the latest protection while younger than this")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  c->add_option("--follow-fuse-s", cmd.options.follow_fuse_s,
                "files: start after the last frame set of a fuse already fusing (its progress younger than this; 0: "
                "never, start at --start)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  return c;
}

CLI::App* AddFuseCommand(CLI::App& app, FuseCommand& cmd) {
  CLI::App* c = app.add_subcommand(
      "fuse", "fuse the edges' changes from MQTT: the map, detections, tracks and outputs of `occmap run`");
  AddCommonOptions(*c, cmd.common);
  c->add_option("--out", cmd.options.run.out_dir, "output folder")->capture_default_str();
  c->add_option("--frames", cmd.options.run.max_frames, "fuse at most N frame sets")
      ->check(CLI::Range(int64_t{1}, int64_t{1'000'000'000'000}));
  c->add_option("--sync", cmd.sync,
                "align the cameras' frames by index or timestamp (default: timestamp when every camera is a live "
                "stream, else index)")
      ->check(CLI::IsMember({"index", "timestamp"}));
  c->add_option("--sync-tolerance-s", cmd.options.sync_tolerance_s,
                "--sync timestamp: a camera's frame this close after a frame set's oldest joins it (the edges' "
                "clocks kept in step, e.g. by NTP; default 0.9 frame intervals)")
      ->check(CLI::PositiveNumber);
  c->add_option("--latency-budget-s", cmd.options.latency_budget_s,
                "a frame set waits this long for its cameras; the late ones are left out (their cells unseen)")
      ->capture_default_str();
  c->add_option("--dead-after-s", cmd.options.dead_after_s,
                "a camera silent this long no longer holds frame sets up (until it sends again)")
      ->capture_default_str();
  c->add_option("--start-wait-s", cmd.options.start_wait_s,
                "before the first frame set, wait this long for every camera's first message")
      ->capture_default_str();
  c->add_option("--start", cmd.options.run.start_frame,
                "aligned by frame index: the edges' first frame (their --start); the first frame set waits for it up "
                "to --start-wait-s (later frames replayed before the edges started skip no frame)")
      ->capture_default_str()
      ->check(CLI::Range(int64_t{0}, int64_t{1'000'000'000'000}));
  c->add_flag("--occupancy-pngs", cmd.options.run.occupancy_pngs, "also write occupancy/NNNNNN.png per frame set");
  c->add_flag("--no-video", cmd.no_video, "do not write occupancy.mp4");
  c->add_flag("--no-wall-clock", cmd.no_wall_clock, "leave t_unix (wall-clock time) out of the JSON lines");
  c->add_flag("--atomic-outputs", cmd.atomic_outputs, "write the outputs through temporaries renamed at the end");
  c->add_option("--summary-every-s", cmd.options.run.summary_every_s,
                "rewrite summary.json with the running figures this often (0 = only at the end)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  AddLiveOutputOptions(*c, cmd.live);
  c->add_option("--listen", cmd.listen,
                "HOST:PORT: the live web view of `occmap serve` (map, tracks, counts, figures; no setup), served "
                "until a signal (port 0: any free port, printed)");
  c->add_option("--token", cmd.token, "--listen: every request needs this token (Authorization: Bearer T or ?token=T)");
  c->add_option("--token-file", cmd.token_file, "--listen: file whose first line is the token");
  AddAllowHostOption(*c, cmd.allow_hosts);
  return c;
}

CLI::App* AddEdgeSimCommand(CLI::App& app, EdgeSimCommand& cmd) {
  CLI::App* c = app.add_subcommand(
      "edge-sim", "bench: record the edges' messages of a site, or send them again as the cameras of a larger site");
  AddCommonOptions(*c, cmd.common);
  auto* record = c->add_option("--record", cmd.record_dir,
                               "subscribe and keep every camera's messages in DIR until every camera has ended");
  auto* replay = c->add_option("--replay", cmd.replay_dir,
                               "send DIR's messages again: camera n gets recorded camera n mod R's, at --rate-hz");
  record->excludes(replay);
  c->add_option("--idle-timeout-s", cmd.idle_timeout_s, "--record: give up when nothing arrived for this long")
      ->capture_default_str();
  c->add_option("--first-camera", cmd.first_camera, "--replay: the first camera index this process sends")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  c->add_option("--cameras", cmd.cameras, "--replay: how many cameras this process sends (0: all from the first)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  c->add_option("--rate-hz", cmd.rate_hz, "--replay: frame sets per second")->capture_default_str()->check(CLI::PositiveNumber);
  c->add_option("--start-unix", cmd.start_unix, "--replay: the first tick at or after this Unix time (0: now)")
      ->capture_default_str();
  c->add_option("--seconds", cmd.seconds, "--replay: seconds of ticks")->capture_default_str()->check(CLI::PositiveNumber);
  return c;
}

Status RunEdgeSimCommand(const EdgeSimCommand& cmd, const std::string& data_root) {
  if (cmd.record_dir.empty() == cmd.replay_dir.empty()) return InvalidInput("edge-sim: expected --record DIR or --replay DIR");
  OCCMAP_ASSIGN_OR_RETURN(Site site, Load(cmd.common, data_root));
  OCCMAP_ASSIGN_OR_RETURN(MqttBroker broker, ParseMqttUrl(cmd.common.broker, "--broker"));
  StopOnSignals signals("");
  if (!cmd.record_dir.empty()) {
    bench::EdgeRecordOptions o;
    o.broker = broker;
    o.topic_prefix = cmd.common.topic_prefix;
    o.dir = cmd.record_dir;
    o.idle_timeout_s = cmd.idle_timeout_s;
    o.stop = signals.stop();
    o.on_subscribed = [] { std::fputs("occmap edge-sim: subscribed\n", stderr); };
    OCCMAP_ASSIGN_OR_RETURN(bench::EdgeRecording r, bench::RecordEdgeMessages(site, o));
    int64_t messages = 0, bytes = 0, payload = 0;
    for (const bench::EdgeRecording::Camera& c : r.cameras) {
      std::fputs(fmt::format("camera {} {}x{}: {} messages, {:.1f} bytes per message ({:.1f} payload)\n", c.id, c.width,
                             c.height, c.messages, c.messages > 0 ? static_cast<double>(c.bytes) / static_cast<double>(c.messages) : 0.0,
                             c.messages > 0 ? static_cast<double>(c.payload_bytes) / static_cast<double>(c.messages) : 0.0)
                     .c_str(),
                 stdout);
      messages += c.messages;
      bytes += c.bytes;
      payload += c.payload_bytes;
    }
    std::fputs(fmt::format("all: {} messages, {:.1f} bytes per message ({:.1f} payload); {} refused\n", messages,
                           messages > 0 ? static_cast<double>(bytes) / static_cast<double>(messages) : 0.0,
                           messages > 0 ? static_cast<double>(payload) / static_cast<double>(messages) : 0.0, r.refused)
                   .c_str(),
               stdout);
    return Status::Ok();
  }
  bench::EdgeReplayOptions o;
  o.broker = broker;
  o.topic_prefix = cmd.common.topic_prefix;
  o.dir = cmd.replay_dir;
  o.first_camera = cmd.first_camera;
  o.cameras = cmd.cameras;
  o.rate_hz = cmd.rate_hz;
  o.start_unix = cmd.start_unix;
  o.seconds = cmd.seconds;
  o.stop = signals.stop();
  OCCMAP_ASSIGN_OR_RETURN(bench::EdgeReplaySummary s, bench::ReplayEdgeMessages(site, o));
  std::fputs(fmt::format("{} ticks, {} messages, {:.1f} kB; {} ticks late (up to {:.0f} ms); {} unacknowledged\n",
                         s.ticks, s.messages, static_cast<double>(s.bytes) / 1e3, s.late_ticks, s.max_behind_s * 1e3,
                         s.unacked)
                 .c_str(),
             stdout);
  return Status::Ok();
}

Status RunEdgeCommand(EdgeCommand cmd, int threads, const std::string& data_root) {
  OCCMAP_ASSIGN_OR_RETURN(Site site, Load(cmd.common, data_root));
  OCCMAP_ASSIGN_OR_RETURN(cmd.options.broker, ParseMqttUrl(cmd.common.broker, "--broker"));
  cmd.options.topic_prefix = cmd.common.topic_prefix;
  cmd.options.run.cache_dir = CacheDir(cmd.common);
  for (size_t at = 0; at < cmd.cameras.size();) {
    const size_t comma = std::min(cmd.cameras.find(',', at), cmd.cameras.size());
    if (comma > at) cmd.options.cameras.push_back(cmd.cameras.substr(at, comma - at));
    at = comma + 1;
  }
  StopOnSignals signals(cmd.options.run.out_dir);
  cmd.options.run.stop = signals.stop();
  cmd.options.run.warning = PrintWarnings("occmap edge");
  Context ctx(threads);
  OCCMAP_ASSIGN_OR_RETURN(EdgeSummary s, RunEdge(site, cmd.options, ctx));
  std::fputs(fmt::format("{} frame sets, {} messages, {:.1f} kB ({:.0f} bytes per message) in {:.2f} s: {}; "
                         "{} reconnects, {} lost, {} sent again\n",
                         s.frame_sets, s.messages, static_cast<double>(s.bytes) / 1e3,
                         s.messages > 0 ? static_cast<double>(s.bytes) / static_cast<double>(s.messages) : 0.0,
                         s.seconds, s.stop_reason, s.reconnects, s.lost, s.resent)
                 .c_str(),
             stdout);
  if (site.backgrounds.adaptive) {
    std::fputs(fmt::format("adaptive backgrounds: {} protections from the fuse, {} frame sets updated without one; "
                           "learned backgrounds checked over this edge's cameras: {} pixels, {} swapped{}\n",
                           s.protections, s.unprotected_updates, s.consensus_pixels_checked, s.consensus_pixels_swapped,
                           s.settle_frame_sets > 0 ? fmt::format("; settled over {} frame sets in {:.1f} s",
                                                                 s.settle_frame_sets, s.settle_s)
                                                   : std::string())
                   .c_str(),
               stdout);
  }
  for (const auto& [id, f] : s.background_cache) {
    std::fputs(fmt::format("cached background of {}: {} refreshes{}, {} failed{}\n", id, f.refreshes,
                           f.last_refresh_frame ? fmt::format(" (the last at frame {})", *f.last_refresh_frame) : "",
                           f.failures, f.last_error.empty() ? "" : fmt::format("; failing: {}", f.last_error))
                   .c_str(),
               stdout);
  }
  return Status::Ok();
}

Status RunFuseCommand(FuseCommand cmd, int threads, const std::string& data_root) {
  OCCMAP_ASSIGN_OR_RETURN(Site site, Load(cmd.common, data_root));
  OCCMAP_ASSIGN_OR_RETURN(cmd.options.broker, ParseMqttUrl(cmd.common.broker, "--broker"));
  cmd.options.topic_prefix = cmd.common.topic_prefix;
  RunOptions& o = cmd.options.run;
  o.cache_dir = CacheDir(cmd.common);
  if (cmd.no_video) o.occupancy_video = false;
  if (!cmd.sync.empty()) cmd.options.sync = cmd.sync == "index" ? FrameSync::kIndex : FrameSync::kTimestamp;
  o.output_mode = cmd.atomic_outputs ? OutputMode::kAtomic : OutputMode::kLive;
  o.wall_clock_times = !cmd.no_wall_clock;
  OCCMAP_ASSIGN_OR_RETURN(const LiveSinks live, AddLiveSinks(site, cmd.live, o, "occmap fuse"));
  if (cmd.listen.empty() && (!cmd.token.empty() || !cmd.token_file.empty() || !cmd.allow_hosts.empty())) {
    return InvalidInput("--token, --token-file, --allow-host: need --listen HOST:PORT");
  }
  // Before any thread starts, so that every thread inherits the blocked signals.
  StopOnSignals signals(o.out_dir);
  o.stop = signals.stop();
  o.warning = PrintWarnings("occmap fuse");  // a table cache that cannot be written
  // The web view: serve's pages over the fuse's own state (serve/view_backend.h).
  std::shared_ptr<LiveState> view;
  std::unique_ptr<ViewBackend> backend;
  std::unique_ptr<WebServer> server;
  if (!cmd.listen.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(const WebServerOptions wo, WebServerOptionsFrom(cmd.listen, cmd.token, cmd.token_file, cmd.allow_hosts));
    OCCMAP_ASSIGN_OR_RETURN(std::string site_text, ReadFileToString(site.file));
    view = std::make_shared<LiveState>();
    view->SetStarting();
    if (live.mqtt) view->SetMqtt(live.mqtt);
    o.sink_frames = true;  // each camera's changes, the tiles' pictures
    o.sinks.push_back(std::make_shared<LiveStateSink>(view));
    backend = std::make_unique<ViewBackend>(view, site, std::move(site_text), o.out_dir, "occmap fuse");
    server = std::make_unique<WebServer>(wo, *backend, EmbeddedWebAssets());
    OCCMAP_ASSIGN_OR_RETURN(const int port, server->Bind());
    server->Start();
    SayListening("occmap fuse", wo.listen, port);
  }
  Context ctx(threads);
  Result<RunSummary> fused = RunFuse(site, cmd.options, ctx);
  if (!fused.ok()) {
    if (server) server->Stop();
    return fused.status();
  }
  const RunSummary& s = *fused;
  std::fputs(fmt::format("{} frame sets in {:.2f} s: {}; tracks {}\nwrote {}\n", s.frames, s.seconds, s.stop_reason,
                         s.tracks, (o.out_dir / "summary.json").string())
                 .c_str(),
             stdout);
  PrintLiveSinks(live);
  if (server) {  // as `occmap serve`: the last state stays on view until a signal
    view->SetRunning(false, s.stop_reason);
    view->Wake();
    std::fflush(stdout);
    while (!signals.stop()->load()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    server->Stop();
  }
  return Status::Ok();
}

}  // namespace occmap
