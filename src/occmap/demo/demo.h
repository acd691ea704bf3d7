// The demo: the first thing a new user runs, and the whole system on a scene whose truth is
// known. Renders the simulator's lab scene (the paper's UCSD lab: 9 x 6.5 m, four 640x480
// cameras at 2.7 m, people walking, a chair pushed, a robot), runs the pipeline on the
// rendered videos, evaluates detections, tracks and occupancy against the ground truth, and
// writes to out_dir:
//   dataset/        the rendered dataset (site.yaml, frames/*.mp4, ground truth)
//   run/            everything `occmap run` writes
//   mosaic.mp4, mosaic.png   the run's mosaic (cameras with changes, map, tracks)
//   summary.json    {"moda", "modp", "precision", "recall", "mota", "idf1", "frames_per_second",
//                    "frames", "seconds": {...}, "evaluation": {...}}
//
//   OCCMAP_ASSIGN_OR_RETURN(DemoResult r, RunDemo({.out_dir = "demo-out"}, ctx, on_stage));
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "occmap/eval/report.h"
#include "occmap/pipeline/run.h"

namespace occmap {

struct DemoOptions {
  std::filesystem::path out_dir = "demo-out";
  int64_t frames = -1;  // -1: the lab scene's length
  uint64_t seed = 1;
};

struct DemoResult {
  RunSummary run;
  EvaluationReport evaluation;
  double synth_seconds = 0, run_seconds = 0, eval_seconds = 0;
  std::filesystem::path summary_file;
};

// stage(name, done, total): progress of the current stage ("render", "run").
using DemoProgress = std::function<void(const std::string& stage, int64_t done, int64_t total)>;

Result<DemoResult> RunDemo(const DemoOptions& options, Context& ctx, const DemoProgress& progress = {});

}  // namespace occmap
