#include "occmap/objects/object_detector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "occmap/lut/test_scene.h"

namespace occmap {
namespace {

// A small room (four cameras in the corners) with two occupied discs on the floor map: a
// standing object (a 1.7 m cylinder whose silhouette every camera's changes show) and a flat
// one (occupied on the floor only: what a ghost looks like from the planes above).
class ObjectDetectorTest : public ::testing::Test {
 protected:
  static constexpr double kRadius = 0.2;
  const Eigen::Vector2d standing_{1.2, 1.5};
  const Eigen::Vector2d flat_{2.9, 1.4};

  void SetUp() override {
    map_ = OccupancyMap(room_.grid);
    for (int64_t i = 0; i < room_.grid.num_cells(); ++i) {
      const Eigen::Vector2d c = room_.grid.CellCenter(i);
      const bool on = (c - standing_).norm() < kRadius || (c - flat_).norm() < kRadius;
      map_.states()[static_cast<size_t>(i)] = on ? CellState::kOccupied : CellState::kFree;
    }
    // Each camera's changed pixels: the standing cylinder's silhouette, sampled densely.
    changed_.resize(room_.cameras.size());
    for (size_t n = 0; n < room_.cameras.size(); ++n) {
      for (double z = 0; z <= 1.7; z += 0.01) {
        for (double r = 0; r <= kRadius; r += 0.01) {
          for (double a = 0; a < 2 * M_PI; a += 0.05) {
            const Eigen::Vector3d p(standing_.x() + r * std::cos(a), standing_.y() + r * std::sin(a), z);
            const auto px = room_.cameras[n].Project(p);
            if (px) changed_[n].insert({static_cast<int>(std::lround(px->x())), static_cast<int>(std::lround(px->y()))});
          }
        }
      }
    }
    for (const PinholeCamera& c : room_.cameras) views_.push_back({&c, nullptr});
  }

  ObjectDetector::ChangeLookup Lookup() const {
    return [this](int n, int x, int y) { return changed_[static_cast<size_t>(n)].count({x, y}) > 0; };
  }

  static ObjectOptions Settings(std::vector<double> heights) {
    ObjectOptions s;
    s.min_area_m2 = 0.01;
    s.remove_ghosts = false;  // this test is about the elevated check alone
    s.support_heights_m = std::move(heights);
    return s;
  }

  testing::SmallRoom room_{320, 240};
  OccupancyMap map_;
  std::vector<std::set<std::pair<int, int>>> changed_;
  std::vector<ObjectDetector::CameraView> views_;
  std::vector<bool> all_active_ = std::vector<bool>(4, true);
};

TEST_F(ObjectDetectorTest, WithoutTheElevatedCheckBothDiscsAreDetections) {
  ObjectDetector detector(Settings({}), 0.0, views_);
  DetectedObjects out;
  detector.Detect(map_, all_active_, Lookup(), out);
  ASSERT_EQ(out.detections.size(), 2u);
  EXPECT_EQ(out.groups.size(), 2u);
}

TEST_F(ObjectDetectorTest, AFlatDetectionIsDroppedAndAStandingOneKept) {
  ObjectDetector detector(Settings({0.35, 1.0}), 0.0, views_);
  DetectedObjects out;
  detector.Detect(map_, all_active_, Lookup(), out);
  ASSERT_EQ(out.detections.size(), 1u);
  EXPECT_NEAR(out.detections[0].x_m, standing_.x(), 0.03);
  EXPECT_NEAR(out.detections[0].y_m, standing_.y(), 0.03);
  ASSERT_EQ(out.groups.size(), 1u) << "the tracker gets only the groups that hold a kept detection";
  EXPECT_NEAR(out.groups[0].group.x_m, standing_.x(), 0.03);
}

TEST_F(ObjectDetectorTest, AnyPlaneThatSupportsTheObjectKeepsIt) {
  // Only a plane above the cylinder (2 m): it is free over both discs, and it drops both;
  // with a plane at 0.5 m beside it, the standing one is supported again (any plane suffices).
  DetectedObjects out;
  ObjectDetector above(Settings({2.0}), 0.0, views_);
  above.Detect(map_, all_active_, Lookup(), out);
  EXPECT_TRUE(out.detections.empty());
  ObjectDetector both(Settings({2.0, 0.5}), 0.0, views_);
  both.Detect(map_, all_active_, Lookup(), out);
  ASSERT_EQ(out.detections.size(), 1u);
  EXPECT_NEAR(out.detections[0].x_m, standing_.x(), 0.03);
}

TEST_F(ObjectDetectorTest, WithoutChangesOrCamerasThereIsNoEvidenceAgainst) {
  ObjectDetector detector(Settings({0.35}), 0.0, views_);
  DetectedObjects out;
  // No change lookup (a path that has no per-pixel changes): the check is skipped.
  detector.Detect(map_, all_active_, {}, out);
  EXPECT_EQ(out.detections.size(), 2u);
  // No active camera: no plane sees anything, nothing speaks against either.
  detector.Detect(map_, std::vector<bool>(4, false), Lookup(), out);
  EXPECT_EQ(out.detections.size(), 2u);
}

TEST_F(ObjectDetectorTest, ACameraThatSeesTheFlatDiscFreeIsEnoughToDropIt) {
  // With only one camera active, the flat disc is still seen free above the floor by it.
  std::vector<bool> one(4, false);
  one[2] = true;
  ObjectDetector detector(Settings({0.35}), 0.0, views_);
  DetectedObjects out;
  detector.Detect(map_, one, Lookup(), out);
  ASSERT_EQ(out.detections.size(), 1u);
  EXPECT_NEAR(out.detections[0].x_m, standing_.x(), 0.03);
}

TEST_F(ObjectDetectorTest, ASmallFootprintIsKeptWhenThePlanesShowItStanding) {
  // Only the 4 cells (0.01 m2) nearest each object's centre are left on the floor (legs, shoes
  // lost to the change test): under min_area_m2 (0.02), over a fifth of it. The planes show the
  // standing cylinder whole.
  for (int64_t i = 0; i < room_.grid.num_cells(); ++i) {
    const Eigen::Vector2d c = room_.grid.CellCenter(i);
    const bool on = (c - standing_).norm() < 0.05 || (c - flat_).norm() < 0.05;
    map_.states()[static_cast<size_t>(i)] = on ? CellState::kOccupied : CellState::kFree;
  }
  ObjectOptions settings = Settings({0.35, 1.0});
  settings.min_area_m2 = 0.02;
  settings.split = false;  // the splitter has its own noise floor (min_detection_area_m2)
  DetectedObjects out;
  ObjectDetector standing(settings, 0.0, views_);
  standing.Detect(map_, all_active_, Lookup(), out);
  ASSERT_EQ(out.detections.size(), 1u) << "the flat speck has nothing above it";
  EXPECT_NEAR(out.detections[0].x_m, standing_.x(), 0.03);
  EXPECT_NEAR(out.detections[0].y_m, standing_.y(), 0.03);

  settings.standing_radius_m = 0;  // off: both under min_area_m2
  ObjectDetector off(settings, 0.0, views_);
  off.Detect(map_, all_active_, Lookup(), out);
  EXPECT_TRUE(out.detections.empty());
  settings.standing_radius_m = 0.2;
  settings.min_area_m2 = 0.06;  // 0.01 m2 is under a fifth of it: a speck, whatever stands above
  ObjectDetector tiny(settings, 0.0, views_);
  tiny.Detect(map_, all_active_, Lookup(), out);
  EXPECT_TRUE(out.detections.empty());
}

TEST_F(ObjectDetectorTest, WithoutSplitTheTrackerMeasuresTheDetectionsAsTheyAre) {
  // Two discs touching: one group that the split would cut in two, and two predictions on it.
  OccupancyMap map(room_.grid);
  for (int64_t i = 0; i < room_.grid.num_cells(); ++i) {
    const Eigen::Vector2d c = room_.grid.CellCenter(i);
    const bool on = (c - standing_).norm() < 0.3 || (c - standing_ - Eigen::Vector2d(0.5, 0)).norm() < 0.3;
    map.states()[static_cast<size_t>(i)] = on ? CellState::kOccupied : CellState::kFree;
  }
  const std::vector<Eigen::Vector2d> predictions = {standing_ + Eigen::Vector2d(0.1, 0),
                                                    standing_ + Eigen::Vector2d(0.3, 0),
                                                    standing_ + Eigen::Vector2d(0.4, 0)};
  ObjectOptions options = Settings({});
  DetectedObjects out;
  ObjectDetector(options, 0.0, views_).Detect(map, all_active_, out);
  ASSERT_EQ(out.detections.size(), 2u) << "split at the neck";
  ASSERT_EQ(out.groups.size(), 1u);
  EXPECT_EQ(out.detections[0].group, 0);
  EXPECT_EQ(out.detections[1].group, 0);
  EXPECT_EQ(GuidedDetections(out, predictions).size(), 3u) << "three predictions on two peaks: guided";

  options.split = false;
  ObjectDetector(options, 0.0, views_).Detect(map, all_active_, out);
  ASSERT_EQ(out.detections.size(), 1u);
  ASSERT_EQ(out.groups.size(), 1u);
  EXPECT_TRUE(out.groups[0].split.cells.empty());
  const std::vector<Detection> measured = GuidedDetections(out, predictions);
  ASSERT_EQ(measured.size(), 1u) << "no split, no guided split: the tracker sees detections.jsonl";
  EXPECT_EQ(measured[0].x_m, out.detections[0].x_m);
  EXPECT_EQ(measured[0].y_m, out.detections[0].y_m);
  EXPECT_EQ(measured[0].area_m2, out.detections[0].area_m2);
  EXPECT_FALSE(measured[0].guided);
}

TEST_F(ObjectDetectorTest, ChangeBuffersGiveTheSameDetectionsAsTheLookup) {
  // The fast path (change buffers) against the reference (the lookup): byte images with rows
  // as wide as the image and with padded rows, and ChangeBits' unchanged bits, for several
  // planes and sets of active cameras.
  for (int layout = 0; layout < 3; ++layout) {
    const size_t pad = layout == 1 ? 5 : 0;
    std::vector<std::vector<uint8_t>> pixels(room_.cameras.size());
    std::vector<std::vector<uint64_t>> bits(room_.cameras.size());
    std::vector<ObjectDetector::ChangeBuffer> buffers;
    for (size_t n = 0; n < room_.cameras.size(); ++n) {
      const ImageSize size = room_.cameras[n].image_size();
      const size_t stride = static_cast<size_t>(size.width) + pad;
      const size_t row_words = (static_cast<size_t>(size.width) + 63) / 64;
      pixels[n].assign(stride * static_cast<size_t>(size.height), 0);
      bits[n].assign(row_words * static_cast<size_t>(size.height), ~uint64_t{0});  // all unchanged
      for (const auto& [x, y] : changed_[n]) {
        if (x < 0 || y < 0 || x >= size.width || y >= size.height) continue;
        pixels[n][static_cast<size_t>(y) * stride + x] = 1;
        bits[n][static_cast<size_t>(y) * row_words + static_cast<size_t>(x) / 64] &= ~(uint64_t{1} << (x % 64));
      }
      ObjectDetector::ChangeBuffer b;
      if (layout == 2) {
        b.unchanged_bits = bits[n].data();
        b.row_words = row_words;
      } else {
        b.pixels = pixels[n].data();
        b.stride = stride;
      }
      buffers.push_back(b);
    }
    for (const std::vector<double>& heights : {std::vector<double>{0.35, 1.0}, {2.0}, {2.0, 0.5}, {0.35}}) {
      // One fast detector for all sets of cameras: what it kept from a frame must not leak
      // into the next.
      ObjectDetector fast(Settings(heights), 0.0, views_);
      for (int mask = 0; mask < 16; ++mask) {
        std::vector<bool> active(4);
        for (size_t n = 0; n < 4; ++n) active[n] = (mask >> n) & 1;
        ObjectDetector reference(Settings(heights), 0.0, views_);
        DetectedObjects expected, got;
        reference.Detect(map_, active, Lookup(), expected);
        fast.Detect(map_, active, {}, got, buffers);
        ASSERT_EQ(got.detections.size(), expected.detections.size()) << "layout " << layout << ", mask " << mask;
        for (size_t k = 0; k < got.detections.size(); ++k) {
          EXPECT_EQ(got.detections[k].x_m, expected.detections[k].x_m);
          EXPECT_EQ(got.detections[k].y_m, expected.detections[k].y_m);
          EXPECT_EQ(got.detections[k].cells, expected.detections[k].cells);
        }
        EXPECT_EQ(got.groups.size(), expected.groups.size());
      }
    }
  }
}

// A chair pushed by someone a step behind it (after the lab rendered with --shadows, frame 42 of
// seed 1, cells of 2 cm; the chair moved 10 cm closer): the person's feet and the chair's four
// legs are fragments 0.1 m apart, so one group, with a neck of 3-4 cm between the two parts of
// the grown group. The default neck (3 cm) splits it into the person and the chair; 5 cm (the
// earlier default) kept them as one detection between the two, about 0.5 m from the chair.
TEST(ObjectDetector, SplitsAChairFromThePersonPushingIt) {
  const FloorGrid grid{.origin_x_m = 2.5, .origin_y_m = 2.3, .cells_x = 120, .cells_y = 80, .cell_size_m = 0.02};
  struct Box {
    double x0, x1, y0, y1;
  };
  const Box person[] = {{3.40, 3.48, 3.10, 3.14}, {3.20, 3.56, 3.06, 3.10}, {3.16, 3.56, 2.90, 3.06},
                        {3.16, 3.44, 2.86, 2.90}, {3.04, 3.36, 2.74, 2.86}, {3.08, 3.16, 2.70, 2.74}};
  const Box chair_legs[] = {{4.02, 4.08, 3.22, 3.28}, {3.66, 3.80, 3.14, 3.24}, {4.10, 4.20, 2.86, 2.94},
                            {3.74, 3.84, 2.78, 2.86}};
  OccupancyMap map(grid);
  for (int64_t i = 0; i < grid.num_cells(); ++i) {
    const Eigen::Vector2d c = grid.CellCenter(i);
    auto in = [&](const Box& b) { return c.x() > b.x0 && c.x() < b.x1 && c.y() > b.y0 && c.y() < b.y1; };
    const bool on = std::any_of(std::begin(person), std::end(person), in) ||
                    std::any_of(std::begin(chair_legs), std::end(chair_legs), in);
    map.states()[static_cast<size_t>(i)] = on ? CellState::kOccupied : CellState::kFree;
  }
  ObjectOptions options;  // the lab's blobs: section
  options.group_radius_m = 0.2;
  options.min_area_m2 = 0.015;
  options.remove_ghosts = false;
  const Eigen::Vector2d chair(3.92, 3.03), pusher(3.30, 2.92);
  DetectedObjects out;
  ObjectDetector(options, 0.0, {}).Detect(map, {}, out);
  ASSERT_EQ(out.groups.size(), 1u);
  ASSERT_EQ(out.detections.size(), 2u) << "the chair and its pusher";
  std::vector<Eigen::Vector2d> at;
  for (const Detection& d : out.detections) at.emplace_back(d.x_m, d.y_m);
  std::sort(at.begin(), at.end(), [](const auto& a, const auto& b) { return a.x() < b.x(); });
  EXPECT_LT((at[0] - pusher).norm(), 0.15) << at[0].transpose();
  EXPECT_LT((at[1] - chair).norm(), 0.15) << at[1].transpose();

  options.split_min_neck_m = 0.04;
  ObjectDetector(options, 0.0, {}).Detect(map, {}, out);
  EXPECT_EQ(out.detections.size(), 1u) << "a deeper neck asked: one detection";
}

}  // namespace
}  // namespace occmap
