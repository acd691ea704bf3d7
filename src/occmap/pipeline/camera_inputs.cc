#include "occmap/pipeline/camera_inputs.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <thread>
#include <utility>

#include "occmap/detect/background.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/site/site_location.h"
#include "occmap/util/file_util.h"
#include "occmap/util/hash.h"
#include "occmap/util/image_io.h"

namespace occmap {
namespace fs = std::filesystem;

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

namespace {

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

}  // namespace

YuvView FrameYuv(const Frame& f) {
  if (f.u.empty()) return {f.gray.view(), {}, {}};
  return {f.gray.view(), f.u.view(), f.v.view()};
}

Status WriteYuvPng(const fs::path& path, const YuvImage& yuv) {
  if (!yuv.has_chroma()) return WritePng(path, yuv.y.view());
  return WritePng(path, RgbFromYuv(yuv.view()).view());
}

namespace {

// With a given background, the shadow look is warmed up on this much of a file source's start.
constexpr double kShadowWarmUpS = 3;
constexpr int64_t kShadowWarmUpFrames = 30;

// The frames a background is estimated or learned from. A file is read by a second source, so
// that the run still starts at its first frame; a live stream by the camera's own: a second
// connection to one stream can be refused (a UDP port is bound once), and its frames go by anyway.
Result<FrameSource*> BackgroundFrames(CameraState& c, const RunOptions& options, const FrameSourceOptions& src_opts,
                                      std::unique_ptr<FrameSource>& opened) {
  if (c.cam->source.kind == FrameSourceSpec::Kind::kStream) return c.source.get();
  OCCMAP_ASSIGN_OR_RETURN(opened, OpenFrameSource(c.cam->source, src_opts));
  OCCMAP_RETURN_IF_ERROR(opened->SkipTo(options.start_frame));
  return opened.get();
}

// A source read from a file (video or pictures), which can be read again from its start.
bool FromFile(const FrameSourceSpec& source) {
  return source.kind == FrameSourceSpec::Kind::kVideo || source.kind == FrameSourceSpec::Kind::kImages;
}

// A learned background's cache entry: one PNG per plane, `<prefix>-y.png` last (it marks the
// set complete); the alternatives' planes too when given, and none left over otherwise.
fs::path CachePlane(const fs::path& prefix, const char* plane) { return fs::path(prefix.string() + "-" + plane + ".png"); }
// In an entry written from a running model (BackgroundCacheRefresh), not learned: the start's
// checks across cameras have been made on it already (CameraState::background_from_model).
fs::path FromModelMark(const fs::path& prefix) { return fs::path(prefix.string() + "-from-model.txt"); }
// Every plane is written beside its place first (the slow part), then the set is swapped in:
// `-y` removed, the others renamed, `-y` renamed last. A run killed meanwhile leaves either the
// old set, or no `-y` (learned again), never a `-y` over planes of another time.
Status CacheAdaptiveBackground(const fs::path& prefix, const YuvImage& background,
                               const BackgroundLearner::Alternative* alternative, bool from_model = false) {
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(prefix.parent_path()));
  const bool chroma = background.has_chroma();
  std::vector<std::pair<const char*, ImageView<const uint8_t>>> planes;
  if (chroma) {
    planes.emplace_back("u", background.u.view());
    planes.emplace_back("v", background.v.view());
  }
  if (alternative) {
    planes.emplace_back("alt-y", alternative->levels.y.view());
    if (chroma) {
      planes.emplace_back("alt-u", alternative->levels.u.view());
      planes.emplace_back("alt-v", alternative->levels.v.view());
    }
    planes.emplace_back("alt-n", alternative->support.view());
  }
  planes.emplace_back("y", background.y.view());  // last: it marks the set complete
  auto fresh = [&](const char* plane) { return fs::path(CachePlane(prefix, plane).string() + ".new"); };
  std::error_code ec;
  for (size_t k = 0; k < planes.size(); ++k) {
    if (Status s = WritePng(fresh(planes[k].first), planes[k].second); !s.ok()) {
      // The entry stays as it was; what this attempt wrote beside it goes (a full disk that
      // fails every period must not fill up with halves).
      for (size_t j = 0; j < k; ++j) fs::remove(fresh(planes[j].first), ec);
      return s;
    }
  }
  const fs::path mark = FromModelMark(prefix), fresh_mark = mark.string() + ".new";
  if (from_model) {
    if (Status s = WriteFileAtomic(fresh_mark, "written from a running model: its start's checks are made\n"); !s.ok()) {
      for (const auto& [plane, image] : planes) fs::remove(fresh(plane), ec);
      return s;
    }
  }
  fs::remove(CachePlane(prefix, "y"), ec);
  for (const char* plane : {"alt-y", "alt-u", "alt-v", "alt-n"}) fs::remove(CachePlane(prefix, plane), ec);
  fs::remove(mark, ec);
  if (from_model) {
    fs::rename(fresh_mark, mark, ec);
    if (ec) return IoError(fmt::format("'{}': could not rename it into place: {}", fresh_mark.string(), ec.message()));
  }
  for (const auto& [plane, image] : planes) {
    fs::rename(fresh(plane), CachePlane(prefix, plane), ec);
    if (ec) return IoError(fmt::format("'{}': could not rename it into place: {}", fresh(plane).string(), ec.message()));
  }
  return Status::Ok();
}

// "3 min ago" for a file's modification time; empty when it has none.
std::string AgeOf(const fs::path& path) {
  std::error_code ec;
  const auto mtime = fs::last_write_time(path, ec);
  if (ec) return {};
  const double s = std::max(0.0, std::chrono::duration<double>(fs::file_time_type::clock::now() - mtime).count());
  if (s < 120) return fmt::format("{:.0f} s ago", s);
  if (s < 7200) return fmt::format("{:.0f} min ago", s / 60);
  if (s < 2 * 86400) return fmt::format("{:.1f} h ago", s / 3600);
  return fmt::format("{:.0f} days ago", s / 86400);
}

// The shadow look before the first frame, so that the first frames are tested with it. A file
// source is run from its start: the look comes from its first seconds (read again), whether the
// background was learned, settled, reused from the cache or given, so that a run gives the same
// answer with and without the cache (the samples spread over the learning window carry its
// whole exposure drift: plaza MODA 0.958 learned against 0.967 reused). A live stream goes on
// from where learning stopped: it takes the learning samples (`learned_from`), or without them
// learns the look from its first frames.
Status WarmUpShadows(const Site& site, const RunOptions& options, const FrameSourceOptions& src_opts, bool chroma,
                     const BackgroundLearner* learned_from, CameraState& c) {
  const BackgroundOptions& bo = site.backgrounds;
  if (!bo.shadows.enabled || !bo.shadows.learn) return Status::Ok();
  const SiteCamera& cam = *c.cam;
  const double fps = c.source->fps().value_or(10.0);
  std::vector<YuvView> samples;
  std::vector<Frame> first;
  const bool file = FromFile(cam.source);
  if (learned_from && !file) {
    for (int k = 0; k < learned_from->count(); ++k) samples.push_back(learned_from->Sample(k));
  } else if (file) {
    OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> src, OpenFrameSource(cam.source, src_opts));
    OCCMAP_RETURN_IF_ERROR(src->SkipTo(options.start_frame));
    const int64_t n = std::min<int64_t>(kShadowWarmUpFrames, std::max<int64_t>(1, std::llround(kShadowWarmUpS * fps)));
    for (int64_t k = 0; k < n; ++k) {
      Frame f;
      OCCMAP_ASSIGN_OR_RETURN(bool got, src->Read(f));
      if (!got) break;
      OCCMAP_RETURN_IF_ERROR(CheckFrameSize(c, f).WithContext(fmt::format("camera {}", cam.id)));
      if (chroma && f.u.empty()) break;  // the run reports the missing colour
      first.push_back(std::move(f));
    }
    for (const Frame& f : first) samples.push_back(FrameYuv(f));
  }
  if (!samples.empty()) c.model->WarmUp(samples, site.detection.threshold);
  return Status::Ok();
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
    // Settled backgrounds depend on every setting of the run (the fusion's, the maintenance's):
    // their key is the whole site file's, with the camera's source.
    const bool settles = SettlesLearnedBackgrounds(site, options);
    Hasher h = BackgroundKey("adaptive-background-v5", site, cam, options.start_frame, chroma);
    h.Add(ToString(bo.learning));
    h.AddPod(bo.learn_s);
    h.AddPod(bo.learn_samples);
    h.AddPod(bo.mode_radius);
    h.AddPod(settles);
    if (settles) {
      h.AddPod(GroundLutKey(site.LutInputs(), site.grid, site.lut));
      if (!site.file.empty()) {
        auto text = ReadFileToString(site.file);
        h.Add(text.ok() ? *text : std::string());
      }
    }
    std::error_code ec;
    const fs::path cached = options.cache_dir.empty() ? fs::path()
                                                      : options.cache_dir / "backgrounds" /
                                                            fmt::format("{}-{}-{:016x}", site.name, cam.id, h.Digest());
    auto plane_path = [&](const char* plane) { return CachePlane(cached, plane); };
    bool reused = false;
    if (!cached.empty() && fs::exists(plane_path("y"), ec)) {
      auto y = ReadGrayImage(plane_path("y"));
      auto u = chroma ? ReadGrayImage(plane_path("u")) : Result<Image<uint8_t>>(Image<uint8_t>());
      auto v = chroma ? ReadGrayImage(plane_path("v")) : Result<Image<uint8_t>>(Image<uint8_t>());
      auto alt_y = ReadGrayImage(plane_path("alt-y"));
      auto alt_u = chroma ? ReadGrayImage(plane_path("alt-u")) : Result<Image<uint8_t>>(Image<uint8_t>());
      auto alt_v = chroma ? ReadGrayImage(plane_path("alt-v")) : Result<Image<uint8_t>>(Image<uint8_t>());
      auto alt_n = ReadGrayImage(plane_path("alt-n"));
      if (y.ok() && u.ok() && v.ok() && y->width() == size.width && y->height() == size.height) {
        background.y = std::move(y).value();
        background.u = std::move(u).value();
        background.v = std::move(v).value();
        if (alt_y.ok() && alt_u.ok() && alt_v.ok() && alt_n.ok() && alt_y->width() == size.width &&
            alt_n->width() == size.width && alt_y->height() == size.height && alt_n->height() == size.height &&
            alt_u->width() == background.u.width() && alt_u->height() == background.u.height() &&
            alt_v->width() == background.v.width() && alt_v->height() == background.v.height()) {
          alternative.emplace();
          alternative->levels.y = std::move(alt_y).value();
          alternative->levels.u = std::move(alt_u).value();
          alternative->levels.v = std::move(alt_v).value();
          alternative->support = std::move(alt_n).value();
        }
        reused = true;
        c.background_learned = true;
        c.background_from_model = fs::exists(FromModelMark(cached), ec);
        c.info.background = fmt::format("reused: {} (saved {})", plane_path("y").string(), AgeOf(plane_path("y")));
      }
    }
    // A live stream's entry follows the scene (BackgroundCacheRefresh); a file's stays as
    // learned, so that a run over it is reproduced from the cache.
    if (!cached.empty() && !settles && cam.source.kind == FrameSourceSpec::Kind::kStream && bo.refresh_cache_s > 0) {
      c.refresh_cache = cached;
    }
    std::unique_ptr<FrameSource> opened;
    OCCMAP_ASSIGN_OR_RETURN(FrameSource* src, BackgroundFrames(c, options, src_opts, opened));
    if (auto f = src->fps()) fps = *f;
    if (!reused) {
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
      c.background_learned = true;
      c.info.background = fmt::format("learned: {} of {} frames over {:.1f} s", ToString(bo.learning), learner.count(),
                                      static_cast<double>(std::min(window, learner.count() * step)) / fps);
      if (settles) {  // cached once settled (pipeline/settle_backgrounds.h)
        c.settles = true;
        c.learned_cache = cached;
      } else if (!cached.empty()) {
        // The cache folder is no output the user named (backgrounds/<camera>.png in out_dir is):
        // a head start for the next run, so a failed write is said, not an error.
        if (Status s = CacheAdaptiveBackground(cached, background, alternative ? &*alternative : nullptr); !s.ok()) {
          WarnCacheNotWritten(options.warning, "background cache", plane_path("y"), s.message());
        }
      }
    }
  }
  c.model = std::make_unique<BackgroundModel>(bo, fps);
  c.model->Reset(background);
  if (alternative) {
    c.model->SetAlternative(*alternative, static_cast<int>(std::ceil(bo.alternative_min_share * bo.learn_samples)));
    c.model->PreferLitAlternatives();
  }
  return WarmUpShadows(site, options, src_opts, chroma, learned_from ? &*learned_from : nullptr, c);
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
  std::unique_ptr<FrameSource> opened;
  OCCMAP_ASSIGN_OR_RETURN(FrameSource* src, BackgroundFrames(c, options, src_opts, opened));
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
  if (!cached.empty()) {  // a head start for the next run, not an output: said, never an error
    Status written = EnsureDirectory(cached.parent_path());
    if (written.ok()) written = colour ? WritePng(cached, c.background_rgb.view()) : WritePng(cached, c.background_gray.view());
    if (!written.ok()) WarnCacheNotWritten(options.warning, "background cache", cached, written.message());
  }
  return Status::Ok();
}


}  // namespace

FrameSourceOptions RunSourceOptions(const FusionPlan& plan, int num_threads, int num_cameras) {
  FrameSourceOptions o;
  o.colour = plan.colour;
  o.chroma = plan.chroma;
  o.decoder_threads = DecoderThreadsPerCamera(num_threads, num_cameras);
  return o;
}

bool SettlesLearnedBackgrounds(const Site& site, const RunOptions& options) {
  const BackgroundOptions& bo = site.backgrounds;
  if (!bo.adaptive || !bo.settle || !options.settle_learned_backgrounds) return false;
  return std::all_of(site.cameras.begin(), site.cameras.end(), [](const SiteCamera& cam) { return FromFile(cam.source); });
}

Status RestartAdaptiveModel(const Site& site, const RunOptions& options, const FrameSourceOptions& src_opts,
                            CameraState& c, const YuvImage& background) {
  c.model = std::make_unique<BackgroundModel>(site.backgrounds, c.source->fps().value_or(10.0));
  c.model->Reset(background);
  OCCMAP_RETURN_IF_ERROR(WarmUpShadows(site, options, src_opts, background.has_chroma(), nullptr, c));
  if (c.learned_cache.empty()) return Status::Ok();
  // The settled background is used either way; its entry only spares the next run the pass.
  if (Status s = CacheAdaptiveBackground(c.learned_cache, background, nullptr); !s.ok()) {
    WarnCacheNotWritten(options.warning, "background cache", CachePlane(c.learned_cache, "y"), s.message());
  }
  return Status::Ok();
}

Status RefreshCachedBackground(const CameraState& c, const BackgroundOptions& bo) {
  if (c.refresh_cache.empty() || !c.model) return Status::Ok();
  const int min_support = static_cast<int>(std::ceil(bo.alternative_min_share * bo.learn_samples));
  const BackgroundLearner::Alternative alternative =
      c.model->CurrentAlternative(static_cast<uint8_t>(std::clamp(min_support, 1, 255)));
  return CacheAdaptiveBackground(c.refresh_cache, c.model->Current(), &alternative, /*from_model=*/true)
      .WithContext(fmt::format("camera {}: refreshing its cached background", c.cam->id));
}

LearnedCheck LearnedCheckOf(const std::vector<CameraState>& cams, size_t num_site_cameras,
                            const std::vector<size_t>& index) {
  LearnedCheck check;
  check.keep.assign(num_site_cameras, false);
  for (size_t k = 0; k < cams.size(); ++k) {
    const CameraState& c = cams[k];
    check.keep[index.empty() ? k : index[k]] = c.background_from_model;
    check.any_alternative |= c.background_learned && !c.background_from_model;
  }
  return check;
}

BackgroundCacheRefresh::BackgroundCacheRefresh(const BackgroundOptions& bo, double fps, WarningCallback warning)
    : options_(bo),
      period_frames_(bo.refresh_cache_s > 0 && fps > 0 ? std::max<int64_t>(1, std::llround(bo.refresh_cache_s * fps)) : 0),
      warning_(std::move(warning)) {}

void BackgroundCacheRefresh::After(int64_t frame_index, const std::vector<CameraState>& cams) {
  if (period_frames_ == 0) return;
  if (!next_frame_) next_frame_ = frame_index + period_frames_;
  if (frame_index < *next_frame_) return;
  next_frame_ = frame_index + period_frames_;
  Now(frame_index, cams);
}

void BackgroundCacheRefresh::Now(int64_t frame_index, const std::vector<CameraState>& cams) {
  for (size_t k = 0; k < cams.size(); ++k) {
    const CameraState& c = cams[k];
    if (c.refresh_cache.empty() || !c.model) continue;
    // Written outside the lock (the slow part); the figures' readers wait for no disk.
    const Status s = RefreshCachedBackground(c, options_);
    std::string said;
    {
      std::lock_guard lock(mutex_);
      if (figures_.size() < cams.size()) figures_.resize(cams.size());
      if (!figures_[k]) {
        figures_[k].emplace();
        figures_[k]->entry = CachePlane(c.refresh_cache, "y").string();
      }
      BackgroundCacheFigures& f = *figures_[k];
      if (s.ok()) {
        if (!f.last_error.empty()) {
          said = fmt::format("camera {}: its cached background is written again ({}; {} writes failed so far)",
                             c.cam->id, f.entry, f.failures);
        }
        ++f.refreshes;
        f.last_refresh_frame = frame_index;
        f.last_error.clear();
      } else {
        // Once per failing spell: a disk that stays full would say it every period otherwise.
        if (f.last_error.empty()) {
          said = fmt::format("{} (the entry is left as it was and the run goes on; said again once a write works)",
                             s.message());
        }
        ++f.failures;
        f.last_error = s.message();
      }
    }
    if (!said.empty() && warning_) warning_(said);
  }
}

std::optional<BackgroundCacheFigures> BackgroundCacheRefresh::figures(size_t k) const {
  std::lock_guard lock(mutex_);
  return k < figures_.size() ? figures_[k] : std::nullopt;
}

int64_t BackgroundCacheRefresh::written() const {
  std::lock_guard lock(mutex_);
  int64_t n = 0;
  for (const auto& f : figures_) n += f ? f->refreshes : 0;
  return n;
}

Result<std::vector<CameraState>> OpenCameras(const Site& site, const RunOptions& options, const FusionPlan& plan,
                                             Context& ctx, const std::vector<size_t>& only) {
  std::vector<size_t> index = only;
  if (index.empty()) {
    for (size_t n = 0; n < site.cameras.size(); ++n) index.push_back(n);
  }
  std::vector<CameraState> cams(index.size());
  const FrameSourceOptions src_opts = RunSourceOptions(plan, ctx.num_threads(), static_cast<int>(cams.size()));
  // A background estimated from one camera's frames uses all the threads.
  FrameSourceOptions background_opts = src_opts;
  background_opts.decoder_threads = ctx.num_threads();
  for (size_t k = 0; k < cams.size(); ++k) {
    const size_t n = index[k];
    CameraState& c = cams[k];
    c.cam = &site.cameras[n];
    c.info.id = c.cam->id;
    if (c.cam->source.kind == FrameSourceSpec::Kind::kNone) {
      return InvalidInput(fmt::format("camera {}: no source (give cameras[{}].source in the site file)", c.cam->id, n));
    }
    c.is_mask = c.cam->source.kind == FrameSourceSpec::Kind::kMasks;
    // Errors found only now still name the site file's line (site/site_location.h).
    auto src = OpenFrameSource(c.cam->source, src_opts);
    if (!src.ok()) {
      return src.status().WithContext(fmt::format("{}: camera {}", SiteCameraLocation(site, n, "source"), c.cam->id));
    }
    c.source = std::move(src).value();
    // --loop: a file read again from its start whenever it ends (streams go on by themselves).
    if (options.loop && FromFile(c.cam->source)) {
      OCCMAP_ASSIGN_OR_RETURN(c.source, LoopFrameSource(c.cam->source, src_opts, std::move(c.source)));
    }
    c.info.source = c.source->Describe();
  }
  // Backgrounds: a live stream's are read from the stream as it goes (learn_s of it when
  // adaptive), so the streams are read at once, a thread each: an edge box of 3 cameras that
  // reboots learns in learn_s, not 3 learn_s. Files are read one after the other.
  std::vector<Status> backgrounds(cams.size());
  auto prepare = [&](size_t k) {
    CameraState& c = cams[k];
    backgrounds[k] = plan.adaptive && !c.is_mask ? PrepareAdaptiveBackground(site, options, plan.chroma, background_opts, c)
                                                 : PrepareBackground(site, options, plan.colour, background_opts, c);
  };
  std::vector<std::thread> readers;
  for (size_t k = 0; k < cams.size(); ++k) {
    if (cams[k].cam->source.kind == FrameSourceSpec::Kind::kStream) {
      readers.emplace_back(prepare, k);
    } else {
      prepare(k);
    }
  }
  for (std::thread& t : readers) t.join();
  for (size_t k = 0; k < cams.size(); ++k) {
    const size_t n = index[k];
    CameraState& c = cams[k];
    if (!backgrounds[k].ok()) {
      return backgrounds[k].WithContext(SiteCameraLocation(site, n, c.cam->background ? "background" : "source"));
    }
    if (options.start_frame > 0) {
      if (Status s = c.source->SkipTo(options.start_frame); !s.ok()) {
        return s.WithContext(
            fmt::format("{}: --start {}: camera {}", SiteCameraLocation(site, n, "source"), options.start_frame, c.cam->id));
      }
    }
    const ImageSize size = c.cam->camera->image_size();
    c.raw_changes = Image<uint8_t>(size.width, size.height);
  }
  return cams;
}

}  // namespace occmap
