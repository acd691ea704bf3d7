#include "occmap/sim/primitives.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace occmap::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double Hash01(uint64_t seed, int64_t i, int64_t j, int64_t k = 0) {
  uint64_t h = Mix64(seed ^ 0x5851f42d4c957f2dULL);
  h = Mix64(h ^ static_cast<uint64_t>(i));
  h = Mix64(h ^ static_cast<uint64_t>(j));
  h = Mix64(h ^ static_cast<uint64_t>(k));
  return UnitFromHash(h);
}

// Smooth 2D value noise in [0, 1) with lattice spacing 1.
double ValueNoise(uint64_t seed, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
  double u = x - fx, v = y - fy;
  u = u * u * (3 - 2 * u);
  v = v * v * (3 - 2 * v);
  const double a = Hash01(seed, ix, iy), b = Hash01(seed, ix + 1, iy);
  const double c = Hash01(seed, ix, iy + 1), d = Hash01(seed, ix + 1, iy + 1);
  return (a * (1 - u) + b * u) * (1 - v) + (c * (1 - u) + d * u) * v;
}

Eigen::Vector3f Scaled(const Eigen::Vector3f& c, double f) {
  return (c * static_cast<float>(f)).cwiseMax(0.0f).cwiseMin(1.0f);
}

// Solves the quadratic a t^2 + 2 b t + c = 0 for its smaller root above t_min (entering).
// Returns +inf when there is none.
double EnteringRoot(double a, double b, double c) {
  const double disc = b * b - a * c;
  if (disc < 0 || a <= 0) return kInf;
  return (-b - std::sqrt(disc)) / a;
}

}  // namespace

Eigen::Vector3f Material::AlbedoAt(const Eigen::Vector3d& p) const {
  switch (pattern) {
    case Pattern::kPlain:
      return colour;
    case Pattern::kNoise: {
      const double g = Hash01(seed, static_cast<int64_t>(std::floor(p.x() * 200)),
                              static_cast<int64_t>(std::floor(p.y() * 200)), static_cast<int64_t>(std::floor(p.z() * 200)));
      return Scaled(colour, 1 + variation * (2 * g - 1));
    }
    case Pattern::kTiles: {
      const double s = scale_m;
      const double fx = p.x() / s, fy = p.y() / s;
      const double gx = fx - std::floor(fx), gy = fy - std::floor(fy);
      const double grout = 0.006 / s;  // 6 mm grout lines
      if (gx < grout || gy < grout) return colour2;
      const auto ti = static_cast<int64_t>(std::floor(fx)), tj = static_cast<int64_t>(std::floor(fy));
      const double tile = Hash01(seed, ti, tj);
      const double speck = Hash01(seed + 1, static_cast<int64_t>(std::floor(p.x() * 250)),
                                  static_cast<int64_t>(std::floor(p.y() * 250)));
      const double mottled = ValueNoise(seed + 2, p.x() * 12, p.y() * 12);
      return Scaled(colour, 1 + variation * (0.6 * (2 * tile - 1) + 0.25 * (2 * mottled - 1) + 0.25 * (2 * speck - 1)));
    }
    case Pattern::kCarpet: {
      const double n1 = ValueNoise(seed, p.x() * 1.3, p.y() * 1.3);
      const double n2 = ValueNoise(seed + 7, p.x() * 6.0, p.y() * 6.0);
      const double n3 = ValueNoise(seed + 13, p.x() * 30.0, p.y() * 30.0);
      const double fibre = Hash01(seed + 3, static_cast<int64_t>(std::floor(p.x() * 250)),
                                  static_cast<int64_t>(std::floor(p.y() * 250)));
      const double f = 1 + variation * (0.35 * (2 * n1 - 1) + 0.3 * (2 * n2 - 1) + 0.2 * (2 * n3 - 1) +
                                        0.15 * (2 * fibre - 1));
      return Scaled(colour, f);
    }
    case Pattern::kBooks: {
      // Shelf boards every scale_m in z (3 cm thick), books of 2-5 cm along the shelf.
      const double shelf = p.z() / scale_m;
      const double in_shelf = (shelf - std::floor(shelf)) * scale_m;
      if (in_shelf < 0.03) return colour2;
      const auto level = static_cast<int64_t>(std::floor(shelf));
      const double along = p.x() + p.y();  // shelves run along a wall: x or y varies
      const double w = 0.035;
      const auto book = static_cast<int64_t>(std::floor(along / w));
      const double top = 0.6 + 0.35 * Hash01(seed, book, level, 1);  // book height, fraction of the shelf
      if (in_shelf > top * scale_m || Hash01(seed, book, level, 2) < 0.08) return Scaled(colour2, 0.55);
      const double r = Hash01(seed, book, level, 3), g = Hash01(seed, book, level, 4), b = Hash01(seed, book, level, 5);
      return Eigen::Vector3f(static_cast<float>(0.15 + 0.6 * r), static_cast<float>(0.12 + 0.5 * g),
                             static_cast<float>(0.12 + 0.5 * b));
    }
  }
  return colour;
}

Primitive Primitive::Box(const Eigen::Vector3d& centre_m, const Eigen::Matrix3d& world_from_local,
                         const Eigen::Vector3d& half_extents_m, const Material& material) {
  Primitive p;
  p.kind = PrimitiveKind::kBox;
  p.a = centre_m;
  p.local_from_world = world_from_local.transpose();
  p.half_extents_m = half_extents_m;
  p.material = material;
  return p;
}

Primitive Primitive::UprightBox(const Eigen::Vector2d& centre_xy_m, double z_bottom_m, double z_top_m,
                                const Eigen::Vector2d& half_size_xy_m, double yaw_rad, const Material& material) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return Box({centre_xy_m.x(), centre_xy_m.y(), 0.5 * (z_bottom_m + z_top_m)}, r,
             {half_size_xy_m.x(), half_size_xy_m.y(), 0.5 * (z_top_m - z_bottom_m)}, material);
}

Primitive Primitive::Ellipsoid(const Eigen::Vector3d& centre_m, const Eigen::Matrix3d& world_from_local,
                               const Eigen::Vector3d& semi_axes_m, const Material& material) {
  Primitive p = Box(centre_m, world_from_local, semi_axes_m, material);
  p.kind = PrimitiveKind::kEllipsoid;
  return p;
}

Primitive Primitive::VerticalCylinder(const Eigen::Vector2d& centre_xy_m, double radius_m, double z_bottom_m,
                                      double z_top_m, const Material& material) {
  Primitive p;
  p.kind = PrimitiveKind::kVerticalCylinder;
  p.a = {centre_xy_m.x(), centre_xy_m.y(), z_bottom_m};
  p.b = {radius_m, 0, z_top_m};
  p.radius_m = radius_m;
  p.material = material;
  return p;
}

Primitive Primitive::Capsule(const Eigen::Vector3d& a_m, const Eigen::Vector3d& b_m, double radius_m,
                             const Material& material) {
  Primitive p;
  p.kind = PrimitiveKind::kCapsule;
  p.a = a_m;
  p.b = b_m;
  p.radius_m = radius_m;
  p.material = material;
  return p;
}

Primitive Primitive::Sphere(const Eigen::Vector3d& centre_m, double radius_m, const Material& material) {
  Primitive p;
  p.kind = PrimitiveKind::kSphere;
  p.a = centre_m;
  p.radius_m = radius_m;
  p.material = material;
  return p;
}

Primitive Primitive::HorizontalRect(double x_min_m, double y_min_m, double x_max_m, double y_max_m, double z_m,
                                    int facing, const Material& material) {
  Primitive p;
  p.kind = PrimitiveKind::kHorizontalRect;
  p.a = {x_min_m, y_min_m, z_m};
  p.b = {x_max_m, y_max_m, facing >= 0 ? 1.0 : -1.0};
  p.material = material;
  return p;
}

void Primitive::Bounds(Eigen::Vector3d* lo, Eigen::Vector3d* hi) const {
  switch (kind) {
    case PrimitiveKind::kBox:
    case PrimitiveKind::kEllipsoid: {
      // |R^T| h: the extent of the rotated box along each world axis.
      const Eigen::Vector3d ext = local_from_world.transpose().cwiseAbs() * half_extents_m;
      *lo = a - ext;
      *hi = a + ext;
      return;
    }
    case PrimitiveKind::kVerticalCylinder:
      *lo = {a.x() - radius_m, a.y() - radius_m, a.z()};
      *hi = {a.x() + radius_m, a.y() + radius_m, b.z()};
      return;
    case PrimitiveKind::kCapsule:
      *lo = a.cwiseMin(b) - Eigen::Vector3d::Constant(radius_m);
      *hi = a.cwiseMax(b) + Eigen::Vector3d::Constant(radius_m);
      return;
    case PrimitiveKind::kSphere:
      *lo = a - Eigen::Vector3d::Constant(radius_m);
      *hi = a + Eigen::Vector3d::Constant(radius_m);
      return;
    case PrimitiveKind::kHorizontalRect:
      *lo = {a.x(), a.y(), a.z()};
      *hi = {b.x(), b.y(), a.z()};
      return;
  }
}

void Primitive::BoundingSphere(Eigen::Vector3d* centre_out, double* radius_out) const {
  Eigen::Vector3d lo, hi;
  Bounds(&lo, &hi);
  *centre_out = 0.5 * (lo + hi);
  *radius_out = 0.5 * (hi - lo).norm();
}

std::optional<RayHit> IntersectRay(const Primitive& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                   double t_max) {
  switch (p.kind) {
    case PrimitiveKind::kBox: {
      const Eigen::Vector3d ol = p.local_from_world * (o - p.a);
      const Eigen::Vector3d dl = p.local_from_world * d;
      double t_near = -kInf, t_far = kInf;
      int axis = -1;
      double sign = 1;
      for (int i = 0; i < 3; ++i) {
        const double h = p.half_extents_m[i];
        if (std::abs(dl[i]) < 1e-300) {
          if (ol[i] < -h || ol[i] > h) return std::nullopt;
          continue;
        }
        const double inv = 1.0 / dl[i];
        double t1 = (-h - ol[i]) * inv, t2 = (h - ol[i]) * inv;
        double s = -1;  // the face entered at t1 is the -h face
        if (t1 > t2) {
          std::swap(t1, t2);
          s = 1;
        }
        if (t1 > t_near) {
          t_near = t1;
          axis = i;
          sign = s;
        }
        t_far = std::min(t_far, t2);
      }
      if (axis < 0 || t_near > t_far || !(t_near > kMinHitDistanceM) || !(t_near < t_max)) return std::nullopt;
      Eigen::Vector3d n_local = Eigen::Vector3d::Zero();
      n_local[axis] = sign;
      return RayHit{t_near, p.local_from_world.transpose() * n_local};
    }
    case PrimitiveKind::kEllipsoid: {
      const Eigen::Vector3d inv_s = p.half_extents_m.cwiseInverse();
      const Eigen::Vector3d ol = (p.local_from_world * (o - p.a)).cwiseProduct(inv_s);
      const Eigen::Vector3d dl = (p.local_from_world * d).cwiseProduct(inv_s);
      const double t = EnteringRoot(dl.squaredNorm(), ol.dot(dl), ol.squaredNorm() - 1);
      if (!(t > kMinHitDistanceM) || !(t < t_max)) return std::nullopt;
      const Eigen::Vector3d q = (ol + t * dl).cwiseProduct(inv_s);  // gradient direction in local
      return RayHit{t, (p.local_from_world.transpose() * q).normalized()};
    }
    case PrimitiveKind::kSphere: {
      const Eigen::Vector3d oc = o - p.a;
      const double t = EnteringRoot(1.0, oc.dot(d), oc.squaredNorm() - p.radius_m * p.radius_m);
      if (!(t > kMinHitDistanceM) || !(t < t_max)) return std::nullopt;
      return RayHit{t, (oc + t * d) / p.radius_m};
    }
    case PrimitiveKind::kVerticalCylinder: {
      const double r = p.radius_m, z0 = p.a.z(), z1 = p.b.z();
      double best = kInf;
      Eigen::Vector3d n = Eigen::Vector3d::Zero();
      // Side: |(o + t d)_xy - c| = r, entering root.
      const double ox = o.x() - p.a.x(), oy = o.y() - p.a.y();
      const double a2 = d.x() * d.x() + d.y() * d.y();
      if (a2 > 1e-300) {
        const double t = EnteringRoot(a2, ox * d.x() + oy * d.y(), ox * ox + oy * oy - r * r);
        if (t < kInf) {
          const double z = o.z() + t * d.z();
          if (z >= z0 && z <= z1 && t > kMinHitDistanceM) {
            best = t;
            n = Eigen::Vector3d((ox + t * d.x()) / r, (oy + t * d.y()) / r, 0);
          }
        }
      }
      // Caps: the top seen from above, the bottom from below.
      if (std::abs(d.z()) > 1e-300) {
        const double zc = d.z() < 0 ? z1 : z0;
        const double t = (zc - o.z()) / d.z();
        if (t > kMinHitDistanceM && t < best) {
          const double x = ox + t * d.x(), y = oy + t * d.y();
          if (x * x + y * y <= r * r) {
            best = t;
            n = Eigen::Vector3d(0, 0, d.z() < 0 ? 1 : -1);
          }
        }
      }
      if (!(best < t_max)) return std::nullopt;
      return RayHit{best, n};
    }
    case PrimitiveKind::kCapsule: {
      // Inigo Quilez's capsule intersection.
      const Eigen::Vector3d ba = p.b - p.a, oa = o - p.a;
      const double baba = ba.dot(ba), bard = ba.dot(d), baoa = ba.dot(oa), rdoa = d.dot(oa), oaoa = oa.dot(oa);
      const double r = p.radius_m;
      const double a = baba - bard * bard;
      const double b = baba * rdoa - baoa * bard;
      const double c = baba * oaoa - baoa * baoa - r * r * baba;
      double t = kInf;
      Eigen::Vector3d n;
      if (a > 1e-300) {
        const double h = b * b - a * c;
        if (h >= 0) {
          const double tc = (-b - std::sqrt(h)) / a;
          const double y = baoa + tc * bard;
          if (y > 0 && y < baba && tc > kMinHitDistanceM) {
            t = tc;
            const Eigen::Vector3d pa = oa + tc * d;
            n = (pa - ba * (y / baba)) / r;
          }
        }
      }
      if (t == kInf) {
        // The capsule is the union of the body and two spheres: its first entry is the first
        // entry into any of them (a body entry outside the segment's span is not one).
        for (const Eigen::Vector3d* centre : {&p.a, &p.b}) {
          const Eigen::Vector3d oc = o - *centre;
          const double ts = EnteringRoot(1.0, oc.dot(d), oc.squaredNorm() - r * r);
          if (ts > kMinHitDistanceM && ts < t) {
            t = ts;
            n = (oc + ts * d) / r;
          }
        }
      }
      if (!(t > kMinHitDistanceM) || !(t < t_max)) return std::nullopt;
      return RayHit{t, n};
    }
    case PrimitiveKind::kHorizontalRect: {
      const double facing = p.b.z();
      if (!(d.z() * facing < 0)) return std::nullopt;  // one-sided
      const double t = (p.a.z() - o.z()) / d.z();
      if (!(t > kMinHitDistanceM) || !(t < t_max)) return std::nullopt;
      const double x = o.x() + t * d.x(), y = o.y() + t * d.y();
      if (x < p.a.x() || x >= p.b.x() || y < p.a.y() || y >= p.b.y()) return std::nullopt;
      return RayHit{t, Eigen::Vector3d(0, 0, facing)};
    }
  }
  return std::nullopt;
}

bool SegmentBlocked(const Primitive& p, const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  const Eigen::Vector3d v = to - from;
  const double len = v.norm();
  if (!(len > 0)) return false;
  return IntersectRay(p, from, v / len, len * (1 - 1e-9)).has_value();
}

std::optional<std::pair<double, double>> RayCylinderInterval(const CylinderBound& c, const Eigen::Vector3d& o,
                                                             const Eigen::Vector3d& d) {
  double t0 = -kInf, t1 = kInf;
  // Slab in z.
  if (std::abs(d.z()) < 1e-300) {
    if (o.z() < c.z_min_m || o.z() > c.z_max_m) return std::nullopt;
  } else {
    double a = (c.z_min_m - o.z()) / d.z(), b = (c.z_max_m - o.z()) / d.z();
    if (a > b) std::swap(a, b);
    t0 = a;
    t1 = b;
  }
  // Infinite cylinder in x-y.
  const double ox = o.x() - c.centre_xy_m.x(), oy = o.y() - c.centre_xy_m.y();
  const double qa = d.x() * d.x() + d.y() * d.y();
  const double qb = ox * d.x() + oy * d.y();
  const double qc = ox * ox + oy * oy - c.radius_m * c.radius_m;
  if (qa < 1e-300) {
    if (qc > 0) return std::nullopt;
  } else {
    const double disc = qb * qb - qa * qc;
    if (disc < 0) return std::nullopt;
    const double s = std::sqrt(disc);
    t0 = std::max(t0, (-qb - s) / qa);
    t1 = std::min(t1, (-qb + s) / qa);
  }
  if (t0 > t1) return std::nullopt;
  return std::make_pair(t0, t1);
}

void Lighting::DirectAt(const Eigen::Vector3d& point_m, Eigen::Vector3d* to_light, double* intensity_out,
                        double* distance_m) const {
  if (kind == Kind::kDirectional) {
    *to_light = direction_to_light;
    *intensity_out = intensity;
    *distance_m = kInf;
    return;
  }
  const Eigen::Vector3d v = position_m - point_m;
  const double dist = v.norm();
  *to_light = dist > 0 ? Eigen::Vector3d(v / dist) : Eigen::Vector3d::UnitZ();
  *intensity_out = intensity / (1 + falloff_per_m2 * dist * dist);
  *distance_m = dist;
}

Eigen::Vector3f Shade(const Material& material, const Eigen::Vector3d& point_m, const Eigen::Vector3d& normal,
                      const Lighting& lighting, Eigen::Vector3f* direct_out) {
  const Eigen::Vector3f albedo = material.AlbedoAt(point_m);
  Eigen::Vector3d to_light;
  double intensity = 0, dist = 0;
  lighting.DirectAt(point_m, &to_light, &intensity, &dist);
  const double cosine = std::max(0.0, normal.dot(to_light));
  // With white lights the products by the colours are exact: the same bits as albedo * k.
  const Eigen::Vector3f direct = albedo.cwiseProduct(lighting.direct_colour) * static_cast<float>(intensity * cosine);
  if (direct_out != nullptr) *direct_out = direct;
  return albedo.cwiseProduct(lighting.ambient_colour) * static_cast<float>(lighting.ambient) + direct;
}

Material MakeMaterial(Eigen::Vector3f colour, Pattern pattern, float variation, Eigen::Vector3f colour2, float scale_m,
                      uint32_t seed) {
  Material m;
  m.colour = colour;
  m.pattern = pattern;
  m.variation = variation;
  m.colour2 = colour2;
  m.scale_m = scale_m;
  m.seed = seed;
  return m;
}

}  // namespace occmap::sim
