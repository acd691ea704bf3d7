#include "occmap/sim/dataset_writer.h"

#include <algorithm>

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>

#include "occmap/calib/opencv_storage.h"
#include "occmap/calib/tsai_yaml.h"
#include "occmap/io/video_writer.h"
#include "occmap/sim/gt_rasters.h"
#include "occmap/sim/renderer.h"
#include "occmap/sim/scene_yaml.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"

namespace occmap::sim {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string FrameName(int64_t frame) { return fmt::format("{:06d}.png", frame); }

// Image sequences: PNG, or JPEG at the scene camera's quality.
bool JpegFrames(const Scene& scene, const DatasetOptions& options) {
  return options.frame_format == DatasetOptions::FrameFormat::kPng && scene.spec().photometry.camera.jpeg_quality > 0;
}
const char* FrameExtension(const Scene& scene, const DatasetOptions& options) {
  return JpegFrames(scene, options) ? "jpg" : "png";
}

// Willson's angles of R = Rot_z(rz) Rot_y(ry) Rot_x(rx).
void TsaiAngles(const Eigen::Matrix3d& r, double* rx, double* ry, double* rz) {
  *ry = std::asin(std::clamp(-r(2, 0), -1.0, 1.0));
  *rx = std::atan2(r(2, 1), r(2, 2));
  *rz = std::atan2(r(1, 0), r(0, 0));
}

// The site file's calibration entry of a camera, after writing its files.
Result<std::string> WriteCalibration(const CameraSpec& c, const fs::path& out_dir) {
  if (c.model == CameraSpec::Model::kPinhole) {
    const std::string intr = fmt::format("calib/intr_{}.xml", c.id), extr = fmt::format("calib/extr_{}.xml", c.id);
    OCCMAP_RETURN_IF_ERROR(WriteOpenCvCalibration(c.pinhole, 1.0, out_dir / intr, out_dir / extr));
    return fmt::format("{{format: opencv, intrinsic: {}, extrinsic: {}, unit: m}}", intr, extr);
  }
  double rx = 0, ry = 0, rz = 0;
  TsaiAngles(c.tsai.cam_from_world_rotation, &rx, &ry, &rz);
  const std::string file = fmt::format("calib/tsai_{}.yaml", c.id);
  OCCMAP_RETURN_IF_ERROR(WriteTsaiYaml(c.tsai, rx, ry, rz, "", out_dir / file, 0.001));
  return fmt::format("{{format: tsai-yaml, file: {}, unit: mm}}", file);
}

nlohmann::json SceneJson(const Scene& scene, const DatasetOptions& options) {
  using nlohmann::json;
  const SceneSpec& spec = scene.spec();
  json cameras = json::array();
  for (size_t c = 0; c < scene.num_cameras(); ++c) {
    const Eigen::Vector3d centre = *scene.camera(c).CenterInWorld();
    const ImageSize size = scene.camera(c).image_size();
    cameras.push_back({{"id", scene.camera_id(c)},
                       {"model", std::string(scene.camera(c).kind())},
                       {"image_size", {size.width, size.height}},
                       {"centre_m", {centre.x(), centre.y(), centre.z()}}});
  }
  json objects = json::array();
  for (const MovingObjectSpec& o : spec.objects) {
    objects.push_back({{"id", o.id},
                       {"class", ToString(o.object_class)},
                       {"height_m", o.appearance.height_m},
                       {"first_s", o.path.front().t_s},
                       {"last_s", o.path.back().t_s},
                       {"waypoints", o.path.size()}});
  }
  json statics = json::array();
  for (const StaticObjectSpec& s : spec.statics) statics.push_back(s.name);
  const PhotometrySpec& ph = spec.photometry;
  json out = json{
      {"name", spec.name},
      {"description", spec.description},
      {"seed", spec.seed},
      {"fps", spec.fps},
      {"frames", spec.num_frames},
      {"grid",
       {{"origin_m", {spec.grid.origin_x_m, spec.grid.origin_y_m}},
        {"cells", {spec.grid.cells_x, spec.grid.cells_y}},
        {"cell_size_m", spec.grid.cell_size_m}}},
      {"outdoor", spec.room.outdoor},
      {"cameras", cameras},
      {"static_objects", statics},
      {"objects", objects},
      {"photometry",
       {{"ambient", ph.lighting.ambient},
        {"ambient_colour", {ph.lighting.ambient_colour[0], ph.lighting.ambient_colour[1], ph.lighting.ambient_colour[2]}},
        {"direct_colour", {ph.lighting.direct_colour[0], ph.lighting.direct_colour[1], ph.lighting.direct_colour[2]}},
        {"light", ph.lighting.kind == Lighting::Kind::kPoint ? "point" : "directional"},
        {"intensity", ph.lighting.intensity},
        {"noise_sigma", ph.noise_sigma},
        {"exposure_drift", ph.exposure_drift},
        {"exposure_period_s", ph.exposure_period_s},
        {"shadows", ph.shadows},
        {"background_noise", ph.background_noise}}},
      {"frames_format", options.frame_format == DatasetOptions::FrameFormat::kPng ? "png" : "video"},
      {"site_backgrounds", options.site_backgrounds},
      {"conventions",
       {{"frame", "dataset frame index from 0; time_s = frame / fps"},
        {"gt/footprint", "one pixel per cell, +x right, +y up (row 0 = cell row cells_y - 1); 255 = an object touches "
                         "the floor (cell centre inside a footprint polygon), 0 = not"},
        {"gt/hull", "ideal plane hull with perfect change detection; 255 free, 0 occupied, 128 unseen; same layout"},
        {"gt/changes", "per camera, 255 where the pixel sees a moving object, 0 elsewhere"},
        {"gt/shadows", "per camera (with shadows), 255 where a moving object's cast shadow darkens a static floor "
                       "pixel that no moving object covers, 0 elsewhere"},
        {"ground_truth", "the objects whose position is inside the grid"},
        {"masks", "255 = the pixel sees the monitored floor, 0 = walls, furniture, static occluders, nothing"},
        {"ids", "object ids of ground_truth.jsonl are the renderer's id-buffer values"}}},
  };
  // Only when on: the files of scenes without them stay as they were.
  if (ph.contact_shadows.enabled()) {
    out["photometry"]["contact_shadows"] = {{"strength", ph.contact_shadows.strength},
                                            {"radius_m", ph.contact_shadows.radius_m},
                                            {"reach_m", ph.contact_shadows.reach_m}};
  }
  if (ph.camera != CameraResponseSpec{}) {
    const CameraResponseSpec& c = ph.camera;
    out["photometry"]["camera"] = {{"auto_exposure", c.auto_exposure}, {"target_luma", c.target_luma},
                                   {"max_gain", c.max_gain},           {"white_balance", c.white_balance},
                                   {"time_constant_s", c.time_constant_s}, {"read_noise", c.read_noise},
                                   {"shot_noise", c.shot_noise},       {"supersample", c.supersample},
                                   {"jpeg_quality", c.jpeg_quality},   {"video_crf", c.video_crf}};
    if (JpegFrames(scene, options)) out["frames_format"] = "jpeg";
  }
  return out;
}

bool ShadowMasks(const Scene& scene, const DatasetOptions& options) {
  const PhotometrySpec& ph = scene.spec().photometry;
  return options.change_masks && (ph.shadows || ph.contact_shadows.enabled());
}

bool InsideGrid(const FloorGrid& g, double x, double y) {
  return x >= g.origin_x_m && y >= g.origin_y_m && x < g.origin_x_m + g.size_x_m() && y < g.origin_y_m + g.size_y_m();
}

std::string ReadmeText(const Scene& scene, const DatasetOptions& options) {
  const SceneSpec& spec = scene.spec();
  std::string cams;
  for (size_t c = 0; c < scene.num_cameras(); ++c) {
    const ImageSize s = scene.camera(c).image_size();
    cams += fmt::format("{}{} ({} {}x{})", c ? ", " : "", scene.camera_id(c), scene.camera(c).kind(), s.width, s.height);
  }
  return fmt::format(
      "Simulated dataset '{}' written by occmap's scene simulator (seed {}).\n\n{}\n\n"
      "{} frames at {} fps; grid {} x {} cells of {} m from ({}, {}) m; cameras: {}; {} moving objects.\n\n"
      "Run it:  occmap run site.yaml\n{}\n"
      "Files:\n"
      "  site.yaml                 the site (calibrations, masks, frames, backgrounds; relative paths)\n"
      "  calib/                    calibrations (OpenCV XML in metres, or Tsai YAML in mm)\n"
      "  frames/                   {}\n"
      "  backgrounds/<cam>.png     the empty scene\n"
      "  masks/<cam>.png           255 = monitored floor, 0 = walls, furniture, occluders\n"
      "  ground_truth.jsonl        per frame: the objects inside the grid (id, class, x_m, y_m, footprint_m polygon)\n"
      "  gt/footprint/%06d.png     255 = an object touches the floor in the cell\n"
      "  gt/hull/%06d.png          ideal plane hull: 255 free, 0 occupied, 128 unseen\n"
      "  gt/changes/<cam>/%06d.png 255 = the pixel sees a moving object\n"
      "{}"
      "  scene.yaml                the scene itself: `occmap synth scene.yaml` renders this again\n"
      "  scene.json                the same facts for programs\n\n"
      "Rasters have one pixel per floor cell, +x to the right and +y up (image row 0 is the last cell row).\n"
      "Frame numbers count from 0; time_s = frame / fps.\n",
      spec.name, spec.seed, spec.description, spec.num_frames, spec.fps, spec.grid.cells_x, spec.grid.cells_y,
      spec.grid.cell_size_m, spec.grid.origin_x_m, spec.grid.origin_y_m, cams, spec.objects.size(),
      options.site_backgrounds ? ""
                               : "site.yaml gives no backgrounds: the run learns them from the frames (the empty "
                                 "scene is in backgrounds/, for comparison).\n",
      options.frame_format != DatasetOptions::FrameFormat::kPng ? "<cam>.mp4 videos (H.264 when available)"
      : JpegFrames(scene, options) ? "<cam>/%06d.jpg RGB frames (JPEG)"
                                   : "<cam>/%06d.png RGB frames",
      !ShadowMasks(scene, options) ? ""
      : spec.photometry.contact_shadows.enabled()
          ? "  gt/shadows/<cam>/%06d.png 255 = a moving object's cast or contact shadow darkens the static floor "
            "(no object seen there)\n"
          : "  gt/shadows/<cam>/%06d.png 255 = a moving object's cast shadow darkens the static "
            "floor (no object seen there)\n");
}

}  // namespace

Status DatasetOptions::Validate() const {
  if (out_dir.empty()) return InvalidInput("output folder: expected a path, found an empty one");
  if (detection_threshold < 0 || detection_threshold > 254) {
    return InvalidInput(fmt::format("detection threshold: expected 0..254, found {}", detection_threshold));
  }
  if (!site_detection_yaml.empty() && !site_detection_yaml.starts_with("detection:")) {
    return InvalidInput(fmt::format("site detection YAML: expected a section starting with 'detection:', found '{}'",
                                    site_detection_yaml.substr(0, 40)));
  }
  return Status::Ok();
}

Result<DatasetSummary> WriteDataset(const Scene& scene, const DatasetOptions& options, Context& ctx,
                                    const DatasetProgressCallback& progress) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  const auto t_start = Clock::now();
  const fs::path& out = options.out_dir;
  DatasetSummary summary;
  summary.frames = scene.num_frames();
  summary.cameras = scene.num_cameras();
  const int64_t n = scene.num_frames();
  const int64_t total = n * static_cast<int64_t>(scene.num_cameras()) + n;
  int64_t done = 0;
  auto report = [&](const std::string& stage) {
    if (progress) progress({stage, done, total});
  };
  for (const char* dir : {"calib", "frames", "backgrounds", "masks"}) OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / dir));
  const bool shadow_masks = ShadowMasks(scene, options);
  if (options.gt_rasters) {
    OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / "gt" / "footprint"));
    OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out / "gt" / "hull"));
  }
  const bool video = options.frame_format == DatasetOptions::FrameFormat::kVideo;
  const bool jpeg = JpegFrames(scene, options);
  const int jpeg_quality = scene.spec().photometry.camera.jpeg_quality;
  const int batch = std::max(2, 2 * ctx.num_threads());
  std::vector<Image<uint8_t>> masks;
  std::string site_cameras;
  for (size_t c = 0; c < scene.num_cameras(); ++c) {
    const std::string& id = scene.camera_id(c);
    const std::string stage = fmt::format("camera {}", id);
    report(stage);
    auto t0 = Clock::now();
    CameraRenderer renderer(scene, c, ctx);
    summary.static_seconds += Since(t0);
    t0 = Clock::now();
    OCCMAP_ASSIGN_OR_RETURN(std::string calib_entry, WriteCalibration(scene.spec().cameras[c], out));
    OCCMAP_RETURN_IF_ERROR(WritePng(out / "masks" / (id + ".png"), renderer.floor_mask().view()));
    OCCMAP_RETURN_IF_ERROR(WritePng(out / "backgrounds" / (id + ".png"), renderer.Background().view()));
    const fs::path changes_dir = out / "gt" / "changes" / id;
    if (options.change_masks) OCCMAP_RETURN_IF_ERROR(EnsureDirectory(changes_dir));
    const fs::path shadows_dir = out / "gt" / "shadows" / id;
    if (shadow_masks) OCCMAP_RETURN_IF_ERROR(EnsureDirectory(shadows_dir));
    const fs::path frames_dir = out / "frames" / id;
    std::unique_ptr<VideoWriter> writer;
    if (video) {
      VideoWriterOptions video_options;
      video_options.crf = scene.spec().photometry.camera.video_crf;
      OCCMAP_ASSIGN_OR_RETURN(writer, VideoWriter::Open(out / "frames" / (id + ".mp4"), renderer.size(),
                                                        scene.spec().fps, video_options));
    } else {
      OCCMAP_RETURN_IF_ERROR(EnsureDirectory(frames_dir));
    }
    summary.write_seconds += Since(t0);
    std::vector<RenderedView> views(static_cast<size_t>(batch));
    // A real camera's exposure and white balance follow the frames in order.
    CameraResponse response = renderer.NewResponse();
    std::vector<Status> statuses(static_cast<size_t>(batch));
    for (int64_t f0 = 0; f0 < n; f0 += batch) {
      const int count = static_cast<int>(std::min<int64_t>(batch, n - f0));
      t0 = Clock::now();
      for (int b = 0; b < count; ++b) {
        renderer.Render(scene.StateAt(f0 + b), ctx, &views[static_cast<size_t>(b)], /*noise=*/true, shadow_masks,
                        &response);
      }
      summary.render_seconds += Since(t0);
      t0 = Clock::now();
      if (writer) {
        for (int b = 0; b < count; ++b) OCCMAP_RETURN_IF_ERROR(writer->Write(views[static_cast<size_t>(b)].rgb.view()));
      }
      ParallelFor(ctx, 0, count, [&](int64_t b0, int64_t b1, int) {
        for (int64_t b = b0; b < b1; ++b) {
          const RenderedView& v = views[static_cast<size_t>(b)];
          Status s;
          if (!video && jpeg) {
            s = WriteJpeg(frames_dir / fmt::format("{:06d}.jpg", f0 + b), v.rgb.view(), jpeg_quality);
          } else if (!video) {
            s = WritePng(frames_dir / FrameName(f0 + b), v.rgb.view());
          }
          if (s.ok() && options.change_masks) s = WritePng(changes_dir / FrameName(f0 + b), ChangeMask(v.ids).view());
          if (s.ok() && shadow_masks) s = WritePng(shadows_dir / FrameName(f0 + b), v.shadow.view());
          statuses[static_cast<size_t>(b)] = s;
        }
      });
      for (int b = 0; b < count; ++b) OCCMAP_RETURN_IF_ERROR(statuses[static_cast<size_t>(b)]);
      summary.write_seconds += Since(t0);
      done += count;
      report(stage);
    }
    if (writer) OCCMAP_RETURN_IF_ERROR(writer->Close());
    masks.push_back(renderer.floor_mask());
    site_cameras += fmt::format(
        "  - id: {}\n    calibration: {}\n    mask: masks/{}.png\n    source: {{{}}}\n{}", id, calib_entry, id,
        video ? fmt::format("video: frames/{}.mp4", id)
              : fmt::format("images: frames/{}/%06d.{}", id, FrameExtension(scene, options)),
        options.site_backgrounds ? fmt::format("    background: backgrounds/{}.png\n", id) : "");
  }

  // Ground truth.
  auto t0 = Clock::now();
  const HullComputer hull(scene, masks, ctx);
  std::vector<GroundTruthFrame> gt;
  gt.reserve(static_cast<size_t>(n));
  for (int64_t f = 0; f < n; ++f) {
    const SceneState state = scene.StateAt(f);
    gt.push_back(ToGroundTruth(state));
    // Objects outside the monitored area (walking in from the street) are no one's to find.
    std::erase_if(gt.back().objects,
                  [&](const GroundTruthObject& o) { return !InsideGrid(scene.grid(), o.x_m, o.y_m); });
    if (options.gt_rasters) {
      const std::vector<uint8_t> feet = FootprintRaster(scene.grid(), state);
      const OccupancyMap ideal = hull.Compute(state, ctx);
      OCCMAP_RETURN_IF_ERROR(WritePng(out / "gt" / "footprint" / FrameName(f), RasterImage(scene.grid(), feet).view()));
      OCCMAP_RETURN_IF_ERROR(WritePng(out / "gt" / "hull" / FrameName(f), ideal.ToGrayImage().view()));
    }
    ++done;
    if (f % 10 == 9 || f + 1 == n) report("ground truth");
  }
  OCCMAP_RETURN_IF_ERROR(WriteGroundTruth(out / "ground_truth.jsonl", gt));
  summary.ground_truth_seconds = Since(t0);

  t0 = Clock::now();
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(out / "scene.yaml", SceneToYaml(scene.spec())));
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(out / "scene.json", SceneJson(scene, options).dump(2) + "\n"));
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(out / "README.txt", ReadmeText(scene, options)));
  const FloorGrid& g = scene.grid();
  std::string detection = options.site_detection_yaml;
  if (detection.empty()) {
    detection = fmt::format(
        "# A pixel sees 2-5 cm of floor, more than a chair's leg: changes are widened by one pixel\n"
        "# so that thin parts survive the AND (equation 5) on a fine grid.\n"
        "detection:\n  threshold: {}\n  tolerance_px: 1\n",
        options.detection_threshold);
  } else if (!detection.ends_with('\n')) {
    detection += '\n';
  }
  // A scene of people only (no chairs, robots or boxes) is detected by the people's model, with
  // the scene's static structures as occluders (fusion/people_options.h, lut/column_lut.h).
  std::string people_yaml;
  const bool people_only = !scene.spec().objects.empty() &&
                           std::all_of(scene.spec().objects.begin(), scene.spec().objects.end(),
                                       [](const MovingObjectSpec& o) { return o.object_class == ObjectClass::kPerson; });
  if (people_only) {
    people_yaml =
        "# Only people move here: they are found by the set of upright people that best explains\n"
        "# every camera's changes, the static structures hiding them from some cameras.\n"
        "people:\n  detector: explain\n";
    std::string statics;
    for (const StaticObjectSpec& o : scene.spec().statics) {
      const std::string name = o.name.empty() ? "" : fmt::format("name: \"{}\", ", o.name);
      if (o.shape == StaticObjectSpec::Shape::kBox) {
        statics += fmt::format("  - {{{}shape: box, centre_m: [{}, {}], size_m: [{}, {}], base_m: {}, height_m: {}, yaw_deg: {}}}\n",
                               name, o.centre_m.x(), o.centre_m.y(), o.size_m.x(), o.size_m.y(), o.base_m, o.height_m,
                               o.yaw_deg);
      } else {
        statics += fmt::format("  - {{{}shape: cylinder, centre_m: [{}, {}], diameter_m: {}, height_m: {}}}\n", name,
                               o.centre_m.x(), o.centre_m.y(), o.size_m.x(), o.height_m);
      }
    }
    if (!statics.empty()) people_yaml += "statics:\n" + statics;
  }
  const std::string site = fmt::format(
      "# Written by occmap's scene simulator: scene '{}' (see README.txt and scene.json).\n"
      "version: 1\nname: \"{}\"\nfloor:\n  origin_m: [{}, {}]\n  cells: [{}, {}]\n  cell_size_m: {}\ncameras:\n{}{}"
      "# A rendered person touches the floor with two feet and a chair with four legs: fragments\n"
      "# closer than 0.4 m form one detection, and specks under 150 cm^2 are dropped. A detection\n"
      "# must also stand up: on one of the planes support_heights_m, at least min_support of its\n"
      "# footprint must be occupied too (ghosts behind people are flat).\n"
      "blobs:\n  group_radius_m: 0.2\n  min_area_m2: 0.015\n  support_heights_m: [0.35, 0.7, 1.0, 1.3]\n"
      "  min_support: 0.3\n{}",
      scene.spec().name, scene.spec().name, g.origin_x_m, g.origin_y_m, g.cells_x, g.cells_y, g.cell_size_m,
      site_cameras, detection, people_yaml);
  summary.site_file = out / "site.yaml";
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(summary.site_file, site));
  summary.write_seconds += Since(t0);
  summary.outputs = {"site.yaml", "calib/", "frames/", "backgrounds/", "masks/", "ground_truth.jsonl", "scene.yaml",
                     "scene.json", "README.txt"};
  if (options.gt_rasters) {
    summary.outputs.push_back("gt/footprint/");
    summary.outputs.push_back("gt/hull/");
  }
  if (options.change_masks) summary.outputs.push_back("gt/changes/");
  if (shadow_masks) summary.outputs.push_back("gt/shadows/");
  summary.seconds = Since(t_start);
  report("done");
  return summary;
}

}  // namespace occmap::sim
