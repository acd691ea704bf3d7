// `occmap bench --workload adaptive`: the speed of the real-scene path of one camera (the
// adaptive model: photometric transfer, change test with colour and shadows, hysteresis, and the
// background's upkeep from a protection map) on frames of a rendered site (`occmap synth`'s
// dataset folders), beside OpenCV's MOG2 apply() and the paper's fused test on the same frames,
// on 1 thread and on the context's threads, in one run.
//
// Per dataset: the first `frames` frame sets are read (luma, chroma and RGB); each camera's
// background is learned from them (BackgroundLearner, the site's method, with alternatives), as
// `occmap run` learns one, and its shadow look warmed up on them (BackgroundModel::WarmUp). The
// protection maps are the frame's own changes marked kPerson (a pass before the timing): the
// run's map protects what changed and lets the rest follow the frame. Then, cameras spread over
// the threads (ParallelFor, OpenCV's own pool at 1 thread so both sides use the same threads):
//   adaptive:  BackgroundModel::DetectChanges + Update per camera (also each alone, 1 thread);
//   mog2:      cv::BackgroundSubtractorMOG2::apply on the RGB frame (history 500, var 16,
//              shadows detected: the model users reach for), one subtractor per camera, warmed
//              up on the frames first;
//   paper:     FastFusion::Fuse of all cameras' luma against the learned luma backgrounds at the
//              site's threshold: the paper's change test fused with the floor AND.
// Figures: camera pixels per second (all cameras' pixels / the fastest time per frame set over
// the repetitions: other work on the machine only slows a pass down).
//
//   AdaptiveBenchOptions o; o.datasets = {"/tmp/wt"};
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<AdaptiveResult> r, RunAdaptiveBench(o, ctx));
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap::bench {

struct AdaptiveBenchOptions {
  // Dataset folders written by `occmap synth` (their site.yaml), or site files.
  std::vector<std::filesystem::path> datasets;
  std::filesystem::path data_root;  // empty: each site file's own data_root
  int frames = 20;                  // frame sets read, learned from and cycled through (2..255)
  int repetitions = 5;              // the fastest of these is reported
  Status Validate() const;
};

struct AdaptiveResult {
  std::string name;  // the dataset folder's name
  std::string site_file;
  int cameras = 0;
  int64_t camera_pixels = 0;  // all cameras, per frame set
  int frames = 0;
  int threads = 1;            // the context's: the "all" figures
  int threshold = 0;          // the site's detection.threshold
  bool chroma = false;        // the frames' chroma planes (the colour change test)
  std::string kernel;         // the kernel set
  double learn_seconds = 0;   // learning the backgrounds and warming up
  double changed_fraction = 0;  // of the pixels, the adaptive test's, over the frames
  // Camera pixels per second.
  double adaptive_1_pps = 0, adaptive_all_pps = 0;   // DetectChanges + Update
  double change_1_pps = 0, update_1_pps = 0;         // each alone, 1 thread
  double mog2_1_pps = 0, mog2_all_pps = 0;
  double paper_1_pps = 0, paper_all_pps = 0;         // FastFusion::Fuse
};

Result<std::vector<AdaptiveResult>> RunAdaptiveBench(const AdaptiveBenchOptions& options, Context& ctx);
std::string AdaptiveTable(const std::vector<AdaptiveResult>& results);
nlohmann::json AdaptiveJson(const std::vector<AdaptiveResult>& results);

}  // namespace occmap::bench
