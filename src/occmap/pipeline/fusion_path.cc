#include "occmap/pipeline/fusion_path.h"

#include <fmt/core.h>

#include "occmap/fusion/fast_fusion.h"

namespace occmap {

FusionPlan ChooseFusionPath(const Site& site, bool needs_change_buffer) {
  FusionPlan p;
  p.adaptive = site.backgrounds.adaptive;
  // The adaptive model reads colour as the decoder's chroma planes; the paper's test as RGB.
  p.colour = site.detection.colour && !p.adaptive;
  p.chroma = site.detection.colour && p.adaptive;
  p.paper_and = site.fusion.method == FusionMethod::kImageBased && site.fusion.max_free_views == 0;
  p.people_detector = site.people.enabled && site.people.detector != PeopleDetector::kFloor;
  for (const SiteCamera& c : site.cameras) p.any_mask_source |= c.source.kind == FrameSourceSpec::Kind::kMasks;
  // Fully fused (no change buffer at all) when nothing needs the per-pixel changes: the paper's
  // AND on grey frames, no mask sources, no output that draws the changes (the mosaic picture
  // of the best frame gets its changes computed when it is drawn), changes per pixel.
  const bool fusable = !p.people_detector && p.paper_and && !p.colour && !p.adaptive && !p.any_mask_source &&
                       !needs_change_buffer && !site.detection.blocks();
  const int r = site.detection.tolerance_px;
  if (fusable && r == 0) {
    p.path = FusionPath::kFused;
  } else if (fusable && r >= 1 && r <= FastFusion::kMaxFusedTolerancePx) {
    p.path = FusionPath::kFusedTolerant;
  } else if (p.paper_and) {
    p.path = FusionPath::kFastChanges;
  } else {
    p.path = FusionPath::kGeneral;
  }
  return p;
}

std::string FusionPlan::Describe(const Site& site) const {
  const int r = site.detection.tolerance_px;
  if (path == FusionPath::kFused) return "fully fused FastFusion::Fuse, no change buffer";
  if (path == FusionPath::kFusedTolerant) {
    return fmt::format("fully fused FastFusion::FuseTolerant (tolerance_px {} folded in as bits), no change buffer", r);
  }
  const std::string people_path =
      people_detector ? fmt::format("; people: {} (row sums, ColumnFusion{})", ToString(site.people.detector),
                                    site.people.detector == PeopleDetector::kExplain ? ", ViewExplainer" : "")
                      : std::string();
  const std::string changes =
      fmt::format("{} change detection{} into change buffers",
                  site.detection.colour ? "colour" : "grey",
                  r > 0 ? fmt::format(" dilated by tolerance_px {}", r) : std::string()) +
      (site.detection.blocks()
           ? fmt::format(" in {}x{} blocks", site.detection.block_width_px, site.detection.block_height_px)
           : std::string());
  if (path == FusionPath::kFastChanges) return changes + ", FastFusion::FuseChanges" + people_path;
  return fmt::format("{}, Fusion::Fuse ({}, max_free_views {}){}", changes,
                     site.fusion.method == FusionMethod::kImageBased ? "image-based" : "map-based",
                     site.fusion.max_free_views, people_path);
}

}  // namespace occmap
