// Cameras on many hosts (issue 17): `occmap edge` runs the per-camera half of the pipeline next
// to its cameras and publishes each camera's changes per frame (edge_message.h) on an MQTT
// broker; `occmap fuse` subscribes, aligns the cameras' messages into frame sets, and runs the
// rest of the pipeline, the same stages as RunSite (fusion_stage.h from the given changes,
// detect_track_stage.h, sink_stage.h) with run's outputs. On the same inputs the outputs equal
// `occmap run`'s (a test with a real broker).
//
// Topics: <prefix>/edge/<camera id> (and <prefix>/protection, <prefix>/fuse/progress), prefix
// occmap/<site slug> by default.
// Alignment (edge_align.h): by frame index over files (edges of one site file start at the same
// frame), by timestamp within a tolerance over live streams (each edge stamps a live frame with
// its arrival on the edge's wall clock, which NTP keeps in step across hosts). A frame set is
// fused when every camera whose source has not ended has reported it, or when latency_budget_s
// has passed since its first message: the cameras missing then are left out (their cells
// unseen) and their late messages are dropped (counted per camera in summary.json). A camera
// silent for dead_after_s no longer holds frame sets up until it sends again (a restarted edge
// rejoins without a restart of the fuse). Over files, where edges run as fast as they decode, a
// budget longer than the slowest edge's lag keeps every frame set whole (the outputs then equal
// `occmap run`'s); over live streams the budget bounds the latency. When every camera has
// reported the end of its source, the fuse finishes. Aligning by frame index, the fuse keeps its
// last frame set fused as a retained message (<prefix>/fuse/progress, refreshed every second,
// cleared when it ends): an edge over files that starts after the fuse began (a restart) begins
// at the frame after it rather than sending frames the fuse would drop as late. A broker restart
// (without persistence it loses what it held and what comes before the fuse subscribes again):
// the fuse judges no set while its link is down and, back, waits for every camera again
// (FrameSetAligner::Resume); an edge over files sends again, once the fuse's progress comes on
// the new connection, its messages past that progress.
//
// Adaptive backgrounds (site backgrounds.adaptive): each edge learns and keeps its cameras'
// backgrounds; their update needs the fused map, so the fuse publishes per frame set the
// protected boxes it computed (protection_message.h, on <prefix>/protection) and each edge draws
// the latest it has into its cameras before it updates them. Over files an edge waits for the
// protection of frame t - protection_lag_frames before it updates with frame t (run uses frame
// t's own); over live streams it never waits and applies the latest while it is younger than
// protection_stale_s. Without one (before the first, or the fuse away) the changed pixels are
// protected as persons: nothing that changed is absorbed. The checks through the floor
// (ResolveLearnedBackgrounds, the shadows' floor check and teachers) run at each edge over its
// own cameras: fewer cameras check less.
//
//   OCCMAP_ASSIGN_OR_RETURN(EdgeSummary e, RunEdge(site, edge_options, ctx));
//   OCCMAP_ASSIGN_OR_RETURN(RunSummary s, RunFuse(site, fuse_options, ctx, progress));
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "occmap/pipeline/run.h"
#include "occmap/publish/mqtt_options.h"

namespace occmap {

struct EdgeOptions {
  RunOptions run;                    // sources: start_frame, max_frames, sync, cache_dir, stop
  std::vector<std::string> cameras;  // camera ids of the site this edge reads (empty: all)
  MqttBroker broker;
  std::string topic_prefix;          // empty: occmap/<site slug>
  std::string client_id;             // empty: occmap-edge-<site slug>-<first camera>
  // Adaptive backgrounds: frame t is updated with the fuse's protection of frame t - lag at the
  // oldest; over files the edge waits up to protection_wait_s for it, or until the broker is
  // back from an outage that may have lost it (then goes on with changed pixels protected,
  // without waiting again until one arrives); over live streams the latest
  // protection is applied while younger than protection_stale_s.
  int protection_lag_frames = 1;
  double protection_wait_s = 30;
  double protection_stale_s = 2;
  // Over files: an edge that starts (or restarts) while a fuse is fusing begins at the frame
  // after the fuse's last frame set (its progress, younger than this on the wall clock) instead
  // of start_frame, so that it sends nothing the fuse would drop as late. 0: never.
  double follow_fuse_s = 10;
};

struct EdgeSummary {
  int64_t frame_sets = 0;
  int64_t messages = 0;
  int64_t bytes = 0;       // message bytes published (headers included)
  int64_t reconnects = 0;  // connections to the broker after the first
  // Over files: messages sent again after a reconnection, past the fuse's progress (what a
  // broker restarted without persistence may have lost).
  int64_t resent = 0;
  // Frame sets not sent: read while the broker was away (live streams do not wait for it; files
  // do and lose nothing), and messages the broker had not acknowledged when the edge stopped.
  int64_t lost = 0;
  double seconds = 0;
  // From the start to the first frame: the sources opened, the backgrounds given, reused from
  // the cache or learned (a live camera's: learn_s of its stream, every camera at once).
  double startup_s = 0;
  std::string stop_reason;
  // Adaptive backgrounds: the fuse's protections received, the frame sets updated without one
  // (changed pixels protected), and the learned backgrounds' check over this edge's cameras.
  int64_t protections = 0;
  int64_t unprotected_updates = 0;
  int64_t consensus_pixels_checked = 0, consensus_pixels_swapped = 0;
  // Learned backgrounds of files settled over the window (an edge of every camera of the site):
  // the pass's frame sets and seconds; 0 when nothing was settled.
  int64_t settle_frame_sets = 0;
  double settle_s = 0;
  // Per live camera whose cached background is refreshed (backgrounds.refresh_cache_s): its id
  // and what the refreshes did, the stop's included. Failures are told to run.warning once.
  std::vector<std::pair<std::string, BackgroundCacheFigures>> background_cache{};
};

Result<EdgeSummary> RunEdge(const Site& site, const EdgeOptions& options, Context& ctx);

struct FuseOptions {
  RunOptions run;  // outputs (out_dir, videos but the mosaic, summary), tracking, stop
  MqttBroker broker;
  std::string topic_prefix;       // empty: occmap/<site slug>
  std::string client_id;          // empty: occmap-fuse-<prefix slug> (a persistent session)
  // How the cameras' messages form frame sets (edge_align.h); empty: by timestamp when every
  // camera is a live stream (their frame indexes are each edge's own count), else by index.
  std::optional<FrameSync> sync;
  // By timestamp: a frame this close after the set's oldest joins it. 0: 0.9 / fps of the first
  // message that states its source's frame rate (live cameras are not in phase), else 0.09 s.
  double sync_tolerance_s = 0;
  double latency_budget_s = 1.0;  // the longest a frame set waits for its cameras
  double dead_after_s = 3.0;      // a camera silent this long no longer holds frame sets up
  // Before the first frame set, every camera is waited for this long (edges starting up open
  // their sources and estimate backgrounds); then the budget and the dead rule apply.
  double start_wait_s = 30.0;
};

Result<RunSummary> RunFuse(const Site& site, const FuseOptions& options, Context& ctx,
                           const ProgressCallback& progress = {});

// <prefix>/edge/<camera id>
std::string EdgeTopic(const std::string& prefix, const std::string& camera_id);
// <prefix>/protection: the fuse's protections for the edges' adaptive backgrounds
std::string ProtectionTopic(const std::string& prefix);
// <prefix>/fuse/progress: the fuse's last frame set fused (frame index alignment), retained,
// read by an edge over files when it starts (docs/formats.md).
std::string ProgressTopic(const std::string& prefix);

}  // namespace occmap
