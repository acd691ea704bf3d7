#include "occmap/sim/builtin_scenes.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "occmap/calib/opencv_storage.h"
#include "occmap/site/demo_scene.h"
#include "occmap/util/file_util.h"
#include "occmap/util/text_guard.h"
#include "occmap/util/safe_files.h"

namespace occmap::sim {
namespace fs = std::filesystem;
namespace {

const Eigen::Vector3f kGrey(0.3f, 0.3f, 0.3f);

StaticObjectSpec Box(std::string name, double cx, double cy, double sx, double sy, double h, Material m,
                     double base = 0) {
  StaticObjectSpec s;
  s.name = std::move(name);
  s.shape = StaticObjectSpec::Shape::kBox;
  s.centre_m = {cx, cy};
  s.size_m = {sx, sy};
  s.height_m = h;
  s.base_m = base;
  s.material = m;
  return s;
}

// Waypoints at a constant speed from a start time, with a wait of waits_s[i] at point i; the
// object then stays at its last point until kHoldUntilS (so that no one vanishes mid-scene).
constexpr double kHoldUntilS = 60.0;
std::vector<Waypoint> Walk(double t0, const std::vector<Eigen::Vector2d>& points, double speed_m_s,
                           const std::vector<double>& waits_s = {}) {
  std::vector<Waypoint> path;
  double t = t0;
  for (size_t i = 0; i < points.size(); ++i) {
    if (i > 0) t += (points[i] - points[i - 1]).norm() / speed_m_s;
    path.push_back({t, points[i], false});
    if (i < waits_s.size() && waits_s[i] > 0) {
      t += waits_s[i];
      path.push_back({t, points[i], false});
    }
  }
  if (path.back().t_s < kHoldUntilS) path.push_back({kHoldUntilS, points.back(), false});
  return path;
}

MovingObjectSpec Object(int64_t id, ObjectClass c, const SceneSpec& spec, const Eigen::Vector3f& floor_colour,
                        std::vector<Waypoint> path, double floor_like_probability = 0.0) {
  MovingObjectSpec o;
  o.id = id;
  o.object_class = c;
  o.appearance = RandomAppearance(c, spec.seed, static_cast<uint64_t>(id), floor_colour, floor_like_probability);
  o.path = std::move(path);
  return o;
}

const PinholeParameters& PinholeOf(const CameraModel& cam) {
  const auto* p = dynamic_cast<const PinholeCamera*>(&cam);
  OCCMAP_CHECK(p != nullptr, "expected a pinhole camera");
  return p->params();
}

}  // namespace

// SceneSpec::Validate's bound (sim/scene.cc), checked here first: MakeLabSceneSpec treats a
// failed SceneSpec::Validate as a bug (an abort), so a user's count must never reach it.
constexpr int64_t kMaxSceneFrames = 10'000'000;

Status BuiltinSceneOptions::Validate() const {
  if (!(image_scale > 0.01 && image_scale <= 4)) {
    return InvalidInput(fmt::format("image scale: expected 0.01 < scale <= 4, found {}", image_scale));
  }
  if (num_frames == 0 || num_frames < -1 || num_frames > kMaxSceneFrames) {
    return InvalidInput(fmt::format("frames: expected 1 .. {}, found {}", kMaxSceneFrames, num_frames));
  }
  if (!(noise_sigma == -1 || (noise_sigma >= 0 && noise_sigma <= 50))) {
    return InvalidInput(fmt::format("noise sigma: expected 0..50 grey levels, found {}", noise_sigma));
  }
  if (!(exposure_drift == -1 || (exposure_drift >= 0 && exposure_drift <= 0.5))) {
    return InvalidInput(fmt::format("exposure drift: expected 0..0.5 (or -1 for the scene's default), found {}", exposure_drift));
  }
  if (!(people == -1 || (people >= 1 && people <= 40))) {
    return InvalidInput(fmt::format("people: expected 1..40 people at a time (or -1 for the scene's default), found {}", people));
  }
  if (!(duration_s == -1 || (duration_s >= 1 && duration_s <= 3600))) {
    return InvalidInput(fmt::format("duration: expected 1..3600 s (or -1 for the scene's default), found {}", duration_s));
  }
  if (!(sun_elevation_deg == -1 || (sun_elevation_deg >= 5 && sun_elevation_deg <= 90))) {
    return InvalidInput(
        fmt::format("sun elevation: expected 5..90 degrees (or -1 for the scene's default), found {}", sun_elevation_deg));
  }
  if (overcast && sun_elevation_deg != -1) {
    return InvalidInput(fmt::format("overcast: an overcast sky has no sun, found a sun elevation of {} degrees too",
                                    sun_elevation_deg));
  }
  if (white_balance && !(*white_balance >= 0 && *white_balance <= 1)) {
    return InvalidInput(fmt::format("white balance: expected a grey-world strength 0..1, found {}", *white_balance));
  }
  if (read_noise && !(*read_noise >= 0 && *read_noise <= 50)) {
    return InvalidInput(fmt::format("read noise: expected 0..50 grey levels, found {}", *read_noise));
  }
  if (shot_noise && !(*shot_noise >= 0 && *shot_noise <= 10)) {
    return InvalidInput(fmt::format("shot noise: expected 0..10 grey levels of variance per grey level, found {}", *shot_noise));
  }
  if (supersample && (*supersample < 1 || *supersample > 4)) {
    return InvalidInput(fmt::format("supersample: expected 1..4 rays per pixel along each axis, found {}", *supersample));
  }
  if (jpeg_quality && (*jpeg_quality < 0 || *jpeg_quality > 100)) {
    return InvalidInput(fmt::format("JPEG quality: expected 0 (PNG) or 1..100, found {}", *jpeg_quality));
  }
  if (video_crf && (*video_crf < -1 || *video_crf > 51)) {
    return InvalidInput(fmt::format("video crf: expected -1 (the writer's default) or an H.264 crf 0..51, found {}", *video_crf));
  }
  if (contact_shadows && !(*contact_shadows >= 0 && *contact_shadows <= 1)) {
    return InvalidInput(fmt::format("contact shadows: expected a strength 0..1, found {}", *contact_shadows));
  }
  return Status::Ok();
}

void ApplyRealCameraPreset(PhotometrySpec& photometry) {
  CameraResponseSpec& c = photometry.camera;
  c.auto_exposure = true;
  c.target_luma = 0;
  c.max_gain = 4;
  c.white_balance = 0.6;
  c.time_constant_s = 0.4;
  c.read_noise = 1.2;
  c.shot_noise = 0.04;
  c.supersample = 2;
  c.jpeg_quality = 75;
  c.video_crf = 28;
  photometry.noise_sigma = 0;  // the sensor's noise instead
  photometry.contact_shadows = ContactShadowSpec{.strength = 0.5, .radius_m = 0.22, .reach_m = 1.5};
}

namespace {

// The plaza's own options, refused by the other scenes (rather than silently ignored).
Status CheckNoPlazaOptions(const BuiltinSceneOptions& options, std::string_view scene) {
  if (options.people != -1) {
    return InvalidInput(fmt::format("people: only the built-in plaza scene takes a people count, found {} for scene '{}'",
                                    options.people, scene));
  }
  if (options.duration_s != -1) {
    return InvalidInput(fmt::format("duration: only the built-in plaza scene takes a duration (use frames), found {} s for "
                                    "scene '{}'", options.duration_s, scene));
  }
  if (options.sun_elevation_deg != -1) {
    return InvalidInput(fmt::format("sun elevation: only the built-in plaza scene has a sun, found {} degrees for scene '{}'",
                                    options.sun_elevation_deg, scene));
  }
  if (options.overcast) {
    return InvalidInput(fmt::format("overcast: only the built-in plaza scene has a sky to change, found it for scene '{}'", scene));
  }
  return Status::Ok();
}

}  // namespace

Status WildtrackSceneOptions::Validate() const {
  if (first_frame < 0) return InvalidInput(fmt::format("first frame: expected >= 0, found {}", first_frame));
  return Status::Ok();
}

std::vector<std::string> BuiltinSceneNames() { return {"lab", "clemson", "wildtrack", "plaza"}; }

Status ApplyBuiltinOptions(const BuiltinSceneOptions& options, SceneSpec& spec) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  OCCMAP_RETURN_IF_ERROR(CheckNoPlazaOptions(options, spec.name));
  if (options.image_scale != 1.0) {
    for (CameraSpec& c : spec.cameras) {
      const ImageSize old_size = c.image_size();
      const ImageSize new_size{std::max(1, static_cast<int>(std::lround(old_size.width * options.image_scale))),
                               std::max(1, static_cast<int>(std::lround(old_size.height * options.image_scale)))};
      OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<CameraModel> cam, c.Build());
      const std::unique_ptr<CameraModel> resized = cam->Resized(new_size);
      if (c.model == CameraSpec::Model::kPinhole) {
        c.pinhole = PinholeOf(*resized);
      } else {
        const auto* t = dynamic_cast<const TsaiCamera*>(resized.get());
        OCCMAP_CHECK(t != nullptr, "expected a Tsai camera");
        c.tsai = t->params();
      }
    }
  }
  if (options.num_frames > 0) spec.num_frames = options.num_frames;
  PhotometrySpec& ph = spec.photometry;
  if (options.real_camera == true) ApplyRealCameraPreset(ph);
  if (options.real_camera == false) {
    ph.camera = CameraResponseSpec{};
    ph.contact_shadows = ContactShadowSpec{};
  }
  if (options.auto_exposure) ph.camera.auto_exposure = *options.auto_exposure;
  if (options.white_balance) ph.camera.white_balance = *options.white_balance;
  if (options.read_noise) ph.camera.read_noise = *options.read_noise;
  if (options.shot_noise) ph.camera.shot_noise = *options.shot_noise;
  if (options.supersample) ph.camera.supersample = *options.supersample;
  if (options.jpeg_quality) ph.camera.jpeg_quality = *options.jpeg_quality;
  if (options.video_crf) ph.camera.video_crf = *options.video_crf;
  if (options.contact_shadows) ph.contact_shadows.strength = *options.contact_shadows;
  if (options.noise_sigma >= 0) spec.photometry.noise_sigma = options.noise_sigma;
  spec.photometry.shadows = spec.photometry.shadows || options.shadows;
  if (options.exposure_drift >= 0) spec.photometry.exposure_drift = options.exposure_drift;
  return spec.Validate();
}

SceneSpec MakeLabSceneSpec(const BuiltinSceneOptions& options) {
  SceneSpec spec;
  spec.name = "lab";
  spec.seed = options.seed;
  spec.fps = 10;
  spec.num_frames = 100;
  spec.description =
      "The paper's UCSD lab: a carpeted 9 x 6.5 m room lined with bookshelves; four 640x480 cameras at 2.7 m "
      "on the walls looking across (mild barrel distortion); three people walking (one pushing a chair) and a "
      "round robot; a potted plant inside the area is a static occluder.";
  const Site demo = MakeDemoLabSite();
  spec.grid = demo.grid;
  for (const SiteCamera& c : demo.cameras) {
    CameraSpec cs;
    cs.id = c.id;
    cs.model = CameraSpec::Model::kPinhole;
    cs.pinhole = PinholeOf(*c.camera);
    spec.cameras.push_back(cs);
  }
  const uint32_t s32 = static_cast<uint32_t>(Mix64(spec.seed));
  const Eigen::Vector3f carpet(0.45f, 0.47f, 0.52f);
  spec.floor.push_back({-0.5, -0.5, 9.5, 7.0, MakeMaterial(carpet, Pattern::kCarpet, 0.22f, kGrey, 0.5f, s32)});
  spec.room.x_min_m = -0.5;
  spec.room.y_min_m = -0.5;
  spec.room.x_max_m = 9.5;
  spec.room.y_max_m = 7.0;
  spec.room.height_m = 3.0;
  spec.room.wall = MakeMaterial({0.82f, 0.8f, 0.74f}, Pattern::kNoise, 0.03f, kGrey, 0.5f, s32 + 1);
  spec.room.ceiling = MakeMaterial({0.9f, 0.9f, 0.88f}, Pattern::kTiles, 0.03f, {0.75f, 0.75f, 0.73f}, 0.6f, s32 + 2);
  const Material books = MakeMaterial({0.5f, 0.4f, 0.3f}, Pattern::kBooks, 0, {0.55f, 0.4f, 0.25f}, 0.38f, s32 + 3);
  const Material wood = MakeMaterial({0.55f, 0.42f, 0.28f}, Pattern::kNoise, 0.05f, kGrey, 0.5f, s32 + 4);
  spec.statics.push_back(Box("shelves south", 4.5, -0.335, 7.6, 0.33, 2.0, books));
  spec.statics.push_back(Box("shelves north", 2.85, 6.835, 4.3, 0.33, 2.0, books));
  spec.statics.push_back(Box("desk", 6.7, 6.76, 2.2, 0.48, 0.75, wood));
  spec.statics.push_back(Box("monitor", 6.7, 6.86, 0.52, 0.06, 0.36, MakeMaterial({0.08f, 0.08f, 0.09f}), 0.78));
  spec.statics.push_back(Box("shelves west", -0.335, 3.25, 0.33, 4.9, 2.0, books));
  spec.statics.push_back(Box("shelves east 1", 9.335, 1.7, 0.33, 1.8, 2.0, books));
  spec.statics.push_back(Box("shelves east 2", 9.335, 4.85, 0.33, 1.7, 2.0, books));
  spec.statics.push_back(Box("door", 9.49, 3.3, 0.02, 0.95, 2.1, MakeMaterial({0.45f, 0.3f, 0.2f})));
  StaticObjectSpec plant;
  plant.name = "potted plant";
  plant.shape = StaticObjectSpec::Shape::kPlanter;
  plant.centre_m = {8.45, 3.3};
  plant.size_m = {0.44, 0.44};
  plant.height_m = 1.1;
  plant.material = MakeMaterial({0.62f, 0.36f, 0.24f}, Pattern::kNoise, 0.05f, kGrey, 0.5f, s32 + 5);
  spec.statics.push_back(plant);

  spec.photometry.lighting.kind = Lighting::Kind::kPoint;
  spec.photometry.lighting.position_m = {4.5, 3.25, 2.9};
  spec.photometry.lighting.ambient = 0.5;
  spec.photometry.lighting.intensity = 0.6;
  spec.photometry.lighting.falloff_per_m2 = 0.02;

  // 1: walks around the room. 2: crosses it diagonally (trousers like the carpet), then waits.
  // 3 pushes chair 4 across the room. 5: the robot shuttles along the north side.
  spec.objects.push_back(Object(1, ObjectClass::kPerson, spec, carpet,
                                Walk(0.0, {{1.2, 1.0}, {7.6, 1.3}, {7.4, 5.0}, {1.6, 4.8}, {1.2, 1.0}}, 1.25)));
  spec.objects.push_back(Object(2, ObjectClass::kPerson, spec, carpet,
                                Walk(0.0, {{8.0, 0.6}, {4.2, 2.0}, {1.0, 5.3}}, 1.0, {0, 0.8, 0}), 1.0));
  const Eigen::Vector2d chair0(2.0, 2.7), chair1(6.8, 3.5);
  const Eigen::Vector2d along = (chair1 - chair0).normalized();
  spec.objects.push_back(Object(3, ObjectClass::kPerson, spec, carpet,
                                Walk(0.0, {chair0 - 0.8 * along, chair1 - 0.8 * along}, 0.55, {0.5})));
  spec.objects.push_back(Object(4, ObjectClass::kChair, spec, carpet,
                                Walk(0.0, {chair0, chair1}, 0.55, {0.5})));
  spec.objects.push_back(Object(5, ObjectClass::kRobot, spec, carpet,
                                Walk(0.0, {{3.0, 5.95}, {6.5, 5.95}, {3.0, 5.95}}, 0.45, {0, 0.6})));
  OCCMAP_CHECK(ApplyBuiltinOptions(options, spec).ok(), "lab scene options");
  return spec;
}

SceneSpec MakeClemsonSceneSpec(const BuiltinSceneOptions& options) {
  SceneSpec spec;
  spec.name = "clemson";
  spec.seed = options.seed;
  spec.fps = 10;
  spec.num_frames = 100;
  spec.description =
      "The paper's Clemson lab: 5 x 4 m, carpet and tiles; six Tsai-model 640x480 cameras on a 2.6 m drop "
      "ceiling near the corners and the centres of the two long walls; two people, a robot and a box.";
  spec.grid = FloorGrid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 250, .cells_y = 200, .cell_size_m = 0.02};
  const uint32_t s32 = static_cast<uint32_t>(Mix64(spec.seed ^ 0xc1e));
  const Eigen::Vector3f carpet(0.4f, 0.34f, 0.3f), tiles(0.78f, 0.76f, 0.7f);
  spec.floor.push_back({-0.4, -0.4, 2.5, 4.4, MakeMaterial(carpet, Pattern::kCarpet, 0.25f, kGrey, 0.5f, s32)});
  spec.floor.push_back({2.5, -0.4, 5.4, 4.4, MakeMaterial(tiles, Pattern::kTiles, 0.1f, {0.55f, 0.55f, 0.52f}, 0.3f, s32 + 1)});
  spec.room.x_min_m = -0.4;
  spec.room.y_min_m = -0.4;
  spec.room.x_max_m = 5.4;
  spec.room.y_max_m = 4.4;
  spec.room.height_m = 2.6;
  spec.room.wall = MakeMaterial({0.85f, 0.84f, 0.8f}, Pattern::kNoise, 0.03f, kGrey, 0.5f, s32 + 2);
  spec.room.ceiling = MakeMaterial({0.88f, 0.88f, 0.86f}, Pattern::kTiles, 0.04f, {0.7f, 0.7f, 0.7f}, 0.6f, s32 + 3);
  const Eigen::Vector3d centre(2.5, 2.0, 0.0);
  const double h = 2.55;
  struct Mount {
    const char* id;
    Eigen::Vector3d at;
    Eigen::Vector3d target;
  };
  const Mount mounts[] = {
      {"c1", {-0.25, -0.25, h}, {2.9, 2.4, 0}}, {"c2", {2.5, -0.3, h}, {2.5, 2.6, 0}},
      {"c3", {5.25, -0.25, h}, {2.1, 2.4, 0}},  {"c4", {5.25, 4.25, h}, {2.1, 1.6, 0}},
      {"c5", {2.5, 4.3, h}, {2.5, 1.4, 0}},     {"c6", {-0.25, 4.25, h}, {2.9, 1.6, 0}},
  };
  for (const Mount& m : mounts) {
    spec.cameras.push_back(LookAtTsai(m.id, m.at, m.target, {640, 480}, 3.0, 0.0074, 0.004));
  }
  spec.photometry.lighting.kind = Lighting::Kind::kDirectional;
  spec.photometry.lighting.direction_to_light = Eigen::Vector3d(0.2, 0.1, 1.0).normalized();
  spec.photometry.lighting.ambient = 0.55;
  spec.photometry.lighting.intensity = 0.45;
  spec.objects.push_back(Object(1, ObjectClass::kPerson, spec, carpet,
                                Walk(0.0, {{0.7, 0.7}, {4.2, 0.9}, {4.0, 3.2}, {0.9, 3.3}, {0.7, 0.7}}, 1.1)));
  spec.objects.push_back(Object(2, ObjectClass::kPerson, spec, tiles,
                                Walk(0.0, {{3.6, 2.3}, {1.4, 2.0}, {3.6, 2.3}}, 0.9, {0, 1.0}), 0.5));
  spec.objects.push_back(Object(3, ObjectClass::kRobot, spec, tiles,
                                Walk(0.0, {{1.6, 1.3}, {3.4, 1.4}, {1.6, 1.3}}, 0.4, {0, 0.5})));
  spec.objects.push_back(Object(4, ObjectClass::kBox, spec, carpet, Walk(1.0, {{2.2, 3.7}, {3.9, 3.7}}, 0.3)));
  OCCMAP_CHECK(ApplyBuiltinOptions(options, spec).ok(), "clemson scene options");
  return spec;
}

Result<SceneSpec> MakeBuiltinSceneSpec(std::string_view name, const BuiltinSceneOptions& options) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  if (name == "plaza") return MakePlazaSceneSpec(options);
  if (name == "wildtrack") return MakeWildtrackSceneSpec(options, WildtrackSceneOptions{});
  if (name != "lab" && name != "clemson") {
    return InvalidInput(fmt::format("scene: expected lab, clemson, wildtrack or plaza, found '{}'", name));
  }
  OCCMAP_RETURN_IF_ERROR(CheckNoPlazaOptions(options, name));
  if (name == "lab") return MakeLabSceneSpec(options);
  return MakeClemsonSceneSpec(options);
}

Eigen::Vector2d WildtrackPositionM(int64_t position_id) {
  return {0.01 * (-300.0 + 2.5 * static_cast<double>(position_id % 480)),
          0.01 * (-900.0 + 2.5 * static_cast<double>(position_id / 480))};
}

Result<std::vector<WildtrackAnnotation>> ReadWildtrackAnnotations(const fs::path& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    return Status(StatusCode::kNotFound, fmt::format("'{}': annotation folder not found", folder.string()));
  }
  std::vector<std::pair<int64_t, fs::path>> files;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    if (entry.path().extension() != ".json") continue;
    const std::string stem = entry.path().stem().string();
    int64_t frame = 0;
    bool digits = !stem.empty();
    for (char c : stem) digits &= (c >= '0' && c <= '9');
    if (!digits || stem.size() > 12) {
      return InvalidInput(fmt::format("'{}': expected a file named by its frame number (00000005.json)", entry.path().string()));
    }
    for (char c : stem) frame = frame * 10 + (c - '0');
    files.emplace_back(frame, entry.path());
  }
  if (ec) return IoError(fmt::format("'{}': cannot list: {}", folder.string(), ec.message()));
  if (files.empty()) return InvalidInput(fmt::format("'{}': no annotation files (*.json)", folder.string()));
  std::sort(files.begin(), files.end());
  std::vector<WildtrackAnnotation> out;
  for (const auto& [frame, path] : files) {
    OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
    OCCMAP_RETURN_IF_ERROR(CheckNesting(text, TextSyntax::kJson, kMaxNestingDepth, fmt::format("'{}'", path.string())));
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {  // syntax, and numbers out of range (1e999)
      return InvalidInput(fmt::format("'{}': JSON syntax error: {}", path.string(), e.what()));
    }
    if (!j.is_array()) return InvalidInput(fmt::format("'{}': expected a list of people", path.string()));
    WildtrackAnnotation a;
    a.frame = frame;
    for (size_t i = 0; i < j.size(); ++i) {
      const auto& p = j[i];
      if (!p.is_object() || !p.contains("personID") || !p["personID"].is_number_integer() ||
          !p.contains("positionID") || !p["positionID"].is_number_integer()) {
        return InvalidInput(fmt::format("'{}': [{}]: expected integer personID and positionID", path.string(), i));
      }
      WildtrackAnnotation::Person person;
      person.person_id = p["personID"].get<int64_t>();
      person.position_id = p["positionID"].get<int64_t>();
      if (person.person_id < 0 || person.person_id >= 65535 || person.position_id < 0 ||
          person.position_id >= 480 * 1440) {
        return InvalidInput(fmt::format("'{}': [{}]: personID {} or positionID {} out of range", path.string(), i,
                                        person.person_id, person.position_id));
      }
      person.position_m = WildtrackPositionM(person.position_id);
      a.people.push_back(person);
    }
    out.push_back(std::move(a));
  }
  return out;
}

Result<SceneSpec> MakeWildtrackSceneSpec(const BuiltinSceneOptions& options, const WildtrackSceneOptions& wt) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  OCCMAP_RETURN_IF_ERROR(CheckNoPlazaOptions(options, "wildtrack"));
  OCCMAP_RETURN_IF_ERROR(wt.Validate());
  SceneSpec spec;
  spec.name = "wildtrack";
  spec.seed = options.seed;
  spec.fps = 10;
  spec.description = fmt::format(
      "WILDTRACK's seven real calibrations ({}) and annotated trajectories from frame {} (people interpolated "
      "linearly between annotations 0.5 s apart, absent where not annotated; object id = personID + 1) on a "
      "synthetic paved square.",
      wt.original_intrinsics ? "intrinsic_original" : "intrinsic_zero", wt.first_frame);
  spec.grid = FloorGrid{.origin_x_m = -3, .origin_y_m = -9, .cells_x = 480, .cells_y = 1440, .cell_size_m = 0.025};
  const char* names[] = {"CVLab1", "CVLab2", "CVLab3", "CVLab4", "IDIAP1", "IDIAP2", "IDIAP3"};
  const fs::path calib = wt.dataset_dir / "calibrations";
  for (int i = 0; i < 7; ++i) {
    const fs::path intr =
        calib / (wt.original_intrinsics ? "intrinsic_original" : "intrinsic_zero") / fmt::format("intr_{}.xml", names[i]);
    const fs::path extr = calib / "extrinsic" / fmt::format("extr_{}.xml", names[i]);
    OCCMAP_ASSIGN_OR_RETURN(PinholeParameters p, ReadOpenCvCalibration(intr, extr, 0.01, ImageSize{1920, 1080}));
    CameraSpec c;
    c.id = fmt::format("C{}", i + 1);
    c.model = CameraSpec::Model::kPinhole;
    c.pinhole = p;
    spec.cameras.push_back(c);
  }
  const uint32_t s32 = static_cast<uint32_t>(Mix64(spec.seed ^ 0x3d));
  const Eigen::Vector3f paving(0.56f, 0.54f, 0.5f);
  spec.floor.push_back({-200, -200, 200, 200, MakeMaterial(paving, Pattern::kTiles, 0.18f, {0.4f, 0.39f, 0.37f}, 0.5f, s32)});
  spec.room.outdoor = true;
  const Material facade = MakeMaterial({0.7f, 0.66f, 0.6f}, Pattern::kNoise, 0.08f, kGrey, 0.5f, s32 + 1);
  spec.statics.push_back(Box("building west", -24, 9, 8, 80, 14, facade));
  spec.statics.push_back(Box("building east", 34, 9, 8, 80, 12, facade));
  spec.statics.push_back(Box("building south", 3, -34, 60, 8, 16, facade));
  spec.statics.push_back(Box("building north", 3, 52, 60, 8, 16, facade));
  spec.photometry.lighting.kind = Lighting::Kind::kDirectional;
  spec.photometry.lighting.direction_to_light = Eigen::Vector3d(0.4, -0.3, 0.85).normalized();
  spec.photometry.lighting.ambient = 0.5;
  spec.photometry.lighting.intensity = 0.55;

  OCCMAP_ASSIGN_OR_RETURN(std::vector<WildtrackAnnotation> annotations,
                          ReadWildtrackAnnotations(wt.dataset_dir / "annotations_positions"));
  const int64_t last_annotated = annotations.back().frame;
  if (wt.first_frame > last_annotated) {
    return InvalidInput(fmt::format("first frame: {} is after the last annotated frame {}", wt.first_frame, last_annotated));
  }
  spec.num_frames = options.num_frames > 0 ? options.num_frames : last_annotated - wt.first_frame + 1;
  const int64_t last_frame = wt.first_frame + spec.num_frames - 1;
  // Per person: waypoints at its annotated frames; a gap where an annotation file lacks it.
  std::map<int64_t, std::vector<Waypoint>> paths;
  std::map<int64_t, size_t> last_file;
  for (size_t k = 0; k < annotations.size(); ++k) {
    const WildtrackAnnotation& a = annotations[k];
    // Keep one annotation either side of the frame range, for interpolation at its ends.
    const int64_t prev = k > 0 ? annotations[k - 1].frame : a.frame;
    const int64_t next = k + 1 < annotations.size() ? annotations[k + 1].frame : a.frame;
    if (next < wt.first_frame || prev > last_frame) continue;
    for (const auto& p : a.people) {
      std::vector<Waypoint>& path = paths[p.person_id];
      const double t = static_cast<double>(a.frame - wt.first_frame) / spec.fps;
      const bool gap = !path.empty() && last_file[p.person_id] + 1 != k;
      if (!path.empty() && !(t > path.back().t_s)) continue;  // a person listed twice in a file
      path.push_back({t, p.position_m, gap});
      last_file[p.person_id] = k;
    }
  }
  for (auto& [person_id, path] : paths) {
    MovingObjectSpec o;
    o.id = person_id + 1;
    o.object_class = ObjectClass::kPerson;
    o.appearance = RandomAppearance(ObjectClass::kPerson, spec.seed, static_cast<uint64_t>(o.id), paving, 0.15);
    o.path = std::move(path);
    spec.objects.push_back(std::move(o));
  }
  BuiltinSceneOptions rest = options;
  rest.num_frames = -1;  // already applied
  OCCMAP_RETURN_IF_ERROR(ApplyBuiltinOptions(rest, spec));
  return spec;
}

}  // namespace occmap::sim
