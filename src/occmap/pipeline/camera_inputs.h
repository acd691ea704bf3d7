// The cameras of a run: each one's frame source and background (given, reused from the cache,
// estimated as a median, or learned by the adaptive model), opened and prepared before the
// first frame set (pipeline/run.cc), then read by the FrameReader (pipeline/frame_reader.h).
//
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<CameraState> cams, OpenCameras(site, options, plan, ctx));
#pragma once

#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "occmap/detect/background_model.h"
#include "occmap/io/frame_source.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/run.h"
#include "occmap/util/image.h"
#include "occmap/util/yuv.h"

namespace occmap {

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
  // Its model was learned by this run and is settled before it (pipeline/settle_backgrounds.h),
  // then cached at learned_cache (empty: no cache).
  bool settles = false;
  std::filesystem::path learned_cache;
  // A live stream's adaptive model: its cache entry, written back as the scene goes on
  // (BackgroundCacheRefresh); empty for files, given backgrounds, or without a cache.
  std::filesystem::path refresh_cache;
  // Its adaptive background was reused from an entry a running model wrote (refresh_cache), not
  // one learned: checked across cameras when first learned, and the scene as it was minutes
  // ago, so the start's check (ResolveLearnedBackgrounds) leaves it as it is.
  bool background_from_model = false;
  // Its adaptive background was learned by this run or reused from a learned entry (not given):
  // it has alternatives for the start's check across cameras to decide (LearnedCheckOf).
  bool background_learned = false;
  CameraRunInfo info;
};

// What the start's check across cameras (ResolveLearnedBackgrounds) is given: keep[n] for the
// cameras whose entry a running model wrote (they vote and are left as they are), and whether
// any other camera has learned alternatives for it to decide (none: no check). index: each
// camera's place among the site's num_site_cameras (an edge's cameras); empty: cams are the site's.
struct LearnedCheck {
  std::vector<bool> keep;
  bool any_alternative = false;
};
LearnedCheck LearnedCheckOf(const std::vector<CameraState>& cams, size_t num_site_cameras,
                            const std::vector<size_t>& index = {});

// A frame's size against the camera's image size (masks: its shape).
Status CheckFrameSize(const CameraState& c, const Frame& f);
// A frame's planes as the adaptive model reads them.
YuvView FrameYuv(const Frame& f);
// A background of the adaptive model as a picture: RGB from luma and chroma, or grey.
Status WriteYuvPng(const std::filesystem::path& path, const YuvImage& yuv);

// The decoder options of the run's sources: grey, colour or chroma as the plan reads them, and
// each camera's share of ctx's threads (the cameras decode side by side).
FrameSourceOptions RunSourceOptions(const FusionPlan& plan, int num_threads, int num_cameras);

// Whether a run settles the backgrounds it learns: the adaptive model learning them
// (site.backgrounds.settle), every camera's source a file (video or pictures: the window is read
// again), and RunOptions::settle_learned_backgrounds.
bool SettlesLearnedBackgrounds(const Site& site, const RunOptions& options);
// Starts camera c's adaptive model again from `background` (its alternatives forgotten), the
// shadow look warmed up as the run's start; caches it at c.learned_cache when that is set.
Status RestartAdaptiveModel(const Site& site, const RunOptions& options, const FrameSourceOptions& src_opts,
                            CameraState& c, const YuvImage& background);
// Writes camera c's adaptive model as it is now (background, alternatives, chroma) over its
// cache entry c.refresh_cache, the planes swapped in together; nothing without one.
Status RefreshCachedBackground(const CameraState& c, const BackgroundOptions& bo);

// The live cameras' cached backgrounds kept up with the scene (site.backgrounds.refresh_cache_s),
// by whoever updates their models (the run's fusion stage, an edge): After() each frame set
// writes them every refresh_cache_s of frames, Now() at a clean stop. A restart then takes the
// background as the scene was when it stopped, not as it was first learned. A write that fails
// (a full disk, the folder gone read-only) leaves the entry as it was and never stops the run:
// it is counted per camera, and `warning` is told once (the camera, the path, the system's
// error), then once more when a write works again, not every period.
//
//   BackgroundCacheRefresh refresh(site.backgrounds, fps, options.warning);
//   refresh.After(set.frame_index, cams);  // per set, after the models' Update
//   refresh.Now(last_frame_index, cams);   // at the end
//   refresh.figures(k);                    // camera k's, from any thread
class BackgroundCacheRefresh {
 public:
  BackgroundCacheRefresh(const BackgroundOptions& bo, double fps, WarningCallback warning = {});
  // frame_index: the frame set whose update the models just took.
  void After(int64_t frame_index, const std::vector<CameraState>& cams);
  // frame_index: the last frame set the models took (the stop's).
  void Now(int64_t frame_index, const std::vector<CameraState>& cams);
  // What camera k's refreshes did so far; none for a camera whose entry is not refreshed (files,
  // given backgrounds, no cache) or before the first write. Any thread.
  std::optional<BackgroundCacheFigures> figures(size_t k) const;
  int64_t written() const;  // camera backgrounds written so far

 private:
  BackgroundOptions options_;
  int64_t period_frames_;  // 0: never
  WarningCallback warning_;
  std::optional<int64_t> next_frame_;
  mutable std::mutex mutex_;  // figures_, for readers on other threads (summary.json)
  std::vector<std::optional<BackgroundCacheFigures>> figures_;
};

// Every camera's source opened (at options.start_frame) and its background prepared; with
// `only` (indices into site.cameras, an edge process's cameras) those cameras alone, in that order.
// Live streams' backgrounds (estimated or learned from the stream as it goes) are prepared at
// once, a thread each: learning takes learn_s however many streams; files' one after the other.
Result<std::vector<CameraState>> OpenCameras(const Site& site, const RunOptions& options, const FusionPlan& plan,
                                             Context& ctx, const std::vector<size_t>& only = {});

}  // namespace occmap
