// Grouping (the first step of object detection, ObjectDetector): the fragments of one object: the paper's map holds exactly what touches the floor,
// so a walking person is two feet and a chair four legs. To count and track objects, the
// occupied cells are grown by a radius r (every seen cell within r of an occupied cell becomes
// occupied; unseen cells never do): fragments less than 2r apart join into one blob. Each
// grown blob is then described by the original occupied cells it holds (FootprintBlobs): its
// centroid and area are those of the footprint, not of the growth.
//
//   OccupancyMap grown;
//   GrowOccupied(map, /*radius_m=*/0.15, grown);
//   std::vector<int32_t> labels;
//   std::vector<Blob> groups = FindBlobs(grown, {}, &labels);
//   std::vector<Blob> detections = FootprintBlobs(map, labels, groups);
// (Connected components themselves, FindBlobs and BlobFinder, are fusion/blobs.h's: a plain
// operation on a map that the background maintenance, the window tracker and the evaluation
// use too.)
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"

namespace occmap {

// out may not alias map; its buffers are reused between calls. r <= 0 copies the map.
void GrowOccupied(const OccupancyMap& map, double radius_m, OccupancyMap& out);

// Brute force (every cell against the disc around it), for tests.
void GrowOccupiedReference(const OccupancyMap& map, double radius_m, OccupancyMap& out);

// For each group (a blob of the grown map, with `labels` from FindBlobs on it): the blob of
// the original occupied cells of that group: centroid and area of the footprint, the group's
// bounding box, `cells` the footprint's cell count. A group cut off from its fragment by
// unseen cells holds no original cell: it gets cells = 0 and area 0 (and the group's centroid).
std::vector<Blob> FootprintBlobs(const OccupancyMap& original, const std::vector<int32_t>& labels,
                                 const std::vector<Blob>& groups);

// The same for the groups a BlobFinder found in the grown map, from each group's cells (no scan
// of the whole map); equal to FootprintBlobs(original, groups.labels(), groups.blobs()). With
// `spreads`, also each footprint's spread: the covariance of its cells' centres (m^2; zero for
// a group without footprint).
void FootprintBlobs(const OccupancyMap& original, const BlobFinder& groups, std::vector<Blob>& out,
                    std::vector<Eigen::Matrix2d>* spreads = nullptr);

}  // namespace occmap
