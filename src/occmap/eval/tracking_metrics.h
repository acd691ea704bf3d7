// Tracking metrics: CLEAR MOT (Bernardin & Stiefelhagen 2008) and the identity measures IDF1,
// IDP, IDR (Ristani et al. 2016), on floor positions with EvalOptions::match_threshold_m.
//
// CLEAR MOT, per frame: (1) a ground-truth object keeps the track it was last matched to when
// that pair is still the latest correspondence of both (track present, distance <= t); (2) the
// remaining objects and tracks are matched by the Hungarian method (most pairs within t, then
// least total distance). An ID switch is counted when an object is matched to a track other
// than the one of its last match (however many frames ago). Over the sequence:
//   MOTA = 1 - (FN + FP + IDSW) / N_gt     (can be negative; NaN when N_gt = 0)
//   MOTP = sum d / TP in metres, and MOTP' = sum (1 - d / t) / TP (WILDTRACK's form)
//   fragmentations: interruptions of an object's tracking (matched, then missed, then matched
//   again: each such gap counts once), over the frames the object is in the ground truth
//   mostly tracked / partially tracked / mostly lost: objects matched in >= 80%, between, or
//   < 20% of their frames (EvalOptions ratios).
// Identity measures: each ground-truth trajectory is paired with at most one track (and each
// track with at most one trajectory) so as to maximise IDTP, the number of frames where paired
// trajectory and track are within t (the min-cost bipartite matching of Ristani et al., whose
// cost is the frames they are not matched). IDFN = N_gt - IDTP, IDFP = N_pred - IDTP,
//   IDF1 = 2 IDTP / (N_gt + N_pred), IDP = IDTP / N_pred, IDR = IDTP / N_gt.
// Every frame given to AddFrame is evaluated; ids must be unique within a frame (CHECKed).
//
//   TrackingEvaluator evaluator(options);
//   for (...) evaluator.AddFrame(gt_frame, tracks_of_frame);
//   TrackingMetrics m = evaluator.Metrics();   // m.mota, m.idf1, ...
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

#include "occmap/eval/eval_options.h"
#include "occmap/eval/run_outputs.h"
#include "occmap/sim/ground_truth.h"

namespace occmap {

// A ground-truth object or a track in one frame.
struct IdPosition {
  int64_t id = 0;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
};

struct TrackingMetrics {
  int64_t frames = 0;
  int64_t gt = 0;           // N_gt: ground-truth objects summed over frames
  int64_t predictions = 0;  // N_pred: tracks summed over frames
  int64_t tp = 0, fp = 0, fn = 0;
  int64_t id_switches = 0;
  int64_t fragmentations = 0;
  int64_t gt_trajectories = 0, track_trajectories = 0;  // distinct ids
  int64_t mostly_tracked = 0, partially_tracked = 0, mostly_lost = 0;
  double mota = 0;
  double motp_m = 0;          // mean distance of matched pairs
  double motp_closeness = 0;  // mean of 1 - d / t over matched pairs
  int64_t idtp = 0, idfp = 0, idfn = 0;
  double idf1 = 0, idp = 0, idr = 0;  // NaN: undefined
  // Filled by EvaluateRun, as in DetectionMetrics.
  int64_t gt_frames_missing_from_run = 0;
  int64_t run_frames_without_gt = 0;
};

class TrackingEvaluator {
 public:
  explicit TrackingEvaluator(const EvalOptions& options = {});

  // Ground-truth objects of the classes the options select, against every track.
  void AddFrame(const GroundTruthFrame& gt, const std::vector<TrackRecord>& tracks);
  // Plain ids and positions, no filter.
  void AddFrame(std::span<const IdPosition> gt, std::span<const IdPosition> tracks);

  // CLEAR MOT counts so far, and the identity measures from one global matching.
  TrackingMetrics Metrics() const;

 private:
  struct Trajectory {
    int64_t frames_present = 0, frames_matched = 0, fragmentations = 0;
    bool ever_matched = false, in_gap = false;
  };
  EvalOptions options_;
  int64_t frames_ = 0, gt_ = 0, predictions_ = 0, tp_ = 0, id_switches_ = 0;
  double distance_sum_m_ = 0, closeness_sum_ = 0;
  std::unordered_map<int64_t, int64_t> last_track_of_gt_, last_gt_of_track_;
  std::map<int64_t, Trajectory> gt_trajectories_;
  std::map<int64_t, int64_t> track_lengths_;
  std::map<std::pair<int64_t, int64_t>, int64_t> frames_within_;  // (gt id, track id) -> frames within t
};

}  // namespace occmap
