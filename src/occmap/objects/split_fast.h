// The fast split (the one the ObjectDetector runs every frame): the same BlobSplit as the plain
// SplitBlob of split.h, bit for bit (tested on random groups), with
//  - buffers reused from one call to the next (SplitScratch: the distance transform, the
//    peaks' union-find, the k-means points and labels), so that a frame's splits allocate
//    little more than their results;
//  - the distance transform in integers (the row envelopes' intersections kept as fractions);
//  - the k-means on flat arrays with Hamerly's bounds (a point's nearest centre is looked for
//    again only when its bound says it may have changed; AVX2 when the CPU has it).
//
//   SplitScratch scratch;   // one per caller, not shared between threads
//   BlobSplit split = SplitBlob(group, grown, finder.labels(), label, options, scratch);
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/objects/object_options.h"
#include "occmap/objects/split.h"

namespace occmap {

// Buffers SplitBlob reuses from one call to the next (the distance transform, the peaks'
// union-find, the k-means points and labels): with one per caller, a frame's splits allocate
// little more than their results. Not shared between threads.
struct SplitScratch {
  std::vector<uint8_t> inside;
  std::vector<int> g, v, locals, start, sorted, parent, peak, rank_of, significant, label;
  std::vector<uint32_t> recompute;
  std::vector<int64_t> ci, cj, sum_i, sum_j, counts, z_num, z_den;
  std::vector<int> previous;
  std::vector<double> d2, f, z, xs, ys, centre_x, centre_y, shift;
  std::vector<float> gap, shift_f;
  std::vector<Eigen::Vector2d> peaks;
  std::vector<std::vector<int64_t>> parts;
};
// The same split as SplitBlob (equal, tested), with scratch buffers reused and the k-means on
// flat arrays.
BlobSplit SplitBlob(const Blob& blob, const OccupancyMap& map, const ObjectOptions& options, SplitScratch& scratch);
// The same split of a blob found by a BlobFinder (or FindBlobs) on `map`: its cells are those
// of its label, read from the box (no search of the map, no relabelling where other blobs
// reach into the box; the same cells as BlobCells, tested).
BlobSplit SplitBlob(const Blob& blob, const OccupancyMap& map, std::span<const int32_t> labels, int32_t label,
                    const ObjectOptions& options, SplitScratch& scratch);
// The split from the blob's cells as BlobCells gives them (sorted, one component).
BlobSplit SplitBlobCells(const Blob& blob, const FloorGrid& grid, std::vector<int64_t> blob_cells,
                         const ObjectOptions& options, SplitScratch& scratch);

}  // namespace occmap
