// The real gopro4 masks (4 GoPro cameras, 480x270 background-subtraction masks): the reference
// Probabilistic Occupancy Map implementation detects 4 people in this frame set.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "occmap/pipeline/run.h"
#include "occmap/util/file_util.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

// tolerance_px < 0: the site file's own setting.
Result<RunSummary> RunGoPro4(const fs::path& root, const fs::path& out, int tolerance_px,
                             FusionMethod method = FusionMethod::kImageBased, int max_free_views = 0) {
  SiteLoadOptions load;
  load.data_root = root;
  OCCMAP_ASSIGN_OR_RETURN(Site site, LoadSite(fs::path(OCCMAP_SOURCE_DIR) / "sites" / "gopro4.yaml", load));
  if (tolerance_px >= 0) site.detection.tolerance_px = tolerance_px;
  site.fusion.method = method;
  site.fusion.max_free_views = max_free_views;
  RunOptions o;
  o.out_dir = out;
  o.occupancy_pngs = true;
  o.wall_clock_times = false;  // runs are compared line by line
  o.occupancy_video = o.mosaic_video = false;
  Context ctx(2);
  return RunSite(site, o, ctx);
}

TEST(GoPro4, ReportsFourPeopleLikeTheReferencePom) {
  OCCMAP_REQUIRE_DATASETS(root);
  testing::TempDir dir;
  auto summary = RunGoPro4(root, dir.path(), /*tolerance_px=*/-1);  // sites/gopro4.yaml: 5 px
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  ASSERT_EQ(summary->frames, 1);
  const std::string detections = *ReadFileToString(dir / "detections.jsonl");
  EXPECT_EQ(summary->blobs_max_per_frame, 4) << detections;
  // Each detection is person-sized: 0.1 to 1 m^2 of floor.
  const auto line = nlohmann::json::parse(detections);
  for (const auto& b : line["blobs"]) {
    EXPECT_GT(b["area_m2"].get<double>(), 0.1) << detections;
    EXPECT_LT(b["area_m2"].get<double>(), 1.0) << detections;
  }
}

TEST(GoPro4, AStrictAndOfTheRawMasksLosesPeople) {
  OCCMAP_REQUIRE_DATASETS(root);
  testing::TempDir dir;
  auto summary = RunGoPro4(root, dir.path(), /*tolerance_px=*/0);
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  EXPECT_LT(summary->blobs_max_per_frame, 4);
}

TEST(GoPro4, ToleranceOfFourOrFivePixelsFindsTheFourPeople) {
  OCCMAP_REQUIRE_DATASETS(root);
  for (int t : {4, 5}) {
    testing::TempDir dir;
    auto summary = RunGoPro4(root, dir.path(), t);
    ASSERT_TRUE(summary.ok()) << summary.status().message();
    EXPECT_EQ(summary->blobs_max_per_frame, 4) << "tolerance " << t;
  }
}

TEST(GoPro4, ImageBasedAndMapBasedFusionGiveIdenticalMapsOnRealMasks) {
  OCCMAP_REQUIRE_DATASETS(root);
  for (int tolerance : {0, 2, 5}) {
    for (int k : {0, 1}) {
      testing::TempDir image, map;
      ASSERT_TRUE(RunGoPro4(root, image.path(), tolerance, FusionMethod::kImageBased, k).ok());
      ASSERT_TRUE(RunGoPro4(root, map.path(), tolerance, FusionMethod::kMapBased, k).ok());
      EXPECT_EQ(*ReadFileToString(image / "occupancy" / "000000.png"), *ReadFileToString(map / "occupancy" / "000000.png"))
          << "tolerance " << tolerance << ", k " << k;
      EXPECT_EQ(*ReadFileToString(image / "detections.jsonl"), *ReadFileToString(map / "detections.jsonl"));
    }
  }
}

}  // namespace
}  // namespace occmap
