#include "occmap/pipeline/settle_backgrounds.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "occmap/pipeline/frame_reader.h"
#include "occmap/pipeline/fusion_stage.h"

namespace occmap {

ConsensusResult CheckLearnedBackgrounds(const Site& site, const GroundLut& lut, std::vector<CameraState>& cams,
                                        const std::vector<size_t>& index) {
  const LearnedCheck check = LearnedCheckOf(cams, site.cameras.size(), index);
  if (!check.any_alternative) return {};
  std::vector<BackgroundModel*> models(site.cameras.size(), nullptr);
  for (size_t k = 0; k < cams.size(); ++k) models[index.empty() ? k : index[k]] = cams[k].model.get();
  std::vector<const CameraModel*> cameras;
  for (const SiteCamera& c : site.cameras) cameras.push_back(c.camera.get());
  const bool settles = std::any_of(cams.begin(), cams.end(), [](const CameraState& c) { return c.settles; });
  return ResolveLearnedBackgrounds(lut, cameras, site.plane_height_m, models, site.detection.threshold,
                                   site.backgrounds.chroma_threshold, /*drop_kept=*/!settles, check.keep);
}

Result<SettleFigures> SettleLearnedBackgrounds(const Site& site, const RunOptions& options, const FusionPlan& plan,
                                               const GroundLut& lut, std::vector<CameraState>& cams, double fps,
                                               Context& ctx) {
  SettleFigures figures;
  if (!plan.adaptive || std::none_of(cams.begin(), cams.end(), [](const CameraState& c) { return c.settles; })) {
    return figures;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const FrameSourceOptions src_opts = RunSourceOptions(plan, ctx.num_threads(), static_cast<int>(cams.size()));
  // The pass's cameras: the same site cameras, sources of their own, copies of the models.
  std::vector<CameraState> pass(cams.size());
  for (size_t n = 0; n < cams.size(); ++n) {
    const CameraState& c = cams[n];
    CameraState& p = pass[n];
    p.cam = c.cam;
    p.is_mask = c.is_mask;
    p.info.id = c.info.id;
    p.background_gray = c.background_gray;
    p.background_rgb = c.background_rgb;
    p.raw_changes = Image<uint8_t>(c.raw_changes.width(), c.raw_changes.height());
    if (c.model) p.model = std::make_unique<BackgroundModel>(*c.model);
    OCCMAP_ASSIGN_OR_RETURN(p.source, OpenFrameSource(c.cam->source, src_opts));
    OCCMAP_RETURN_IF_ERROR(p.source->SkipTo(options.start_frame));
  }
  // The window's frame sets, without --change-pngs' pictures: the pass keeps only the models.
  RunOptions pass_options = options;
  pass_options.max_frames = std::max<int64_t>(1, std::llround(site.backgrounds.learn_s * fps));
  pass_options.change_pngs = false;
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FusionStage> fusion,
                          FusionStage::Create(site, pass_options, plan, lut, pass, fps, ctx));
  FrameReader reader(pass, pass_options, ctx.num_threads(), src_opts);
  FrameSet set;
  set.frames.resize(pass.size());
  set.active.assign(pass.size(), false);
  set.map = OccupancyMap(site.grid);
  auto stop_requested = [&] { return options.stop != nullptr && options.stop->load(); };
  while (!stop_requested() && reader.Read(set)) {
    fusion->Process(set, ctx);
    ++figures.frame_sets;
  }
  if (!reader.failure().ok()) return reader.failure().WithContext("settling the learned backgrounds");
  if (stop_requested()) return figures;  // the run stops at once: the learned models stay, uncached
  for (size_t n = 0; n < cams.size(); ++n) {
    CameraState& c = cams[n];
    if (!c.settles || !pass[n].model) continue;
    OCCMAP_RETURN_IF_ERROR(RestartAdaptiveModel(site, options, src_opts, c, pass[n].model->Current()));
    c.info.background += fmt::format(", settled over {} frame sets", figures.frame_sets);
  }
  figures.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return figures;
}

}  // namespace occmap
