#include "occmap/pipeline/background_maintenance.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <nlohmann/json.hpp>

#include "occmap/detect/background_model.h"
#include "occmap/eval/run_outputs.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/lut/test_scene.h"
#include "occmap/pipeline/run.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/dataset_writer.h"
#include "occmap/site/site.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

constexpr double kFps = 5;
constexpr int64_t kFrames = 310;          // 62 s
constexpr int64_t kLightsOnFrame = 200;   // every pixel + 40 from here on
const Eigen::Vector2d kPerson(3.0, 3.0);  // stands still the whole time
const Eigen::Vector2d kBoxStart(6.5, 4.5), kBoxEnd(6.5, 2.0);  // pushed at 4-8 s, then left

// The lab at half size with no one but a person standing still for 62 s and a box pushed and
// left; from frame kLightsOnFrame every pixel of every camera is 40 levels brighter.
class StillScene : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir();
    sim::BuiltinSceneOptions o;
    o.image_scale = 0.5;
    sim::SceneSpec spec = sim::MakeLabSceneSpec(o);
    spec.fps = kFps;
    spec.num_frames = kFrames;
    spec.objects.clear();
    const Eigen::Vector3f carpet(0.35f, 0.35f, 0.4f);
    sim::MovingObjectSpec person;
    person.id = 1;
    person.object_class = sim::ObjectClass::kPerson;
    person.appearance = sim::RandomAppearance(sim::ObjectClass::kPerson, 3, 1, carpet, 0.0);
    person.path = {{0.0, kPerson, false}, {70.0, kPerson, false}};
    sim::MovingObjectSpec box;
    box.id = 2;
    box.object_class = sim::ObjectClass::kBox;
    box.appearance = sim::RandomAppearance(sim::ObjectClass::kBox, 3, 2, carpet, 0.0);
    box.appearance.height_m = 0.6;
    box.appearance.width_m = 0.5;
    box.appearance.depth_m = 0.4;
    box.appearance.top = {0.8f, 0.6f, 0.2f};
    box.path = {{0.0, kBoxStart, false}, {4.0, kBoxStart, false}, {8.0, kBoxEnd, false}, {70.0, kBoxEnd, false}};
    spec.objects = {person, box};
    auto scene = sim::Scene::Create(spec);
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    sim::DatasetOptions d;
    d.out_dir = dir_->path() / "data";
    d.gt_rasters = false;
    d.change_masks = false;
    Context ctx(2);
    auto written = sim::WriteDataset(*scene, d, ctx);
    ASSERT_TRUE(written.ok()) << written.status().message();
    site_file_ = new fs::path(written->site_file);
    // Lights on.
    for (const auto& cam : spec.cameras) {
      for (int64_t f = kLightsOnFrame; f < kFrames; ++f) {
        const fs::path p = d.out_dir / "frames" / cam.id / fmt::format("{:06d}.png", f);
        auto rgb = ReadRgbImage(p);
        ASSERT_TRUE(rgb.ok()) << rgb.status().message();
        for (int y = 0; y < rgb->height(); ++y) {
          for (int x = 0; x < rgb->width(); ++x) {
            Rgb8& px = (*rgb)(x, y);
            px = {static_cast<uint8_t>(std::min(255, px.r + 40)), static_cast<uint8_t>(std::min(255, px.g + 40)),
                  static_cast<uint8_t>(std::min(255, px.b + 40))};
          }
        }
        ASSERT_TRUE(WritePng(p, rgb->view()).ok());
      }
    }
  }
  static void TearDownTestSuite() {
    delete site_file_;
    delete dir_;
  }

  // Runs the site with the adaptive model; the detections per frame.
  std::vector<DetectionFrame> Run(double absorb_s, const std::string& name, nlohmann::json* summary = nullptr) {
    auto site = LoadSite(*site_file_);
    EXPECT_TRUE(site.ok()) << site.status().message();
    for (SiteCamera& c : site->cameras) c.source.fps = kFps;
    site->detection.colour = true;
    site->backgrounds.adaptive = true;
    site->backgrounds.absorb_s = absorb_s;
    // Indoors without cast shadows: the shadow test would only take the person's grey trousers
    // on the grey carpet for a shadow (its documented failure), which is not what this tests.
    site->backgrounds.shadows.enabled = false;
    RunOptions r;
    r.out_dir = dir_->path() / name;
    r.occupancy_video = false;
    r.mosaic_video = false;
    r.track = false;
    Context ctx(2);
    auto run = RunSite(*site, r, ctx);
    EXPECT_TRUE(run.ok()) << run.status().message();
    if (summary != nullptr) *summary = nlohmann::json::parse(ReadFileToString(r.out_dir / "summary.json").value());
    auto frames = ReadDetections(r.out_dir / "detections.jsonl");
    EXPECT_TRUE(frames.ok());
    return frames.ok() ? *frames : std::vector<DetectionFrame>{};
  }

  static bool Near(const DetectionFrame& f, const Eigen::Vector2d& at, double r_m) {
    for (const DetectedBlob& b : f.blobs) {
      if (std::hypot(b.x_m - at.x(), b.y_m - at.y()) <= r_m) return true;
    }
    return false;
  }

  static testing::TempDir* dir_;
  static fs::path* site_file_;
};
testing::TempDir* StillScene::dir_ = nullptr;
fs::path* StillScene::site_file_ = nullptr;

TEST_F(StillScene, KeepsThePersonAbsorbsTheBoxAndFollowsTheLights) {
  nlohmann::json summary;
  const std::vector<DetectionFrame> frames = Run(/*absorb_s=*/10, "adaptive", &summary);
  ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames));
  const int64_t box_still = static_cast<int64_t>(8 * kFps);
  const int64_t absorbed_by = box_still + static_cast<int64_t>((10 + 2) * kFps);  // absorb_s + 2 s
  const int64_t recovered_by = kLightsOnFrame + static_cast<int64_t>(3 * kFps);
  for (const DetectionFrame& f : frames) {
    // The person standing still for 62 s is never taken into the background.
    EXPECT_TRUE(Near(f, kPerson, 0.5)) << "frame " << f.frame << ": the person is missing";
    if (f.frame >= absorbed_by) {
      EXPECT_FALSE(Near(f, kBoxEnd, 0.6)) << "frame " << f.frame << ": the box left still is not absorbed";
    }
    // Before the lights and from 3 s after them, the person is all there is.
    if ((f.frame >= absorbed_by && f.frame < kLightsOnFrame) || f.frame >= recovered_by) {
      EXPECT_EQ(f.blobs.size(), 1u) << "frame " << f.frame;
    }
  }
  // The box was seen while it moved.
  EXPECT_TRUE(Near(frames[static_cast<size_t>(box_still)], kBoxEnd, 0.6));
  // summary.json tells how much of each background was updated and how old it is.
  for (const auto& cam : summary["cameras"]) {
    ASSERT_TRUE(cam.contains("background_model")) << cam.dump();
    EXPECT_GT(cam["background_model"]["updated_fraction"].get<double>(), 0.5);
    EXPECT_GE(cam["background_model"]["mean_age_s"].get<double>(), 0.0);
    EXPECT_NEAR(cam["background_model"]["last_frame"]["offset"].get<double>(), 40, 8);
  }
}

// The small room's tables.
Result<GroundLut> SmallRoomLut(const testing::SmallRoom& room) {
  std::vector<LutCameraInput> inputs;
  for (const auto& c : room.cameras) inputs.push_back({&c, {}});
  Context ctx(1);
  return BuildGroundLut(inputs, room.grid, LutOptions{}, ctx);
}

// The floor of the small room: 50 cm squares of two greys.
int FloorLevel(const Eigen::Vector2d& p) {
  return ((static_cast<int>(std::floor(p.x() / 0.5)) + static_cast<int>(std::floor(p.y() / 0.5))) % 2) ? 160 : 60;
}

// The small room's learned backgrounds: camera n's is the floor at exposure 1 + gain_step n, but
// where learned_in(n, x, y) a person was learned in (250), with the floor as the pixel's
// alternative where also floor_kept(n, x, y).
using PixelTest = std::function<bool(size_t n, int x, int y)>;
std::vector<std::unique_ptr<BackgroundModel>> LearnedRoom(const testing::SmallRoom& room, double gain_step,
                                                          const PixelTest& learned_in, const PixelTest& floor_kept) {
  std::vector<std::unique_ptr<BackgroundModel>> models;
  for (size_t n = 0; n < room.cameras.size(); ++n) {
    const double gain = 1 + gain_step * static_cast<double>(n);
    YuvImage b;
    b.y = Image<uint8_t>(160, 120, 0);
    BackgroundLearner::Alternative alt{{Image<uint8_t>(160, 120, 0), {}, {}}, Image<uint8_t>(160, 120, 0)};
    for (int y = 0; y < 120; ++y) {
      for (int x = 0; x < 160; ++x) {
        const auto p = room.cameras[n].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
        const int floor = p ? static_cast<int>(std::lround(gain * FloorLevel(*p))) : 0;
        b.y(x, y) = static_cast<uint8_t>(floor);
        if (!learned_in(n, x, y)) continue;
        b.y(x, y) = 250;
        if (floor_kept(n, x, y)) {
          alt.levels.y(x, y) = static_cast<uint8_t>(floor);
          alt.support(x, y) = 10;
        }
      }
    }
    models.push_back(std::make_unique<BackgroundModel>(BackgroundOptions{}, 10.0));
    models.back()->Reset(b);
    models.back()->SetAlternative(alt, 3);
  }
  return models;
}

std::vector<BackgroundModel*> Pointers(const std::vector<std::unique_ptr<BackgroundModel>>& models) {
  std::vector<BackgroundModel*> p;
  for (const auto& m : models) p.push_back(m.get());
  return p;
}

TEST(ResolveLearnedBackgrounds, APersonLearnedInOneViewTakesTheFloorTheOthersSee) {
  testing::SmallRoom room;
  auto lut = SmallRoomLut(room);
  ASSERT_TRUE(lut.ok()) << lut.status().message();
  // Each camera's background is the floor at its own exposure (gain 1 + 0.1 n); camera 0 has a
  // person learned in over two rectangles, the floor as alternative on the first only.
  const int x0 = 60, x1 = 80, y0 = 60, y1 = 90, x2 = 100, x3 = 120;
  const auto models = LearnedRoom(
      room, 0.1,
      [&](size_t n, int x, int y) { return n == 0 && y >= y0 && y < y1 && ((x >= x0 && x < x1) || (x >= x2 && x < x3)); },
      [&](size_t, int x, int) { return x < x1; });
  const std::vector<BackgroundModel*> pointers = Pointers(models);
  int64_t floor_pixels_first = 0;
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) floor_pixels_first += lut->l1(0)[static_cast<size_t>(y) * 160 + x] != lut->sentinel();
  }
  const ConsensusResult r = ResolveLearnedBackgrounds(*lut, {}, 0.0, pointers, 20, 0);
  EXPECT_GT(floor_pixels_first, 400);
  // Every pixel of the first rectangle that sees the floor takes the floor (its cell seen by at
  // least three cameras), the second keeps the person (no alternative), nothing else moves.
  EXPECT_GE(r.pixels_swapped, floor_pixels_first * 9 / 10);
  EXPECT_LE(r.pixels_swapped, floor_pixels_first);
  const auto seen = room.cameras[0].PixelToPlane(Eigen::Vector2d(x0 + 5, y0 + 5), 0.0);
  ASSERT_TRUE(seen.has_value());
  EXPECT_EQ(models[0]->BackgroundLevel(x0 + 5, y0 + 5), FloorLevel(*seen));
  EXPECT_EQ(models[0]->AlternativeLevel(x0 + 5, y0 + 5), -1);  // decided: the person is never swapped back in
  EXPECT_EQ(models[0]->BackgroundLevel(x2 + 5, y0 + 5), 250);
  EXPECT_EQ(models[1]->AlternativeLevel(5, 5), -1);
}

// Cameras 0 and 1 each have a person learned in over a rectangle, the floor as alternative;
// camera 0's background was reused from an entry its running model wrote (kept): it votes, but
// keeps its look and its alternative (what its model took in since it was checked, a change it
// alone sees), while camera 1 takes the floor the others see.
TEST(ResolveLearnedBackgrounds, AKeptCameraIsLeftAsItIs) {
  testing::SmallRoom room;
  auto lut = SmallRoomLut(room);
  ASSERT_TRUE(lut.ok()) << lut.status().message();
  const int x0 = 60, x1 = 80, y0 = 60, y1 = 90;
  auto build = [&] {
    return LearnedRoom(
        room, 0.0, [&](size_t n, int x, int y) { return n <= 1 && y >= y0 && y < y1 && x >= x0 && x < x1; },
        [](size_t, int, int) { return true; });
  };
  const int xs = x0 + 5, ys = y0 + 5;
  std::array<int, 2> floor{};
  for (size_t n = 0; n <= 1; ++n) {
    const auto seen = room.cameras[n].PixelToPlane(Eigen::Vector2d(xs, ys), 0.0);
    ASSERT_TRUE(seen.has_value());
    floor[n] = FloorLevel(*seen);
  }
  const auto checked_all = build();
  const ConsensusResult all = ResolveLearnedBackgrounds(*lut, {}, 0.0, Pointers(checked_all), 20, 0);
  EXPECT_EQ(checked_all[0]->BackgroundLevel(xs, ys), floor[0]);  // unkept, camera 0 takes the floor too

  const auto models = build();
  const ConsensusResult r = ResolveLearnedBackgrounds(*lut, {}, 0.0, Pointers(models), 20, 0, /*drop_kept=*/true,
                                                      /*keep=*/{true, false, false, false});
  EXPECT_EQ(models[0]->BackgroundLevel(xs, ys), 250);
  EXPECT_EQ(models[0]->AlternativeLevel(xs, ys), floor[0]);
  EXPECT_EQ(models[1]->BackgroundLevel(xs, ys), floor[1]);
  EXPECT_EQ(models[1]->AlternativeLevel(xs, ys), -1);
  EXPECT_GT(r.pixels_swapped, 0);
  EXPECT_LT(r.pixels_swapped, all.pixels_swapped);
  EXPECT_LT(r.pixels_checked, all.pixels_checked);  // camera 0's pixels are not counted
}

// The same room with a grid over its first 2 x 1.5 m only: camera 0 has a person learned in
// where it sees the floor at (3.0, 2.2) m, off the grid. Only with the cameras does the check
// reach that floor, take it, and settle the pixels (their alternative, the person, dropped).
// A look whose luma is the floor's but whose colour is not (an orange shirt on grey paving, or
// the ray of a kiosk's pixel meeting the floor behind it) is not kept for good in colour: its
// alternative stays, for the settling pass to swap in when the look leaves. A look of the floor's
// luma and colour is kept, as in grey.
TEST(ResolveLearnedBackgrounds, ALookOfTheFloorsLumaButNotItsColourKeepsItsAlternative) {
  testing::SmallRoom room;
  auto lut = SmallRoomLut(room);
  ASSERT_TRUE(lut.ok()) << lut.status().message();
  // Camera 0: over the first rectangle a look of the floor's luma in orange, over the second one
  // of its luma and colour; both with a dark alternative (the person's shade, a kiosk).
  const int x0 = 60, x1 = 80, y0 = 60, y1 = 90, x2 = 100, x3 = 120;
  auto run = [&](int chroma_threshold) {
    std::vector<std::unique_ptr<BackgroundModel>> models;
    std::vector<BackgroundModel*> pointers;
    for (size_t n = 0; n < room.cameras.size(); ++n) {
      YuvImage b;
      b.y = Image<uint8_t>(160, 120, 0);
      b.u = Image<uint8_t>(80, 60, 128);
      b.v = Image<uint8_t>(80, 60, 128);
      BackgroundLearner::Alternative alt{{Image<uint8_t>(160, 120, 20), Image<uint8_t>(80, 60, 128), Image<uint8_t>(80, 60, 128)},
                                         Image<uint8_t>(160, 120, 0)};
      for (int y = 0; y < 120; ++y) {
        for (int x = 0; x < 160; ++x) {
          const auto p = room.cameras[n].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
          b.y(x, y) = static_cast<uint8_t>(p ? FloorLevel(*p) : 0);
          const bool first = x >= x0 && x < x1, second = x >= x2 && x < x3;
          if (n == 0 && y >= y0 && y < y1 && (first || second)) {
            alt.support(x, y) = 10;
            if (first) {
              b.u(x / 2, y / 2) = 80;
              b.v(x / 2, y / 2) = 180;
            }
          }
        }
      }
      models.push_back(std::make_unique<BackgroundModel>(BackgroundOptions{}, 10.0));
      models.back()->Reset(b);
      models.back()->SetAlternative(alt, 3);
      pointers.push_back(models.back().get());
    }
    ResolveLearnedBackgrounds(*lut, {}, 0.0, pointers, 20, chroma_threshold);
    return std::pair{models[0]->AlternativeLevel(x0 + 5, y0 + 5), models[0]->AlternativeLevel(x2 + 5, y0 + 5)};
  };
  ASSERT_TRUE(room.cameras[0].PixelToPlane(Eigen::Vector2d(x0 + 5, y0 + 5), 0.0).has_value());
  ASSERT_TRUE(room.cameras[0].PixelToPlane(Eigen::Vector2d(x2 + 5, y0 + 5), 0.0).has_value());
  const auto [orange, grey] = run(16);
  EXPECT_EQ(orange, 20);  // undecided: the alternative stays
  EXPECT_EQ(grey, -1);    // kept for good
  const auto [orange_luma, grey_luma] = run(0);
  EXPECT_EQ(orange_luma, -1);  // luma alone takes the orange for the floor
  EXPECT_EQ(grey_luma, -1);
}

TEST(ResolveLearnedBackgrounds, BeyondTheGridWithTheCameras) {
  testing::SmallRoom room;
  const FloorGrid small{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 40, .cells_y = 30, .cell_size_m = 0.05};
  std::vector<LutCameraInput> inputs;
  std::vector<const CameraModel*> cameras;
  for (const auto& c : room.cameras) {
    inputs.push_back({&c, {}});
    cameras.push_back(&c);
  }
  Context ctx(2);
  auto lut = BuildGroundLut(inputs, small, LutOptions{}, ctx);
  ASSERT_TRUE(lut.ok()) << lut.status().message();
  const auto centre = room.cameras[0].Project({3.0, 2.2, 0.0});
  ASSERT_TRUE(centre.has_value());
  const int cx = static_cast<int>(std::lround(centre->x())), cy = static_cast<int>(std::lround(centre->y()));
  auto make = [&](std::vector<std::unique_ptr<BackgroundModel>>& models, std::vector<BackgroundModel*>& pointers) {
    for (size_t n = 0; n < room.cameras.size(); ++n) {
      YuvImage b;
      b.y = Image<uint8_t>(160, 120, 0);
      BackgroundLearner::Alternative alt{{Image<uint8_t>(160, 120, 0), {}, {}}, Image<uint8_t>(160, 120, 0)};
      for (int y = 0; y < 120; ++y) {
        for (int x = 0; x < 160; ++x) {
          const auto p = room.cameras[n].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
          const int floor = p ? FloorLevel(*p) : 0;
          b.y(x, y) = static_cast<uint8_t>(floor);
          if (n == 0 && std::abs(x - cx) <= 4 && std::abs(y - cy) <= 4) {
            b.y(x, y) = 250;
            alt.levels.y(x, y) = static_cast<uint8_t>(floor);
            alt.support(x, y) = 10;
          }
        }
      }
      models.push_back(std::make_unique<BackgroundModel>(BackgroundOptions{}, 10.0));
      models.back()->Reset(b);
      models.back()->SetAlternative(alt, 3);
      pointers.push_back(models.back().get());
    }
  };
  ASSERT_EQ(lut->l1(0)[static_cast<size_t>(cy) * 160 + cx], lut->sentinel());  // off the grid
  std::vector<std::unique_ptr<BackgroundModel>> grid_only, beyond;
  std::vector<BackgroundModel*> grid_only_p, beyond_p;
  make(grid_only, grid_only_p);
  make(beyond, beyond_p);
  ResolveLearnedBackgrounds(*lut, {}, 0.0, grid_only_p, 20, 0);
  EXPECT_EQ(grid_only[0]->BackgroundLevel(cx, cy), 250);
  const ConsensusResult r = ResolveLearnedBackgrounds(*lut, cameras, 0.0, beyond_p, 20, 0);
  const auto seen = room.cameras[0].PixelToPlane(Eigen::Vector2d(cx, cy), 0.0);
  ASSERT_TRUE(seen.has_value());
  EXPECT_EQ(beyond[0]->BackgroundLevel(cx, cy), FloorLevel(*seen));
  EXPECT_EQ(beyond[0]->AlternativeLevel(cx, cy), -1);
  EXPECT_GE(r.pixels_swapped, 70);  // most of the 81
  EXPECT_GE(r.pixels_settled, r.pixels_swapped);
}

TEST_F(StillScene, WithoutAbsorptionTheBoxStays) {
  const std::vector<DetectionFrame> frames = Run(/*absorb_s=*/1000, "no-absorb");
  ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames));
  EXPECT_TRUE(Near(frames[150], kBoxEnd, 0.6));
  EXPECT_TRUE(Near(frames.back(), kBoxEnd, 0.6));
}

}  // namespace
}  // namespace occmap

namespace occmap {
namespace {

// A person seen walking in is marked kWalkedPerson (never swapped with the alternative), any
// other kPerson.
TEST(BackgroundProtection, PeopleFromAnotherDetectorAreProtectedAsPersons) {
  testing::SmallRoom room(160, 120);
  std::vector<const CameraModel*> cameras;
  for (const auto& c : room.cameras) cameras.push_back(&c);
  OccupancyMap empty(room.grid);
  for (auto& s : empty.states()) s = CellState::kFree;
  std::vector<Image<uint8_t>> changes;
  std::vector<ImageView<const uint8_t>> views;
  for (int n = 0; n < 4; ++n) changes.emplace_back(160, 120, uint8_t{0});
  for (auto& c : changes) views.push_back(c.view());
  for (const bool walked : {false, true}) {
    SCOPED_TRACE(walked ? "walked in" : "not seen walking");
    BackgroundProtection protection(cameras, 0.0, ProtectionOptions{});
    protection.Compute(empty, views);
    EXPECT_EQ(protection.persons(), 0);
    protection.AddPeople({Eigen::Vector2d(2.0, 1.5)}, 0.25, {walked});
    EXPECT_EQ(protection.persons(), 1);
    const uint8_t expected = walked ? BackgroundModel::kWalkedPerson : BackgroundModel::kPerson;
    for (size_t n = 0; n < 4; ++n) {
      const auto head = room.cameras[n].Project({2.0, 1.5, 1.6});
      const auto foot = room.cameras[n].Project({2.0, 1.5, 0.0});
      ASSERT_TRUE(head && foot);
      EXPECT_EQ(protection.image(n)(static_cast<int>(std::lround(head->x())), static_cast<int>(std::lround(head->y()))),
                expected);
      EXPECT_EQ(protection.image(n)(static_cast<int>(std::lround(foot->x())), static_cast<int>(std::lround(foot->y()))),
                expected);
      EXPECT_EQ(protection.image(n)(0, 0), BackgroundModel::kFree);
    }
  }
}

// A box protects its projected outline, not the outline's bounding rectangle: in a camera that
// sees it from the side and above, the rectangle's corners beside the box's top and foot show
// what lies around and behind it, and stay free.
TEST(BackgroundProtection, ABoxProtectsItsOutlineNotItsBoundingRectangle) {
  testing::SmallRoom room(160, 120);
  std::vector<const CameraModel*> cameras;
  for (const auto& c : room.cameras) cameras.push_back(&c);
  BackgroundProtection protection(cameras, 0.0, ProtectionOptions{});
  protection.ProtectChanges({{}, {}, {}, {}});
  protection.AddMissedPeople({Eigen::Vector2d(2.0, 1.5)}, 0.25);
  const double radius = 0.25 + ProtectionOptions{}.margin_m, height = ProtectionOptions{}.height_m;
  int corners_free = 0;
  for (size_t n = 0; n < 4; ++n) {
    double u0 = 1e9, v0 = 1e9, u1 = -1e9, v1 = -1e9;
    for (int k = 0; k < 12; ++k) {
      const double a = 2 * std::numbers::pi * k / 12;
      for (double z : {0.0, height}) {
        const auto p = room.cameras[n].Project({2.0 + radius * std::cos(a), 1.5 + radius * std::sin(a), z});
        ASSERT_TRUE(p);
        u0 = std::min(u0, p->x()), u1 = std::max(u1, p->x()), v0 = std::min(v0, p->y()), v1 = std::max(v1, p->y());
      }
    }
    const auto mid = room.cameras[n].Project({2.0, 1.5, 0.5 * height});
    ASSERT_TRUE(mid);
    EXPECT_EQ(protection.image(n)(static_cast<int>(std::lround(mid->x())), static_cast<int>(std::lround(mid->y()))),
              BackgroundModel::kObject) << "camera " << n;
    for (const auto& [u, v] : {std::pair{u0, v0}, {u1, v0}, {u0, v1}, {u1, v1}}) {
      const int x = std::clamp(static_cast<int>(std::lround(u)), 0, 159), y = std::clamp(static_cast<int>(std::lround(v)), 0, 119);
      corners_free += protection.image(n)(x, y) == BackgroundModel::kFree;
    }
  }
  EXPECT_GE(corners_free, 8) << "of the 16 corners of the four cameras' rectangles";
}

// An edge draws the fuse's boxes into its own cameras (occmap edge, protection_message.h): the
// images equal those the fuse's Compute + AddPeople made for those cameras.
TEST(BackgroundProtection, BoxesDrawnForSomeCamerasGiveTheirImages) {
  testing::SmallRoom room(160, 120);
  std::vector<const CameraModel*> cameras;
  for (const auto& c : room.cameras) cameras.push_back(&c);
  OccupancyMap map(room.grid);
  for (auto& s : map.states()) s = CellState::kFree;
  const FloorGrid& g = room.grid;
  for (int j = 20; j < 28; ++j) {  // an object of 8 x 8 cells
    for (int i = 30; i < 38; ++i) map.states()[static_cast<size_t>(j) * g.cells_x + i] = CellState::kOccupied;
  }
  std::vector<Image<uint8_t>> changes;
  std::vector<ImageView<const uint8_t>> views;
  for (int n = 0; n < 4; ++n) changes.emplace_back(160, 120, uint8_t{0});
  for (auto& c : changes) views.push_back(c.view());
  BackgroundProtection fuse(cameras, 0.0, ProtectionOptions{});
  fuse.Compute(map, views);
  fuse.AddPeople({Eigen::Vector2d(2.0, 1.5)}, 0.25, {true});
  fuse.AddMissedPeople({Eigen::Vector2d(0.8, 0.8)}, 0.25);
  ASSERT_EQ(fuse.boxes().size(), 3u);
  EXPECT_EQ(fuse.boxes()[0].value, BackgroundModel::kObject);
  EXPECT_EQ(fuse.boxes()[1].value, BackgroundModel::kWalkedPerson);
  EXPECT_EQ(fuse.boxes()[2].value, BackgroundModel::kObject);  // a person missed: an object
  EXPECT_EQ(fuse.persons(), 1);
  BackgroundProtection edge({cameras[1], cameras[3]}, 0.0, ProtectionOptions{});
  edge.Draw(fuse.boxes(), fuse.person_positions());
  EXPECT_EQ(edge.person_positions(), fuse.person_positions());
  EXPECT_EQ(edge.boxes(), fuse.boxes());
  for (const auto& [local, n] : {std::pair<size_t, size_t>{0, 1}, {1, 3}}) {
    EXPECT_EQ(edge.image(local), fuse.image(n)) << "camera " << n;
  }
  // Without the fuse's boxes, every changed pixel is a person's, the rest free.
  changes[3](5, 7) = 1;
  edge.ProtectChanges({views[1], views[3]});
  EXPECT_TRUE(edge.boxes().empty());
  EXPECT_EQ(edge.image(1)(5, 7), BackgroundModel::kPerson);
  EXPECT_EQ(edge.image(1)(6, 7), BackgroundModel::kFree);
  EXPECT_EQ(edge.image(0)(5, 7), BackgroundModel::kFree);
}

// Three people: one walks in and stops, one stands still where first seen (a ghost, or a person
// learned in), one walks by and leaves. Flags follow each position, whatever its order.
TEST(WalkedPeople, OnlyThoseSeenWalkingHaveWalked) {
  WalkedPeople walked;
  std::vector<bool> last;
  for (int f = 0; f < 60; ++f) {
    const Eigen::Vector2d in(1.0 + 0.1 * std::min(f, 30), 1.0);  // walks 3 m, then stands
    const Eigen::Vector2d still(5.0, 5.0);
    std::vector<Eigen::Vector2d> positions = {still, in};
    if (f < 20) positions.emplace_back(8.0, 0.5 + 0.1 * f);  // walks 2 m, then is gone
    if (f % 2) std::swap(positions[0], positions[1]);
    last = walked.Update(positions);
    ASSERT_EQ(last.size(), positions.size());
    const size_t in_k = f % 2 ? 0 : 1, still_k = 1 - in_k;
    EXPECT_FALSE(last[still_k]) << "frame " << f;
    EXPECT_EQ(last[in_k], f >= 11) << "frame " << f;  // more than 1 m from its start
    if (f < 20) {
      EXPECT_EQ(last[2], f >= 11) << "frame " << f;
    }
  }
  EXPECT_EQ(walked.followed(), 2);  // the passer-by forgotten after 20 missed frames
  // A person who jumps farther than the gate is someone new, who has not walked.
  const std::vector<bool>& jumped = walked.Update({Eigen::Vector2d(5.0, 5.0), Eigen::Vector2d(4.0, 3.0)});
  EXPECT_FALSE(jumped[0]);
  EXPECT_FALSE(jumped[1]);
}

// A walker who stops and is then missed (behind others in a crowd) is remembered where they
// stood, for hold_frames; someone who never walked (a ghost), and a walker missed while still
// walking, are not.
TEST(WalkedPeople, AWalkerWhoStoodIsHeldWhereLastSeen) {
  WalkedPeople walked(WalkedPeopleOptions{.hold_frames = 50});
  const Eigen::Vector2d ghost(5.0, 5.0);
  Eigen::Vector2d stander(1.0, 1.0), passer(8.0, 0.5);
  for (int f = 0; f < 60; ++f) {  // the stander walks 2 m and stands; the passer walks on
    stander = Eigen::Vector2d(1.0 + 0.1 * std::min(f, 20), 1.0);
    passer = Eigen::Vector2d(8.0, 0.5 + 0.1 * f);
    walked.Update({stander, ghost, passer});
    EXPECT_TRUE(walked.missed_m().empty()) << "frame " << f;
  }
  for (int f = 0; f < 60; ++f) {  // all three missed
    walked.Update({});
    if (f < 49) {
      ASSERT_EQ(walked.missed_m().size(), 1u) << "missed frame " << f;
      EXPECT_EQ(walked.missed_m()[0], stander);
    } else {
      EXPECT_TRUE(walked.missed_m().empty()) << "missed frame " << f;
    }
  }
  EXPECT_EQ(walked.followed(), 0);
}

// The floor a cast shadow covers in the shadow tests.
bool InCastShadow(const Eigen::Vector2d& p) { return p.x() >= 1.0 && p.x() < 2.0 && p.y() >= 1.0 && p.y() < 1.6; }

// A cast shadow on the floor is dark in every view; clothing that camera 0 takes for a shadow
// stands above the floor, whose cells the other cameras see lit. Only the shadow teaches, and
// not where a person stands.
TEST(ShadowTeachers, TheFloorEveryCameraSeesDarkTeachesClothingDoesNot) {
  testing::SmallRoom room(160, 120);
  auto lut = SmallRoomLut(room);
  ASSERT_TRUE(lut.ok()) << lut.status().message();
  std::vector<Image<uint8_t>> classes, ratios;
  int64_t shadow_pixels = 0;
  for (size_t n = 0; n < room.cameras.size(); ++n) {
    Image<uint8_t>& c = classes.emplace_back(160, 120, BackgroundModel::kBackground);
    Image<uint8_t>& r = ratios.emplace_back(160, 120, uint8_t{0});
    for (int y = 0; y < 120; ++y) {
      for (int x = 0; x < 160; ++x) {
        const auto p = room.cameras[n].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
        if (p && InCastShadow(*p)) {
          c(x, y) = n % 2 == 0 ? BackgroundModel::kChanged : BackgroundModel::kShadow;
          r(x, y) = static_cast<uint8_t>(110 + n * 3);  // 0.43-0.47 of the lit floor
          shadow_pixels += n == 0;
        }
      }
    }
  }
  // Clothing in camera 0 only: pixels whose floor is lit for the others.
  int clothing = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      const auto p = room.cameras[0].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
      if (!p || p->x() < 3.0 || p->x() >= 3.4 || p->y() < 2.0 || p->y() >= 2.4) continue;
      classes[0](x, y) = BackgroundModel::kChanged;
      ratios[0](x, y) = 115;
      ++clothing;
    }
  }
  ASSERT_GT(clothing, 50);
  ASSERT_GT(shadow_pixels, 200);
  std::vector<ImageView<const uint8_t>> views, ratio_views;
  for (const auto& c : classes) views.push_back(c.view());
  for (const auto& r : ratios) ratio_views.push_back(r.view());
  ShadowTeachers teachers(*lut);
  OccupancyMap map(room.grid);  // nothing held: every cell unseen
  teachers.Compute(views, ratio_views, map, {}, 0.35);
  int64_t taught_shadow = 0, taught_clothing = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      if (teachers.image(0)(x, y) == 0) continue;
      const auto p = room.cameras[0].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
      ASSERT_TRUE(p.has_value());
      (InCastShadow(*p) ? taught_shadow : taught_clothing) += 1;
    }
  }
  EXPECT_EQ(taught_clothing, 0);
  EXPECT_GT(taught_shadow, shadow_pixels * 8 / 10);  // its edge cells may hold lit pixels too
  // A camera that is not active abstains: the others still agree.
  views[3] = ratio_views[3] = {};
  teachers.Compute(views, ratio_views, map, {}, 0.35);
  const int64_t three = teachers.teachers();
  EXPECT_GT(three, 0);
  EXPECT_EQ(teachers.image(3)(80, 60), 0);
  // Where a person stands, the dark cells are their feet.
  teachers.Compute(views, ratio_views, map, {Eigen::Vector2d(1.5, 1.3)}, 1.0);
  EXPECT_EQ(teachers.teachers(), 0);
  // Where the map holds an object (a robot's dark base), its cells and their margin do not teach.
  OccupancyMap held(room.grid);
  const FloorGrid& g = room.grid;
  for (int j = 0; j < g.cells_y; ++j) {
    for (int i = 0; i < g.cells_x; ++i) {
      const double x = g.origin_x_m + (i + 0.5) * g.cell_size_m, y = g.origin_y_m + (j + 0.5) * g.cell_size_m;
      if (InCastShadow({x, y})) held.states()[static_cast<size_t>(j) * g.cells_x + i] = CellState::kOccupied;
    }
  }
  teachers.Compute(views, ratio_views, held, {}, 0.35);
  EXPECT_EQ(teachers.teachers(), 0);
  teachers.Compute(views, ratio_views, map, {}, 0.35);
  EXPECT_EQ(teachers.teachers(), three);
  // An object's sides, each lit its own way: camera 1 sees it far darker than the others.
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      if (ratios[1](x, y) != 0) ratios[1](x, y) = 40;
    }
  }
  teachers.Compute(views, ratio_views, map, {}, 0.35);
  EXPECT_LT(teachers.teachers(), three / 10);
}

}  // namespace
}  // namespace occmap

namespace occmap {
namespace {

// Every camera's class image over the small room (160 x 120), each pixel classed by
// class_of(camera, the floor point its ray meets), kBackground where it meets none; change
// masks all zero; and their views, for ShadowCheck::Apply.
struct FloorClasses {
  std::vector<Image<uint8_t>> classes, changes;
  std::vector<ImageView<const uint8_t>> class_views;
  std::vector<ImageView<uint8_t>> change_views;
};
FloorClasses PaintFloorClasses(const testing::SmallRoom& room,
                               const std::function<uint8_t(size_t, const Eigen::Vector2d&)>& class_of) {
  FloorClasses out;
  for (size_t n = 0; n < room.cameras.size(); ++n) {
    Image<uint8_t>& c = out.classes.emplace_back(160, 120, BackgroundModel::kBackground);
    out.changes.emplace_back(160, 120, uint8_t{0});
    for (int y = 0; y < 120; ++y) {
      for (int x = 0; x < 160; ++x) {
        const auto p = room.cameras[n].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
        if (p) c(x, y) = class_of(n, *p);
      }
    }
  }
  for (const auto& c : out.classes) out.class_views.push_back(c.view());
  for (auto& c : out.changes) out.change_views.push_back(c.view());
  return out;
}

// A cast shadow every camera sees dark stays a shadow; clothing that camera 0 alone takes for a
// shadow, over floor the others see lit, is a change. Camera 0 sees the shadow one cell wider
// than the others (a pixel wider than the cells): that rim, lit in the other views but beside
// cells dark in them, stays a shadow.
TEST(ShadowCheck, ShadowsOverFloorTheOthersSeeLitAreChanges) {
  testing::SmallRoom room(160, 120);
  auto lut = SmallRoomLut(room);
  ASSERT_TRUE(lut.ok()) << lut.status().message();
  auto in_clothing = [](const Eigen::Vector2d& p) { return p.x() >= 3.0 && p.x() < 3.4 && p.y() >= 2.0 && p.y() < 2.4; };
  int64_t shadow_pixels = 0, clothing_pixels = 0;
  FloorClasses painted = PaintFloorClasses(room, [&](size_t n, const Eigen::Vector2d& p) -> uint8_t {
    if (InCastShadow(p) || (n == 0 && p.x() >= 2.0 && p.x() < 2.05 && p.y() >= 1.0 && p.y() < 1.6)) {
      shadow_pixels += n == 0;
      return n == 2 ? BackgroundModel::kChanged : BackgroundModel::kShadow;  // someone in front, in view 2
    }
    if (n == 0 && in_clothing(p)) {
      ++clothing_pixels;
      return BackgroundModel::kShadow;
    }
    return BackgroundModel::kBackground;
  });
  auto& [classes, changes, class_views, change_views] = painted;
  ASSERT_GT(shadow_pixels, 200);
  ASSERT_GT(clothing_pixels, 50);
  ShadowCheck check(*lut);
  const int64_t turned = check.Apply(class_views, change_views);
  int64_t turned_shadow = 0, turned_clothing = 0;
  for (size_t n = 0; n < room.cameras.size(); ++n) {
    for (int y = 0; y < 120; ++y) {
      for (int x = 0; x < 160; ++x) {
        if (changes[n](x, y) == 0) continue;
        const auto p = room.cameras[n].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
        ASSERT_TRUE(p.has_value());
        (in_clothing(*p) ? turned_clothing : turned_shadow) += 1;  // the rim counts as shadow
      }
    }
  }
  EXPECT_EQ(turned_shadow, 0);
  // All but the clothing's rim, whose cells touch floor camera 0 alone sees dark.
  EXPECT_GT(turned_clothing, clothing_pixels / 2);
  EXPECT_EQ(turned, turned_clothing);
  // One other camera is not enough (cells at the edge of the views): cameras 2 and 3 not active.
  for (size_t n = 2; n < room.cameras.size(); ++n) class_views[n] = {};
  for (auto& c : changes) {
    for (int y = 0; y < 120; ++y) std::fill_n(c.row(y), 160, uint8_t{0});
  }
  EXPECT_EQ(check.Apply(class_views, change_views), 0);
}

}  // namespace
}  // namespace occmap

namespace occmap {
namespace {

// A soft shadow (no learned look vouches for it) stays a shadow only where another camera sees
// its floor cell shadowed as well: a contact shadow that every camera sees soft stays; grey
// clothing that camera 0 takes for a soft shadow, over floor the others see lit, or hidden by
// the person (changed), is a change; with no other camera seeing its cell shadowed it is a
// change too (where the cast rule would keep it).
TEST(ShadowCheck, SoftShadowsStayOnlyWhereAnotherCameraSeesTheirFloorShadowed) {
  testing::SmallRoom room(160, 120);
  auto lut = SmallRoomLut(room);
  ASSERT_TRUE(lut.ok()) << lut.status().message();
  const auto in_contact = [](const Eigen::Vector2d& p) { return p.x() >= 1.0 && p.x() < 1.5 && p.y() >= 1.0 && p.y() < 1.5; };
  const auto in_lit = [](const Eigen::Vector2d& p) { return p.x() >= 3.0 && p.x() < 3.4 && p.y() >= 2.0 && p.y() < 2.4; };
  const auto in_hidden = [](const Eigen::Vector2d& p) { return p.x() >= 2.4 && p.x() < 2.8 && p.y() >= 0.4 && p.y() < 0.8; };
  int64_t contact = 0, lit = 0, hidden = 0;
  FloorClasses painted = PaintFloorClasses(room, [&](size_t n, const Eigen::Vector2d& p) -> uint8_t {
    if (in_contact(p)) {
      contact += n == 0;
      return n == 2 ? BackgroundModel::kChanged : BackgroundModel::kSoftShadow;
    }
    if (in_lit(p) && n == 0) {
      ++lit;
      return BackgroundModel::kSoftShadow;
    }
    if (in_hidden(p)) {
      hidden += n == 0;
      return n == 0 ? BackgroundModel::kSoftShadow : BackgroundModel::kChanged;
    }
    return BackgroundModel::kBackground;
  });
  auto& [classes, changes, class_views, change_views] = painted;
  ASSERT_GT(contact, 200);
  ASSERT_GT(lit, 50);
  ASSERT_GT(hidden, 50);
  ShadowCheck check(*lut);
  check.Apply(class_views, change_views);
  int64_t turned_contact = 0, turned_lit = 0, turned_hidden = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      if (changes[0](x, y) == 0) continue;
      const auto p = room.cameras[0].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
      ASSERT_TRUE(p.has_value());
      turned_contact += in_contact(*p);
      turned_lit += in_lit(*p);
      turned_hidden += in_hidden(*p);
    }
  }
  // The contact shadow's rim (cells half outside) may turn; its body stays.
  EXPECT_LT(turned_contact, contact / 5);
  EXPECT_GT(turned_lit, lit * 4 / 5);
  EXPECT_GT(turned_hidden, hidden * 4 / 5);
  // The same pixels as cast shadows: the cast rule keeps the hidden patch (nobody sees it lit).
  for (auto& c : classes) {
    for (int y = 0; y < 120; ++y) {
      for (int x = 0; x < 160; ++x) if (c(x, y) == BackgroundModel::kSoftShadow) c(x, y) = BackgroundModel::kShadow;
    }
  }
  for (auto& c : changes) {
    for (int y = 0; y < 120; ++y) std::fill_n(c.row(y), 160, uint8_t{0});
  }
  check.Apply(class_views, change_views);
  int64_t cast_hidden = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      const auto p = room.cameras[0].PixelToPlane(Eigen::Vector2d(x, y), 0.0);
      if (p && in_hidden(*p)) cast_hidden += changes[0](x, y) != 0;
    }
  }
  EXPECT_LT(cast_hidden, hidden / 5);
}

}  // namespace
}  // namespace occmap
