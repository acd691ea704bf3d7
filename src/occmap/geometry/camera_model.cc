#include "occmap/geometry/camera_model.h"

#include <cmath>

namespace occmap {

std::optional<Eigen::Vector2d> IntersectRayWithPlane(const Ray& ray, double plane_z_m) {
  const double dz = ray.direction_in_world.z();
  if (std::abs(dz) < 1e-15) return std::nullopt;
  const double d = (plane_z_m - ray.origin_in_world.z()) / dz;
  if (!(d > 0) || !std::isfinite(d)) return std::nullopt;
  return Eigen::Vector2d(ray.origin_in_world.x() + d * ray.direction_in_world.x(),
                         ray.origin_in_world.y() + d * ray.direction_in_world.y());
}

std::optional<Eigen::Vector2d> CameraModel::PixelToPlane(const Eigen::Vector2d& pixel,
                                                         double plane_z_m) const {
  const std::optional<Ray> ray = BackProject(pixel);
  if (!ray) return std::nullopt;
  return IntersectRayWithPlane(*ray, plane_z_m);
}

bool CameraModel::SupportsPlaneHeight(double) const { return true; }

bool CameraModel::InImage(const Eigen::Vector2d& pixel) const {
  const ImageSize size = image_size();
  return pixel.x() >= -0.5 && pixel.y() >= -0.5 && pixel.x() < size.width - 0.5 &&
         pixel.y() < size.height - 0.5;
}

PixelRescale PixelRescale::Between(ImageSize old_size, ImageSize new_size) {
  return {static_cast<double>(new_size.width) / old_size.width,
          static_cast<double>(new_size.height) / old_size.height};
}

}  // namespace occmap
