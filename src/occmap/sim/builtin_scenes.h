// The simulator's built-in scenes, as SceneSpecs (write one out with SceneToYaml to start a
// custom scene).
//
//   lab        the paper's UCSD lab: a carpeted 9 x 6.5 m room lined with bookshelves, a desk,
//              a potted plant inside the area; the four 640x480 cameras of `occmap demo`
//              (site/demo_scene.h: 2.7 m, mild barrel distortion) looking across; three people
//              walking (one pushing a chair), a round robot; 10 fps, 10 s.
//   clemson    the Clemson lab: 5 x 4 m, half carpet, half tiles, six Tsai cameras (Sony
//              XC-75-like, 3.5 mm lens) on a 2.6 m drop ceiling near the corners and the
//              centres of the two long walls; two people, a robot, a box pushed around.
//   wildtrack  WILDTRACK's seven real calibrations and annotated trajectories (people
//              interpolated linearly between the annotations, 0.5 s apart, absent where not
//              annotated) on a paved square, 10 fps; object id = personID + 1.
//   plaza      a sunny paved square outdoors, 20 x 14 m monitored (cells of 5 cm): six
//              1280x720 pinhole cameras on poles at 2.6-3.5 m around it looking across (mild
//              barrel distortion), pillars, planters, a kiosk and benches inside; a low sun
//              (25 degrees by default) casting long dark shadows, bluish sky light in them,
//              exposure drift (or an overcast sky: soft contact shadows only);
//              `people` people at a time (default 16), drawn from the seed:
//              some cross the square (entering and leaving beyond its edges), some meet in
//              groups of 2-3 and talk for 10-40 s, some stand alone for 20-50 s, then leave;
//              one object id per visit. Default 60 s at 10 fps (plaza_scene.cc).
//
//   sim::BuiltinSceneOptions opt;  opt.seed = 7;
//   OCCMAP_ASSIGN_OR_RETURN(sim::SceneSpec spec, sim::MakeBuiltinSceneSpec("lab", opt));
//   OCCMAP_ASSIGN_OR_RETURN(sim::Scene scene, sim::Scene::Create(std::move(spec)));
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/sim/scene.h"
#include "occmap/util/status.h"

namespace occmap::sim {

struct BuiltinSceneOptions {
  uint64_t seed = 1;
  // Image size as a fraction of the cameras' native size (intrinsics scaled by
  // CameraModel::Resized's rule): 1 = native, 0.5 = half.
  double image_scale = 1.0;
  int64_t num_frames = -1;      // -1: the scene's default length
  double noise_sigma = -1;      // -1: the scene's default (2 grey levels)
  bool shadows = false;          // true: cast shadows on (a scene may have them on already: plaza)
  double exposure_drift = -1;    // relative amplitude 0..0.5 (0 = off); -1: the scene's (plaza 0.1, else 0)
  // A real camera and contact shadows (RealCameraPreset): nullopt keeps the scene's, true
  // turns the preset on, false the ideal camera with no contact shadows.
  std::optional<bool> real_camera;
  // Single knobs, applied after real_camera (nullopt: as the scene or the preset has them;
  // ranges as scene.h's CameraResponseSpec and ContactShadowSpec).
  std::optional<bool> auto_exposure;
  std::optional<double> white_balance;    // grey-world strength 0..1
  std::optional<double> read_noise;       // grey levels
  std::optional<double> shot_noise;       // variance per grey level
  std::optional<int> supersample;         // 1..4
  std::optional<int> jpeg_quality;        // 0 (PNG) .. 100
  std::optional<int> video_crf;           // -1 .. 51
  std::optional<double> contact_shadows;  // strength 0..1 (0 = off)
  // Plaza only (-1: its default; the other scenes reject any other value):
  int people = -1;                // people in the area at a time, 1..40 (default 16)
  double duration_s = -1;         // length of the scene, 1..3600 s (default 60; sets the frames)
  double sun_elevation_deg = -1;  // the sun above the horizon, 5..90 degrees (default 25)
  // An overcast sky instead of the sun: no direct light, no cast shadows, the paving as bright
  // (ambient 0.85, faintly blue), contact shadows on (RealCameraPreset's, unless set).
  bool overcast = false;
  Status Validate() const;
};

// The real camera of `occmap synth --real-camera` (values near the EPFL terrace's cameras):
// automatic exposure to the empty view's luma (gain 1/4..4), grey-world white balance of
// strength 0.6, both with a time constant of 0.4 s; read noise 1.2 and shot noise 0.04 grey
// levels (about 2.4 at mid grey; the renderer's Gaussian noise_sigma set to 0); rendered at
// twice the size and area-averaged; JPEG quality 75 (H.264 crf 28 for videos); contact shadows
// of strength 0.5 (radius 0.22 m, reach 1.5 m).
void ApplyRealCameraPreset(PhotometrySpec& photometry);

struct WildtrackSceneOptions {
  // The dataset folder (holding calibrations/ and annotations_positions/).
  std::filesystem::path dataset_dir = "../shared/datasets/wildtrack";
  bool original_intrinsics = false;  // intrinsic_original (distorted) rather than intrinsic_zero
  int64_t first_frame = 0;           // 10 fps frame number of the dataset (annotations every 5)
  Status Validate() const;
};

// "lab", "clemson", "wildtrack", "plaza" (wildtrack needs files: MakeWildtrackSceneSpec).
std::vector<std::string> BuiltinSceneNames();
Result<SceneSpec> MakeBuiltinSceneSpec(std::string_view name, const BuiltinSceneOptions& options);

// These three CHECK that `options` is valid for them (MakeBuiltinSceneSpec returns the error).
SceneSpec MakeLabSceneSpec(const BuiltinSceneOptions& options);
SceneSpec MakeClemsonSceneSpec(const BuiltinSceneOptions& options);
SceneSpec MakePlazaSceneSpec(const BuiltinSceneOptions& options);
// num_frames -1 means up to the last annotated frame (1995 for the full dataset).
Result<SceneSpec> MakeWildtrackSceneSpec(const BuiltinSceneOptions& options, const WildtrackSceneOptions& wildtrack);

// WILDTRACK annotations: person positions per annotated frame.
struct WildtrackAnnotation {
  int64_t frame = 0;  // 10 fps frame number (the file name)
  struct Person {
    int64_t person_id = 0;
    int64_t position_id = 0;
    Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  };
  std::vector<Person> people;
};
// Reads annotations_positions/*.json in frame order.
Result<std::vector<WildtrackAnnotation>> ReadWildtrackAnnotations(const std::filesystem::path& folder);
// X = -300 + 2.5 (id % 480), Y = -900 + 2.5 (id / 480) centimetres, in metres.
Eigen::Vector2d WildtrackPositionM(int64_t position_id);

// Applies options common to all scenes (scale, frames, the real camera and its knobs, noise,
// shadows, drift) to a spec; the plaza's own options (people, duration, sun, overcast) must be
// unset (an error naming the option if not).
// Shadows given by the spec stay on; exposure drift -1 keeps the spec's.
Status ApplyBuiltinOptions(const BuiltinSceneOptions& options, SceneSpec& spec);

}  // namespace occmap::sim
