// Detection: one object found on the floor in one frame, what the trackers measure. It is the
// output of every detector in this module: the ObjectDetector's (a part of a group of occupied
// cells) and any other's that has no map at all (a position, an area, a spread, a class hint).
// What a detection came from, when it came from a map, is its `group` in the frame's
// ObjectFrame (object_frame.h); the tracker's guided split applies only to those.
//
//   Detection d;                  // from a detector without groups
//   d.x_m = 2.0, d.y_m = 3.1, d.area_m2 = 0.2, d.spread_m2 = 0.01 * Eigen::Matrix2d::Identity();
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>

namespace occmap {

struct Detection {
  double x_m = 0, y_m = 0;  // floor position (world metres)
  // Footprint area (0 when the detector does not know it): the trackers' class by area.
  double area_m2 = 0;
  // Cells it was measured from (0 for a detector without a map).
  int64_t cells = 0;
  // Covariance of the position's spread: of its cells' centres for a detection from a map, the
  // detector's own estimate otherwise; 0 when unknown (and for a guided cut). The tracker
  // counts the part beyond one person's disc as measurement noise.
  Eigen::Matrix2d spread_m2 = Eigen::Matrix2d::Zero();
  // A class the detector is sure of ("" none): a tracker with a class of this name takes it
  // instead of the class by area.
  std::string class_hint;
  // Index of the group it was cut from (ObjectFrame::groups, or the blob for the split
  // functions of split.h); -1 when it comes from no group.
  int group = -1;
  int parts = 1;        // how many detections that group gave
  bool guided = false;  // placed by the tracks' predictions (object_frame.h), not by a shape
};

}  // namespace occmap
