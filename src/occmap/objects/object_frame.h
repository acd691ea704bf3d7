// ObjectFrame: one frame's detections (detection.h) with the groups of occupied cells they were
// cut from, what a tracker consumes. A detector without a map fills `detections` alone; the
// ObjectDetector also fills `groups`, so that the tracker can redo the split of a group that
// holds more of its tracks than the group's shape shows people (GuidedDetections).
//
// Track-guided detections (the last step of splitting, split.h): when more predicted track
// positions (within guide_radius_m of a group's cells) than distance peaks fall on a group
// that may hold them (BlobSplit::max_people), that group's detections are replaced by those
// predictions shifted together so that their mean is the centroid of the group's footprint:
// the group measures where the people are, the predictions how they stand within it (cutting
// the group between predictions that nearly coincide would pick an arbitrary direction and bend
// the tracks). Each gets an equal share of the footprint's area and cells, no spread,
// guided = true, and extra measurement noise in the tracker.
//
//   ObjectFrame frame;                                   // a detector without groups
//   frame.grid = grid;
//   frame.detections.push_back(d);
//   std::vector<Detection> measured = GuidedDetections(frame, predictions);  // == detections
#pragma once

#include <Eigen/Core>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/objects/detection.h"
#include "occmap/objects/split.h"

namespace occmap {

// A group of occupied cells that gave detections.
struct DetectionGroup {
  Blob group;       // in the map the detector split (fragments grouped): bounding box, cells
  Blob footprint;   // its occupied cells before the grouping: centroid, area, cells
  // Its split (cells, max_people, peaks); no cells (the default) when the detector did not
  // split it: never guided.
  BlobSplit split;
};

struct ObjectFrame {
  FloorGrid grid;
  std::vector<Detection> detections;   // Detection::group indexes `groups` (or is -1)
  std::vector<DetectionGroup> groups;
  double guide_radius_m = 0;           // a prediction this close to a group's cells is on it
};

// The frame's detections, each group where the guided rule applies (above) giving the guided
// ones instead of its own, at the place of its first detection; every other detection as it
// is, in order. `predicted_positions_m`: the tracks' predictions in order of priority (the
// first ones win when a group can hold fewer).
std::vector<Detection> GuidedDetections(const ObjectFrame& frame,
                                        const std::vector<Eigen::Vector2d>& predicted_positions_m);

}  // namespace occmap
