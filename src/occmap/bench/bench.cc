#include "occmap/bench/bench.h"

#include <fmt/core.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <optional>
#include <random>
#include <thread>
#include <unistd.h>
#include <opencv2/imgproc.hpp>
#include <yaml-cpp/yaml.h>

#include "occmap/bench/pass_times.h"
#include "occmap/detect/background_model.h"
#include "occmap/detect/change_detection.h"
#include "occmap/geometry/rotation.h"
#include "occmap/fusion/column_fusion.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/view_explainer.h"
#include "occmap/io/frame_source.h"
#include "occmap/pipeline/run.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/sim/renderer.h"
#include "occmap/sim/scene.h"
#include "occmap/geometry/pinhole_camera.h"
#include "occmap/site/site.h"

namespace occmap::bench {
namespace {

using Clock = std::chrono::steady_clock;

PinholeCamera LookAt(const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m, int width, int height,
                     double f_px) {
  PinholeParameters p;
  p.image_size = {width, height};
  p.fx_px = p.fy_px = f_px;
  p.cx_px = (width - 1) / 2.0;
  p.cy_px = (height - 1) / 2.0;
  p.cam_from_world_rotation = LookAtRotation(position_m, target_m);
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * position_m;
  return PinholeCamera::Create(p).value();
}

struct Workload {
  std::string name;
  std::vector<std::unique_ptr<CameraModel>> cameras;
  std::vector<Image<uint8_t>> masks;  // per camera, may be empty
  FloorGrid grid;
  double plane_height_m = 0;
  std::filesystem::path wildtrack_dir;  // the dataset folder (calibrations, annotations), wildtrack only
};

// `count` cameras on the walls of a room of size_x x size_y m at 2.8 m, looking across it.
Workload SyntheticRoom(std::string name, int count, int width, int height, FloorGrid grid) {
  Workload w;
  w.name = std::move(name);
  w.grid = grid;
  const double sx = grid.size_x_m(), sy = grid.size_y_m();
  const Eigen::Vector3d center(grid.origin_x_m + sx / 2, grid.origin_y_m + sy / 2, 0.0);
  for (int i = 0; i < count; ++i) {
    const double angle = 2 * M_PI * (i + 0.125) / count;
    const Eigen::Vector3d position(center.x() + 0.55 * sx * std::cos(angle), center.y() + 0.55 * sy * std::sin(angle),
                                   2.8);
    const Eigen::Vector3d target = center + 0.2 * (center - Eigen::Vector3d(position.x(), position.y(), 0.0));
    w.cameras.push_back(LookAt(position, target, width, height, 0.6 * width).Clone());
  }
  w.masks.resize(w.cameras.size());
  return w;
}

Result<std::optional<Workload>> MakeWorkload(const std::string& name, const BenchOptions& options, std::string& note) {
  if (name == "paper") {
    return std::optional<Workload>(SyntheticRoom(
        "paper", 6, 640, 480,
        FloorGrid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 640, .cells_y = 480, .cell_size_m = 0.02}));
  }
  if (name == "tiny") {
    return std::optional<Workload>(SyntheticRoom(
        "tiny", 4, 96, 72, FloorGrid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 80, .cells_y = 60, .cell_size_m = 0.05}));
  }
  // wildtrack
  std::error_code ec;
  if (!std::filesystem::exists(options.wildtrack_site, ec)) {
    note = fmt::format("skipped: site file {} not found (run from the checkout)", options.wildtrack_site.string());
    return std::optional<Workload>();
  }
  SiteLoadOptions load;
  if (!options.data_root.empty()) load.data_root = options.data_root;
  auto site = LoadSite(options.wildtrack_site, load);
  if (!site.ok()) {
    note = "skipped: WILDTRACK data not available (" + site.status().message() + ")";
    return std::optional<Workload>();
  }
  Workload w;
  w.name = "wildtrack";
  // The dataset folder: the data root (--data-root, else the site file's data_root against
  // the file's folder) + wildtrack/, as the site's calibration paths resolve.
  std::filesystem::path root = options.data_root;
  if (root.empty()) {
    const std::filesystem::path site_dir = options.wildtrack_site.parent_path();
    root = site_dir;
    try {
      const YAML::Node node = YAML::LoadFile(options.wildtrack_site.string())["data_root"];
      if (node && node.IsScalar()) root = site_dir / node.as<std::string>();
    } catch (const YAML::Exception&) {
      // LoadSite read the file just above; keep the file's folder.
    }
  }
  w.wildtrack_dir = root / "wildtrack";
  w.grid = site->grid;
  w.plane_height_m = site->plane_height_m;
  for (SiteCamera& cam : site->cameras) {
    w.cameras.push_back(std::move(cam.camera));
    w.masks.push_back(std::move(cam.mask));
  }
  return std::optional<Workload>(std::move(w));
}

// Background uniform random; the frame equals it except for changed_fraction of the pixels,
// which differ by T + 1 .. 255 (in range).
void MakeFrames(std::mt19937& rng, ImageSize size, int threshold, double changed_fraction, int count,
                Image<uint8_t>& background, std::vector<Image<uint8_t>>& frames) {
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_real_distribution<double> unit(0, 1);
  background = Image<uint8_t>(size.width, size.height);
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) background(x, y) = static_cast<uint8_t>(byte(rng));
  }
  for (int k = 0; k < count; ++k) {
    Image<uint8_t> frame = background;
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        if (unit(rng) >= changed_fraction) continue;
        const int b = background(x, y);
        const int room = std::max(b, 255 - b);  // >= 128 > T for T <= 127
        const int d = std::min(room, threshold + 1 + byte(rng) % std::max(1, room - threshold));
        frame(x, y) = static_cast<uint8_t>(b >= 128 ? b - d : b + d);
      }
    }
    frames.push_back(std::move(frame));
  }
}

Image<uint8_t> Grey(const Image<Rgb8>& rgb) {
  Image<uint8_t> out(rgb.width(), rgb.height());
  for (int y = 0; y < rgb.height(); ++y) {
    const Rgb8* in = rgb.row(y);
    uint8_t* o = out.row(y);
    for (int x = 0; x < rgb.width(); ++x) o[x] = static_cast<uint8_t>((77 * in[x].r + 150 * in[x].g + 29 * in[x].b + 128) >> 8);
  }
  return out;
}

// Median over repetitions of the time per frame of fn(frame index), in seconds.
double MedianSecondsPerFrame(int repetitions, int frames, const std::function<void(int)>& fn) {
  std::vector<double> times = SecondsPerFrameOfEachPass(repetitions, frames, fn);
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

struct FrameRates {
  double paper_pps = 0, opencv_pps = 0, fast_1_pps = 0, fast_all_pps = 0, streaming_1_pps = 0, streaming_all_pps = 0;
  double primary_failure_fraction = 0, primary_tested_fraction = 0, secondary_probes_per_frame = 0,
         streamed_frame_fraction = 0;
};

// (a) to (e) on the frames frame_views[f] (options.frames of them) against one background set.
FrameRates MeasureFrames(const GroundLut& lut, OpenCvFusion& opencv, FastFusion& fast,
                         const std::vector<std::vector<ImageView<const uint8_t>>>& frame_views,
                         const std::vector<ImageView<const uint8_t>>& background_views, const BenchOptions& options,
                         Context& ctx, int& opencv_threads) {
  FrameRates rates;
  const double pixels = static_cast<double>(lut.total_pixels());
  const int frames = static_cast<int>(frame_views.size());
  std::vector<uint8_t> occupancy;
  rates.paper_pps = pixels / MedianSecondsPerFrame(options.repetitions, frames, [&](int f) {
                      PaperLoop(lut, frame_views[static_cast<size_t>(f)], background_views, options.threshold, occupancy);
                    });
  cv::Mat cv_out;
  // OpenCV parallelises absdiff / threshold / remap itself: give it the same threads as (d).
  const int saved_cv_threads = cv::getNumThreads();
  cv::setNumThreads(ctx.num_threads());
  opencv_threads = cv::getNumThreads();
  rates.opencv_pps = pixels / MedianSecondsPerFrame(options.repetitions, frames, [&](int f) {
                       opencv.Fuse(frame_views[static_cast<size_t>(f)], background_views, options.threshold, cv_out);
                     });
  cv::setNumThreads(saved_cv_threads);
  OccupancyMap map;
  Context one(1);
  // The probe statistics of one pass over the frames on one thread.
  int64_t probed = 0, tested = 0, failed = 0, secondary = 0, streamed = 0;
  for (int f = 0; f < frames; ++f) {
    fast.Fuse(frame_views[static_cast<size_t>(f)], background_views, options.threshold, one, map);
    const FastFusion::FrameStats& stats = fast.last_frame_stats();
    probed += stats.primary_probed;
    tested += stats.primary_tested;
    failed += stats.primary_failed;
    secondary += stats.secondary_probed;
    streamed += stats.streamed ? 1 : 0;
  }
  rates.primary_failure_fraction = probed > 0 ? static_cast<double>(failed) / static_cast<double>(probed) : 0.0;
  rates.primary_tested_fraction = probed > 0 ? static_cast<double>(tested) / static_cast<double>(probed) : 0.0;
  rates.secondary_probes_per_frame = static_cast<double>(secondary) / frames;
  rates.streamed_frame_fraction = static_cast<double>(streamed) / frames;
  rates.fast_1_pps = pixels / MedianSecondsPerFrame(options.repetitions, frames, [&](int f) {
                       fast.Fuse(frame_views[static_cast<size_t>(f)], background_views, options.threshold, one, map);
                     });
  rates.fast_all_pps = pixels / MedianSecondsPerFrame(options.repetitions, frames, [&](int f) {
                         fast.Fuse(frame_views[static_cast<size_t>(f)], background_views, options.threshold, ctx, map);
                       });
  rates.streaming_1_pps = pixels / MedianSecondsPerFrame(options.repetitions, frames, [&](int f) {
                            fast.FuseWith(FastFusion::Method::kRowStreaming, frame_views[static_cast<size_t>(f)],
                                          background_views, options.threshold, one, map);
                          });
  rates.streaming_all_pps = pixels / MedianSecondsPerFrame(options.repetitions, frames, [&](int f) {
                              fast.FuseWith(FastFusion::Method::kRowStreaming, frame_views[static_cast<size_t>(f)],
                                            background_views, options.threshold, ctx, map);
                            });
  return rates;
}

Result<WorkloadResult> RunWorkload(Workload& w, const BenchOptions& options, Context& ctx) {
  WorkloadResult result;
  result.name = w.name;
  result.cameras = static_cast<int>(w.cameras.size());
  result.cells = w.grid.num_cells();
  result.threads = ctx.num_threads();
  result.kernel = FastFusion::KernelName();

  std::vector<LutCameraInput> inputs;
  for (size_t n = 0; n < w.cameras.size(); ++n) inputs.push_back({w.cameras[n].get(), w.masks[n].view()});
  LutOptions lut_options;
  lut_options.plane_height_m = w.plane_height_m;
  auto t0 = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(GroundLut lut, BuildGroundLut(inputs, w.grid, lut_options, ctx));
  result.lut_build_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  t0 = Clock::now();
  FastFusion fast(lut);
  result.fast_build_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  result.lut_bytes = lut.MemoryBytes();
  result.fast_bytes = fast.MemoryBytes();
  result.fast_runs = fast.num_runs();
  result.fast_pairs = fast.num_pairs();
  result.mapped_pixels = fast.mapped_pixels();
  result.camera_pixels = lut.total_pixels();
  result.fast_bytes_read_per_frame = 2 * result.camera_pixels + fast.TableBytesPerFrame();
  result.fast_probe_table_bytes = fast.ProbeTableBytes();
  result.fast_streaming_table_bytes = fast.StreamingTableBytes();
  result.primary_probes = fast.num_primary_probes();
  result.secondary_probes = fast.num_secondary_probes();
  result.probe_rows = fast.num_probe_rows();
  result.probe_bytes_read_per_frame = fast.ProbeBytesPerFrame();

  std::vector<const CameraModel*> cams;
  for (const auto& c : w.cameras) cams.push_back(c.get());
  OpenCvFusion opencv(cams, w.grid, w.plane_height_m);

  // Frames: [frame index][camera].
  std::mt19937 rng(2024);
  std::vector<Image<uint8_t>> backgrounds(w.cameras.size());
  std::vector<std::vector<Image<uint8_t>>> per_camera(w.cameras.size());
  for (size_t n = 0; n < w.cameras.size(); ++n) {
    MakeFrames(rng, lut.image_size(static_cast<int>(n)), options.threshold, options.changed_fraction, options.frames,
               backgrounds[n], per_camera[n]);
  }
  std::vector<ImageView<const uint8_t>> background_views;
  for (const auto& b : backgrounds) background_views.push_back(b.view());
  std::vector<std::vector<ImageView<const uint8_t>>> frame_views(static_cast<size_t>(options.frames));
  for (int f = 0; f < options.frames; ++f) {
    for (size_t n = 0; n < w.cameras.size(); ++n) frame_views[static_cast<size_t>(f)].push_back(per_camera[n][static_cast<size_t>(f)].view());
  }

  const double pixels = static_cast<double>(result.camera_pixels);
  OccupancyMap map;
  Context one(1);
  const FrameRates random_rates =
      MeasureFrames(lut, opencv, fast, frame_views, background_views, options, ctx, result.opencv_threads);
  result.paper_pps = random_rates.paper_pps;
  result.opencv_pps = random_rates.opencv_pps;
  result.fast_1_pps = random_rates.fast_1_pps;
  result.fast_all_pps = random_rates.fast_all_pps;
  result.streaming_1_pps = random_rates.streaming_1_pps;
  result.streaming_all_pps = random_rates.streaming_all_pps;
  result.primary_failure_fraction = random_rates.primary_failure_fraction;
  result.primary_tested_fraction = random_rates.primary_tested_fraction;
  // The change test alone, one thread: the paper's |I - B| > T against the adaptive model's
  // (transfer, chroma, shadows) and its update, on the same frames with random chroma.
  {
    std::vector<Image<uint8_t>> changes;
    std::vector<std::vector<YuvImage>> yuv_frames(w.cameras.size());
    std::vector<BackgroundModel> models;
    std::vector<Image<uint8_t>> free_protection;
    BackgroundOptions adaptive;
    adaptive.adaptive = true;
    for (size_t n = 0; n < w.cameras.size(); ++n) {
      const Image<uint8_t>& b = backgrounds[n];
      changes.emplace_back(b.width(), b.height());
      free_protection.emplace_back(b.width(), b.height(), BackgroundModel::kFree);
      YuvImage yb;
      yb.y = b;
      yb.u = Image<uint8_t>(ChromaPlaneSize(b.width()), ChromaPlaneSize(b.height()));
      yb.v = yb.u;
      for (int y = 0; y < yb.u.height(); ++y) {
        for (int x = 0; x < yb.u.width(); ++x) {
          yb.u(x, y) = static_cast<uint8_t>(96 + rng() % 64);
          yb.v(x, y) = static_cast<uint8_t>(96 + rng() % 64);
        }
      }
      for (int f = 0; f < options.frames; ++f) {
        YuvImage yf;
        yf.y = per_camera[n][static_cast<size_t>(f)];
        yf.u = yb.u;
        yf.v = yb.v;
        yuv_frames[n].push_back(std::move(yf));
      }
      models.emplace_back(adaptive, 10.0);
      models.back().Reset(yb);
    }
    result.plain_change_1_pps = pixels / MedianSecondsPerFrame(options.repetitions, options.frames, [&](int f) {
                                  for (size_t n = 0; n < w.cameras.size(); ++n) {
                                    DetectChangesGray(per_camera[n][static_cast<size_t>(f)].view(), backgrounds[n].view(),
                                                      options.threshold, changes[n].view());
                                  }
                                });
    result.adaptive_change_1_pps = pixels / MedianSecondsPerFrame(options.repetitions, options.frames, [&](int f) {
                                     for (size_t n = 0; n < w.cameras.size(); ++n) {
                                       models[n].DetectChanges(yuv_frames[n][static_cast<size_t>(f)].view(),
                                                               options.threshold, changes[n].view());
                                     }
                                   });
    result.adaptive_update_1_pps = pixels / MedianSecondsPerFrame(options.repetitions, options.frames, [&](int f) {
                                     for (size_t n = 0; n < w.cameras.size(); ++n) {
                                       models[n].Update(yuv_frames[n][static_cast<size_t>(f)].view(),
                                                        free_protection[n].view(), f);
                                     }
                                   });
  }
  // Worst case: every pixel changed (|I - B| = 128 > T), as many distinct frames.
  std::vector<std::vector<Image<uint8_t>>> changed(static_cast<size_t>(options.frames));
  std::vector<std::vector<ImageView<const uint8_t>>> changed_views(static_cast<size_t>(options.frames));
  for (size_t f = 0; f < changed.size(); ++f) {
    for (size_t n = 0; n < w.cameras.size(); ++n) {
      const Image<uint8_t>& b = backgrounds[n];
      Image<uint8_t> frame(b.width(), b.height());
      for (int y = 0; y < b.height(); ++y) {
        for (int x = 0; x < b.width(); ++x) frame(x, y) = static_cast<uint8_t>(b(x, y) ^ 0x80);
      }
      changed[f].push_back(std::move(frame));
      changed_views[f].push_back(changed[f].back().view());
    }
  }
  result.worst_1_pps = pixels / MedianSecondsPerFrame(options.repetitions, options.frames, [&](int f) {
                         fast.Fuse(changed_views[static_cast<size_t>(f)], background_views, options.threshold, one, map);
                       });
  result.worst_all_pps = pixels / MedianSecondsPerFrame(options.repetitions, options.frames, [&](int f) {
                           fast.Fuse(changed_views[static_cast<size_t>(f)], background_views, options.threshold, ctx, map);
                         });
  if (w.name == "wildtrack") {
    RenderedResult& rendered = result.rendered;
    if (options.rendered_frames <= 0) {
      rendered.note = "not measured (no rendered frames asked for)";
      return result;
    }
    std::vector<ImageSize> sizes;
    for (int n = 0; n < lut.num_cameras(); ++n) sizes.push_back(lut.image_size(n));
    t0 = Clock::now();
    auto frames = RenderWildtrackFrames(w.wildtrack_dir, options.rendered_frames, sizes, ctx);
    rendered.render_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    if (!frames.ok()) {
      rendered.note = "skipped: " + frames.status().message();
      return result;
    }
    std::vector<ImageView<const uint8_t>> rendered_backgrounds;
    for (const auto& b : frames->backgrounds) rendered_backgrounds.push_back(b.view());
    std::vector<std::vector<ImageView<const uint8_t>>> rendered_views(frames->frames.size());
    int64_t changed_pixels = 0;
    for (size_t f = 0; f < frames->frames.size(); ++f) {
      for (size_t n = 0; n < frames->frames[f].size(); ++n) {
        const Image<uint8_t>& frame = frames->frames[f][n];
        const Image<uint8_t>& background = frames->backgrounds[n];
        rendered_views[f].push_back(frame.view());
        for (int y = 0; y < frame.height(); ++y) {
          for (int x = 0; x < frame.width(); ++x) changed_pixels += std::abs(frame(x, y) - background(x, y)) > options.threshold;
        }
      }
    }
    BenchOptions rendered_options = options;
    rendered_options.frames = static_cast<int>(frames->frames.size());
    const FrameRates rates = MeasureFrames(lut, opencv, fast, rendered_views, rendered_backgrounds, rendered_options,
                                           ctx, result.opencv_threads);
    rendered.measured = true;
    rendered.frames = static_cast<int>(frames->frames.size());
    rendered.note = "scene frames";
    for (const int64_t f : frames->scene_frames) rendered.note += fmt::format(" {}", f);
    rendered.changed_fraction = static_cast<double>(changed_pixels) / (pixels * static_cast<double>(rendered.frames));
    rendered.paper_pps = rates.paper_pps;
    rendered.opencv_pps = rates.opencv_pps;
    rendered.fast_1_pps = rates.fast_1_pps;
    rendered.fast_all_pps = rates.fast_all_pps;
    rendered.streaming_1_pps = rates.streaming_1_pps;
    rendered.streaming_all_pps = rates.streaming_all_pps;
    rendered.primary_failure_fraction = rates.primary_failure_fraction;
    rendered.primary_tested_fraction = rates.primary_tested_fraction;
    rendered.secondary_probes_per_frame = rates.secondary_probes_per_frame;
    rendered.streamed_frame_fraction = rates.streamed_frame_fraction;
    // (j)-(l): the people path as `occmap synth --scene wildtrack` sets it up (people: {detector:
    // explain}, the scene's statics), on the same frames and backgrounds.
    PeopleOptions people;
    people.enabled = true;
    people.detector = PeopleDetector::kExplain;
    OCCMAP_ASSIGN_OR_RETURN(rendered.people, MeasurePeople(inputs, w.grid, w.plane_height_m, frames->statics, people,
                                                           rendered_views, rendered_backgrounds, options.threshold,
                                                           options.repetitions, ctx));
  }
  return result;
}

double Mega(int64_t n) { return static_cast<double>(n) / 1e6; }

}  // namespace

Result<PeopleRates> MeasurePeople(const std::vector<LutCameraInput>& cameras, const FloorGrid& grid,
                                  double plane_height_m, std::span<const Occluder> statics,
                                  const PeopleOptions& people,
                                  const std::vector<std::vector<ImageView<const uint8_t>>>& frames,
                                  std::span<const ImageView<const uint8_t>> backgrounds, int threshold,
                                  int repetitions, Context& ctx) {
  const size_t num_cameras = cameras.size();
  if (people.detector != PeopleDetector::kExplain) {
    return InvalidInput(fmt::format("people bench: detector explain expected, found {}", ToString(people.detector)));
  }
  OCCMAP_RETURN_IF_ERROR(people.Validate(static_cast<int>(num_cameras)));
  if (frames.empty() || backgrounds.size() != num_cameras || repetitions < 1) {
    return InvalidInput(fmt::format("people bench: {} frame sets, {} backgrounds for {} cameras, {} repetitions",
                                    frames.size(), backgrounds.size(), num_cameras, repetitions));
  }
  for (const auto& set : frames) {
    if (set.size() != num_cameras) {
      return InvalidInput(fmt::format("people bench: a frame set of {} images for {} cameras", set.size(), num_cameras));
    }
    for (size_t n = 0; n < num_cameras; ++n) {
      if (set[n].width() != backgrounds[n].width() || set[n].height() != backgrounds[n].height()) {
        return InvalidInput(fmt::format("people bench: camera {}: frame {}x{}, background {}x{}", n + 1,
                                        set[n].width(), set[n].height(), backgrounds[n].width(),
                                        backgrounds[n].height()));
      }
    }
  }
  PeopleRates rates;
  auto t0 = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(ColumnLut columns,
                          BuildColumnLut(cameras, grid, plane_height_m, people.columns, statics, ctx));
  rates.column_lut_build_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  rates.column_lut_bytes = columns.MemoryBytes();
  rates.candidates = columns.candidates().num_cells();
  rates.occluders = static_cast<int>(statics.size());

  double pixels = 0;
  for (const auto& b : backgrounds) pixels += static_cast<double>(b.width()) * b.height();
  const int num_frames = static_cast<int>(frames.size());
  const auto n_cams = static_cast<int64_t>(num_cameras);
  // The change masks of every frame set, computed once: the input of (j) and (k), as the run's
  // change buffer; and each set's row sums and column map, the input of (k).
  std::vector<std::vector<Image<uint8_t>>> changes(frames.size());
  std::vector<std::vector<ImageView<const uint8_t>>> change_views(frames.size());
  std::vector<std::vector<ChangeRowSums>> counts(frames.size(), std::vector<ChangeRowSums>(num_cameras));
  std::vector<OccupancyMap> column_maps(frames.size());
  const std::vector<bool> active(num_cameras, true);
  const ColumnFusion fusion(columns);
  ViewExplainer explainer(columns);
  std::vector<ExplainedPerson> found;
  int64_t occupied = 0, people_found = 0;
  for (size_t f = 0; f < frames.size(); ++f) {
    for (size_t n = 0; n < num_cameras; ++n) {
      changes[f].emplace_back(backgrounds[n].width(), backgrounds[n].height());
      DetectChangesGray(frames[f][n], backgrounds[n], threshold, changes[f][n].view());
      change_views[f].push_back(changes[f][n].view());
      counts[f][n].Build(change_views[f][n]);
    }
    fusion.Fuse(counts[f], active, people.column, ctx, column_maps[f]);
    occupied += column_maps[f].Count(CellState::kOccupied);
    explainer.Explain(change_views[f], counts[f], active, column_maps[f], people.explain, ctx, found);
    people_found += static_cast<int64_t>(found.size());
  }
  rates.occupied_candidates_per_frame = static_cast<double>(occupied) / num_frames;
  rates.people_per_frame = static_cast<double>(people_found) / num_frames;

  // Per camera in parallel, as `occmap run` builds the row sums.
  std::vector<ChangeRowSums> scratch_counts(num_cameras);
  auto build_counts = [&](std::span<const ImageView<const uint8_t>> views, Context& c) {
    ParallelFor(c, 0, n_cams, [&](int64_t b, int64_t e, int) {
      for (int64_t n = b; n < e; ++n) scratch_counts[static_cast<size_t>(n)].Build(views[static_cast<size_t>(n)]);
    });
  };
  OccupancyMap map;
  Context one(1);
  rates.change_test_1_pps = pixels / MedianSecondsPerFrame(repetitions, num_frames, [&](int f) {
                              for (size_t n = 0; n < num_cameras; ++n) {
                                DetectChangesGray(frames[static_cast<size_t>(f)][n], backgrounds[n], threshold,
                                                  changes[static_cast<size_t>(f)][n].view());
                              }
                            });
  for (Context* c : {&one, &ctx}) {
    const double column_pps = pixels / MedianSecondsPerFrame(repetitions, num_frames, [&](int f) {
                                build_counts(change_views[static_cast<size_t>(f)], *c);
                                fusion.Fuse(scratch_counts, active, people.column, *c, map);
                              });
    const double explain_pps = pixels / MedianSecondsPerFrame(repetitions, num_frames, [&](int f) {
                                 const auto k = static_cast<size_t>(f);
                                 explainer.Explain(change_views[k], counts[k], active, column_maps[k], people.explain,
                                                   *c, found);
                               });
    // (l): the change masks (per camera in parallel), the row sums, the column map, the people.
    const double path_pps = pixels / MedianSecondsPerFrame(repetitions, num_frames, [&](int f) {
                              const auto k = static_cast<size_t>(f);
                              ParallelFor(*c, 0, n_cams, [&](int64_t b, int64_t e, int) {
                                for (int64_t n = b; n < e; ++n) {
                                  const auto m = static_cast<size_t>(n);
                                  DetectChangesGray(frames[k][m], backgrounds[m], threshold, changes[k][m].view());
                                }
                              });
                              build_counts(change_views[k], *c);
                              fusion.Fuse(scratch_counts, active, people.column, *c, map);
                              explainer.Explain(change_views[k], scratch_counts, active, map, people.explain, *c,
                                                found);
                            });
    (c == &one ? rates.column_1_pps : rates.column_all_pps) = column_pps;
    (c == &one ? rates.explain_1_pps : rates.explain_all_pps) = explain_pps;
    (c == &one ? rates.path_1_pps : rates.path_all_pps) = path_pps;
  }
  rates.measured = true;
  rates.note = fmt::format("detector {}, band {}-{} m, {} candidates of {} m, {} occluders; change masks |I - B| > {}",
                           ToString(people.detector), people.column.band_low_m, people.column.band_high_m,
                           rates.candidates, columns.candidates().cell_size_m, rates.occluders, threshold);
  return rates;
}

Result<RenderedFrames> RenderWildtrackFrames(const std::filesystem::path& dataset_dir, int count,
                                             const std::vector<ImageSize>& sizes, Context& ctx) {
  sim::WildtrackSceneOptions wt;
  wt.dataset_dir = dataset_dir;
  OCCMAP_ASSIGN_OR_RETURN(sim::SceneSpec spec, sim::MakeWildtrackSceneSpec(sim::BuiltinSceneOptions{}, wt));
  OCCMAP_ASSIGN_OR_RETURN(sim::Scene scene, sim::Scene::Create(std::move(spec)));
  if (scene.num_cameras() != sizes.size()) {
    return InvalidInput(fmt::format("wildtrack scene: {} cameras, the site has {}", scene.num_cameras(), sizes.size()));
  }
  RenderedFrames r;
  // As `occmap synth` writes the site's statics: boxes as they are, the rest as cylinders.
  for (const sim::StaticObjectSpec& o : scene.spec().statics) {
    Occluder occluder;
    occluder.centre_m = o.centre_m;
    occluder.height_m = o.height_m;
    if (o.shape == sim::StaticObjectSpec::Shape::kBox) {
      occluder.shape = Occluder::Shape::kBox;
      occluder.size_m = o.size_m;
      occluder.base_m = o.base_m;
      occluder.yaw_deg = o.yaw_deg;
    } else {
      occluder.shape = Occluder::Shape::kCylinder;
      occluder.size_m = Eigen::Vector2d(o.size_m.x(), o.size_m.x());
    }
    r.statics.push_back(occluder);
  }
  const int64_t n = scene.num_frames();
  for (int k = 0; k < count; ++k) r.scene_frames.push_back((2 * k + 1) * n / (2 * count));
  r.frames.resize(static_cast<size_t>(count));
  for (size_t c = 0; c < scene.num_cameras(); ++c) {
    const sim::CameraRenderer renderer(scene, c, ctx);
    if (!(renderer.size() == sizes[c])) {
      return InvalidInput(fmt::format("wildtrack scene: camera {} renders {}x{}, the site's is {}x{}", c + 1,
                                      renderer.size().width, renderer.size().height, sizes[c].width, sizes[c].height));
    }
    r.backgrounds.push_back(Grey(renderer.Background()));
    sim::RenderedView view;
    for (int k = 0; k < count; ++k) {
      renderer.Render(scene.StateAt(r.scene_frames[static_cast<size_t>(k)]), ctx, &view);
      r.frames[static_cast<size_t>(k)].push_back(Grey(view.rgb));
    }
  }
  return r;
}

Status BenchOptions::Validate() const {
  if (workload != "paper" && workload != "wildtrack" && workload != "adaptive" && workload != "all" &&
      workload != "tiny") {
    return InvalidInput(fmt::format("--workload: expected paper, wildtrack, adaptive or all, found '{}'", workload));
  }
  if (workload == "adaptive" || (workload == "all" && !adaptive.datasets.empty())) {
    OCCMAP_RETURN_IF_ERROR(adaptive.Validate());
  }
  if (frames < 1 || frames > 1000) return InvalidInput(fmt::format("--frames: expected 1..1000, found {}", frames));
  if (repetitions < 1) return InvalidInput("repetitions: expected at least 1");
  if (!(changed_fraction >= 0 && changed_fraction <= 1)) {
    return InvalidInput(fmt::format("--changed-fraction: expected 0..1, found {}", changed_fraction));
  }
  if (rendered_frames < 0 || rendered_frames > 100) {
    return InvalidInput(fmt::format("--rendered-frames: expected 0..100, found {}", rendered_frames));
  }
  if (wildtrack_end_to_end_frames != 0 && (wildtrack_end_to_end_frames < 22 || wildtrack_end_to_end_frames > 2000)) {
    return InvalidInput(fmt::format("--wildtrack-end-to-end-frames: expected 0 or 22..2000, found {}",
                                    wildtrack_end_to_end_frames));
  }
  if (threshold < 0 || threshold > 127) return InvalidInput("threshold: expected 0..127");
  return Status::Ok();
}

void PaperLoop(const GroundLut& lut, std::span<const ImageView<const uint8_t>> frames,
               std::span<const ImageView<const uint8_t>> backgrounds, int threshold, std::vector<uint8_t>& occupancy) {
  OCCMAP_CHECK(frames.size() == static_cast<size_t>(lut.num_cameras()) && backgrounds.size() == frames.size(),
               "paper loop: one frame and one background per camera");
  occupancy.assign(static_cast<size_t>(lut.grid().num_cells()) + 1, 1);  // O = 1
  uint8_t* o = occupancy.data();
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const ImageSize size = lut.image_size(n);
    const uint32_t* l1 = lut.l1(n).data();
    const ImageView<const uint8_t> image = frames[static_cast<size_t>(n)];
    const ImageView<const uint8_t> background = backgrounds[static_cast<size_t>(n)];
    // for r, for c: if |I - B| <= T then O[L1[n, c, r]] = 0 (the sentinel absorbs unmapped pixels)
    for (int r = 0; r < size.height; ++r) {
      const uint8_t* i_row = image.row(r);
      const uint8_t* b_row = background.row(r);
      const uint32_t* l1_row = l1 + static_cast<size_t>(r) * size.width;
      for (int c = 0; c < size.width; ++c) {
        if (std::abs(int{i_row[c]} - int{b_row[c]}) <= threshold) o[l1_row[c]] = 0;
      }
    }
    const std::span<const uint32_t> extra_pixels = lut.extra_pixels(n);
    const std::span<const uint32_t> extra_cells = lut.extra_cells(n);
    for (size_t e = 0; e < extra_pixels.size(); ++e) {
      const int r = static_cast<int>(extra_pixels[e] / static_cast<uint32_t>(size.width));
      const int c = static_cast<int>(extra_pixels[e] % static_cast<uint32_t>(size.width));
      if (std::abs(int{image(c, r)} - int{background(c, r)}) <= threshold) o[extra_cells[e]] = 0;
    }
  }
}

OpenCvFusion::OpenCvFusion(const std::vector<const CameraModel*>& cameras, const FloorGrid& grid,
                           double plane_height_m) {
  for (const CameraModel* camera : cameras) {
    cv::Mat mx(grid.cells_y, grid.cells_x, CV_32FC1), my(grid.cells_y, grid.cells_x, CV_32FC1);
    const ImageSize size = camera->image_size();
    for (int j = 0; j < grid.cells_y; ++j) {
      for (int i = 0; i < grid.cells_x; ++i) {
        const Eigen::Vector2d c = grid.CellCenter(static_cast<int64_t>(j) * grid.cells_x + i);
        const auto pixel = camera->Project(Eigen::Vector3d(c.x(), c.y(), plane_height_m));
        const bool in = pixel && pixel->x() > -0.5 && pixel->y() > -0.5 && pixel->x() < size.width - 0.5 &&
                        pixel->y() < size.height - 0.5;
        mx.at<float>(j, i) = in ? static_cast<float>(pixel->x()) : -10.0f;
        my.at<float>(j, i) = in ? static_cast<float>(pixel->y()) : -10.0f;
      }
    }
    map_x_.push_back(mx);
    map_y_.push_back(my);
  }
}

void OpenCvFusion::Fuse(std::span<const ImageView<const uint8_t>> frames,
                        std::span<const ImageView<const uint8_t>> backgrounds, int threshold, cv::Mat& out) {
  for (size_t n = 0; n < map_x_.size(); ++n) {
    const cv::Mat image(frames[n].height(), frames[n].width(), CV_8UC1, const_cast<uint8_t*>(frames[n].data()),
                        static_cast<size_t>(frames[n].stride_elems()));
    const cv::Mat background(backgrounds[n].height(), backgrounds[n].width(), CV_8UC1,
                             const_cast<uint8_t*>(backgrounds[n].data()),
                             static_cast<size_t>(backgrounds[n].stride_elems()));
    cv::absdiff(image, background, diff_);
    cv::threshold(diff_, mask_, threshold, 255, cv::THRESH_BINARY);
    if (n == 0) {
      cv::remap(mask_, out, map_x_[n], map_y_[n], cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(255));
    } else {
      cv::remap(mask_, remapped_, map_x_[n], map_y_[n], cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(255));
      cv::bitwise_and(out, remapped_, out);
    }
  }
}

std::string MachineName() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      if (colon != std::string::npos) {
        std::string name = line.substr(colon + 1);
        name.erase(0, name.find_first_not_of(' '));
        return name;
      }
    }
  }
  return "unknown";
}

Result<BenchResults> RunBench(const BenchOptions& options, Context& ctx) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  std::vector<std::string> names;
  const bool adaptive = options.workload == "adaptive" || (options.workload == "all" && !options.adaptive.datasets.empty());
  if (options.workload == "all") {
    names = {"paper", "wildtrack"};
  } else if (options.workload != "adaptive") {
    names = {options.workload};
  }
  std::vector<WorkloadResult> results;
  std::filesystem::path wildtrack_dir;  // the wildtrack workload's dataset folder, when it ran
  for (const std::string& name : names) {
    std::string note;
    OCCMAP_ASSIGN_OR_RETURN(std::optional<Workload> workload, MakeWorkload(name, options, note));
    if (workload && name == "wildtrack") wildtrack_dir = workload->wildtrack_dir;
    if (!workload) {
      WorkloadResult skipped;
      skipped.name = name;
      skipped.skipped = true;
      skipped.note = note;
      results.push_back(skipped);
      continue;
    }
    OCCMAP_ASSIGN_OR_RETURN(WorkloadResult r, RunWorkload(*workload, options, ctx));
    results.push_back(std::move(r));
  }
  BenchResults all;
  all.workloads = std::move(results);
  if (adaptive) {
    AdaptiveBenchOptions a = options.adaptive;
    if (a.data_root.empty()) a.data_root = options.data_root;
    OCCMAP_ASSIGN_OR_RETURN(all.adaptive, RunAdaptiveBench(a, ctx));
  }
  if (options.workload == "adaptive") {
    all.end_to_end.note = "not measured (the adaptive workload alone)";
  } else if (options.end_to_end_frames > 0) {
    OCCMAP_ASSIGN_OR_RETURN(all.end_to_end, MeasureEndToEnd(options.end_to_end_frames, ctx));
  } else {
    all.end_to_end.note = "not measured (--end-to-end-frames 0)";
  }
  all.wildtrack_end_to_end.scene = "wildtrack";
  if (wildtrack_dir.empty()) {
    all.wildtrack_end_to_end.note = "not measured (no wildtrack workload)";
  } else if (options.wildtrack_end_to_end_frames <= 0) {
    all.wildtrack_end_to_end.note = "not measured (--wildtrack-end-to-end-frames 0)";
  } else {
    OCCMAP_ASSIGN_OR_RETURN(all.wildtrack_end_to_end,
                            MeasureEndToEnd(options.wildtrack_end_to_end_frames, ctx, wildtrack_dir));
  }
  return all;
}

std::string BenchTable(const BenchResults& all) {
  std::string s = fmt::format("machine: {}, {} hardware threads\n", MachineName(), std::thread::hardware_concurrency());
  for (const WorkloadResult& r : all.workloads) {
    if (r.skipped) {
      s += fmt::format("\n{}: {}\n", r.name, r.note);
      continue;
    }
    s += fmt::format("\n{}: {} cameras, {:.2f} Mpixel per frame, {} cells; kernel {}\n", r.name, r.cameras,
                     Mega(r.camera_pixels), r.cells, r.kernel);
    s += fmt::format("  tables: GroundLut built in {:.2f} s, {:.1f} MB; FastFusion built in {:.3f} s, {:.1f} MB: "
                     "cell probes {:.1f} MB ({} primary probes on {} image rows, {} secondary), row streaming "
                     "{:.1f} MB ({} runs, {:.2f} mapped pixels per run, {} coverage-fix pairs)\n",
                     r.lut_build_seconds, Mega(r.lut_bytes), r.fast_build_seconds, Mega(r.fast_bytes),
                     Mega(r.fast_probe_table_bytes), r.primary_probes, r.probe_rows, r.secondary_probes,
                     Mega(r.fast_streaming_table_bytes), r.fast_runs,
                     r.fast_runs > 0 ? static_cast<double>(r.mapped_pixels) / static_cast<double>(r.fast_runs) : 0.0,
                     r.fast_pairs);
    s += fmt::format("  {:<28} {:>10} {:>10} {:>12}\n", "method", "Gpixel/s", "ms/frame", "vs paper");
    auto row = [&](const char* name, double pps) {
      s += fmt::format("  {:<28} {:>10.3f} {:>10.3f} {:>11.2f}x\n", name, pps / 1e9,
                       pps > 0 ? 1e3 * static_cast<double>(r.camera_pixels) / pps : 0.0, Ratio(pps, r.paper_pps));
    };
    row("(a) paper loop", r.paper_pps);
    row(fmt::format("(b) OpenCV remap, {} threads", r.opencv_threads).c_str(), r.opencv_pps);
    row("(c) FastFusion 1 thread", r.fast_1_pps);
    row(fmt::format("(d) FastFusion {} threads", r.threads).c_str(), r.fast_all_pps);
    row("(e) row streaming 1 thread", r.streaming_1_pps);
    row(fmt::format("(e) row streaming {} threads", r.threads).c_str(), r.streaming_all_pps);
    row("(f) all changed, 1 thread", r.worst_1_pps);
    row(fmt::format("(f) all changed, {} threads", r.threads).c_str(), r.worst_all_pps);
    row("(g) change test alone, plain", r.plain_change_1_pps);
    row("(h) adaptive test (shadows)", r.adaptive_change_1_pps);
    row("(i) adaptive update", r.adaptive_update_1_pps);
    s += fmt::format("  the adaptive model (transfer, chroma, shadow test) costs {:.2f}x the plain change test; its update "
                     "{:.2f}x (1 thread, no fusion)\n",
                     Ratio(r.plain_change_1_pps, r.adaptive_change_1_pps), Ratio(r.plain_change_1_pps, r.adaptive_update_1_pps));
    s += fmt::format("  FastFusion ({}): speedup vs OpenCV {:.2f}x, vs paper loop {:.2f}x, {} threads vs 1 {:.2f}x; "
                     "first pass reads {:.1f} MB per frame (row streaming {:.1f} MB)\n",
                     "cell probes, occmap run's path", Ratio(r.fast_all_pps, r.opencv_pps),
                     Ratio(r.fast_all_pps, r.paper_pps), r.threads, Ratio(r.fast_all_pps, r.fast_1_pps),
                     Mega(r.probe_bytes_read_per_frame), Mega(r.fast_bytes_read_per_frame));
    s += fmt::format("  all pixels changed (hand-over to row streaming): vs OpenCV {:.2f}x, vs paper loop {:.2f}x "
                     "(OpenCV and the paper loop measured at the normal frames)\n",
                     Ratio(r.worst_all_pps, r.opencv_pps), Ratio(r.worst_all_pps, r.paper_pps));
    const RenderedResult& rr = r.rendered;
    if (r.name == "wildtrack" && !rr.measured) {
      s += fmt::format("  rendered frames: {}\n", rr.note);
    } else if (rr.measured) {
      s += fmt::format("  rendered frames (simulator, WILDTRACK trajectories; {}; rendered in {:.1f} s): {:.2f} % of "
                       "pixels changed, {:.1f} % of primary probes tested (their first pixel changed), "
                       "{:.2f} % failed, {:.0f} secondary probes per frame, {:.0f} % of frames handed to row streaming\n",
                       rr.note, rr.render_seconds, 100 * rr.changed_fraction, 100 * rr.primary_tested_fraction,
                       100 * rr.primary_failure_fraction,
                       rr.secondary_probes_per_frame, 100 * rr.streamed_frame_fraction);
      auto rendered_row = [&](const std::string& name, double pps) {
        s += fmt::format("  {:<28} {:>10.3f} {:>10.3f} {:>11.2f}x\n", name, pps / 1e9,
                         pps > 0 ? 1e3 * static_cast<double>(r.camera_pixels) / pps : 0.0, Ratio(pps, rr.paper_pps));
      };
      rendered_row("(a) paper loop", rr.paper_pps);
      rendered_row(fmt::format("(b) OpenCV remap, {} threads", r.opencv_threads), rr.opencv_pps);
      rendered_row("(c) FastFusion 1 thread", rr.fast_1_pps);
      rendered_row(fmt::format("(d) FastFusion {} threads", r.threads), rr.fast_all_pps);
      rendered_row("(e) row streaming 1 thread", rr.streaming_1_pps);
      rendered_row(fmt::format("(e) row streaming {} threads", r.threads), rr.streaming_all_pps);
      s += fmt::format("  FastFusion on rendered frames: speedup vs OpenCV {:.2f}x, vs paper loop {:.2f}x, {} threads "
                       "vs 1 {:.2f}x\n",
                       Ratio(rr.fast_all_pps, rr.opencv_pps), Ratio(rr.fast_all_pps, rr.paper_pps), r.threads,
                       Ratio(rr.fast_all_pps, rr.fast_1_pps));
      const PeopleRates& p = rr.people;
      if (p.measured) {
        rendered_row("(j) column fusion 1 thread", p.column_1_pps);
        rendered_row(fmt::format("(j) column fusion {} threads", r.threads), p.column_all_pps);
        rendered_row("(k) explanation 1 thread", p.explain_1_pps);
        rendered_row(fmt::format("(k) explanation {} threads", r.threads), p.explain_all_pps);
        rendered_row("(l) people path 1 thread", p.path_1_pps);
        rendered_row(fmt::format("(l) people path {} threads", r.threads), p.path_all_pps);
        s += fmt::format("  people ({}): column fusion (j) vs OpenCV {:.2f}x, vs FastFusion {:.2f}x; the whole path (l: "
                         "change masks, (j), (k)) vs OpenCV {:.2f}x, vs FastFusion {:.2f}x ({} threads); change masks "
                         "alone {:.3f} ms on 1 thread; {:.0f} occupied candidates, {:.1f} people per frame set; column "
                         "tables built in {:.2f} s, {:.1f} MB\n",
                         p.note, Ratio(p.column_all_pps, rr.opencv_pps), Ratio(p.column_all_pps, rr.fast_all_pps),
                         Ratio(p.path_all_pps, rr.opencv_pps), Ratio(p.path_all_pps, rr.fast_all_pps), r.threads,
                         p.change_test_1_pps > 0 ? 1e3 * static_cast<double>(r.camera_pixels) / p.change_test_1_pps : 0.0,
                         p.occupied_candidates_per_frame, p.people_per_frame, p.column_lut_build_seconds,
                         Mega(p.column_lut_bytes));
      } else {
        s += fmt::format("  people: {}\n", p.note);
      }
    }
  }
  for (const EndToEndResult* e : {&all.end_to_end, &all.wildtrack_end_to_end}) {
    if (e->measured) {
      s += fmt::format("\nend to end ({}):\n  steady state: RunSite {:.1f} frames/s, decode only {:.1f} frames/s "
                       "(one thread per camera {:.1f}, cameras in turn {:.1f}), ratio {:.2f}\n"
                       "  RunSite start-up {:.2f} s, {:.1f} frames/s over the whole call; CPU per frame set: RunSite "
                       "{:.2f} ms, decode only {:.2f} ms; at the steady state {:.2f} ms and {:.2f} ms (occmap's own "
                       "{:.2f} ms)\n"
                       "  RunSite stage times (overlapping threads): decode {:.2f} s, detect {:.2f} s, fuse {:.2f} s, "
                       "blobs {:.2f} s, track {:.2f} s, output {:.2f} s\n"
                       "  RunSite latency, a frame set's arrival to its outputs written: p50 {:.1f} ms, p95 {:.1f} ms, "
                       "p99 {:.1f} ms\n",
                       e->note, e->run_fps, e->decode_fps, e->decode_parallel_fps, e->decode_interleaved_fps,
                       Ratio(e->run_fps, e->decode_fps), e->run_startup_s, e->run_overall_fps, e->run_cpu_ms_per_frame,
                       e->decode_cpu_ms_per_frame, e->run_steady_cpu_ms_per_frame, e->decode_steady_cpu_ms_per_frame,
                       e->run_steady_cpu_ms_per_frame - e->decode_steady_cpu_ms_per_frame, e->decode_s, e->detect_s, e->fuse_s, e->blobs_s, e->track_s,
                       e->output_s, e->latency_p50_ms, e->latency_p95_ms, e->latency_p99_ms);
      if (e->floor.measured) {
        const EndToEndResult::FloorPass& f = e->floor;
        s += fmt::format("  people detector {}: people stage {:.2f} s; occmap's own CPU {:.2f} ms per frame set = {:.2f}x "
                         "the decoding's {:.2f} ms\n"
                         "  floor AND (people detector off: {}): RunSite {:.1f} frames/s (ratio {:.2f}), steady CPU "
                         "{:.2f} ms per frame set, occmap's own {:.2f} ms = {:.2f}x the decoding's; stage times: detect "
                         "{:.2f} s, fuse {:.2f} s, blobs {:.2f} s, track {:.2f} s\n",
                         e->people_detector, e->people_s,
                         e->run_steady_cpu_ms_per_frame - e->decode_steady_cpu_ms_per_frame, e->OwnCpuVsDecode(),
                         e->decode_steady_cpu_ms_per_frame, f.fusion_path, f.run_fps, Ratio(f.run_fps, e->decode_fps),
                         f.run_steady_cpu_ms_per_frame, f.run_steady_cpu_ms_per_frame - e->decode_steady_cpu_ms_per_frame,
                         e->FloorOwnCpuVsDecode(), f.detect_s, f.fuse_s, f.blobs_s, f.track_s);
      }
    } else {
      s += fmt::format("\nend to end ({}): {}\n", e->scene, e->note);
    }
  }
  s += AdaptiveTable(all.adaptive);
  return s;
}

nlohmann::json BenchJson(const BenchResults& all) {
  nlohmann::json out;
  const EndToEndResult& e = all.end_to_end;
  out["machine"] = MachineName();
  out["nproc"] = std::thread::hardware_concurrency();
  out["end_to_end_vs_decode"] = e.measured ? nlohmann::json(Ratio(e.run_fps, e.decode_fps)) : nlohmann::json(nullptr);
  auto end_to_end_json = [](const EndToEndResult& r) {
    nlohmann::json j{{"scene", r.scene},
                          {"measured", r.measured},
                          {"note", r.note},
                          {"frames", r.frames},
                          {"repeats", r.repeats},
                          {"run_frames_per_second", r.run_fps},
                          {"decode_frames_per_second", r.decode_fps},
                          {"decode_parallel_frames_per_second", r.decode_parallel_fps},
                          {"decode_interleaved_frames_per_second", r.decode_interleaved_fps},
                          {"run_startup_seconds", r.run_startup_s},
                          {"run_overall_frames_per_second", r.run_overall_fps},
                          {"run_cpu_ms_per_frame", r.run_cpu_ms_per_frame},
                          {"decode_cpu_ms_per_frame", r.decode_cpu_ms_per_frame},
                          {"run_steady_cpu_ms_per_frame", r.run_steady_cpu_ms_per_frame},
                          {"decode_steady_cpu_ms_per_frame", r.decode_steady_cpu_ms_per_frame},
                          {"run_stage_seconds",
                           {{"decode", r.decode_s},
                            {"detect", r.detect_s},
                            {"fuse", r.fuse_s},
                            {"blobs", r.blobs_s},
                            {"track", r.track_s},
                            {"output", r.output_s},
                            {"people", r.people_s}}},
                          {"latency_ms", {{"p50", r.latency_p50_ms}, {"p95", r.latency_p95_ms}, {"p99", r.latency_p99_ms}}},
                          {"people_detector", r.people_detector},
                          {"own_steady_cpu_ms_per_frame", r.run_steady_cpu_ms_per_frame - r.decode_steady_cpu_ms_per_frame},
                          {"own_cpu_vs_decode", r.OwnCpuVsDecode()}};
    const EndToEndResult::FloorPass& f = r.floor;
    j["floor_and"] = f.measured ? nlohmann::json{{"fusion_path", f.fusion_path},
                                                 {"run_frames_per_second", f.run_fps},
                                                 {"run_vs_decode", Ratio(f.run_fps, r.decode_fps)},
                                                 {"run_startup_seconds", f.run_startup_s},
                                                 {"run_overall_frames_per_second", f.run_overall_fps},
                                                 {"run_cpu_ms_per_frame", f.run_cpu_ms_per_frame},
                                                 {"run_steady_cpu_ms_per_frame", f.run_steady_cpu_ms_per_frame},
                                                 {"own_steady_cpu_ms_per_frame",
                                                  f.run_steady_cpu_ms_per_frame - r.decode_steady_cpu_ms_per_frame},
                                                 {"own_cpu_vs_decode", r.FloorOwnCpuVsDecode()},
                                                 {"run_stage_seconds",
                                                  {{"detect", f.detect_s},
                                                   {"fuse", f.fuse_s},
                                                   {"blobs", f.blobs_s},
                                                   {"track", f.track_s}}}}
                                : nlohmann::json(nullptr);
    return j;
  };
  out["end_to_end"] = end_to_end_json(e);
  out["wildtrack_end_to_end"] = end_to_end_json(all.wildtrack_end_to_end);
  const EndToEndResult& we = all.wildtrack_end_to_end;
  out["notes"] = {
      "pixels_per_second = all cameras' pixels / median time per frame; frames: random background, --changed-fraction "
      "(default 10%) of pixels changed by more than T = 30, independently (few cells fail their first probe)",
      "rendered (wildtrack): the same measurements on frames rendered by the simulator from WILDTRACK's calibrations "
      "and annotated trajectories (grey, empty-scene backgrounds; changes clustered on people: more cells fail their "
      "first probe); rendered once per run, render_seconds apart",
      "fast_* = FastFusion::Fuse, the cell-probe method occmap run uses; row_streaming_* = its row-streaming "
      "method; all_changed_* = FastFusion::Fuse with every pixel changed (the worst case)",
      "end_to_end_vs_decode = RunSite steady-state frames/s / the faster pure decoding pass's steady-state "
      "frames/s over the same H.264 files (start-up reported apart: end_to_end.run_startup_seconds); the top "
      "level's and the paper workload's are the lab scene's (end_to_end), the wildtrack workload's its own scene's "
      "(wildtrack_end_to_end; null when not measured)",
      "own_cpu_vs_decode = (run_steady_cpu_ms_per_frame - decode_steady_cpu_ms_per_frame) / "
      "decode_steady_cpu_ms_per_frame: occmap's own CPU per frame set beside the decoders; with a people detector "
      "on the site (people_detector) floor_and holds the same run without it (the floor AND and its blobs), "
      "else null",
      "rendered.people (wildtrack): the people path on the rendered frames: column_fusion = ChangeRowSums::Build + "
      "ColumnFusion::Fuse, explain = ViewExplainer::Explain, both from the change masks |I - B| > T; path = the "
      "change masks, the column fusion and the explanation; *_vs_opencv and *_vs_fast_fusion on all threads"};
  nlohmann::json list = nlohmann::json::array();
  for (const WorkloadResult& r : all.workloads) {
    nlohmann::json j;
    j["name"] = r.name;
    j["skipped"] = r.skipped;
    if (r.skipped) {
      j["note"] = r.note;
      list.push_back(j);
      continue;
    }
    j["cameras"] = r.cameras;
    j["camera_pixels"] = r.camera_pixels;
    j["cells"] = r.cells;
    j["threads"] = r.threads;
    j["opencv_threads"] = r.opencv_threads;
    j["machine"] = MachineName();
    j["nproc"] = std::thread::hardware_concurrency();
    j["kernel"] = r.kernel;
    j["paper_loop_pixels_per_second"] = r.paper_pps;
    j["opencv_pixels_per_second"] = r.opencv_pps;
    j["fast_1_thread_pixels_per_second"] = r.fast_1_pps;
    j["fast_all_threads_pixels_per_second"] = r.fast_all_pps;
    j["fast_all_threads_vs_1_thread"] = Ratio(r.fast_all_pps, r.fast_1_pps);
    j["change_tests"] = {{"plain_pixels_per_second", r.plain_change_1_pps},
                         {"adaptive_pixels_per_second", r.adaptive_change_1_pps},
                         {"adaptive_update_pixels_per_second", r.adaptive_update_1_pps},
                         {"adaptive_cost_vs_plain", Ratio(r.plain_change_1_pps, r.adaptive_change_1_pps)}};
    j["row_streaming_1_thread_pixels_per_second"] = r.streaming_1_pps;
    j["row_streaming_all_threads_pixels_per_second"] = r.streaming_all_pps;
    j["all_changed_1_thread_pixels_per_second"] = r.worst_1_pps;
    j["all_changed_all_threads_pixels_per_second"] = r.worst_all_pps;
    j["fast_probe_table_bytes"] = r.fast_probe_table_bytes;
    j["fast_streaming_table_bytes"] = r.fast_streaming_table_bytes;
    j["primary_probes"] = r.primary_probes;
    j["secondary_probes"] = r.secondary_probes;
    j["probe_bytes_read_per_frame"] = r.probe_bytes_read_per_frame;
    j["speedup_vs_opencv"] = Ratio(r.fast_all_pps, r.opencv_pps);
    j["speedup_vs_paper_loop"] = Ratio(r.fast_all_pps, r.paper_pps);
    j["speedup_1_thread_vs_paper_loop"] = Ratio(r.fast_1_pps, r.paper_pps);
    j["lut_build_seconds"] = r.lut_build_seconds;
    j["fast_build_seconds"] = r.fast_build_seconds;
    j["lut_bytes"] = r.lut_bytes;
    j["fast_bytes"] = r.fast_bytes;
    j["fast_runs"] = r.fast_runs;
    j["fast_pairs"] = r.fast_pairs;
    j["mapped_pixels"] = r.mapped_pixels;
    j["fast_bytes_read_per_frame"] = r.fast_bytes_read_per_frame;
    j["primary_failure_fraction"] = r.primary_failure_fraction;
    j["primary_tested_fraction"] = r.primary_tested_fraction;
    const RenderedResult& rr = r.rendered;
    if (rr.measured) {
      j["rendered"] = {{"skipped", false},
                       {"frames", rr.frames},
                       {"note", rr.note},
                       {"render_seconds", rr.render_seconds},
                       {"changed_fraction", rr.changed_fraction},
                       {"paper_loop_pixels_per_second", rr.paper_pps},
                       {"opencv_pixels_per_second", rr.opencv_pps},
                       {"fast_1_thread_pixels_per_second", rr.fast_1_pps},
                       {"fast_all_threads_pixels_per_second", rr.fast_all_pps},
                       {"row_streaming_1_thread_pixels_per_second", rr.streaming_1_pps},
                       {"row_streaming_all_threads_pixels_per_second", rr.streaming_all_pps},
                       {"fast_all_threads_vs_1_thread", Ratio(rr.fast_all_pps, rr.fast_1_pps)},
                       {"speedup_vs_opencv", Ratio(rr.fast_all_pps, rr.opencv_pps)},
                       {"speedup_vs_paper_loop", Ratio(rr.fast_all_pps, rr.paper_pps)},
                       {"speedup_1_thread_vs_paper_loop", Ratio(rr.fast_1_pps, rr.paper_pps)},
                       {"primary_failure_fraction", rr.primary_failure_fraction},
                       {"primary_tested_fraction", rr.primary_tested_fraction},
                       {"secondary_probes_per_frame", rr.secondary_probes_per_frame},
                       {"streamed_frame_fraction", rr.streamed_frame_fraction}};
      const PeopleRates& p = rr.people;
      const double pixels = static_cast<double>(r.camera_pixels);
      auto ms = [&](double pps) { return pps > 0 ? 1e3 * pixels / pps : 0.0; };
      j["rendered"]["people"] =
          p.measured ? nlohmann::json{{"measured", true},
                                      {"note", p.note},
                                      {"candidates", p.candidates},
                                      {"occluders", p.occluders},
                                      {"column_lut_build_seconds", p.column_lut_build_seconds},
                                      {"column_lut_bytes", p.column_lut_bytes},
                                      {"change_test_1_thread_pixels_per_second", p.change_test_1_pps},
                                      {"column_fusion_1_thread_pixels_per_second", p.column_1_pps},
                                      {"column_fusion_all_threads_pixels_per_second", p.column_all_pps},
                                      {"explain_1_thread_pixels_per_second", p.explain_1_pps},
                                      {"explain_all_threads_pixels_per_second", p.explain_all_pps},
                                      {"path_1_thread_pixels_per_second", p.path_1_pps},
                                      {"path_all_threads_pixels_per_second", p.path_all_pps},
                                      {"column_fusion_1_thread_ms_per_frame_set", ms(p.column_1_pps)},
                                      {"column_fusion_all_threads_ms_per_frame_set", ms(p.column_all_pps)},
                                      {"explain_1_thread_ms_per_frame_set", ms(p.explain_1_pps)},
                                      {"explain_all_threads_ms_per_frame_set", ms(p.explain_all_pps)},
                                      {"path_1_thread_ms_per_frame_set", ms(p.path_1_pps)},
                                      {"path_all_threads_ms_per_frame_set", ms(p.path_all_pps)},
                                      {"column_fusion_vs_opencv", Ratio(p.column_all_pps, rr.opencv_pps)},
                                      {"column_fusion_vs_fast_fusion", Ratio(p.column_all_pps, rr.fast_all_pps)},
                                      {"path_vs_opencv", Ratio(p.path_all_pps, rr.opencv_pps)},
                                      {"path_vs_fast_fusion", Ratio(p.path_all_pps, rr.fast_all_pps)},
                                      {"occupied_candidates_per_frame", p.occupied_candidates_per_frame},
                                      {"people_per_frame", p.people_per_frame}}
                     : nlohmann::json{{"measured", false}, {"note", p.note}};
    } else if (r.name == "wildtrack") {
      j["rendered"] = {{"skipped", true}, {"note", rr.note}};
    }
    if (r.name == "wildtrack") {
      j["end_to_end_vs_decode"] = we.measured ? nlohmann::json(Ratio(we.run_fps, we.decode_fps)) : nlohmann::json(nullptr);
    } else {
      j["end_to_end_vs_decode"] = out["end_to_end_vs_decode"];
    }
    list.push_back(j);
  }
  out["workloads"] = list;
  out["adaptive"] = AdaptiveJson(all.adaptive);
  return out;
}

}  // namespace occmap::bench
