#include "occmap/demo/demo.h"

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "occmap/eval/evaluate_run.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/util/file_util.h"

namespace occmap {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json Metric(double v) { return std::isfinite(v) ? json(std::round(v * 1e4) / 1e4) : json(nullptr); }

Status CopyFile(const fs::path& from, const fs::path& to) {
  OCCMAP_ASSIGN_OR_RETURN(std::string bytes, ReadFileToString(from));
  return WriteFileAtomic(to, bytes);
}

}  // namespace

Result<DemoResult> RunDemo(const DemoOptions& options, Context& ctx, const DemoProgress& progress) {
  using Clock = std::chrono::steady_clock;
  DemoResult result;
  const fs::path out = options.out_dir;
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out));

  // 1. Render the lab scene into a dataset (videos, ground truth, reference rasters).
  auto t0 = Clock::now();
  sim::BuiltinSceneOptions scene_options;
  scene_options.seed = options.seed;
  scene_options.num_frames = options.frames;
  OCCMAP_ASSIGN_OR_RETURN(sim::Scene scene, sim::Scene::Create(sim::MakeLabSceneSpec(scene_options)));
  sim::DatasetOptions dataset;
  dataset.out_dir = out / "dataset";
  dataset.frame_format = sim::DatasetOptions::FrameFormat::kVideo;
  dataset.change_masks = false;
  OCCMAP_ASSIGN_OR_RETURN(sim::DatasetSummary written,
                          sim::WriteDataset(scene, dataset, ctx, [&](const sim::DatasetProgress& p) {
                            if (progress) progress("render", p.done, p.total);
                          }));
  result.synth_seconds = std::chrono::duration<double>(Clock::now() - t0).count();

  // 2. The pipeline, as `occmap run` does it, on the rendered videos.
  t0 = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(written.site_file));
  RunOptions run;
  run.out_dir = out / "run";
  run.occupancy_pngs = true;  // for the occupancy metrics
  run.wall_clock_times = false;  // the demo's outputs are the same on every run
  OCCMAP_ASSIGN_OR_RETURN(result.run, RunSite(site, run, ctx, [&](const RunProgress& p) {
                            if (progress) progress("run", p.frames_done, p.frames_total.value_or(0));
                          }));
  result.run_seconds = std::chrono::duration<double>(Clock::now() - t0).count();

  // 3. Evaluation against the ground truth.
  t0 = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(result.evaluation, EvaluateRun(dataset.out_dir, run.out_dir, EvalOptions{}));
  result.eval_seconds = std::chrono::duration<double>(Clock::now() - t0).count();

  for (const char* name : {"mosaic.mp4", "mosaic.png"}) {
    if (fs::exists(run.out_dir / name)) OCCMAP_RETURN_IF_ERROR(CopyFile(run.out_dir / name, out / name));
  }
  const EvaluationReport& e = result.evaluation;
  json j;
  j["scene"] = "lab";
  j["frames"] = result.run.frames;
  j["cameras"] = site.cameras.size();
  j["moda"] = e.detection ? Metric(e.detection->moda) : json(nullptr);
  j["modp"] = e.detection ? Metric(e.detection->modp) : json(nullptr);
  j["precision"] = e.detection ? Metric(e.detection->precision) : json(nullptr);
  j["recall"] = e.detection ? Metric(e.detection->recall) : json(nullptr);
  j["mota"] = e.tracking ? Metric(e.tracking->mota) : json(nullptr);
  j["idf1"] = e.tracking ? Metric(e.tracking->idf1) : json(nullptr);
  j["hull_iou"] = e.hull ? Metric(e.hull->iou) : json(nullptr);
  j["footprint_iou"] = e.footprint ? Metric(e.footprint->iou) : json(nullptr);
  j["frames_per_second"] = std::round(result.run.frames_per_second * 10) / 10;
  j["seconds"] = {{"render", result.synth_seconds}, {"run", result.run_seconds}, {"evaluate", result.eval_seconds}};
  j["evaluation"] = EvaluationReportJson(e);
  j["outputs"] = {{"dataset", dataset.out_dir.string()}, {"run", run.out_dir.string()},
                  {"mosaic", (out / "mosaic.mp4").string()}, {"picture", (out / "mosaic.png").string()}};
  result.summary_file = out / "summary.json";
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(result.summary_file, j.dump(2) + "\n"));
  return result;
}

}  // namespace occmap
