#include "occmap/pipeline/run.h"

#include <fmt/core.h>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>
#include <nlohmann/json.hpp>
#include <set>

#include "occmap/detect/background.h"
#include "occmap/detect/background_model.h"
#include "occmap/detect/change_detection.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/fusion.h"
#include "occmap/fusion/column_fusion.h"
#include "occmap/fusion/view_explainer.h"
#include "occmap/objects/people_detections.h"
#include "occmap/lut/column_lut.h"
#include "occmap/io/frame_source.h"
#include "occmap/io/video_writer.h"
#include "occmap/pipeline/background_maintenance.h"
#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/frame_reader.h"
#include "occmap/pipeline/frame_set.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/latency.h"
#include "occmap/pipeline/output_files.h"
#include "occmap/objects/object_detector.h"
#include "occmap/pipeline/mosaic.h"
#include "occmap/pipeline/stage_queue.h"
#include "occmap/site/site_lut.h"
#include "occmap/track/multi_target_tracker.h"
#include "occmap/track/track_output.h"
#include "occmap/track/window_tracker.h"
#include "occmap/track/count_lines.h"
#include "occmap/track/zones.h"
#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"
#include "occmap/util/hash.h"
#include "occmap/util/image_io.h"

namespace occmap {
namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// A figure written by one stage's thread and read by the writer's for the running figures
// (RunStats): one writer, so a relaxed load and store add without a lock.
class SharedFigure {
 public:
  explicit SharedFigure(double v = 0) : v_(v) {}
  void Add(double d) { v_.store(v_.load(std::memory_order_relaxed) + d, std::memory_order_relaxed); }
  void Set(double v) { v_.store(v, std::memory_order_relaxed); }
  double get() const { return v_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> v_;
};

// The site's tracker, whichever algorithm it names.
class AnyTracker {
 public:
  static Result<AnyTracker> Create(const TrackerOptions& options) {
    AnyTracker t;
    if (options.algorithm == TrackerAlgorithm::kWindow) {
      OCCMAP_ASSIGN_OR_RETURN(WindowTracker w, WindowTracker::Create(options));
      t.window_ = std::make_unique<WindowTracker>(std::move(w));
    } else {
      OCCMAP_ASSIGN_OR_RETURN(MultiTargetTracker m, MultiTargetTracker::Create(options));
      t.multi_ = std::make_unique<MultiTargetTracker>(std::move(m));
    }
    return t;
  }
  // The multi-target tracker measures the detections; the paper's window tracker reads the
  // groups' cells in the grown map.
  Result<std::vector<Track>> Update(const DetectedObjects& objects, double time_s) {
    if (!window_) return multi_->Update(objects, time_s);
    groups_.clear();
    for (const DetectionGroup& g : objects.groups) groups_.push_back(g.group);
    return window_->Update(groups_, objects.grown, time_s);
  }

 private:
  std::unique_ptr<WindowTracker> window_;
  std::unique_ptr<MultiTargetTracker> multi_;
  std::vector<Blob> groups_;  // the window tracker's input, buffer kept
};

// Frame sets whose outputs may wait for the writer (each up to a mosaic picture, ~3 MB).
constexpr size_t kOutputQueue = 4;
// Frames left out of the steady-state rate: decoders filling their frame threads, first touches.
constexpr int64_t kWarmUpFrames = 10;
// Around a person's position, cells are their feet: they never teach the shadow look.
constexpr double kShadowTeacherPersonRadiusM = 0.35;

// Mosaic pictures handed back by the writer stage to the post stage, which draws the next ones
// over them (MosaicRenderer::Render): a few buffers for a whole run instead of a fresh one of
// several MB per frame set, taken on one thread and freed on another.
class PicturePool {
 public:
  Image<Rgb8> Take() {
    std::lock_guard lock(mutex_);
    if (free_.empty()) return {};
    Image<Rgb8> picture = std::move(free_.back());
    free_.pop_back();
    return picture;
  }
  void Give(Image<Rgb8>&& picture) {
    std::lock_guard lock(mutex_);
    if (!picture.empty() && free_.size() < kOutputQueue + 2) free_.push_back(std::move(picture));
  }

 private:
  std::mutex mutex_;
  std::vector<Image<Rgb8>> free_;
};

LatencyFigures Figures(const LatencyHistogram& h) {
  LatencyFigures f;
  f.count = h.count();
  f.p50_ms = 1e3 * h.Percentile(0.50);
  f.p95_ms = 1e3 * h.Percentile(0.95);
  f.p99_ms = 1e3 * h.Percentile(0.99);
  f.max_ms = 1e3 * h.max_s();
  return f;
}

// summary.json's tracking.lines: per counting line its name and crossings in and out so far.
json LinesJson(const std::vector<LineOptions>& lines, const std::vector<LineCounts>& counts) {
  json out = json::array();
  for (size_t l = 0; l < lines.size(); ++l) {
    const LineCounts c = l < counts.size() ? counts[l] : LineCounts{};
    out.push_back({{"name", lines[l].name}, {"in", c.in}, {"out", c.out}});
  }
  return out;
}

json LatencyJson(const LatencyFigures& f) {
  auto ms = [](double v) { return std::round(v * 1e3) / 1e3; };
  return {{"frame_sets", f.count}, {"p50", ms(f.p50_ms)}, {"p95", ms(f.p95_ms)}, {"p99", ms(f.p99_ms)},
          {"max", ms(f.max_ms)}};
}

}  // namespace

int DecoderThreadsPerCamera(int num_threads, int num_cameras) {
  return std::max(1, num_threads / std::max(1, num_cameras));
}

Status RunOptions::Validate() const {
  if (out_dir.empty()) return InvalidInput("--out: expected a folder");
  if (start_frame < 0) return InvalidInput(fmt::format("--start: expected >= 0, found {}", start_frame));
  if (max_frames < -1 || max_frames == 0) return InvalidInput(fmt::format("--frames: expected >= 1, found {}", max_frames));
  if (background_frames < 1 || background_frames > 255) {
    return InvalidInput(fmt::format("--background-frames: expected 1..255, found {}", background_frames));
  }
  if (background_step < 1) return InvalidInput(fmt::format("background step: expected >= 1, found {}", background_step));
  if (!(sync_tolerance_s > 0)) return InvalidInput("--sync-tolerance-s: expected > 0");
  if (!(camera_lost_after_s > 0)) {
    return InvalidInput(fmt::format("--camera-lost-after-s: expected > 0, found {}", camera_lost_after_s));
  }
  if (!(live_sync_window_s > 0 && live_sync_window_s <= 10)) {
    return InvalidInput(fmt::format("live sync window: expected 0 < s <= 10, found {}", live_sync_window_s));
  }
  return Status::Ok();
}

namespace {

// RunOptions::sink_frames: each active camera's frame and its changes (after the tolerance),
// copied into the record (the slot is reused once the post stage is done with it).
void CopyFramesForSinks(const FrameSet& set, const GroundLut& lut, FrameRecord& record) {
  const size_t n_cams = set.frames.size();
  record.frames_gray.resize(n_cams);
  record.frames_rgb.resize(n_cams);
  record.change_masks.resize(n_cams);
  for (size_t n = 0; n < n_cams; ++n) {
    if (!set.active[n]) continue;
    const Frame& f = set.frames[n];
    record.frames_gray[n] = f.gray;
    record.frames_rgb[n] = f.rgb;
    if (!set.changes_ready) continue;
    const int w = f.gray.width(), h = f.gray.height();
    Image<uint8_t>& mask = record.change_masks[n];
    mask = Image<uint8_t>(w, h);
    const uint8_t* src = set.changes.data() + lut.pixel_offset(static_cast<int>(n));
    for (int y = 0; y < h; ++y) std::memcpy(mask.row(y), src + static_cast<ptrdiff_t>(y) * w, static_cast<size_t>(w));
  }
}

}  // namespace

Result<RunSummary> RunSite(const Site& site, const RunOptions& options, Context& ctx, const ProgressCallback& progress) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  OCCMAP_RETURN_IF_ERROR(site.detection.Validate());
  OCCMAP_RETURN_IF_ERROR(site.fusion.Validate(static_cast<int>(site.cameras.size())));
  const auto t_start = Clock::now();
  RunSummary summary;
  auto stop_requested = [&] { return options.stop != nullptr && options.stop->load(); };
  OCCMAP_RETURN_IF_ERROR(site.backgrounds.Validate());
  // How changes are computed and fused: one choice (pipeline/fusion_path.h).
  const FusionPlan plan = ChooseFusionPath(site, options.mosaic_video || options.change_pngs || options.sink_frames);
  const bool adaptive = plan.adaptive;
  const bool colour = plan.colour;
  const bool chroma = plan.chroma;

  // Sources and backgrounds.
  OCCMAP_ASSIGN_OR_RETURN(std::vector<CameraState> cams, OpenCameras(site, options, plan, ctx));

  // Tables.
  const auto t_lut = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(CachedLut cached, LoadOrBuildSiteLut(site, options.cache_dir.empty() ? fs::path() : options.cache_dir, ctx));
  summary.lut_cache = ToString(cached.outcome);
  summary.lut_seconds = Since(t_lut);
  const GroundLut& lut = cached.lut;
  // Learned backgrounds: each pixel's two candidates checked against the other cameras' view
  // of its floor cell.
  if (adaptive) {
    std::vector<BackgroundModel*> models;
    bool any_alternative = false;
    for (auto& c : cams) {
      models.push_back(c.model.get());
      any_alternative |= c.info.background.starts_with("learned") || c.info.background.starts_with("reused");
    }
    if (any_alternative) {
      std::vector<const CameraModel*> cameras;
      for (const auto& c : cams) cameras.push_back(c.cam->camera.get());
      const ConsensusResult r = ResolveLearnedBackgrounds(lut, cameras, site.plane_height_m, models, site.detection.threshold);
      summary.consensus_pixels_checked = r.pixels_checked;
      summary.consensus_pixels_swapped = r.pixels_swapped;
      summary.consensus_pixels_settled = r.pixels_settled;
    }
  }
  Fusion fusion(lut);
  // The paper's AND with every camera active takes the fast path (its tables are built only
  // when the site's fusion settings can use them).
  const bool paper_and = plan.paper_and;
  std::optional<FastFusion> fast;
  if (paper_and) fast.emplace(lut);
  const bool fully_fused = plan.path == FusionPath::kFused;
  const bool tolerant_fused = plan.path == FusionPath::kFusedTolerant;
  // People (the site's `people:` section): the column fusion, and the explanation of the views,
  // on the change buffer after the floor AND.
  const PeopleOptions& people = site.people;
  const bool people_detector = plan.people_detector;
  std::optional<ColumnLut> column_lut;
  std::optional<ColumnFusion> column_fusion;
  std::optional<ViewExplainer> explainer;
  std::vector<ChangeRowSums> change_counts(site.cameras.size());
  std::vector<Eigen::Vector2d> people_positions;
  std::vector<ImageView<const uint8_t>> change_views(site.cameras.size());
  if (people_detector) {
    OCCMAP_ASSIGN_OR_RETURN(ColumnLut columns, BuildColumnLut(site.LutInputs(), site.grid, site.plane_height_m,
                                                              people.columns, site.statics, ctx));
    column_lut = std::move(columns);
    column_fusion.emplace(*column_lut);
    if (people.detector == PeopleDetector::kExplain) explainer.emplace(*column_lut);
  }
  std::vector<ImageView<const uint8_t>> frame_views(site.cameras.size()), background_views(site.cameras.size());

  // Outputs: the backgrounds now; per frame set the sinks, the run's files first
  // (pipeline/output_files.h), then the caller's (RunOptions::sinks).
  const fs::path out = options.out_dir;
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out));
  RemoveStaleTemporaries(out, /*recursive=*/true);  // of killed runs (util/file_util.h)
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / "backgrounds"));
  for (const auto& c : cams) {
    if (c.is_mask) continue;
    const fs::path p = out / "backgrounds" / (c.cam->id + ".png");
    if (c.model) {
      OCCMAP_RETURN_IF_ERROR(WriteYuvPng(p, c.model->Current()));
    } else {
      OCCMAP_RETURN_IF_ERROR(colour ? WritePng(p, c.background_rgb.view()) : WritePng(p, c.background_gray.view()));
    }
    summary.outputs.push_back(p.string());
  }
  const double fps = cams[0].source->fps().value_or(10.0);
  MosaicRenderer mosaic(site, options.mosaic_width_px);
  OutputFilesOptions file_options;
  file_options.mode = options.output_mode;
  file_options.track = options.track;
  file_options.events = options.track && (!site.tracking.zones.empty() || !site.tracking.lines.empty());
  file_options.occupancy_video = options.occupancy_video;
  file_options.occupancy_pngs = options.occupancy_pngs;
  file_options.mosaic_video = options.mosaic_video;
  file_options.mosaic_size = mosaic.size();
  file_options.change_pngs = options.change_pngs;
  file_options.wall_clock_times = options.wall_clock_times;
  auto files = std::make_shared<OutputFiles>(file_options);
  std::vector<std::shared_ptr<FrameSink>> sinks = {files};
  for (const auto& sink : options.sinks) {
    if (sink) sinks.push_back(sink);
  }
  SinkStart sink_start;
  sink_start.site = &site;
  sink_start.lut = &lut;
  sink_start.out_dir = out;
  sink_start.fps = fps;
  sink_start.track = options.track;
  sink_start.wall_clock_times = options.wall_clock_times;
  for (const auto& c : cams) sink_start.camera_ids.push_back(c.cam->id);
  // Sinks opened get Close whatever happens next (OutputFiles: kAtomic drops its temporaries).
  size_t sinks_open = 0;
  RunStats stats;
  bool sinks_closed = false;
  auto close_sinks = [&]() -> Status {
    Status first;
    if (sinks_closed) return first;
    sinks_closed = true;
    for (size_t k = 0; k < sinks_open; ++k) {
      Status s = sinks[k]->Close(stats);
      if (first.ok() && !s.ok()) first = std::move(s);
    }
    return first;
  };
  struct SinkGuard {  // a run that returns early still closes what it opened
    std::function<Status()>& close;
    ~SinkGuard() { (void)close(); }
  };
  std::function<Status()> close_sinks_fn = close_sinks;
  SinkGuard sink_guard{close_sinks_fn};
  for (const auto& sink : sinks) {
    OCCMAP_RETURN_IF_ERROR(sink->Open(sink_start));
    ++sinks_open;
  }
  Image<Rgb8> best_mosaic;
  size_t best_blobs = 0;

  std::vector<ObjectDetector::CameraView> views;
  for (const auto& c : cams) views.push_back({c.cam->camera.get(), &c.cam->mask});
  ObjectDetector detector(site.objects, site.plane_height_m, std::move(views));
  DetectedObjects objects;

  // Tracking.
  std::optional<AnyTracker> tracker;
  std::optional<ZoneMonitor> zones;
  std::optional<LineCounter> lines;
  TrailHistory trails(site.tracking.trail_length);
  double last_track_time_s = -std::numeric_limits<double>::infinity();
  if (options.track) {
    OCCMAP_ASSIGN_OR_RETURN(AnyTracker t, AnyTracker::Create(site.tracking));
    tracker = std::move(t);
    OCCMAP_ASSIGN_OR_RETURN(ZoneMonitor z, ZoneMonitor::Create(site.tracking.zones, site.tracking.zone_count_every_frame));
    zones = std::move(z);
    OCCMAP_ASSIGN_OR_RETURN(LineCounter l, LineCounter::Create(site.tracking.lines));
    lines = std::move(l);
  }

  // The parts of summary.json known before the first frame set; the running summary (rewritten
  // every summary_every_s by the writer stage) adds the RunStats, the final one everything.
  json static_summary;
  static_summary["site"] = site.name;
  static_summary["start_frame"] = options.start_frame;
  static_summary["output_mode"] = ToString(options.output_mode);
  if (options.track) {
    static_summary["tracking"] = {{"algorithm", std::string(ToString(site.tracking.algorithm))},
                                  {"tracks", 0},
                                  {"zones", site.tracking.zones.size()},
                                  {"zone_events", 0},
                                  {"lines", LinesJson(site.tracking.lines, {})}};
  }
  if (adaptive) {
    const BackgroundOptions& bo = site.backgrounds;
    static_summary["backgrounds"] = {{"adaptive", true}, {"learning", ToString(bo.learning)}, {"learn_s", bo.learn_s},
                        {"learn_samples", bo.learn_samples}, {"adapt_s", bo.adapt_s}, {"relight_s", bo.relight_s},
                        {"absorb_s", bo.absorb_s}, {"person_height_m", bo.person_height_m},
                        {"chroma", chroma}, {"chroma_threshold", bo.chroma_threshold},
                        {"shadows", {{"enabled", bo.shadows.enabled}, {"min_ratio", bo.shadows.min_ratio},
                                     {"max_ratio", bo.shadows.max_ratio}, {"max_channel_spread", bo.shadows.max_channel_spread},
                                     {"texture_radius_px", bo.shadows.texture_radius_px},
                                     {"floor_check", bo.shadows.floor_check}}},
                        {"consensus", {{"pixels_checked", summary.consensus_pixels_checked},
                                       {"pixels_swapped", summary.consensus_pixels_swapped},
                                       {"pixels_settled", summary.consensus_pixels_settled}}}};
  }
  static_summary["settings"] = {{"threshold", site.detection.threshold},
                   {"colour", site.detection.colour},
                   {"tolerance_px", site.detection.tolerance_px},
                   {"fusion", ToString(site.fusion.method)},
                   {"fusion_path", plan.Describe(site)},
                   {"max_free_views", site.fusion.max_free_views},
                   {"sync", options.sync == FrameSync::kIndex ? "index" : "timestamp"},
                   {"sync_tolerance_s", options.sync_tolerance_s},
                   {"on_camera_failure", options.on_camera_failure == OnCameraFailure::kStop ? "stop" : "continue"},
                   {"blobs", {{"group_radius_m", site.objects.group_radius_m}, {"min_area_m2", site.objects.min_area_m2},
                              {"split", site.objects.split}, {"remove_ghosts", site.objects.remove_ghosts},
                              {"occluder_height_m", site.objects.occluder_height_m}}},
                   {"threads", ctx.num_threads()},
                   {"grid", {{"origin_m", {site.grid.origin_x_m, site.grid.origin_y_m}},
                             {"cells", {site.grid.cells_x, site.grid.cells_y}},
                             {"cell_size_m", site.grid.cell_size_m}}}};
  static_summary["tables"] = {{"cache", summary.lut_cache}, {"seconds", summary.lut_seconds}};
  std::vector<json> static_cameras;
  for (const auto& c : cams) {
    static_cameras.push_back({{"id", c.info.id}, {"source", c.info.source}, {"background", c.info.background}});
  }

  std::optional<int64_t> total;
  for (const auto& c : cams) {
    if (auto fc = c.source->frame_count()) total = total ? std::min(*total, *fc - options.start_frame) : *fc - options.start_frame;
  }
  if (options.max_frames > 0) total = total ? std::min(*total, options.max_frames) : options.max_frames;

  // 1. The reader (pipeline/frame_reader.h): one frame per active camera, by index or by
  // timestamp, on its own thread (decoding overlaps the processing of the previous frames),
  // into a ring of kSlots frame sets: memory stays flat.
  FrameReader frame_reader(cams, options, ctx.num_threads(),
                           RunSourceOptions(plan, ctx.num_threads(), static_cast<int>(cams.size())));

  // The stages, each on its own thread, joined by bounded queues (stage_queue.h): memory stays
  // flat however long the run, and the stages overlap, so a run over video files is limited by
  // decoding rather than by the work of any one stage.
  //   reader (1.)     decodes one frame set into a free slot of the ring        -> filled_slots
  //   this thread     change detection and fusion into the slot's map (2.-3.)   -> post
  //   post            detections, tracking, the pictures that need the frames;
  //                   gives the slot back to the reader                          -> writer
  //   writer          the sinks: the run's files (appends the text outputs, encodes the videos,
  //                   writes PNGs), then the caller's
  // A stage that fails stops the reader; the others drain their queues and the first error is
  // returned after the frames before it are written (kAtomic and a failed write: nothing is
  // committed). The fusion alone uses ctx's pool (ParallelFor); the other stages are
  // single-threaded.
  constexpr int kSlots = 4;  // one per stage that holds a slot (reader, fusion, post) + 1 spare
  std::vector<FrameSet> slots(kSlots);
  for (FrameSet& set : slots) {
    set.frames.resize(cams.size());
    set.active.assign(cams.size(), false);
    set.map = OccupancyMap(site.grid);
  }
  StageQueue<int> free_slots(kSlots), filled_slots(kSlots);
  for (int k = 0; k < kSlots; ++k) free_slots.Push(k);
  std::atomic<bool> stop_reading{false};

  // Writer stage: the sinks, in frame order; the one place the outputs are touched until it is
  // finished. The stats the sinks see are this thread's.
  double write_s = 0;
  // The other stages' seconds and the adaptive backgrounds' ages, for the running figures.
  SharedFigure detect_s, fuse_s, people_s, background_s, blobs_s, track_s, post_output_s;
  std::vector<SharedFigure> background_age_s(cams.size());
  for (auto& a : background_age_s) a.Set(std::numeric_limits<double>::quiet_NaN());
  LatencyHistogram latency;
  // Distinct track ids in constant memory: the trackers give ids in increasing order, at
  // confirmation, when a track is reported at once, so an id above every earlier one is new.
  int64_t max_track_id = 0;
  stats.cameras.resize(cams.size());
  for (size_t n = 0; n < cams.size(); ++n) stats.cameras[n].id = cams[n].cam->id;
  int64_t total_blobs = 0;
  size_t max_blobs = 0;
  Clock::time_point t_first_written, t_summary_written;
  PicturePool mosaic_pool;
  StageWorker<FrameRecord> writer(kOutputQueue, [&](FrameRecord& r) -> Status {
    const auto t0 = Clock::now();
    ++stats.frames;
    stats.elapsed_s = Since(t_start);
    for (size_t n = 0; n < cams.size(); ++n) {
      CameraStats& cs = stats.cameras[n];
      cs.frames += r.active[n] ? 1 : 0;
      if (const LiveSource* live = frame_reader.live(n); live != nullptr) {
        cs.connected = live->connected();
        cs.dropped = live->dropped();
        cs.reconnects = live->reconnects();
        cs.active = true;
      } else {
        cs.active = r.active[n];
      }
      cs.background_age_s = cams[n].is_mask ? std::numeric_limits<double>::quiet_NaN()
                            : cams[n].model ? background_age_s[n].get()
                                            : static_cast<double>(r.frame - options.start_frame) / fps;
    }
    stats.stages = {frame_reader.decode_s(), detect_s.get(), fuse_s.get(), blobs_s.get(), track_s.get(),
                    post_output_s.get() + write_s, background_s.get(), people_s.get(), summary.lut_seconds};
    const int64_t max_before = max_track_id;
    for (const Track& t : r.tracks) {
      if (t.id > max_before) ++stats.tracks;
      max_track_id = std::max(max_track_id, t.id);
    }
    stats.zone_events += static_cast<int64_t>(r.zones.events.size());
    if (!r.lines.counts.empty()) stats.lines = r.lines.counts;
    total_blobs += static_cast<int64_t>(r.detections.size());
    max_blobs = std::max(max_blobs, r.detections.size());
    if (stats.frames == 1) t_first_written = t0;
    stats.frames_per_second =
        stats.frames >= 2 ? static_cast<double>(stats.frames - 1) / std::chrono::duration<double>(t0 - t_first_written).count() : 0;
    MakeJsonLines(r, options.wall_clock_times);
    for (const auto& sink : sinks) OCCMAP_RETURN_IF_ERROR(sink->Consume(r, stats));
    mosaic_pool.Give(std::move(r.mosaic));
    latency.Add(std::chrono::duration<double>(Clock::now() - r.arrival).count());
    stats.latency = Figures(latency);
    // The running summary (live outputs only: atomic ones appear at the end, all at once).
    if (options.output_mode == OutputMode::kLive && options.summary_every_s > 0 &&
        (stats.frames == 1 || Since(t_summary_written) >= options.summary_every_s)) {
      json j = static_summary;
      j["running"] = true;
      j["frames"] = stats.frames;
      j["seconds"] = stats.elapsed_s;
      j["frames_per_second"] = stats.frames_per_second;
      j["latency_ms"] = LatencyJson(stats.latency);
      if (options.track) {
        j["tracking"]["tracks"] = stats.tracks;
        j["tracking"]["zone_events"] = stats.zone_events;
        j["tracking"]["lines"] = LinesJson(site.tracking.lines, stats.lines);
      }
      json cj = json::array();
      for (size_t n = 0; n < cams.size(); ++n) {
        json e = static_cameras[n];
        e["active"] = stats.cameras[n].active;
        e["connected"] = stats.cameras[n].connected;
        e["frames"] = stats.cameras[n].frames;
        e["dropped_frames"] = stats.cameras[n].dropped;
        e["reconnects"] = stats.cameras[n].reconnects;
        cj.push_back(std::move(e));
      }
      j["cameras"] = std::move(cj);
      OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(out / "summary.json", j.dump(2) + "\n"));
      t_summary_written = Clock::now();
    }
    write_s += Since(t0);
    return Status::Ok();
  });

  // The change buffer of one camera of a slot, from its frame (or mask).
  // dilate: false leaves the tolerance to the caller (changes in `raw` when it is > 0).
  auto camera_changes = [&](FrameSet& set, size_t n, Image<uint8_t>& raw, std::vector<uint8_t>& scratch, bool dilate) {
    const CameraState& c = cams[n];
    const ImageSize size = c.cam->camera->image_size();
    ImageView<uint8_t> slice(set.changes.data() + lut.pixel_offset(static_cast<int>(n)), size.width, size.height,
                             size.width);
    const int r = site.detection.tolerance_px;
    const Frame& frame = set.frames[n];
    if (r > 0 && r <= 4 && !c.is_mask && !colour && !c.model && !options.change_pngs) {
      // small tolerances on grey: one pass, no raw image
      DetectChangesGrayDilated(frame.gray.view(), c.background_gray.view(), site.detection.threshold, r, slice,
                               scratch);
      return;
    }
    if (r > 0 && (raw.width() != size.width || raw.height() != size.height)) raw = Image<uint8_t>(size.width, size.height);
    ImageView<uint8_t> target = r > 0 ? raw.view() : slice;
    if (c.is_mask) {
      MaskToChanges(frame.gray.view(), target);
    } else if (c.model) {
      c.model->DetectChanges(FrameYuv(frame), site.detection.threshold, target);
    } else if (colour) {
      DetectChangesRgb(frame.rgb.view(), c.background_rgb.view(), site.detection.threshold, target);
    } else {
      DetectChangesGray(frame.gray.view(), c.background_gray.view(), site.detection.threshold, target);
    }
    if (r > 0 && dilate) DilateChanges(raw.view(), r, slice, scratch);
  };
  auto ensure_changes = [&](FrameSet& set) {
    if (set.changes.size() != static_cast<size_t>(lut.total_pixels())) set.changes.assign(lut.total_pixels(), 0);
  };

  // The mosaic picture of a frame set: its frames, their changes (computed here when the frame
  // was fully fused), the map, detections and tracks.
  std::vector<Image<uint8_t>> post_raw(cams.size());
  std::vector<std::vector<uint8_t>> post_scratch(cams.size());
  auto render_mosaic = [&](FrameSet& set, const std::vector<Detection>& blobs, double time_s,
                           const std::vector<Track>& tracks, const std::vector<Trail>& trail_list,
                           Image<Rgb8>& picture) {
    const std::vector<Frame>& frames = set.frames;
    const std::vector<bool>& active = set.active;
    if (!set.changes_ready) {  // fully fused: the changes of this frame, for its picture
      ensure_changes(set);
      for (size_t n = 0; n < cams.size(); ++n) {
        if (active[n]) camera_changes(set, n, post_raw[n], post_scratch[n], true);
      }
      set.changes_ready = true;
    }
    std::vector<MosaicCamera> tiles;
    for (size_t n = 0; n < cams.size(); ++n) {
      const CameraState& c = cams[n];
      const ImageSize size = c.cam->camera->image_size();
      MosaicCamera t;
      t.id = c.cam->id;
      t.active = active[n];
      if (active[n]) {
        const ImageView<const uint8_t> changes(set.changes.data() + lut.pixel_offset(static_cast<int>(n)), size.width,
                                               size.height, size.width);
        t.gray = frames[n].gray.view();
        if (c.is_mask && (frames[n].gray.width() != size.width || frames[n].gray.height() != size.height)) {
          t.gray = changes;
        }
        t.changes = changes;
        if (t.gray.width() != t.changes.width()) t.changes = {};
      }
      tiles.push_back(t);
    }
    mosaic.Render(tiles, set.map, blobs, set.frame_index, time_s, tracks, trail_list, picture);
  };
  // Without mosaic video: the frame set with the most detections so far and what its picture
  // shows, drawn at the end.
  struct KeptFrame {
    FrameSet set;
    std::vector<Detection> detections;
    std::vector<Track> tracks;
    std::vector<Trail> trails;
    double time_s = 0;
    bool kept = false;
  } best_frame;

  // Post stage: detections, tracking and the frame's outputs, in frame order.
  std::vector<size_t> camera_width;  // read per pixel by the elevated check: no virtual call there
  for (const auto& c : cams) camera_width.push_back(static_cast<size_t>(c.cam->camera->image_size().width));
  int64_t frames_done = 0;
  Clock::time_point t_first_done, t_warm_done, t_last_done;
  std::vector<ObjectDetector::ChangeBuffer> post_changes;  // the elevated check's fast path
  StageWorker<int> post(
      kSlots,
      [&](int& slot) -> Status {
        FrameSet& set = slots[slot];
        struct GiveBack {  // the slot goes back to the reader however this returns
          StageQueue<int>& queue;
          int slot;
          ~GiveBack() { queue.Push(slot); }
        } give_back{free_slots, slot};
        const std::vector<Frame>& frames = set.frames;
        const std::vector<bool>& active = set.active;
        const OccupancyMap& map = set.map;
        auto t0 = Clock::now();
        // Detections (ObjectDetector: fragments grouped, described by their footprint, small
        // ones dropped, large ones split at their necks, flat ones and ghosts removed). The
        // tracker gets the kept groups with their splits, which it refines by its predictions.
        // The elevated check reads single pixels' changes: from the change buffer when this
        // frame has one, from the fusion's bits (fused with a tolerance), else (fully fused:
        // grey, no tolerance, no masks) from frame and background.
        const ObjectDetector::ChangeLookup changed = [&](int n, int x, int y) {
          const CameraState& c = cams[static_cast<size_t>(n)];
          if (set.bits_ready) return set.change_bits.Changed(n, x, y);
          if (set.changes_ready) {
            const size_t width = camera_width[static_cast<size_t>(n)];
            return set.changes[lut.pixel_offset(n) + static_cast<size_t>(y) * width + static_cast<size_t>(x)] != 0;
          }
          const int d = static_cast<int>(frames[static_cast<size_t>(n)].gray.view()(x, y)) -
                        static_cast<int>(c.background_gray.view()(x, y));
          return std::abs(d) > site.detection.threshold;
        };
        post_changes.clear();
        for (size_t n = 0; n < cams.size() && (set.changes_ready || set.bits_ready); ++n) {
          ObjectDetector::ChangeBuffer b;
          if (set.bits_ready) {
            b.unchanged_bits = set.change_bits.words.data() + set.change_bits.camera_word[n];
            b.row_words = set.change_bits.row_words[n];
          } else {
            b.pixels = set.changes.data() + lut.pixel_offset(static_cast<int>(n));
            b.stride = camera_width[n];
          }
          post_changes.push_back(b);
        }
        // With a people detector the floor's objects are not needed (the paper's window tracker
        // still reads the floor's groups).
        if (!people_detector || site.tracking.algorithm == TrackerAlgorithm::kWindow) {
          detector.Detect(map, active, changed, objects, post_changes);
        }
        // People (the site's `people:` section): the explained people, or the column map's blobs.
        if (explainer) {
          PeopleDetections(set.people, column_lut->candidates(), site.tracking.person_radius_m(), objects);
        } else if (column_fusion) {
          ColumnMapDetections(set.column_map, objects);
        }
        const std::vector<Detection>& blobs = objects.detections;
        blobs_s.Add(Since(t0));
        const int64_t frame_index = set.frame_index;
        const double time_s = std::isnan(set.timestamp_s) ? static_cast<double>(frame_index) / fps : set.timestamp_s;
        FrameRecord record;
        record.frame = frame_index;
        record.time_s = time_s;
        record.t_unix = set.t_unix;
        record.arrival = set.arrival;
        record.active = set.active;

        // 3b. Tracking (the tracker needs strictly increasing times: a repeated timestamp, as
        // some streams give, is nudged forward by a microsecond).
        t0 = Clock::now();
        std::vector<Track>& tracks = record.tracks;
        if (tracker) {
          const double track_time_s = std::max(time_s, last_track_time_s + 1e-6);
          last_track_time_s = track_time_s;
          OCCMAP_ASSIGN_OR_RETURN(tracks, tracker->Update(objects, track_time_s));
          // Zones count every live track; the outputs get the reported ones.
          record.zones = zones->Update(frame_index, time_s, tracks);
          record.lines = lines->Update(frame_index, time_s, tracks);
          std::erase_if(tracks, [&](const Track& t) { return !IsReported(t, site.tracking.report_coasting_s); });
          trails.Update(tracks);
        }
        track_s.Add(Since(t0));

        // 4. Outputs: what the sinks (the writer stage) get for this frame set.
        t0 = Clock::now();
        record.map = map;
        record.detections = blobs;
        if (options.change_pngs) {
          record.change_pictures.resize(cams.size());
          for (size_t n = 0; n < cams.size(); ++n) {
            if (active[n]) record.change_pictures[n] = set.change_pictures[n];
          }
        }
        if (options.sink_frames) CopyFramesForSinks(set, lut, record);
        const bool first = options.mosaic_video ? best_mosaic.empty() : !best_frame.kept;
        const bool best = first || blobs.size() > best_blobs;
        if (options.mosaic_video) {
          Image<Rgb8> picture = mosaic_pool.Take();
          render_mosaic(set, blobs, time_s, tracks, trails.Trails(), picture);
          if (best) {
            best_mosaic = picture;
            best_blobs = blobs.size();
          }
          record.mosaic = std::move(picture);
        } else if (best) {
          // mosaic.png only: the frame set is kept and drawn once at the end (a 7 x 1080p
          // picture with its changes costs more than the copy, and the best frame changes
          // often early in a run).
          FrameSet& kept = best_frame.set;
          kept.frames = set.frames;
          kept.active = set.active;
          kept.map = set.map;
          kept.frame_index = set.frame_index;
          kept.changes_ready = set.changes_ready;
          if (set.changes_ready) kept.changes = set.changes;
          best_frame.detections = blobs;
          best_frame.tracks = tracks;
          best_frame.trails = trails.Trails();
          best_frame.time_s = time_s;
          best_frame.kept = true;
          best_blobs = blobs.size();
        }
        post_output_s.Add(Since(t0));
        if (!writer.Push(std::move(record))) return Internal("the writer stage stopped");
        ++frames_done;
        summary.frames = frames_done;
        const auto now = Clock::now();
        if (frames_done == 1) t_first_done = now;
        if (frames_done == kWarmUpFrames + 1) t_warm_done = now;
        t_last_done = now;
        if (progress) progress({frames_done, total, Since(t_start)});
        return Status::Ok();
      },
      [&](int& slot) { free_slots.Push(slot); });

  std::thread reader([&] {
    while (std::optional<int> slot = free_slots.Pop()) {
      if (stop_reading.load() || stop_requested() || !frame_reader.Read(slots[*slot])) break;
      filled_slots.Push(*slot);
    }
    filled_slots.Close();  // the end
  });
  // Whatever way this thread leaves, the reader is told to stop, woken, and joined before the
  // sources it uses are destroyed.
  struct ReaderGuard {
    std::thread& thread;
    std::atomic<bool>& stop;
    StageQueue<int>& free_slots;
    ~ReaderGuard() {
      if (!thread.joinable()) return;
      stop = true;
      free_slots.Close();
      thread.join();
    }
  } reader_guard{reader, stop_reading, free_slots};

  // 2.-3. Change detection and fusion, on this thread.
  std::optional<Clock::time_point> t_first_set;
  std::optional<BackgroundProtection> protection;
  std::vector<ImageView<const uint8_t>> protection_changes(cams.size());
  std::optional<ShadowTeachers> teachers;
  std::optional<ShadowCheck> shadow_check;
  std::vector<ImageView<const uint8_t>> check_classes(cams.size());
  std::vector<ImageView<uint8_t>> check_changes(cams.size());
  if (adaptive && site.backgrounds.shadows.enabled && site.backgrounds.shadows.floor_check) shadow_check.emplace(lut);
  WalkedPeople walked_people;  // people seen walking in stay people where they stop
  std::vector<ImageView<const uint8_t>> teacher_classes(cams.size()), teacher_ratios(cams.size());
  int64_t last_frame_index = options.start_frame;
  int64_t next_age_frame = 0;
  if (adaptive) {
    std::vector<const CameraModel*> models;
    for (const auto& c : cams) models.push_back(c.cam->camera.get());
    ProtectionOptions po;
    po.person_height_m = site.backgrounds.person_height_m;
    protection.emplace(std::move(models), site.plane_height_m, po);
    if (site.backgrounds.shadows.enabled && site.backgrounds.shadows.learn) teachers.emplace(lut);
  }
  while (std::optional<int> slot = filled_slots.Pop()) {
    if (!t_first_set) t_first_set = Clock::now();
    FrameSet& set = slots[*slot];
    if (post.failed()) {  // stop reading; drain what the reader already has
      stop_reading = true;
      free_slots.Push(*slot);
      continue;
    }
    const std::vector<bool>& active = set.active;
    // Change detection, cameras in parallel, into the slot's change buffer (or fused with the
    // fusion itself, FastFusion::Fuse, when nothing else needs the changes).
    const bool all_active = std::all_of(active.begin(), active.end(), [](bool a) { return a; });
    const bool fused_now = (fully_fused || tolerant_fused) && all_active;
    auto t0 = Clock::now();
    set.changes_ready = false;
    set.bits_ready = false;
    if (!fused_now) {
      ensure_changes(set);
      ParallelFor(ctx, 0, static_cast<int64_t>(cams.size()), [&](int64_t b, int64_t e, int) {
        for (int64_t n = b; n < e; ++n) {
          if (active[n]) camera_changes(set, n, cams[n].raw_changes, cams[n].dilate_scratch, !shadow_check);
        }
      });
      if (shadow_check) {  // shadows whose floor the other cameras see lit are changes; then the tolerance
        const int r = site.detection.tolerance_px;
        for (size_t n = 0; n < cams.size(); ++n) {
          const ImageSize size = cams[n].cam->camera->image_size();
          const bool checked = active[n] && cams[n].model;
          check_classes[n] = checked ? cams[n].model->pixel_classes() : ImageView<const uint8_t>();
          check_changes[n] = !checked ? ImageView<uint8_t>()
                             : r > 0  ? cams[n].raw_changes.view()
                                      : ImageView<uint8_t>(set.changes.data() + lut.pixel_offset(static_cast<int>(n)),
                                                           size.width, size.height, size.width);
        }
        shadow_check->Apply(check_classes, check_changes);
        if (r > 0) {
          ParallelFor(ctx, 0, static_cast<int64_t>(cams.size()), [&](int64_t b, int64_t e, int) {
            for (int64_t n = b; n < e; ++n) {
              if (!active[n]) continue;
              const ImageSize size = cams[n].cam->camera->image_size();
              DilateChanges(cams[n].raw_changes.view(), r,
                            ImageView<uint8_t>(set.changes.data() + lut.pixel_offset(static_cast<int>(n)), size.width,
                                               size.height, size.width),
                            cams[n].dilate_scratch);
            }
          });
        }
      }
      set.changes_ready = true;
      if (options.change_pngs) {
        set.change_pictures.resize(cams.size());
        for (size_t n = 0; n < cams.size(); ++n) {
          if (!active[n]) continue;
          const ImageSize size = cams[n].cam->camera->image_size();
          // Before the tolerance: the raw image when there is one, else the change buffer.
          const bool raw = site.detection.tolerance_px > 0;
          const ImageView<const uint8_t> src =
              raw ? cams[n].raw_changes.view()
                  : ImageView<const uint8_t>(set.changes.data() + lut.pixel_offset(static_cast<int>(n)), size.width,
                                             size.height, size.width);
          Image<uint8_t>& pic = set.change_pictures[n];
          if (pic.width() != size.width || pic.height() != size.height) pic = Image<uint8_t>(size.width, size.height);
          for (int y = 0; y < size.height; ++y) {
            const uint8_t* a = src.row(y);
            uint8_t* b = pic.row(y);
            for (int x = 0; x < size.width; ++x) b[x] = a[x] != 0 ? 255 : 0;
          }
        }
      }
    }
    detect_s.Add(Since(t0));
    t0 = Clock::now();
    if (fused_now) {
      for (size_t n = 0; n < cams.size(); ++n) {
        frame_views[n] = set.frames[n].gray.view();
        background_views[n] = cams[n].background_gray.view();
      }
      if (tolerant_fused) {
        fast->FuseTolerant(frame_views, background_views, site.detection.threshold, site.detection.tolerance_px, ctx,
                           set.map, set.change_bits);
        set.bits_ready = true;
      } else {
        fast->Fuse(frame_views, background_views, site.detection.threshold, ctx, set.map);
      }
    } else if (paper_and && all_active) {
      fast->FuseChanges(set.changes, ctx, set.map);
    } else {
      fusion.Fuse(set.changes, active, site.fusion, set.map);
    }
    fuse_s.Add(Since(t0));
    if (column_fusion) {
      t0 = Clock::now();
      for (size_t n = 0; n < cams.size(); ++n) {
        const ImageSize size = cams[n].cam->camera->image_size();
        change_views[n] = ImageView<const uint8_t>(set.changes.data() + lut.pixel_offset(static_cast<int>(n)), size.width,
                                                   size.height, size.width);
      }
      ParallelFor(ctx, 0, static_cast<int64_t>(cams.size()), [&](int64_t b, int64_t e, int) {
        for (int64_t n = b; n < e; ++n)
          if (active[n]) change_counts[n].Build(change_views[n]);
      });
      column_fusion->Fuse(change_counts, active, people.column, ctx, set.column_map);
      if (explainer) explainer->Explain(change_views, change_counts, active, set.column_map, people.explain, ctx, set.people);
      people_s.Add(Since(t0));
    }
    // The adaptive backgrounds follow the frame where the map says nothing stands.
    if (adaptive) {
      t0 = Clock::now();
      for (size_t n = 0; n < cams.size(); ++n) {
        const ImageSize size = cams[n].cam->camera->image_size();
        protection_changes[n] = active[n] ? ImageView<const uint8_t>(set.changes.data() + lut.pixel_offset(static_cast<int>(n)),
                                                                     size.width, size.height, size.width)
                                          : ImageView<const uint8_t>();
      }
      protection->Compute(set.map, protection_changes);
      if (explainer) {  // the people the views explain, though their feet may leave the floor unchanged
        people_positions.clear();
        for (const ExplainedPerson& p : set.people) people_positions.emplace_back(p.x_m, p.y_m);
        protection->AddPeople(people_positions, site.tracking.person_radius_m(), walked_people.Update(people_positions));
      }
      if (teachers) {  // the pixels that show the floor darkened, as the cameras agree
        for (size_t n = 0; n < cams.size(); ++n) {
          teacher_classes[n] = active[n] && cams[n].model ? cams[n].model->pixel_classes() : ImageView<const uint8_t>();
          teacher_ratios[n] = active[n] && cams[n].model ? cams[n].model->pixel_ratios() : ImageView<const uint8_t>();
        }
        teachers->Compute(teacher_classes, teacher_ratios, protection->person_positions(), kShadowTeacherPersonRadiusM);
      }
      ParallelFor(ctx, 0, static_cast<int64_t>(cams.size()), [&](int64_t b, int64_t e, int) {
        for (int64_t n = b; n < e; ++n) {
          if (active[n] && cams[n].model) {
            if (teachers) cams[n].model->LearnShadows(FrameYuv(set.frames[n]), teachers->image(static_cast<size_t>(n)).view());
            cams[n].model->Update(FrameYuv(set.frames[n]), protection->image(static_cast<size_t>(n)).view(), set.frame_index);
          }
        }
      });
      last_frame_index = set.frame_index;
      if (set.frame_index >= next_age_frame) {  // a pass over the pixels: about once a second
        for (size_t n = 0; n < cams.size(); ++n) {
          if (cams[n].model) background_age_s[n].Set(cams[n].model->MeanAgeS(set.frame_index));
        }
        next_age_frame = set.frame_index + std::max<int64_t>(1, std::lround(fps));
      }
      background_s.Add(Since(t0));
    }
    post.Push(*slot);  // when it has failed, the slot goes straight back to the reader
  }
  reader.join();  // it has closed filled_slots: the sources, flags and infos are ours again
  const Status post_status = post.Finish();
  const Status writer_status = writer.Finish();
  summary.latency = stats.latency;  // the writer stage's, over every frame set
  summary.detect_s = detect_s.get();
  summary.fuse_s = fuse_s.get();
  summary.people_s = people_s.get();
  summary.background_s = background_s.get();
  summary.blobs_s = blobs_s.get();
  summary.track_s = track_s.get();
  summary.output_s = post_output_s.get() + write_s;
  summary.decode_s = frame_reader.decode_s();
  if (t_first_set) summary.startup_s = std::chrono::duration<double>(*t_first_set - t_start).count();
  if (frames_done > 2 * kWarmUpFrames) {
    summary.steady_frames = frames_done - kWarmUpFrames - 1;
    summary.steady_seconds = std::chrono::duration<double>(t_last_done - t_warm_done).count();
  } else if (frames_done >= 2) {
    summary.steady_frames = frames_done - 1;
    summary.steady_seconds = std::chrono::duration<double>(t_last_done - t_first_done).count();
  }
  if (summary.steady_seconds > 0) summary.steady_fps = static_cast<double>(summary.steady_frames) / summary.steady_seconds;
  summary.max_queued_outputs = static_cast<int>(writer.queue().high_water());
  // A failed write (or tracker) stops the run with its error; kAtomic commits nothing (no
  // output is ever half-written), kLive keeps the whole lines written before it. The small
  // summary.json still says why: dropping the temporaries first frees what a full disk needs.
  Status output_failure = !writer_status.ok() ? writer_status : post_status;
  if (!output_failure.ok()) {
    files->Abandon();
    (void)close_sinks_fn();
  }
  const Status& failure = frame_reader.failure();
  summary.stop_reason = frame_reader.stop_reason();
  if (summary.stop_reason.empty()) {
    summary.stop_reason = stop_requested()                                                      ? "stop requested"
                          : options.max_frames > 0 && summary.frames >= options.max_frames ? "frame limit"
                                                                                            : "stopped";
  }
  if (!failure.ok()) summary.stop_reason = failure.message();
  if (!output_failure.ok()) summary.stop_reason = output_failure.message();

  // Finalise every output, also when a camera failed: frames processed are never lost.
  stats.stop_reason = summary.stop_reason;
  stats.elapsed_s = Since(t_start);
  if (output_failure.ok()) output_failure = close_sinks_fn();
  for (const fs::path& p : files->written()) summary.outputs.push_back(p.string());
  summary.tracks = stats.tracks;
  summary.zone_events = stats.zone_events;
  if (best_frame.kept && output_failure.ok()) {
    render_mosaic(best_frame.set, best_frame.detections, best_frame.time_s, best_frame.tracks, best_frame.trails,
                  best_mosaic);
  }
  if (!best_mosaic.empty() && output_failure.ok()) {
    output_failure = WritePng(out / "mosaic.png", best_mosaic.view());
    if (output_failure.ok()) summary.outputs.push_back((out / "mosaic.png").string());
  }
  if (!output_failure.ok()) summary.stop_reason = output_failure.message();
  summary.seconds = Since(t_start);
  summary.frames_per_second = summary.seconds > 0 ? static_cast<double>(summary.frames) / summary.seconds : 0;
  for (const auto& c : cams) summary.cameras.push_back(c.info);

  json j = static_summary;
  j["running"] = false;
  j["frames"] = summary.frames;
  j["seconds"] = summary.seconds;
  j["frames_per_second"] = summary.frames_per_second;
  j["startup_seconds"] = summary.startup_s;
  j["steady_state"] = {{"frames", summary.steady_frames}, {"seconds", summary.steady_seconds},
                       {"frames_per_second", summary.steady_fps}};
  j["stage_seconds"] = {{"decode", summary.decode_s}, {"detect", summary.detect_s}, {"fuse", summary.fuse_s},
                        {"blobs", summary.blobs_s}, {"track", summary.track_s}, {"output", summary.output_s},
                        {"background", summary.background_s}, {"people", summary.people_s},
                        {"tables", summary.lut_seconds}};
  if (options.track) {
    j["tracking"]["tracks"] = summary.tracks;
    j["tracking"]["zone_events"] = summary.zone_events;
    j["tracking"]["lines"] = LinesJson(site.tracking.lines, stats.lines);
  }
  j["stop_reason"] = summary.stop_reason;
  j["latency_ms"] = LatencyJson(stats.latency);
  json cj = json::array();
  for (size_t n = 0; n < summary.cameras.size(); ++n) {
    const CameraRunInfo& c = summary.cameras[n];
    json e = {{"id", c.id}, {"source", c.source}, {"background", c.background}};
    if (const BackgroundModel* m = cams[n].model.get(); m != nullptr) {
      const BackgroundStats& st = m->stats();
      e["background_model"] = {
          {"updated_fraction", st.pixels > 0 ? static_cast<double>(st.pixels_updated) / static_cast<double>(st.pixels) : 0.0},
          {"mean_age_s", m->MeanAgeS(last_frame_index)},
          {"absorbed_pixel_events", st.pixels_absorbed},
          {"last_frame", {{"gain", st.transfer.gain}, {"offset", st.transfer.offset},
                          {"changed_fraction", st.changed_fraction}, {"shadow_fraction", st.shadow_fraction}}},
          {"shadow_look", {{"ratio", m->shadow_look().ratio}, {"pattern_rgb", m->shadow_look().pattern},
                           {"mass", m->shadow_look().mass}, {"peak_share", m->shadow_look().peak_share}}}};
    }
    if (c.ended_at_frame) e["ended_at_frame"] = *c.ended_at_frame;
    if (!c.end_reason.empty()) e["end_reason"] = c.end_reason;
    e["frames"] = stats.cameras[n].frames;
    e["dropped_frames"] = stats.cameras[n].dropped;
    e["reconnects"] = stats.cameras[n].reconnects;
    cj.push_back(e);
  }
  j["cameras"] = cj;
  summary.blobs_total = total_blobs;
  summary.blobs_max_per_frame = static_cast<int64_t>(max_blobs);
  j["blobs"] = {{"total", total_blobs},
                {"max_per_frame", max_blobs},
                {"mean_per_frame", summary.frames > 0 ? static_cast<double>(total_blobs) / static_cast<double>(summary.frames) : 0.0}};
  summary.outputs.push_back((out / "summary.json").string());
  j["outputs"] = summary.outputs;
  const Status summary_written = WriteFileAtomic(out / "summary.json", j.dump(2) + "\n");
  if (!output_failure.ok()) {
    return Status(output_failure.code(),
                  summary_written.ok()
                      ? fmt::format("{}; summary.json written with this stop_reason", output_failure.message())
                      : fmt::format("{}; and summary.json not written either: {}", output_failure.message(),
                                    summary_written.message()));
  }
  OCCMAP_RETURN_IF_ERROR(summary_written);
  if (!failure.ok()) return failure;
  return summary;
}

}  // namespace occmap
