// Analytic primitives for the scene simulator's ray caster, and their ray intersections.
//
// Every shape is solid and given in world coordinates (metres, z up, the floor at z = 0):
// oriented boxes and ellipsoids (a rotation plus half extents / semi-axes), vertical cylinders
// (a disc in x-y between two heights), capsules (a segment with a radius), spheres, and
// horizontal rectangles (floor and ceiling pieces, one-sided: facing +z or -z). A ray is
// origin + t * direction with a unit direction; an intersection reports the smallest
// t in (kMinHitDistanceM, t_max) where the ray enters the solid, and the outward unit normal
// there. A ray starting inside a solid does not see it (cameras are never inside objects).
//
// Colours are albedos in 0..1 (display space); a material may carry a procedural pattern
// evaluated at the world hit point (floor tiles, carpet-like noise, books on shelves).
//
//   Primitive box = Primitive::Box({1, 2, 0.5}, Eigen::Matrix3d::Identity(), {0.5, 0.5, 0.5}, mat);
//   std::optional<RayHit> hit = IntersectRay(box, origin, direction, /*t_max=*/1e9);
//   bool blocked = SegmentBlocked(box, camera_centre, floor_point);
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

namespace occmap::sim {

inline constexpr double kMinHitDistanceM = 1e-9;

// A procedural surface pattern; `colour` is the base albedo.
enum class Pattern : uint8_t {
  kPlain,
  kTiles,   // square tiles of `scale_m` with grout lines of `colour2`, per-tile variation
  kCarpet,  // multi-scale value noise of relative amplitude `variation`, fibres at 4 mm
  kBooks,   // shelves every `scale_m` in z, books of random colours, `colour2` = shelf boards
  kNoise,   // fine grain of relative amplitude `variation` (walls, plastic)
};

struct Material {
  Eigen::Vector3f colour{0.5f, 0.5f, 0.5f};   // albedo, 0..1 per channel
  Pattern pattern = Pattern::kPlain;
  Eigen::Vector3f colour2{0.3f, 0.3f, 0.3f};  // second colour of the pattern
  float scale_m = 0.5f;                        // tile size, shelf height
  float variation = 0.0f;                      // relative albedo variation of the pattern
  uint32_t seed = 0;                           // pattern randomness

  // Albedo at a world point (patterns are functions of the point only: deterministic).
  Eigen::Vector3f AlbedoAt(const Eigen::Vector3d& point_in_world) const;
};

// A material from its fields, in the order scenes write them.
Material MakeMaterial(Eigen::Vector3f colour, Pattern pattern = Pattern::kPlain, float variation = 0,
                      Eigen::Vector3f colour2 = {0.3f, 0.3f, 0.3f}, float scale_m = 0.5f, uint32_t seed = 0);

// What a surface is, for masks and ground truth.
enum class Surface : uint8_t { kFloor, kStatic, kDynamic };

enum class PrimitiveKind : uint8_t { kBox, kEllipsoid, kVerticalCylinder, kCapsule, kSphere, kHorizontalRect };

struct Primitive {
  PrimitiveKind kind = PrimitiveKind::kSphere;
  Surface surface = Surface::kStatic;
  // kBox, kEllipsoid: centre; kVerticalCylinder: (x, y, z_bottom); kCapsule: end a;
  // kSphere: centre; kHorizontalRect: (x_min, y_min, z).
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  // kVerticalCylinder: (radius, -, z_top); kCapsule: end b; kHorizontalRect: (x_max, y_max, facing +1/-1).
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  Eigen::Vector3d half_extents_m = Eigen::Vector3d::Zero();  // kBox half sizes, kEllipsoid semi-axes
  Eigen::Matrix3d local_from_world = Eigen::Matrix3d::Identity();  // kBox, kEllipsoid
  double radius_m = 0;  // kCapsule, kSphere, kVerticalCylinder
  Material material;

  static Primitive Box(const Eigen::Vector3d& centre_m, const Eigen::Matrix3d& world_from_local,
                       const Eigen::Vector3d& half_extents_m, const Material& material);
  // A box standing on z = z_bottom, rotated by yaw about the vertical axis.
  static Primitive UprightBox(const Eigen::Vector2d& centre_xy_m, double z_bottom_m, double z_top_m,
                              const Eigen::Vector2d& half_size_xy_m, double yaw_rad, const Material& material);
  static Primitive Ellipsoid(const Eigen::Vector3d& centre_m, const Eigen::Matrix3d& world_from_local,
                             const Eigen::Vector3d& semi_axes_m, const Material& material);
  static Primitive VerticalCylinder(const Eigen::Vector2d& centre_xy_m, double radius_m, double z_bottom_m,
                                    double z_top_m, const Material& material);
  static Primitive Capsule(const Eigen::Vector3d& a_m, const Eigen::Vector3d& b_m, double radius_m,
                           const Material& material);
  static Primitive Sphere(const Eigen::Vector3d& centre_m, double radius_m, const Material& material);
  // facing: +1 seen from above (floor), -1 seen from below (ceiling).
  static Primitive HorizontalRect(double x_min_m, double y_min_m, double x_max_m, double y_max_m, double z_m,
                                  int facing, const Material& material);

  // A sphere containing the primitive (for culling); infinite radius for huge rectangles is
  // never needed: rectangles are static and not culled.
  void BoundingSphere(Eigen::Vector3d* centre_out, double* radius_out) const;
  // The axis-aligned box containing the primitive.
  void Bounds(Eigen::Vector3d* min_out, Eigen::Vector3d* max_out) const;
};

struct RayHit {
  double t = 0;                      // distance along the unit direction
  Eigen::Vector3d normal_in_world;   // outward, unit length
};

// The first entry of the ray into the primitive with kMinHitDistanceM < t < t_max.
std::optional<RayHit> IntersectRay(const Primitive& p, const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& unit_direction, double t_max);

// Whether the open segment from `from` to `to` (excluding a relative 1e-9 at the end `to`)
// passes through the primitive: the ray from a camera centre to a floor point is blocked.
bool SegmentBlocked(const Primitive& p, const Eigen::Vector3d& from, const Eigen::Vector3d& to);

// Ray against a vertical cylinder bound (x, y, radius, z range): the parameter interval
// [t_enter, t_exit] of the ray inside it, or nullopt. Used to cull objects per pixel.
struct CylinderBound {
  Eigen::Vector2d centre_xy_m = Eigen::Vector2d::Zero();
  double radius_m = 0;
  double z_min_m = 0, z_max_m = 0;
};
std::optional<std::pair<double, double>> RayCylinderInterval(const CylinderBound& bound, const Eigen::Vector3d& origin,
                                                             const Eigen::Vector3d& direction);

// Lambertian shading under ambient light plus one directional or point light.
struct Lighting {
  enum class Kind { kDirectional, kPoint };
  double ambient = 0.5;                 // fraction of the albedo seen without direct light
  Kind kind = Kind::kDirectional;
  Eigen::Vector3d direction_to_light = Eigen::Vector3d(0.3, 0.2, 1.0).normalized();  // kDirectional
  Eigen::Vector3d position_m = Eigen::Vector3d(0, 0, 3);                             // kPoint
  double intensity = 0.5;               // direct light on a surface facing it (kPoint: at 1 m... see DirectAt)
  double falloff_per_m2 = 0.0;          // kPoint: intensity / (1 + falloff * d^2)
  // Colours of the two lights, per channel (0..2; white = (1, 1, 1), the default): outdoors the
  // sky's ambient light is slightly blue and the sun slightly warm, so that cast shadows, lit by
  // the sky alone, are bluer than the sunlit ground around them.
  Eigen::Vector3f ambient_colour = Eigen::Vector3f::Ones();
  Eigen::Vector3f direct_colour = Eigen::Vector3f::Ones();

  // Unit vector from the point towards the light, and the direct intensity before the cosine.
  void DirectAt(const Eigen::Vector3d& point_m, Eigen::Vector3d* to_light, double* intensity_out,
                double* distance_m) const;
};

// Radiance (0..1 scale, before exposure) of a surface point, per channel:
// albedo * (ambient * ambient_colour + direct * cos * direct_colour).
// `direct_out` receives the direct part alone (for cast shadows), when non-null.
Eigen::Vector3f Shade(const Material& material, const Eigen::Vector3d& point_m, const Eigen::Vector3d& normal,
                      const Lighting& lighting, Eigen::Vector3f* direct_out = nullptr);

// Integer hashing used by patterns and noise (SplitMix64 finaliser).
inline uint64_t Mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
// A deterministic uniform double in [0, 1) from a hash.
inline double UnitFromHash(uint64_t h) { return static_cast<double>(h >> 11) * 0x1.0p-53; }

}  // namespace occmap::sim
