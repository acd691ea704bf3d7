// FusionStage: the second stage of a run (pipeline/run.h), on the run's calling thread with
// ctx's pool. Input: a FrameSet whose frames the reader filled (frame_reader.h). Output, in the
// same FrameSet: the fused tri-state map (equation 5), the change buffer or the fusion's change
// bits (or neither, fully fused), and with the site's `people:` the column map and the explained
// people. The path is the FusionPlan's (fusion_path.h, the one choice); a set with a camera
// missing takes the general fusion. Adaptive backgrounds are updated here from the fused map
// (background_maintenance.h), so the next set is tested against them.
//
//   OCCMAP_ASSIGN_OR_RETURN(auto fusion, FusionStage::Create(site, options, plan, lut, cams, fps, ctx));
//   fusion->Process(set, ctx);   // per frame set, in frame order
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "occmap/fusion/column_fusion.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/occluder_learning.h"
#include "occmap/fusion/fusion.h"
#include "occmap/fusion/view_explainer.h"
#include "occmap/lut/column_lut.h"
#include "occmap/pipeline/background_maintenance.h"
#include "occmap/pipeline/camera_changes.h"
#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/frame_set.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/run.h"
#include "occmap/pipeline/shared_figure.h"
#include "occmap/site/site.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

class FusionStage {
 public:
  // Builds what the plan needs: FastFusion's tables for the paper's AND, the people's column
  // tables, the backgrounds' protection and shadow checks. fps: the run's, for the adaptive
  // backgrounds' ages (0: none, as the fuse, whose edges keep the backgrounds, makes its stage
  // before the first message tells the rate).
  static Result<std::unique_ptr<FusionStage>> Create(const Site& site, const RunOptions& options,
                                                     const FusionPlan& plan, const GroundLut& lut,
                                                     std::vector<CameraState>& cams, double fps, Context& ctx);
  FusionStage(const FusionStage&) = delete;
  FusionStage& operator=(const FusionStage&) = delete;

  void Process(FrameSet& set, Context& ctx);

  // The people's candidate columns (null without a people detector): the detect/track stage
  // turns the explained people into detections at them.
  const ColumnLut* column_lut() const { return column_lut_ ? &*column_lut_ : nullptr; }
  const CameraChanges& changes() const { return changes_; }
  // Seconds so far (any thread may read them while the stage runs).
  double detect_s() const { return detect_s_.get(); }
  double fuse_s() const { return fuse_s_.get(); }
  double people_s() const { return people_s_.get(); }
  double occluders_s() const { return occluders_s_.get(); }  // learning occluders (not in people_s)
  double background_s() const { return background_s_.get(); }
  // Camera n's adaptive background's mean age (NaN before it is first sampled, or no model).
  double background_age_s(size_t n) const { return background_age_s_[n].get(); }
  // With `people: {occluders: {learn: true}}`: writes the learned occluders to out/occluders.txt
  // and to the cache (the next run starts from them); the paths written are appended.
  Status SaveLearnedOccluders(const std::filesystem::path& out, std::vector<std::string>& written) const;
  // Live cameras' adaptive backgrounds written back to their cache entries now (at a clean stop;
  // the stage writes them every backgrounds.refresh_cache_s meanwhile). A failure is counted and
  // told to RunOptions::warning, never returned: the cache is no output of the run.
  void RefreshCachedBackgrounds() { refresh_.Now(last_frame_index_, cams_); }
  // What camera n's refreshes did (none: its entry is not refreshed). Any thread.
  std::optional<BackgroundCacheFigures> background_cache(size_t n) const { return refresh_.figures(n); }
  // The last frame whose backgrounds were updated (options.start_frame before any).
  int64_t last_frame_index() const { return last_frame_index_; }
  // Adaptive backgrounds: the protection of the last frame set (null without them). The fuse
  // sends its boxes to the edges, which keep the backgrounds (protection_message.h).
  const BackgroundProtection* protection() const { return protection_ ? &*protection_ : nullptr; }

 private:
  FusionStage(const Site& site, const RunOptions& options, const FusionPlan& plan, const GroundLut& lut,
              std::vector<CameraState>& cams, double fps);
  void DetectChanges(FrameSet& set, Context& ctx);
  void Fuse(FrameSet& set, bool fused_now, Context& ctx);
  void FindPeople(FrameSet& set, Context& ctx);
  void UpdateBackgrounds(FrameSet& set, Context& ctx);

  const Site& site_;
  const RunOptions& options_;
  const FusionPlan plan_;
  std::vector<CameraState>& cams_;
  const double fps_;
  CameraChanges changes_;
  Fusion fusion_;
  std::optional<FastFusion> fast_;  // the paper's AND (its tables only when the plan can use them)
  std::vector<ImageView<const uint8_t>> frame_views_, background_views_;
  // People (the site's `people:` section): the column fusion, and the explanation of the views,
  // on the change buffer after the floor AND.
  std::optional<ColumnLut> column_lut_;
  std::optional<ColumnFusion> column_fusion_;
  std::optional<ViewExplainer> explainer_;
  std::optional<OccluderLearner> occluders_;
  std::filesystem::path occluders_cache_;  // empty: no cache
  std::vector<ChangeRowSums> change_counts_;
  std::vector<ImageView<const uint8_t>> change_views_;
  // Adaptive backgrounds: protection from the map, shadow teachers and the shadows' floor check.
  std::optional<BackgroundProtection> protection_;
  std::vector<ImageView<const uint8_t>> protection_changes_;
  std::optional<ShadowTeachers> teachers_;
  std::optional<ShadowCheck> shadow_check_;
  std::vector<ImageView<const uint8_t>> check_classes_;
  std::vector<ImageView<uint8_t>> check_changes_;
  WalkedPeople walked_people_;  // people seen walking in stay people where they stop; missed ones objects
  std::vector<Eigen::Vector2d> people_positions_;
  std::vector<ImageView<const uint8_t>> teacher_classes_, teacher_ratios_;
  int64_t last_frame_index_ = 0;
  int64_t next_age_frame_ = 0;
  SharedFigure detect_s_, fuse_s_, people_s_, occluders_s_, background_s_;
  std::vector<SharedFigure> background_age_s_;
  BackgroundCacheRefresh refresh_;  // live cameras' cached backgrounds
};

}  // namespace occmap
