// Detections from the people's fusions (fusion/people_options.h), for the trackers.
//
// PeopleDetections: each person the views' explanation chose is one detection, without a group
// (the tracker measures exactly these, no guided split); its area is one person's disc, its
// spread that disc's (r^2 / 4) plus the candidate spacing's (the position is a candidate's
// centre: IDF1 0.83 -> 0.86 on rendered WILDTRACK over the disc's alone); class hint "person".
// ColumnMapDetections: the column map's blobs (the `column` detector), one detection each.
// Both set the frame's grid to the candidate grid (the tracker ends tracks that leave it).
#pragma once

#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/fusion/view_explainer.h"
#include "occmap/lut/floor_grid.h"
#include "occmap/objects/object_frame.h"

namespace occmap {

void PeopleDetections(const std::vector<ExplainedPerson>& people, const FloorGrid& candidates, double person_radius_m,
                      ObjectFrame& frame);

void ColumnMapDetections(const OccupancyMap& column_map, ObjectFrame& frame);

}  // namespace occmap
