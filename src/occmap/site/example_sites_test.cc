// The example site files in sites/ load as they are and give complete tables (needs
// ../shared/datasets; skipped when absent).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "occmap/site/site.h"
#include "occmap/site/site_lut.h"
#include "occmap/util/testing.h"

#ifndef OCCMAP_SOURCE_DIR
#error "OCCMAP_SOURCE_DIR must be defined"
#endif

namespace occmap {
namespace {
namespace fs = std::filesystem;

fs::path SitePath(const char* name) { return fs::path(OCCMAP_SOURCE_DIR) / "sites" / name; }

// Every cell whose centre projects into a camera's image (onto an unmasked pixel) has at least
// one pixel of that camera in L2. Returns the number of (camera, cell) pairs checked.
int64_t ExpectEveryCellInViewHasAPixel(const Site& site, const GroundLut& lut) {
  int64_t checked = 0;
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const CameraModel& cam = *site.cameras[n].camera;
    int64_t missing = 0;
    for (int64_t cell = 0; cell < lut.grid().num_cells(); ++cell) {
      const Eigen::Vector2d c = lut.grid().CellCenter(cell);
      const auto px = cam.Project({c.x(), c.y(), lut.plane_height_m()});
      if (!px || !cam.InImage(*px)) continue;
      const int x = static_cast<int>(std::lround(px->x())), y = static_cast<int>(std::lround(px->y()));
      if (!site.cameras[n].mask.empty() && site.cameras[n].mask(std::clamp(x, 0, cam.image_size().width - 1),
                                                                std::clamp(y, 0, cam.image_size().height - 1)) == 0) {
        continue;
      }
      ++checked;
      bool found = false;
      for (uint32_t p : lut.l2_pixels_of(cell)) {
        found |= p >= lut.pixel_offset(n) && p < lut.pixel_offset(n + 1);
      }
      missing += !found;
    }
    EXPECT_EQ(missing, 0) << site.cameras[n].id;
  }
  return checked;
}

class ExampleSite : public ::testing::TestWithParam<const char*> {};

TEST_P(ExampleSite, LoadsAndEveryCellInViewHasAPixel) {
  OCCMAP_REQUIRE_DATASETS(root);
  SiteLoadOptions options;
  options.data_root = root;
  auto site = LoadSite(SitePath(GetParam()), options);
  ASSERT_TRUE(site.ok()) << site.status().message();
  Context ctx(0);
  auto cached = LoadOrBuildSiteLut(*site, {}, ctx);
  ASSERT_TRUE(cached.ok()) << cached.status().message();
  EXPECT_GT(ExpectEveryCellInViewHasAPixel(*site, cached->lut), 1000);
  const GridCoverage g = SummarizeCoverage(cached->lut);
  EXPECT_GT(g.cells_seen_by_at_least[1], g.cells * 9 / 10);  // the example grids are in view
}

INSTANTIATE_TEST_SUITE_P(Sites, ExampleSite,
                         ::testing::Values("wildtrack.yaml", "multiviewx.yaml", "gopro4.yaml", "terrace.yaml",
                                           "terrace-video.yaml"),
                         [](const ::testing::TestParamInfo<const char*>& param_info) {
                           std::string name = fs::path(param_info.param).stem().string();
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// The real terrace footage: its images were taken at irregular steps of a 25 fps video, and
// each source carries their times from frame_numbers.txt.
TEST(ExampleSite, TerraceVideoSourcesCarryTheirFrameTimes) {
  OCCMAP_REQUIRE_DATASETS(root);
  SiteLoadOptions options;
  options.data_root = root;
  auto site = LoadSite(SitePath("terrace-video.yaml"), options);
  ASSERT_TRUE(site.ok()) << site.status().message();
  ASSERT_EQ(site->cameras.size(), 4u);
  for (const SiteCamera& cam : site->cameras) {
    const std::vector<double>& t = cam.source.timestamps_s;
    ASSERT_EQ(t.size(), 300u) << cam.id;
    EXPECT_DOUBLE_EQ(t[0], 10.0 / 25);
    EXPECT_DOUBLE_EQ(t[1], 15.0 / 25);
    for (size_t k = 1; k < t.size(); ++k) {
      const double step = t[k] - t[k - 1];
      EXPECT_TRUE(std::abs(step - 0.2) < 1e-9 || std::abs(step - 0.4) < 1e-9) << cam.id << " image " << k << ": " << step;
    }
  }
}

TEST(ExampleSite, WildtrackHasSevenFullHdTablesOnItsGrid) {
  OCCMAP_REQUIRE_DATASETS(root);
  SiteLoadOptions options;
  options.data_root = root;
  auto site = LoadSite(SitePath("wildtrack.yaml"), options);
  ASSERT_TRUE(site.ok()) << site.status().message();
  Context ctx(0);
  const GroundLut lut = LoadOrBuildSiteLut(*site, {}, ctx)->lut;
  ASSERT_EQ(lut.num_cameras(), 7);
  for (int n = 0; n < 7; ++n) {
    EXPECT_EQ(lut.image_size(n), (ImageSize{1920, 1080}));
    EXPECT_EQ(lut.l1(n).size(), 1920u * 1080u);
    EXPECT_GT(lut.coverage()[n].pixels_mapped, 1920 * 1080 / 2);
  }
  EXPECT_EQ(lut.grid().cells_x, 480);
  EXPECT_EQ(lut.grid().cells_y, 1440);
  EXPECT_EQ(lut.grid().cell_size_m, 0.025);
}

TEST(ExampleSite, MultiviewxCamerasLookAlongNegativeZ) {
  OCCMAP_REQUIRE_DATASETS(root);
  SiteLoadOptions options;
  options.data_root = root;
  auto site = LoadSite(SitePath("multiviewx.yaml"), options);
  ASSERT_TRUE(site.ok()) << site.status().message();
  for (const auto& cam : site->cameras) {
    // The centre of the area is in front of every camera only with forward sign -1.
    EXPECT_TRUE(cam.camera->Project({12.5, 8.0, 0.0}).has_value()) << cam.id;
  }
}

TEST(ExampleSite, SitesWorkFromACheckoutWithSharedBeside) {
  // Without --data-root the files' own data_root (../../shared/datasets) is used.
  const fs::path beside = fs::path(OCCMAP_SOURCE_DIR) / ".." / "shared" / "datasets";
  if (!fs::is_directory(beside)) GTEST_SKIP() << "no ../shared beside the checkout; skipped";
  for (const char* name : {"wildtrack.yaml", "multiviewx.yaml", "gopro4.yaml", "terrace.yaml"}) {
    auto site = LoadSite(SitePath(name));
    EXPECT_TRUE(site.ok()) << name << ": " << site.status().message();
  }
}

}  // namespace
}  // namespace occmap
