// CameraModel: forward projection (world point -> pixel) and back-projection (pixel -> ray ->
// point on a horizontal plane), the paper's transform T_n (equations 1, 2 and 6-20).
//
// Conventions, stated once for all of occmap:
// - World frame: metres; the support plane is horizontal, z = plane height (0 = the floor); z
//   points away from the floor towards the cameras. Calibrations in other units are converted
//   to metres when they are read (calib/), never later. Datasets whose world is left-handed
//   (MultiviewX) keep their frame; only the sign of the camera's optical axis changes (below).
// - Camera frame: x along increasing image columns, y along increasing image rows, z along the
//   optical axis. point_in_cam = cam_from_world_rotation * point_in_world +
//   cam_from_world_translation_m. A point is in front of the camera when
//   forward_sign * z_cam > 0; forward_sign is +1 for every ordinary calibration.
// - Pixels: (u, v) = (column, row). Pixel (c, r) has its centre at (c, r) and covers
//   [c - 0.5, c + 0.5) x [r - 0.5, r + 0.5); the top-left corner of the image is (-0.5, -0.5).
//   This is the convention of OpenCV and of Willson's Tsai code, so calibrations need no shift.
//
//   std::unique_ptr<CameraModel> cam = ...;                 // see calib/ for readers
//   std::optional<Eigen::Vector2d> px = cam->Project({1.0, 2.0, 0.0});
//   std::optional<Eigen::Vector2d> floor_m = cam->PixelToPlane({640, 480}, 0.0);
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string_view>

#include "occmap/util/hash.h"

namespace occmap {

struct ImageSize {
  int width = 0;
  int height = 0;
  friend bool operator==(const ImageSize&, const ImageSize&) = default;
};

// A viewing ray: the points origin + d * direction, d > 0, are the ones the pixel sees.
struct Ray {
  Eigen::Vector3d origin_in_world;
  Eigen::Vector3d direction_in_world;  // unit length
};

class CameraModel {
 public:
  virtual ~CameraModel() = default;

  // "tsai", "pinhole" (OpenCV / Brown-Conrady) or "homography".
  virtual std::string_view kind() const = 0;
  virtual ImageSize image_size() const = 0;

  // World point -> pixel. nullopt when the point is not in front of the camera or lies outside
  // the domain where the lens model is invertible. Image bounds are not checked (InImage).
  virtual std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point_in_world) const = 0;

  // Pixel -> the ray it sees. nullopt outside the lens model's valid domain, or for models
  // without 3D rays (homography).
  virtual std::optional<Ray> BackProject(const Eigen::Vector2d& pixel) const = 0;

  // Pixel -> the point (x, y) where its ray meets the plane z = plane_z_m in front of the
  // camera (d > 0, the paper's equation 2). nullopt when the ray is parallel to the plane,
  // meets it behind the camera, or the pixel is outside the model's domain.
  virtual std::optional<Eigen::Vector2d> PixelToPlane(const Eigen::Vector2d& pixel,
                                                      double plane_z_m) const;

  // Whether PixelToPlane / Project work for the plane z = plane_z_m (homographies know one).
  virtual bool SupportsPlaneHeight(double plane_z_m) const;

  // The same physical camera for images resized to new_size (e.g. quarter-size masks).
  virtual std::unique_ptr<CameraModel> Resized(ImageSize new_size) const = 0;
  virtual std::unique_ptr<CameraModel> Clone() const = 0;

  // Adds every parameter that changes the geometry (for lookup-table cache keys).
  virtual void AppendToHash(Hasher& hasher) const = 0;

  // The optical centre in world coordinates; nullopt for homographies.
  virtual std::optional<Eigen::Vector3d> CenterInWorld() const = 0;

  // True when the pixel position lies on the image: [-0.5, w - 0.5) x [-0.5, h - 0.5).
  bool InImage(const Eigen::Vector2d& pixel) const;
};

// Intersects a ray with the plane z = plane_z_m in front of its origin.
std::optional<Eigen::Vector2d> IntersectRayWithPlane(const Ray& ray, double plane_z_m);

// The pixel-coordinate map for resizing an image of old_size to new_size, under the pixel
// convention above: u' = (u + 0.5) * scale_x - 0.5.
struct PixelRescale {
  double scale_x = 1, scale_y = 1;
  static PixelRescale Between(ImageSize old_size, ImageSize new_size);
  double MapU(double u) const { return (u + 0.5) * scale_x - 0.5; }
  double MapV(double v) const { return (v + 0.5) * scale_y - 0.5; }
};

// Intrinsics of a pinhole model (any struct with image_size, fx_px, fy_px, cx_px, cy_px and
// skew_px) for images resized to new_size: focal lengths and skew scale with the pixels, the
// principal point maps as a pixel (PixelRescale).
template <class Intrinsics>
Intrinsics ResizedIntrinsics(Intrinsics k, ImageSize new_size) {
  const PixelRescale s = PixelRescale::Between(k.image_size, new_size);
  k.image_size = new_size;
  k.fx_px *= s.scale_x;
  k.skew_px *= s.scale_x;
  k.fy_px *= s.scale_y;
  k.cx_px = s.MapU(k.cx_px);
  k.cy_px = s.MapV(k.cy_px);
  return k;
}

}  // namespace occmap
