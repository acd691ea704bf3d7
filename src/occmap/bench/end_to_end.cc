// The end-to-end measurement of `occmap bench`: `occmap run` over H.264 files of the lab scene
// against a pure decoding pass of the same files (same decoder, same threads).
#include <fmt/core.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <unistd.h>

#include "occmap/bench/bench.h"
#include "occmap/io/frame_source.h"
#include "occmap/pipeline/run.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/sim/scene.h"
#include "occmap/site/site.h"

namespace occmap::bench {
namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

Result<EndToEndResult> MeasureEndToEnd(int frames, Context& ctx) {
  EndToEndResult e;
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
  OCCMAP_ASSIGN_OR_RETURN(sim::SceneSpec spec, sim::MakeBuiltinSceneSpec("lab", o));
  OCCMAP_ASSIGN_OR_RETURN(sim::Scene scene, sim::Scene::Create(std::move(spec)));
  sim::DatasetOptions d;
  d.out_dir = dir / "dataset";
  d.frame_format = sim::DatasetOptions::FrameFormat::kVideo;
  d.change_masks = false;
  d.gt_rasters = false;
  OCCMAP_ASSIGN_OR_RETURN(sim::DatasetSummary written, sim::WriteDataset(scene, d, ctx));
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(written.site_file));
  e.cameras = static_cast<int>(site.cameras.size());
  // Pure decode: every camera's file to the end, same decoder threads as RunSite.
  FrameSourceOptions src;
  src.decoder_threads = ctx.num_threads();
  const auto t0 = Clock::now();
  int64_t decoded = 0;
  for (const SiteCamera& cam : site.cameras) {
    OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> source, OpenFrameSource(cam.source, src));
    Frame frame;
    int64_t n = 0;
    while (true) {
      OCCMAP_ASSIGN_OR_RETURN(bool got, source->Read(frame));
      if (!got) break;
      ++n;
    }
    decoded = std::max(decoded, n);
  }
  const double decode_s = std::chrono::duration<double>(Clock::now() - t0).count();
  e.decode_fps = decode_s > 0 ? static_cast<double>(decoded) / decode_s : 0;
  RunOptions r;
  r.out_dir = dir / "run";
  r.occupancy_video = false;
  r.mosaic_video = false;
  OCCMAP_ASSIGN_OR_RETURN(RunSummary run, RunSite(site, r, ctx));
  e.frames = run.frames;
  e.run_fps = run.frames_per_second;
  e.decode_s = run.decode_s;
  e.detect_s = run.detect_s;
  e.fuse_s = run.fuse_s;
  e.measured = true;
  e.note = fmt::format("lab scene, {} cameras 640x480 H.264, {} frames; RunSite (no video outputs, fully fused "
                       "FastFusion path, frames decoded on a reader thread) includes its start-up (backgrounds, "
                       "tables), detections and tracking",
                       e.cameras, e.frames);
  return e;
}

}  // namespace occmap::bench
