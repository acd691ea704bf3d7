// Change detection, median backgrounds and the simulator for Python.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <array>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common.h"
#include "occmap/detect/background.h"
#include "occmap/detect/change_detection.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/sim/renderer.h"
#include "occmap/sim/scene.h"
#include "occmap/sim/scene_yaml.h"

namespace occmap::python {
namespace {

namespace fs = std::filesystem;
using namespace pybind11::literals;

// A view of a (rows, columns, 3) uint8 array as RGB pixels.
ImageView<const Rgb8> RgbView(const U8Array& array, const std::string& what) {
  if (array.ndim() != 3 || array.shape(2) != 3) {
    ThrowInvalid(what + ": expected a (rows, columns, 3) RGB array, found " + std::to_string(array.ndim()) + "-D");
  }
  if (array.shape(0) == 0 || array.shape(1) == 0) ThrowInvalid(what + ": expected a non-empty image");
  return {reinterpret_cast<const Rgb8*>(array.data()), static_cast<int>(array.shape(1)),
          static_cast<int>(array.shape(0)), array.shape(1)};
}

void CheckSameSize(const U8Array& a, const U8Array& b) {
  for (int d = 0; d < a.ndim() && d < b.ndim(); ++d) {
    if (a.shape(d) != b.shape(d)) {
      ThrowInvalid("background: expected the frame's size (" + std::to_string(a.shape(0)) + " x " +
                   std::to_string(a.shape(1)) + "), found " + std::to_string(b.shape(0)) + " x " +
                   std::to_string(b.shape(1)));
    }
  }
  if (a.ndim() != b.ndim()) ThrowInvalid("background: expected as many channels as the frame");
}

// Equation 4 with the tolerance: 1 where |frame - background| > threshold (any channel of RGB).
py::array_t<uint8_t> DetectChanges(const U8Array& frame, const U8Array& background, int threshold, int tolerance_px) {
  ChangeDetectionOptions options;
  options.threshold = threshold;
  options.tolerance_px = tolerance_px;
  ThrowIfError(options.Validate());
  if (frame.ndim() != 2 && frame.ndim() != 3) {
    ThrowInvalid("frame: expected a grey (rows, columns) or RGB (rows, columns, 3) array, found " +
                 std::to_string(frame.ndim()) + "-D");
  }
  CheckSameSize(frame, background);
  const bool rgb = frame.ndim() == 3;
  const int width = static_cast<int>(frame.shape(1)), height = static_cast<int>(frame.shape(0));
  ImageView<const Rgb8> frame_rgb, background_rgb;
  ImageView<const uint8_t> frame_gray, background_gray;
  if (rgb) {
    frame_rgb = RgbView(frame, "frame");
    background_rgb = RgbView(background, "background");
  } else {
    frame_gray = GrayView(frame, "frame");
    background_gray = GrayView(background, "background");
  }
  Image<uint8_t> raw(width, height), out(width, height);
  {
    py::gil_scoped_release release;
    if (rgb) {
      DetectChangesRgb(frame_rgb, background_rgb, threshold, raw.view());
    } else {
      DetectChangesGray(frame_gray, background_gray, threshold, raw.view());
    }
    std::vector<uint8_t> scratch;
    if (tolerance_px > 0) DilateChanges(raw.view(), tolerance_px, out.view(), scratch);
  }
  return ToArray(tolerance_px > 0 ? out.view() : raw.view());
}

// A per-pixel median of grey or RGB frames.
class PyMedianBackground {
 public:
  void Add(const U8Array& frame) {
    const bool rgb = frame.ndim() == 3;
    if (!gray_ && !rgb_) {
      if (rgb) {
        RgbView(frame, "frame");
        rgb_.emplace(static_cast<int>(frame.shape(1)), static_cast<int>(frame.shape(0)));
      } else {
        GrayView(frame, "frame");
        gray_.emplace(static_cast<int>(frame.shape(1)), static_cast<int>(frame.shape(0)));
      }
      shape_ = {frame.shape(0), frame.shape(1)};
    }
    if (rgb != rgb_.has_value() || frame.shape(0) != shape_[0] || frame.shape(1) != shape_[1]) {
      ThrowInvalid("frame: expected the first frame's size and channels (" + std::to_string(shape_[0]) + " x " +
                   std::to_string(shape_[1]) + (rgb_ ? " x 3" : "") + ")");
    }
    if (count() >= MedianBackground::kMaxFrames) {
      ThrowInvalid("frame: a median background holds at most " + std::to_string(MedianBackground::kMaxFrames) + " frames");
    }
    const int w = static_cast<int>(shape_[1]), h = static_cast<int>(shape_[0]);
    if (rgb_) {
      rgb_->Add(ImageView<const Rgb8>(reinterpret_cast<const Rgb8*>(frame.data()), w, h, w));
    } else {
      gray_->Add(ImageView<const uint8_t>(frame.data(), w, h, w));
    }
  }
  int count() const { return rgb_ ? rgb_->count() : gray_ ? gray_->count() : 0; }
  py::array_t<uint8_t> Median() const {
    if (count() == 0) ThrowInvalid("median: no frame added");
    if (rgb_) return ToArray(rgb_->Median().view());
    return ToArray(gray_->Median().view());
  }

 private:
  std::optional<MedianBackground> gray_;
  std::optional<MedianBackgroundRgb> rgb_;
  std::array<py::ssize_t, 2> shape_{};
};

// A scene with one renderer per camera (the static scene cast once).
class Simulator {
 public:
  Simulator(sim::SceneSpec spec, int threads) : ctx_(threads), scene_(Unwrap(sim::Scene::Create(std::move(spec)))) {
    py::gil_scoped_release release;
    for (size_t c = 0; c < scene_.num_cameras(); ++c) renderers_.push_back(std::make_unique<sim::CameraRenderer>(scene_, c, ctx_));
  }

  const sim::Scene& scene() const { return scene_; }

  py::dict Render(int64_t frame, bool noise, bool shadow_masks) {
    if (frame < 0 || frame >= scene_.num_frames()) {
      ThrowInvalid("frame: expected 0.." + std::to_string(scene_.num_frames() - 1) + ", found " + std::to_string(frame));
    }
    std::vector<sim::RenderedView> views(renderers_.size());
    sim::SceneState state;
    {
      py::gil_scoped_release release;
      std::lock_guard lock(mutex_);
      state = scene_.StateAt(frame);
      for (size_t c = 0; c < renderers_.size(); ++c) renderers_[c]->Render(state, ctx_, &views[c], noise, shadow_masks);
    }
    py::list frames, masks, shadows, truth;
    for (const sim::RenderedView& v : views) {
      frames.append(ToArray(v.rgb.view()));
      masks.append(ToArray(sim::ChangeMask(v.ids).view()));
      if (shadow_masks) shadows.append(ToArray(v.shadow.view()));
    }
    const FloorGrid& g = scene_.grid();
    const GroundTruthFrame truth_frame = sim::ToGroundTruth(state);
    for (const GroundTruthObject& o : truth_frame.objects) {
      const bool inside = o.x_m >= g.origin_x_m && o.x_m < g.origin_x_m + g.size_x_m() && o.y_m >= g.origin_y_m &&
                          o.y_m < g.origin_y_m + g.size_y_m();
      truth.append(py::dict("id"_a = o.id, "class"_a = o.object_class, "x_m"_a = o.x_m, "y_m"_a = o.y_m,
                            "inside"_a = inside));
    }
    py::dict out("frame"_a = frame, "time_s"_a = scene_.TimeOf(frame), "frames"_a = frames, "change_masks"_a = masks,
                 "ground_truth"_a = truth);
    if (shadow_masks) out["shadow_masks"] = shadows;
    return out;
  }

  py::list Backgrounds(bool noise) const {
    py::list out;
    for (const auto& r : renderers_) out.append(ToArray(r->Background(noise).view()));
    return out;
  }
  py::list FloorMasks() const {
    py::list out;
    for (const auto& r : renderers_) out.append(ToArray(r->floor_mask().view()));
    return out;
  }

  fs::path WriteDataset(const fs::path& out_dir, bool video, bool site_backgrounds) {
    sim::DatasetOptions options;
    options.out_dir = out_dir;
    options.frame_format = video ? sim::DatasetOptions::FrameFormat::kVideo : sim::DatasetOptions::FrameFormat::kPng;
    options.site_backgrounds = site_backgrounds;
    py::gil_scoped_release release;
    std::lock_guard lock(mutex_);
    Result<sim::DatasetSummary> summary = sim::WriteDataset(scene_, options, ctx_);
    if (!summary.ok()) {
      py::gil_scoped_acquire acquire;
      throw StatusError(summary.status());
    }
    return summary->site_file;
  }

 private:
  Context ctx_;
  sim::Scene scene_;
  std::vector<std::unique_ptr<sim::CameraRenderer>> renderers_;
  std::mutex mutex_;
};

sim::SceneSpec MakeSpec(const std::string& scene, uint64_t seed, std::optional<int64_t> frames, double scale,
                        std::optional<double> noise, bool shadows) {
  sim::BuiltinSceneOptions options;
  options.seed = seed;
  options.image_scale = scale;
  options.num_frames = frames.value_or(-1);
  options.noise_sigma = noise.value_or(-1);
  options.shadows = shadows;
  ThrowIfError(options.Validate());
  for (const std::string& name : sim::BuiltinSceneNames()) {
    if (scene == name && name != "wildtrack") return Unwrap(sim::MakeBuiltinSceneSpec(scene, options));
  }
  // A scene YAML file (sim/scene_yaml.h), or its text.
  sim::SceneSpec spec = scene.find('\n') != std::string::npos ? Unwrap(sim::ParseSceneYaml(scene, "<scene text>"))
                                                              : Unwrap(sim::LoadSceneYaml(scene));
  ThrowIfError(sim::ApplyBuiltinOptions(options, spec));
  return spec;
}

}  // namespace

void BindSim(py::module_& m) {
  m.def("detect_changes", &DetectChanges, "frame"_a, "background"_a, "threshold"_a = 30, "tolerance_px"_a = 0,
        "Equation 4: 1 where |frame - background| > threshold, else 0 (grey (rows, columns) or RGB\n"
        "(rows, columns, 3): a change in any channel), dilated by tolerance_px. Releases the GIL.");

  py::class_<PyMedianBackground>(m, "MedianBackground", "The per-pixel median of grey or RGB frames (at most 255).")
      .def(py::init<>())
      .def("add", &PyMedianBackground::Add, "frame"_a)
      .def_property_readonly("count", &PyMedianBackground::count)
      .def("median", &PyMedianBackground::Median, "The background: the lower median of each pixel (and channel).");

  py::class_<Simulator>(m, "Simulator",
      "A rendered scene: frames of every camera with exact ground truth and perfect change masks.")
      .def(py::init([](const std::string& scene, uint64_t seed, std::optional<int64_t> frames, double scale,
                       std::optional<double> noise, bool shadows, int threads) {
             return std::make_unique<Simulator>(MakeSpec(scene, seed, frames, scale, noise, shadows), threads);
           }),
           "scene"_a = "lab", "seed"_a = 1, "frames"_a = py::none(), "scale"_a = 1.0, "noise"_a = py::none(),
           "shadows"_a = false, "threads"_a = 0,
           "scene: lab, clemson, plaza, a scene YAML file, or a scene's YAML text (scene_yaml() gives one\n"
           "to start from). frames: the scene's length by default; scale: image size as a fraction;\n"
           "noise: sensor noise sigma in grey levels (default 2); shadows: cast shadows.")
      .def_property_readonly("num_frames", [](const Simulator& s) { return s.scene().num_frames(); })
      .def_property_readonly("fps", [](const Simulator& s) { return s.scene().spec().fps; })
      .def_property_readonly("grid", [](const Simulator& s) { return s.scene().grid(); })
      .def_property_readonly("camera_ids", [](const Simulator& s) {
        std::vector<std::string> ids;
        for (size_t c = 0; c < s.scene().num_cameras(); ++c) ids.push_back(s.scene().camera_id(c));
        return ids;
      })
      .def("render", &Simulator::Render, "frame"_a, "noise"_a = true, "shadow_masks"_a = false,
           "One frame: a dict with 'frames' (RGB arrays, one per camera), 'change_masks' (255 where a\n"
           "moving object is seen), 'ground_truth' (dicts id, class, x_m, y_m, inside: within the grid),\n"
           "'time_s', and with shadow_masks 'shadow_masks'. Releases the GIL.")
      .def("backgrounds", &Simulator::Backgrounds, "noise"_a = true, "The empty scene of each camera (RGB).")
      .def("floor_masks", &Simulator::FloorMasks, "Per camera, 255 where the pixel sees the monitored floor.")
      .def("write_dataset", &Simulator::WriteDataset, "out_dir"_a, "video"_a = false, "site_backgrounds"_a = true,
           "Writes the dataset `occmap synth` writes (site.yaml, frames, masks, ground truth); returns the\n"
           "site file's path, for load_site.");

  m.def("scene_yaml", [](const std::string& name, uint64_t seed) {
    sim::BuiltinSceneOptions options;
    options.seed = seed;
    return sim::SceneToYaml(Unwrap(sim::MakeBuiltinSceneSpec(name, options)));
  }, "name"_a = "lab", "seed"_a = 1, "A built-in scene as YAML text: edit it to make a custom scene for Simulator.");
}

}  // namespace occmap::python
