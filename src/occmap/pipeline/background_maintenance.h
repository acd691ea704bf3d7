// What only a multi-camera system knows when it updates a background: where the fused map says
// something stands, and whether that something is a person.
//
// From each frame's map (after the fusion), every group of occupied cells of at least
// min_area_m2 is an object; its cells' bounding box, widened by margin_m, is lifted to a box
// of height_m and projected into every camera: the pixels inside the projection are protected
// (BackgroundModel::kObject) and do not follow the frame. An object is a person when the
// cameras that see it see change at person_height_m above its centroid (a majority of them,
// read in a window of 2 pixels around the projection): its pixels are kPerson, and a person
// is never absorbed into the background however long it stands. The rest of the image is
// kFree: what changes there is not an object on the floor, and becomes background.
//
//   BackgroundProtection protection(cameras, options);
//   protection.Compute(map, changes, active);      // after the fusion of a frame
//   model.Update(frame, protection.image(n).view(), frame_index);
#pragma once

#include <cstdint>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/geometry/camera_model.h"
#include "occmap/util/image.h"

namespace occmap {

struct ProtectionOptions {
  double min_area_m2 = 0.01;     // smaller specks of occupied cells protect nothing
  double margin_m = 0.25;        // around an object's cells
  double height_m = 2.1;         // of the protected box
  double person_height_m = 1.2;  // change seen here above the centroid: a person
};

class BackgroundProtection {
 public:
  // The cameras (at run-time image size) must outlive this.
  BackgroundProtection(std::vector<const CameraModel*> cameras, double plane_height_m, ProtectionOptions options);

  // changes[n]: camera n's change mask of this frame (non-zero = changed), empty when the
  // camera is not active (then its image is all kFree, and it does not vote on persons).
  void Compute(const OccupancyMap& map, const std::vector<ImageView<const uint8_t>>& changes);

  const Image<uint8_t>& image(size_t camera) const { return images_[camera]; }
  int objects() const { return objects_; }
  int persons() const { return persons_; }

 private:
  std::vector<const CameraModel*> cameras_;
  double plane_height_m_;
  ProtectionOptions options_;
  std::vector<Image<uint8_t>> images_;
  BlobFinder finder_;
  int objects_ = 0, persons_ = 0;
};

}  // namespace occmap
