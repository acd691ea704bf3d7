// WriteDataset: renders a Scene into a dataset folder that `occmap run` reads as it is.
//
//   site.yaml                    the site (LoadSite): grid, cameras with relative paths to
//                                their calibration, mask, frames and (unless
//                                site_backgrounds is off) background; written last, so a
//                                folder with a site.yaml is complete
//   calib/intr_<cam>.xml, calib/extr_<cam>.xml   pinhole cameras (OpenCV FileStorage, metres)
//   calib/tsai_<cam>.yaml        Tsai cameras (Willson's units, T in mm)
//   frames/<cam>/%06d.png        RGB frames (or frames/<cam>.mp4, H.264 through io/VideoWriter);
//                                with a scene camera's jpeg_quality %06d.jpg, with its video_crf
//                                that H.264 rate factor; a real camera's exposure and white
//                                balance follow each camera's frames in order
//   backgrounds/<cam>.png        the empty scene (its own noise stream, or none); written even
//                                when site.yaml does not name them (for evaluation)
//   masks/<cam>.png              floor mask: 255 where the pixel sees the monitored floor, 0 where
//                                it sees walls, furniture, static occluders or nothing
//   ground_truth.jsonl           sim/ground_truth.h, one line per frame: the objects whose
//                                position is inside the monitored area (the grid)
//   gt/footprint/%06d.png        per cell: 255 where an object touches the floor, else 0
//   gt/hull/%06d.png             the ideal plane hull: 255 free, 0 occupied, 128 unseen
//                                (both one pixel per cell, +x right, +y up: row 0 = cell row
//                                cells_y - 1, as occmap's occupancy pictures)
//   gt/changes/<cam>/%06d.png    perfect change masks: 255 where a moving object is seen
//   gt/shadows/<cam>/%06d.png    with change masks and cast or contact shadows on: 255 where a
//                                moving object's shadow darkens a static floor pixel that no
//                                moving object covers (renderer.h: a contact shadow from 1/16
//                                of the pixel's radiance), else 0 (shadows are not objects:
//                                they are not in gt/changes)
//   scene.yaml                   the scene (sim/scene_yaml.h): renders the same dataset again
//   scene.json, README.txt       what the scene is, sizes, conventions, file list
// Frame numbers in file names and in ground_truth.jsonl are the dataset's own, from 0 (the
// frame index of the pipeline's sources); time_s = frame / fps.
//
// Every file is written atomically (util/file_util.h). Work per camera: the static scene is
// cast once, then the frames are rendered (rows in parallel on the context's threads) and
// encoded (frames in parallel).
//
//   sim::DatasetOptions options;  options.out_dir = "lab-data";
//   OCCMAP_ASSIGN_OR_RETURN(sim::DatasetSummary s, sim::WriteDataset(scene, options, ctx, on_progress));
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "occmap/sim/scene.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap::sim {

struct DatasetOptions {
  enum class FrameFormat { kPng, kVideo };
  std::filesystem::path out_dir;
  FrameFormat frame_format = FrameFormat::kPng;
  bool change_masks = true;   // gt/changes/
  bool gt_rasters = true;     // gt/footprint/, gt/hull/
  // Written into site.yaml (detection.threshold): 7 sigma of the difference of a frame and a
  // background with the renderer's default noise (noise_sigma 2 each), and low enough for
  // clothes near the floor's colour (on lab seeds 1-5, T = 20 beats T = 30 on every seed).
  int detection_threshold = 20;
  // Whether site.yaml gives each camera its background (backgrounds/<cam>.png). Off, the run
  // learns the backgrounds from the frames, as on a real site; the files are written anyway.
  bool site_backgrounds = true;
  // When not empty, replaces site.yaml's detection section (from "detection:" on, YAML at the
  // top level, e.g. "detection:\n  threshold: 25\n"); empty: threshold and tolerance_px 1.
  std::string site_detection_yaml;
  Status Validate() const;
};

struct DatasetProgress {
  std::string stage;  // "camera cam1", "ground truth"
  int64_t done = 0;   // work units (camera frames + ground-truth frames) finished
  int64_t total = 0;
};
using DatasetProgressCallback = std::function<void(const DatasetProgress&)>;

struct DatasetSummary {
  std::filesystem::path site_file;
  int64_t frames = 0;
  size_t cameras = 0;
  double seconds = 0;
  double render_seconds = 0;        // ray casting of the moving objects (all cameras)
  double static_seconds = 0;        // casting the static scenes
  double ground_truth_seconds = 0;  // footprints and hulls
  double write_seconds = 0;         // encoding and writing files
  std::vector<std::string> outputs; // files and folders written, relative to out_dir
};

Result<DatasetSummary> WriteDataset(const Scene& scene, const DatasetOptions& options, Context& ctx,
                                    const DatasetProgressCallback& progress = {});

}  // namespace occmap::sim
