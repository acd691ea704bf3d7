// The plaza: a sunny paved square outdoors (builtin_scenes.h), and the visitors' behaviour.
//
// Visitors come in parties: a crosser (enters beyond one edge of the area, walks across, leaves
// beyond another), a lone stander (walks to a free spot, stands 20-50 s, leaves) or a group of
// 2-3 (each member walks in from an edge of its own to a meeting point, they stand in a ring
// facing its centre and talk for 10-40 s after the last one has arrived, then leave together or
// each their own way). A new party arrives whenever fewer than `people` visitors are in the
// area or on their way into it; the story starts 90 s before frame 0 so that frame 0 already
// shows a plaza in use. Walks go around the static objects (detours past keep-out discs); people
// do not avoid each other. Everything is drawn from the seed (one SplitMix64 stream).
#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "occmap/sim/builtin_scenes.h"

namespace occmap::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kWidthM = 20.0, kDepthM = 14.0;  // the monitored area: [0, 20] x [0, 14] m
constexpr double kCellM = 0.05;
constexpr int kDefaultPeople = 16;
constexpr double kDefaultDurationS = 60.0;
constexpr double kDefaultSunElevationDeg = 25.0;
// The sun stands in the south-west (azimuth from +x, counter-clockwise): shadows fall to the
// north-east, diagonally across the square and away from the buildings on its north and east.
constexpr double kSunAzimuthDeg = 215.0;
constexpr double kWarmUpS = 90.0;

class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(Mix64(seed ^ 0x706c617a61ULL)) {}
  double Uniform(double lo, double hi) {
    state_ = Mix64(state_);
    return lo + (hi - lo) * UnitFromHash(state_);
  }
  int Int(int n) { return std::min(n - 1, static_cast<int>(Uniform(0, n))); }  // 0 .. n-1
  bool Chance(double p) { return Uniform(0, 1) < p; }

 private:
  uint64_t state_;
};

StaticObjectSpec Static(std::string name, StaticObjectSpec::Shape shape, Eigen::Vector2d centre, Eigen::Vector2d size,
                        double height_m, double yaw_deg, Material m, double base_m = 0) {
  StaticObjectSpec s;
  s.name = std::move(name);
  s.shape = shape;
  s.centre_m = centre;
  s.size_m = size;
  s.height_m = height_m;
  s.yaw_deg = yaw_deg;
  s.base_m = base_m;
  s.material = m;
  return s;
}

// A disc walkers keep out of (a static object plus clearance).
struct KeepOut {
  Eigen::Vector2d centre;
  double radius_m = 0;
};

// A walk from a to b around the keep-out discs it crosses: three points on an arc about each
// (at -60, 0, +60 degrees from the side the walk passes on, radius r / cos 30: the arc's chords
// touch the disc), the first disc along the walk first, recursively on both sides.
void Route(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const std::vector<KeepOut>& keep_out, int depth,
           std::vector<Eigen::Vector2d>& out) {
  const Eigen::Vector2d ab = b - a;
  const double len = ab.norm();
  const KeepOut* first = nullptr;
  double first_s = 1e300;
  if (len > 1e-9 && depth < 4) {
    for (const KeepOut& k : keep_out) {
      const double s = std::clamp((k.centre - a).dot(ab) / (len * len), 0.0, 1.0);
      if ((a + s * ab - k.centre).norm() < k.radius_m && s < first_s && (a - k.centre).norm() > k.radius_m &&
          (b - k.centre).norm() > k.radius_m) {
        first = &k;
        first_s = s;
      }
    }
  }
  if (first == nullptr) {
    out.push_back(b);
    return;
  }
  const Eigen::Vector2d t = ab / len;
  Eigen::Vector2d n(-t.y(), t.x());
  if ((a + first_s * ab - first->centre).dot(n) < 0) n = -n;
  const double r = first->radius_m / std::cos(kPi / 6);
  const double c = std::cos(kPi / 3), s = std::sin(kPi / 3);
  const Eigen::Vector2d p0 = first->centre + r * (c * n - s * t), p1 = first->centre + r * n,
                        p2 = first->centre + r * (c * n + s * t);
  Route(a, p0, keep_out, depth + 1, out);
  out.push_back(p1);
  out.push_back(p2);
  Route(p2, b, keep_out, depth + 1, out);
}

// Timed waypoints of a walk at a constant speed from `t0_s`; returns the arrival time.
double AppendWalk(std::vector<Waypoint>& path, double t0_s, const std::vector<Eigen::Vector2d>& points, double speed_m_s) {
  double t = t0_s;
  for (const Eigen::Vector2d& p : points) {
    if (!path.empty()) {
      const double d = (p - path.back().position_m).norm();
      if (d < 1e-6) continue;
      t = std::max(t, path.back().t_s) + d / speed_m_s;
    }
    path.push_back({t, p, false});
  }
  return t;
}

void Stay(std::vector<Waypoint>& path, double until_s) {
  if (until_s > path.back().t_s + 1e-6) path.push_back({until_s, path.back().position_m, false});
}

// A point beyond the area's edge (0 south, 1 east, 2 north, 3 west), 2-3.5 m out: visitors
// appear and vanish outside the monitored area, in the cameras' view.
Eigen::Vector2d EdgePoint(int edge, Rng& rng) {
  const double out = rng.Uniform(2.0, 3.5);
  switch (edge) {
    case 0: return {rng.Uniform(-1.0, kWidthM + 1.0), -out};
    case 1: return {kWidthM + out, rng.Uniform(-1.0, kDepthM + 1.0)};
    case 2: return {rng.Uniform(-1.0, kWidthM + 1.0), kDepthM + out};
    default: return {-out, rng.Uniform(-1.0, kDepthM + 1.0)};
  }
}

int OtherEdge(int edge, Rng& rng) {
  // Opposite half of the time, else a side.
  if (rng.Chance(0.5)) return (edge + 2) % 4;
  return (edge + (rng.Chance(0.5) ? 1 : 3)) % 4;
}

bool InsideArea(const Eigen::Vector2d& p) { return p.x() >= 0 && p.y() >= 0 && p.x() < kWidthM && p.y() < kDepthM; }

// An interior point at least `clearance_m` beyond every keep-out disc and from `avoid` points.
Eigen::Vector2d FreeSpot(Rng& rng, const std::vector<KeepOut>& keep_out, const std::vector<Eigen::Vector2d>& avoid,
                         double clearance_m) {
  Eigen::Vector2d p;
  for (int attempt = 0; attempt < 50; ++attempt) {
    p = {rng.Uniform(1.0, kWidthM - 1.0), rng.Uniform(1.0, kDepthM - 1.0)};
    const bool ok =
        std::none_of(keep_out.begin(), keep_out.end(),
                     [&](const KeepOut& k) { return (p - k.centre).norm() < k.radius_m + clearance_m; }) &&
        std::none_of(avoid.begin(), avoid.end(), [&](const Eigen::Vector2d& a) { return (p - a).norm() < 1.6; });
    if (ok) break;
  }
  return p;
}

struct Visitor {
  std::vector<Waypoint> path;
  double leaves_area_s = 0;  // when it has left the area for good (or ends its path)
};

// When a path is last inside the area (sampled every 0.1 s).
double LeavesAreaAt(const std::vector<Waypoint>& path) {
  const PreparedPath prepared(path);
  double last = path.front().t_s;
  for (double t = path.front().t_s; t <= path.back().t_s + 1e-9; t += 0.1) {
    const PathSample s = prepared.Sample(t);
    if (s.present && InsideArea(s.position_m)) last = t;
  }
  return last + 0.1;
}

class PlazaCrowd {
 public:
  PlazaCrowd(uint64_t seed, std::vector<KeepOut> keep_out, std::vector<Eigen::Vector2d> meeting_points)
      : rng_(seed), keep_out_(std::move(keep_out)), meeting_points_(std::move(meeting_points)),
        meeting_busy_until_s_(meeting_points_.size(), -1e300) {}

  // Parties arrive from -kWarmUpS until end_s, whenever fewer than `people` visitors are in the
  // area or walking towards it.
  std::vector<Visitor> Generate(int people, double end_s) {
    for (double t = -kWarmUpS; t < end_s; t += rng_.Uniform(0.3, 1.5)) {
      const int present = static_cast<int>(std::count_if(visitors_.begin(), visitors_.end(), [&](const Visitor& v) {
        return v.path.front().t_s <= t && t < v.leaves_area_s;
      }));
      if (present >= people) continue;
      const double kind = rng_.Uniform(0, 1);
      if (kind < 0.35 && people - present >= 2 && Group(t, people - present >= 3 && rng_.Chance(0.4) ? 3 : 2)) continue;
      if (kind < 0.35 + 0.2) {
        Stander(t);
      } else {
        Crosser(t);
      }
    }
    return std::move(visitors_);
  }

 private:
  std::vector<Eigen::Vector2d> Walk(const Eigen::Vector2d& from, const Eigen::Vector2d& to) {
    std::vector<Eigen::Vector2d> points{from};
    Route(from, to, keep_out_, 0, points);
    return points;
  }

  void Add(std::vector<Waypoint> path) {
    Visitor v;
    v.path = std::move(path);
    v.leaves_area_s = LeavesAreaAt(v.path);
    visitors_.push_back(std::move(v));
  }

  void Crosser(double t0) {
    const int edge = rng_.Int(4);
    const Eigen::Vector2d start = EdgePoint(edge, rng_), end = EdgePoint(OtherEdge(edge, rng_), rng_);
    std::vector<Eigen::Vector2d> points = Walk(start, end);
    if (rng_.Chance(0.5)) {  // a bend through an interior point
      const Eigen::Vector2d via = FreeSpot(rng_, keep_out_, {}, 0.3);
      points = Walk(start, via);
      const std::vector<Eigen::Vector2d> rest = Walk(via, end);
      points.insert(points.end(), rest.begin() + 1, rest.end());
    }
    std::vector<Waypoint> path;
    AppendWalk(path, t0, points, rng_.Uniform(1.05, 1.5));
    Add(std::move(path));
  }

  void Stander(double t0) {
    const Eigen::Vector2d start = EdgePoint(rng_.Int(4), rng_);
    const Eigen::Vector2d spot = FreeSpot(rng_, keep_out_, meeting_points_, 0.8);
    const double speed = rng_.Uniform(0.9, 1.35);
    std::vector<Waypoint> path;
    const double arrive = AppendWalk(path, t0, Walk(start, spot), speed);
    Stay(path, arrive + rng_.Uniform(20, 50));
    AppendWalk(path, path.back().t_s, Walk(spot, EdgePoint(rng_.Int(4), rng_)), speed);
    Add(std::move(path));
  }

  // False when every meeting point is taken.
  bool Group(double t0, int size) {
    std::vector<size_t> free;
    for (size_t m = 0; m < meeting_points_.size(); ++m) {
      if (meeting_busy_until_s_[m] < t0) free.push_back(m);
    }
    if (free.empty()) return false;
    const size_t m = free[static_cast<size_t>(rng_.Int(static_cast<int>(free.size())))];
    const Eigen::Vector2d centre = meeting_points_[m];
    const double ring_m = size == 2 ? 0.42 : 0.52;
    const double angle0 = rng_.Uniform(0, 2 * kPi);
    std::vector<std::vector<Waypoint>> paths(static_cast<size_t>(size));
    std::vector<Eigen::Vector2d> slots;
    double last_arrival = t0;
    for (int j = 0; j < size; ++j) {
      const double a = angle0 + 2 * kPi * j / size + rng_.Uniform(-0.25, 0.25);
      const Eigen::Vector2d radial(std::cos(a), std::sin(a));
      const Eigen::Vector2d slot = centre + ring_m * radial;
      slots.push_back(slot);
      // The last step goes towards the centre: standing, they face each other.
      std::vector<Eigen::Vector2d> points = Walk(EdgePoint(rng_.Int(4), rng_), slot + 0.35 * radial);
      points.push_back(slot);
      const double arrival = AppendWalk(paths[static_cast<size_t>(j)], t0 + rng_.Uniform(0, 5), points,
                                        rng_.Uniform(1.0, 1.4));
      last_arrival = std::max(last_arrival, arrival);
    }
    const double talk_end = last_arrival + rng_.Uniform(10, 40);
    meeting_busy_until_s_[m] = talk_end + 4;
    const bool together = rng_.Chance(0.6);
    const int exit_edge = rng_.Int(4);
    const Eigen::Vector2d exit = EdgePoint(exit_edge, rng_);
    const double together_speed = rng_.Uniform(1.0, 1.3);
    for (int j = 0; j < size; ++j) {
      std::vector<Waypoint>& path = paths[static_cast<size_t>(j)];
      Stay(path, talk_end + rng_.Uniform(0, together ? 1.0 : 4.0));
      const Eigen::Vector2d slot = slots[static_cast<size_t>(j)];
      if (together) {
        // Side by side: exits 0.7 m apart along the edge.
        const Eigen::Vector2d along = exit_edge % 2 == 0 ? Eigen::Vector2d(1, 0) : Eigen::Vector2d(0, 1);
        AppendWalk(path, path.back().t_s, Walk(slot, exit + 0.7 * (j - 0.5 * (size - 1)) * along), together_speed);
      } else {
        AppendWalk(path, path.back().t_s, Walk(slot, EdgePoint(rng_.Int(4), rng_)), rng_.Uniform(1.0, 1.4));
      }
      Add(std::move(path));
    }
    return true;
  }

  Rng rng_;
  std::vector<KeepOut> keep_out_;
  std::vector<Eigen::Vector2d> meeting_points_;
  std::vector<double> meeting_busy_until_s_;
  std::vector<Visitor> visitors_;
};

}  // namespace

SceneSpec MakePlazaSceneSpec(const BuiltinSceneOptions& options) {
  OCCMAP_CHECK(options.Validate().ok(), "plaza scene options");
  const int people = options.people > 0 ? options.people : kDefaultPeople;
  const double duration_s = options.duration_s > 0 ? options.duration_s : kDefaultDurationS;
  const double sun_deg = options.sun_elevation_deg > 0 ? options.sun_elevation_deg : kDefaultSunElevationDeg;
  SceneSpec spec;
  spec.name = "plaza";
  spec.seed = options.seed;
  spec.fps = 10;
  spec.num_frames = std::max<int64_t>(1, std::llround(duration_s * spec.fps));
  const std::string sky =
      options.overcast ? std::string("an overcast sky (soft contact shadows around the visitors' feet), exposure drift")
                       : fmt::format("a low sun ({} degrees, from the south-west) casting long shadows, bluish sky light "
                                     "in them, exposure drift",
                                     sun_deg);
  spec.description = fmt::format(
      "A {} paved square outdoors, 20 x 14 m monitored: six 1280x720 cameras on poles at 2.6-3.5 m around it "
      "looking across (mild barrel distortion); three pillars, three planters, a kiosk and three benches inside; "
      "{}; {} people at a time crossing, meeting in groups of 2-3 and standing alone.",
      options.overcast ? "grey" : "sunny", sky, people);
  spec.grid = FloorGrid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = static_cast<int>(std::lround(kWidthM / kCellM)),
                        .cells_y = static_cast<int>(std::lround(kDepthM / kCellM)), .cell_size_m = kCellM};
  const uint32_t s32 = static_cast<uint32_t>(Mix64(spec.seed ^ 0x91a2a));
  // Stone slabs of 60 cm with dark joints, each slab its own shade; asphalt around.
  const Eigen::Vector3f paving(0.6f, 0.57f, 0.52f);
  spec.floor.push_back({-1, -1, kWidthM + 1, kDepthM + 1,
                        MakeMaterial(paving, Pattern::kTiles, 0.2f, {0.36f, 0.34f, 0.31f}, 0.6f, s32)});
  const Material asphalt = MakeMaterial({0.3f, 0.3f, 0.31f}, Pattern::kCarpet, 0.2f, {0.3f, 0.3f, 0.3f}, 0.5f, s32 + 1);
  constexpr double kFar = 120;
  spec.floor.push_back({-kFar, -kFar, kWidthM + kFar, -1, asphalt});
  spec.floor.push_back({-kFar, kDepthM + 1, kWidthM + kFar, kDepthM + kFar, asphalt});
  spec.floor.push_back({-kFar, -1, -1, kDepthM + 1, asphalt});
  spec.floor.push_back({kWidthM + 1, -1, kWidthM + kFar, kDepthM + 1, asphalt});
  spec.room.outdoor = true;

  using Shape = StaticObjectSpec::Shape;
  const Material stone = MakeMaterial({0.78f, 0.75f, 0.68f}, Pattern::kNoise, 0.06f, {0.3f, 0.3f, 0.3f}, 0.5f, s32 + 2);
  const Material kiosk = MakeMaterial({0.56f, 0.2f, 0.14f}, Pattern::kNoise, 0.05f, {0.3f, 0.3f, 0.3f}, 0.5f, s32 + 3);
  const Material roof = MakeMaterial({0.22f, 0.24f, 0.26f}, Pattern::kNoise, 0.04f, {0.3f, 0.3f, 0.3f}, 0.5f, s32 + 4);
  const Material wood = MakeMaterial({0.5f, 0.36f, 0.22f}, Pattern::kNoise, 0.08f, {0.3f, 0.3f, 0.3f}, 0.5f, s32 + 5);
  const Material pot = MakeMaterial({0.42f, 0.43f, 0.45f}, Pattern::kNoise, 0.05f, {0.3f, 0.3f, 0.3f}, 0.5f, s32 + 6);
  const Material metal = MakeMaterial({0.25f, 0.27f, 0.28f}, Pattern::kPlain, 0.0f, {0.3f, 0.3f, 0.3f}, 0.5f, 0);
  const Material facade = MakeMaterial({0.72f, 0.66f, 0.58f}, Pattern::kNoise, 0.08f, {0.3f, 0.3f, 0.3f}, 0.5f, s32 + 7);
  const Material facade2 = MakeMaterial({0.62f, 0.64f, 0.66f}, Pattern::kNoise, 0.08f, {0.3f, 0.3f, 0.3f}, 0.5f, s32 + 8);
  spec.statics.push_back(Static("kiosk", Shape::kBox, {11.5, 7.8}, {2.0, 1.5}, 2.5, 12, kiosk));
  spec.statics.push_back(Static("kiosk roof", Shape::kBox, {11.5, 7.8}, {2.5, 2.0}, 0.15, 12, roof, 2.5));
  spec.statics.push_back(Static("pillar west", Shape::kCylinder, {4.5, 4.0}, {0.55, 0.55}, 4.2, 0, stone));
  spec.statics.push_back(Static("pillar north", Shape::kCylinder, {6.0, 10.8}, {0.5, 0.5}, 4.2, 0, stone));
  spec.statics.push_back(Static("pillar east", Shape::kCylinder, {15.5, 10.5}, {0.55, 0.55}, 4.2, 0, stone));
  spec.statics.push_back(Static("planter south-east", Shape::kPlanter, {16.5, 3.8}, {1.3, 1.3}, 1.1, 0, pot));
  spec.statics.push_back(Static("planter south", Shape::kPlanter, {8.5, 3.0}, {1.1, 1.1}, 1.0, 0, pot));
  spec.statics.push_back(Static("planter west", Shape::kPlanter, {2.8, 8.2}, {1.2, 1.2}, 1.2, 0, pot));
  spec.statics.push_back(Static("bench south", Shape::kBox, {13.5, 3.2}, {1.8, 0.5}, 0.45, 0, wood));
  spec.statics.push_back(Static("bench north", Shape::kBox, {8.0, 12.2}, {1.8, 0.5}, 0.45, 0, wood));
  spec.statics.push_back(Static("bench east", Shape::kBox, {17.8, 7.5}, {1.8, 0.5}, 0.45, 90, wood));
  // Buildings on the north and east sides only: the sun (south-west) leaves their shadows off
  // the square at any elevation.
  spec.statics.push_back(Static("building north", Shape::kBox, {10, 31}, {70, 10}, 15, 0, facade));
  spec.statics.push_back(Static("building east", Shape::kBox, {37, 7}, {10, 38}, 12, 0, facade2));

  struct Mount {
    const char* id;
    Eigen::Vector3d at_m;
    Eigen::Vector3d target_m;
    double focal_px;
  };
  const Mount mounts[] = {
      {"c1", {-0.8, -0.8, 3.2}, {10.5, 7.5, 0}, 560},  {"c2", {10.0, -1.0, 3.5}, {10.0, 8.0, 0}, 640},
      {"c3", {20.8, -0.8, 2.8}, {9.5, 7.5, 0}, 560},   {"c4", {20.8, 14.8, 3.0}, {9.5, 6.5, 0}, 560},
      {"c5", {10.0, 15.0, 2.6}, {10.0, 6.0, 0}, 640},  {"c6", {-0.8, 14.8, 3.4}, {10.5, 6.5, 0}, 560},
  };
  for (const Mount& m : mounts) {
    spec.cameras.push_back(LookAtPinhole(m.id, m.at_m, m.target_m, {1280, 720}, m.focal_px, {-0.06, 0.01, 0, 0, 0}));
    spec.statics.push_back(Static(fmt::format("pole {}", m.id), Shape::kCylinder, m.at_m.head<2>(), {0.14, 0.14},
                                  m.at_m.z() - 0.12, 0, metal));
  }

  // A low sun: the light on the ground twice (2.2 times) the sky's, and the two together give
  // the sunlit paving 0.85 of its albedo whatever the elevation (as a camera's exposure would),
  // up to the intensity's limit of 4 (below about 8 degrees the shadows are lighter).
  Lighting& light = spec.photometry.lighting;
  const double el = sun_deg * kPi / 180, az = kSunAzimuthDeg * kPi / 180;
  light.kind = Lighting::Kind::kDirectional;
  light.direction_to_light = Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  light.ambient = 0.85 / 3.2;
  light.intensity = std::min(4.0, 2.2 * light.ambient / std::sin(el));
  light.ambient_colour = {0.84f, 0.93f, 1.14f};  // sky
  light.direct_colour = {1.07f, 1.0f, 0.9f};     // sun
  spec.photometry.shadows = true;
  spec.photometry.exposure_drift = 0.1;
  spec.photometry.noise_sigma = 2;
  if (options.overcast) {
    // A bright overcast: the sky alone lights the paving as the sun and sky did (0.85 of its
    // albedo), faintly blue; no cast shadows, only the sky each visitor hides near their feet.
    light.intensity = 0;
    light.ambient = 0.85;
    light.ambient_colour = {0.96f, 1.0f, 1.06f};
    spec.photometry.shadows = false;
    PhotometrySpec preset;
    ApplyRealCameraPreset(preset);
    spec.photometry.contact_shadows = preset.contact_shadows;
  }

  std::vector<KeepOut> keep_out;
  for (const StaticObjectSpec& s : spec.statics) {
    const double r = s.shape == Shape::kBox ? 0.5 * s.size_m.norm() : 0.5 * s.size_m.x();
    if (r < 5) keep_out.push_back({s.centre_m, r + 0.35});
  }
  const std::vector<Eigen::Vector2d> meeting_points = {{7.5, 6.5},  {14.5, 6.0}, {10.0, 10.5}, {4.0, 12.0},
                                                       {17.0, 12.2}, {3.3, 2.3},  {11.0, 2.0},  {18.2, 1.8}};
  const double story_end_s = std::max(duration_s, static_cast<double>(options.num_frames) / spec.fps);
  PlazaCrowd crowd(spec.seed, keep_out, meeting_points);
  int64_t id = 0;
  for (Visitor& v : crowd.Generate(people, story_end_s)) {
    if (v.path.back().t_s < 0 || v.path.front().t_s > story_end_s) continue;
    MovingObjectSpec o;
    o.id = ++id;
    o.object_class = ObjectClass::kPerson;
    o.appearance = RandomAppearance(ObjectClass::kPerson, spec.seed, static_cast<uint64_t>(o.id), paving, 0.2);
    o.path = std::move(v.path);
    spec.objects.push_back(std::move(o));
  }

  BuiltinSceneOptions rest = options;
  rest.people = -1;
  rest.duration_s = -1;
  rest.sun_elevation_deg = -1;
  rest.overcast = false;
  OCCMAP_CHECK(ApplyBuiltinOptions(rest, spec).ok(), "plaza scene options");
  return spec;
}

}  // namespace occmap::sim
