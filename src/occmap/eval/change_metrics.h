// Change-mask metrics: a run's per-camera change masks against the simulator's perfect ones,
// pixel by pixel, and how many of the pixels darkened only by a cast shadow the run calls
// changed.
//
// Inputs (any non-zero pixel = set):
//   run_dir/changes/<camera>/NNNNNN.png      the run's changes (`occmap run --change-pngs`)
//   dataset_dir/gt/changes/<camera>/NNNNNN.png   perfect changes: a moving object is seen
//   dataset_dir/gt/shadows/<camera>/NNNNNN.png   optional: floor darkened by a moving object's
//                                                cast shadow, no object seen there
// NNNNNN is the frame index (6 digits or more), the same numbering in both folders. A frame is
// evaluated for a camera when both change masks are there; its shadow mask, when there, adds
// to the shadow counts. With "positive" = changed, summed over the frames (and over the
// cameras for the overall figures):
//   precision = TP / (TP + FP), recall = TP / (TP + FN), F1 = 2 TP / (2 TP + FP + FN),
//   shadow_changed_fraction = run-changed shadow pixels / shadow pixels
// each NaN (null in JSON) when its denominator is 0 or, for the shadow fraction, when no
// evaluated frame has a shadow mask.
//
// Cameras are the subfolders of both changes/ folders, matched by name; one in only one of
// them is skipped with a note. Masks of one camera and frame of different sizes are an error
// naming both files and sizes. Files are read in parallel on the context's threads.
//
//   std::vector<std::string> notes;
//   OCCMAP_ASSIGN_OR_RETURN(ChangeEvaluation changes,
//                           EvaluateChangeMasks(run / "changes", dataset / "gt", ctx, notes));
//   double f1 = changes.overall.f1;
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "occmap/util/image.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

// Pixel counts of one or more frames.
struct ChangeCounts {
  int64_t tp = 0;  // changed in the run and in the ground truth
  int64_t fp = 0;  // changed in the run only
  int64_t fn = 0;  // changed in the ground truth only
  int64_t tn = 0;  // changed in neither
  int64_t shadow_pixels = 0;   // pixels of the ground-truth shadow masks
  int64_t shadow_changed = 0;  // those of them the run calls changed

  ChangeCounts& operator+=(const ChangeCounts& other);
  friend bool operator==(const ChangeCounts&, const ChangeCounts&) = default;
};

// Counts one frame: run and gt (and shadow, when not empty) have the same size (CHECKed).
ChangeCounts CountChanges(ImageView<const uint8_t> run, ImageView<const uint8_t> gt,
                          ImageView<const uint8_t> shadow = {});

struct ChangeMetrics {
  int64_t frames = 0;         // frames evaluated (one camera: its frames; overall: distinct frame numbers)
  int64_t shadow_frames = 0;  // of those, frames with a shadow mask (overall: (camera, frame) pairs)
  ChangeCounts counts;
  double precision = std::numeric_limits<double>::quiet_NaN();
  double recall = std::numeric_limits<double>::quiet_NaN();
  double f1 = std::numeric_limits<double>::quiet_NaN();
  double shadow_changed_fraction = std::numeric_limits<double>::quiet_NaN();
};

// The ratios of `counts` (shadow_frames decides whether the shadow fraction is defined).
ChangeMetrics MakeChangeMetrics(int64_t frames, int64_t shadow_frames, const ChangeCounts& counts);

struct CameraChangeMetrics {
  std::string id;  // the camera's folder name
  ChangeMetrics metrics;
};

struct ChangeEvaluation {
  ChangeMetrics overall;                    // pixel counts summed over every camera
  std::vector<CameraChangeMetrics> cameras;  // evaluated cameras, by id
};

// run_changes_dir: the run's changes/ folder; gt_dir: the dataset's gt/ folder (changes/ and
// shadows/ below it). What was skipped is appended to `notes`.
Result<ChangeEvaluation> EvaluateChangeMasks(const std::filesystem::path& run_changes_dir,
                                             const std::filesystem::path& gt_dir, Context& ctx,
                                             std::vector<std::string>& notes);

}  // namespace occmap
