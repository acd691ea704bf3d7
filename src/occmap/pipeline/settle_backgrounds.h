// Settling learned backgrounds: before a run over files, the learning window is run once
// through the change test, the fusion and the backgrounds' maintenance (pipeline/
// fusion_stage.h), and the run starts from each learned background as it is at the window's end.
//
// Why: learning takes what a pixel shows most of the window (detect/background_model.h), so a
// person who stood there from the first frame for over half of it is learned as floor. The
// cross-camera check (background_maintenance.h) undoes that where the other cameras see the
// floor behind them, not at their feet, which every camera sees alike. The maintenance does
// undo it once they walk away: the fused map sees them leave and the floor they uncover is
// taken. A live run starts after its learning window, so such people have left by then; a run
// over files replays the window from its first frame, and without settling would miss them
// until they leave (held-out plazas: MODA 0.80 and 0.82 learned, 0.90 and 0.92 settled, 0.93
// given the empty scene).
//
// The settled backgrounds start like given ones: no alternatives (what the window could tell
// of them is used), the shadow look warmed up on the run's first seconds. They are cached in
// place of the learned ones, under a key that covers the site file and the tables, so a second
// run reuses them without the pass. Costs one pass over the window without tracking or outputs.
//
//   OCCMAP_ASSIGN_OR_RETURN(SettleFigures s, SettleLearnedBackgrounds(site, options, plan, lut, cams, fps, ctx));
#pragma once

#include <cstdint>
#include <vector>

#include "occmap/lut/ground_lut.h"
#include "occmap/pipeline/background_maintenance.h"
#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/run.h"
#include "occmap/site/site.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

struct SettleFigures {
  int64_t frame_sets = 0;  // 0: nothing to settle
  double seconds = 0;
};

// The start's check of learned backgrounds across cameras (ResolveLearnedBackgrounds, before
// settling and the first frame set): cams are the site's cameras, or with `index` an edge's
// (cams[k] is site camera index[k]; the others take no part). Nothing to do without learned
// alternatives. Settling reads the alternatives of the kept pixels too: they stay then.
ConsensusResult CheckLearnedBackgrounds(const Site& site, const GroundLut& lut, std::vector<CameraState>& cams,
                                        const std::vector<size_t>& index = {});

// Settles the models of the cameras marked CameraState::settles (learned by this run, sources
// that are files: camera_inputs.h, SettlesLearnedBackgrounds); the other cameras' models take
// part in the pass through copies and are left as they were. The cameras' own sources are not
// read: the window is read again by sources of its own.
Result<SettleFigures> SettleLearnedBackgrounds(const Site& site, const RunOptions& options, const FusionPlan& plan,
                                               const GroundLut& lut, std::vector<CameraState>& cams, double fps,
                                               Context& ctx);

}  // namespace occmap
