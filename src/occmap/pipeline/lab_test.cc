// The simulator's lab scene through the whole system: perfect change masks reproduce the ideal
// plane hull (the paper's claim), and the demo scores its detections and tracks.
#include <fmt/core.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "occmap/pipeline/demo.h"
#include "occmap/pipeline/run.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

constexpr int kFrames = 12;

// A lab dataset (PNG frames, perfect change masks, reference rasters), written once.
class LabDataset : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir();
    sim::BuiltinSceneOptions o;
    o.num_frames = kFrames;
    auto scene = sim::Scene::Create(sim::MakeLabSceneSpec(o));
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    sim::DatasetOptions d;
    d.out_dir = dir_->path() / "lab";
    Context ctx(2);
    auto written = sim::WriteDataset(*scene, d, ctx);
    ASSERT_TRUE(written.ok()) << written.status().message();
  }
  static void TearDownTestSuite() { delete dir_; }
  static fs::path Lab() { return dir_->path() / "lab"; }
  static testing::TempDir* dir_;
};
testing::TempDir* LabDataset::dir_ = nullptr;

TEST_F(LabDataset, PerfectChangeMasksReproduceTheIdealPlaneHull) {
  auto site = LoadSite(Lab() / "site.yaml");
  ASSERT_TRUE(site.ok()) << site.status().message();
  for (auto& cam : site->cameras) {
    cam.source = {FrameSourceSpec::Kind::kMasks, (Lab() / "gt" / "changes" / cam.id / "%06d.png").string()};
  }
  RunOptions o;
  o.out_dir = Lab() / "perfect";
  o.occupancy_pngs = true;
  o.occupancy_video = o.mosaic_video = false;
  Context ctx(2);
  auto run = RunSite(*site, o, ctx);
  ASSERT_TRUE(run.ok()) << run.status().message();
  ASSERT_EQ(run->frames, kFrames);
  int64_t seen = 0, agree = 0, boundary = 0, boundary_occupied = 0, interior = 0, interior_occupied = 0;
  int64_t between_legs_seen = 0, between_legs_free = 0;
  for (int f = 0; f < kFrames; ++f) {
    const std::string name = fmt::format("{:06d}.png", f);
    const Image<uint8_t> map = *ReadGrayImage(Lab() / "perfect" / "occupancy" / name);
    const Image<uint8_t> hull = *ReadGrayImage(Lab() / "gt" / "hull" / name);
    const Image<uint8_t> feet = *ReadGrayImage(Lab() / "gt" / "footprint" / name);
    for (int y = 0; y < map.height(); ++y) {
      for (int x = 0; x < map.width(); ++x) {
        if (map(x, y) == 128) continue;  // unseen
        ++seen;
        agree += (map(x, y) == 0) == (hull(x, y) == 0);
        // A footprint cell on the object's boundary that the hull shows some camera sees.
        if (feet(x, y) == 255 && hull(x, y) != 128) {
          bool on_boundary = false;
          for (auto [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
            const int nx = x + dx, ny = y + dy;
            if (nx >= 0 && ny >= 0 && nx < map.width() && ny < map.height()) on_boundary |= feet(nx, ny) == 0;
          }
          if (on_boundary) {
            ++boundary;
            boundary_occupied += map(x, y) == 0;
          } else {
            ++interior;
            interior_occupied += map(x, y) == 0;
          }
        }
      }
    }
  }
  const double agreement = static_cast<double>(agree) / static_cast<double>(seen);
  EXPECT_GE(agreement, 0.995) << agree << " of " << seen << " seen cells";
  EXPECT_GT(boundary, 100);
  // The footprint's inside is occupied. On its boundary, a 2 cm cell is only partly under the
  // object and a pixel sees 3-5 cm of floor at these distances: any pixel whose ray lands on
  // the cell's free part frees it (the AND), so the discrete map loses about a third of the
  // boundary cells (measured: 1394 of 2099 kept, interior 4994 of 5058). The continuous claim
  // (every visible boundary point is a hard point) holds on the ideal hull computed at cell
  // centres: sim's HullOccupiesEveryBoundaryFootprintCellThatSomeCameraSees.
  EXPECT_GE(static_cast<double>(interior_occupied) / static_cast<double>(interior), 0.98)
      << interior_occupied << " of " << interior << " interior footprint cells";
  EXPECT_GE(static_cast<double>(boundary_occupied) / static_cast<double>(boundary), 0.6)
      << boundary_occupied << " of " << boundary << " boundary footprint cells";

  // The chair (the only "chair" object): the floor between its legs is free where it is seen.
  const auto gt_lines = *ReadFileToString(Lab() / "ground_truth.jsonl");
  const auto first = nlohmann::json::parse(gt_lines.substr(0, gt_lines.find('\n')));
  for (const auto& obj : first["objects"]) {
    if (obj["class"] != "chair") continue;
    const Image<uint8_t> map = *ReadGrayImage(Lab() / "perfect" / "occupancy" / "000000.png");
    const FloorGrid& g = site->grid;
    const double cx = obj["x_m"].get<double>(), cy = obj["y_m"].get<double>();
    // Cells within 0.1 m of the chair's centre: under the seat, between the legs.
    for (int y = 0; y < map.height(); ++y) {
      for (int x = 0; x < map.width(); ++x) {
        const int64_t cell = static_cast<int64_t>(g.cells_y - 1 - y) * g.cells_x + x;
        const auto c = g.CellCenter(cell);
        if (std::hypot(c.x() - cx, c.y() - cy) > 0.1 || map(x, y) == 128) continue;
        ++between_legs_seen;
        between_legs_free += map(x, y) == 255;
      }
    }
  }
  EXPECT_GT(between_legs_seen, 0);
  EXPECT_GT(between_legs_free, between_legs_seen / 2);
}

TEST(Demo, RendersRunsAndScoresTheLab) {
  testing::TempDir dir;
  Context ctx(2);
  DemoOptions o;
  o.out_dir = dir.path();
  o.frames = 30;
  auto r = RunDemo(o, ctx);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->run.frames, 30);
  const auto summary = nlohmann::json::parse(*ReadFileToString(dir / "summary.json"));
  for (const char* key : {"moda", "modp", "precision", "recall", "mota", "idf1", "frames_per_second"}) {
    ASSERT_TRUE(summary.contains(key)) << key;
    ASSERT_TRUE(summary[key].is_number()) << key << ": " << summary[key];
  }
  // Measured on the full 100 frames: MODA 0.88, MODP 0.84 (see the README); on this shorter
  // run the chair (four 3.5 cm legs) is harder, so the bar here is lower.
  EXPECT_GE(summary["moda"].get<double>(), 0.7);
  EXPECT_GE(summary["modp"].get<double>(), 0.75);
  EXPECT_GE(summary["mota"].get<double>(), 0.6);
  EXPECT_TRUE(fs::exists(dir / "mosaic.mp4"));
  EXPECT_TRUE(fs::exists(dir / "mosaic.png"));
  EXPECT_TRUE(fs::exists(dir / "run" / "tracks.jsonl"));
}

}  // namespace
}  // namespace occmap
