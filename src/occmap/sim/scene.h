// The simulator's scene: a monitored floor, calibrated cameras, a static set (textured floor,
// walls, furniture, occluders), moving objects on timed paths, and the photometry.
//
// SceneSpec is plain data (what a scene YAML file holds, scene_yaml.h); Scene is a validated
// spec with its camera models built, and answers "where is everything at frame f":
// StateAt(f) gives each present object's primitives (for the renderer), its floor footprint
// polygons and its ground-truth record. Everything random (clothing, textures, noise) comes
// from SceneSpec::seed through counter-based hashing: a scene renders identically for a seed,
// on any number of threads.
//
// Frames: scene frame f (0 .. num_frames - 1) is at time_s = f / fps. Objects move along
// piecewise-linear paths of timed waypoints (x, y in metres on the floor); an object is present
// from its first to its last waypoint, except across a waypoint marked `gap_before` (it leaves
// after the previous waypoint and comes back at this one). It faces along its motion.
//
// Object classes and what touches the floor (their footprint):
//   person  articulated: two legs (thigh, shin, foot) that alternate while walking, pelvis,
//           torso, two swinging arms, head with hair; its feet touch the floor (the swinging
//           foot is lifted); (x, y) is the centre between the feet.
//   chair   four legs, seat and backrest; its four leg squares touch the floor (a concave
//           footprint: the floor between the legs shows under the seat).
//   robot   a round mobile robot (a vertical cylinder with a top plate and a sensor); a disc.
//   box     an upright box; a rectangle.
// Footprint polygons are counter-clockwise and lie inside the primitives' contact with the
// floor, so every ray from above to a point inside one is blocked by the object.
//
//   OCCMAP_ASSIGN_OR_RETURN(sim::Scene scene, sim::Scene::Create(sim::MakeLabSceneSpec({})));
//   sim::SceneState state = scene.StateAt(12);
//   GroundTruthFrame gt = sim::ToGroundTruth(state);
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "occmap/geometry/pinhole_camera.h"
#include "occmap/geometry/rotation.h"
#include "occmap/geometry/tsai_camera.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/sim/ground_truth.h"
#include "occmap/sim/primitives.h"
#include "occmap/util/status.h"

namespace occmap::sim {

// A camera of the scene: an OpenCV pinhole (Brown-Conrady) or a Tsai camera.
struct CameraSpec {
  enum class Model { kPinhole, kTsai };
  std::string id;  // letters, digits, '_', '-', '.' (it names files)
  Model model = Model::kPinhole;
  PinholeParameters pinhole;  // kPinhole (forward_sign must be +1)
  TsaiParameters tsai;        // kTsai

  Result<std::unique_ptr<CameraModel>> Build() const;
  ImageSize image_size() const { return model == Model::kPinhole ? pinhole.image_size : tsai.image_size; }
};

// A pinhole camera looking at a point.
CameraSpec LookAtPinhole(std::string id, const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m,
                         ImageSize size, double focal_px, std::array<double, 5> distortion = {0, 0, 0, 0, 0});
// A Tsai camera looking at a point: sensor cells of dx_mm (square), Ncx = Nfx = width, sx = 1,
// principal point at the image centre.
CameraSpec LookAtTsai(std::string id, const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m,
                      ImageSize size, double f_mm, double cell_mm, double kappa1_per_mm2);

// A floor piece (z = 0 unless the scene says otherwise), seen from above.
struct FloorPatch {
  double x_min_m = 0, y_min_m = 0, x_max_m = 0, y_max_m = 0;
  Material material;
};

// Walls, ceiling and the floor around the monitored area; `outdoor` has no walls or ceiling
// and a sky.
struct RoomSpec {
  bool outdoor = false;
  double x_min_m = 0, y_min_m = 0, x_max_m = 0, y_max_m = 0;  // inner faces of the walls
  double height_m = 3.0;                                        // the ceiling
  Material wall;
  Material ceiling;
  Eigen::Vector3f sky_colour{0.62f, 0.72f, 0.85f};            // outdoor: what rays that hit nothing see
};

// A static thing: furniture around the area or an occluder inside it.
struct StaticObjectSpec {
  enum class Shape { kBox, kCylinder, kPlanter };
  std::string name;
  Shape shape = Shape::kBox;
  Eigen::Vector2d centre_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d size_m = Eigen::Vector2d(0.5, 0.5);  // box: x-y size before yaw; cylinder/planter: 2 r
  double height_m = 1.0;
  double base_m = 0.0;  // box: height of its bottom (a monitor on a desk); others stand on the floor
  double yaw_deg = 0;
  Material material;  // the planter's foliage is drawn from the seed
};

enum class ObjectClass { kPerson, kChair, kRobot, kBox };
const char* ToString(ObjectClass c);

struct Waypoint {
  double t_s = 0;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  bool gap_before = false;  // absent between the previous waypoint and this one
};

// Appearance of a moving object; colours are albedos 0..1.
struct Appearance {
  double height_m = 1.75;   // person: standing height; chair: backrest top; robot/box: height
  double width_m = 0.45;    // chair seat, robot diameter, box x size
  double depth_m = 0.45;    // chair seat, box y size
  Eigen::Vector3f top{0.6f, 0.2f, 0.2f};       // person shirt, chair seat, robot body, box
  Eigen::Vector3f bottom{0.2f, 0.2f, 0.3f};    // person trousers, chair legs and frame, robot bumper
  Eigen::Vector3f skin{0.8f, 0.6f, 0.5f};      // person skin
  Eigen::Vector3f hair{0.2f, 0.15f, 0.1f};     // person hair
  Eigen::Vector3f shoes{0.1f, 0.1f, 0.1f};     // person shoes
};

struct MovingObjectSpec {
  int64_t id = 1;  // 1 .. 65535, unique: the renderer's id buffer value
  ObjectClass object_class = ObjectClass::kPerson;
  Appearance appearance;
  std::vector<Waypoint> path;  // increasing times
};

// Soft contact shadows, as under an overcast sky: an object hides part of the sky from the floor
// around it. A floor point at a horizontal distance d from an object's axis loses the fraction
//   strength * S(d),  S(d) = [asin(r / d) / (pi / 2)] * [h^2 / (h^2 + d^2)] / [h^2 / (h^2 + r^2)]
// of its ambient (sky) light (S = 1 for d <= r): the cosine-weighted sky an upright cylinder of
// radius r and height h hides, scaled to 1 at its side; S is tapered to 0 between 0.7 and 1 times
// `reach_m` (no edge anywhere). Several objects combine as 1 - prod(1 - strength S). r is
// `radius_m` for a person, the bounding cylinder's radius for other objects; h their height.
// Only the ambient part darkens: the direct light is the cast shadows' (`shadows`).
struct ContactShadowSpec {
  double strength = 0;     // the fraction of sky light lost at an object's side, 0..1 (0 = off)
  double radius_m = 0.22;  // a person's body (r above)
  double reach_m = 1.5;    // no darkening beyond (from the object's axis)
  bool enabled() const { return strength > 0; }
};

// A real camera's response (sim/camera_response.h), off by default (the ideal camera: gain 1,
// or exposure_drift's, and Gaussian noise_sigma). Each is on when it differs from its default.
struct CameraResponseSpec {
  // Automatic exposure: a gain that brings the frame's mean luma (BT.601 weights, over the
  // pixels with a ray) to `target_luma` grey levels; 0 = the empty view's own mean luma (the
  // empty scene keeps its brightness; content moves the gain).
  bool auto_exposure = false;
  double target_luma = 0;      // 0, or 1..254
  double max_gain = 4;         // the exposure gain stays in [1 / max_gain, max_gain]
  // Automatic white balance, grey world: per channel the gain (Y / mean_c)^strength, then
  // scaled to keep the luma (0 = off, 1 = full grey world).
  double white_balance = 0;
  // Both follow the content with this time constant (frames rendered in order; the first frame
  // starts settled).
  double time_constant_s = 0.4;
  // Sensor noise per channel, after the gains: variance read_noise^2 + shot_noise * value
  // (grey levels), added to noise_sigma's.
  double read_noise = 0;       // grey levels
  double shot_noise = 0;       // grey levels of variance per grey level of signal
  // Rendered at supersample x the image size (s^2 rays a pixel), area-averaged (1 = off).
  int supersample = 1;
  // What the dataset writer stores: image sequences as JPEG of this quality (0 = PNG); videos
  // with H.264 at this constant rate factor (-1 = the video writer's default, 23).
  int jpeg_quality = 0;
  int video_crf = -1;

  // Whether a frame goes through CameraResponse (else the ideal camera's exact old path).
  bool processes_frames() const {
    return auto_exposure || white_balance > 0 || read_noise > 0 || shot_noise > 0 || supersample > 1;
  }
  bool operator==(const CameraResponseSpec&) const = default;
};

struct PhotometrySpec {
  Lighting lighting;
  double noise_sigma = 2.0;            // Gaussian sensor noise, grey levels (0 = none)
  double exposure_drift = 0.0;         // relative amplitude of a slow gain drift (0 = off)
  double exposure_period_s = 30.0;     // its period (each camera has its own phase)
  // Cast shadows: moving objects' on the floor (per frame), and static objects' on the floor
  // and on each other (cast once; the room's walls and ceiling cast none).
  bool shadows = false;
  bool background_noise = true;        // backgrounds get noise too (their own noise stream)
  ContactShadowSpec contact_shadows;   // off by default
  CameraResponseSpec camera;           // the ideal camera by default
};

struct SceneSpec {
  std::string name = "scene";
  uint64_t seed = 1;
  double fps = 10;
  int64_t num_frames = 100;
  FloorGrid grid;                       // the monitored area and the site's grid
  std::vector<FloorPatch> floor;        // floor pieces (z = 0); must cover the monitored area
  RoomSpec room;
  std::vector<CameraSpec> cameras;      // 1 .. 255
  std::vector<StaticObjectSpec> statics;
  std::vector<MovingObjectSpec> objects;
  PhotometrySpec photometry;
  // Free text for the dataset README (where the scene comes from).
  std::string description;

  Status Validate() const;
};

// An object as it is at one instant.
struct ObjectInstance {
  int64_t id = 0;
  ObjectClass object_class = ObjectClass::kPerson;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  double heading_rad = 0;
  std::vector<Primitive> parts;      // surface kDynamic
  CylinderBound bound;               // contains every part
  Eigen::Vector3d sphere_centre_m = Eigen::Vector3d::Zero();  // bounding sphere of the parts
  double sphere_radius_m = 0;
  std::vector<std::vector<Eigen::Vector2d>> footprint_m;  // polygons, counter-clockwise
};

struct SceneState {
  int64_t frame = 0;
  double time_s = 0;
  std::vector<ObjectInstance> objects;  // present objects, in spec order
};

// The primitives of a static object or of the room (floor pieces with surface kFloor).
std::vector<Primitive> StaticPrimitives(const SceneSpec& spec);
// The primitives of the static objects alone (no floor, walls or ceiling): what casts static
// shadows (a room's walls and ceiling would shade the whole floor from a directional light,
// which indoors stands for light through windows and lamps).
std::vector<Primitive> StaticObjectPrimitives(const SceneSpec& spec);

// Pose on a path at a time: position, heading, speed, walked distance, presence.
struct PathSample {
  bool present = false;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  double heading_rad = 0;
  double speed_m_s = 0;
  double distance_m = 0;  // along the path since its first waypoint (drives the gait)
};

// A path with its segment headings and walked distances computed once.
struct PreparedPath {
  explicit PreparedPath(std::vector<Waypoint> waypoints);
  PathSample Sample(double time_s) const;
  std::vector<Waypoint> path;
  std::vector<double> headings;      // per segment
  std::vector<double> cumulative_m;  // per waypoint
};
PathSample SamplePath(const std::vector<Waypoint>& path, double time_s);

class Scene {
 public:
  static Result<Scene> Create(SceneSpec spec);

  const SceneSpec& spec() const { return *spec_; }
  const FloorGrid& grid() const { return spec_->grid; }
  size_t num_cameras() const { return cameras_.size(); }
  const CameraModel& camera(size_t i) const { return *cameras_[i]; }
  const std::string& camera_id(size_t i) const { return spec_->cameras[i].id; }
  const std::vector<Primitive>& static_primitives() const { return statics_; }
  const std::vector<Primitive>& shadow_casters() const { return shadow_casters_; }  // StaticObjectPrimitives
  int64_t num_frames() const { return spec_->num_frames; }
  double TimeOf(int64_t frame) const { return static_cast<double>(frame) / spec_->fps; }

  SceneState StateAt(int64_t frame) const;
  // The instance of one object at a time, or nullopt when it is absent then.
  std::optional<ObjectInstance> InstanceAt(size_t object_index, double time_s) const;

 private:
  Scene() = default;
  std::shared_ptr<const SceneSpec> spec_;
  std::vector<std::shared_ptr<const CameraModel>> cameras_;
  std::vector<Primitive> statics_;
  std::vector<Primitive> shadow_casters_;
  std::vector<PreparedPath> paths_;
};

// The parts and footprint of an object at a pose (exposed for tests).
ObjectInstance MakeInstance(const MovingObjectSpec& object, const PathSample& pose);

GroundTruthFrame ToGroundTruth(const SceneState& state);

// Random appearance for an object of a class, drawn from (seed, salt); with probability
// `floor_like_probability` the person's trousers (or a chair's seat, a box) get a colour close
// to `floor_colour`.
Appearance RandomAppearance(ObjectClass c, uint64_t seed, uint64_t salt, const Eigen::Vector3f& floor_colour,
                            double floor_like_probability = 0.25);

}  // namespace occmap::sim
