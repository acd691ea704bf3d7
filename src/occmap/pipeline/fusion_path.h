// The one place that chooses how a run computes changes and fuses them (pipeline/run.cc; the
// bench's end-to-end pass reports the same choice, bench/end_to_end.cc).
//
//   kFused          the paper's AND on grey frames, no tolerance: FastFusion::Fuse takes the
//                   frames themselves, the change test (equation 4) fused in, no change buffer
//   kFusedTolerant  the same with tolerance_px 1..FastFusion::kMaxFusedTolerancePx folded in:
//                   FastFusion::FuseTolerant, the changes only as bits (ChangeBits)
//   kFastChanges    the paper's AND over change buffers: FastFusion::FuseChanges
//   kGeneral        change buffers, Fusion::Fuse (image- or map-based, the vote rule)
// The fused and fast paths need every camera active; a frame set with a camera missing takes
// kGeneral whatever the plan. The people's detector (site `people:`) needs the change buffer.
//
//   const FusionPlan plan = ChooseFusionPath(site, /*needs_change_buffer=*/options.mosaic_video);
//   if (plan.path == FusionPath::kFused) ...;  fmt::print("{}", plan.Describe());
#pragma once

#include <string>

#include "occmap/site/site.h"

namespace occmap {

enum class FusionPath { kFused, kFusedTolerant, kFastChanges, kGeneral };

struct FusionPlan {
  FusionPath path = FusionPath::kGeneral;
  bool paper_and = false;        // image-based with max_free_views 0: FastFusion's tables are built
  bool colour = false;           // the paper's test on RGB frames (not the adaptive model's chroma)
  bool chroma = false;           // the adaptive model's test on the decoder's chroma planes
  bool adaptive = false;         // site backgrounds.adaptive
  bool people_detector = false;  // column fusion (and the views' explanation) after the floor
  bool any_mask_source = false;
  // For messages and the bench: "fully fused FastFusion::Fuse, no change buffer", ...
  std::string Describe(const Site& site) const;
};

// needs_change_buffer: an output reads every pixel's changes (the mosaic video, change PNGs).
FusionPlan ChooseFusionPath(const Site& site, bool needs_change_buffer);

}  // namespace occmap
