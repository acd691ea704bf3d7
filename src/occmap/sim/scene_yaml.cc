#include "occmap/sim/scene_yaml.h"

#include <fmt/core.h>

#include <cmath>
#include <set>

#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"
#include "occmap/util/text_guard.h"
#include "occmap/util/yaml_util.h"

namespace occmap::sim {
namespace {

Result<Eigen::Vector3f> GetColour(const YamlField& f) {
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, f.AsDoubles(3));
  for (double c : v) {
    if (c < 0 || c > 1) return f.Error(fmt::format("expected colour values in 0..1, found [{}, {}, {}]", v[0], v[1], v[2]));
  }
  return Eigen::Vector3f(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
}

// A light's colour: per channel 0..2 (white = [1, 1, 1]).
Result<Eigen::Vector3f> GetLightColour(const YamlField& f) {
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, f.AsDoubles(3));
  for (double c : v) {
    if (!(c >= 0 && c <= 2)) {
      return f.Error(fmt::format("expected light colour values in 0..2, found [{}, {}, {}]", v[0], v[1], v[2]));
    }
  }
  return Eigen::Vector3f(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
}

Result<double> Positive(const YamlField& parent, std::string_view key, double default_value) {
  OCCMAP_ASSIGN_OR_RETURN(double v, parent.GetDouble(key, default_value));
  if (!(v > 0)) return parent.Find(key)->Error(fmt::format("expected a positive number, found {}", v));
  return v;
}

Result<Material> ParseMaterial(const YamlField& f, const Material& defaults) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"colour", "pattern", "colour2", "scale_m", "variation", "seed"}));
  Material m = defaults;
  if (auto c = f.Find("colour")) {
    OCCMAP_ASSIGN_OR_RETURN(m.colour, GetColour(*c));
  }
  if (auto c = f.Find("colour2")) {
    OCCMAP_ASSIGN_OR_RETURN(m.colour2, GetColour(*c));
  }
  if (auto p = f.Find("pattern")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string name, p->AsString());
    if (name == "plain") m.pattern = Pattern::kPlain;
    else if (name == "tiles") m.pattern = Pattern::kTiles;
    else if (name == "carpet") m.pattern = Pattern::kCarpet;
    else if (name == "books") m.pattern = Pattern::kBooks;
    else if (name == "noise") m.pattern = Pattern::kNoise;
    else return p->Error(fmt::format("expected plain, tiles, carpet, books or noise, found '{}'", name));
  }
  OCCMAP_ASSIGN_OR_RETURN(double scale, Positive(f, "scale_m", m.scale_m));
  m.scale_m = static_cast<float>(scale);
  OCCMAP_ASSIGN_OR_RETURN(double variation, f.GetDouble("variation", m.variation));
  if (variation < 0 || variation > 1) {
    return f.Find("variation")->Error(fmt::format("expected 0..1, found {}", variation));
  }
  m.variation = static_cast<float>(variation);
  OCCMAP_ASSIGN_OR_RETURN(int64_t seed, f.GetInt("seed", m.seed));
  if (seed < 0 || seed > 0xffffffffLL) return f.Find("seed")->Error(fmt::format("expected 0..4294967295, found {}", seed));
  m.seed = static_cast<uint32_t>(seed);
  return m;
}

Result<Material> MaybeMaterial(const YamlField& parent, std::string_view key, const Material& defaults) {
  if (auto f = parent.Find(key)) return ParseMaterial(*f, defaults);
  return defaults;
}

Result<std::array<double, 4>> GetRect(const YamlField& f) {
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, f.AsDoubles(4));
  if (!(v[2] > v[0]) || !(v[3] > v[1])) {
    return f.Error(fmt::format("expected [x_min, y_min, x_max, y_max] with min < max, found [{}, {}, {}, {}]", v[0],
                               v[1], v[2], v[3]));
  }
  return std::array<double, 4>{v[0], v[1], v[2], v[3]};
}

Result<FloorGrid> ParseGrid(const YamlField& floor) { return ParseFloorGrid(floor); }

Result<Eigen::Matrix3d> GetRotation(const YamlField& f) {
  if (!f.IsSequence() || f.size() != 3) return f.Error("expected a 3x3 matrix (3 rows of 3 numbers)");
  Eigen::Matrix3d r;
  for (size_t i = 0; i < 3; ++i) {
    OCCMAP_ASSIGN_OR_RETURN(YamlField row, f.At(i));
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, row.AsDoubles(3));
    for (int j = 0; j < 3; ++j) r(static_cast<int>(i), j) = v[static_cast<size_t>(j)];
  }
  return r;
}

Result<ImageSize> GetImageSize(const YamlField& f) {
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, f.AsDoubles(2));
  for (double d : v) {
    if (d != std::floor(d) || d < 1 || d > 16384) {
      return f.Error(fmt::format("expected [width, height] in whole pixels 1..16384, found [{}, {}]", v[0], v[1]));
    }
  }
  return ImageSize{static_cast<int>(v[0]), static_cast<int>(v[1])};
}

Result<CameraSpec> ParseCamera(const YamlField& f) {
  OCCMAP_ASSIGN_OR_RETURN(std::string model, f.GetString("model", "pinhole"));
  const std::initializer_list<std::string_view> pose_keys = {"id", "model", "image_size", "position_m", "look_at_m",
                                                            "rotation", "translation_m"};
  std::vector<std::string> keys(pose_keys.begin(), pose_keys.end());
  if (model == "pinhole") {
    for (const char* k : {"focal_px", "fx_px", "fy_px", "cx_px", "cy_px", "skew_px", "distortion"}) keys.push_back(k);
  } else if (model == "tsai") {
    for (const char* k : {"f_mm", "cell_mm", "dx_mm", "dy_mm", "kappa1_per_mm2", "sx", "ncx", "nfx", "cx_px", "cy_px"}) {
      keys.push_back(k);
    }
  } else {
    return f.Find("model")->Error(fmt::format("expected pinhole or tsai, found '{}'", model));
  }
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys(keys));
  CameraSpec c;
  OCCMAP_ASSIGN_OR_RETURN(YamlField id, f.Get("id"));
  OCCMAP_ASSIGN_OR_RETURN(c.id, id.AsString());
  OCCMAP_ASSIGN_OR_RETURN(YamlField size_field, f.Get("image_size"));
  OCCMAP_ASSIGN_OR_RETURN(ImageSize size, GetImageSize(size_field));
  // Pose.
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  const bool look_at = f.Has("position_m") || f.Has("look_at_m");
  const bool explicit_pose = f.Has("rotation") || f.Has("translation_m");
  if (look_at == explicit_pose) {
    return f.Error("expected a pose: position_m and look_at_m, or rotation and translation_m");
  }
  if (look_at) {
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> pos, f.GetDoubles("position_m", 3));
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> at, f.GetDoubles("look_at_m", 3));
    const Eigen::Vector3d p(pos[0], pos[1], pos[2]), t(at[0], at[1], at[2]);
    if ((t - p).norm() < 1e-6) return f.Find("look_at_m")->Error("expected a point away from position_m");
    rotation = LookAtRotation(p, t);
    translation = -rotation * p;
  } else {
    OCCMAP_ASSIGN_OR_RETURN(YamlField rf, f.Get("rotation"));
    OCCMAP_ASSIGN_OR_RETURN(rotation, GetRotation(rf));
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> t, f.GetDoubles("translation_m", 3));
    translation = Eigen::Vector3d(t[0], t[1], t[2]);
  }
  const double cx_default = (size.width - 1) / 2.0, cy_default = (size.height - 1) / 2.0;
  if (model == "pinhole") {
    c.model = CameraSpec::Model::kPinhole;
    PinholeParameters& p = c.pinhole;
    p.image_size = size;
    if (f.Has("focal_px") == (f.Has("fx_px") || f.Has("fy_px"))) {
      return f.Error("expected focal_px, or fx_px and fy_px");
    }
    if (f.Has("focal_px")) {
      OCCMAP_ASSIGN_OR_RETURN(p.fx_px, Positive(f, "focal_px", 1));
      p.fy_px = p.fx_px;
    } else {
      OCCMAP_ASSIGN_OR_RETURN(p.fx_px, f.GetDouble("fx_px"));
      OCCMAP_ASSIGN_OR_RETURN(p.fy_px, f.GetDouble("fy_px"));
    }
    OCCMAP_ASSIGN_OR_RETURN(p.cx_px, f.GetDouble("cx_px", cx_default));
    OCCMAP_ASSIGN_OR_RETURN(p.cy_px, f.GetDouble("cy_px", cy_default));
    OCCMAP_ASSIGN_OR_RETURN(p.skew_px, f.GetDouble("skew_px", 0.0));
    if (auto d = f.Find("distortion")) {
      OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, d->AsDoubles(5));
      for (size_t i = 0; i < 5; ++i) p.distortion[i] = v[i];
    }
    p.cam_from_world_rotation = rotation;
    p.cam_from_world_translation_m = translation;
  } else {
    c.model = CameraSpec::Model::kTsai;
    TsaiParameters& p = c.tsai;
    p.image_size = size;
    if (!f.Has("f_mm")) return f.Error("missing required field 'f_mm'");
    OCCMAP_ASSIGN_OR_RETURN(p.f_mm, Positive(f, "f_mm", 1));
    if (f.Has("cell_mm") == (f.Has("dx_mm") || f.Has("dy_mm"))) return f.Error("expected cell_mm, or dx_mm and dy_mm");
    if (f.Has("cell_mm")) {
      OCCMAP_ASSIGN_OR_RETURN(p.dx_mm, Positive(f, "cell_mm", 1));
      p.dy_mm = p.dx_mm;
    } else {
      OCCMAP_ASSIGN_OR_RETURN(p.dx_mm, Positive(f, "dx_mm", 1));
      OCCMAP_ASSIGN_OR_RETURN(p.dy_mm, Positive(f, "dy_mm", 1));
    }
    OCCMAP_ASSIGN_OR_RETURN(p.kappa1_per_mm2, f.GetDouble("kappa1_per_mm2", 0.0));
    OCCMAP_ASSIGN_OR_RETURN(p.sx, Positive(f, "sx", 1.0));
    OCCMAP_ASSIGN_OR_RETURN(p.Ncx, Positive(f, "ncx", size.width));
    OCCMAP_ASSIGN_OR_RETURN(p.Nfx, Positive(f, "nfx", size.width));
    OCCMAP_ASSIGN_OR_RETURN(p.Cx_px, f.GetDouble("cx_px", cx_default));
    OCCMAP_ASSIGN_OR_RETURN(p.Cy_px, f.GetDouble("cy_px", cy_default));
    p.cam_from_world_rotation = rotation;
    p.cam_from_world_translation_m = translation;
  }
  if (auto built = c.Build(); !built.ok()) return f.Error(built.status().message());
  return c;
}

Result<StaticObjectSpec> ParseStatic(const YamlField& f, size_t index) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"name", "shape", "centre_m", "size_m", "height_m", "base_m", "yaw_deg", "material"}));
  StaticObjectSpec s;
  OCCMAP_ASSIGN_OR_RETURN(s.name, f.GetString("name", fmt::format("static {}", index)));
  OCCMAP_ASSIGN_OR_RETURN(std::string shape, f.GetString("shape", "box"));
  if (shape == "box") s.shape = StaticObjectSpec::Shape::kBox;
  else if (shape == "cylinder") s.shape = StaticObjectSpec::Shape::kCylinder;
  else if (shape == "planter") s.shape = StaticObjectSpec::Shape::kPlanter;
  else return f.Find("shape")->Error(fmt::format("expected box, cylinder or planter, found '{}'", shape));
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> c, f.GetDoubles("centre_m", 2));
  s.centre_m = {c[0], c[1]};
  OCCMAP_ASSIGN_OR_RETURN(YamlField size_field, f.Get("size_m"));
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> sz, size_field.AsDoubles(2));
  if (!(sz[0] > 0) || !(sz[1] > 0)) return size_field.Error(fmt::format("expected positive sizes, found [{}, {}]", sz[0], sz[1]));
  s.size_m = {sz[0], sz[1]};
  OCCMAP_ASSIGN_OR_RETURN(s.height_m, Positive(f, "height_m", 1.0));
  OCCMAP_ASSIGN_OR_RETURN(s.base_m, f.GetDouble("base_m", 0.0));
  if (s.base_m < 0) return f.Find("base_m")->Error(fmt::format("expected >= 0, found {}", s.base_m));
  OCCMAP_ASSIGN_OR_RETURN(s.yaw_deg, f.GetDouble("yaw_deg", 0.0));
  Material def;
  def.colour = {0.5f, 0.45f, 0.4f};
  OCCMAP_ASSIGN_OR_RETURN(s.material, MaybeMaterial(f, "material", def));
  return s;
}

Result<std::vector<Waypoint>> ParsePath(const YamlField& f) {
  if (!f.IsSequence() || f.size() == 0) return f.Error("expected a list of waypoints");
  std::vector<Waypoint> path;
  for (size_t i = 0; i < f.size(); ++i) {
    OCCMAP_ASSIGN_OR_RETURN(YamlField w, f.At(i));
    OCCMAP_RETURN_IF_ERROR(w.CheckKeys({"at_m", "t_s", "speed_m_s", "wait_s", "gap"}));
    Waypoint wp;
    OCCMAP_ASSIGN_OR_RETURN(wp.gap_before, w.GetBool("gap", false));
    const int timing = int{w.Has("t_s")} + int{w.Has("speed_m_s")} + int{w.Has("wait_s")};
    if (w.Has("wait_s")) {
      if (i == 0) return w.Error("expected at_m for the first waypoint (a wait needs a place)");
      if (timing != 1 || w.Has("at_m") || wp.gap_before) return w.Error("expected wait_s alone");
      OCCMAP_ASSIGN_OR_RETURN(double wait, Positive(w, "wait_s", 1));
      wp.position_m = path.back().position_m;
      wp.t_s = path.back().t_s + wait;
      path.push_back(wp);
      continue;
    }
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> at, w.GetDoubles("at_m", 2));
    wp.position_m = {at[0], at[1]};
    if (i == 0) {
      if (w.Has("speed_m_s")) return w.Find("speed_m_s")->Error("the first waypoint has no speed (give t_s)");
      if (wp.gap_before) return w.Find("gap")->Error("the first waypoint cannot start a gap");
      OCCMAP_ASSIGN_OR_RETURN(wp.t_s, w.GetDouble("t_s", 0.0));
    } else {
      if (timing != 1) return w.Error("expected exactly one of t_s or speed_m_s");
      if (w.Has("t_s")) {
        OCCMAP_ASSIGN_OR_RETURN(wp.t_s, w.GetDouble("t_s"));
        if (!(wp.t_s > path.back().t_s)) {
          return w.Find("t_s")->Error(fmt::format("expected a time after the previous waypoint's {} s, found {}",
                                                  path.back().t_s, wp.t_s));
        }
      } else {
        if (wp.gap_before) return w.Find("gap")->Error("a gap needs t_s (when the object comes back)");
        OCCMAP_ASSIGN_OR_RETURN(YamlField sf, w.Get("speed_m_s"));
        OCCMAP_ASSIGN_OR_RETURN(double speed, sf.AsDouble());
        if (!(speed > 0 && speed <= 20)) return sf.Error(fmt::format("expected 0 < speed <= 20 m/s, found {}", speed));
        const double dist = (wp.position_m - path.back().position_m).norm();
        if (dist == 0) return sf.Error("expected a move (use wait_s to stand still)");
        wp.t_s = path.back().t_s + dist / speed;
      }
    }
    path.push_back(wp);
  }
  return path;
}

Result<MovingObjectSpec> ParseObject(const YamlField& f, uint64_t seed, const Eigen::Vector3f& floor_colour) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"id", "class", "height_m", "width_m", "depth_m", "colours", "path"}));
  MovingObjectSpec o;
  OCCMAP_ASSIGN_OR_RETURN(YamlField id, f.Get("id"));
  OCCMAP_ASSIGN_OR_RETURN(o.id, id.AsInt());
  if (o.id < 1 || o.id > 65535) return id.Error(fmt::format("expected an id in 1..65535, found {}", o.id));
  OCCMAP_ASSIGN_OR_RETURN(std::string cls, f.GetString("class"));
  if (cls == "person") o.object_class = ObjectClass::kPerson;
  else if (cls == "chair") o.object_class = ObjectClass::kChair;
  else if (cls == "robot") o.object_class = ObjectClass::kRobot;
  else if (cls == "box") o.object_class = ObjectClass::kBox;
  else return f.Find("class")->Error(fmt::format("expected person, chair, robot or box, found '{}'", cls));
  o.appearance = RandomAppearance(o.object_class, seed, static_cast<uint64_t>(o.id), floor_colour);
  Appearance& a = o.appearance;
  for (const auto& [key, value] : {std::pair{"height_m", &a.height_m}, std::pair{"width_m", &a.width_m},
                                   std::pair{"depth_m", &a.depth_m}}) {
    if (auto v = f.Find(key)) {
      OCCMAP_ASSIGN_OR_RETURN(*value, v->AsDouble());
      if (!(*value >= 0.05 && *value <= 5)) return v->Error(fmt::format("expected 0.05 .. 5 m, found {}", *value));
    }
  }
  if (o.object_class == ObjectClass::kChair && a.height_m < 0.5) {
    return f.Find("height_m")->Error(fmt::format("expected a chair at least 0.5 m high, found {}", a.height_m));
  }
  if (auto c = f.Find("colours")) {
    OCCMAP_RETURN_IF_ERROR(c->CheckKeys({"top", "bottom", "skin", "hair", "shoes"}));
    for (const auto& [key, value] : {std::pair{"top", &a.top}, std::pair{"bottom", &a.bottom},
                                     std::pair{"skin", &a.skin}, std::pair{"hair", &a.hair},
                                     std::pair{"shoes", &a.shoes}}) {
      if (auto v = c->Find(key)) {
    OCCMAP_ASSIGN_OR_RETURN(*value, GetColour(*v));
  }
    }
  }
  OCCMAP_ASSIGN_OR_RETURN(YamlField path, f.Get("path"));
  OCCMAP_ASSIGN_OR_RETURN(o.path, ParsePath(path));
  return o;
}

Status ParseLighting(const YamlField& f, Lighting& l) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"ambient", "light", "ambient_colour", "direct_colour"}));
  OCCMAP_ASSIGN_OR_RETURN(l.ambient, f.GetDouble("ambient", l.ambient));
  if (l.ambient < 0 || l.ambient > 2) return f.Find("ambient")->Error(fmt::format("expected 0..2, found {}", l.ambient));
  if (auto c = f.Find("ambient_colour")) {
    OCCMAP_ASSIGN_OR_RETURN(l.ambient_colour, GetLightColour(*c));
  }
  if (auto c = f.Find("direct_colour")) {
    OCCMAP_ASSIGN_OR_RETURN(l.direct_colour, GetLightColour(*c));
  }
  if (auto light = f.Find("light")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string type, light->GetString("type", "directional"));
    if (type == "directional") {
      OCCMAP_RETURN_IF_ERROR(light->CheckKeys({"type", "direction_to_light", "intensity"}));
      l.kind = Lighting::Kind::kDirectional;
      if (auto d = light->Find("direction_to_light")) {
        OCCMAP_ASSIGN_OR_RETURN(std::vector<double> v, d->AsDoubles(3));
        const Eigen::Vector3d dir(v[0], v[1], v[2]);
        if (!(dir.norm() > 1e-9)) return d->Error("expected a non-zero direction");
        // Keep an already unit vector as written (exact round trips).
        l.direction_to_light = std::abs(dir.norm() - 1) < 1e-12 ? dir : Eigen::Vector3d(dir.normalized());
      }
    } else if (type == "point") {
      OCCMAP_RETURN_IF_ERROR(light->CheckKeys({"type", "position_m", "intensity", "falloff_per_m2"}));
      l.kind = Lighting::Kind::kPoint;
      OCCMAP_ASSIGN_OR_RETURN(std::vector<double> p, light->GetDoubles("position_m", 3));
      l.position_m = {p[0], p[1], p[2]};
      OCCMAP_ASSIGN_OR_RETURN(l.falloff_per_m2, light->GetDouble("falloff_per_m2", 0.0));
      if (l.falloff_per_m2 < 0) return light->Find("falloff_per_m2")->Error("expected >= 0");
    } else {
      return light->Find("type")->Error(fmt::format("expected directional or point, found '{}'", type));
    }
    OCCMAP_ASSIGN_OR_RETURN(l.intensity, light->GetDouble("intensity", l.intensity));
    if (l.intensity < 0 || l.intensity > 4) {
      return light->Find("intensity")->Error(fmt::format("expected 0..4, found {}", l.intensity));
    }
  }
  return Status::Ok();
}

Status ParseContactShadows(const YamlField& f, ContactShadowSpec& c) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"strength", "radius_m", "reach_m"}));
  OCCMAP_ASSIGN_OR_RETURN(c.strength, f.GetDouble("strength", 0.5));
  if (!(c.strength >= 0 && c.strength <= 1)) {
    return f.Find("strength")->Error(fmt::format("expected a fraction 0..1, found {}", c.strength));
  }
  OCCMAP_ASSIGN_OR_RETURN(c.radius_m, f.GetDouble("radius_m", c.radius_m));
  if (!(c.radius_m > 0 && c.radius_m <= 2)) {
    return f.Find("radius_m")->Error(fmt::format("expected 0 < radius <= 2 m, found {}", c.radius_m));
  }
  OCCMAP_ASSIGN_OR_RETURN(c.reach_m, f.GetDouble("reach_m", c.reach_m));
  if (!(c.reach_m > c.radius_m && c.reach_m <= 10)) {
    const YamlField& where = f.Has("reach_m") ? *f.Find("reach_m") : f;
    return where.Error(fmt::format("expected radius_m ({}) < reach <= 10 m, found {}", c.radius_m, c.reach_m));
  }
  return Status::Ok();
}

Status ParseCameraResponse(const YamlField& f, CameraResponseSpec& c) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"auto_exposure", "target_luma", "max_gain", "white_balance", "time_constant_s",
                                      "read_noise", "shot_noise", "supersample", "jpeg_quality", "video_crf"}));
  OCCMAP_ASSIGN_OR_RETURN(c.auto_exposure, f.GetBool("auto_exposure", c.auto_exposure));
  auto in_range = [&](std::string_view key, double* value, double lo, double hi, const char* what) -> Status {
    OCCMAP_ASSIGN_OR_RETURN(*value, f.GetDouble(key, *value));
    if (!(*value >= lo && *value <= hi)) return f.Find(key)->Error(fmt::format("expected {}, found {}", what, *value));
    return Status::Ok();
  };
  OCCMAP_RETURN_IF_ERROR(in_range("target_luma", &c.target_luma, 0, 254, "0 (the empty view's) or 1..254 grey levels"));
  if (c.target_luma > 0 && c.target_luma < 1) {
    return f.Find("target_luma")->Error(fmt::format("expected 0 (the empty view's) or 1..254 grey levels, found {}", c.target_luma));
  }
  OCCMAP_RETURN_IF_ERROR(in_range("max_gain", &c.max_gain, 1, 64, "a gain limit 1..64"));
  OCCMAP_RETURN_IF_ERROR(in_range("white_balance", &c.white_balance, 0, 1, "a grey-world strength 0..1"));
  OCCMAP_RETURN_IF_ERROR(in_range("time_constant_s", &c.time_constant_s, 0, 3600, "0..3600 s"));
  OCCMAP_RETURN_IF_ERROR(in_range("read_noise", &c.read_noise, 0, 50, "0..50 grey levels"));
  OCCMAP_RETURN_IF_ERROR(in_range("shot_noise", &c.shot_noise, 0, 10, "0..10 grey levels of variance per grey level"));
  auto int_in_range = [&](std::string_view key, int* value, int lo, int hi, const char* what) -> Status {
    OCCMAP_ASSIGN_OR_RETURN(int64_t v, f.GetInt(key, *value));
    if (v < lo || v > hi) return f.Find(key)->Error(fmt::format("expected {}, found {}", what, v));
    *value = static_cast<int>(v);
    return Status::Ok();
  };
  OCCMAP_RETURN_IF_ERROR(int_in_range("supersample", &c.supersample, 1, 4, "1..4 rays per pixel along each axis"));
  OCCMAP_RETURN_IF_ERROR(int_in_range("jpeg_quality", &c.jpeg_quality, 0, 100, "0 (PNG) or a JPEG quality 1..100"));
  OCCMAP_RETURN_IF_ERROR(int_in_range("video_crf", &c.video_crf, -1, 51, "-1 (the writer's default) or an H.264 crf 0..51"));
  return Status::Ok();
}

Status ParsePhotometry(const YamlField& f, PhotometrySpec& p) {
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"noise_sigma", "exposure_drift", "exposure_period_s", "shadows", "background_noise",
                                      "contact_shadows", "camera"}));
  if (auto c = f.Find("contact_shadows")) OCCMAP_RETURN_IF_ERROR(ParseContactShadows(*c, p.contact_shadows));
  if (auto c = f.Find("camera")) OCCMAP_RETURN_IF_ERROR(ParseCameraResponse(*c, p.camera));
  OCCMAP_ASSIGN_OR_RETURN(p.noise_sigma, f.GetDouble("noise_sigma", p.noise_sigma));
  if (p.noise_sigma < 0 || p.noise_sigma > 50) {
    return f.Find("noise_sigma")->Error(fmt::format("expected 0..50 grey levels, found {}", p.noise_sigma));
  }
  OCCMAP_ASSIGN_OR_RETURN(p.exposure_drift, f.GetDouble("exposure_drift", p.exposure_drift));
  if (p.exposure_drift < 0 || p.exposure_drift > 0.5) {
    return f.Find("exposure_drift")->Error(fmt::format("expected 0..0.5, found {}", p.exposure_drift));
  }
  OCCMAP_ASSIGN_OR_RETURN(p.exposure_period_s, Positive(f, "exposure_period_s", p.exposure_period_s));
  OCCMAP_ASSIGN_OR_RETURN(p.shadows, f.GetBool("shadows", p.shadows));
  OCCMAP_ASSIGN_OR_RETURN(p.background_noise, f.GetBool("background_noise", p.background_noise));
  return Status::Ok();
}

// Shortest round-trip text of a number.
std::string Num(double v) { return fmt::format("{}", v); }
std::string Num(float v) { return fmt::format("{}", v); }
std::string Vec(const Eigen::Vector3f& v) { return fmt::format("[{}, {}, {}]", Num(v[0]), Num(v[1]), Num(v[2])); }
std::string Vec(const Eigen::Vector3d& v) { return fmt::format("[{}, {}, {}]", Num(v[0]), Num(v[1]), Num(v[2])); }
std::string Vec(const Eigen::Vector2d& v) { return fmt::format("[{}, {}]", Num(v[0]), Num(v[1])); }
std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out + "\"";
}

const char* PatternName(Pattern p) {
  switch (p) {
    case Pattern::kPlain: return "plain";
    case Pattern::kTiles: return "tiles";
    case Pattern::kCarpet: return "carpet";
    case Pattern::kBooks: return "books";
    case Pattern::kNoise: return "noise";
  }
  return "plain";
}

std::string MaterialText(const Material& m) {
  return fmt::format("{{colour: {}, pattern: {}, colour2: {}, scale_m: {}, variation: {}, seed: {}}}", Vec(m.colour),
                     PatternName(m.pattern), Vec(m.colour2), Num(m.scale_m), Num(m.variation), m.seed);
}

std::string MatrixText(const Eigen::Matrix3d& r) {
  return fmt::format("[{}, {}, {}]", Vec(Eigen::Vector3d(r.row(0).transpose())), Vec(Eigen::Vector3d(r.row(1).transpose())),
                     Vec(Eigen::Vector3d(r.row(2).transpose())));
}

}  // namespace

Result<SceneSpec> ParseSceneYaml(std::string_view text, const std::string& file_name) {
  OCCMAP_ASSIGN_OR_RETURN(YamlField root, ParseYaml(text, file_name));
  if (!root.IsMap()) return root.Error("expected a scene description (a map with floor and cameras)");
  OCCMAP_RETURN_IF_ERROR(root.CheckKeys({"version", "name", "seed", "fps", "frames", "duration_s", "description", "floor",
                                         "room", "cameras", "statics", "objects", "lighting", "photometry"}));
  OCCMAP_ASSIGN_OR_RETURN(int64_t version, root.GetInt("version", 1));
  if (version != 1) return root.Find("version")->Error(fmt::format("expected scene format version 1, found {}", version));
  SceneSpec spec;
  const std::string stem = std::filesystem::path(file_name).stem().string();
  OCCMAP_ASSIGN_OR_RETURN(spec.name, root.GetString("name", stem.empty() ? "scene" : stem));
  if (spec.name.empty()) return root.Find("name")->Error("expected a non-empty name");
  // The name becomes the written site's name (and its files'): refused here as the site loader
  // would refuse it ("../../evil" was written, then not loaded).
  if (auto bad = CheckSafeFileName(spec.name)) {
    if (auto name = root.Find("name")) return name->Error(fmt::format("scene name '{}': {}", Excerpt(spec.name), *bad));
    return root.Error(fmt::format("the file's name '{}' is the scene's name and {}; give a `name:`", Excerpt(spec.name), *bad));
  }
  OCCMAP_ASSIGN_OR_RETURN(int64_t seed, root.GetInt("seed", 1));
  if (seed < 0) return root.Find("seed")->Error(fmt::format("expected a seed >= 0, found {}", seed));
  spec.seed = static_cast<uint64_t>(seed);
  OCCMAP_ASSIGN_OR_RETURN(spec.fps, root.GetDouble("fps", 10.0));
  if (!(spec.fps > 0 && spec.fps <= 1000)) return root.Find("fps")->Error(fmt::format("expected 0 < fps <= 1000, found {}", spec.fps));
  if (root.Has("frames") && root.Has("duration_s")) return root.Error("expected one of 'frames' or 'duration_s'");
  if (auto f = root.Find("duration_s")) {
    OCCMAP_ASSIGN_OR_RETURN(double d, f->AsDouble());
    if (!(d > 0 && d * spec.fps <= 1e7)) return f->Error(fmt::format("expected a positive duration, found {}", d));
    spec.num_frames = std::max<int64_t>(1, static_cast<int64_t>(std::floor(d * spec.fps + 1e-9)));
  } else {
    OCCMAP_ASSIGN_OR_RETURN(spec.num_frames, root.GetInt("frames", 100));
    if (spec.num_frames < 1 || spec.num_frames > 10'000'000) {
      return root.Find("frames")->Error(fmt::format("expected 1 .. 10000000 frames, found {}", spec.num_frames));
    }
  }
  OCCMAP_ASSIGN_OR_RETURN(spec.description, root.GetString("description", ""));

  OCCMAP_ASSIGN_OR_RETURN(YamlField floor, root.Get("floor"));
  OCCMAP_RETURN_IF_ERROR(floor.CheckKeys({"origin_m", "cells", "size_m", "cell_size_m", "pieces"}));
  OCCMAP_ASSIGN_OR_RETURN(spec.grid, ParseGrid(floor));
  const FloorGrid& g = spec.grid;

  // Room (defaults: walls 0.5 m around the area, 3 m high).
  RoomSpec& room = spec.room;
  room.x_min_m = g.origin_x_m - 0.5;
  room.y_min_m = g.origin_y_m - 0.5;
  room.x_max_m = g.origin_x_m + g.size_x_m() + 0.5;
  room.y_max_m = g.origin_y_m + g.size_y_m() + 0.5;
  room.wall.colour = {0.82f, 0.8f, 0.74f};
  room.wall.pattern = Pattern::kNoise;
  room.wall.variation = 0.03f;
  room.ceiling.colour = {0.9f, 0.9f, 0.88f};
  if (auto rf = root.Find("room")) {
    OCCMAP_RETURN_IF_ERROR(rf->CheckKeys({"outdoor", "walls_m", "height_m", "wall", "ceiling", "sky_colour"}));
    OCCMAP_ASSIGN_OR_RETURN(room.outdoor, rf->GetBool("outdoor", false));
    if (auto w = rf->Find("walls_m")) {
      if (room.outdoor) return w->Error("an outdoor scene has no walls");
      OCCMAP_ASSIGN_OR_RETURN(auto r, GetRect(*w));
      room.x_min_m = r[0];
      room.y_min_m = r[1];
      room.x_max_m = r[2];
      room.y_max_m = r[3];
    }
    OCCMAP_ASSIGN_OR_RETURN(room.height_m, Positive(*rf, "height_m", room.height_m));
    OCCMAP_ASSIGN_OR_RETURN(room.wall, MaybeMaterial(*rf, "wall", room.wall));
    OCCMAP_ASSIGN_OR_RETURN(room.ceiling, MaybeMaterial(*rf, "ceiling", room.ceiling));
    if (auto s = rf->Find("sky_colour")) {
    OCCMAP_ASSIGN_OR_RETURN(room.sky_colour, GetColour(*s));
  }
  }
  // Floor pieces (default: one carpet over the room, or 20 m around the area outdoors).
  if (auto pieces = floor.Find("pieces")) {
    if (!pieces->IsSequence() || pieces->size() == 0) return pieces->Error("expected a list of floor pieces");
    for (size_t i = 0; i < pieces->size(); ++i) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField p, pieces->At(i));
      OCCMAP_RETURN_IF_ERROR(p.CheckKeys({"area_m", "material"}));
      OCCMAP_ASSIGN_OR_RETURN(YamlField area, p.Get("area_m"));
      OCCMAP_ASSIGN_OR_RETURN(auto r, GetRect(area));
      Material def;
      def.colour = {0.45f, 0.47f, 0.52f};
      OCCMAP_ASSIGN_OR_RETURN(Material m, MaybeMaterial(p, "material", def));
      spec.floor.push_back({r[0], r[1], r[2], r[3], m});
    }
  } else {
    Material carpet;
    carpet.colour = {0.45f, 0.47f, 0.52f};
    carpet.pattern = Pattern::kCarpet;
    carpet.variation = 0.2f;
    carpet.seed = static_cast<uint32_t>(spec.seed);
    const double m = room.outdoor ? 20.0 : 0.0;
    if (room.outdoor) {
      spec.floor.push_back({g.origin_x_m - m, g.origin_y_m - m, g.origin_x_m + g.size_x_m() + m,
                            g.origin_y_m + g.size_y_m() + m, carpet});
    } else {
      spec.floor.push_back({room.x_min_m, room.y_min_m, room.x_max_m, room.y_max_m, carpet});
    }
  }

  OCCMAP_ASSIGN_OR_RETURN(YamlField cams, root.Get("cameras"));
  if (!cams.IsSequence() || cams.size() == 0) return cams.Error("expected a list of at least one camera");
  if (cams.size() > 255) return cams.Error(fmt::format("expected at most 255 cameras, found {}", cams.size()));
  std::set<std::string> ids;
  for (size_t i = 0; i < cams.size(); ++i) {
    OCCMAP_ASSIGN_OR_RETURN(YamlField cf, cams.At(i));
    OCCMAP_ASSIGN_OR_RETURN(CameraSpec c, ParseCamera(cf));
    const YamlField idf = *cf.Find("id");
    for (char ch : c.id) {
      if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '.')) {
        return idf.Error(fmt::format("expected letters, digits, '_', '-' or '.', found '{}'", c.id));
      }
    }
    if (c.id.empty() || c.id == "." || c.id == "..") return idf.Error("expected a camera id that can name a file");
    if (!ids.insert(c.id).second) return idf.Error(fmt::format("duplicate camera id '{}'", c.id));
    spec.cameras.push_back(std::move(c));
  }
  if (auto statics = root.Find("statics")) {
    if (!statics->IsSequence()) return statics->Error("expected a list of static objects");
    for (size_t i = 0; i < statics->size(); ++i) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField sf, statics->At(i));
      OCCMAP_ASSIGN_OR_RETURN(StaticObjectSpec s, ParseStatic(sf, i));
      spec.statics.push_back(std::move(s));
    }
  }
  if (auto objects = root.Find("objects")) {
    if (!objects->IsSequence()) return objects->Error("expected a list of moving objects");
    std::set<int64_t> object_ids;
    for (size_t i = 0; i < objects->size(); ++i) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField of, objects->At(i));
      OCCMAP_ASSIGN_OR_RETURN(MovingObjectSpec o, ParseObject(of, spec.seed, spec.floor.front().material.colour));
      if (!object_ids.insert(o.id).second) return of.Find("id")->Error(fmt::format("duplicate object id {}", o.id));
      spec.objects.push_back(std::move(o));
    }
  }
  if (auto l = root.Find("lighting")) OCCMAP_RETURN_IF_ERROR(ParseLighting(*l, spec.photometry.lighting));
  if (auto p = root.Find("photometry")) OCCMAP_RETURN_IF_ERROR(ParsePhotometry(*p, spec.photometry));
  if (Status s = spec.Validate(); !s.ok()) return root.Error(s.message());
  return spec;
}

Result<SceneSpec> LoadSceneYaml(const std::filesystem::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
  return ParseSceneYaml(text, path.string());
}

std::string SceneToYaml(const SceneSpec& spec) {
  std::string out = "# occmap simulated scene (sim/scene_yaml.h)\nversion: 1\n";
  out += fmt::format("name: {}\nseed: {}\nfps: {}\nframes: {}\n", Quote(spec.name), spec.seed, Num(spec.fps),
                     spec.num_frames);
  if (!spec.description.empty()) out += fmt::format("description: {}\n", Quote(spec.description));
  const FloorGrid& g = spec.grid;
  out += fmt::format("floor:\n  origin_m: [{}, {}]\n  cells: [{}, {}]\n  cell_size_m: {}\n  pieces:\n", Num(g.origin_x_m),
                     Num(g.origin_y_m), g.cells_x, g.cells_y, Num(g.cell_size_m));
  for (const FloorPatch& f : spec.floor) {
    out += fmt::format("    - {{area_m: [{}, {}, {}, {}], material: {}}}\n", Num(f.x_min_m), Num(f.y_min_m),
                       Num(f.x_max_m), Num(f.y_max_m), MaterialText(f.material));
  }
  const RoomSpec& r = spec.room;
  if (r.outdoor) {
    out += fmt::format("room:\n  outdoor: true\n  sky_colour: {}\n", Vec(r.sky_colour));
  } else {
    out += fmt::format("room:\n  walls_m: [{}, {}, {}, {}]\n  height_m: {}\n  wall: {}\n  ceiling: {}\n", Num(r.x_min_m),
                       Num(r.y_min_m), Num(r.x_max_m), Num(r.y_max_m), Num(r.height_m), MaterialText(r.wall),
                       MaterialText(r.ceiling));
  }
  out += "cameras:\n";
  for (const CameraSpec& c : spec.cameras) {
    out += fmt::format("  - id: {}\n", Quote(c.id));
    const ImageSize size = c.image_size();
    if (c.model == CameraSpec::Model::kPinhole) {
      const PinholeParameters& p = c.pinhole;
      out += fmt::format("    model: pinhole\n    image_size: [{}, {}]\n", size.width, size.height);
      out += fmt::format("    fx_px: {}\n    fy_px: {}\n    cx_px: {}\n    cy_px: {}\n    skew_px: {}\n", Num(p.fx_px),
                         Num(p.fy_px), Num(p.cx_px), Num(p.cy_px), Num(p.skew_px));
      out += fmt::format("    distortion: [{}, {}, {}, {}, {}]\n", Num(p.distortion[0]), Num(p.distortion[1]),
                         Num(p.distortion[2]), Num(p.distortion[3]), Num(p.distortion[4]));
      out += fmt::format("    rotation: {}\n    translation_m: {}\n", MatrixText(p.cam_from_world_rotation),
                         Vec(p.cam_from_world_translation_m));
    } else {
      const TsaiParameters& p = c.tsai;
      out += fmt::format("    model: tsai\n    image_size: [{}, {}]\n", size.width, size.height);
      out += fmt::format(
          "    f_mm: {}\n    dx_mm: {}\n    dy_mm: {}\n    kappa1_per_mm2: {}\n    sx: {}\n    ncx: {}\n    nfx: {}\n"
          "    cx_px: {}\n    cy_px: {}\n",
          Num(p.f_mm), Num(p.dx_mm), Num(p.dy_mm), Num(p.kappa1_per_mm2), Num(p.sx), Num(p.Ncx), Num(p.Nfx), Num(p.Cx_px),
          Num(p.Cy_px));
      out += fmt::format("    rotation: {}\n    translation_m: {}\n", MatrixText(p.cam_from_world_rotation),
                         Vec(p.cam_from_world_translation_m));
    }
  }
  if (!spec.statics.empty()) {
    out += "statics:\n";
    for (const StaticObjectSpec& s : spec.statics) {
      const char* shape = s.shape == StaticObjectSpec::Shape::kBox        ? "box"
                          : s.shape == StaticObjectSpec::Shape::kCylinder ? "cylinder"
                                                                          : "planter";
      out += fmt::format(
          "  - {{name: {}, shape: {}, centre_m: {}, size_m: {}, height_m: {}, base_m: {}, yaw_deg: {}, material: {}}}\n",
          Quote(s.name), shape, Vec(s.centre_m), Vec(s.size_m), Num(s.height_m), Num(s.base_m), Num(s.yaw_deg),
          MaterialText(s.material));
    }
  }
  if (!spec.objects.empty()) {
    out += "objects:\n";
    for (const MovingObjectSpec& o : spec.objects) {
      const Appearance& a = o.appearance;
      out += fmt::format("  - id: {}\n    class: {}\n    height_m: {}\n    width_m: {}\n    depth_m: {}\n", o.id,
                         ToString(o.object_class), Num(a.height_m), Num(a.width_m), Num(a.depth_m));
      out += fmt::format("    colours: {{top: {}, bottom: {}, skin: {}, hair: {}, shoes: {}}}\n    path:\n", Vec(a.top),
                         Vec(a.bottom), Vec(a.skin), Vec(a.hair), Vec(a.shoes));
      for (const Waypoint& w : o.path) {
        out += fmt::format("      - {{at_m: {}, t_s: {}{}}}\n", Vec(w.position_m), Num(w.t_s), w.gap_before ? ", gap: true" : "");
      }
    }
  }
  const Lighting& l = spec.photometry.lighting;
  out += fmt::format("lighting:\n  ambient: {}\n", Num(l.ambient));
  // White lights are the default and are left out (scenes written before the colours existed
  // read back the same).
  if (l.ambient_colour != Eigen::Vector3f::Ones()) out += fmt::format("  ambient_colour: {}\n", Vec(l.ambient_colour));
  if (l.direct_colour != Eigen::Vector3f::Ones()) out += fmt::format("  direct_colour: {}\n", Vec(l.direct_colour));
  if (l.kind == Lighting::Kind::kDirectional) {
    out += fmt::format("  light: {{type: directional, direction_to_light: {}, intensity: {}}}\n", Vec(l.direction_to_light),
                       Num(l.intensity));
  } else {
    out += fmt::format("  light: {{type: point, position_m: {}, intensity: {}, falloff_per_m2: {}}}\n", Vec(l.position_m),
                       Num(l.intensity), Num(l.falloff_per_m2));
  }
  const PhotometrySpec& p = spec.photometry;
  out += fmt::format(
      "photometry:\n  noise_sigma: {}\n  exposure_drift: {}\n  exposure_period_s: {}\n  shadows: {}\n  background_noise: {}\n",
      Num(p.noise_sigma), Num(p.exposure_drift), Num(p.exposure_period_s), p.shadows, p.background_noise);
  // Written only when on: scenes without them write the same text as before they existed.
  if (p.contact_shadows.enabled()) {
    out += fmt::format("  contact_shadows: {{strength: {}, radius_m: {}, reach_m: {}}}\n", Num(p.contact_shadows.strength),
                       Num(p.contact_shadows.radius_m), Num(p.contact_shadows.reach_m));
  }
  if (p.camera != CameraResponseSpec{}) {
    const CameraResponseSpec& c = p.camera;
    out += fmt::format(
        "  camera:\n    auto_exposure: {}\n    target_luma: {}\n    max_gain: {}\n    white_balance: {}\n"
        "    time_constant_s: {}\n    read_noise: {}\n    shot_noise: {}\n    supersample: {}\n    jpeg_quality: {}\n"
        "    video_crf: {}\n",
        c.auto_exposure, Num(c.target_luma), Num(c.max_gain), Num(c.white_balance), Num(c.time_constant_s),
        Num(c.read_noise), Num(c.shot_noise), c.supersample, c.jpeg_quality, c.video_crf);
  }
  return out;
}

}  // namespace occmap::sim
