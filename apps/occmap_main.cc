// occmap: the command-line program. Thin: parse arguments, call the library, turn a Status
// into a message on stderr and an exit code (2 for bad input, 1 for other failures).
#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <pthread.h>
#include <signal.h>
#include <vector>
#include <unistd.h>

#include <atomic>
#include <thread>

#include "calibrate_command.h"
#include "live_outputs.h"
#include "suggest.h"
#include "run_support.h"
#include "edge_fuse_command.h"
#include "serve_command.h"
#include "occmap/lut/visibility_image.h"
#include "occmap/eval/benchmark_annotations.h"
#include "occmap/eval/evaluate_run.h"
#include "occmap/demo/demo.h"
#include "occmap/pipeline/mqtt_sink.h"
#include "occmap/pipeline/ros_map_sink.h"
#include "occmap/pipeline/run.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/sim/scene_yaml.h"
#include "occmap/site/demo_scene.h"
#include "occmap/site/site.h"
#include "occmap/site/site_lut.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/thread_pool.h"
#include "occmap/bench/bench.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace occmap {
namespace {

constexpr const char* kVersion = "0.1.0";

struct CommonOptions {
  int threads = 0;
  std::string data_root;
};

struct LutCommand {
  std::string site_path;
  std::string out_dir = "occmap-out";
  std::string cache_dir;
  bool no_cache = false;
  std::optional<double> plane_height_m;
  bool json_to_stdout = false;
};

json CoverageJson(const Site& site, const CachedLut& cached, const fs::path& cache_path) {
  const GroundLut& lut = cached.lut;
  json j;
  j["site"] = site.name;
  j["grid"] = {{"origin_m", {lut.grid().origin_x_m, lut.grid().origin_y_m}},
               {"cells", {lut.grid().cells_x, lut.grid().cells_y}},
               {"cell_size_m", lut.grid().cell_size_m},
               {"plane_height_m", lut.plane_height_m()}};
  j["tables"] = {{"key", fmt::format("{:016x}", cached.key)},
                 {"cache", ToString(cached.outcome)},
                 {"cache_file", cache_path.string()},
                 {"reason", cached.reason},
                 {"build_seconds", cached.build_seconds},
                 {"load_seconds", cached.load_seconds},
                 {"memory_bytes", lut.MemoryBytes()}};
  json cams = json::array();
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const CameraCoverage& c = lut.coverage()[n];
    cams.push_back({{"id", site.cameras[n].id},
                    {"model", site.cameras[n].camera->kind()},
                    {"image_size", {lut.image_size(n).width, lut.image_size(n).height}},
                    {"pixels", c.pixels},
                    {"pixels_masked", c.pixels_masked},
                    {"pixels_no_ray", c.pixels_no_ray},
                    {"pixels_off_grid", c.pixels_off_grid},
                    {"pixels_mapped", c.pixels_mapped},
                    {"cells_from_rays", c.cells_from_rays},
                    {"cells_added", c.cells_added},
                    {"cells_seen", c.cells_seen}});
  }
  j["cameras"] = cams;
  const GridCoverage g = SummarizeCoverage(lut);
  j["cells"] = g.cells;
  j["cells_seen_by_at_least"] = g.cells_seen_by_at_least;
  return j;
}

// Builds or loads the tables, prints the coverage, writes visibility.png and lut.json.
Status WriteLutReport(const Site& site, const fs::path& out_dir, const fs::path& cache_dir, Context& ctx,
                      bool json_to_stdout) {
  OCCMAP_ASSIGN_OR_RETURN(CachedLut cached, LoadOrBuildSiteLut(site, cache_dir, ctx));
  const fs::path cache_path = cache_dir.empty() ? fs::path() : SiteLutPath(site, cache_dir);
  // The cache folder is no output here either (the report is): a failed write is said, not an error.
  if (!cached.write_error.empty()) WarnCacheNotWritten(PrintWarnings("occmap lut"), "table cache", cache_path, cached.write_error);
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out_dir));
  const Image<Rgb8> picture = RenderVisibility(cached.lut, SiteCameraMarkers(site), 1200);
  OCCMAP_RETURN_IF_ERROR(WritePng(out_dir / "visibility.png", picture.view()));
  const json report = CoverageJson(site, cached, cache_path);
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(out_dir / "lut.json", report.dump(2) + "\n"));
  if (json_to_stdout) {
    std::fputs((report.dump(2) + "\n").c_str(), stdout);
    return Status::Ok();
  }
  const FloorGrid& g = site.grid;
  std::fputs(fmt::format("site {}: {} cameras; grid {} x {} cells of {:g} m ({:g} x {:g} m) at z = {:g} m\n", site.name,
                         site.cameras.size(), g.cells_x, g.cells_y, g.cell_size_m, g.size_x_m(), g.size_y_m(),
                         site.lut.plane_height_m)
                 .c_str(),
             stdout);
  std::string how = ToString(cached.outcome);
  if (cached.outcome == LutCacheOutcome::kLoaded) {
    how += fmt::format(" in {:.3f} s", cached.load_seconds);
  } else {
    how += fmt::format("; built in {:.3f} s on {} threads", cached.build_seconds, ctx.num_threads());
  }
  std::fputs(fmt::format("tables: {} ({:.1f} MB){}\n", how, static_cast<double>(cached.lut.MemoryBytes()) / 1e6,
                         cache_path.empty() ? "" : fmt::format(", cache {}", cache_path.string()))
                 .c_str(),
             stdout);
  if (!cached.reason.empty()) std::fputs(fmt::format("  ({})\n", cached.reason).c_str(), stdout);
  std::fputs(CoverageTable(site, cached.lut).c_str(), stdout);
  std::fputs(fmt::format("wrote {} and {}\n", (out_dir / "visibility.png").string(), (out_dir / "lut.json").string()).c_str(),
             stdout);
  return Status::Ok();
}

Status RunLut(const CommonOptions& common, const LutCommand& cmd) {
  SiteLoadOptions load;
  if (!common.data_root.empty()) load.data_root = fs::path(common.data_root);
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(cmd.site_path, load));
  if (cmd.plane_height_m) {
    for (const auto& c : site.cameras) {
      if (!c.camera->SupportsPlaneHeight(*cmd.plane_height_m)) {
        return InvalidInput(fmt::format("--plane-height-m: camera {} has a {} calibration, which only knows the floor",
                                        c.id, c.camera->kind()));
      }
    }
    site.lut.plane_height_m = *cmd.plane_height_m;
    site.plane_height_m = *cmd.plane_height_m;
  }
  Context ctx(common.threads);
  const fs::path cache_dir = cmd.no_cache ? fs::path() : cmd.cache_dir.empty() ? DefaultCacheDir() : fs::path(cmd.cache_dir);
  return WriteLutReport(site, cmd.out_dir, cache_dir, ctx, cmd.json_to_stdout);
}

Status RunCheck(const CommonOptions& common, const std::string& site_path) {
  SiteLoadOptions load;
  if (!common.data_root.empty()) load.data_root = fs::path(common.data_root);
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(site_path, load));
  std::fputs(fmt::format("{}: valid site '{}' with {} cameras\n", site_path, site.name, site.cameras.size()).c_str(), stdout);
  for (const auto& c : site.cameras) {
    const ImageSize s = c.camera->image_size();
    std::string center = "-";
    if (auto p = c.camera->CenterInWorld()) center = fmt::format("({:.2f}, {:.2f}, {:.2f}) m", p->x(), p->y(), p->z());
    std::fputs(fmt::format("  {:<10} {:<11} {}x{}{}  centre {}  mask {}\n", c.id, c.calibration_format, s.width, s.height,
                           s == c.calibrated_size ? "" : fmt::format(" (calibrated {}x{})", c.calibrated_size.width, c.calibrated_size.height),
                           center, c.mask.empty() ? "none" : "yes")
                   .c_str(),
               stdout);
  }
  return Status::Ok();
}

// A progress bar on a terminal (stderr), nothing when piped. Callers that know no elapsed time
// (demo, synth: elapsed_s 0) get the bar's own, from its first update after a Finish.
class ProgressBar {
 public:
  ProgressBar() : enabled_(::isatty(STDERR_FILENO) == 1) {}
  ~ProgressBar() { Finish(); }
  void Update(RunProgress p, const std::string& label = "") {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (!started_) {
      start_ = now;
      started_ = true;
    }
    if (p.elapsed_s <= 0) p.elapsed_s = std::chrono::duration<double>(now - start_).count();
    // Redrawn at most 10 times a second (a terminal write per frame costs a fast run time),
    // and always at the last frame.
    const bool last = p.frames_total && p.frames_done >= *p.frames_total;
    if (shown_ && !last && p.elapsed_s - drawn_s_ < 0.1) return;
    drawn_s_ = p.elapsed_s;
    const double fps = p.elapsed_s > 0 ? static_cast<double>(p.frames_done) / p.elapsed_s : 0;
    std::string line;
    if (p.frames_total && *p.frames_total > 0) {
      const double f = std::min(1.0, static_cast<double>(p.frames_done) / static_cast<double>(*p.frames_total));
      const int width = 30, filled = static_cast<int>(f * width);
      const double eta = fps > 0 ? static_cast<double>(*p.frames_total - p.frames_done) / fps : 0;
      line = fmt::format("\r{}[{}{}] {:>3.0f}% {}/{}", label.empty() ? "" : label + " ", std::string(filled, '#'),
                         std::string(width - filled, '.'), 100 * f, p.frames_done, *p.frames_total);
      if (p.elapsed_s > 0) line += fmt::format("  {:.1f} frames/s  eta {:.0f} s ", fps, eta);
    } else {
      line = fmt::format("\r{}{} done", label.empty() ? "" : label + " ", p.frames_done);
      if (p.elapsed_s > 0) line += fmt::format("  {:.1f} frames/s ", fps);
    }
    std::fputs(line.c_str(), stderr);
    shown_ = true;
  }
  void Finish() {
    if (shown_) std::fputs("\n", stderr);
    shown_ = false;
    started_ = false;
    drawn_s_ = 0;
  }

 private:
  bool enabled_;
  bool shown_ = false;
  bool started_ = false;
  std::chrono::steady_clock::time_point start_;
  double drawn_s_ = 0;
};

struct RunCommand {
  LiveOutputsCommand live;
  std::string site_path;
  RunOptions options;
  std::string cache_dir;
  bool no_cache = false;
  std::string sync = "index";
  bool continue_without_camera = false;
  bool no_video = false;
  bool atomic_outputs = false;
  bool no_wall_clock = false;
  std::optional<double> min_blob_area_m2;
};

Status RunRun(const CommonOptions& common, RunCommand cmd) {
  if (cmd.options.loop && cmd.options.max_frames < 0) {
    return InvalidInput("--loop: give --frames N too (a looped file never ends, and the run's files would grow for ever)");
  }
  SiteLoadOptions load;
  if (!common.data_root.empty()) load.data_root = fs::path(common.data_root);
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(cmd.site_path, load));
  if (cmd.min_blob_area_m2) {
    if (!(*cmd.min_blob_area_m2 >= 0)) return InvalidInput("--min-blob-area-m2: expected >= 0");
    site.objects.min_area_m2 = *cmd.min_blob_area_m2;
  }
  OCCMAP_ASSIGN_OR_RETURN(LiveSinks live, AddLiveSinks(site, cmd.live, cmd.options, "occmap run"));
  // Before any thread starts (the context's pool, the MQTT client's), so that every thread
  // inherits the mask.
  StopOnSignals signals(cmd.options.out_dir);
  Context ctx(common.threads);
  RunOptions& o = cmd.options;
  o.cache_dir = cmd.no_cache ? fs::path() : cmd.cache_dir.empty() ? DefaultCacheDir() : fs::path(cmd.cache_dir);
  o.sync = cmd.sync == "timestamp" ? FrameSync::kTimestamp : FrameSync::kIndex;
  o.on_camera_failure = cmd.continue_without_camera ? OnCameraFailure::kContinue : OnCameraFailure::kStop;
  if (cmd.no_video) o.occupancy_video = o.mosaic_video = false;
  o.output_mode = cmd.atomic_outputs ? OutputMode::kAtomic : OutputMode::kLive;
  o.wall_clock_times = !cmd.no_wall_clock;
  o.stop = signals.stop();
  o.warning = PrintWarnings("occmap run");
  ProgressBar bar;
  auto summary = RunSite(site, o, ctx, [&](const RunProgress& p) { bar.Update(p); });
  bar.Finish();
  if (!summary.ok()) return summary.status();
  const int64_t max_blobs = summary->blobs_max_per_frame;
  const double mean =
      summary->frames > 0 ? static_cast<double>(summary->blobs_total) / static_cast<double>(summary->frames) : 0.0;
  std::fputs(fmt::format("{} frames in {:.2f} s ({:.1f} frames/s; tables {}): {} ; blobs per frame: mean {:.2f}, max {}\n",
                         summary->frames, summary->seconds, summary->frames_per_second, summary->lut_cache,
                         summary->stop_reason, mean, max_blobs)
                 .c_str(),
             stdout);
  for (const auto& c : summary->cameras) {
    std::fputs(fmt::format("  {:<10} {}; background {}{}\n", c.id, c.source, c.background,
                           c.ended_at_frame ? fmt::format("; ended at frame {}: {}", *c.ended_at_frame, c.end_reason) : "")
                   .c_str(),
               stdout);
  }
  PrintLiveSinks(live);
  std::fputs(fmt::format("wrote {}\n", (o.out_dir / "summary.json").string()).c_str(), stdout);
  return Status::Ok();
}

Status RunDemoCommand(const CommonOptions& common, const std::string& out_dir, int64_t frames) {
  Context ctx(common.threads);
  std::fputs("occmap demo: renders the paper's lab (9 x 6.5 m, four 640x480 cameras at 2.7 m, people, a chair,\n"
             "a robot), runs the pipeline on the videos and scores it against the ground truth\n",
             stdout);
  ProgressBar bar;
  std::string stage;
  DemoOptions options;
  options.out_dir = out_dir;
  options.frames = frames;
  auto result = RunDemo(options, ctx, [&](const std::string& name, int64_t done, int64_t total) {
    if (name != stage) {
      bar.Finish();
      stage = name;
    }
    bar.Update({done, total > 0 ? std::optional<int64_t>(total) : std::nullopt, 0}, name);
  });
  bar.Finish();
  if (!result.ok()) return result.status();
  std::fputs(EvaluationReportText(result->evaluation).c_str(), stdout);
  std::fputs(fmt::format("{} frames: rendered in {:.1f} s, run at {:.1f} frames/s, evaluated in {:.1f} s\n",
                         result->run.frames, result->synth_seconds, result->run.frames_per_second, result->eval_seconds)
                 .c_str(),
             stdout);
  const fs::path out(out_dir);
  std::fputs(fmt::format("look at {} (the mosaic video), {} and {}\n", (out / "mosaic.mp4").string(),
                         (out / "mosaic.png").string(), result->summary_file.string())
                 .c_str(),
             stdout);
  return Status::Ok();
}

struct SynthCommand {
  std::string scene = "lab";
  std::string out_dir = "synth-out";
  int64_t frames = -1;
  uint64_t seed = 1;
  double scale = 1.0;
  bool video = false;
  bool shadows = false;
  double exposure_drift = -1;
  double noise_sigma = -1;
  bool original_intrinsics = false;
  int64_t first_frame = 0;
  bool no_change_masks = false;
  int people = -1;
  double duration_s = -1;
  double sun_elevation_deg = -1;
  bool overcast = false;
  bool site_backgrounds = false;
  bool real_camera = false;
  bool ideal_camera = false;
  bool auto_exposure = false;
  std::optional<double> white_balance;
  std::optional<double> read_noise;
  std::optional<double> shot_noise;
  std::optional<int> supersample;
  std::optional<int> jpeg_quality;
  std::optional<int> crf;
  std::optional<double> contact_shadows;
};

Status RunSynth(const CommonOptions& common, const SynthCommand& cmd) {
  sim::BuiltinSceneOptions o;
  o.seed = cmd.seed;
  o.image_scale = cmd.scale;
  o.num_frames = cmd.frames;
  o.noise_sigma = cmd.noise_sigma;
  o.shadows = cmd.shadows;
  o.exposure_drift = cmd.exposure_drift;
  o.people = cmd.people;
  o.duration_s = cmd.duration_s;
  o.sun_elevation_deg = cmd.sun_elevation_deg;
  o.overcast = cmd.overcast;
  if (cmd.real_camera && cmd.ideal_camera) {
    return InvalidInput("--real-camera and --ideal-camera: expected one of them, found both");
  }
  if (cmd.real_camera) o.real_camera = true;
  if (cmd.ideal_camera) o.real_camera = false;
  if (cmd.auto_exposure) o.auto_exposure = true;
  o.white_balance = cmd.white_balance;
  o.read_noise = cmd.read_noise;
  o.shot_noise = cmd.shot_noise;
  o.supersample = cmd.supersample;
  o.jpeg_quality = cmd.jpeg_quality;
  o.video_crf = cmd.crf;
  o.contact_shadows = cmd.contact_shadows;
  OCCMAP_RETURN_IF_ERROR(o.Validate());
  sim::SceneSpec spec;
  if (cmd.scene == "wildtrack") {
    sim::WildtrackSceneOptions w;
    const fs::path root = common.data_root.empty() ? fs::path("../shared/datasets") : fs::path(common.data_root);
    w.dataset_dir = root / "wildtrack";
    w.original_intrinsics = cmd.original_intrinsics;
    w.first_frame = cmd.first_frame;
    OCCMAP_ASSIGN_OR_RETURN(spec, sim::MakeWildtrackSceneSpec(o, w));
  } else if (cmd.scene.ends_with(".yaml") || cmd.scene.ends_with(".yml")) {
    OCCMAP_ASSIGN_OR_RETURN(spec, sim::LoadSceneYaml(cmd.scene));
    OCCMAP_RETURN_IF_ERROR(sim::ApplyBuiltinOptions(o, spec));
  } else {
    OCCMAP_ASSIGN_OR_RETURN(spec, sim::MakeBuiltinSceneSpec(cmd.scene, o));
  }
  OCCMAP_ASSIGN_OR_RETURN(sim::Scene scene, sim::Scene::Create(std::move(spec)));
  sim::DatasetOptions d;
  d.out_dir = cmd.out_dir;
  d.frame_format = cmd.video ? sim::DatasetOptions::FrameFormat::kVideo : sim::DatasetOptions::FrameFormat::kPng;
  d.change_masks = !cmd.no_change_masks;
  // The plaza is run as on a real site: the backgrounds are learnt from the busy frames unless
  // --site-backgrounds hands over the empty scene.
  d.site_backgrounds = cmd.site_backgrounds || scene.spec().name != "plaza";
  if (scene.spec().name == "plaza") {
    // Outdoors, busy and sunny: colour, the background learned and kept up to date from the
    // fused map, cast shadows told from objects (site `backgrounds:`, docs/formats.md).
    d.site_detection_yaml = fmt::format(
        "detection:\n  threshold: {}\n  tolerance_px: 1\n  colour: true\n"
        "# Outdoors, busy and sunny: the background is learned from the video, kept up to date from\n"
        "# the fused map, and cast shadows are told from objects.\n"
        "backgrounds:\n  adaptive: true\n",
        d.detection_threshold);
  }
  Context ctx(common.threads);
  ProgressBar bar;
  auto summary = sim::WriteDataset(scene, d, ctx, [&](const sim::DatasetProgress& p) {
    bar.Update({p.done, p.total > 0 ? std::optional<int64_t>(p.total) : std::nullopt, 0}, p.stage);
  });
  bar.Finish();
  if (!summary.ok()) return summary.status();
  std::fputs(fmt::format("{} frames of {} cameras in {:.1f} s (static {:.1f}, render {:.1f}, ground truth {:.1f}, "
                         "files {:.1f})\nwrote {}; run it with: occmap run {}\n",
                         summary->frames, summary->cameras, summary->seconds, summary->static_seconds,
                         summary->render_seconds, summary->ground_truth_seconds, summary->write_seconds,
                         cmd.out_dir, summary->site_file.string())
                 .c_str(),
             stdout);
  return Status::Ok();
}

struct EvalCommand {
  std::string dataset_dir;
  std::string run_dir;
  double threshold_m = 0.5;
  bool json_to_stdout = false;
  // A benchmark's annotations (eval/benchmark_annotations.h).
  std::string format = "auto";
  std::optional<std::string> frame_step;
  std::optional<int64_t> first_frame;
  std::optional<std::string> annotation_range;
};

// DATASET is read as a benchmark's annotations when a format is given, or when it has no
// ground_truth.jsonl and holds annotations_positions/ (or is that folder).
Result<EvaluationReport> EvaluateEvalCommand(const EvalCommand& cmd, const EvalOptions& o, Context& ctx) {
  const fs::path dataset(cmd.dataset_dir);
  std::error_code ec;
  const bool has_ground_truth = fs::is_regular_file(dataset / "ground_truth.jsonl", ec) ||
                                fs::is_regular_file(dataset / "gt" / "ground_truth.jsonl", ec);
  const bool mapping_given = cmd.frame_step || cmd.first_frame || cmd.annotation_range;
  if (cmd.format == "auto" && has_ground_truth) {
    if (mapping_given) {
      return InvalidInput(fmt::format("--frame-step, --first-frame, --annotation-range: expected a benchmark's annotation "
                                      "folder, found {} (give --format to read its annotations_positions/)",
                                      (dataset / "ground_truth.jsonl").string()));
    }
    return EvaluateRun(dataset, cmd.run_dir, o, ctx);
  }
  if (cmd.format == "auto" && !FindAnnotationFolder(dataset)) {
    return NotFound(fmt::format("{}: no ground truth: expected ground_truth.jsonl, gt/ground_truth.jsonl, "
                                "annotations_positions/ or annotation files (00000005.json)",
                                dataset.string()));
  }
  BenchmarkEvalOptions b;
  if (cmd.format != "auto") {
    OCCMAP_ASSIGN_OR_RETURN(b.format, ParseBenchmarkFormat(cmd.format, "--format"));
  }
  if (cmd.frame_step) {
    OCCMAP_ASSIGN_OR_RETURN(b.frame_step, ParseFrameStep(*cmd.frame_step, "--frame-step"));
  }
  if (cmd.first_frame) b.first_frame = *cmd.first_frame;
  if (cmd.annotation_range) {
    OCCMAP_ASSIGN_OR_RETURN(b.annotation_range, ParseAnnotationRange(*cmd.annotation_range, "--annotation-range"));
  }
  return EvaluateRunOnBenchmark(dataset, cmd.run_dir, b, o, ctx);
}

Status RunEval(const CommonOptions& common, const EvalCommand& cmd) {
  EvalOptions o;
  o.match_threshold_m = cmd.threshold_m;
  Context ctx(common.threads);
  OCCMAP_ASSIGN_OR_RETURN(EvaluationReport report, EvaluateEvalCommand(cmd, o, ctx));
  const std::string json_text = EvaluationReportJson(report).dump(2) + "\n";
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(fs::path(cmd.run_dir) / "evaluation.json", json_text));
  std::fputs(cmd.json_to_stdout ? json_text.c_str() : EvaluationReportText(report).c_str(), stdout);
  if (!cmd.json_to_stdout) {
    std::fputs(fmt::format("wrote {}\n", (fs::path(cmd.run_dir) / "evaluation.json").string()).c_str(), stdout);
  }
  return Status::Ok();
}

struct BenchCommand {
  std::string workload = "all";
  int frames = 4;
  bool json_to_stdout = false;
  std::string site = "sites/wildtrack.yaml";
  int end_to_end_frames = 60;
  double changed_fraction = 0.10;
  int rendered_frames = 4;
  int wildtrack_end_to_end_frames = 30;
  std::vector<std::string> datasets;
  int adaptive_frames = 20;
};

Status RunBenchCommand(const CommonOptions& common, const BenchCommand& cmd) {
  bench::BenchOptions o;
  o.workload = cmd.workload;
  o.frames = cmd.frames;
  o.wildtrack_site = cmd.site;
  o.end_to_end_frames = cmd.end_to_end_frames;
  o.changed_fraction = cmd.changed_fraction;
  o.rendered_frames = cmd.rendered_frames;
  o.wildtrack_end_to_end_frames = cmd.wildtrack_end_to_end_frames;
  for (const std::string& d : cmd.datasets) o.adaptive.datasets.emplace_back(d);
  o.adaptive.frames = cmd.adaptive_frames;
  if (!common.data_root.empty()) o.data_root = common.data_root;
  OCCMAP_RETURN_IF_ERROR(o.Validate());
  Context ctx(common.threads);
  OCCMAP_ASSIGN_OR_RETURN(bench::BenchResults results, bench::RunBench(o, ctx));
  if (cmd.json_to_stdout) {
    fmt::print("{}\n", bench::BenchJson(results).dump(2));
  } else {
    fmt::print("{}", bench::BenchTable(results));
  }
  return Status::Ok();
}

int Fail(const Status& status) {
  std::fputs(fmt::format("occmap: error: {}\n", status.message()).c_str(), stderr);
  return ExitCodeFor(status);
}

}  // namespace
}  // namespace occmap

int main(int argc, char** argv) {
  using namespace occmap;
  // A file-size limit (ulimit -f) then fails the write with EFBIG, which names the file,
  // instead of killing the run before it can write summary.json.
  ::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{"occmap: floor occupancy from several calibrated cameras (volume intersection in a plane)"};
  app.set_version_flag("--version", kVersion);
  app.require_subcommand(1);
  app.fallthrough();  // --threads and --data-root may also follow the subcommand
  CommonOptions common;
  app.add_option("--threads", common.threads, "worker threads (0 = all cores)")->check(CLI::Range(0, 1024));
  app.add_option("--data-root", common.data_root,
                 "folder that relative paths in the site file resolve against (overrides its data_root)");

  LutCommand lut;
  CLI::App* lut_cmd = app.add_subcommand("lut", "build (or load) the lookup tables of a site and report their coverage");
  lut_cmd->add_option("site", lut.site_path, "site file (YAML)")->required();
  lut_cmd->add_option("--out", lut.out_dir, "folder for visibility.png and lut.json")->capture_default_str();
  lut_cmd->add_option("--cache-dir", lut.cache_dir, "folder of cached tables (default: ~/.cache/occmap)");
  lut_cmd->add_flag("--no-cache", lut.no_cache, "always build, never read or write a cache file");
  lut_cmd->add_option("--plane-height-m", lut.plane_height_m, "height of the plane (default: the site's, 0 = floor)");
  lut_cmd->add_flag("--json", lut.json_to_stdout, "print the report as JSON instead of a table");

  std::string check_site;
  CLI::App* check_cmd = app.add_subcommand("check", "validate a site file and list its cameras");
  check_cmd->add_option("site", check_site, "site file (YAML)")->required();

  RunCommand run;
  CLI::App* run_cmd = app.add_subcommand("run", "the main job: occupancy, detections and mosaic from the site's cameras");
  run_cmd->add_option("site", run.site_path, "site file (YAML)")->required();
  run_cmd->add_option("--out", run.options.out_dir, "output folder")->capture_default_str();
  // -1 is the library's "until a source ends": not a count a user may give.
  run_cmd->add_option("--frames", run.options.max_frames, "process at most N frames")
      ->check(CLI::Range(int64_t{1}, int64_t{1'000'000'000'000}));
  run_cmd->add_option("--start", run.options.start_frame, "first frame of every source")
      ->capture_default_str()
      ->check(CLI::Range(int64_t{0}, int64_t{1'000'000'000'000}));
  run_cmd->add_flag("--loop", run.options.loop,
                    "read video files and image sequences again from their start when they end (with --frames)");
  run_cmd->add_option("--cache-dir", run.cache_dir, "folder of cached tables and backgrounds (default: ~/.cache/occmap)");
  run_cmd->add_flag("--no-cache", run.no_cache, "never read or write cached tables or backgrounds");
  run_cmd->add_option("--sync", run.sync, "synchronise cameras by frame index or timestamp")
      ->check(CLI::IsMember({"index", "timestamp"}))->capture_default_str();
  run_cmd->add_option("--sync-tolerance-s", run.options.sync_tolerance_s,
                      "--sync timestamp: a camera's frame within this many seconds of camera 0's joins its frame "
                      "set (older ones are dropped, later ones wait)")
      ->capture_default_str();
  run_cmd->add_flag("--continue-without-camera", run.continue_without_camera,
                    "when a camera's stream ends or fails, go on without it (its cells become unseen)");
  run_cmd->add_option("--camera-lost-after-s", run.options.camera_lost_after_s,
                      "a live stream without a frame this long ends the run (camera lost), unless "
                      "--continue-without-camera (then it keeps reconnecting)")
      ->capture_default_str();
  run_cmd->add_flag("--occupancy-pngs", run.options.occupancy_pngs, "also write occupancy/NNNNNN.png per frame");
  run_cmd->add_flag("--change-pngs", run.options.change_pngs,
                    "also write changes/<camera>/NNNNNN.png per frame (changed pixels, before the tolerance)");
  run_cmd->add_flag("--no-video", run.no_video, "do not write occupancy.mp4 and mosaic.mp4");
  run_cmd->add_flag("--no-wall-clock", run.no_wall_clock,
                    "leave t_unix (wall-clock time) out of the JSON lines: outputs that depend on the inputs alone");
  run_cmd->add_flag("--atomic-outputs", run.atomic_outputs,
                    "write the outputs through temporaries renamed at the end (all or nothing) instead of "
                    "appending whole lines per frame set");
  run_cmd->add_option("--summary-every-s", run.options.summary_every_s,
                      "rewrite summary.json with the running figures this often (0 = only at the end)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  run_cmd->add_option("--background-frames", run.options.background_frames,
                      "K: frames in the median background of a camera without one")->capture_default_str();
  run_cmd->add_option("--min-blob-area-m2", run.min_blob_area_m2, "drop detections with a smaller footprint (default: the site's blobs.min_area_m2)");
  AddLiveOutputOptions(*run_cmd, run.live);

  std::string demo_out = "demo-out";
  int64_t demo_frames = -1;
  CLI::App* demo_cmd = app.add_subcommand("demo", "render the built-in lab scene, run on it and score the result");
  demo_cmd->add_option("--out", demo_out, "output folder")->capture_default_str();
  demo_cmd->add_option("--frames", demo_frames, "frames to render (default: the scene's 100)")
      ->check(CLI::Range(int64_t{1}, int64_t{10'000'000}));  // a scene's limit (sim/scene.cc)

  SynthCommand synth;
  CLI::App* synth_cmd = app.add_subcommand("synth", "render a scene with exact ground truth into a dataset folder");
  synth_cmd->add_option("--scene", synth.scene, "lab, clemson, wildtrack, plaza, or a scene YAML file")->capture_default_str();
  synth_cmd->add_option("--out", synth.out_dir, "dataset folder")->capture_default_str();
  synth_cmd->add_option("--frames", synth.frames, "frames to render (default: the scene's length)")
      ->check(CLI::Range(int64_t{1}, int64_t{10'000'000}));  // a scene's limit (sim/scene.cc)
  synth_cmd->add_option("--seed", synth.seed, "random seed (clothing, noise)")->capture_default_str();
  synth_cmd->add_option("--scale", synth.scale, "image size as a fraction of the cameras' native size")
      ->capture_default_str();
  synth_cmd->add_flag("--video", synth.video, "write H.264 videos instead of PNG (or JPEG) frames");
  synth_cmd->add_flag("--shadows", synth.shadows, "cast shadows on the floor (plaza: always)");
  synth_cmd->add_option("--exposure-drift", synth.exposure_drift,
                        "slow exposure drift, relative amplitude (default: the scene's, plaza 0.1, else 0)");
  synth_cmd->add_option("--noise", synth.noise_sigma, "sensor noise sigma in grey levels (default 2)");
  synth_cmd->add_flag("--original-intrinsics", synth.original_intrinsics, "wildtrack: distorted raw-frame intrinsics");
  synth_cmd->add_option("--first-frame", synth.first_frame, "wildtrack: first 10 fps frame of the dataset");
  synth_cmd->add_flag("--no-change-masks", synth.no_change_masks, "do not write the perfect change masks");
  synth_cmd->add_option("--people", synth.people, "plaza: people in the area at a time, 1..40 (default 16)");
  synth_cmd->add_option("--duration-s", synth.duration_s, "plaza: length of the scene in seconds (default 60)");
  synth_cmd->add_option("--sun-elevation-deg", synth.sun_elevation_deg,
                        "plaza: the sun's elevation, 5..90 degrees (default 25)");
  synth_cmd->add_flag("--site-backgrounds", synth.site_backgrounds,
                      "plaza: give the empty-scene backgrounds in site.yaml (by default the run learns them)");
  synth_cmd->add_flag("--overcast", synth.overcast,
                      "plaza: an overcast sky instead of the sun (no cast shadows; soft contact shadows)");
  synth_cmd->add_flag("--real-camera", synth.real_camera,
                      "a real camera: automatic exposure and white balance following the content, shot and read "
                      "noise, rendered at twice the size and downscaled, JPEG 75 (H.264 crf 28), contact shadows");
  synth_cmd->add_flag("--ideal-camera", synth.ideal_camera, "the ideal camera, no contact shadows (the scene's are off)");
  synth_cmd->add_flag("--auto-exposure", synth.auto_exposure,
                      "automatic exposure: the frame's mean luma held at the empty view's");
  synth_cmd->add_option("--white-balance", synth.white_balance,
                        "automatic grey-world white balance of this strength, 0..1 (0 = off)");
  synth_cmd->add_option("--read-noise", synth.read_noise, "sensor read noise sigma per channel, grey levels");
  synth_cmd->add_option("--shot-noise", synth.shot_noise, "sensor shot noise: variance per grey level of signal");
  synth_cmd->add_option("--supersample", synth.supersample,
                        "render N x N rays per pixel and average them (downscaling), 1..4");
  synth_cmd->add_option("--jpeg-quality", synth.jpeg_quality, "write the frames as JPEG of this quality, 1..100 (0 = PNG)");
  synth_cmd->add_option("--crf", synth.crf, "with --video: H.264 constant rate factor, 0..51 (-1 = 23)");
  synth_cmd->add_option("--contact-shadows", synth.contact_shadows,
                        "soft contact shadows around objects' feet, strength 0..1 (0 = off)");

  EvalCommand eval;
  CLI::App* eval_cmd = app.add_subcommand("eval", "score a run against a dataset's ground truth");
  eval_cmd->add_option("dataset", eval.dataset_dir,
                       "dataset folder (ground_truth.jsonl, gt/), or a WILDTRACK / MultiviewX dataset root holding "
                       "annotations_positions/ (or that folder)")
      ->required();
  eval_cmd->add_option("run", eval.run_dir, "run folder (detections.jsonl, tracks.jsonl, occupancy/, changes/)")
      ->required();
  eval_cmd->add_option("--threshold-m", eval.threshold_m, "match distance")->capture_default_str();
  eval_cmd->add_flag("--json", eval.json_to_stdout, "print the report as JSON");
  eval_cmd->add_option("--format", eval.format,
                       "annotations: wildtrack, multiviewx or terrace (auto: from the file names, 8, 5 or 6 digits)")
      ->check(CLI::IsMember({"auto", "wildtrack", "multiviewx", "terrace"}))
      ->capture_default_str();
  eval_cmd->add_option("--frame-step", eval.frame_step,
                       "annotations: annotation numbers per run frame, N or P/Q (default wildtrack 5, multiviewx and terrace 1: "
                       "a run over the distributed images; 1 for 10 fps WILDTRACK frames)");
  eval_cmd->add_option("--first-frame", eval.first_frame,
                       "annotations: the annotation number of run frame 0 (default 0; file = F + step x frame)")
      ->check(CLI::Range(int64_t{0}, int64_t{999'999'999'999}));
  eval_cmd->add_option("--annotation-range", eval.annotation_range,
                       "annotations: FIRST:LAST annotation numbers to evaluate, e.g. 1800:1995 (default: the run's "
                       "frames)");

  BenchCommand bench_opts;
  CLI::App* bench_cmd = app.add_subcommand("bench", "measure change detection + fusion: paper loop, OpenCV, fast path");
  bench_cmd->add_option("--workload", bench_opts.workload,
                        "paper, wildtrack, adaptive (the real-scene path on --dataset's frames) or all")
      ->capture_default_str();
  bench_cmd->add_option("--dataset", bench_opts.datasets,
                        "adaptive workload: a dataset folder written by `occmap synth` (or a site file); repeatable");
  bench_cmd->add_option("--adaptive-frames", bench_opts.adaptive_frames,
                        "adaptive workload: frame sets read, learned from and cycled through")
      ->capture_default_str()
      ->check(CLI::Range(2, 255));
  bench_cmd->add_option("--frames", bench_opts.frames, "distinct random frames per repetition")->capture_default_str();
  bench_cmd->add_option("--site", bench_opts.site, "the WILDTRACK site file")->capture_default_str();
  bench_cmd->add_option("--end-to-end-frames", bench_opts.end_to_end_frames,
                        "lab frames rendered to H.264 for RunSite vs decode (0 = skip)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  bench_cmd->add_option("--changed-fraction", bench_opts.changed_fraction,
                        "fraction of pixels changed in the random frames, 0..1")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  bench_cmd->add_option("--rendered-frames", bench_opts.rendered_frames,
                        "WILDTRACK frames rendered by the simulator for the wildtrack workload (0 = skip)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100));
  bench_cmd->add_option("--wildtrack-end-to-end-frames", bench_opts.wildtrack_end_to_end_frames,
                        "WILDTRACK scene frames rendered to 1920x1080 H.264 for its own RunSite vs decode "
                        "(0 = skip, else 22..2000)")
      ->capture_default_str();
  bench_cmd->add_flag("--json", bench_opts.json_to_stdout, "print one JSON object with a record per workload");

  CalibrateCommand calibrate;
  CLI::App* calibrate_cmd = AddCalibrateCommand(app, calibrate);
  ServeCommand serve;
  CLI::App* serve_cmd = AddServeCommand(app, serve);
  EdgeCommand edge;
  CLI::App* edge_cmd = AddEdgeCommand(app, edge);
  FuseCommand fuse;
  CLI::App* fuse_cmd = AddFuseCommand(app, fuse);
  EdgeSimCommand edge_sim;
  CLI::App* edge_sim_cmd = AddEdgeSimCommand(app, edge_sim);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // A mistyped command ("occmap runn"): CLI11 would only say that one is required.
    if (app.get_subcommands().empty()) {
      std::vector<std::string> names;
      for (const CLI::App* sub : app.get_subcommands({})) names.push_back(sub->get_name());
      for (int k = 1; k < argc; ++k) {
        const std::string_view arg = argv[k];
        if (arg == "--threads" || arg == "--data-root") ++k;  // their values
        if (arg.empty() || arg.front() == '-') continue;
        if (std::find(names.begin(), names.end(), arg) != names.end()) break;
        const std::string nearest = NearestName(arg, names);
        std::fputs(fmt::format("occmap: error: unknown command '{}'{}; `occmap --help` lists them\n", arg,
                               nearest.empty() ? "" : fmt::format(" (did you mean '{}'?)", nearest))
                       .c_str(),
                   stderr);
        return 2;
      }
    }
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  Status status;
  if (lut_cmd->parsed()) status = RunLut(common, lut);
  if (run_cmd->parsed()) status = RunRun(common, run);
  if (check_cmd->parsed()) status = RunCheck(common, check_site);
  if (demo_cmd->parsed()) status = RunDemoCommand(common, demo_out, demo_frames);
  if (synth_cmd->parsed()) status = RunSynth(common, synth);
  if (eval_cmd->parsed()) status = RunEval(common, eval);
  if (bench_cmd->parsed()) status = RunBenchCommand(common, bench_opts);
  if (calibrate_cmd->parsed()) status = RunCalibrate(calibrate, common.data_root);
  if (serve_cmd->parsed()) status = RunServe(serve, common.threads, common.data_root);
  if (edge_cmd->parsed()) status = RunEdgeCommand(edge, common.threads, common.data_root);
  if (fuse_cmd->parsed()) status = RunFuseCommand(fuse, common.threads, common.data_root);
  if (edge_sim_cmd->parsed()) status = RunEdgeSimCommand(edge_sim, common.data_root);
  return status.ok() ? 0 : Fail(status);
}
