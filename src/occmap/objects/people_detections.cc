#include "occmap/objects/people_detections.h"

#include <numbers>

#include "occmap/fusion/blobs.h"

namespace occmap {

void PeopleDetections(const std::vector<ExplainedPerson>& people, const FloorGrid& candidates, double person_radius_m,
                      ObjectFrame& frame) {
  frame.grid = candidates;
  frame.detections.clear();
  frame.groups.clear();
  const double r = person_radius_m;
  const double step_m = candidates.cell_size_m;
  for (const ExplainedPerson& p : people) {
    Detection d;
    d.x_m = p.x_m;
    d.y_m = p.y_m;
    d.area_m2 = std::numbers::pi * r * r;
    d.spread_m2 = Eigen::Matrix2d::Identity() * (r * r / 4 + step_m * step_m);
    d.class_hint = "person";
    frame.detections.push_back(d);
  }
}

void ColumnMapDetections(const OccupancyMap& column_map, ObjectFrame& frame) {
  frame.grid = column_map.grid();
  frame.detections.clear();
  frame.groups.clear();
  for (const Blob& b : FindBlobs(column_map)) {
    Detection d;
    d.x_m = b.x_m;
    d.y_m = b.y_m;
    d.area_m2 = b.area_m2;
    d.cells = b.cells;
    frame.detections.push_back(d);
  }
}

}  // namespace occmap
