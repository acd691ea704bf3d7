#include "occmap/pipeline/run.h"

#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>
#include <nlohmann/json.hpp>
#include <set>

#include "occmap/detect/background.h"
#include "occmap/detect/change_detection.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/fusion.h"
#include "occmap/fusion/morphology.h"
#include "occmap/io/frame_source.h"
#include "occmap/io/video_writer.h"
#include "occmap/pipeline/object_detector.h"
#include "occmap/pipeline/mosaic.h"
#include "occmap/track/detections.h"
#include "occmap/site/site_lut.h"
#include "occmap/track/multi_target_tracker.h"
#include "occmap/track/track_output.h"
#include "occmap/track/window_tracker.h"
#include "occmap/track/zones.h"
#include "occmap/util/file_util.h"
#include "occmap/util/hash.h"
#include "occmap/util/image_io.h"

namespace occmap {
namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct CameraState {
  const SiteCamera* cam = nullptr;
  std::unique_ptr<FrameSource> source;
  bool is_mask = false;
  Image<uint8_t> background_gray;
  Image<Rgb8> background_rgb;
  Frame lookahead;  // timestamp sync: the next frame not yet used
  bool has_lookahead = false;
  bool present = false;  // has a frame for the current instant
  bool active = true;    // its stream has not ended or failed
  Image<uint8_t> raw_changes;
  std::vector<uint8_t> dilate_scratch;
  CameraRunInfo info;
};

Status CheckFrameSize(const CameraState& c, const Frame& f) {
  const ImageSize want = c.cam->camera->image_size();
  if (c.is_mask) {
    // Masks at any resolution are resampled to the camera's size, but not to another shape.
    const double a_want = static_cast<double>(want.width) / want.height;
    const double a_got = static_cast<double>(f.gray.width()) / std::max(1, f.gray.height());
    if (std::abs(a_got / a_want - 1) > 0.01) {
      return InvalidInput(fmt::format("{} gives {}x{} masks, expected the shape of the {}x{} image "
                                      "(any resolution with the same aspect ratio)",
                                      c.source->Describe(), f.gray.width(), f.gray.height(), want.width,
                                      want.height));
    }
    return Status::Ok();
  }
  if (f.gray.width() != want.width || f.gray.height() != want.height) {
    return InvalidInput(fmt::format("{} gives {}x{} frames, expected the site's image size {}x{} "
                                    "(set the camera's image_size)",
                                    c.source->Describe(), f.gray.width(), f.gray.height(), want.width,
                                    want.height));
  }
  return Status::Ok();
}

// The background of a camera: given, reused from the cache, or the median of K frames.
Status PrepareBackground(const Site& site, const RunOptions& options, bool colour, const FrameSourceOptions& src_opts,
                         CameraState& c) {
  const SiteCamera& cam = *c.cam;
  const ImageSize size = cam.camera->image_size();
  if (c.is_mask) {
    c.info.background = "none (foreground masks)";
    return Status::Ok();
  }
  auto check_size = [&](int w, int h, const fs::path& path) -> Status {
    if (w == size.width && h == size.height) return Status::Ok();
    return InvalidInput(fmt::format("camera {}: background '{}' is {}x{}, expected the image size {}x{}", cam.id,
                                    path.string(), w, h, size.width, size.height));
  };
  auto load = [&](const fs::path& path) -> Status {
    if (colour) {
      auto rgb = ReadRgbImage(path);
      if (!rgb.ok()) return rgb.status().WithContext(fmt::format("camera {}: background", cam.id));
      OCCMAP_RETURN_IF_ERROR(check_size(rgb->width(), rgb->height(), path));
      c.background_rgb = std::move(rgb).value();
    }
    auto gray = ReadGrayImage(path);
    if (!gray.ok()) return gray.status().WithContext(fmt::format("camera {}: background", cam.id));
    OCCMAP_RETURN_IF_ERROR(check_size(gray->width(), gray->height(), path));
    c.background_gray = std::move(gray).value();
    return Status::Ok();
  };
  if (cam.background) {
    OCCMAP_RETURN_IF_ERROR(load(*cam.background));
    c.info.background = fmt::format("given: {}", cam.background->string());
    return Status::Ok();
  }
  // Estimated backgrounds are cached under a key of everything they depend on.
  Hasher h;
  h.Add("background-v1");
  h.Add(site.name);
  h.Add(cam.id);
  h.Add(cam.source.location);
  h.AddPod(options.background_frames);
  h.AddPod(options.background_step);
  h.AddPod(options.start_frame);
  h.AddPod(colour);
  h.AddPod(size.width);
  h.AddPod(size.height);
  std::error_code ec;
  if (const auto mtime = fs::last_write_time(cam.source.location, ec); !ec) h.AddPod(mtime.time_since_epoch().count());
  const fs::path cached = options.cache_dir.empty()
                              ? fs::path()
                              : options.cache_dir / "backgrounds" / fmt::format("{}-{}-{:016x}.png", site.name, cam.id, h.Digest());
  if (!cached.empty() && fs::exists(cached, ec) && load(cached).ok()) {
    c.info.background = fmt::format("reused: {}", cached.string());
    return Status::Ok();
  }
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> src, OpenFrameSource(cam.source, src_opts));
  OCCMAP_RETURN_IF_ERROR(src->SkipTo(options.start_frame));
  MedianBackground gray_median(size.width, size.height);
  MedianBackgroundRgb rgb_median(size.width, size.height);
  Frame f;
  int64_t read = 0;
  while (gray_median.count() < options.background_frames) {
    OCCMAP_ASSIGN_OR_RETURN(bool got, src->Read(f));
    if (!got) break;
    if (read++ % options.background_step != 0) continue;
    OCCMAP_RETURN_IF_ERROR(CheckFrameSize(c, f).WithContext(fmt::format("camera {}", cam.id)));
    gray_median.Add(f.gray.view());
    if (colour) rgb_median.Add(f.rgb.view());
  }
  if (gray_median.count() == 0) {
    return InvalidInput(fmt::format("camera {}: {} has no frames to estimate a background from", cam.id, src->Describe()));
  }
  c.background_gray = gray_median.Median();
  if (colour) c.background_rgb = rgb_median.Median();
  c.info.background = fmt::format("estimated: median of {} frames", gray_median.count());
  if (!cached.empty()) {
    OCCMAP_RETURN_IF_ERROR(EnsureDirectory(cached.parent_path()));
    if (colour) {
      OCCMAP_RETURN_IF_ERROR(WritePng(cached, c.background_rgb.view()));
    } else {
      OCCMAP_RETURN_IF_ERROR(WritePng(cached, c.background_gray.view()));
    }
  }
  return Status::Ok();
}

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
  Result<std::vector<Track>> Update(const std::vector<Blob>& blobs, const OccupancyMap& map, double time_s) {
    return window_ ? window_->Update(blobs, map, time_s) : multi_->Update(blobs, map, time_s);
  }

 private:
  std::unique_ptr<WindowTracker> window_;
  std::unique_ptr<MultiTargetTracker> multi_;
};

json BlobJson(const Blob& b) {
  return {{"x_m", std::round(b.x_m * 1e4) / 1e4}, {"y_m", std::round(b.y_m * 1e4) / 1e4},
          {"area_m2", std::round(b.area_m2 * 1e5) / 1e5}, {"cells", b.cells}};
}

// The map's grey picture (OccupancyMap::ToGrayImage) enlarged by `scale`, in RGB for video.
Image<Rgb8> OccupancyPicture(const Image<uint8_t>& gray, int scale) {
  Image<Rgb8> out(gray.width() * scale, gray.height() * scale);
  for (int y = 0; y < out.height(); ++y) {
    const uint8_t* src = gray.row(y / scale);
    Rgb8* dst = out.row(y);
    for (int x = 0; x < out.width(); ++x) {
      const uint8_t v = src[x / scale];
      dst[x] = {v, v, v};
    }
  }
  return out;
}

// The frames of all cameras for one instant, filled by the reader thread.
struct FrameSet {
  int64_t frame_index = 0;
  std::vector<Frame> frames;  // per camera; buffers reused from set to set
  std::vector<bool> active;   // the camera's frame is there (stream not ended, synchronised)
};

// A blocking FIFO of slot indices between the reader thread and the processing loop.
class SlotQueue {
 public:
  void Push(int slot) {
    {
      std::lock_guard lock(mutex_);
      items_.push_back(slot);
    }
    ready_.notify_one();
  }
  int Pop() {
    std::unique_lock lock(mutex_);
    ready_.wait(lock, [&] { return !items_.empty(); });
    const int slot = items_.front();
    items_.pop_front();
    return slot;
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<int> items_;
};

}  // namespace

Status RunOptions::Validate() const {
  if (out_dir.empty()) return InvalidInput("--out: expected a folder");
  if (start_frame < 0) return InvalidInput(fmt::format("--start: expected >= 0, found {}", start_frame));
  if (max_frames < -1 || max_frames == 0) return InvalidInput(fmt::format("--frames: expected >= 1, found {}", max_frames));
  if (background_frames < 1 || background_frames > 255) {
    return InvalidInput(fmt::format("--background-frames: expected 1..255, found {}", background_frames));
  }
  if (background_step < 1) return InvalidInput(fmt::format("background step: expected >= 1, found {}", background_step));
  if (!(sync_tolerance_s > 0)) return InvalidInput("--sync-tolerance-s: expected > 0");
  return Status::Ok();
}

Result<RunSummary> RunSite(const Site& site, const RunOptions& options, Context& ctx, const ProgressCallback& progress) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  OCCMAP_RETURN_IF_ERROR(site.detection.Validate());
  OCCMAP_RETURN_IF_ERROR(site.fusion.Validate(static_cast<int>(site.cameras.size())));
  const auto t_start = Clock::now();
  RunSummary summary;
  const bool colour = site.detection.colour;

  // Sources and backgrounds.
  std::vector<CameraState> cams(site.cameras.size());
  FrameSourceOptions src_opts;
  src_opts.colour = colour;
  src_opts.decoder_threads = ctx.num_threads();
  for (size_t n = 0; n < cams.size(); ++n) {
    CameraState& c = cams[n];
    c.cam = &site.cameras[n];
    c.info.id = c.cam->id;
    if (c.cam->source.kind == FrameSourceSpec::Kind::kNone) {
      return InvalidInput(fmt::format("camera {}: no source (give cameras[{}].source in the site file)", c.cam->id, n));
    }
    c.is_mask = c.cam->source.kind == FrameSourceSpec::Kind::kMasks;
    auto src = OpenFrameSource(c.cam->source, src_opts);
    if (!src.ok()) return src.status().WithContext(fmt::format("camera {}", c.cam->id));
    c.source = std::move(src).value();
    c.info.source = c.source->Describe();
    OCCMAP_RETURN_IF_ERROR(PrepareBackground(site, options, colour, src_opts, c));
    if (options.start_frame > 0) {
      OCCMAP_RETURN_IF_ERROR(c.source->SkipTo(options.start_frame).WithContext(fmt::format("camera {}", c.cam->id)));
    }
    const ImageSize size = c.cam->camera->image_size();
    c.raw_changes = Image<uint8_t>(size.width, size.height);
  }

  // Tables.
  const auto t_lut = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(CachedLut cached, LoadOrBuildSiteLut(site, options.cache_dir.empty() ? fs::path() : options.cache_dir, ctx));
  summary.lut_cache = ToString(cached.outcome);
  summary.lut_seconds = Since(t_lut);
  const GroundLut& lut = cached.lut;
  Fusion fusion(lut);
  // Fully fused (no change buffer at all) when nothing needs the per-pixel changes: grey
  // differencing without tolerance, no mask sources, and no mosaic video (the mosaic picture
  // of the best frame gets its changes computed when it is drawn).
  const bool paper_and = site.fusion.method == FusionMethod::kImageBased && site.fusion.max_free_views == 0;
  // The paper's AND with every camera active takes the fast path (its tables are built only
  // when the site's fusion settings can use them).
  std::optional<FastFusion> fast;
  if (paper_and) fast.emplace(lut);
  bool any_mask_source = false;
  for (const auto& c : site.cameras) any_mask_source |= c.source.kind == FrameSourceSpec::Kind::kMasks;
  const bool fully_fused = paper_and && !colour && site.detection.tolerance_px == 0 && !any_mask_source &&
                           !options.mosaic_video;
  std::vector<ImageView<const uint8_t>> frame_views(site.cameras.size()), background_views(site.cameras.size());
  OccupancyMap map(site.grid);
  std::vector<uint8_t> changes(lut.total_pixels(), 0);

  // Outputs.
  const fs::path out = options.out_dir;
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out));
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / "backgrounds"));
  for (const auto& c : cams) {
    if (c.is_mask) continue;
    const fs::path p = out / "backgrounds" / (c.cam->id + ".png");
    OCCMAP_RETURN_IF_ERROR(colour ? WritePng(p, c.background_rgb.view()) : WritePng(p, c.background_gray.view()));
    summary.outputs.push_back(p.string());
  }
  if (options.occupancy_pngs) OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / "occupancy"));
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<AtomicFileWriter> detections, AtomicFileWriter::Open(out / "detections.jsonl"));
  const double fps = cams[0].source->fps().value_or(10.0);
  const int map_scale = std::max(1, 400 / std::max(site.grid.cells_x, site.grid.cells_y));
  MosaicRenderer mosaic(site, options.mosaic_width_px);
  std::unique_ptr<VideoWriter> occupancy_video, mosaic_video;
  if (options.occupancy_video) {
    OCCMAP_ASSIGN_OR_RETURN(occupancy_video,
                            VideoWriter::Open(out / "occupancy.mp4",
                                              {site.grid.cells_x * map_scale, site.grid.cells_y * map_scale}, fps));
  }
  if (options.mosaic_video) {
    OCCMAP_ASSIGN_OR_RETURN(mosaic_video, VideoWriter::Open(out / "mosaic.mp4", mosaic.size(), fps));
  }
  Image<Rgb8> best_mosaic;
  size_t best_blobs = 0;

  // The tracker sees footprints grown by r, so its idea of one person's size grows with them.
  TrackerOptions tracker_options = site.tracking;
  tracker_options.person_diameter_m += 2 * site.blobs.group_radius_m;
  std::vector<ObjectDetector::CameraView> views;
  for (const auto& c : cams) views.push_back({c.cam->camera.get(), &c.cam->mask});
  ObjectDetector detector(site.blobs, tracker_options, site.plane_height_m, std::move(views));
  DetectedObjects objects;
  const OccupancyMap& grown = objects.grown;

  // Tracking.
  std::optional<AnyTracker> tracker;
  std::optional<ZoneMonitor> zones;
  TrailHistory trails(site.tracking.trail_length);
  std::unique_ptr<AtomicFileWriter> tracks_file, mot_file, events_file;
  std::set<int64_t> track_ids;
  double last_track_time_s = -std::numeric_limits<double>::infinity();
  if (options.track) {
    OCCMAP_ASSIGN_OR_RETURN(AnyTracker t, AnyTracker::Create(tracker_options));
    tracker = std::move(t);
    OCCMAP_ASSIGN_OR_RETURN(ZoneMonitor z, ZoneMonitor::Create(site.tracking.zones, site.tracking.zone_count_every_frame));
    zones = std::move(z);
    OCCMAP_ASSIGN_OR_RETURN(tracks_file, AtomicFileWriter::Open(out / "tracks.jsonl"));
    OCCMAP_ASSIGN_OR_RETURN(mot_file, AtomicFileWriter::Open(out / "tracks_mot.csv"));
    if (!site.tracking.zones.empty()) {
      OCCMAP_ASSIGN_OR_RETURN(events_file, AtomicFileWriter::Open(out / "events.jsonl"));
    }
  }

  std::vector<bool> active(cams.size(), true);
  std::optional<int64_t> total;
  for (const auto& c : cams) {
    if (auto fc = c.source->frame_count()) total = total ? std::min(*total, *fc - options.start_frame) : *fc - options.start_frame;
  }
  if (options.max_frames > 0) total = total ? std::min(*total, options.max_frames) : options.max_frames;

  Status failure;  // an error that stopped the run, returned after the outputs are finalised
  int64_t next_frame_index = options.start_frame;
  // 1. The reader: one frame per active camera, by index or by timestamp, on its own thread
  // (decoding overlaps the processing of the previous frames), into a ring of kSlots frame
  // sets: memory stays flat. Returns false when the run ends (streams, a failure, the limit).
  // The reader alone touches the sources, the cameras' active flags and infos, `failure`,
  // stop_reason and decode_s until it is joined.
  double decode_s = 0;
  int64_t frames_read = 0;
  auto read_step = [&](FrameSet& set) -> bool {
    if (options.max_frames >= 0 && frames_read >= options.max_frames) return false;
    auto t0 = Clock::now();
    std::vector<std::pair<size_t, Status>> ended;  // camera, status (ok = end of stream)
    for (size_t n = 0; n < cams.size(); ++n) {
      CameraState& c = cams[n];
      c.present = false;
      if (!c.active) continue;
      const bool by_time = options.sync == FrameSync::kTimestamp && n > 0;
      if (!by_time) {
        auto got = c.source->Read(set.frames[n]);
        if (!got.ok() || !*got) {
          ended.emplace_back(n, got.ok() ? Status::Ok() : got.status());
          continue;
        }
        if (Status s = CheckFrameSize(c, set.frames[n]); !s.ok()) {
          ended.emplace_back(n, s);
          continue;
        }
        c.present = true;
      }
    }
    if (options.sync == FrameSync::kTimestamp && cams[0].present) {
      const double t_ref = set.frames[0].timestamp_s;
      if (std::isnan(t_ref)) {
        failure = InvalidInput(fmt::format("camera {}: {} has no timestamps; synchronise by frame index", cams[0].cam->id,
                                           cams[0].source->Describe()));
        return false;
      }
      for (size_t n = 1; n < cams.size(); ++n) {
        CameraState& c = cams[n];
        if (!c.active) continue;
        while (true) {
          if (!c.has_lookahead) {
            auto got = c.source->Read(c.lookahead);
            if (!got.ok() || !*got) {
              ended.emplace_back(n, got.ok() ? Status::Ok() : got.status());
              break;
            }
            if (std::isnan(c.lookahead.timestamp_s)) {
              ended.emplace_back(n, InvalidInput(fmt::format("camera {}: {} has no timestamps; synchronise by frame index",
                                                             c.cam->id, c.source->Describe())));
              break;
            }
            c.has_lookahead = true;
          }
          const double dt = c.lookahead.timestamp_s - t_ref;
          if (dt < -options.sync_tolerance_s) {  // too old: drop it
            c.has_lookahead = false;
            continue;
          }
          if (dt <= options.sync_tolerance_s) {  // close enough: use it for this instant
            std::swap(set.frames[n], c.lookahead);
            c.has_lookahead = false;
            if (Status s = CheckFrameSize(c, set.frames[n]); !s.ok()) {
              ended.emplace_back(n, s);
              break;
            }
            c.present = true;
          }
          break;  // in the future: no frame of this camera for this instant
        }
      }
    }
    decode_s += Since(t0);
    if (!ended.empty()) {
      size_t active_left = 0;
      for (const auto& c : cams) active_left += c.active;
      bool stop = ended.size() == active_left || options.on_camera_failure == OnCameraFailure::kStop;
      const bool all_ended = ended.size() == active_left;
      for (const auto& [n, status] : ended) {
        CameraState& c = cams[n];
        if (!all_ended || !status.ok()) {  // a normal end of every stream is not news
          c.info.ended_at_frame = next_frame_index;
          c.info.end_reason = status.ok() ? "end of stream" : status.message();
        }
        if (!status.ok() && options.on_camera_failure == OnCameraFailure::kStop && failure.ok()) {
          failure = status.WithContext(fmt::format("camera {} at frame {}", c.cam->id, next_frame_index));
        }
        c.active = false;
        c.present = false;
      }
      if (options.sync == FrameSync::kTimestamp && !cams[0].active) stop = true;  // the reference ended
      if (stop) {
        if (all_ended) {
          summary.stop_reason = "end of streams";
        } else {
          summary.stop_reason = fmt::format("camera {} ended at frame {}", cams[ended[0].first].cam->id, next_frame_index);
        }
        return false;
      }
    }
    set.frame_index = next_frame_index++;
    for (size_t n = 0; n < cams.size(); ++n) set.active[n] = cams[n].active && cams[n].present;
    ++frames_read;
    return true;
  };

  constexpr int kSlots = 3;
  std::vector<FrameSet> slots(kSlots);
  for (FrameSet& set : slots) {
    set.frames.resize(cams.size());
    set.active.assign(cams.size(), false);
  }
  SlotQueue free_slots, filled_slots;
  for (int k = 0; k < kSlots; ++k) free_slots.Push(k);
  std::atomic<bool> stop_reading{false};
  std::thread reader([&] {
    while (true) {
      const int slot = free_slots.Pop();
      if (stop_reading.load() || !read_step(slots[slot])) break;
      filled_slots.Push(slot);
    }
    filled_slots.Push(-1);  // the end
  });
  // Whatever way the processing loop leaves (an output error returns early), the reader is
  // told to stop, woken, and joined before the sources it uses are destroyed.
  struct ReaderGuard {
    std::thread& thread;
    std::atomic<bool>& stop;
    SlotQueue& free_slots;
    ~ReaderGuard() {
      if (!thread.joinable()) return;
      stop = true;
      free_slots.Push(0);
      thread.join();
    }
  } reader_guard{reader, stop_reading, free_slots};

  while (true) {
    const int slot = filled_slots.Pop();
    if (slot < 0) break;
    FrameSet& set = slots[slot];
    const std::vector<Frame>& frames = set.frames;
    const int64_t frame_index_now = set.frame_index;
    active = set.active;
    auto t0 = Clock::now();

    // 2. Change detection, cameras in parallel, into the global change buffer (or fused
    // with the fusion itself, FastFusion::Fuse, when nothing else needs the changes).
    const bool all_active = std::all_of(active.begin(), active.end(), [](bool a) { return a; });
    const bool fused_now = fully_fused && all_active;
    auto detect_changes = [&] {
      ParallelFor(ctx, 0, static_cast<int64_t>(cams.size()), [&](int64_t b, int64_t e, int) {
        for (int64_t n = b; n < e; ++n) {
          CameraState& c = cams[n];
          if (!active[n]) continue;
          const ImageSize size = c.cam->camera->image_size();
          ImageView<uint8_t> slice(changes.data() + lut.pixel_offset(static_cast<int>(n)), size.width, size.height,
                                   size.width);
          const int r = site.detection.tolerance_px;
          ImageView<uint8_t> target = r > 0 ? c.raw_changes.view() : slice;
          if (c.is_mask) {
            MaskToChanges(frames[n].gray.view(), target);
          } else if (colour) {
            DetectChangesRgb(frames[n].rgb.view(), c.background_rgb.view(), site.detection.threshold, target);
          } else {
            DetectChangesGray(frames[n].gray.view(), c.background_gray.view(), site.detection.threshold, target);
          }
          if (r > 0) DilateChanges(c.raw_changes.view(), r, slice, c.dilate_scratch);
        }
      });
    };
    t0 = Clock::now();
    if (!fused_now) detect_changes();
    summary.detect_s += Since(t0);

    // 3. Fusion and blobs.
    t0 = Clock::now();
    if (fused_now) {
      for (size_t n = 0; n < cams.size(); ++n) {
        frame_views[n] = frames[n].gray.view();
        background_views[n] = cams[n].background_gray.view();
      }
      fast->Fuse(frame_views, background_views, site.detection.threshold, ctx, map);
    } else if (paper_and && all_active) {
      fast->FuseChanges(changes, ctx, map);
    } else {
      fusion.Fuse(changes, active, site.fusion, map);
    }
    summary.fuse_s += Since(t0);
    t0 = Clock::now();
    // Detections (BlobSettings in site.h): fragments grouped, described by their footprint,
    // too-small groups dropped, large ones split at their necks, ghosts removed. The tracker
    // gets the groups of the grown map (it splits them itself, guided by its tracks).
    detector.Detect(map, active, objects);
    const std::vector<Blob>& blobs = objects.detections;
    const std::vector<Blob>& groups = objects.groups;
    summary.blobs_s += Since(t0);
    const int64_t frame_index = frame_index_now;
    const double time_s = std::isnan(frames[0].timestamp_s) ? static_cast<double>(frame_index) / fps
                                                            : frames[0].timestamp_s;

    // 3b. Tracking (the tracker needs strictly increasing times: a repeated timestamp, as some
    // streams give, is nudged forward by a microsecond).
    t0 = Clock::now();
    std::vector<Track> tracks;
    if (tracker) {
      const double track_time_s = std::max(time_s, last_track_time_s + 1e-6);
      last_track_time_s = track_time_s;
      OCCMAP_ASSIGN_OR_RETURN(tracks, tracker->Update(groups, grown, track_time_s));
      trails.Update(tracks);
      for (const Track& t : tracks) track_ids.insert(t.id);
      OCCMAP_RETURN_IF_ERROR(tracks_file->Append(TracksJsonLine(frame_index, time_s, tracks) + "\n"));
      OCCMAP_RETURN_IF_ERROR(mot_file->Append(MotGroundPlaneRows(frame_index, tracks)));
      const ZoneFrame z = zones->Update(frame_index, time_s, tracks);
      for (const ZoneEvent& e : z.events) {
        OCCMAP_RETURN_IF_ERROR(events_file->Append(ZoneEventJsonLine(e) + "\n"));
        ++summary.zone_events;
      }
    }
    summary.track_s += Since(t0);

    // 4. Outputs.
    t0 = Clock::now();
    json line = {{"frame", frame_index}, {"time_s", std::round(time_s * 1e6) / 1e6}, {"blobs", json::array()}};
    for (const auto& b : blobs) line["blobs"].push_back(BlobJson(b));
    OCCMAP_RETURN_IF_ERROR(detections->Append(line.dump() + "\n"));
    summary.blob_counts.push_back(blobs.size());
    if (occupancy_video || options.occupancy_pngs) {
      const Image<uint8_t> gray = map.ToGrayImage();
      if (occupancy_video) OCCMAP_RETURN_IF_ERROR(occupancy_video->Write(OccupancyPicture(gray, map_scale).view()));
      if (options.occupancy_pngs) {
        OCCMAP_RETURN_IF_ERROR(WritePng(out / "occupancy" / fmt::format("{:06d}.png", frame_index), gray.view()));
      }
    }
    std::vector<MosaicCamera> tiles;
    for (size_t n = 0; n < cams.size(); ++n) {
      const CameraState& c = cams[n];
      const ImageSize size = c.cam->camera->image_size();
      MosaicCamera t;
      t.id = c.cam->id;
      t.active = active[n];
      if (active[n]) {
        t.gray = frames[n].gray.view();
        if (c.is_mask && (frames[n].gray.width() != size.width || frames[n].gray.height() != size.height)) {
          t.gray = ImageView<const uint8_t>(changes.data() + lut.pixel_offset(static_cast<int>(n)), size.width, size.height, size.width);
        }
        t.changes = ImageView<const uint8_t>(changes.data() + lut.pixel_offset(static_cast<int>(n)), size.width,
                                             size.height, size.width);
        if (t.gray.width() != t.changes.width()) t.changes = {};
      }
      tiles.push_back(t);
    }
    if (mosaic_video || best_mosaic.empty() || blobs.size() > best_blobs) {
      if (fused_now) detect_changes();  // the changes of this frame, for its picture
      Image<Rgb8> picture = mosaic.Render(tiles, map, blobs, frame_index, time_s, tracks, trails.Trails());
      if (mosaic_video) OCCMAP_RETURN_IF_ERROR(mosaic_video->Write(picture.view()));
      if (best_mosaic.empty() || blobs.size() > best_blobs) {
        best_mosaic = std::move(picture);
        best_blobs = blobs.size();
      }
    }
    summary.output_s += Since(t0);
    ++summary.frames;
    if (progress) progress({summary.frames, total, Since(t_start)});
    free_slots.Push(slot);
  }
  reader.join();  // it has pushed the end: the sources, flags and infos are ours again
  summary.decode_s = decode_s;
  if (summary.stop_reason.empty()) summary.stop_reason = options.max_frames > 0 && summary.frames >= options.max_frames ? "frame limit" : "stopped";
  if (!failure.ok()) summary.stop_reason = failure.message();

  // Finalise every output, also when a camera failed: frames processed are never lost.
  OCCMAP_RETURN_IF_ERROR(detections->Commit());
  summary.outputs.push_back((out / "detections.jsonl").string());
  if (occupancy_video) {
    OCCMAP_RETURN_IF_ERROR(occupancy_video->Close());
    summary.outputs.push_back((out / "occupancy.mp4").string());
  }
  if (mosaic_video) {
    OCCMAP_RETURN_IF_ERROR(mosaic_video->Close());
    summary.outputs.push_back((out / "mosaic.mp4").string());
  }
  if (tracks_file) {
    OCCMAP_RETURN_IF_ERROR(tracks_file->Commit());
    OCCMAP_RETURN_IF_ERROR(mot_file->Commit());
    summary.outputs.push_back((out / "tracks.jsonl").string());
    summary.outputs.push_back((out / "tracks_mot.csv").string());
  }
  if (events_file) {
    OCCMAP_RETURN_IF_ERROR(events_file->Commit());
    summary.outputs.push_back((out / "events.jsonl").string());
  }
  summary.tracks = static_cast<int64_t>(track_ids.size());
  if (!best_mosaic.empty()) {
    OCCMAP_RETURN_IF_ERROR(WritePng(out / "mosaic.png", best_mosaic.view()));
    summary.outputs.push_back((out / "mosaic.png").string());
  }
  summary.seconds = Since(t_start);
  summary.frames_per_second = summary.seconds > 0 ? static_cast<double>(summary.frames) / summary.seconds : 0;
  for (const auto& c : cams) summary.cameras.push_back(c.info);

  json j;
  j["site"] = site.name;
  j["frames"] = summary.frames;
  j["start_frame"] = options.start_frame;
  j["seconds"] = summary.seconds;
  j["frames_per_second"] = summary.frames_per_second;
  j["stage_seconds"] = {{"decode", summary.decode_s}, {"detect", summary.detect_s}, {"fuse", summary.fuse_s},
                        {"blobs", summary.blobs_s}, {"track", summary.track_s}, {"output", summary.output_s},
                        {"tables", summary.lut_seconds}};
  if (options.track) {
    j["tracking"] = {{"algorithm", std::string(ToString(site.tracking.algorithm))},
                     {"tracks", summary.tracks},
                     {"zones", site.tracking.zones.size()},
                     {"zone_events", summary.zone_events}};
  }
  j["stop_reason"] = summary.stop_reason;
  j["settings"] = {{"threshold", site.detection.threshold},
                   {"colour", site.detection.colour},
                   {"tolerance_px", site.detection.tolerance_px},
                   {"fusion", ToString(site.fusion.method)},
                   {"max_free_views", site.fusion.max_free_views},
                   {"sync", options.sync == FrameSync::kIndex ? "index" : "timestamp"},
                   {"on_camera_failure", options.on_camera_failure == OnCameraFailure::kStop ? "stop" : "continue"},
                   {"blobs", {{"group_radius_m", site.blobs.group_radius_m}, {"min_area_m2", site.blobs.min_area_m2},
                              {"split", site.blobs.split}, {"remove_ghosts", site.blobs.remove_ghosts},
                              {"occluder_height_m", site.blobs.occluder_height_m}}},
                   {"threads", ctx.num_threads()},
                   {"grid", {{"origin_m", {site.grid.origin_x_m, site.grid.origin_y_m}},
                             {"cells", {site.grid.cells_x, site.grid.cells_y}},
                             {"cell_size_m", site.grid.cell_size_m}}}};
  j["tables"] = {{"cache", summary.lut_cache}, {"seconds", summary.lut_seconds}};
  json cj = json::array();
  for (const auto& c : summary.cameras) {
    json e = {{"id", c.id}, {"source", c.source}, {"background", c.background}};
    if (c.ended_at_frame) e["ended_at_frame"] = *c.ended_at_frame;
    if (!c.end_reason.empty()) e["end_reason"] = c.end_reason;
    cj.push_back(e);
  }
  j["cameras"] = cj;
  size_t max_blobs = 0, total_blobs = 0;
  for (size_t b : summary.blob_counts) {
    max_blobs = std::max(max_blobs, b);
    total_blobs += b;
  }
  j["blobs"] = {{"total", total_blobs},
                {"max_per_frame", max_blobs},
                {"mean_per_frame", summary.frames > 0 ? static_cast<double>(total_blobs) / static_cast<double>(summary.frames) : 0.0}};
  summary.outputs.push_back((out / "summary.json").string());
  j["outputs"] = summary.outputs;
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(out / "summary.json", j.dump(2) + "\n"));
  if (!failure.ok()) return failure;
  return summary;
}

}  // namespace occmap
