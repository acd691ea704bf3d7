// HomographyCamera: a plain image <-> floor homography, for sites calibrated only that way.
//
// floor_from_image maps a pixel (u, v, 1) to homogeneous floor coordinates in metres on the
// plane z = 0. It knows nothing of 3D: Project accepts only points on z = 0, BackProject has no
// ray, and lookup tables for planes above the floor cannot be built from it.
// The floor is seen where the homogeneous scale w of H (u, v, 1) has the sign it has at the
// bottom-centre pixel of the image (a camera looking at a floor sees it at the bottom of its
// picture); pixels with the other sign are beyond the horizon.
//
//   OCCMAP_ASSIGN_OR_RETURN(HomographyCamera cam, HomographyCamera::Create(h, {640, 480}));
//   auto floor_m = cam.PixelToPlane({320, 400}, 0.0);
#pragma once

#include <Eigen/Core>

#include "occmap/geometry/camera_model.h"
#include "occmap/util/status.h"

namespace occmap {

class HomographyCamera final : public CameraModel {
 public:
  static Result<HomographyCamera> Create(const Eigen::Matrix3d& floor_from_image,
                                         ImageSize image_size);

  std::string_view kind() const override { return "homography"; }
  ImageSize image_size() const override { return image_size_; }
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point_in_world) const override;
  std::optional<Ray> BackProject(const Eigen::Vector2d&) const override { return std::nullopt; }
  std::optional<Eigen::Vector2d> PixelToPlane(const Eigen::Vector2d& pixel,
                                              double plane_z_m) const override;
  bool SupportsPlaneHeight(double plane_z_m) const override { return plane_z_m == 0.0; }
  std::unique_ptr<CameraModel> Resized(ImageSize new_size) const override;
  std::unique_ptr<CameraModel> Clone() const override;
  void AppendToHash(Hasher& hasher) const override;
  std::optional<Eigen::Vector3d> CenterInWorld() const override { return std::nullopt; }

  const Eigen::Matrix3d& floor_from_image() const { return floor_from_image_; }

 private:
  HomographyCamera(const Eigen::Matrix3d& h, ImageSize size);
  Eigen::Matrix3d floor_from_image_;
  Eigen::Matrix3d image_from_floor_;
  ImageSize image_size_;
  double visible_w_sign_ = 1;
};

}  // namespace occmap
