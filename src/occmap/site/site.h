// Site: the one file a user writes (YAML), loaded and validated into cameras, masks and grid.
//
// The full schema is in docs/formats.md. In short:
//   version: 1
//   name: wildtrack
//   data_root: ../../shared/datasets   # relative paths below resolve against it (default: this
//                                      # file's folder); `--data-root` overrides it
//   floor: {origin_m: [-3, -9], cells: [480, 1440], cell_size_m: 0.025}   # or size_m: [12, 36]
//   cameras:
//     - id: C1
//       calibration: {format: opencv, intrinsic: ..., extrinsic: ..., unit: cm, image_size: [1920, 1080]}
//       image_size: [480, 270]          # run-time frames/masks; intrinsics are scaled
//       mask: {polygon: [[0, 500], [1919, 500], [1919, 1079], [0, 1079]]}   # or mask.png
//       source: {video: c1.mp4}
//       background: c1_bg.png
//   detection: {threshold: 30, tolerance_px: 0}
//   backgrounds: {adaptive: true, learning: mode, learn_s: 60, shadows: {enabled: true}}
//   fusion: {algorithm: image-based, max_free_views: 0}
//   blobs: {group_radius_m: 0.2, min_area_m2: 0.003, split: true, remove_ghosts: true}
//   lut: {add_cell_projections: true}
//   tracking: {algorithm: multi_target, max_speed_mps: 2.5, zones: [...], lines: [...]}   # track/tracker_options.h
//   outputs: {mqtt: {url: mqtt://HOST:PORT, topic_prefix: occmap/lab}}   # publish/mqtt_options.h
//   (blobs: and tracking:'s person size and split keys: objects/object_options.h)
//
// Every error names the file, line and field, what was expected and what was found:
//   site.yaml:14: cameras[2].calibration.intrinsic: file not found: '/data/intr_C3.xml'
//
//   OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite("sites/wildtrack.yaml", {}));
//   std::vector<LutCameraInput> inputs = site.LutInputs();
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "occmap/detect/background_model.h"
#include "occmap/detect/change_detection.h"
#include "occmap/fusion/fusion.h"
#include "occmap/fusion/people_options.h"
#include "occmap/geometry/camera_model.h"
#include "occmap/io/frame_source.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/objects/object_options.h"
#include "occmap/publish/mqtt_options.h"
#include "occmap/track/tracker_options.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

struct SiteCamera {
  std::string id;
  std::unique_ptr<CameraModel> camera;  // at the run-time image size
  ImageSize calibrated_size;
  std::string calibration_format;       // opencv, gopro-json, tsai-yaml, homography
  std::vector<std::filesystem::path> calibration_files;
  Image<uint8_t> mask;                  // empty: every pixel is floor; non-zero = floor
  FrameSourceSpec source;
  std::optional<std::filesystem::path> background;
};

// The `outputs:` section: where a run publishes besides its output folder.
struct SiteOutputs {
  std::optional<MqttOptions> mqtt;  // `outputs.mqtt` (publish/mqtt_options.h)
};

struct Site {
  std::filesystem::path file;  // the site file ("" for scenes built in code)
  std::string name;
  FloorGrid grid;
  double plane_height_m = 0;
  std::vector<SiteCamera> cameras;
  LutOptions lut;
  ChangeDetectionOptions detection;
  BackgroundOptions backgrounds;  // the `backgrounds:` section: learning, maintenance, shadows
  FusionOptions fusion;
  // From the map to detections: the `blobs:` section and the person-size and split keys of
  // `tracking:` (objects/object_options.h, parsed there).
  ObjectOptions objects;
  // The rest of `tracking:`: trackers, zones, trails (track/tracker_options.h, parsed there).
  TrackerOptions tracking;
  PeopleOptions people;           // the `people:` section (fusion/people_options.h)
  std::vector<Occluder> statics;  // the `statics:` section: structures that hide people (lut/column_lut.h)
  SiteOutputs outputs;

  std::vector<LutCameraInput> LutInputs() const;
};

struct SiteLoadOptions {
  std::optional<std::filesystem::path> data_root;  // overrides the file's data_root
};

Result<Site> LoadSite(const std::filesystem::path& path, const SiteLoadOptions& options = {});
Result<Site> ParseSite(std::string_view yaml_text, const std::filesystem::path& path,
                       const SiteLoadOptions& options = {});

// Rasterises polygons (pixel coordinates, centre of pixel (c, r) at (c, r)) into a mask:
// 255 inside any polygon, 0 elsewhere.
Image<uint8_t> RasterizePolygons(const std::vector<std::vector<Eigen::Vector2d>>& polygons, ImageSize size);

const char* ToString(FusionMethod method);

}  // namespace occmap
