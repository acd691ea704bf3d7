#include "occmap/pipeline/run.h"

#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <limits>
#include <optional>
#include <thread>

#include "occmap/pipeline/background_maintenance.h"
#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/detect_track_stage.h"
#include "occmap/pipeline/frame_reader.h"
#include "occmap/pipeline/frame_set.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/fusion_stage.h"
#include "occmap/pipeline/output_files.h"
#include "occmap/pipeline/settle_backgrounds.h"
#include "occmap/pipeline/sink_stage.h"
#include "occmap/pipeline/stage_queue.h"
#include "occmap/pipeline/summary_file.h"
#include "occmap/site/site_lut.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/safe_files.h"

namespace occmap {
namespace fs = std::filesystem;

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

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Frames left out of the steady-state rate: decoders filling their frame threads, first touches.
constexpr int64_t kWarmUpFrames = 10;
// Frame sets in the ring: one per stage that holds a slot (reader, fusion, detect/track) + 1 spare.
constexpr int kSlots = 4;

// backgrounds/<camera>.png: the background each camera starts from.
Status WriteBackgrounds(const fs::path& out, const std::vector<CameraState>& cams, bool colour,
                        std::vector<std::string>& written) {
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / "backgrounds"));
  for (const auto& c : cams) {
    if (c.is_mask) continue;
    const fs::path p = out / "backgrounds" / (c.cam->id + ".png");
    if (c.model) {
      OCCMAP_RETURN_IF_ERROR(WriteYuvPng(p, c.model->Current()));
    } else {
      OCCMAP_RETURN_IF_ERROR(colour ? WritePng(p, c.background_rgb.view()) : WritePng(p, c.background_gray.view()));
    }
    written.push_back(p.string());
  }
  return Status::Ok();
}

// The steady-state rate: completions after the warm-up, timed by the detect/track stage.
struct Completions {
  int64_t done = 0;
  Clock::time_point first, warm, last;
  void Add() {
    ++done;
    const auto now = Clock::now();
    if (done == 1) first = now;
    if (done == kWarmUpFrames + 1) warm = now;
    last = now;
  }
  void Report(RunSummary& s) const {
    if (done > 2 * kWarmUpFrames) {
      s.steady_frames = done - kWarmUpFrames - 1;
      s.steady_seconds = std::chrono::duration<double>(last - warm).count();
    } else if (done >= 2) {
      s.steady_frames = done - 1;
      s.steady_seconds = std::chrono::duration<double>(last - first).count();
    }
    if (s.steady_seconds > 0) s.steady_fps = static_cast<double>(s.steady_frames) / s.steady_seconds;
  }
};

}  // namespace

void WarnCacheNotWritten(const WarningCallback& warning, std::string_view what, const fs::path& path,
                         std::string_view error) {
  if (warning) warning(fmt::format("could not write the {} {}: {}; going on without it", what, path.string(), error));
}

FusionPlan RunFusionPlan(const Site& site, const RunOptions& options) {
  return ChooseFusionPath(site, options.mosaic_video || options.change_pngs || options.sink_frames);
}

Result<RunSummary> RunSite(const Site& site, const RunOptions& options, Context& ctx, const ProgressCallback& progress) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  OCCMAP_RETURN_IF_ERROR(site.detection.Validate());
  OCCMAP_RETURN_IF_ERROR(site.fusion.Validate(static_cast<int>(site.cameras.size())));
  OCCMAP_RETURN_IF_ERROR(site.backgrounds.Validate());
  const auto t_start = Clock::now();
  RunSummary summary;
  auto stop_requested = [&] { return options.stop != nullptr && options.stop->load(); };
  // How changes are computed and fused: one choice (pipeline/fusion_path.h).
  const FusionPlan plan = RunFusionPlan(site, options);
  summary.fusion_path = plan.Describe(site);

  // Sources and backgrounds, then the tables.
  OCCMAP_ASSIGN_OR_RETURN(std::vector<CameraState> cams, OpenCameras(site, options, plan, ctx));
  const auto t_lut = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(CachedLut cached, LoadOrBuildSiteLut(site, options.cache_dir, ctx));
  if (!cached.write_error.empty()) {
    WarnCacheNotWritten(options.warning, "table cache", SiteLutPath(site, options.cache_dir), cached.write_error);
  }
  summary.lut_cache = ToString(cached.outcome);
  summary.lut_seconds = Since(t_lut);
  const GroundLut& lut = cached.lut;
  if (plan.adaptive) {  // each learned pixel's two candidates checked against the other cameras' view
    const ConsensusResult r = CheckLearnedBackgrounds(site, lut, cams);
    summary.consensus_pixels_checked = r.pixels_checked;
    summary.consensus_pixels_swapped = r.pixels_swapped;
    summary.consensus_pixels_settled = r.pixels_settled;
  }
  const double fps = cams[0].source->fps().value_or(10.0);
  OCCMAP_ASSIGN_OR_RETURN(const SettleFigures settled, SettleLearnedBackgrounds(site, options, plan, lut, cams, fps, ctx));
  summary.settle_frame_sets = settled.frame_sets;
  summary.settle_s = settled.seconds;

  // The stages: reader (frame_reader.h) -> change detection and fusion (fusion_stage.h) ->
  // detections and tracking (detect_track_stage.h) -> the sinks (sink_stage.h).
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FusionStage> fusion, FusionStage::Create(site, options, plan, lut, cams, fps, ctx));
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<DetectTrackStage> post,
                          DetectTrackStage::Create(site, options, plan, lut, cams, fusion->changes(),
                                                   fusion->column_lut(), fps));

  // Outputs: the backgrounds now; per frame set the sinks, the run's files first
  // (pipeline/output_files.h), then the caller's (RunOptions::sinks).
  const fs::path out = options.out_dir;
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out));
  RemoveStaleTemporaries(out, /*recursive=*/true);  // of killed runs (util/file_util.h)
  OCCMAP_RETURN_IF_ERROR(WriteBackgrounds(out, cams, plan.colour, summary.outputs));
  auto files = std::make_shared<OutputFiles>(RunFileOptions(site, options, post->mosaic_size()));
  const std::vector<std::shared_ptr<FrameSink>> sinks = RunSinks(files, options);
  std::vector<std::string> camera_ids;
  for (const auto& c : cams) camera_ids.push_back(c.cam->id);
  const SinkStart sink_start = RunSinkStart(site, lut, options, fps, camera_ids);
  const SummaryFile summary_file(out / "summary.json", site, options, plan, summary, cams, ctx.num_threads());

  // 1. The reader: one frame per active camera, by index or by timestamp, on its own thread
  // (decoding overlaps the processing of the previous frames), into a ring of kSlots frame
  // sets: memory stays flat.
  FrameReader frame_reader(cams, options, ctx.num_threads(),
                           RunSourceOptions(plan, ctx.num_threads(), static_cast<int>(cams.size())));

  // What the sinks see of the other stages while the run goes on (their figures are atomics).
  auto running_figures = [&](const FrameRecord& r, RunStats& stats) {
    for (size_t n = 0; n < cams.size(); ++n) {
      CameraStats& cs = stats.cameras[n];
      if (const LiveSource* live = frame_reader.live(n); live != nullptr) {
        cs.connected = live->connected();
        cs.dropped = live->dropped();
        cs.reconnects = live->reconnects();
        cs.active = true;
      } else {
        cs.active = r.active[n];
      }
      cs.background_cache = fusion->background_cache(n);
      cs.background_age_s = cams[n].is_mask ? std::numeric_limits<double>::quiet_NaN()
                            : cams[n].model ? fusion->background_age_s(n)
                                            : static_cast<double>(r.frame - options.start_frame) / fps;
    }
    stats.stages = {frame_reader.decode_s(), fusion->detect_s(), fusion->fuse_s(), post->blobs_s(),
                    post->track_s(), post->output_s(), fusion->background_s(), fusion->people_s(),
                    summary.lut_seconds};
  };
  SinkStage sink_stage(sinks, camera_ids, options, &summary_file, t_start, running_figures);
  OCCMAP_RETURN_IF_ERROR(sink_stage.Open(sink_start));

  std::optional<int64_t> total;
  for (const auto& c : cams) {
    if (!c.source) continue;  // a live stream: the reader holds it now, and it has no end
    if (auto fc = c.source->frame_count()) total = total ? std::min(*total, *fc - options.start_frame) : *fc - options.start_frame;
  }
  if (options.max_frames > 0) total = total ? std::min(*total, options.max_frames) : options.max_frames;

  // The stages, each on its own thread, joined by bounded queues (stage_queue.h): memory stays
  // flat however long the run, and the stages overlap, so a run over video files is limited by
  // decoding rather than by the work of any one stage.
  //   reader          decodes one frame set into a free slot of the ring        -> filled_slots
  //   this thread     FusionStage: changes and fusion into the slot's map        -> post
  //   post            DetectTrackStage: detections, tracking, pictures;
  //                   gives the slot back to the reader                          -> writer
  //   writer          SinkStage: the run's files, then the caller's sinks
  // A stage that fails stops the reader; the others drain their queues and the first error is
  // returned after the frames before it are written (kAtomic and a failed write: nothing is
  // committed). The fusion alone uses ctx's pool (ParallelFor); the other stages are
  // single-threaded.
  std::vector<FrameSet> slots(kSlots);
  for (FrameSet& set : slots) {
    set.frames.resize(cams.size());
    set.active.assign(cams.size(), false);
    set.map = OccupancyMap(site.grid);
  }
  StageQueue<int> free_slots(kSlots), filled_slots(kSlots);
  for (int k = 0; k < kSlots; ++k) free_slots.Push(k);
  std::atomic<bool> stop_reading{false};

  StageWorker<FrameRecord> writer(kOutputQueue, [&](FrameRecord& r) -> Status {
    OCCMAP_RETURN_IF_ERROR(sink_stage.Consume(r));
    post->GivePicture(std::move(r.mosaic));
    return Status::Ok();
  });
  Completions completions;
  StageWorker<int> post_worker(
      kSlots,
      [&](int& slot) -> Status {
        struct GiveBack {  // the slot goes back to the reader however this returns
          StageQueue<int>& queue;
          int slot;
          ~GiveBack() { queue.Push(slot); }
        } give_back{free_slots, slot};
        FrameRecord record;
        OCCMAP_RETURN_IF_ERROR(post->Process(slots[slot], record));
        if (!writer.Push(std::move(record))) return Internal("the writer stage stopped");
        completions.Add();
        summary.frames = completions.done;
        if (progress) progress({completions.done, total, Since(t_start)});
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
  while (std::optional<int> slot = filled_slots.Pop()) {
    if (!t_first_set) t_first_set = Clock::now();
    if (post_worker.failed()) {  // stop reading; drain what the reader already has
      stop_reading = true;
      free_slots.Push(*slot);
      continue;
    }
    fusion->Process(slots[*slot], ctx);
    post_worker.Push(*slot);  // when it has failed, the slot goes straight back to the reader
  }
  reader.join();  // it has closed filled_slots: the sources, flags and infos are ours again
  // Live cameras' backgrounds as they are now, for the next start (a best effort, as the
  // periodic writes: the cache is no output of the run; summary.json tells how it went).
  fusion->RefreshCachedBackgrounds();
  const Status post_status = post_worker.Finish();
  const Status writer_status = writer.Finish();
  const RunStats& stats = sink_stage.stats();
  summary.latency = stats.latency;  // the sink stage's, over every frame set
  summary.detect_s = fusion->detect_s();
  summary.fuse_s = fusion->fuse_s();
  summary.people_s = fusion->people_s();
  summary.occluders_s = fusion->occluders_s();
  summary.background_s = fusion->background_s();
  summary.blobs_s = post->blobs_s();
  summary.track_s = post->track_s();
  summary.output_s = post->output_s() + sink_stage.write_s();
  summary.decode_s = frame_reader.decode_s();
  if (t_first_set) summary.startup_s = std::chrono::duration<double>(*t_first_set - t_start).count();
  completions.Report(summary);
  summary.max_queued_outputs = static_cast<int>(writer.queue().high_water());
  // A failed write (or tracker) stops the run with its error; kAtomic commits nothing (no
  // output is ever half-written), kLive keeps the whole lines written before it. The small
  // summary.json still says why: dropping the temporaries first frees what a full disk needs.
  Status output_failure = !writer_status.ok() ? writer_status : post_status;
  if (!output_failure.ok()) {
    files->Abandon();
    (void)sink_stage.Close(output_failure.message());
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
  if (output_failure.ok()) output_failure = sink_stage.Close(summary.stop_reason);
  for (const fs::path& p : files->written()) summary.outputs.push_back(p.string());
  summary.tracks = stats.tracks;
  summary.zone_events = stats.zone_events;
  if (output_failure.ok()) {
    const Image<Rgb8>& best_mosaic = post->BestMosaic();
    if (!best_mosaic.empty()) {
      output_failure = WritePng(out / "mosaic.png", best_mosaic.view());
      if (output_failure.ok()) summary.outputs.push_back((out / "mosaic.png").string());
    }
  }
  if (output_failure.ok()) output_failure = fusion->SaveLearnedOccluders(out, summary.outputs);
  if (!output_failure.ok()) summary.stop_reason = output_failure.message();
  summary.seconds = Since(t_start);
  summary.frames_per_second = summary.seconds > 0 ? static_cast<double>(summary.frames) / summary.seconds : 0;
  for (size_t n = 0; n < cams.size(); ++n) {
    summary.cameras.push_back(cams[n].info);
    summary.cameras.back().background_cache = fusion->background_cache(n);
  }
  summary.blobs_total = sink_stage.blobs_total();
  summary.blobs_max_per_frame = sink_stage.blobs_max_per_frame();
  summary.outputs.push_back(summary_file.path().string());
  const Status summary_written = summary_file.WriteFinal(summary, stats, cams, fusion->last_frame_index());
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
