#include "occmap/bench/adaptive_bench.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/video/background_segm.hpp>

#include "occmap/bench/pass_times.h"
#include "occmap/detect/background_model.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/io/frame_source.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/site/site.h"
#include "occmap/util/simd.h"

namespace occmap::bench {
namespace {

using Clock = std::chrono::steady_clock;

// The fastest pass's time per frame set of fn(frame index), in seconds.
double FastestSecondsPerSet(int repetitions, int frames, const std::function<void(int)>& fn) {
  const std::vector<double> times = SecondsPerFrameOfEachPass(repetitions, frames, fn);
  return *std::min_element(times.begin(), times.end());
}

// One camera's frames as read, and what each method keeps.
struct CameraData {
  std::vector<YuvImage> frames;
  std::vector<cv::Mat> bgr;                  // the frames for MOG2
  std::vector<Image<uint8_t>> protection;    // per frame
  std::unique_ptr<BackgroundModel> model;
  cv::Ptr<cv::BackgroundSubtractorMOG2> mog2;
  Image<uint8_t> changes;
  cv::Mat mog2_mask;
  YuvImage background;
};

Result<AdaptiveResult> RunOne(const std::filesystem::path& dataset, const AdaptiveBenchOptions& options, Context& ctx) {
  std::error_code ec;
  const std::filesystem::path site_file =
      std::filesystem::is_directory(dataset, ec) ? dataset / "site.yaml" : dataset;
  SiteLoadOptions load;
  if (!options.data_root.empty()) load.data_root = options.data_root;
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(site_file, load));
  AdaptiveResult r;
  r.site_file = site_file.string();
  r.name = std::filesystem::is_directory(dataset, ec) ? dataset.filename().string() : site.name;
  if (r.name.empty()) r.name = site.name;
  r.cameras = static_cast<int>(site.cameras.size());
  r.threads = ctx.num_threads();
  r.threshold = site.detection.threshold;
  r.kernel = KernelSetName(ActiveKernels());
  BackgroundOptions bo = site.backgrounds;
  bo.adaptive = true;

  // Frames: luma, chroma and RGB (MOG2's input) of the first `frames` frame sets.
  FrameSourceOptions src;
  src.chroma = true;
  src.colour = true;
  src.decoder_threads = ctx.num_threads();
  std::vector<CameraData> cams(site.cameras.size());
  for (size_t n = 0; n < site.cameras.size(); ++n) {
    if (site.cameras[n].source.kind == FrameSourceSpec::Kind::kMasks) {
      return InvalidInput(fmt::format("{}: camera {} gives masks, not frames: nothing to measure", site_file.string(),
                                      site.cameras[n].id));
    }
    OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> source, OpenFrameSource(site.cameras[n].source, src));
    Frame frame;
    for (int f = 0; f < options.frames; ++f) {
      OCCMAP_ASSIGN_OR_RETURN(bool more, source->Read(frame));
      if (!more) break;
      YuvImage yuv;
      yuv.y = frame.gray;
      yuv.u = frame.u;
      yuv.v = frame.v;
      cams[n].frames.push_back(std::move(yuv));
      cv::Mat rgb(frame.rgb.height(), frame.rgb.width(), CV_8UC3, frame.rgb.row(0),
                  static_cast<size_t>(frame.rgb.stride_elems()) * sizeof(Rgb8));
      cams[n].bgr.push_back(rgb.clone());  // channel order does not matter to MOG2
    }
    if (cams[n].frames.size() < 2) {
      return InvalidInput(fmt::format("{}: camera {} has {} frames, expected at least 2", site_file.string(),
                                      site.cameras[n].id, cams[n].frames.size()));
    }
  }
  size_t count = cams[0].frames.size();
  for (const CameraData& c : cams) count = std::min(count, c.frames.size());
  r.frames = static_cast<int>(count);
  r.chroma = cams[0].frames[0].has_chroma();
  for (CameraData& c : cams) {
    c.frames.resize(count);
    c.bgr.resize(count);
    r.camera_pixels += static_cast<int64_t>(c.frames[0].y.width()) * c.frames[0].y.height();
  }
  const double fps = 10;  // the time constants' scale only

  // The backgrounds as `occmap run` learns them, the shadow look warmed up, then the protection
  // maps from a first pass of the change test.
  const auto t0 = Clock::now();
  ParallelFor(ctx, 0, static_cast<int64_t>(cams.size()), [&](int64_t b, int64_t e, int) {
    for (int64_t n = b; n < e; ++n) {
      CameraData& c = cams[static_cast<size_t>(n)];
      const int w = c.frames[0].y.width(), h = c.frames[0].y.height();
      BackgroundLearner learner(w, h, c.frames[0].has_chroma(), static_cast<int>(count));
      for (const YuvImage& f : c.frames) learner.Add(f.view());
      BackgroundLearner::Alternative alternative;
      c.background = learner.Learn(bo.learning, bo.mode_radius, &alternative);
      c.model = std::make_unique<BackgroundModel>(bo, fps);
      c.model->Reset(c.background);
      c.model->SetAlternative(alternative, static_cast<int>(std::ceil(bo.alternative_min_share * static_cast<double>(count))));
      c.model->PreferLitAlternatives();
      std::vector<YuvView> views;
      for (const YuvImage& f : c.frames) views.push_back(f.view());
      c.model->WarmUp(views, site.detection.threshold);
      c.changes = Image<uint8_t>(w, h);
      for (const YuvImage& f : c.frames) {
        c.model->DetectChanges(f.view(), site.detection.threshold, c.changes.view());
        Image<uint8_t> p(w, h);
        for (int y = 0; y < h; ++y) {
          const uint8_t* ch = c.changes.row(y);
          uint8_t* o = p.row(y);
          for (int x = 0; x < w; ++x) o[x] = ch[x] != 0 ? BackgroundModel::kPerson : BackgroundModel::kFree;
        }
        c.protection.push_back(std::move(p));
      }
      c.mog2 = cv::createBackgroundSubtractorMOG2(500, 16, true);
    }
  });
  r.learn_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  int64_t changed = 0;
  for (const CameraData& c : cams) {
    for (const Image<uint8_t>& p : c.protection) {
      for (int y = 0; y < p.height(); ++y) {
        const uint8_t* row = p.row(y);
        for (int x = 0; x < p.width(); ++x) changed += row[x] != 0;
      }
    }
  }
  r.changed_fraction = static_cast<double>(changed) / (static_cast<double>(r.camera_pixels) * static_cast<double>(count));

  const int frames = static_cast<int>(count);
  const int threshold = site.detection.threshold;
  const double pixels = static_cast<double>(r.camera_pixels);
  Context one(1);
  // fn(camera, frame, frame index): the index grows over the passes, as a run's (Update's ages).
  int64_t frame_index = static_cast<int64_t>(count);
  auto per_camera = [&](Context& c, const std::function<void(CameraData&, int, int64_t)>& fn) {
    return pixels / FastestSecondsPerSet(options.repetitions, frames, [&](int f) {
             const int64_t index = frame_index++;
             ParallelFor(c, 0, static_cast<int64_t>(cams.size()), [&](int64_t b, int64_t e, int) {
               for (int64_t n = b; n < e; ++n) fn(cams[static_cast<size_t>(n)], f, index);
             });
           });
  };
  auto adaptive = [&](CameraData& c, int f, int64_t index) {
    const YuvView v = c.frames[static_cast<size_t>(f)].view();
    c.model->DetectChanges(v, threshold, c.changes.view());
    c.model->Update(v, c.protection[static_cast<size_t>(f)].view(), index);
  };
  // OpenCV's own pool at one thread: the cameras are spread over the same threads as ours.
  const int saved_cv_threads = cv::getNumThreads();
  cv::setNumThreads(1);
  r.adaptive_1_pps = per_camera(one, adaptive);
  r.adaptive_all_pps = per_camera(ctx, adaptive);
  r.change_1_pps = per_camera(one, [&](CameraData& c, int f, int64_t) {
    c.model->DetectChanges(c.frames[static_cast<size_t>(f)].view(), threshold, c.changes.view());
  });
  r.update_1_pps = per_camera(one, [&](CameraData& c, int f, int64_t index) {
    c.model->Update(c.frames[static_cast<size_t>(f)].view(), c.protection[static_cast<size_t>(f)].view(), index);
  });
  auto mog2 = [&](CameraData& c, int f, int64_t) { c.mog2->apply(c.bgr[static_cast<size_t>(f)], c.mog2_mask); };
  for (CameraData& c : cams) {
    for (int f = 0; f < frames; ++f) mog2(c, f, 0);
  }
  r.mog2_1_pps = per_camera(one, mog2);
  r.mog2_all_pps = per_camera(ctx, mog2);
  cv::setNumThreads(saved_cv_threads);

  // The paper's test fused with the floor AND, against the learned luma backgrounds.
  OCCMAP_ASSIGN_OR_RETURN(GroundLut lut, BuildGroundLut(site.LutInputs(), site.grid, site.lut, ctx));
  FastFusion fast(lut);
  std::vector<ImageView<const uint8_t>> backgrounds;
  for (const CameraData& c : cams) backgrounds.push_back(c.background.y.view());
  std::vector<std::vector<ImageView<const uint8_t>>> frame_views(count);
  for (size_t f = 0; f < count; ++f) {
    for (const CameraData& c : cams) frame_views[f].push_back(c.frames[f].y.view());
  }
  OccupancyMap map;
  r.paper_1_pps = pixels / FastestSecondsPerSet(options.repetitions, frames, [&](int f) {
                    fast.Fuse(frame_views[static_cast<size_t>(f)], backgrounds, threshold, one, map);
                  });
  r.paper_all_pps = pixels / FastestSecondsPerSet(options.repetitions, frames, [&](int f) {
                      fast.Fuse(frame_views[static_cast<size_t>(f)], backgrounds, threshold, ctx, map);
                    });
  return r;
}

}  // namespace

Status AdaptiveBenchOptions::Validate() const {
  if (datasets.empty()) {
    return InvalidInput("--dataset: the adaptive workload needs at least one dataset folder written by `occmap synth`");
  }
  if (frames < 2 || frames > 255) return InvalidInput(fmt::format("--adaptive-frames: expected 2..255, found {}", frames));
  if (repetitions < 1) return InvalidInput("repetitions: expected at least 1");
  return Status::Ok();
}

Result<std::vector<AdaptiveResult>> RunAdaptiveBench(const AdaptiveBenchOptions& options, Context& ctx) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  std::vector<AdaptiveResult> out;
  for (const std::filesystem::path& d : options.datasets) {
    OCCMAP_ASSIGN_OR_RETURN(AdaptiveResult r, RunOne(d, options, ctx));
    out.push_back(std::move(r));
  }
  return out;
}

std::string AdaptiveTable(const std::vector<AdaptiveResult>& results) {
  std::string s;
  for (const AdaptiveResult& r : results) {
    s += fmt::format("\nadaptive, {} ({}): {} cameras, {:.2f} Mpixel per frame set, {} frame sets, T = {}, {}; kernel {}; "
                     "backgrounds learned and warmed up in {:.1f} s; {:.2f} % of pixels changed\n",
                     r.name, r.site_file, r.cameras, static_cast<double>(r.camera_pixels) / 1e6, r.frames, r.threshold,
                     r.chroma ? "luma and chroma" : "luma only", r.kernel, r.learn_seconds, 100 * r.changed_fraction);
    s += fmt::format("  {:<44} {:>10} {:>10} {:>12} {:>12}\n", "method", "Gpixel/s", "ms/set", "vs MOG2", "vs paper");
    auto row = [&](const std::string& name, double pps, double mog2, double paper) {
      s += fmt::format("  {:<44} {:>10.3f} {:>10.2f} {:>11.2f}x {:>11.2f}x\n", name, pps / 1e9,
                       pps > 0 ? 1e3 * static_cast<double>(r.camera_pixels) / pps : 0.0, Ratio(pps, mog2),
                       Ratio(pps, paper));
    };
    row("adaptive: change test + upkeep, 1 thread", r.adaptive_1_pps, r.mog2_1_pps, r.paper_1_pps);
    row(fmt::format("adaptive: change test + upkeep, {} threads", r.threads), r.adaptive_all_pps, r.mog2_all_pps,
        r.paper_all_pps);
    row("  change test alone, 1 thread", r.change_1_pps, r.mog2_1_pps, r.paper_1_pps);
    row("  upkeep alone, 1 thread", r.update_1_pps, r.mog2_1_pps, r.paper_1_pps);
    row("OpenCV MOG2 apply(), 1 thread", r.mog2_1_pps, r.mog2_1_pps, r.paper_1_pps);
    row(fmt::format("OpenCV MOG2 apply(), {} threads", r.threads), r.mog2_all_pps, r.mog2_all_pps, r.paper_all_pps);
    row("paper's test fused (FastFusion), 1 thread", r.paper_1_pps, r.mog2_1_pps, r.paper_1_pps);
    row(fmt::format("paper's test fused (FastFusion), {} threads", r.threads), r.paper_all_pps, r.mog2_all_pps,
        r.paper_all_pps);
  }
  return s;
}

nlohmann::json AdaptiveJson(const std::vector<AdaptiveResult>& results) {
  nlohmann::json list = nlohmann::json::array();
  for (const AdaptiveResult& r : results) {
    list.push_back({{"name", r.name},
                    {"site_file", r.site_file},
                    {"cameras", r.cameras},
                    {"camera_pixels", r.camera_pixels},
                    {"frames", r.frames},
                    {"threads", r.threads},
                    {"threshold", r.threshold},
                    {"chroma", r.chroma},
                    {"kernel", r.kernel},
                    {"learn_seconds", r.learn_seconds},
                    {"changed_fraction", r.changed_fraction},
                    {"adaptive_1_thread_pixels_per_second", r.adaptive_1_pps},
                    {"adaptive_all_threads_pixels_per_second", r.adaptive_all_pps},
                    {"change_test_1_thread_pixels_per_second", r.change_1_pps},
                    {"upkeep_1_thread_pixels_per_second", r.update_1_pps},
                    {"mog2_1_thread_pixels_per_second", r.mog2_1_pps},
                    {"mog2_all_threads_pixels_per_second", r.mog2_all_pps},
                    {"paper_fused_1_thread_pixels_per_second", r.paper_1_pps},
                    {"paper_fused_all_threads_pixels_per_second", r.paper_all_pps},
                    {"adaptive_vs_mog2", Ratio(r.adaptive_all_pps, r.mog2_all_pps)},
                    {"adaptive_vs_paper_fused", Ratio(r.adaptive_all_pps, r.paper_all_pps)}});
  }
  return list;
}

}  // namespace occmap::bench
