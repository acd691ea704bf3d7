#include "occmap/sim/renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>

namespace occmap::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Acklam's rational approximation of the inverse normal CDF (relative error < 1.2e-9).
double InverseNormalCdf(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                                 1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                                 6.680131188771972e+01,  -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                                 -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                                 3.754408661907416e+00};
  constexpr double kLow = 0.02425;
  if (p < kLow) {
    const double q = std::sqrt(-2 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  if (p > 1 - kLow) return -InverseNormalCdf(1 - p);
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}

// Standard normal quantiles of the 65536 equiprobable bins' centres.
const std::array<float, 65536>& GaussianTable() {
  static const std::array<float, 65536> table = [] {
    std::array<float, 65536> t{};
    for (size_t i = 0; i < t.size(); ++i) t[i] = static_cast<float>(InverseNormalCdf((static_cast<double>(i) + 0.5) / 65536.0));
    return t;
  }();
  return table;
}

uint64_t NoiseStream(uint64_t seed, size_t camera, int64_t frame) {
  return Mix64(Mix64(seed ^ 0x6e6f697365ULL) ^ Mix64((static_cast<uint64_t>(camera) << 40) ^ static_cast<uint64_t>(frame)));
}

struct StaticHit {
  double t = kInf;
  const Primitive* prim = nullptr;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
};

StaticHit TraceStatic(const std::vector<Primitive>& prims, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  StaticHit best;
  for (const Primitive& p : prims) {
    if (auto hit = IntersectRay(p, o, d, best.t)) {
      best.t = hit->t;
      best.prim = &p;
      best.normal = hit->normal_in_world;
    }
  }
  return best;
}

bool InsideGrid(const FloorGrid& g, const Eigen::Vector3d& p) {
  return p.x() >= g.origin_x_m && p.y() >= g.origin_y_m && p.x() < g.origin_x_m + g.size_x_m() &&
         p.y() < g.origin_y_m + g.size_y_m();
}

// Whether the floor point p is in the shadow of the object (towards the light).
bool Shadowed(const ObjectInstance& obj, const Lighting& light, const Eigen::Vector3d& p) {
  Eigen::Vector3d to_light;
  double intensity = 0, dist = 0;
  light.DirectAt(p, &to_light, &intensity, &dist);
  // Cull: the distance from the bounding sphere's centre to the shadow ray.
  const Eigen::Vector3d v = obj.sphere_centre_m - p;
  const double along = v.dot(to_light);
  if (along < -obj.sphere_radius_m || along > dist + obj.sphere_radius_m) return false;
  if ((v - along * to_light).squaredNorm() > obj.sphere_radius_m * obj.sphere_radius_m) return false;
  for (const Primitive& part : obj.parts) {
    if (IntersectRay(part, p, to_light, dist)) return true;
  }
  return false;
}

// Whether a static object lies between the surface point p (outward normal n) and the light.
bool StaticallyShadowed(const std::vector<Primitive>& casters, const Lighting& light, const Eigen::Vector3d& p,
                        const Eigen::Vector3d& normal) {
  Eigen::Vector3d to_light;
  double intensity = 0, dist = 0;
  light.DirectAt(p, &to_light, &intensity, &dist);
  // From just off the surface: a solid's lit face must not shade itself through rounding.
  const Eigen::Vector3d from = p + 1e-6 * normal;
  for (const Primitive& c : casters) {
    if (IntersectRay(c, from, to_light, dist)) return true;
  }
  return false;
}

double PointSegmentDistance2(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double s = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + s * ab - p).squaredNorm();
}

double PointBoxDistance2(const Eigen::Vector2d& p, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
  return (p - p.cwiseMax(lo).cwiseMin(hi)).squaredNorm();
}

// Whether the segment a-b crosses the box (Liang-Barsky clipping).
bool SegmentMeetsBox(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& lo,
                     const Eigen::Vector2d& hi) {
  double t0 = 0, t1 = 1;
  const Eigen::Vector2d d = b - a;
  for (int k = 0; k < 2; ++k) {
    if (std::abs(d[k]) < 1e-15) {
      if (a[k] < lo[k] || a[k] > hi[k]) return false;
      continue;
    }
    double ta = (lo[k] - a[k]) / d[k], tb = (hi[k] - a[k]) / d[k];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

// Where an object's shadow can fall on the floor.
//  Directional light: the shadow of the object's bounding cylinder, which is exactly the floor
//  points within the cylinder's radius of the segment s0-s1 (its axis projected along the light
//  onto the floor): a stadium. Tight around a standing person (its shadow at 25 degrees is
//  4 m long and 0.5 m wide; the bounding sphere's would be 4.6 x 2 m).
//  Point light above the object: a box, the central projection of the bounding sphere's box
//  from the light (the convex hull of its corners' projections); the sphere test then per point.
//  Otherwise (a light below the object's top, or the sun at the horizon): anywhere.
struct ShadowRegion {
  enum class Kind { kStadium, kBox, kAnywhere };
  Kind kind = Kind::kAnywhere;
  Eigen::Vector2d s0 = Eigen::Vector2d::Zero(), s1 = Eigen::Vector2d::Zero();
  double radius_m = 0;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(-kInf), hi = Eigen::Vector2d::Constant(kInf);

  bool MayMeet(const Eigen::Vector2d& box_lo, const Eigen::Vector2d& box_hi) const {
    if (!(box_lo.x() <= box_hi.x())) return false;  // no lit floor in the tile
    if (!(lo.x() <= box_hi.x() && box_lo.x() <= hi.x() && lo.y() <= box_hi.y() && box_lo.y() <= hi.y())) return false;
    if (kind != Kind::kStadium || SegmentMeetsBox(s0, s1, box_lo, box_hi)) return true;
    // Disjoint convex shapes are nearest at a vertex of one of them.
    const double r2 = radius_m * radius_m;
    if (PointBoxDistance2(s0, box_lo, box_hi) <= r2 || PointBoxDistance2(s1, box_lo, box_hi) <= r2) return true;
    for (const Eigen::Vector2d& c : {box_lo, box_hi, Eigen::Vector2d(box_lo.x(), box_hi.y()),
                                     Eigen::Vector2d(box_hi.x(), box_lo.y())}) {
      if (PointSegmentDistance2(c, s0, s1) <= r2) return true;
    }
    return false;
  }
};

ShadowRegion ShadowRegionOf(const ObjectInstance& obj, const Lighting& light) {
  ShadowRegion region;
  if (light.kind == Lighting::Kind::kDirectional) {
    const Eigen::Vector3d& l = light.direction_to_light;
    if (!(l.z() > 1e-9)) return region;
    const CylinderBound& b = obj.bound;
    const Eigen::Vector2d shift = l.head<2>() / l.z();  // floor offset per metre of height
    region.kind = ShadowRegion::Kind::kStadium;
    region.s0 = b.centre_xy_m - std::max(0.0, b.z_min_m) * shift;
    region.s1 = b.centre_xy_m - std::max(0.0, b.z_max_m) * shift;
    region.radius_m = b.radius_m + 1e-6;
    region.lo = region.s0.cwiseMin(region.s1) - Eigen::Vector2d::Constant(region.radius_m);
    region.hi = region.s0.cwiseMax(region.s1) + Eigen::Vector2d::Constant(region.radius_m);
    return region;
  }
  const Eigen::Vector3d& c = obj.sphere_centre_m;
  const double r = obj.sphere_radius_m;
  const Eigen::Vector3d& q = light.position_m;
  if (!(q.z() > c.z() + r + 1e-6)) return region;
  region.kind = ShadowRegion::Kind::kBox;
  region.lo = Eigen::Vector2d::Constant(kInf);
  region.hi = Eigen::Vector2d::Constant(-kInf);
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d corner = c + r * Eigen::Vector3d(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1);
    const Eigen::Vector2d p = q.head<2>() + (corner - q).head<2>() * (q.z() / (q.z() - corner.z()));
    region.lo = region.lo.cwiseMin(p);
    region.hi = region.hi.cwiseMax(p);
  }
  region.lo -= Eigen::Vector2d::Constant(1e-6);
  region.hi += Eigen::Vector2d::Constant(1e-6);
  return region;
}

// Whether the floor point p is in the object's shadow, the region test first.
bool ShadowedIn(const ObjectInstance& obj, const ShadowRegion& region, const Lighting& light, const Eigen::Vector3d& p) {
  if (region.kind != ShadowRegion::Kind::kStadium) return Shadowed(obj, light, p);
  if (PointSegmentDistance2(p.head<2>(), region.s0, region.s1) > region.radius_m * region.radius_m) return false;
  for (const Primitive& part : obj.parts) {
    if (IntersectRay(part, p, light.direction_to_light, kInf)) return true;
  }
  return false;
}

// The fraction S(d) of the sky light an upright occluder hides at a horizontal distance d from
// its axis, scaled to 1 at its side, tapered to 0 at the reach (scene.h ContactShadowSpec).
double ContactShadowShape(double d, double radius_m, double height_m, double reach_m) {
  if (!(d < reach_m)) return 0;
  double s = 1;
  if (d > radius_m) {
    const double h2 = height_m * height_m;
    s = std::asin(radius_m / d) / (0.5 * std::numbers::pi) * (h2 / (h2 + d * d)) * ((h2 + radius_m * radius_m) / h2);
  }
  const double taper_from = 0.7 * reach_m;
  if (d > taper_from) {
    const double u = (d - taper_from) / (reach_m - taper_from);
    s *= 1 - u * u * (3 - 2 * u);
  }
  return s;
}

// An object as the sky's occluder of the floor around it.
struct ContactOccluder {
  Eigen::Vector2d centre_m = Eigen::Vector2d::Zero();
  double radius_m = 0, height_m = 0;
};

// A contact shadow's darkening is marked in the shadow mask from this fraction of the pixel's
// radiance on: about the change a detector's threshold could see, not the faint halo.
constexpr float kContactShadowMaskFraction = 1.0f / 16.0f;

}  // namespace

Eigen::Vector3f MissRadiance(const SceneSpec& spec, const Eigen::Vector3d& d) {
  if (!spec.room.outdoor) return Eigen::Vector3f::Zero();
  const float up = static_cast<float>(std::clamp(d.z(), 0.0, 1.0));
  return spec.room.sky_colour * (0.85f + 0.3f * up);
}

Image<uint8_t> ChangeMask(const Image<uint16_t>& ids) {
  Image<uint8_t> mask(ids.width(), ids.height());
  for (int y = 0; y < ids.height(); ++y) {
    const uint16_t* in = ids.row(y);
    uint8_t* out = mask.row(y);
    for (int x = 0; x < ids.width(); ++x) out[x] = in[x] != 0 ? 255 : 0;
  }
  return mask;
}

CameraRenderer::CameraRenderer(const Scene& scene, size_t camera_index, Context& ctx)
    : scene_(scene), camera_index_(camera_index) {
  OCCMAP_CHECK(camera_index < scene.num_cameras(), "camera index out of range");
  const SceneSpec& spec = scene_.spec();
  const CameraModel& scene_camera = scene_.camera(camera_index);
  size_ = scene_camera.image_size();
  supersample_ = spec.photometry.camera.supersample;
  std::unique_ptr<CameraModel> resized;
  if (supersample_ > 1) resized = scene_camera.Resized({size_.width * supersample_, size_.height * supersample_});
  const CameraModel& cam = resized ? *resized : scene_camera;
  render_size_ = cam.image_size();
  origin_ = *cam.CenterInWorld();
  const size_t n = static_cast<size_t>(render_size_.width) * static_cast<size_t>(render_size_.height);
  dir_.assign(n, Eigen::Vector3d::Zero());
  has_ray_.assign(n, 0);
  static_t_.assign(n, kInf);
  static_surface_.assign(n, 0);
  bg_.assign(n, Eigen::Vector3f::Zero());
  const bool shadows = spec.photometry.shadows;
  const bool contact = spec.photometry.contact_shadows.enabled();
  if (shadows) direct_.assign(n, Eigen::Vector3f::Zero());
  if (contact) ambient_.assign(n, Eigen::Vector3f::Zero());
  floor_mask_ = Image<uint8_t>(render_size_.width, render_size_.height, 0);
  const std::vector<Primitive>& statics = scene_.static_primitives();
  const std::vector<Primitive>& casters = scene_.shadow_casters();
  ParallelFor(ctx, 0, render_size_.height, [&](int64_t y0, int64_t y1, int) {
    for (int y = static_cast<int>(y0); y < y1; ++y) {
      for (int x = 0; x < render_size_.width; ++x) {
        const size_t i = Index(x, y);
        const std::optional<Ray> ray = cam.BackProject(Eigen::Vector2d(x, y));
        if (!ray) continue;
        has_ray_[i] = 1;
        dir_[i] = ray->direction_in_world;
        const StaticHit hit = TraceStatic(statics, origin_, dir_[i]);
        if (hit.prim == nullptr) {
          bg_[i] = MissRadiance(spec, dir_[i]);
          continue;
        }
        static_t_[i] = hit.t;
        const Eigen::Vector3d p = origin_ + hit.t * dir_[i];
        const bool floor = hit.prim->surface == Surface::kFloor;
        static_surface_[i] = floor ? 1 : 2;
        Eigen::Vector3f direct;
        bg_[i] = Shade(hit.prim->material, p, hit.normal, spec.photometry.lighting, &direct);
        if (contact && floor) ambient_[i] = bg_[i] - direct;
        if (shadows && direct != Eigen::Vector3f::Zero() &&
            StaticallyShadowed(casters, spec.photometry.lighting, p, hit.normal)) {
          bg_[i] -= direct;
          direct.setZero();
        }
        if (shadows) direct_[i] = direct;
        if (floor && InsideGrid(scene_.grid(), p)) floor_mask_(x, y) = 255;
      }
    }
  });
  // Tile cones: the mean direction and the largest angle to it.
  tiles_x_ = (render_size_.width + kTilePx - 1) / kTilePx;
  tiles_y_ = (render_size_.height + kTilePx - 1) / kTilePx;
  tiles_.assign(static_cast<size_t>(tiles_x_) * static_cast<size_t>(tiles_y_), TileCone{});
  for (int ty = 0; ty < tiles_y_; ++ty) {
    for (int tx = 0; tx < tiles_x_; ++tx) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      const int x0 = tx * kTilePx, y0 = ty * kTilePx;
      const int x1 = std::min(render_size_.width, x0 + kTilePx), y1 = std::min(render_size_.height, y0 + kTilePx);
      for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) sum += dir_[Index(x, y)];
      }
      TileCone& cone = tiles_[static_cast<size_t>(ty * tiles_x_ + tx)];
      if (sum.norm() < 1e-12) continue;
      cone.axis = sum.normalized();
      double min_cos = 1;
      for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
          if (has_ray_[Index(x, y)]) min_cos = std::min(min_cos, cone.axis.dot(dir_[Index(x, y)]));
        }
      }
      cone.half_angle_rad = std::acos(std::clamp(min_cos, -1.0, 1.0)) + 1e-6;
    }
  }
  if (shadows || contact) {
    if (shadows) tile_floor_.assign(tiles_.size(), TileFloor{});
    if (contact) tile_contact_floor_.assign(tiles_.size(), TileFloor{});
    for (int y = 0; y < render_size_.height; ++y) {
      for (int x = 0; x < render_size_.width; ++x) {
        const size_t i = Index(x, y);
        if (static_surface_[i] != 1) continue;
        const Eigen::Vector2d p = (origin_ + static_t_[i] * dir_[i]).head<2>();
        const size_t tile = static_cast<size_t>((y / kTilePx) * tiles_x_ + x / kTilePx);
        if (contact) {
          tile_contact_floor_[tile].lo = tile_contact_floor_[tile].lo.cwiseMin(p);
          tile_contact_floor_[tile].hi = tile_contact_floor_[tile].hi.cwiseMax(p);
        }
        if (!shadows || direct_[i] == Eigen::Vector3f::Zero()) continue;
        TileFloor& t = tile_floor_[tile];
        t.lo = t.lo.cwiseMin(p);
        t.hi = t.hi.cwiseMax(p);
      }
    }
  }
  if (supersample_ > 1) {
    // An image pixel is monitored floor when most of its rays are.
    const int s = supersample_;
    Image<uint8_t> mask(size_.width, size_.height, 0);
    for (int y = 0; y < size_.height; ++y) {
      for (int x = 0; x < size_.width; ++x) {
        int floor = 0;
        for (int dy = 0; dy < s; ++dy) {
          for (int dx = 0; dx < s; ++dx) floor += floor_mask_(x * s + dx, y * s + dy) != 0;
        }
        mask(x, y) = 2 * floor >= s * s ? 255 : 0;
      }
    }
    floor_mask_ = std::move(mask);
  }
  if (spec.photometry.camera.processes_frames()) {
    const int s = supersample_;
    out_has_ray_.assign(static_cast<size_t>(size_.width) * static_cast<size_t>(size_.height), 0);
    for (int y = 0; y < size_.height; ++y) {
      for (int x = 0; x < size_.width; ++x) {
        uint8_t any = 0;
        for (int dy = 0; dy < s; ++dy) {
          for (int dx = 0; dx < s; ++dx) any |= has_ray_[Index(x * s + dx, y * s + dy)];
        }
        out_has_ray_[static_cast<size_t>(y) * static_cast<size_t>(size_.width) + static_cast<size_t>(x)] = any;
      }
    }
    empty_mean_ = MeanRadiance(AreaMean(bg_));
  }
  exposure_phase_rad_ = 2 * std::numbers::pi * UnitFromHash(Mix64(spec.seed ^ Mix64(0xe7 + camera_index)));
}

double CameraRenderer::Gain(double time_s) const {
  const PhotometrySpec& ph = scene_.spec().photometry;
  if (ph.exposure_drift == 0) return 1.0;
  return 1.0 + ph.exposure_drift * std::sin(2 * std::numbers::pi * time_s / ph.exposure_period_s + exposure_phase_rad_);
}

uint8_t CameraRenderer::Quantize(float value, float noise) const {
  const float v = std::nearbyint(value + noise);
  return static_cast<uint8_t>(std::clamp(v, 0.0f, 255.0f));
}

Image<Rgb8> CameraRenderer::Background(bool noise) const {
  const PhotometrySpec& ph = scene_.spec().photometry;
  if (ph.camera.processes_frames()) {
    // The empty view through the camera, settled on it (no drift: the gain 1 of the ideal camera).
    const CameraResponseSpec& cam = ph.camera;
    const bool add_noise =
        noise && ph.background_noise && (ph.noise_sigma > 0 || cam.read_noise > 0 || cam.shot_noise > 0);
    Image<Rgb8> out(size_.width, size_.height);
    Expose(AreaMean(bg_), NewResponse().SettledGains(empty_mean_), add_noise,
           NoiseStream(scene_.spec().seed, camera_index_, -1), nullptr, &out);
    return out;
  }
  const bool add_noise = noise && ph.background_noise && ph.noise_sigma > 0;
  const float sigma = static_cast<float>(ph.noise_sigma);
  const auto& table = GaussianTable();
  const uint64_t stream = NoiseStream(scene_.spec().seed, camera_index_, -1);
  Image<Rgb8> out(size_.width, size_.height);
  for (int y = 0; y < size_.height; ++y) {
    Rgb8* row = out.row(y);
    for (int x = 0; x < size_.width; ++x) {
      const size_t i = Index(x, y);
      const Eigen::Vector3f v = bg_[i] * 255.0f;
      float n[3] = {0, 0, 0};
      if (add_noise && has_ray_[i]) {
        const uint64_t h = Mix64(stream ^ i);
        for (int c = 0; c < 3; ++c) n[c] = sigma * table[(h >> (16 * c)) & 0xffff];
      }
      row[x] = {Quantize(v[0], n[0]), Quantize(v[1], n[1]), Quantize(v[2], n[2])};
    }
  }
  return out;
}

CameraResponse CameraRenderer::NewResponse() const {
  return CameraResponse(scene_.spec().photometry.camera, scene_.spec().fps, empty_mean_);
}

template <typename Sink>
void CameraRenderer::Cast(const SceneState& state, Context& ctx, Sink&& sink) const {
  const SceneSpec& spec = scene_.spec();
  const PhotometrySpec& ph = spec.photometry;
  const std::vector<ObjectInstance>& objects = state.objects;
  const bool shadows = ph.shadows && !objects.empty();
  std::vector<ShadowRegion> shadow_regions;
  if (shadows) {
    shadow_regions.reserve(objects.size());
    for (const ObjectInstance& obj : objects) shadow_regions.push_back(ShadowRegionOf(obj, ph.lighting));
  }
  const ContactShadowSpec& contact = ph.contact_shadows;
  const bool contact_shadows = contact.enabled() && !objects.empty();
  std::vector<ContactOccluder> occluders;
  if (contact_shadows) {
    occluders.reserve(objects.size());
    for (const ObjectInstance& obj : objects) {
      const bool person = obj.object_class == ObjectClass::kPerson;
      const double radius = person ? contact.radius_m : std::max(1e-3, obj.bound.radius_m);
      occluders.push_back({obj.position_m, radius, std::max(obj.bound.z_max_m, 1e-3)});
    }
  }
  const double reach2 = contact.reach_m * contact.reach_m;

  // Tile rows are dealt out in turn (task k takes rows k, k + T, ...): people stand in the lower
  // part of most views, and contiguous chunks would leave one thread with most of the work.
  const int num_tasks = std::max(1, std::min(ctx.num_threads(), tiles_y_));
  ParallelFor(ctx, 0, num_tasks, [&](int64_t k0, int64_t k1, int) {
    std::vector<const ObjectInstance*> candidates;
    std::vector<size_t> shadow_candidates;
    std::vector<size_t> contact_candidates;
    candidates.reserve(objects.size());
    shadow_candidates.reserve(objects.size());
    contact_candidates.reserve(objects.size());
    for (int64_t k = k0; k < k1; ++k)
    for (int ty = static_cast<int>(k); ty < tiles_y_; ty += num_tasks) {
      for (int tx = 0; tx < tiles_x_; ++tx) {
        const size_t tile = static_cast<size_t>(ty * tiles_x_ + tx);
        const TileCone& cone = tiles_[tile];
        candidates.clear();
        if (cone.half_angle_rad >= 0) {
          for (const ObjectInstance& obj : objects) {
            const Eigen::Vector3d v = obj.sphere_centre_m - origin_;
            const double dist = v.norm();
            if (dist <= obj.sphere_radius_m) {
              candidates.push_back(&obj);
              continue;
            }
            const double gamma = std::acos(std::clamp(cone.axis.dot(v) / dist, -1.0, 1.0));
            const double beta = std::asin(std::min(1.0, obj.sphere_radius_m / dist));
            if (gamma <= cone.half_angle_rad + beta + 1e-9) candidates.push_back(&obj);
          }
        }
        shadow_candidates.clear();
        if (shadows) {
          const TileFloor& floor = tile_floor_[tile];
          for (size_t o = 0; o < objects.size(); ++o) {
            if (shadow_regions[o].MayMeet(floor.lo, floor.hi)) shadow_candidates.push_back(o);
          }
        }
        contact_candidates.clear();
        if (contact_shadows) {
          const TileFloor& floor = tile_contact_floor_[tile];
          for (size_t o = 0; o < occluders.size(); ++o) {
            if (floor.lo.x() <= floor.hi.x() && PointBoxDistance2(occluders[o].centre_m, floor.lo, floor.hi) < reach2) {
              contact_candidates.push_back(o);
            }
          }
        }
        const int x0 = tx * kTilePx, y0 = ty * kTilePx;
        const int x1 = std::min(render_size_.width, x0 + kTilePx), y1 = std::min(render_size_.height, y0 + kTilePx);
        for (int y = y0; y < y1; ++y) {
          for (int x = x0; x < x1; ++x) {
            const size_t i = Index(x, y);
            Eigen::Vector3f radiance = bg_[i];
            uint16_t id = 0;
            if (has_ray_[i] && !candidates.empty()) {
              const Eigen::Vector3d& d = dir_[i];
              double t_best = static_t_[i];
              const Primitive* part_hit = nullptr;
              Eigen::Vector3d normal;
              for (const ObjectInstance* obj : candidates) {
                const auto interval = RayCylinderInterval(obj->bound, origin_, d);
                if (!interval || interval->second <= kMinHitDistanceM || interval->first >= t_best) continue;
                for (const Primitive& part : obj->parts) {
                  if (auto hit = IntersectRay(part, origin_, d, t_best)) {
                    t_best = hit->t;
                    part_hit = &part;
                    normal = hit->normal_in_world;
                    id = static_cast<uint16_t>(obj->id);
                  }
                }
              }
              if (part_hit != nullptr) {
                radiance = Shade(part_hit->material, origin_ + t_best * d, normal, ph.lighting);
              }
            }
            bool in_shadow = false;
            if (!shadow_candidates.empty() && id == 0 && static_surface_[i] == 1 &&
                direct_[i] != Eigen::Vector3f::Zero()) {
              const Eigen::Vector3d p = origin_ + static_t_[i] * dir_[i];
              for (size_t o : shadow_candidates) {
                if (ShadowedIn(objects[o], shadow_regions[o], ph.lighting, p)) {
                  radiance -= direct_[i];
                  in_shadow = true;
                  break;
                }
              }
            }
            if (!contact_candidates.empty() && id == 0 && static_surface_[i] == 1) {
              const Eigen::Vector2d p = (origin_ + static_t_[i] * dir_[i]).head<2>();
              double lit = 1;  // the part of the sky still seen
              for (size_t o : contact_candidates) {
                const ContactOccluder& occ = occluders[o];
                lit *= 1 - contact.strength * ContactShadowShape((p - occ.centre_m).norm(), occ.radius_m, occ.height_m,
                                                                 contact.reach_m);
              }
              if (lit < 1) {
                const Eigen::Vector3f darkening = static_cast<float>(1 - lit) * ambient_[i];
                if (darkening.sum() >= kContactShadowMaskFraction * radiance.sum()) in_shadow = true;
                radiance -= darkening;
              }
            }
            sink(x, y, i, radiance, id, in_shadow);
          }
        }
      }
    }
  });
}

void CameraRenderer::Render(const SceneState& state, Context& ctx, RenderedView* out, bool noise, bool shadow_mask,
                            CameraResponse* response) const {
  const SceneSpec& spec = scene_.spec();
  const PhotometrySpec& ph = spec.photometry;
  if (ph.camera.processes_frames()) {
    RenderRealCamera(state, ctx, out, noise, shadow_mask, response);
    return;
  }
  if (out->rgb.width() != size_.width || out->rgb.height() != size_.height) out->rgb = Image<Rgb8>(size_.width, size_.height);
  if (out->ids.width() != size_.width || out->ids.height() != size_.height) out->ids = Image<uint16_t>(size_.width, size_.height);
  const double drift = Gain(state.time_s);
  const float gain = static_cast<float>(drift) * 255.0f;
  const bool add_noise = noise && ph.noise_sigma > 0;
  const float sigma = static_cast<float>(ph.noise_sigma);
  const auto& table = GaussianTable();
  const uint64_t stream = NoiseStream(spec.seed, camera_index_, state.frame);
  if (shadow_mask && (out->shadow.width() != size_.width || out->shadow.height() != size_.height)) {
    out->shadow = Image<uint8_t>(size_.width, size_.height);
  }
  Cast(state, ctx, [&](int x, int y, size_t i, const Eigen::Vector3f& radiance, uint16_t id, bool in_shadow) {
    if (shadow_mask) out->shadow.row(y)[x] = in_shadow ? 255 : 0;
    const Eigen::Vector3f v = radiance * gain;
    float n[3] = {0, 0, 0};
    if (add_noise && has_ray_[i]) {
      const uint64_t h = Mix64(stream ^ i);
      for (int c = 0; c < 3; ++c) n[c] = sigma * table[(h >> (16 * c)) & 0xffff];
    }
    out->rgb.row(y)[x] = {Quantize(v[0], n[0]), Quantize(v[1], n[1]), Quantize(v[2], n[2])};
    out->ids.row(y)[x] = id;
  });
  out->gains = Eigen::Vector3d::Constant(drift);
}

std::vector<Eigen::Vector3f> CameraRenderer::AreaMean(const std::vector<Eigen::Vector3f>& cast) const {
  if (supersample_ == 1) return cast;
  const int s = supersample_;
  const float scale = 1.0f / static_cast<float>(s * s);
  std::vector<Eigen::Vector3f> out(static_cast<size_t>(size_.width) * static_cast<size_t>(size_.height));
  for (int y = 0; y < size_.height; ++y) {
    for (int x = 0; x < size_.width; ++x) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (int dy = 0; dy < s; ++dy) {
        for (int dx = 0; dx < s; ++dx) sum += cast[Index(x * s + dx, y * s + dy)];
      }
      out[static_cast<size_t>(y) * static_cast<size_t>(size_.width) + static_cast<size_t>(x)] = sum * scale;
    }
  }
  return out;
}

Eigen::Vector3d CameraRenderer::MeanRadiance(const std::vector<Eigen::Vector3f>& radiance) const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int64_t count = 0;
  for (size_t i = 0; i < radiance.size(); ++i) {
    if (!out_has_ray_[i]) continue;
    sum += radiance[i].cast<double>();
    ++count;
  }
  return count > 0 ? Eigen::Vector3d(sum / static_cast<double>(count)) : Eigen::Vector3d::Zero();
}

void CameraRenderer::Expose(const std::vector<Eigen::Vector3f>& radiance, const Eigen::Vector3d& gains, bool add_noise,
                            uint64_t stream, Context* ctx, Image<Rgb8>* out) const {
  const PhotometrySpec& ph = scene_.spec().photometry;
  const float base_variance = static_cast<float>(ph.noise_sigma * ph.noise_sigma +
                                                 ph.camera.read_noise * ph.camera.read_noise);
  const float shot = static_cast<float>(ph.camera.shot_noise);
  const Eigen::Vector3f gain = (gains * 255.0).cast<float>();
  const auto& table = GaussianTable();
  auto rows = [&](int64_t y0, int64_t y1) {
    for (int y = static_cast<int>(y0); y < y1; ++y) {
      Rgb8* row = out->row(y);
      for (int x = 0; x < size_.width; ++x) {
        const size_t i = static_cast<size_t>(y) * static_cast<size_t>(size_.width) + static_cast<size_t>(x);
        const Eigen::Vector3f v = radiance[i].cwiseProduct(gain);
        float n[3] = {0, 0, 0};
        if (add_noise && out_has_ray_[i]) {
          const uint64_t h = Mix64(stream ^ i);
          for (int c = 0; c < 3; ++c) {
            n[c] = std::sqrt(base_variance + shot * std::max(0.0f, v[c])) * table[(h >> (16 * c)) & 0xffff];
          }
        }
        row[x] = {Quantize(v[0], n[0]), Quantize(v[1], n[1]), Quantize(v[2], n[2])};
      }
    }
  };
  if (ctx != nullptr) {
    ParallelFor(*ctx, 0, size_.height, [&](int64_t y0, int64_t y1, int) { rows(y0, y1); });
  } else {
    rows(0, size_.height);
  }
}

void CameraRenderer::RenderRealCamera(const SceneState& state, Context& ctx, RenderedView* out, bool noise,
                                      bool shadow_mask, CameraResponse* response) const {
  const SceneSpec& spec = scene_.spec();
  const PhotometrySpec& ph = spec.photometry;
  const size_t cast_pixels = static_cast<size_t>(render_size_.width) * static_cast<size_t>(render_size_.height);
  std::vector<Eigen::Vector3f> cast(cast_pixels);
  std::vector<uint16_t> cast_ids(cast_pixels);
  std::vector<uint8_t> cast_shadow(shadow_mask ? cast_pixels : 0);
  Cast(state, ctx, [&](int, int, size_t i, const Eigen::Vector3f& radiance, uint16_t id, bool in_shadow) {
    cast[i] = radiance;
    cast_ids[i] = id;
    if (shadow_mask) cast_shadow[i] = in_shadow ? 1 : 0;
  });
  if (out->rgb.width() != size_.width || out->rgb.height() != size_.height) out->rgb = Image<Rgb8>(size_.width, size_.height);
  if (out->ids.width() != size_.width || out->ids.height() != size_.height) out->ids = Image<uint16_t>(size_.width, size_.height);
  if (shadow_mask && (out->shadow.width() != size_.width || out->shadow.height() != size_.height)) {
    out->shadow = Image<uint8_t>(size_.width, size_.height);
  }
  // Ids and shadows: an object is seen where it covers at least half of the pixel's rays (the
  // most frequent one), a shadow where most rays fall in one.
  const int s = supersample_;
  ParallelFor(ctx, 0, size_.height, [&](int64_t y0, int64_t y1, int) {
    std::array<std::pair<uint16_t, int>, 16> counts{};
    for (int y = static_cast<int>(y0); y < y1; ++y) {
      for (int x = 0; x < size_.width; ++x) {
        int distinct = 0, covered = 0, shadowed = 0;
        for (int dy = 0; dy < s; ++dy) {
          for (int dx = 0; dx < s; ++dx) {
            const size_t i = Index(x * s + dx, y * s + dy);
            if (shadow_mask) shadowed += cast_shadow[i];
            const uint16_t id = cast_ids[i];
            if (id == 0) continue;
            ++covered;
            int k = 0;
            while (k < distinct && counts[static_cast<size_t>(k)].first != id) ++k;
            if (k == distinct) counts[static_cast<size_t>(distinct++)] = {id, 0};
            ++counts[static_cast<size_t>(k)].second;
          }
        }
        uint16_t id = 0;
        if (2 * covered >= s * s) {
          int best = 0;
          for (int k = 0; k < distinct; ++k) {
            if (counts[static_cast<size_t>(k)].second > best) {
              best = counts[static_cast<size_t>(k)].second;
              id = counts[static_cast<size_t>(k)].first;
            }
          }
        }
        out->ids(x, y) = id;
        if (shadow_mask) out->shadow(x, y) = id == 0 && 2 * shadowed >= s * s ? 255 : 0;
      }
    }
  });
  const std::vector<Eigen::Vector3f> radiance = AreaMean(cast);
  const Eigen::Vector3d mean = MeanRadiance(radiance);
  const Eigen::Vector3d gains =
      (response != nullptr ? response->Update(mean) : NewResponse().SettledGains(mean)) * Gain(state.time_s);
  out->gains = gains;
  const CameraResponseSpec& cam = ph.camera;
  const bool add_noise = noise && (ph.noise_sigma > 0 || cam.read_noise > 0 || cam.shot_noise > 0);
  Expose(radiance, gains, add_noise, NoiseStream(spec.seed, camera_index_, state.frame), &ctx, &out->rgb);
}

PixelTrace TracePixelReference(const Scene& scene, size_t camera_index, const SceneState& state,
                               const Eigen::Vector2d& pixel) {
  PixelTrace out;
  const std::optional<Ray> ray = scene.camera(camera_index).BackProject(pixel);
  if (!ray) return out;
  out.has_ray = true;
  const Eigen::Vector3d& o = ray->origin_in_world;
  const Eigen::Vector3d& d = ray->direction_in_world;
  const StaticHit s = TraceStatic(scene.static_primitives(), o, d);
  double t_best = s.t;
  const Primitive* best = s.prim;
  Eigen::Vector3d normal = s.normal;
  for (const ObjectInstance& obj : state.objects) {
    for (const Primitive& part : obj.parts) {
      if (auto hit = IntersectRay(part, o, d, t_best)) {
        t_best = hit->t;
        best = &part;
        normal = hit->normal_in_world;
        out.id = static_cast<uint16_t>(obj.id);
      }
    }
  }
  if (best == nullptr) {
    out.radiance = MissRadiance(scene.spec(), d);
    return out;
  }
  out.hit_anything = true;
  out.t = t_best;
  out.surface = best->surface;
  out.radiance = Shade(best->material, o + t_best * d, normal, scene.spec().photometry.lighting);
  return out;
}

}  // namespace occmap::sim
