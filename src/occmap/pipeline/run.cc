#include "occmap/pipeline/run.h"

#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
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
#include "occmap/objects/object_detector.h"
#include "occmap/pipeline/mosaic.h"
#include "occmap/pipeline/stage_queue.h"
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
  // The adaptive model (site.backgrounds.adaptive): learned or given, kept up to date.
  std::unique_ptr<BackgroundModel> model;
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

// A background picture's size against the camera's image size.
Status CheckBackgroundSize(const SiteCamera& cam, int width, int height, const fs::path& path) {
  const ImageSize size = cam.camera->image_size();
  if (width == size.width && height == size.height) return Status::Ok();
  return InvalidInput(fmt::format("camera {}: background '{}' is {}x{}, expected the image size {}x{}", cam.id,
                                  path.string(), width, height, size.width, size.height));
}

// The part of an estimated background's cache key every estimate depends on (the source and its
// modification time, the start frame, colour, the size); callers add their own settings.
Hasher BackgroundKey(std::string_view version, const Site& site, const SiteCamera& cam, int64_t start_frame,
                     bool colour) {
  Hasher h;
  h.Add(version);
  h.Add(site.name);
  h.Add(cam.id);
  h.Add(cam.source.location);
  h.AddPod(start_frame);
  h.AddPod(colour);
  const ImageSize size = cam.camera->image_size();
  h.AddPod(size.width);
  h.AddPod(size.height);
  std::error_code ec;
  if (const auto mtime = fs::last_write_time(cam.source.location, ec); !ec) h.AddPod(mtime.time_since_epoch().count());
  return h;
}

YuvView FrameYuv(const Frame& f) {
  if (f.u.empty()) return {f.gray.view(), {}, {}};
  return {f.gray.view(), f.u.view(), f.v.view()};
}

// A background of the adaptive model as a picture: RGB from luma and chroma, or grey.
Status WriteYuvPng(const fs::path& path, const YuvImage& yuv) {
  if (!yuv.has_chroma()) return WritePng(path, yuv.y.view());
  return WritePng(path, RgbFromYuv(yuv.view()).view());
}

// The adaptive model's background of a camera: given (a picture), reused from the cache, or
// learned from the busy video (site.backgrounds: K frames over learn_s seconds).
Status PrepareAdaptiveBackground(const Site& site, const RunOptions& options, bool chroma,
                                 const FrameSourceOptions& src_opts, CameraState& c) {
  const SiteCamera& cam = *c.cam;
  const BackgroundOptions& bo = site.backgrounds;
  const ImageSize size = cam.camera->image_size();
  YuvImage background;
  std::optional<BackgroundLearner::Alternative> alternative;
  std::optional<BackgroundLearner> learned_from;  // its samples warm the shadow look up
  auto check_size = [&](int w, int h, const fs::path& path) { return CheckBackgroundSize(cam, w, h, path); };
  double fps = 10;
  if (cam.background) {
    if (chroma) {
      auto rgb = ReadRgbImage(*cam.background);
      if (!rgb.ok()) return rgb.status().WithContext(fmt::format("camera {}: background", cam.id));
      OCCMAP_RETURN_IF_ERROR(check_size(rgb->width(), rgb->height(), *cam.background));
      background = YuvFromRgb(rgb->view());
    } else {
      auto gray = ReadGrayImage(*cam.background);
      if (!gray.ok()) return gray.status().WithContext(fmt::format("camera {}: background", cam.id));
      OCCMAP_RETURN_IF_ERROR(check_size(gray->width(), gray->height(), *cam.background));
      background.y = std::move(gray).value();
    }
    c.info.background = fmt::format("given: {}", cam.background->string());
    if (auto f = c.source->fps()) fps = *f;
  } else {
    Hasher h = BackgroundKey("adaptive-background-v3", site, cam, options.start_frame, chroma);
    h.Add(ToString(bo.learning));
    h.AddPod(bo.learn_s);
    h.AddPod(bo.learn_samples);
    h.AddPod(bo.mode_radius);
    std::error_code ec;
    const fs::path cached = options.cache_dir.empty() ? fs::path()
                                                      : options.cache_dir / "backgrounds" /
                                                            fmt::format("{}-{}-{:016x}", site.name, cam.id, h.Digest());
    auto plane_path = [&](const char* plane) { return fs::path(cached.string() + "-" + plane + ".png"); };
    bool reused = false;
    if (!cached.empty() && fs::exists(plane_path("y"), ec)) {
      auto y = ReadGrayImage(plane_path("y"));
      auto u = chroma ? ReadGrayImage(plane_path("u")) : Result<Image<uint8_t>>(Image<uint8_t>());
      auto v = chroma ? ReadGrayImage(plane_path("v")) : Result<Image<uint8_t>>(Image<uint8_t>());
      auto alt_y = ReadGrayImage(plane_path("alt-y"));
      auto alt_n = ReadGrayImage(plane_path("alt-n"));
      if (y.ok() && u.ok() && v.ok() && y->width() == size.width && y->height() == size.height) {
        background.y = std::move(y).value();
        background.u = std::move(u).value();
        background.v = std::move(v).value();
        if (alt_y.ok() && alt_n.ok() && alt_y->width() == size.width && alt_n->width() == size.width &&
            alt_y->height() == size.height && alt_n->height() == size.height) {
          alternative.emplace();
          alternative->levels.y = std::move(alt_y).value();
          alternative->support = std::move(alt_n).value();
        }
        reused = true;
        c.info.background = fmt::format("reused: {}", plane_path("y").string());
      }
    }
    OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> src, OpenFrameSource(cam.source, src_opts));
    if (auto f = src->fps()) fps = *f;
    if (!reused) {
      OCCMAP_RETURN_IF_ERROR(src->SkipTo(options.start_frame));
      const int64_t window = std::max<int64_t>(1, std::llround(bo.learn_s * fps));
      const int64_t step = std::max<int64_t>(1, window / bo.learn_samples);
      BackgroundLearner& learner = learned_from.emplace(size.width, size.height, chroma, bo.learn_samples);
      Frame f;
      for (int64_t read = 0; read < window && learner.count() < bo.learn_samples; ++read) {
        OCCMAP_ASSIGN_OR_RETURN(bool got, src->Read(f));
        if (!got) break;
        if (read % step != 0) continue;
        OCCMAP_RETURN_IF_ERROR(CheckFrameSize(c, f).WithContext(fmt::format("camera {}", cam.id)));
        learner.Add(FrameYuv(f));
      }
      if (learner.count() == 0) {
        return InvalidInput(fmt::format("camera {}: {} has no frames to learn a background from", cam.id, src->Describe()));
      }
      if (bo.learning == BackgroundLearning::kMode) alternative.emplace();
      background = learner.Learn(bo.learning, bo.mode_radius, alternative ? &*alternative : nullptr);
      c.info.background = fmt::format("learned: {} of {} frames over {:.1f} s", ToString(bo.learning), learner.count(),
                                      static_cast<double>(std::min(window, learner.count() * step)) / fps);
      if (!cached.empty()) {
        OCCMAP_RETURN_IF_ERROR(EnsureDirectory(cached.parent_path()));
        if (chroma) {
          OCCMAP_RETURN_IF_ERROR(WritePng(plane_path("u"), background.u.view()));
          OCCMAP_RETURN_IF_ERROR(WritePng(plane_path("v"), background.v.view()));
        }
        if (alternative) {
          OCCMAP_RETURN_IF_ERROR(WritePng(plane_path("alt-y"), alternative->levels.y.view()));
          OCCMAP_RETURN_IF_ERROR(WritePng(plane_path("alt-n"), alternative->support.view()));
        }
        OCCMAP_RETURN_IF_ERROR(WritePng(plane_path("y"), background.y.view()));  // last: marks the set complete
      }
    }
  }
  c.model = std::make_unique<BackgroundModel>(bo, fps);
  c.model->Reset(background);
  if (alternative) {
    c.model->SetAlternative(*alternative, static_cast<int>(std::ceil(bo.alternative_min_share * bo.learn_samples)));
  }
  if (learned_from && bo.shadows.enabled && bo.shadows.learn) {
    // The shadow look from the learning samples, so that the first frames are tested with it.
    std::vector<YuvView> samples;
    for (int k = 0; k < learned_from->count(); ++k) samples.push_back(learned_from->Sample(k));
    c.model->WarmUp(samples, site.detection.threshold);
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
  auto check_size = [&](int w, int h, const fs::path& path) { return CheckBackgroundSize(cam, w, h, path); };
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
  Hasher h = BackgroundKey("background-v2", site, cam, options.start_frame, colour);
  h.AddPod(options.background_frames);
  h.AddPod(options.background_step);
  std::error_code ec;
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

json BlobJson(const Detection& b) {
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

// One slot of the ring: the frames of all cameras for one instant (filled by the reader) and
// what the fusion stage makes of them (read by the post stage). Buffers are reused.
struct FrameSet {
  int64_t frame_index = 0;
  std::vector<Frame> frames;     // per camera
  std::vector<bool> active;      // the camera's frame is there (stream not ended, synchronised)
  OccupancyMap map;              // the fused map of this instant
  std::vector<uint8_t> changes;  // the change buffer (global pixel ids), allocated when first needed
  bool changes_ready = false;    // `changes` holds this instant's changes (not so when fully fused)
  ChangeBits change_bits;        // FastFusion::FuseTolerant's changes after the tolerance, as bits
  bool bits_ready = false;       // `change_bits` holds this instant's changes
  std::vector<Image<uint8_t>> change_pictures;  // --change-pngs: per camera, 255 changed (before the tolerance)
  OccupancyMap column_map;
  std::vector<ExplainedPerson> people;
};

// What the writer stage writes for one frame, in frame order.
struct FrameOutput {
  int64_t frame = 0;
  std::string detections_line, tracks_line, mot_rows, event_lines;
  Image<uint8_t> occupancy;  // the map's grey picture, when occupancy.mp4 or the PNGs are on
  Image<Rgb8> mosaic;        // when mosaic.mp4 is on
  std::vector<Image<uint8_t>> changes;  // --change-pngs, per camera (empty: inactive)
};
// Frames whose outputs may wait for the writer (each up to a mosaic picture, ~3 MB).
constexpr size_t kOutputQueue = 4;
// Frames left out of the steady-state rate: decoders filling their frame threads, first touches.
constexpr int64_t kWarmUpFrames = 10;

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
  return Status::Ok();
}

Result<RunSummary> RunSite(const Site& site, const RunOptions& options, Context& ctx, const ProgressCallback& progress) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  OCCMAP_RETURN_IF_ERROR(site.detection.Validate());
  OCCMAP_RETURN_IF_ERROR(site.fusion.Validate(static_cast<int>(site.cameras.size())));
  const auto t_start = Clock::now();
  RunSummary summary;
  OCCMAP_RETURN_IF_ERROR(site.backgrounds.Validate());
  const bool adaptive = site.backgrounds.adaptive;
  // The adaptive model reads colour as the decoder's chroma planes; the paper's test as RGB.
  const bool colour = site.detection.colour && !adaptive;
  const bool chroma = site.detection.colour && adaptive;

  // Sources and backgrounds.
  std::vector<CameraState> cams(site.cameras.size());
  FrameSourceOptions src_opts;
  src_opts.colour = colour;
  src_opts.chroma = chroma;
  // The cameras decode side by side (the reader stage below): each decoder gets its share of the
  // threads, at least one. A background estimated from one camera's frames uses them all.
  src_opts.decoder_threads = DecoderThreadsPerCamera(ctx.num_threads(), static_cast<int>(site.cameras.size()));
  FrameSourceOptions background_opts = src_opts;
  background_opts.decoder_threads = ctx.num_threads();
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
    if (adaptive && !c.is_mask) {
      OCCMAP_RETURN_IF_ERROR(PrepareAdaptiveBackground(site, options, chroma, background_opts, c));
    } else {
      OCCMAP_RETURN_IF_ERROR(PrepareBackground(site, options, colour, background_opts, c));
    }
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
      const ConsensusResult r = ResolveLearnedBackgrounds(lut, models, site.detection.threshold);
      summary.consensus_pixels_checked = r.pixels_checked;
      summary.consensus_pixels_swapped = r.pixels_swapped;
    }
  }
  Fusion fusion(lut);
  const bool paper_and = site.fusion.method == FusionMethod::kImageBased && site.fusion.max_free_views == 0;
  // The paper's AND with every camera active takes the fast path (its tables are built only
  // when the site's fusion settings can use them).
  std::optional<FastFusion> fast;
  if (paper_and) fast.emplace(lut);
  bool any_mask_source = false;
  for (const auto& c : site.cameras) any_mask_source |= c.source.kind == FrameSourceSpec::Kind::kMasks;
  // Fully fused (no change buffer at all) when nothing needs the per-pixel changes: the paper's
  // AND on grey frames, no mask sources, no mosaic video (the mosaic picture of the best frame
  // gets its changes computed when it is drawn); without tolerance (Fuse) or with a small one
  // folded in (FuseTolerant: the changes exist only as bits, which the elevated check reads).
  // People (the site's `people:` section): the column fusion, and the explanation of the views,
  // on the change buffer after the floor AND.
  const PeopleOptions& people = site.people;
  const bool people_detector = people.enabled && people.detector != PeopleDetector::kFloor;
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
  const bool fusable = !people_detector && paper_and && !colour && !adaptive && !any_mask_source && !options.mosaic_video &&
                       !options.change_pngs;
  const bool fully_fused = fusable && site.detection.tolerance_px == 0;
  const bool tolerant_fused = fusable && site.detection.tolerance_px >= 1 &&
                              site.detection.tolerance_px <= FastFusion::kMaxFusedTolerancePx;
  std::vector<ImageView<const uint8_t>> frame_views(site.cameras.size()), background_views(site.cameras.size());

  // Outputs.
  const fs::path out = options.out_dir;
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out));
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
  if (options.occupancy_pngs) OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / "occupancy"));
  if (options.change_pngs) {
    for (const auto& c : cams) OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / "changes" / c.cam->id));
  }
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

  std::vector<ObjectDetector::CameraView> views;
  for (const auto& c : cams) views.push_back({c.cam->camera.get(), &c.cam->mask});
  ObjectDetector detector(site.objects, site.plane_height_m, std::move(views));
  DetectedObjects objects;

  // Tracking.
  std::optional<AnyTracker> tracker;
  std::optional<ZoneMonitor> zones;
  TrailHistory trails(site.tracking.trail_length);
  std::unique_ptr<AtomicFileWriter> tracks_file, mot_file, events_file;
  std::set<int64_t> track_ids;
  double last_track_time_s = -std::numeric_limits<double>::infinity();
  if (options.track) {
    OCCMAP_ASSIGN_OR_RETURN(AnyTracker t, AnyTracker::Create(site.tracking));
    tracker = std::move(t);
    OCCMAP_ASSIGN_OR_RETURN(ZoneMonitor z, ZoneMonitor::Create(site.tracking.zones, site.tracking.zone_count_every_frame));
    zones = std::move(z);
    OCCMAP_ASSIGN_OR_RETURN(tracks_file, AtomicFileWriter::Open(out / "tracks.jsonl"));
    OCCMAP_ASSIGN_OR_RETURN(mot_file, AtomicFileWriter::Open(out / "tracks_mot.csv"));
    if (!site.tracking.zones.empty()) {
      OCCMAP_ASSIGN_OR_RETURN(events_file, AtomicFileWriter::Open(out / "events.jsonl"));
    }
  }

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
  // One decoding thread per camera (the reader and cameras - 1 more): decoders without frame
  // threads, side by side, cost less CPU per frame than frame-threaded ones taking turns
  // (lab bench, 4 x 640x480 H.264 on 2 cores: 2.6 against 3.3 ms of CPU per frame set).
  Context decode_ctx(static_cast<int>(cams.size()));
  std::vector<size_t> to_read;
  std::vector<char> read_got(cams.size(), 0);
  std::vector<Status> read_status(cams.size());
  auto read_step = [&](FrameSet& set) -> bool {
    if (options.max_frames >= 0 && frames_read >= options.max_frames) return false;
    auto t0 = Clock::now();
    std::vector<std::pair<size_t, Status>> ended;  // camera, status (ok = end of stream)
    // The cameras read by index (all of them, or camera 0 under timestamp sync) decode in
    // parallel, one task per camera on decode_ctx's threads.
    to_read.clear();
    for (size_t n = 0; n < cams.size(); ++n) {
      cams[n].present = false;
      if (cams[n].active && !(options.sync == FrameSync::kTimestamp && n > 0)) to_read.push_back(n);
    }
    decode_ctx.pool().Run(static_cast<int>(to_read.size()), [&](int task, int) {
      const size_t n = to_read[task];
      auto got = cams[n].source->Read(set.frames[n]);
      read_got[n] = got.ok() && *got;
      read_status[n] = !got.ok() ? got.status() : read_got[n] ? CheckFrameSize(cams[n], set.frames[n]) : Status::Ok();
    });
    for (const size_t n : to_read) {
      if (!read_got[n] || !read_status[n].ok()) {
        ended.emplace_back(n, read_status[n]);
        continue;
      }
      cams[n].present = true;
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

  // The stages, each on its own thread, joined by bounded queues (stage_queue.h): memory stays
  // flat however long the run, and the stages overlap, so a run over video files is limited by
  // decoding rather than by the work of any one stage.
  //   reader (1.)     decodes one frame set into a free slot of the ring        -> filled_slots
  //   this thread     change detection and fusion into the slot's map (2.-3.)   -> post
  //   post            detections, tracking, the pictures that need the frames;
  //                   gives the slot back to the reader                          -> writer
  //   writer          appends the text outputs, encodes the videos, writes PNGs
  // A stage that fails stops the reader; the others drain their queues and the first error is
  // returned after the frames before it are committed (a failed write: nothing is committed).
  // The fusion alone uses ctx's pool (ParallelFor); the other stages are single-threaded.
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

  // Writer stage: the one place the output files are touched until it is finished.
  double write_s = 0;
  StageWorker<FrameOutput> writer(kOutputQueue, [&](FrameOutput& o) -> Status {
    const auto t0 = Clock::now();
    OCCMAP_RETURN_IF_ERROR(detections->Append(o.detections_line));
    if (tracks_file) {
      OCCMAP_RETURN_IF_ERROR(tracks_file->Append(o.tracks_line));
      OCCMAP_RETURN_IF_ERROR(mot_file->Append(o.mot_rows));
    }
    if (events_file && !o.event_lines.empty()) OCCMAP_RETURN_IF_ERROR(events_file->Append(o.event_lines));
    if (occupancy_video) OCCMAP_RETURN_IF_ERROR(occupancy_video->Write(OccupancyPicture(o.occupancy, map_scale).view()));
    if (options.occupancy_pngs) {
      OCCMAP_RETURN_IF_ERROR(WritePng(out / "occupancy" / fmt::format("{:06d}.png", o.frame), o.occupancy.view()));
    }
    if (mosaic_video) OCCMAP_RETURN_IF_ERROR(mosaic_video->Write(o.mosaic.view()));
    for (size_t n = 0; n < o.changes.size(); ++n) {
      if (o.changes[n].empty()) continue;
      OCCMAP_RETURN_IF_ERROR(WritePng(out / "changes" / cams[n].cam->id / fmt::format("{:06d}.png", o.frame), o.changes[n].view()));
    }
    write_s += Since(t0);
    return Status::Ok();
  });

  // The change buffer of one camera of a slot, from its frame (or mask).
  auto camera_changes = [&](FrameSet& set, size_t n, Image<uint8_t>& raw, std::vector<uint8_t>& scratch) {
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
    if (r > 0) DilateChanges(raw.view(), r, slice, scratch);
  };
  auto ensure_changes = [&](FrameSet& set) {
    if (set.changes.size() != static_cast<size_t>(lut.total_pixels())) set.changes.assign(lut.total_pixels(), 0);
  };

  // The mosaic picture of a frame set: its frames, their changes (computed here when the frame
  // was fully fused), the map, detections and tracks.
  std::vector<Image<uint8_t>> post_raw(cams.size());
  std::vector<std::vector<uint8_t>> post_scratch(cams.size());
  auto render_mosaic = [&](FrameSet& set, const std::vector<Detection>& blobs, double time_s,
                           const std::vector<Track>& tracks, const std::vector<Trail>& trail_list) {
    const std::vector<Frame>& frames = set.frames;
    const std::vector<bool>& active = set.active;
    if (!set.changes_ready) {  // fully fused: the changes of this frame, for its picture
      ensure_changes(set);
      for (size_t n = 0; n < cams.size(); ++n) {
        if (active[n]) camera_changes(set, n, post_raw[n], post_scratch[n]);
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
    return mosaic.Render(tiles, set.map, blobs, set.frame_index, time_s, tracks, trail_list);
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
  double post_output_s = 0;
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
        summary.blobs_s += Since(t0);
        const int64_t frame_index = set.frame_index;
        const double time_s = std::isnan(frames[0].timestamp_s) ? static_cast<double>(frame_index) / fps
                                                                : frames[0].timestamp_s;
        FrameOutput output;
        output.frame = frame_index;

        // 3b. Tracking (the tracker needs strictly increasing times: a repeated timestamp, as
        // some streams give, is nudged forward by a microsecond).
        t0 = Clock::now();
        std::vector<Track> tracks;
        if (tracker) {
          const double track_time_s = std::max(time_s, last_track_time_s + 1e-6);
          last_track_time_s = track_time_s;
          OCCMAP_ASSIGN_OR_RETURN(tracks, tracker->Update(objects, track_time_s));
          // Zones count every live track; the outputs get the reported ones.
          const ZoneFrame z = zones->Update(frame_index, time_s, tracks);
          std::erase_if(tracks, [&](const Track& t) { return !IsReported(t, site.tracking.report_coasting_s); });
          trails.Update(tracks);
          for (const Track& t : tracks) track_ids.insert(t.id);
          output.tracks_line = TracksJsonLine(frame_index, time_s, tracks) + "\n";
          output.mot_rows = MotGroundPlaneRows(frame_index, tracks);
          for (const ZoneEvent& e : z.events) {
            output.event_lines += ZoneEventJsonLine(e) + "\n";
            ++summary.zone_events;
          }
        }
        summary.track_s += Since(t0);

        // 4. Outputs: the text and pictures of this frame, written by the writer stage.
        t0 = Clock::now();
        json line = {{"frame", frame_index}, {"time_s", std::round(time_s * 1e6) / 1e6}, {"blobs", json::array()}};
        for (const auto& b : blobs) line["blobs"].push_back(BlobJson(b));
        output.detections_line = line.dump() + "\n";
        summary.blob_counts.push_back(blobs.size());
        if (occupancy_video || options.occupancy_pngs) output.occupancy = map.ToGrayImage();
        if (options.change_pngs) {
          output.changes.resize(cams.size());
          for (size_t n = 0; n < cams.size(); ++n) {
            if (active[n]) output.changes[n] = set.change_pictures[n];
          }
        }
        const bool first = mosaic_video ? best_mosaic.empty() : !best_frame.kept;
        const bool best = first || blobs.size() > best_blobs;
        if (mosaic_video) {
          Image<Rgb8> picture = render_mosaic(set, blobs, time_s, tracks, trails.Trails());
          if (best) {
            best_mosaic = picture;
            best_blobs = blobs.size();
          }
          output.mosaic = std::move(picture);
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
        post_output_s += Since(t0);
        if (!writer.Push(std::move(output))) return Internal("the writer stage stopped");
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
      if (stop_reading.load() || !read_step(slots[*slot])) break;
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
  int64_t last_frame_index = options.start_frame;
  if (adaptive) {
    std::vector<const CameraModel*> models;
    for (const auto& c : cams) models.push_back(c.cam->camera.get());
    ProtectionOptions po;
    po.person_height_m = site.backgrounds.person_height_m;
    protection.emplace(std::move(models), site.plane_height_m, po);
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
          if (active[n]) camera_changes(set, n, cams[n].raw_changes, cams[n].dilate_scratch);
        }
      });
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
    summary.detect_s += Since(t0);
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
    summary.fuse_s += Since(t0);
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
      summary.people_s += Since(t0);
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
        protection->AddPeople(people_positions, site.tracking.person_radius_m());
      }
      ParallelFor(ctx, 0, static_cast<int64_t>(cams.size()), [&](int64_t b, int64_t e, int) {
        for (int64_t n = b; n < e; ++n) {
          if (active[n] && cams[n].model) {
            cams[n].model->Update(FrameYuv(set.frames[n]), protection->image(static_cast<size_t>(n)).view(), set.frame_index);
          }
        }
      });
      last_frame_index = set.frame_index;
      summary.background_s += Since(t0);
    }
    post.Push(*slot);  // when it has failed, the slot goes straight back to the reader
  }
  reader.join();  // it has closed filled_slots: the sources, flags and infos are ours again
  const Status post_status = post.Finish();
  const Status writer_status = writer.Finish();
  summary.output_s = post_output_s + write_s;
  summary.decode_s = decode_s;
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
  // A failed write (or tracker) stops the run without committing anything: no output is ever
  // half-written, and the exit code says why.
  if (!writer_status.ok()) return writer_status;
  if (!post_status.ok()) return post_status;
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
  if (best_frame.kept) {
    best_mosaic =
        render_mosaic(best_frame.set, best_frame.detections, best_frame.time_s, best_frame.tracks, best_frame.trails);
  }
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
  j["startup_seconds"] = summary.startup_s;
  j["steady_state"] = {{"frames", summary.steady_frames}, {"seconds", summary.steady_seconds},
                       {"frames_per_second", summary.steady_fps}};
  j["stage_seconds"] = {{"decode", summary.decode_s}, {"detect", summary.detect_s}, {"fuse", summary.fuse_s},
                        {"blobs", summary.blobs_s}, {"track", summary.track_s}, {"output", summary.output_s},
                        {"background", summary.background_s}, {"people", summary.people_s},
                        {"tables", summary.lut_seconds}};
  if (options.track) {
    j["tracking"] = {{"algorithm", std::string(ToString(site.tracking.algorithm))},
                     {"tracks", summary.tracks},
                     {"zones", site.tracking.zones.size()},
                     {"zone_events", summary.zone_events}};
  }
  j["stop_reason"] = summary.stop_reason;
  if (adaptive) {
    const BackgroundOptions& bo = site.backgrounds;
    j["backgrounds"] = {{"adaptive", true}, {"learning", ToString(bo.learning)}, {"learn_s", bo.learn_s},
                        {"learn_samples", bo.learn_samples}, {"adapt_s", bo.adapt_s}, {"relight_s", bo.relight_s},
                        {"absorb_s", bo.absorb_s}, {"person_height_m", bo.person_height_m},
                        {"chroma", chroma}, {"chroma_threshold", bo.chroma_threshold},
                        {"shadows", {{"enabled", bo.shadows.enabled}, {"min_ratio", bo.shadows.min_ratio},
                                     {"max_ratio", bo.shadows.max_ratio}, {"max_channel_spread", bo.shadows.max_channel_spread},
                                     {"texture_radius_px", bo.shadows.texture_radius_px}}}};
  }
  j["settings"] = {{"threshold", site.detection.threshold},
                   {"colour", site.detection.colour},
                   {"tolerance_px", site.detection.tolerance_px},
                   {"fusion", ToString(site.fusion.method)},
                   {"max_free_views", site.fusion.max_free_views},
                   {"sync", options.sync == FrameSync::kIndex ? "index" : "timestamp"},
                   {"on_camera_failure", options.on_camera_failure == OnCameraFailure::kStop ? "stop" : "continue"},
                   {"blobs", {{"group_radius_m", site.objects.group_radius_m}, {"min_area_m2", site.objects.min_area_m2},
                              {"split", site.objects.split}, {"remove_ghosts", site.objects.remove_ghosts},
                              {"occluder_height_m", site.objects.occluder_height_m}}},
                   {"threads", ctx.num_threads()},
                   {"grid", {{"origin_m", {site.grid.origin_x_m, site.grid.origin_y_m}},
                             {"cells", {site.grid.cells_x, site.grid.cells_y}},
                             {"cell_size_m", site.grid.cell_size_m}}}};
  j["tables"] = {{"cache", summary.lut_cache}, {"seconds", summary.lut_seconds}};
  if (adaptive) {
    j["backgrounds"]["consensus"] = {{"pixels_checked", summary.consensus_pixels_checked},
                                     {"pixels_swapped", summary.consensus_pixels_swapped}};
  }
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
