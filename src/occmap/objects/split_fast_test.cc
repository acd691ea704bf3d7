#include "occmap/objects/split_fast.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "occmap/objects/test_floor.h"
#include "occmap/util/simd_testing.h"

namespace occmap {
namespace {

using testing::TestGrid;

// Every kernel set this CPU has (util/simd.h): the AVX2 k-means steps and the portable ones.
class SplitBlobKernels : public KernelSetTest {};

INSTANTIATE_TEST_SUITE_P(KernelSets, SplitBlobKernels, ::testing::Values("portable", "avx2"));

TEST_P(SplitBlobKernels, WithReusedScratchEqualsTheReferenceOnRandomGroups) {
  // Random groups of 1-5 people, noisy discs of several radii: SplitBlob with one scratch
  // reused over all blobs (flat k-means, buffers kept) gives the reference's split exactly.
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> x(1.0, 7.0), y(1.0, 5.0), near(-0.45, 0.45), radius(0.15, 0.3);
  ObjectOptions options;
  SplitScratch scratch;
  int split = 0;
  options.max_people_per_blob = 12;
  for (int trial = 0; trial < 150; ++trial) {
    std::vector<Eigen::Vector2d> people;
    for (int g = 0; g < 3; ++g) {
      const Eigen::Vector2d centre(x(rng), y(rng));
      // Now and then a crowd (k-means with many centres and rounds, as on WILDTRACK).
      const int members = trial % 10 == 0 ? 6 + static_cast<int>(rng() % 7) : 1 + static_cast<int>(rng() % 5);
      for (int m = 0; m < members; ++m) people.push_back(centre + Eigen::Vector2d(near(rng), near(rng)));
    }
    const OccupancyMap map = testing::FloorWithDiscs(TestGrid(), people, radius(rng), testing::kNoisy, rng);
    std::vector<int32_t> labels;
    const std::vector<Blob> blobs = FindBlobs(map, {}, &labels);
    for (size_t index = 0; index < blobs.size(); ++index) {
      const Blob& b = blobs[index];
      const BlobSplit reference = SplitBlob(b, map, options);
      // Every other blob through the cells of its label (the detector's way).
      const BlobSplit fast = index % 2 == 0 ? SplitBlob(b, map, options, scratch)
                                            : SplitBlob(b, map, labels, static_cast<int32_t>(index), options, scratch);
      EXPECT_EQ(fast.cells, reference.cells);
      EXPECT_EQ(fast.max_people, reference.max_people);
      EXPECT_EQ(fast.peaks, reference.peaks);
      ASSERT_EQ(fast.detections.size(), reference.detections.size()) << "trial " << trial;
      for (size_t k = 0; k < fast.detections.size(); ++k) {
        EXPECT_EQ(fast.detections[k].x_m, reference.detections[k].x_m);
        EXPECT_EQ(fast.detections[k].y_m, reference.detections[k].y_m);
        EXPECT_EQ(fast.detections[k].area_m2, reference.detections[k].area_m2);
        EXPECT_EQ(fast.detections[k].cells, reference.detections[k].cells);
        EXPECT_EQ(fast.detections[k].spread_m2, reference.detections[k].spread_m2);
        EXPECT_EQ(fast.detections[k].parts, reference.detections[k].parts);
      }
      split += fast.detections.size() > 1;
      if (!reference.cells.empty() && reference.max_people >= 2) {
        // The peaks themselves: the fast transform and union-find against DistancePeaks.
        const std::vector<Eigen::Vector2d> peaks = DistancePeaks(map.grid(), reference.cells, options);
        EXPECT_EQ(std::min(peaks.size(), static_cast<size_t>(reference.max_people)), fast.peaks);
      }
    }
  }
  EXPECT_GT(split, 30);
}

}  // namespace
}  // namespace occmap
