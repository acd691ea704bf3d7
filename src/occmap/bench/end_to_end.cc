// The end-to-end measurement of `occmap bench`: `occmap run` over H.264 files of a rendered
// scene (the lab, or WILDTRACK's real geometry and trajectories) against pure decoding of the
// same files.
//
// "Sustains" is a steady-state rate: both sides leave out the first kWarmUp frame sets (opening,
// decoders filling their pipelines) and are timed from the completion of set kWarmUp + 1 to the
// last; RunSite's start-up (sources, tables, first frames) is reported apart, in seconds. The
// decoding reference reads the same files with the same decoder options in two ways, and the
// faster one counts: one thread per camera side by side (as RunSite's reader decodes, with
// DecoderThreadsPerCamera threads each), and one thread reading the cameras in turn with
// frame-threaded decoders (every thread each). On a machine shared with other work the passes
// alternate (decode, decode, run; repeated) and the rates are medians; the CPU time per frame
// set of the process is reported beside them, as it depends less on other load.
//
// A site with a people detector (the WILDTRACK scene: `occmap synth` writes people: {detector:
// explain} and the scene's statics for a scene of people only) is run as written, the new
// default, and also without it (people.enabled = false: the floor AND and its blobs), the two
// runs alternating in each repeat (decode, decode, people, floor; then floor first), so that
// both stand against the same decoding passes.
#include <fmt/core.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "occmap/bench/bench.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/io/frame_source.h"
#include "occmap/pipeline/run.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/sim/scene.h"
#include "occmap/site/site.h"

namespace occmap::bench {
namespace {
using Clock = std::chrono::steady_clock;

constexpr int64_t kWarmUp = 10;  // as RunSite's steady state
constexpr int kRepeats = 3;

double CpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 == 1 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

struct DecodePass {
  double steady_fps = 0;
  double cpu_ms_per_set = 0;
  double steady_cpu_ms_per_set = 0;  // from set kWarmUp + 1 to the last, as steady_fps
};

// The process's CPU time at the frame sets a pass's steady rate is timed between (the first,
// kWarmUp + 1, the last), and the CPU per frame set over them (as RunSummary::steady_fps: after
// the warm-up, or from the first set in a short pass; 0 with fewer than two sets).
struct SteadyCpu {
  double first = 0, warm = 0, last = 0;
  int64_t sets = 0;
  void At(int64_t set) {
    const double now = CpuSeconds();
    if (set == 1) first = now;
    if (set == kWarmUp + 1) warm = now;
    last = now;
    sets = set;
  }
  double MsPerSet() const {
    const bool long_pass = sets > 2 * kWarmUp;
    const int64_t from = long_pass ? kWarmUp + 1 : 1;
    return sets > from ? 1e3 * (last - (long_pass ? warm : first)) / static_cast<double>(sets - from) : 0;
  }
};

// Decodes every camera's file to the end, a frame set at a time (one frame of each camera), as
// RunSite's reader does: in parallel, one task per camera (parallel), or in turn on this thread.
Result<DecodePass> Decode(const Site& site, const FrameSourceOptions& options, bool parallel) {
  std::vector<std::unique_ptr<FrameSource>> sources;
  for (const SiteCamera& cam : site.cameras) {
    OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> source, OpenFrameSource(cam.source, options));
    sources.push_back(std::move(source));
  }
  Context decode_ctx(parallel ? static_cast<int>(sources.size()) : 1);
  std::vector<Frame> frames(sources.size());
  std::vector<Status> status(sources.size());
  std::vector<char> got(sources.size(), 0);
  const double cpu0 = CpuSeconds();
  int64_t sets = 0;
  Clock::time_point t_first, t_warm, t_last;
  SteadyCpu steady_cpu;
  while (true) {
    decode_ctx.pool().Run(static_cast<int>(sources.size()), [&](int n, int) {
      auto r = sources[n]->Read(frames[n]);
      got[n] = r.ok() && *r;
      status[n] = r.ok() ? Status::Ok() : r.status();
    });
    for (const Status& s : status) OCCMAP_RETURN_IF_ERROR(s);
    if (std::count(got.begin(), got.end(), 1) != static_cast<ptrdiff_t>(got.size())) break;
    ++sets;
    t_last = Clock::now();
    steady_cpu.At(sets);
    if (sets == 1) t_first = t_last;
    if (sets == kWarmUp + 1) t_warm = t_last;
  }
  DecodePass pass;
  pass.cpu_ms_per_set = sets > 0 ? 1e3 * (CpuSeconds() - cpu0) / static_cast<double>(sets) : 0;
  // As RunSummary::steady_fps: after the warm-up, or from the first set in a short pass.
  const bool long_pass = sets > 2 * kWarmUp;
  const int64_t steady_sets = long_pass ? sets - kWarmUp - 1 : sets - 1;
  const double seconds = std::chrono::duration<double>(t_last - (long_pass ? t_warm : t_first)).count();
  pass.steady_fps = steady_sets > 0 && seconds > 0 ? static_cast<double>(steady_sets) / seconds : 0;
  pass.steady_cpu_ms_per_set = steady_cpu.MsPerSet();
  return pass;
}

bool PeopleDetectorOn(const Site& site) {
  return site.people.enabled && site.people.detector != PeopleDetector::kFloor;
}

struct RunPass {
  RunSummary summary;
  double cpu_ms_per_set = 0, steady_cpu_ms_per_set = 0;
};

Result<RunPass> TimedRun(const Site& site, const RunOptions& options, Context& ctx) {
  RunPass pass;
  const double cpu0 = CpuSeconds();
  // The process's CPU time at the frame sets RunSite's steady rate is timed between (its
  // progress is reported after each frame set's post stage).
  SteadyCpu steady_cpu;
  const ProgressCallback progress = [&](const RunProgress& p) { steady_cpu.At(p.frames_done); };
  OCCMAP_ASSIGN_OR_RETURN(pass.summary, RunSite(site, options, ctx, progress));
  pass.steady_cpu_ms_per_set = steady_cpu.MsPerSet();
  pass.cpu_ms_per_set =
      pass.summary.frames > 0 ? 1e3 * (CpuSeconds() - cpu0) / static_cast<double>(pass.summary.frames) : 0;
  return pass;
}

}  // namespace

Result<EndToEndResult> MeasureEndToEnd(int frames, Context& ctx, const std::filesystem::path& wildtrack_dir) {
  EndToEndResult e;
  const bool wildtrack = !wildtrack_dir.empty();
  e.scene = wildtrack ? "wildtrack" : "lab";
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / fmt::format("occmap-bench-{}", static_cast<long>(getpid()));
  std::error_code ec;
  fs::remove_all(dir, ec);
  struct Cleanup {
    fs::path dir;
    ~Cleanup() {
      std::error_code ignored;
      fs::remove_all(dir, ignored);
    }
  } cleanup{dir};
  sim::BuiltinSceneOptions o;
  o.num_frames = frames;
  sim::SceneSpec spec;
  if (wildtrack) {
    sim::WildtrackSceneOptions wt;
    wt.dataset_dir = wildtrack_dir;
    OCCMAP_ASSIGN_OR_RETURN(spec, sim::MakeWildtrackSceneSpec(o, wt));
  } else {
    OCCMAP_ASSIGN_OR_RETURN(spec, sim::MakeBuiltinSceneSpec("lab", o));
  }
  OCCMAP_ASSIGN_OR_RETURN(sim::Scene scene, sim::Scene::Create(std::move(spec)));
  sim::DatasetOptions d;
  d.out_dir = dir / "dataset";
  d.frame_format = sim::DatasetOptions::FrameFormat::kVideo;
  d.change_masks = false;
  d.gt_rasters = false;
  OCCMAP_ASSIGN_OR_RETURN(sim::DatasetSummary written, sim::WriteDataset(scene, d, ctx));
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(written.site_file));
  e.cameras = static_cast<int>(site.cameras.size());

  // The decoder options of RunSite (grey, DecoderThreadsPerCamera threads each), and the
  // frame-threaded alternative.
  FrameSourceOptions parallel_options;
  parallel_options.decoder_threads = DecoderThreadsPerCamera(ctx.num_threads(), e.cameras);
  FrameSourceOptions interleaved_options;
  interleaved_options.decoder_threads = ctx.num_threads();
  RunOptions r;
  r.out_dir = dir / "run";
  r.occupancy_video = false;
  r.mosaic_video = false;
  std::vector<double> parallel_fps, interleaved_fps, decode_cpu, run_fps, run_cpu, startup, overall;
  std::vector<double> decode_steady_cpu, run_steady_cpu;
  std::vector<double> latency_p50, latency_p95, latency_p99;
  std::vector<double> floor_fps, floor_cpu, floor_steady_cpu, floor_startup, floor_overall;
  RunSummary run, floor_run;
  const bool people = PeopleDetectorOn(site);
  e.people_detector = people ? ToString(site.people.detector) : "floor";
  for (int k = 0; k < kRepeats; ++k) {
    OCCMAP_ASSIGN_OR_RETURN(DecodePass par, Decode(site, parallel_options, /*parallel=*/true));
    OCCMAP_ASSIGN_OR_RETURN(DecodePass inter, Decode(site, interleaved_options, /*parallel=*/false));
    parallel_fps.push_back(par.steady_fps);
    interleaved_fps.push_back(inter.steady_fps);
    decode_cpu.push_back(par.steady_fps >= inter.steady_fps ? par.cpu_ms_per_set : inter.cpu_ms_per_set);
    decode_steady_cpu.push_back(par.steady_fps >= inter.steady_fps ? par.steady_cpu_ms_per_set
                                                                   : inter.steady_cpu_ms_per_set);
    // The site as written, and without its people detector (odd repeats: the floor first).
    for (const bool floor_pass : {k % 2 == 1, k % 2 == 0}) {
      if (floor_pass && !people) continue;
      site.people.enabled = people && !floor_pass;
      auto pass = TimedRun(site, r, ctx);
      site.people.enabled = people;
      OCCMAP_RETURN_IF_ERROR(pass.status());
      if (floor_pass) {
        floor_run = pass->summary;
        floor_steady_cpu.push_back(pass->steady_cpu_ms_per_set);
        floor_cpu.push_back(pass->cpu_ms_per_set);
        floor_fps.push_back(floor_run.steady_fps);
        floor_startup.push_back(floor_run.startup_s);
        floor_overall.push_back(floor_run.frames_per_second);
      } else {
        run = pass->summary;
        run_steady_cpu.push_back(pass->steady_cpu_ms_per_set);
        run_cpu.push_back(pass->cpu_ms_per_set);
        run_fps.push_back(run.steady_fps);
        startup.push_back(run.startup_s);
        overall.push_back(run.frames_per_second);
        latency_p50.push_back(run.latency.p50_ms);
        latency_p95.push_back(run.latency.p95_ms);
        latency_p99.push_back(run.latency.p99_ms);
      }
    }
  }
  e.repeats = kRepeats;
  e.decode_parallel_fps = Median(parallel_fps);
  e.decode_interleaved_fps = Median(interleaved_fps);
  e.decode_fps = std::max(e.decode_parallel_fps, e.decode_interleaved_fps);
  e.decode_cpu_ms_per_frame = Median(decode_cpu);
  e.frames = run.frames;
  e.run_fps = Median(run_fps);
  e.run_overall_fps = Median(overall);
  e.run_startup_s = Median(startup);
  e.run_cpu_ms_per_frame = Median(run_cpu);
  e.run_steady_cpu_ms_per_frame = Median(run_steady_cpu);
  e.decode_steady_cpu_ms_per_frame = Median(decode_steady_cpu);
  e.decode_s = run.decode_s;
  e.detect_s = run.detect_s;
  e.fuse_s = run.fuse_s;
  e.blobs_s = run.blobs_s;
  e.track_s = run.track_s;
  e.output_s = run.output_s;
  e.people_s = run.people_s;
  e.latency_p50_ms = Median(latency_p50);
  e.latency_p95_ms = Median(latency_p95);
  e.latency_p99_ms = Median(latency_p99);
  if (people) {
    EndToEndResult::FloorPass& f = e.floor;
    f.measured = true;
    f.fusion_path = floor_run.fusion_path;  // RunSite's own choice (RunFusionPlan)
    f.run_fps = Median(floor_fps);
    f.run_overall_fps = Median(floor_overall);
    f.run_startup_s = Median(floor_startup);
    f.run_cpu_ms_per_frame = Median(floor_cpu);
    f.run_steady_cpu_ms_per_frame = Median(floor_steady_cpu);
    f.fuse_s = floor_run.fuse_s;
    f.detect_s = floor_run.detect_s;
    f.blobs_s = floor_run.blobs_s;
    f.track_s = floor_run.track_s;
  }
  e.measured = true;
  const ImageSize size = site.cameras.front().camera->image_size();
  e.note = fmt::format("{} scene, {} cameras {}x{} H.264, {} frames, {} threads; steady state (after {} frames), "
                       "medians of {} alternated passes; RunSite without video outputs ({}, detections, tracking, "
                       "text outputs); decoding: the faster of one thread per camera and the cameras in turn{}",
                       e.scene, e.cameras, size.width, size.height, e.frames, ctx.num_threads(), kWarmUp, kRepeats,
                       run.fusion_path,
                       people ? fmt::format("; also without the people detector ({})", e.floor.fusion_path)
                              : std::string());
  return e;
}

double EndToEndResult::OwnCpuVsDecode() const {
  return decode_steady_cpu_ms_per_frame > 0
             ? (run_steady_cpu_ms_per_frame - decode_steady_cpu_ms_per_frame) / decode_steady_cpu_ms_per_frame
             : 0.0;
}

double EndToEndResult::FloorOwnCpuVsDecode() const {
  return floor.measured && decode_steady_cpu_ms_per_frame > 0
             ? (floor.run_steady_cpu_ms_per_frame - decode_steady_cpu_ms_per_frame) / decode_steady_cpu_ms_per_frame
             : 0.0;
}

}  // namespace occmap::bench
