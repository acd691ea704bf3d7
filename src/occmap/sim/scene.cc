#include "occmap/sim/scene.h"

#include <Eigen/Geometry>
#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

namespace occmap::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTimeEps = 1e-9;
// A path segment shorter than this (or slower than kMinHeadingSpeed) does not turn the object:
// annotation jitter of someone standing must not spin them around.
constexpr double kMinHeadingMove = 0.06;
constexpr double kMinHeadingSpeed = 0.12;
constexpr double kHeadingBlendS = 0.25;  // turns are blended over +-0.25 s around a waypoint

Eigen::Matrix3d Yaw(double rad) { return Eigen::AngleAxisd(rad, Eigen::Vector3d::UnitZ()).toRotationMatrix(); }

double WrapAngle(double a) {
  while (a > kPi) a -= 2 * kPi;
  while (a < -kPi) a += 2 * kPi;
  return a;
}

bool ValidId(const std::string& id) {
  if (id.empty() || id == "." || id == "..") return false;
  for (char c : id) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) return false;
  }
  return true;
}

bool FiniteColour(const Eigen::Vector3f& c) {
  return c.allFinite() && c.minCoeff() >= 0 && c.maxCoeff() <= 1;
}

// Rectangle (centre, half sizes, yaw) as a counter-clockwise polygon, shrunk by `inset_m`.
std::vector<Eigen::Vector2d> RectPolygon(const Eigen::Vector2d& centre, double half_x, double half_y, double yaw,
                                         double inset_m = 1e-4) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  const double hx = half_x - inset_m, hy = half_y - inset_m;
  std::vector<Eigen::Vector2d> poly;
  for (const auto& [lx, ly] : {std::pair{-hx, -hy}, std::pair{hx, -hy}, std::pair{hx, hy}, std::pair{-hx, hy}}) {
    poly.emplace_back(centre.x() + c * lx - s * ly, centre.y() + s * lx + c * ly);
  }
  return poly;
}

std::vector<Eigen::Vector2d> CirclePolygon(const Eigen::Vector2d& centre, double radius, int n = 32) {
  std::vector<Eigen::Vector2d> poly;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * kPi * i / n;
    poly.emplace_back(centre.x() + radius * std::cos(a), centre.y() + radius * std::sin(a));
  }
  return poly;  // inscribed: inside the disc
}

Material Plain(const Eigen::Vector3f& c) {
  Material m;
  m.colour = c;
  return m;
}

void FinishBounds(ObjectInstance& inst) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  for (const Primitive& p : inst.parts) {
    Eigen::Vector3d a, b;
    p.Bounds(&a, &b);
    lo = lo.cwiseMin(a);
    hi = hi.cwiseMax(b);
  }
  constexpr double kPad = 1e-3;
  lo -= Eigen::Vector3d::Constant(kPad);
  hi += Eigen::Vector3d::Constant(kPad);
  inst.bound.centre_xy_m = 0.5 * (lo.head<2>() + hi.head<2>());
  inst.bound.radius_m = 0.5 * (hi.head<2>() - lo.head<2>()).norm();
  inst.bound.z_min_m = lo.z();
  inst.bound.z_max_m = hi.z();
  inst.sphere_centre_m = 0.5 * (lo + hi);
  inst.sphere_radius_m = 0.5 * (hi - lo).norm();
}

// The articulated person: see scene.h. Local frame: x forward, y left, z up.
void AddPerson(const Appearance& ap, const PathSample& pose, ObjectInstance& inst) {
  const double s = ap.height_m / 1.75;
  const Eigen::Matrix3d yaw = Yaw(pose.heading_rad);
  const Eigen::Vector3d base(pose.position_m.x(), pose.position_m.y(), 0);
  auto world = [&](double x, double y, double z) { return Eigen::Vector3d(base + yaw * Eigen::Vector3d(x, y, z)); };
  const double ankle_h = 0.08 * s, leg = 0.82 * s, cycle_m = 1.45 * s;
  const double amp = 0.42 * std::clamp(pose.speed_m_s / 1.3, 0.0, 1.0);
  const double phase = 2 * kPi * pose.distance_m / cycle_m;
  const double swing = amp * std::sin(phase);
  const double hip_h = ankle_h + leg * std::cos(swing);
  const double lift_scale = amp / 0.42;
  const Material trousers = Plain(ap.bottom), shirt = Plain(ap.top), skin = Plain(ap.skin), hair = Plain(ap.hair),
                 shoes = Plain(ap.shoes);
  for (int side = 0; side < 2; ++side) {
    const double lateral = (side == 0 ? 1 : -1) * 0.095 * s;  // 0 = left leg
    const double theta = side == 0 ? swing : -swing;
    const double forward_swing = side == 0 ? std::cos(phase) : -std::cos(phase);
    const double lift = 0.07 * s * lift_scale * std::pow(std::max(0.0, forward_swing), 2);
    const Eigen::Vector3d hip(0, lateral, hip_h);
    const Eigen::Vector3d ankle(leg * std::sin(theta) - 0.4 * lift, lateral, ankle_h + lift);
    const Eigen::Vector3d knee = 0.5 * (hip + Eigen::Vector3d(leg * std::sin(theta), lateral, ankle_h)) +
                                 Eigen::Vector3d(0.6 * lift, 0, 0.3 * lift);
    inst.parts.push_back(Primitive::Capsule(world(hip.x(), hip.y(), hip.z()), world(knee.x(), knee.y(), knee.z()),
                                            0.075 * s, trousers));
    inst.parts.push_back(Primitive::Capsule(world(knee.x(), knee.y(), knee.z()),
                                            world(ankle.x(), ankle.y(), ankle.z()), 0.055 * s, trousers));
    // Foot: heel 7 cm behind the ankle, toe 19 cm in front, 10 cm wide, 8 cm high.
    const double heel = -0.07 * s, toe = 0.19 * s, half_w = 0.05 * s;
    const Eigen::Vector2d foot_centre_local(ankle.x() + 0.5 * (heel + toe), lateral);
    const Eigen::Vector2d foot_centre = pose.position_m + (yaw.topLeftCorner<2, 2>() * foot_centre_local);
    inst.parts.push_back(Primitive::UprightBox(foot_centre, lift, lift + 0.08 * s,
                                               {0.5 * (toe - heel), half_w}, pose.heading_rad, shoes));
    if (lift == 0.0) {
      inst.footprint_m.push_back(RectPolygon(foot_centre, 0.5 * (toe - heel), half_w, pose.heading_rad));
    }
  }
  inst.parts.push_back(Primitive::Ellipsoid(world(0, 0, hip_h + 0.03 * s), yaw,
                                            Eigen::Vector3d(0.11, 0.18, 0.13) * s, trousers));
  inst.parts.push_back(Primitive::Ellipsoid(world(0, 0, hip_h + 0.34 * s), yaw,
                                            Eigen::Vector3d(0.12, 0.2, 0.31) * s, shirt));
  inst.parts.push_back(
      Primitive::Capsule(world(0, 0, hip_h + 0.6 * s), world(0, 0, hip_h + 0.68 * s), 0.05 * s, skin));
  const Eigen::Vector3d head = world(0, 0, hip_h + 0.745 * s);
  inst.parts.push_back(Primitive::Sphere(head, 0.105 * s, skin));
  inst.parts.push_back(Primitive::Sphere(world(-0.018 * s, 0, hip_h + 0.765 * s), 0.108 * s, hair));
  for (int side = 0; side < 2; ++side) {
    const double lateral = (side == 0 ? 1 : -1) * 0.205 * s;
    const double alpha = -(side == 0 ? swing : -swing) * 0.8;  // arms swing against the legs
    const Eigen::Vector3d shoulder(0, lateral, hip_h + 0.55 * s);
    const Eigen::Vector3d elbow = shoulder + 0.29 * s * Eigen::Vector3d(std::sin(alpha), 0.08 * lateral / s, -std::cos(alpha));
    const double fore = alpha + 0.25;
    const Eigen::Vector3d hand = elbow + 0.27 * s * Eigen::Vector3d(std::sin(fore), 0, -std::cos(fore));
    inst.parts.push_back(Primitive::Capsule(world(shoulder.x(), shoulder.y(), shoulder.z()),
                                            world(elbow.x(), elbow.y(), elbow.z()), 0.048 * s, shirt));
    inst.parts.push_back(Primitive::Capsule(world(elbow.x(), elbow.y(), elbow.z()),
                                            world(hand.x(), hand.y(), hand.z()), 0.04 * s, skin));
  }
}

void AddChair(const Appearance& ap, const PathSample& pose, ObjectInstance& inst) {
  const double yaw = pose.heading_rad;
  const Eigen::Matrix2d r = Yaw(yaw).topLeftCorner<2, 2>();
  const double hd = 0.5 * ap.depth_m, hw = 0.5 * ap.width_m;
  const double seat_z = 0.45, leg_half = 0.0175, inset = 0.03;
  const Material seat = Plain(ap.top), frame = Plain(ap.bottom);
  auto at = [&](double lx, double ly) { return Eigen::Vector2d(pose.position_m + r * Eigen::Vector2d(lx, ly)); };
  inst.parts.push_back(Primitive::UprightBox(pose.position_m, seat_z - 0.04, seat_z, {hd, hw}, yaw, seat));
  // Legs in counter-clockwise order (front right, front left, back left, back right).
  for (const auto& [sx, sy] : {std::pair{1, -1}, std::pair{1, 1}, std::pair{-1, 1}, std::pair{-1, -1}}) {
    const Eigen::Vector2d c = at(sx * (hd - inset), sy * (hw - inset));
    inst.parts.push_back(Primitive::UprightBox(c, 0.0, seat_z - 0.04, {leg_half, leg_half}, yaw, frame));
    inst.footprint_m.push_back(RectPolygon(c, leg_half, leg_half, yaw));
    if (sx < 0) {  // back posts carry the backrest
      inst.parts.push_back(Primitive::UprightBox(c, seat_z, ap.height_m, {leg_half, leg_half}, yaw, frame));
    }
  }
  const double back_bottom = seat_z + 0.5 * (ap.height_m - seat_z);
  inst.parts.push_back(
      Primitive::UprightBox(at(-(hd - inset), 0), back_bottom, ap.height_m, {0.015, hw - 0.01}, yaw, seat));
}

void AddRobot(const Appearance& ap, const PathSample& pose, ObjectInstance& inst) {
  const double r = 0.5 * ap.width_m, h = ap.height_m;
  const Eigen::Matrix2d rot = Yaw(pose.heading_rad).topLeftCorner<2, 2>();
  inst.parts.push_back(Primitive::VerticalCylinder(pose.position_m, r, 0.0, 0.8 * h, Plain(ap.top)));
  inst.parts.push_back(Primitive::VerticalCylinder(pose.position_m, 0.93 * r, 0.8 * h, h, Plain(ap.bottom)));
  // A bumper band and a sensor turret at the front.
  inst.parts.push_back(Primitive::VerticalCylinder(pose.position_m, r + 0.01, 0.03, 0.09, Plain(ap.bottom)));
  inst.parts.push_back(Primitive::VerticalCylinder(pose.position_m + rot * Eigen::Vector2d(0.5 * r, 0), 0.05, h,
                                                   h + 0.08, Plain({0.9f, 0.9f, 0.9f})));
  inst.footprint_m.push_back(CirclePolygon(pose.position_m, r - 1e-4));
}

void AddBox(const Appearance& ap, const PathSample& pose, ObjectInstance& inst) {
  Material m;
  m.colour = ap.top;
  m.pattern = Pattern::kNoise;
  m.variation = 0.06f;
  inst.parts.push_back(Primitive::UprightBox(pose.position_m, 0.0, ap.height_m, {0.5 * ap.width_m, 0.5 * ap.depth_m},
                                             pose.heading_rad, m));
  inst.footprint_m.push_back(RectPolygon(pose.position_m, 0.5 * ap.width_m, 0.5 * ap.depth_m, pose.heading_rad));
}

// Heading of each segment (waypoint k to k + 1): its direction when it moves enough, else
// the last moving one before it (segments before the first moving one take that one's).
std::vector<double> SegmentHeadings(const std::vector<Waypoint>& path) {
  const size_t n = path.size() < 2 ? 0 : path.size() - 1;
  std::vector<double> heading(n, 0.0);
  std::vector<bool> moving(n, false);
  std::optional<size_t> first_moving;
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d d = path[k + 1].position_m - path[k].position_m;
    const double dt = path[k + 1].t_s - path[k].t_s;
    if (!path[k + 1].gap_before && d.norm() >= kMinHeadingMove && d.norm() / dt >= kMinHeadingSpeed) {
      moving[k] = true;
      heading[k] = std::atan2(d.y(), d.x());
      if (!first_moving) first_moving = k;
    }
  }
  if (!first_moving) return heading;
  for (size_t k = 0; k < n; ++k) {
    if (k < *first_moving) heading[k] = heading[*first_moving];
    else if (!moving[k]) heading[k] = heading[k - 1];
  }
  return heading;
}

}  // namespace

const char* ToString(ObjectClass c) {
  switch (c) {
    case ObjectClass::kPerson: return "person";
    case ObjectClass::kChair: return "chair";
    case ObjectClass::kRobot: return "robot";
    case ObjectClass::kBox: return "box";
  }
  return "?";
}

Result<std::unique_ptr<CameraModel>> CameraSpec::Build() const {
  if (model == Model::kPinhole) {
    if (pinhole.forward_sign != 1) return InvalidInput("scene cameras look along +z (forward_sign +1)");
    OCCMAP_ASSIGN_OR_RETURN(PinholeCamera cam, PinholeCamera::Create(pinhole));
    return std::unique_ptr<CameraModel>(std::make_unique<PinholeCamera>(std::move(cam)));
  }
  OCCMAP_ASSIGN_OR_RETURN(TsaiCamera cam, TsaiCamera::Create(tsai));
  return std::unique_ptr<CameraModel>(std::make_unique<TsaiCamera>(std::move(cam)));
}

CameraSpec LookAtPinhole(std::string id, const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m,
                         ImageSize size, double focal_px, std::array<double, 5> distortion) {
  CameraSpec c;
  c.id = std::move(id);
  c.model = CameraSpec::Model::kPinhole;
  c.pinhole.image_size = size;
  c.pinhole.fx_px = c.pinhole.fy_px = focal_px;
  c.pinhole.cx_px = (size.width - 1) / 2.0;
  c.pinhole.cy_px = (size.height - 1) / 2.0;
  c.pinhole.distortion = distortion;
  c.pinhole.cam_from_world_rotation = LookAtRotation(position_m, target_m);
  c.pinhole.cam_from_world_translation_m = -c.pinhole.cam_from_world_rotation * position_m;
  return c;
}

CameraSpec LookAtTsai(std::string id, const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m,
                      ImageSize size, double f_mm, double cell_mm, double kappa1_per_mm2) {
  CameraSpec c;
  c.id = std::move(id);
  c.model = CameraSpec::Model::kTsai;
  TsaiParameters& p = c.tsai;
  p.image_size = size;
  p.Ncx = p.Nfx = size.width;
  p.dx_mm = p.dy_mm = cell_mm;
  p.sx = 1;
  p.Cx_px = (size.width - 1) / 2.0;
  p.Cy_px = (size.height - 1) / 2.0;
  p.f_mm = f_mm;
  p.kappa1_per_mm2 = kappa1_per_mm2;
  p.cam_from_world_rotation = LookAtRotation(position_m, target_m);
  p.cam_from_world_translation_m = -p.cam_from_world_rotation * position_m;
  return c;
}

Status SceneSpec::Validate() const {
  if (name.empty()) return InvalidInput("scene name: expected a non-empty name");
  if (!(fps > 0) || !std::isfinite(fps) || fps > 1000) return InvalidInput(fmt::format("fps: expected 0 < fps <= 1000, found {}", fps));
  if (num_frames < 1 || num_frames > 10'000'000) {
    return InvalidInput(fmt::format("frames: expected 1 .. 10000000, found {}", num_frames));
  }
  if (Status s = grid.Validate(); !s.ok()) return s.WithContext("floor grid");
  if (floor.empty()) return InvalidInput("floor: expected at least one floor piece");
  for (const FloorPatch& f : floor) {
    if (!(f.x_max_m > f.x_min_m) || !(f.y_max_m > f.y_min_m)) {
      return InvalidInput(fmt::format("floor piece [{}, {}] x [{}, {}]: expected min < max", f.x_min_m, f.x_max_m,
                                      f.y_min_m, f.y_max_m));
    }
  }
  // The floor pieces must cover the monitored area.
  for (int i = 0; i <= 10; ++i) {
    for (int j = 0; j <= 10; ++j) {
      const double x = grid.origin_x_m + grid.size_x_m() * (0.001 + 0.998 * i / 10.0);
      const double y = grid.origin_y_m + grid.size_y_m() * (0.001 + 0.998 * j / 10.0);
      const bool covered = std::any_of(floor.begin(), floor.end(), [&](const FloorPatch& f) {
        return x >= f.x_min_m && x < f.x_max_m && y >= f.y_min_m && y < f.y_max_m;
      });
      if (!covered) {
        return InvalidInput(fmt::format("floor: the floor pieces do not cover the monitored area at ({:.3f}, {:.3f})", x, y));
      }
    }
  }
  if (!room.outdoor) {
    if (!(room.x_max_m > room.x_min_m) || !(room.y_max_m > room.y_min_m) || !(room.height_m > 0)) {
      return InvalidInput("room: expected walls with min < max and a positive height");
    }
  }
  if (cameras.empty() || cameras.size() > 255) {
    return InvalidInput(fmt::format("cameras: expected 1 to 255 cameras, found {}", cameras.size()));
  }
  std::set<std::string> ids;
  for (const CameraSpec& c : cameras) {
    if (!ValidId(c.id)) {
      return InvalidInput(fmt::format("camera id '{}': expected letters, digits, '_', '-' or '.'", c.id));
    }
    if (!ids.insert(c.id).second) return InvalidInput(fmt::format("camera id '{}': duplicate", c.id));
    auto built = c.Build();
    if (!built.ok()) return built.status().WithContext(fmt::format("camera {}", c.id));
  }
  for (const StaticObjectSpec& s : statics) {
    if (!s.centre_m.allFinite() || !(s.size_m.minCoeff() > 0) || !(s.height_m > 0) || !std::isfinite(s.yaw_deg) ||
        !(s.base_m >= 0 && s.base_m < 100)) {
      return InvalidInput(fmt::format("static object '{}': expected positive sizes and finite values", s.name));
    }
  }
  std::set<int64_t> object_ids;
  for (const MovingObjectSpec& o : objects) {
    if (o.id < 1 || o.id > 65535) return InvalidInput(fmt::format("object id {}: expected 1 .. 65535", o.id));
    if (!object_ids.insert(o.id).second) return InvalidInput(fmt::format("object id {}: duplicate", o.id));
    const Appearance& a = o.appearance;
    if (!(a.height_m > 0.05 && a.height_m < 5) || !(a.width_m > 0.05 && a.width_m < 5) ||
        !(a.depth_m > 0.05 && a.depth_m < 5)) {
      return InvalidInput(fmt::format("object {}: expected sizes between 0.05 and 5 m", o.id));
    }
    if (o.object_class == ObjectClass::kChair && a.height_m < 0.5) {
      return InvalidInput(fmt::format("object {}: a chair is at least 0.5 m high (its seat is at 0.45 m)", o.id));
    }
    for (const auto* c : {&a.top, &a.bottom, &a.skin, &a.hair, &a.shoes}) {
      if (!FiniteColour(*c)) return InvalidInput(fmt::format("object {}: expected colours in 0..1", o.id));
    }
    if (o.path.empty()) return InvalidInput(fmt::format("object {}: expected a path of at least one waypoint", o.id));
    if (o.path.front().gap_before) return InvalidInput(fmt::format("object {}: the first waypoint cannot start a gap", o.id));
    for (size_t k = 0; k < o.path.size(); ++k) {
      const Waypoint& w = o.path[k];
      if (!std::isfinite(w.t_s) || !w.position_m.allFinite()) {
        return InvalidInput(fmt::format("object {}: waypoint {}: expected finite values", o.id, k));
      }
      if (k > 0 && !(w.t_s > o.path[k - 1].t_s)) {
        return InvalidInput(fmt::format("object {}: waypoint {}: expected times in increasing order, found {} after {}",
                                        o.id, k, w.t_s, o.path[k - 1].t_s));
      }
    }
  }
  const Lighting& l = photometry.lighting;
  if (!(l.ambient >= 0 && l.ambient <= 2) || !(l.intensity >= 0 && l.intensity <= 4) ||
      !(l.falloff_per_m2 >= 0 && l.falloff_per_m2 < 100)) {
    return InvalidInput("lighting: expected ambient 0..2, intensity 0..4, falloff >= 0");
  }
  if (l.kind == Lighting::Kind::kDirectional && !(std::abs(l.direction_to_light.norm() - 1) < 1e-6)) {
    return InvalidInput("lighting: expected a unit direction towards the light");
  }
  if (!l.position_m.allFinite()) return InvalidInput("lighting: expected a finite light position");
  for (const auto& [key, c] : {std::pair{"ambient_colour", &l.ambient_colour}, std::pair{"direct_colour", &l.direct_colour}}) {
    if (!(c->allFinite() && c->minCoeff() >= 0 && c->maxCoeff() <= 2)) {
      return InvalidInput(fmt::format("lighting: {}: expected values in 0..2, found [{}, {}, {}]", key, (*c)[0], (*c)[1], (*c)[2]));
    }
  }
  if (!(photometry.noise_sigma >= 0 && photometry.noise_sigma <= 50)) {
    return InvalidInput(fmt::format("noise_sigma: expected 0..50 grey levels, found {}", photometry.noise_sigma));
  }
  if (!(photometry.exposure_drift >= 0 && photometry.exposure_drift <= 0.5) || !(photometry.exposure_period_s > 0)) {
    return InvalidInput("exposure drift: expected an amplitude 0..0.5 and a positive period");
  }
  const ContactShadowSpec& cs = photometry.contact_shadows;
  if (!(cs.strength >= 0 && cs.strength <= 1) || !(cs.radius_m > 0 && cs.radius_m <= 2) ||
      !(cs.reach_m > cs.radius_m && cs.reach_m <= 10)) {
    return InvalidInput(fmt::format("contact_shadows: expected strength 0..1, radius_m 0..2 and radius_m < reach_m <= 10, "
                                    "found {}, {}, {}", cs.strength, cs.radius_m, cs.reach_m));
  }
  const CameraResponseSpec& cam = photometry.camera;
  if (!(cam.target_luma == 0 || (cam.target_luma >= 1 && cam.target_luma <= 254))) {
    return InvalidInput(fmt::format("camera: target_luma: expected 0 (the empty view's) or 1..254, found {}", cam.target_luma));
  }
  if (!(cam.max_gain >= 1 && cam.max_gain <= 64)) {
    return InvalidInput(fmt::format("camera: max_gain: expected 1..64, found {}", cam.max_gain));
  }
  if (!(cam.white_balance >= 0 && cam.white_balance <= 1)) {
    return InvalidInput(fmt::format("camera: white_balance: expected a strength 0..1, found {}", cam.white_balance));
  }
  if (!(cam.time_constant_s >= 0 && cam.time_constant_s <= 3600)) {
    return InvalidInput(fmt::format("camera: time_constant_s: expected 0..3600 s, found {}", cam.time_constant_s));
  }
  if (!(cam.read_noise >= 0 && cam.read_noise <= 50) || !(cam.shot_noise >= 0 && cam.shot_noise <= 10)) {
    return InvalidInput(fmt::format("camera: expected read_noise 0..50 and shot_noise 0..10, found {} and {}",
                                    cam.read_noise, cam.shot_noise));
  }
  if (cam.supersample < 1 || cam.supersample > 4) {
    return InvalidInput(fmt::format("camera: supersample: expected 1..4, found {}", cam.supersample));
  }
  if (cam.jpeg_quality < 0 || cam.jpeg_quality > 100) {
    return InvalidInput(fmt::format("camera: jpeg_quality: expected 0 (PNG) or 1..100, found {}", cam.jpeg_quality));
  }
  if (cam.video_crf < -1 || cam.video_crf > 51) {
    return InvalidInput(fmt::format("camera: video_crf: expected -1 (the writer's default) or 0..51, found {}", cam.video_crf));
  }
  return Status::Ok();
}

std::vector<Primitive> StaticPrimitives(const SceneSpec& spec) {
  std::vector<Primitive> prims;
  for (const FloorPatch& f : spec.floor) {
    Primitive p = Primitive::HorizontalRect(f.x_min_m, f.y_min_m, f.x_max_m, f.y_max_m, 0.0, +1, f.material);
    p.surface = Surface::kFloor;
    prims.push_back(p);
  }
  const RoomSpec& r = spec.room;
  if (!r.outdoor) {
    constexpr double kT = 0.2;  // wall thickness
    const double x0 = r.x_min_m, x1 = r.x_max_m, y0 = r.y_min_m, y1 = r.y_max_m, h = r.height_m;
    const Eigen::Vector2d cx(0.5 * (x0 + x1), 0.5 * (y0 + y1));
    const double hx = 0.5 * (x1 - x0) + kT, hy = 0.5 * (y1 - y0) + kT;
    prims.push_back(Primitive::UprightBox({cx.x(), y0 - 0.5 * kT}, -0.01, h + 0.01, {hx, 0.5 * kT}, 0, r.wall));
    prims.push_back(Primitive::UprightBox({cx.x(), y1 + 0.5 * kT}, -0.01, h + 0.01, {hx, 0.5 * kT}, 0, r.wall));
    prims.push_back(Primitive::UprightBox({x0 - 0.5 * kT, cx.y()}, -0.01, h + 0.01, {0.5 * kT, hy}, 0, r.wall));
    prims.push_back(Primitive::UprightBox({x1 + 0.5 * kT, cx.y()}, -0.01, h + 0.01, {0.5 * kT, hy}, 0, r.wall));
    prims.push_back(Primitive::HorizontalRect(x0 - kT, y0 - kT, x1 + kT, y1 + kT, h, -1, r.ceiling));
    // The floor under the walls' feet, so that no ray escapes between floor pieces and walls.
    Material under = r.wall;
    prims.push_back(Primitive::HorizontalRect(x0 - kT, y0 - kT, x1 + kT, y1 + kT, -0.005, +1, under));
  }
  const std::vector<Primitive> objects = StaticObjectPrimitives(spec);
  prims.insert(prims.end(), objects.begin(), objects.end());
  return prims;
}

std::vector<Primitive> StaticObjectPrimitives(const SceneSpec& spec) {
  std::vector<Primitive> prims;
  for (size_t i = 0; i < spec.statics.size(); ++i) {
    const StaticObjectSpec& s = spec.statics[i];
    const double yaw = s.yaw_deg * kPi / 180;
    switch (s.shape) {
      case StaticObjectSpec::Shape::kBox:
        prims.push_back(Primitive::UprightBox(s.centre_m, s.base_m, s.base_m + s.height_m, 0.5 * s.size_m, yaw, s.material));
        break;
      case StaticObjectSpec::Shape::kCylinder:
        prims.push_back(Primitive::VerticalCylinder(s.centre_m, 0.5 * s.size_m.x(), 0.0, s.height_m, s.material));
        break;
      case StaticObjectSpec::Shape::kPlanter: {
        const double rad = 0.5 * s.size_m.x();
        prims.push_back(Primitive::VerticalCylinder(s.centre_m, rad, 0.0, 0.4 * s.height_m, s.material));
        Material leaves;
        leaves.colour = {0.18f, 0.42f, 0.16f};
        leaves.pattern = Pattern::kNoise;
        leaves.variation = 0.35f;
        leaves.seed = static_cast<uint32_t>(Mix64(spec.seed ^ (0x1000 + i)));
        prims.push_back(Primitive::Ellipsoid({s.centre_m.x(), s.centre_m.y(), 0.7 * s.height_m}, Yaw(yaw),
                                             {1.4 * rad, 1.4 * rad, 0.3 * s.height_m}, leaves));
        break;
      }
    }
  }
  return prims;
}

Result<Scene> Scene::Create(SceneSpec spec) {
  OCCMAP_RETURN_IF_ERROR(spec.Validate());
  Scene scene;
  for (const CameraSpec& c : spec.cameras) {
    OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<CameraModel> cam, c.Build());
    scene.cameras_.push_back(std::shared_ptr<const CameraModel>(std::move(cam)));
  }
  scene.statics_ = StaticPrimitives(spec);
  scene.shadow_casters_ = StaticObjectPrimitives(spec);
  for (const MovingObjectSpec& o : spec.objects) scene.paths_.emplace_back(o.path);
  scene.spec_ = std::make_shared<const SceneSpec>(std::move(spec));
  return scene;
}

PreparedPath::PreparedPath(std::vector<Waypoint> waypoints) : path(std::move(waypoints)) {
  headings = SegmentHeadings(path);
  cumulative_m.assign(path.size(), 0.0);
  for (size_t k = 1; k < path.size(); ++k) {
    cumulative_m[k] = cumulative_m[k - 1] + (path[k].gap_before ? 0.0 : (path[k].position_m - path[k - 1].position_m).norm());
  }
}

PathSample PreparedPath::Sample(double t) const {
  PathSample out;
  if (path.empty() || t < path.front().t_s - kTimeEps || t > path.back().t_s + kTimeEps) return out;
  // The segment k with t_k <= t < t_{k+1} (k = the last waypoint at or before t).
  auto it = std::upper_bound(path.begin(), path.end(), t + kTimeEps, [](double v, const Waypoint& w) { return v < w.t_s; });
  size_t k = static_cast<size_t>(std::max<ptrdiff_t>(0, (it - path.begin()) - 1));
  const size_t n_seg = headings.size();
  if (k + 1 >= path.size() || std::abs(t - path[k].t_s) <= kTimeEps) {
    // On waypoint k.
    out.present = true;
    out.position_m = path[k].position_m;
    out.distance_m = cumulative_m[k];
    if (n_seg > 0) {
      const size_t in = k > 0 ? k - 1 : 0, outgoing = std::min(k, n_seg - 1);
      const bool blend = k > 0 && k < n_seg && !path[k].gap_before && !path[k + 1].gap_before;
      out.heading_rad = blend ? WrapAngle(headings[in] + 0.5 * WrapAngle(headings[outgoing] - headings[in]))
                              : (k < n_seg && !path[k + 1].gap_before ? headings[outgoing] : headings[in]);
    }
    if (k + 1 < path.size() && !path[k + 1].gap_before) {
      out.speed_m_s = (path[k + 1].position_m - path[k].position_m).norm() / (path[k + 1].t_s - path[k].t_s);
    }
    return out;
  }
  const Waypoint& w0 = path[k];
  const Waypoint& w1 = path[k + 1];
  if (w1.gap_before) return out;
  const double f = (t - w0.t_s) / (w1.t_s - w0.t_s);
  out.present = true;
  out.position_m = w0.position_m + f * (w1.position_m - w0.position_m);
  const double seg_len = (w1.position_m - w0.position_m).norm();
  out.distance_m = cumulative_m[k] + f * seg_len;
  out.speed_m_s = seg_len / (w1.t_s - w0.t_s);
  double heading = headings[k];
  // Blend with the previous segment near w0 and with the next one near w1.
  if (k > 0 && !w0.gap_before && t - w0.t_s < kHeadingBlendS) {
    const double u = 0.5 + 0.5 * (t - w0.t_s) / kHeadingBlendS;
    heading = headings[k - 1] + u * WrapAngle(headings[k] - headings[k - 1]);
  } else if (k + 1 < n_seg && !path[k + 2].gap_before && w1.t_s - t < kHeadingBlendS) {
    const double u = 0.5 - 0.5 * (w1.t_s - t) / kHeadingBlendS;
    heading = headings[k] + u * WrapAngle(headings[k + 1] - headings[k]);
  }
  out.heading_rad = WrapAngle(heading);
  return out;
}

PathSample SamplePath(const std::vector<Waypoint>& path, double time_s) { return PreparedPath(path).Sample(time_s); }

ObjectInstance MakeInstance(const MovingObjectSpec& object, const PathSample& pose) {
  ObjectInstance inst;
  inst.id = object.id;
  inst.object_class = object.object_class;
  inst.position_m = pose.position_m;
  inst.heading_rad = pose.heading_rad;
  switch (object.object_class) {
    case ObjectClass::kPerson: AddPerson(object.appearance, pose, inst); break;
    case ObjectClass::kChair: AddChair(object.appearance, pose, inst); break;
    case ObjectClass::kRobot: AddRobot(object.appearance, pose, inst); break;
    case ObjectClass::kBox: AddBox(object.appearance, pose, inst); break;
  }
  for (Primitive& p : inst.parts) p.surface = Surface::kDynamic;
  FinishBounds(inst);
  return inst;
}

std::optional<ObjectInstance> Scene::InstanceAt(size_t object_index, double time_s) const {
  const MovingObjectSpec& o = spec_->objects[object_index];
  const PathSample pose = paths_[object_index].Sample(time_s);
  if (!pose.present) return std::nullopt;
  return MakeInstance(o, pose);
}

SceneState Scene::StateAt(int64_t frame) const {
  SceneState state;
  state.frame = frame;
  state.time_s = TimeOf(frame);
  for (size_t i = 0; i < spec_->objects.size(); ++i) {
    if (auto inst = InstanceAt(i, state.time_s)) state.objects.push_back(std::move(*inst));
  }
  return state;
}

GroundTruthFrame ToGroundTruth(const SceneState& state) {
  GroundTruthFrame f;
  f.frame = state.frame;
  f.time_s = state.time_s;
  for (const ObjectInstance& inst : state.objects) {
    GroundTruthObject o;
    o.id = inst.id;
    o.object_class = ToString(inst.object_class);
    o.x_m = inst.position_m.x();
    o.y_m = inst.position_m.y();
    // One outline for several polygons: each polygon is walked from its first vertex and the
    // walk returns along the same bridges (zero area; even-odd and non-zero rules agree).
    const auto& polys = inst.footprint_m;
    for (size_t i = 0; i < polys.size(); ++i) {
      for (const auto& v : polys[i]) o.footprint_m.push_back(v);
      if (polys.size() > 1) o.footprint_m.push_back(polys[i].front());
    }
    for (size_t i = polys.size(); i-- > 1;) o.footprint_m.push_back(polys[i - 1].front());
    if (polys.size() > 1) o.footprint_m.pop_back();  // the outline closes on its first vertex
    f.objects.push_back(std::move(o));
  }
  return f;
}

Appearance RandomAppearance(ObjectClass c, uint64_t seed, uint64_t salt, const Eigen::Vector3f& floor_colour,
                            double floor_like_probability) {
  uint64_t state = Mix64(seed ^ Mix64(salt + 0x51ed));
  auto uniform = [&](double lo, double hi) {
    state = Mix64(state);
    return lo + (hi - lo) * UnitFromHash(state);
  };
  auto hsv = [&](double h, double s, double v) {
    const double c6 = h * 6;
    const int i = static_cast<int>(std::floor(c6)) % 6;
    const double f = c6 - std::floor(c6);
    const double p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    double r = v, g = t, b = p;
    switch (i) {
      case 0: r = v; g = t; b = p; break;
      case 1: r = q; g = v; b = p; break;
      case 2: r = p; g = v; b = t; break;
      case 3: r = p; g = q; b = v; break;
      case 4: r = t; g = p; b = v; break;
      default: r = v; g = p; b = q; break;
    }
    return Eigen::Vector3f(static_cast<float>(r), static_cast<float>(g), static_cast<float>(b));
  };
  auto near_floor = [&]() {
    Eigen::Vector3f col = floor_colour;
    for (int i = 0; i < 3; ++i) col[i] = static_cast<float>(std::clamp(col[i] * uniform(0.94, 1.06), 0.0, 1.0));
    return col;
  };
  Appearance a;
  const bool floor_like = uniform(0, 1) < floor_like_probability;
  switch (c) {
    case ObjectClass::kPerson: {
      a.height_m = uniform(1.58, 1.92);
      a.top = hsv(uniform(0, 1), uniform(0.15, 0.85), uniform(0.25, 0.95));
      if (floor_like) {
        a.bottom = near_floor();
      } else if (uniform(0, 1) < 0.5) {
        a.bottom = hsv(uniform(0.58, 0.66), uniform(0.3, 0.7), uniform(0.15, 0.45));  // jeans
      } else {
        a.bottom = hsv(uniform(0, 1), uniform(0.0, 0.5), uniform(0.1, 0.7));
      }
      static const Eigen::Vector3f kSkins[] = {{0.94f, 0.78f, 0.67f}, {0.85f, 0.64f, 0.5f}, {0.66f, 0.45f, 0.32f},
                                               {0.45f, 0.3f, 0.2f}, {0.3f, 0.2f, 0.14f}};
      static const Eigen::Vector3f kHair[] = {{0.08f, 0.06f, 0.05f}, {0.25f, 0.16f, 0.08f}, {0.6f, 0.48f, 0.3f},
                                              {0.55f, 0.55f, 0.55f}, {0.4f, 0.22f, 0.1f}};
      a.skin = kSkins[static_cast<int>(uniform(0, 4.999))];
      a.hair = kHair[static_cast<int>(uniform(0, 4.999))];
      a.shoes = uniform(0, 1) < 0.7 ? hsv(0, 0, uniform(0.05, 0.2)) : hsv(0, 0, uniform(0.75, 0.9));
      break;
    }
    case ObjectClass::kChair:
      a.height_m = uniform(0.85, 0.95);
      a.width_m = a.depth_m = uniform(0.42, 0.5);
      a.top = floor_like ? near_floor() : hsv(uniform(0, 1), uniform(0.2, 0.8), uniform(0.15, 0.6));
      a.bottom = hsv(0, 0, uniform(0.1, 0.3));
      break;
    case ObjectClass::kRobot:
      a.height_m = 0.38;
      a.width_m = a.depth_m = 0.44;
      a.top = hsv(0, 0, uniform(0.2, 0.85));
      a.bottom = hsv(0, 0, 0.08);
      break;
    case ObjectClass::kBox:
      a.height_m = uniform(0.3, 0.6);
      a.width_m = uniform(0.3, 0.6);
      a.depth_m = uniform(0.3, 0.6);
      a.top = floor_like ? near_floor() : hsv(uniform(0.07, 0.1), uniform(0.4, 0.6), uniform(0.55, 0.75));
      break;
  }
  return a;
}

}  // namespace occmap::sim
