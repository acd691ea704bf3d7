// occmap: the command-line program. Thin: parse arguments, call the library, turn a Status
// into a message on stderr and an exit code (2 for bad input, 1 for other failures).
#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <unistd.h>

#include "occmap/lut/visibility_image.h"
#include "occmap/pipeline/run.h"
#include "occmap/site/demo_scene.h"
#include "occmap/site/site.h"
#include "occmap/site/site_lut.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/thread_pool.h"

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

// The default cache folder: $XDG_CACHE_HOME/occmap, else ~/.cache/occmap, else ./.occmap-cache.
fs::path DefaultCacheDir() {
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg != nullptr && *xdg != '\0') return fs::path(xdg) / "occmap";
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') return fs::path(home) / ".cache" / "occmap";
  return ".occmap-cache";
}

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

Status RunDemo(const CommonOptions& common, const std::string& out_dir) {
  const Site site = MakeDemoLabSite();
  Context ctx(common.threads);
  std::fputs("occmap demo: the paper's lab (9 x 6.5 m, four 640x480 cameras at 2.7 m), built in code\n", stdout);
  OCCMAP_RETURN_IF_ERROR(WriteLutReport(site, out_dir, fs::path(), ctx, false));
  std::fputs(fmt::format("look at {} for the floor seen by each camera count\n", (fs::path(out_dir) / "visibility.png").string())
                 .c_str(),
             stdout);
  return Status::Ok();
}

// A progress bar on a terminal (stderr), nothing when piped.
class ProgressBar {
 public:
  ProgressBar() : enabled_(::isatty(STDERR_FILENO) == 1) {}
  ~ProgressBar() { Finish(); }
  void Update(const RunProgress& p) {
    if (!enabled_) return;
    const double fps = p.elapsed_s > 0 ? static_cast<double>(p.frames_done) / p.elapsed_s : 0;
    std::string line;
    if (p.frames_total && *p.frames_total > 0) {
      const double f = std::min(1.0, static_cast<double>(p.frames_done) / static_cast<double>(*p.frames_total));
      const int width = 30, filled = static_cast<int>(f * width);
      const double eta = fps > 0 ? static_cast<double>(*p.frames_total - p.frames_done) / fps : 0;
      line = fmt::format("\r[{}{}] {:>3.0f}% {}/{} frames  {:.1f} frames/s  eta {:.0f} s ", std::string(filled, '#'),
                         std::string(width - filled, '.'), 100 * f, p.frames_done, *p.frames_total, fps, eta);
    } else {
      line = fmt::format("\r{} frames  {:.1f} frames/s ", p.frames_done, fps);
    }
    std::fputs(line.c_str(), stderr);
    shown_ = true;
  }
  void Finish() {
    if (shown_) std::fputs("\n", stderr);
    shown_ = false;
  }

 private:
  bool enabled_;
  bool shown_ = false;
};

struct RunCommand {
  std::string site_path;
  RunOptions options;
  std::string cache_dir;
  bool no_cache = false;
  std::string sync = "index";
  bool continue_without_camera = false;
  bool no_video = false;
};

Status RunRun(const CommonOptions& common, RunCommand cmd) {
  SiteLoadOptions load;
  if (!common.data_root.empty()) load.data_root = fs::path(common.data_root);
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(cmd.site_path, load));
  Context ctx(common.threads);
  RunOptions& o = cmd.options;
  o.cache_dir = cmd.no_cache ? fs::path() : cmd.cache_dir.empty() ? DefaultCacheDir() : fs::path(cmd.cache_dir);
  o.sync = cmd.sync == "timestamp" ? FrameSync::kTimestamp : FrameSync::kIndex;
  o.on_camera_failure = cmd.continue_without_camera ? OnCameraFailure::kContinue : OnCameraFailure::kStop;
  if (cmd.no_video) o.occupancy_video = o.mosaic_video = false;
  ProgressBar bar;
  auto summary = RunSite(site, o, ctx, [&](const RunProgress& p) { bar.Update(p); });
  bar.Finish();
  if (!summary.ok()) return summary.status();
  size_t max_blobs = 0;
  double mean = 0;
  for (size_t b : summary->blob_counts) {
    max_blobs = std::max(max_blobs, b);
    mean += static_cast<double>(b);
  }
  if (!summary->blob_counts.empty()) mean /= static_cast<double>(summary->blob_counts.size());
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
  std::fputs(fmt::format("wrote {}\n", (o.out_dir / "summary.json").string()).c_str(), stdout);
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
  run_cmd->add_option("--frames", run.options.max_frames, "process at most N frames");
  run_cmd->add_option("--start", run.options.start_frame, "first frame of every source")->capture_default_str();
  run_cmd->add_option("--cache-dir", run.cache_dir, "folder of cached tables and backgrounds (default: ~/.cache/occmap)");
  run_cmd->add_flag("--no-cache", run.no_cache, "never read or write cached tables or backgrounds");
  run_cmd->add_option("--sync", run.sync, "synchronise cameras by frame index or timestamp")
      ->check(CLI::IsMember({"index", "timestamp"}))->capture_default_str();
  run_cmd->add_flag("--continue-without-camera", run.continue_without_camera,
                    "when a camera's stream ends or fails, go on without it (its cells become unseen)");
  run_cmd->add_flag("--occupancy-pngs", run.options.occupancy_pngs, "also write occupancy/NNNNNN.png per frame");
  run_cmd->add_flag("--no-video", run.no_video, "do not write occupancy.mp4 and mosaic.mp4");
  run_cmd->add_option("--background-frames", run.options.background_frames,
                      "K: frames in the median background of a camera without one")->capture_default_str();
  run_cmd->add_option("--min-blob-area-m2", run.options.min_blob_area_m2, "drop smaller blobs")->capture_default_str();

  std::string demo_out = "demo-out";
  CLI::App* demo_cmd = app.add_subcommand("demo", "run on the built-in lab scene (no data needed)");
  demo_cmd->add_option("--out", demo_out, "output folder")->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  Status status;
  if (lut_cmd->parsed()) status = RunLut(common, lut);
  if (run_cmd->parsed()) status = RunRun(common, run);
  if (check_cmd->parsed()) status = RunCheck(common, check_site);
  if (demo_cmd->parsed()) status = RunDemo(common, demo_out);
  return status.ok() ? 0 : Fail(status);
}
