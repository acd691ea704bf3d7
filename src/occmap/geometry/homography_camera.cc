#include "occmap/geometry/homography_camera.h"

#include <Eigen/LU>
#include <fmt/core.h>

#include <cmath>

namespace occmap {

Result<HomographyCamera> HomographyCamera::Create(const Eigen::Matrix3d& h, ImageSize size) {
  if (!h.allFinite()) return InvalidInput("homography: expected finite values, found NaN or infinity");
  if (size.width <= 0 || size.height <= 0) {
    return InvalidInput(fmt::format("image size: expected positive, found {}x{}", size.width, size.height));
  }
  const double det = h.determinant();
  const double scale = h.cwiseAbs().maxCoeff();
  if (!(std::abs(det) > 1e-12 * scale * scale * scale)) {
    return InvalidInput(fmt::format("homography: expected an invertible matrix, found determinant {:.3g}", det));
  }
  HomographyCamera cam(h, size);
  const Eigen::Vector3d bottom = h * Eigen::Vector3d(0.5 * (size.width - 1), size.height - 1, 1);
  if (bottom.z() == 0) return InvalidInput("homography: the bottom-centre pixel maps to infinity");
  return cam;
}

HomographyCamera::HomographyCamera(const Eigen::Matrix3d& h, ImageSize size)
    : floor_from_image_(h), image_from_floor_(h.inverse()), image_size_(size) {
  const Eigen::Vector3d bottom = h * Eigen::Vector3d(0.5 * (size.width - 1), size.height - 1, 1);
  visible_w_sign_ = bottom.z() < 0 ? -1.0 : 1.0;
}

std::optional<Eigen::Vector2d> HomographyCamera::Project(const Eigen::Vector3d& p) const {
  if (std::abs(p.z()) > 1e-9) return std::nullopt;  // only points on the floor (to rounding)
  const Eigen::Vector3d q = image_from_floor_ * Eigen::Vector3d(p.x(), p.y(), 1);
  // H (q / q_z) = (x, y, 1) / q_z, so that pixel's scale w is 1 / q_z.
  if (!(visible_w_sign_ * q.z() > 0)) return std::nullopt;
  return Eigen::Vector2d(q.x() / q.z(), q.y() / q.z());
}

std::optional<Eigen::Vector2d> HomographyCamera::PixelToPlane(const Eigen::Vector2d& pixel,
                                                              double plane_z_m) const {
  if (plane_z_m != 0.0) return std::nullopt;
  const Eigen::Vector3d f = floor_from_image_ * Eigen::Vector3d(pixel.x(), pixel.y(), 1);
  if (!(visible_w_sign_ * f.z() > 0)) return std::nullopt;
  return Eigen::Vector2d(f.x() / f.z(), f.y() / f.z());
}

std::unique_ptr<CameraModel> HomographyCamera::Resized(ImageSize new_size) const {
  const PixelRescale s = PixelRescale::Between(image_size_, new_size);
  // new pixel = A old pixel, with A = [sx 0 (sx-1)/2; 0 sy (sy-1)/2; 0 0 1].
  Eigen::Matrix3d a;
  a << s.scale_x, 0, 0.5 * s.scale_x - 0.5, 0, s.scale_y, 0.5 * s.scale_y - 0.5, 0, 0, 1;
  return std::make_unique<HomographyCamera>(HomographyCamera(floor_from_image_ * a.inverse(), new_size));
}

std::unique_ptr<CameraModel> HomographyCamera::Clone() const {
  return std::make_unique<HomographyCamera>(*this);
}

void HomographyCamera::AppendToHash(Hasher& h) const {
  h.Add("homography");
  h.AddPod(image_size_.width);
  h.AddPod(image_size_.height);
  h.AddBytes(floor_from_image_.data(), sizeof(double) * 9);
}

}  // namespace occmap
