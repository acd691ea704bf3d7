// Splitting: detections (detection.h), one per object, from the blobs of an occupancy map. A
// blob holding several people (they walk close, or cross) is split.
//
// How a blob is split, and why this way:
//  1. Its cells are found again in the map (BlobCells) and their Euclidean distance
//     transform is computed: the distance of each cell to the nearest cell outside the blob.
//  2. People are the significant peaks of that distance: a secondary peak counts only if it
//     rises at least split_min_neck_m (and one cell size) above the saddle joining it to a
//     higher peak (its persistence: how deep the "neck" between two bodies is) and stands at
//     least split_min_peak_radius_m from the edge. Peaks are found exactly, by merging cells
//     in decreasing order of distance with a union-find.
//  3. The number of detections is capped by the area: a blob holds at most
//     n = floor(area / person_area + 1 - split_area_margin) people (and max_people_per_blob).
//  4. The cells are clustered by k-means seeded at the kept peaks (Lloyd iterations until
//     no cell changes cluster; a cluster's centre is the centre of its cells' mean index, from
//     exact integer sums); each cluster is a detection at its centroid.
//  5. Track-guided detections: when more predicted track positions (within a person's radius
//     of the blob's cells) than peaks fall on a blob that may hold them (step 3), the
//     detections are those predictions shifted together so that their mean is the blob's
//     centroid: the blob measures where the group is, the predictions how its members stand
//     within it (cutting the blob between predictions that nearly coincide would pick an
//     arbitrary direction and bend the tracks). Each gets an equal share of the blob's area,
//     no spread, guided = true, and extra measurement noise in the tracker.
// A large object without a neck (a cart, a person with a long shadow) has one peak and stays
// one detection, which splitting by area alone (k = round(area / person area)) would cut into
// several; two people side by side or crossing have a neck as long as their footprints
// overlap by less than about half a radius; closer than that, the tracks' predictions carry
// them (step 5). Parts smaller than min_detection_area_m2 are dropped.
//
//   std::vector<Blob> blobs = FindBlobs(map);
//   std::vector<Detection> detections = DetectionsFromBlobs(blobs, map, options);
//   for (const Detection& d : detections) ... d.x_m, d.y_m, d.spread_m2 ...
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/objects/detection.h"
#include "occmap/objects/object_options.h"

namespace occmap {

// The cells (map indices, increasing) of a blob FindBlobs found in `map`: the 8-connected
// occupied component in its bounding box with its cell count and centroid. The blob must
// come from this map (checked).
std::vector<int64_t> BlobCells(const OccupancyMap& map, const Blob& blob);

// The detection of a set of cells: centroid and covariance of their centres, area, count.
Detection DetectionFromCells(const FloorGrid& grid, const std::vector<int64_t>& cells);

// The most people a blob of this area may hold (step 3 above), >= 1.
int MaxPeopleInArea(double area_m2, const ObjectOptions& options);

// The peaks of the distance transform of a set of cells (step 2), strongest first, as
// positions in metres. `cells` are map indices of one connected blob.
std::vector<Eigen::Vector2d> DistancePeaks(const FloorGrid& grid, const std::vector<int64_t>& cells,
                                           const ObjectOptions& options);

// Detections of all blobs, in blob order. `predicted_positions_m` are the predictions of the
// tracks that may guide a split, in order of priority (the first ones win when a blob can
// hold fewer).
std::vector<Detection> DetectionsFromBlobs(const std::vector<Blob>& blobs, const OccupancyMap& map,
                                           const ObjectOptions& options,
                                           const std::vector<Eigen::Vector2d>& predicted_positions_m = {});

// DetectionsFromBlobs in two halves, so that a blob is split once per frame although both the
// detector (without predictions) and the tracker (with them) need its detections: SplitBlob
// does what does not depend on predictions (its cells, the peaks, the k-means split), and
// DetectionsFromSplits adds the predictions (step 5), which only matter when more of them
// than peaks fall on a blob. DetectionsFromSplits(blobs, splits, map, options, predictions)
// == DetectionsFromBlobs(blobs, map, options, predictions) when splits[b] ==
// SplitBlob(blobs[b], map, options) for every b (tested).
struct BlobSplit {
  std::vector<int64_t> cells;          // BlobCells (none when the blob is too small to detect)
  int max_people = 1;                  // MaxPeopleInArea
  size_t peaks = 0;                    // distance peaks kept (at most max_people; 0 if max_people < 2)
  std::vector<Detection> detections;   // without predictions, blob_index 0
};
// The plain split, the oracle of the fast one (split_fast.h: SplitBlob with a SplitScratch).
BlobSplit SplitBlob(const Blob& blob, const OccupancyMap& map, const ObjectOptions& options);

// Step 5's two halves, shared with GuidedDetections (object_frame.h): the predictions within
// radius_m of the blob's cells (split.cells; none when it may hold fewer than two), at most
// split.max_people, in the order given ...
std::vector<Eigen::Vector2d> PredictionsOnBlob(const FloorGrid& grid, const Blob& blob, const BlobSplit& split,
                                               double radius_m,
                                               const std::vector<Eigen::Vector2d>& predicted_positions_m);
// ... and the guided detections of a group with the centroid (x_m, y_m), area and cells given:
// the predictions moved together onto the centroid, equal shares (group -1: the caller's).
std::vector<Detection> GuidedCut(double x_m, double y_m, double area_m2, int64_t cells,
                                 const std::vector<Eigen::Vector2d>& inside);
std::vector<Detection> DetectionsFromSplits(const std::vector<Blob>& blobs, const std::vector<BlobSplit>& splits,
                                            const OccupancyMap& map, const ObjectOptions& options,
                                            const std::vector<Eigen::Vector2d>& predicted_positions_m = {});

}  // namespace occmap
