#include "occmap/objects/split.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "occmap/objects/test_floor.h"

namespace occmap {
namespace {

using testing::FloorWithDiscs;
using testing::TestGrid;

// Detections sorted by x, then y, for stable comparisons.
std::vector<Detection> SortedByX(std::vector<Detection> d) {
  std::sort(d.begin(), d.end(), [](const Detection& a, const Detection& b) {
    return a.x_m != b.x_m ? a.x_m < b.x_m : a.y_m < b.y_m;
  });
  return d;
}

TEST(MaxPeopleInArea, NeedsTheMarginAbovePersonAreasForEachExtraPerson) {
  ObjectOptions options;  // person area = pi 0.25^2 = 0.19635 m^2, margin 0.2
  const double a = options.person_area_m2();
  EXPECT_EQ(MaxPeopleInArea(0.5 * a, options), 1);
  EXPECT_EQ(MaxPeopleInArea(1.19 * a, options), 1);
  EXPECT_EQ(MaxPeopleInArea(1.21 * a, options), 2);
  EXPECT_EQ(MaxPeopleInArea(2.21 * a, options), 3);
  options.max_people_per_blob = 2;
  EXPECT_EQ(MaxPeopleInArea(10 * a, options), 2);
}

TEST(BlobCells, FindsTheBlobAmongOtherBlobsReachingIntoItsBox) {
  // An L-shaped blob whose bounding box also holds a separate square.
  OccupancyMap map = testing::FreeFloor(TestGrid());
  testing::MarkRectangle(map, 1.0, 1.0, 1.04, 2.0);  // vertical bar, 1 cell wide
  testing::MarkRectangle(map, 1.0, 1.0, 2.0, 1.04);  // horizontal bar
  testing::MarkRectangle(map, 1.5, 1.5, 1.7, 1.7);   // a square inside the L's box
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 2u);
  const Blob& l_blob = blobs[0].cells > blobs[1].cells ? blobs[0] : blobs[1];
  const std::vector<int64_t> cells = BlobCells(map, l_blob);
  EXPECT_EQ(static_cast<int64_t>(cells.size()), l_blob.cells);
  for (int64_t c : cells) {
    const Eigen::Vector2d p = map.grid().CellCenter(c);
    EXPECT_TRUE(p.x() < 1.05 || p.y() < 1.05) << p.transpose();
  }
}

TEST(DetectionsFromBlobs, OnePersonIsOneDetectionAtTheBlobCentroid) {
  const OccupancyMap map = FloorWithDiscs(TestGrid(), {{2.0, 3.0}});
  const std::vector<Blob> blobs = FindBlobs(map);
  const std::vector<Detection> d = DetectionsFromBlobs(blobs, map, ObjectOptions{});
  ASSERT_EQ(d.size(), 1u);
  EXPECT_NEAR(d[0].x_m, blobs[0].x_m, 1e-9);
  EXPECT_NEAR(d[0].y_m, blobs[0].y_m, 1e-9);
  EXPECT_NEAR(d[0].area_m2, blobs[0].area_m2, 1e-12);
  EXPECT_EQ(d[0].parts, 1);
  EXPECT_FALSE(d[0].guided);
  // A disc's spread is r^2 / 4 per axis (0.0156 m^2), up to the cells.
  EXPECT_NEAR(d[0].spread_m2(0, 0), 0.25 * 0.25 / 4, 0.002);
}

TEST(DetectionsFromBlobs, MergedBlobOfTwoPeopleStanding0_6mApartIsSplitIntoTwoDetectionsNearThem) {
  // Footprints of radius 0.32 m (legs apart, shadows) 0.6 m apart overlap into one blob.
  for (const Eigen::Vector2d& offset : {Eigen::Vector2d(0.6, 0.0), Eigen::Vector2d(0.0, 0.6),
                                        Eigen::Vector2d(0.6 / std::sqrt(2.0), 0.6 / std::sqrt(2.0))}) {
    const Eigen::Vector2d a(3.0, 2.5), b = a + offset;
    const OccupancyMap map = FloorWithDiscs(TestGrid(), {a, b}, 0.32);
    const std::vector<Blob> blobs = FindBlobs(map);
    ASSERT_EQ(blobs.size(), 1u) << "the two footprints should form one blob";
    const std::vector<Detection> d = DetectionsFromBlobs(blobs, map, ObjectOptions{});
    ASSERT_EQ(d.size(), 2u) << offset.transpose();
    const Eigen::Vector2d p0(d[0].x_m, d[0].y_m), p1(d[1].x_m, d[1].y_m);
    const double error = std::min(std::max((p0 - a).norm(), (p1 - b).norm()), std::max((p0 - b).norm(), (p1 - a).norm()));
    EXPECT_LT(error, 0.05) << offset.transpose() << ": " << p0.transpose() << " / " << p1.transpose();
    EXPECT_EQ(d[0].parts, 2);
    EXPECT_FALSE(d[0].guided);
  }
}

TEST(DetectionsFromBlobs, TwoPeopleHoldingHandsAreSplitAtTheirArms) {
  // Discs of 0.25 m, 0.6 m apart, joined by a 10 cm wide bridge.
  OccupancyMap map = FloorWithDiscs(TestGrid(), {{3.0, 2.5}, {3.6, 2.5}});
  testing::MarkRectangle(map, 3.0, 2.45, 3.6, 2.55);
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 1u);
  const std::vector<Detection> d = SortedByX(DetectionsFromBlobs(blobs, map, ObjectOptions{}));
  ASSERT_EQ(d.size(), 2u);
  EXPECT_NEAR(d[0].x_m, 3.0, 0.05);
  EXPECT_NEAR(d[1].x_m, 3.6, 0.05);
  EXPECT_NEAR(d[0].y_m, 2.5, 0.02);
  EXPECT_NEAR(d[1].y_m, 2.5, 0.02);
}

TEST(DetectionsFromBlobs, ThreePeopleInARowGiveThreeDetections) {
  const OccupancyMap map = FloorWithDiscs(TestGrid(), {{2.0, 3.0}, {2.6, 3.0}, {3.2, 3.0}}, 0.32);
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 1u);
  const std::vector<Detection> d = SortedByX(DetectionsFromBlobs(blobs, map, ObjectOptions{}));
  ASSERT_EQ(d.size(), 3u);
  EXPECT_NEAR(d[0].x_m, 2.0, 0.06);
  EXPECT_NEAR(d[1].x_m, 2.6, 0.02);
  EXPECT_NEAR(d[2].x_m, 3.2, 0.06);
}

TEST(DetectionsFromBlobs, LargeObjectWithoutANeckStaysOneDetection) {
  // A 1 x 0.5 m cart: 2.5 person areas, which splitting by area alone would cut in two or three.
  OccupancyMap map = testing::FreeFloor(TestGrid());
  testing::MarkRectangle(map, 2.0, 2.0, 3.0, 2.5);
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 1u);
  ObjectOptions options;
  ASSERT_GE(MaxPeopleInArea(blobs[0].area_m2, options), 2);
  const std::vector<Detection> d = DetectionsFromBlobs(blobs, map, options);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_NEAR(d[0].x_m, 2.5, 0.03);
  EXPECT_NEAR(d[0].y_m, 2.25, 0.03);
}

TEST(DetectionsFromBlobs, PeopleOverlappingWithoutANeckAreTheTracksPredictionsMovedOntoTheBlob) {
  // 0.2 m apart: one peak, one blob of about 1.5 person areas, centroid (3.1, 3.0).
  const Eigen::Vector2d a(3.0, 3.0), b(3.2, 3.0);
  const OccupancyMap map = FloorWithDiscs(TestGrid(), {a, b});
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 1u);
  const ObjectOptions options;
  EXPECT_EQ(DetectionsFromBlobs(blobs, map, options).size(), 1u) << "no neck: one detection without tracks";

  // Predictions 0.1 m too far up and right: the detections keep their spacing, on the blob.
  const Eigen::Vector2d off(0.1, 0.1);
  const std::vector<Detection> d = SortedByX(DetectionsFromBlobs(blobs, map, options, {b + off, a + off}));
  ASSERT_EQ(d.size(), 2u);
  EXPECT_TRUE(d[0].guided && d[1].guided);
  EXPECT_EQ(d[0].parts, 2);
  EXPECT_NEAR(d[0].x_m, a.x(), 1e-9);
  EXPECT_NEAR(d[0].y_m, a.y(), 1e-9);
  EXPECT_NEAR(d[1].x_m, b.x(), 1e-9);
  EXPECT_NEAR(d[1].y_m, b.y(), 1e-9);
  EXPECT_NEAR(d[0].area_m2 + d[1].area_m2, blobs[0].area_m2, 1e-12);

  // A prediction far away does not count, nor does a blob too small to hold two.
  EXPECT_EQ(DetectionsFromBlobs(blobs, map, options, {a, Eigen::Vector2d(6.0, 3.0)}).size(), 1u);
  const OccupancyMap one = FloorWithDiscs(TestGrid(), {a});
  EXPECT_EQ(DetectionsFromBlobs(FindBlobs(one), one, options, {a, a + Eigen::Vector2d(0.1, 0)}).size(), 1u);
  // Peaks win over predictions when there are as many: two people with a neck.
  const OccupancyMap apart = FloorWithDiscs(TestGrid(), {a, a + Eigen::Vector2d(0.6, 0)}, 0.32);
  const std::vector<Detection> split =
      DetectionsFromBlobs(FindBlobs(apart), apart, options, {a + off, a + Eigen::Vector2d(0.6, 0) + off});
  ASSERT_EQ(split.size(), 2u);
  EXPECT_FALSE(split[0].guided);
}

TEST(DetectionsFromBlobs, BlobsSmallerThanTheMinimumAreaAreIgnored) {
  OccupancyMap map = FloorWithDiscs(TestGrid(), {{2.0, 2.0}});
  map.states()[static_cast<size_t>(map.grid().CellAt(5.0, 5.0))] = CellState::kOccupied;  // one speck
  const std::vector<Blob> blobs = FindBlobs(map);
  ASSERT_EQ(blobs.size(), 2u);
  const std::vector<Detection> d = DetectionsFromBlobs(blobs, map, ObjectOptions{});
  ASSERT_EQ(d.size(), 1u);
  EXPECT_NEAR(d[0].x_m, 2.0, 0.01);
}


TEST(DetectionsFromSplits, EqualsDetectionsFromBlobsWithAndWithoutPredictions) {
  // Random groups of 1-4 people (close together, overlapping or apart), noisy discs, and
  // predictions near and away from them: the split made once gives what the reference gives.
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> x(1.0, 7.0), y(1.0, 5.0), near(-0.35, 0.35);
  ObjectOptions options;
  int guided = 0, split = 0;
  for (int trial = 0; trial < 120; ++trial) {
    std::vector<Eigen::Vector2d> people, predictions;
    for (int g = 0; g < 3; ++g) {
      const Eigen::Vector2d centre(x(rng), y(rng));
      const int members = 1 + static_cast<int>(rng() % 4);
      for (int m = 0; m < members; ++m) people.push_back(centre + Eigen::Vector2d(near(rng), near(rng)));
    }
    for (const Eigen::Vector2d& p : people) {
      if (rng() % 4 != 0) predictions.push_back(p + Eigen::Vector2d(0.3 * near(rng), 0.3 * near(rng)));
    }
    predictions.emplace_back(x(rng), y(rng));
    const OccupancyMap map = testing::FloorWithDiscs(TestGrid(), people, 0.25, testing::kNoisy, rng);
    const std::vector<Blob> blobs = FindBlobs(map);
    std::vector<BlobSplit> splits;
    for (const Blob& b : blobs) splits.push_back(SplitBlob(b, map, options));
    for (const auto& given : {std::vector<Eigen::Vector2d>{}, predictions}) {
      const std::vector<Detection> reference = DetectionsFromBlobs(blobs, map, options, given);
      const std::vector<Detection> fast = DetectionsFromSplits(blobs, splits, map, options, given);
      ASSERT_EQ(fast.size(), reference.size()) << "trial " << trial;
      for (size_t k = 0; k < fast.size(); ++k) {
        EXPECT_EQ(fast[k].x_m, reference[k].x_m);
        EXPECT_EQ(fast[k].y_m, reference[k].y_m);
        EXPECT_EQ(fast[k].area_m2, reference[k].area_m2);
        EXPECT_EQ(fast[k].cells, reference[k].cells);
        EXPECT_EQ(fast[k].spread_m2, reference[k].spread_m2);
        EXPECT_EQ(fast[k].group, reference[k].group);
        EXPECT_EQ(fast[k].parts, reference[k].parts);
        EXPECT_EQ(fast[k].guided, reference[k].guided);
        guided += fast[k].guided;
        split += fast[k].parts > 1 && !fast[k].guided;
      }
    }
  }
  EXPECT_GT(guided, 20);  // both kinds of cut were tested
  EXPECT_GT(split, 20);
}

}  // namespace
}  // namespace occmap
