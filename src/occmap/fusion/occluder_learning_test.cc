#include "occmap/fusion/occluder_learning.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "occmap/fusion/test_people.h"
#include "occmap/fusion/view_explainer.h"
#include "occmap/util/file_util.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;

// The small room's pillar: it hides (2.0, 1.5) from camera 0.
Occluder Pillar() {
  Occluder pillar;
  pillar.shape = Occluder::Shape::kCylinder;
  pillar.centre_m = {1.0, 0.7};
  pillar.size_m = {0.4, 0.4};
  pillar.height_m = 3;
  return pillar;
}

// People seen as a pillar lets them be: each painted in every camera but those the pillar's
// table (given) says it hides.
struct Walk {
  testing::PeopleRoom truth;
  explicit Walk(bool pillar) : truth(pillar ? std::vector<Occluder>{Pillar()} : std::vector<Occluder>{}) {}
  // Paints people at the positions into `scene` (whose table knows no statics).
  void Paint(testing::PeopleRoom& scene, const std::vector<Eigen::Vector2d>& people) const {
    scene.Clear();
    for (const auto& p : people) scene.Paint(p.x(), p.y(), 0.2, &truth.columns);
  }
};

OccluderLearningOptions TestOptions() {
  OccluderLearningOptions o;
  o.learn = true;
  o.episode_frames = 3;
  return o;
}

// People in the room, frame after frame: `near` of them around the hidden spot, the rest anywhere.
std::vector<Eigen::Vector2d> People(std::mt19937& rng, int near, int anywhere) {
  std::uniform_real_distribution<double> dx(1.8, 2.2), dy(1.3, 1.7), ax(0.4, 3.6), ay(0.4, 2.6);
  std::vector<Eigen::Vector2d> people;
  for (int i = 0; i < near; ++i) people.emplace_back(dx(rng), dy(rng));
  for (int i = 0; i < anywhere; ++i) people.emplace_back(ax(rng), ay(rng));
  return people;
}

// The column fusion's AND (no view outvoted): the learning is about one camera's unchanged view,
// which the default vote of column_fusion.h overrules where two others see the torso.
ColumnFusionOptions StrictColumns() {
  ColumnFusionOptions o;
  o.max_free_views = 0;
  return o;
}

// The people the views' explanation finds, as a run does (the default detector).
std::vector<ExplainedPerson> Explained(testing::PeopleRoom& scene) {
  ColumnFusion fusion(scene.columns);
  ViewExplainer explainer(scene.columns);
  Context ctx(1);
  OccupancyMap map;
  const std::vector<bool> active(4, true);
  fusion.Fuse(scene.Sums(), active, StrictColumns(), ctx, map);
  std::vector<ExplainedPerson> people;
  explainer.Explain(scene.Views(), scene.Sums(), active, map, ExplainOptions{}, ctx, people);
  return people;
}

// One frame set: explained, then learned from.
void Observe(OccluderLearner& learner, testing::PeopleRoom& scene, int64_t frame, Context& ctx) {
  const std::vector<ExplainedPerson> people = Explained(scene);
  learner.Observe(scene.Views(), scene.Sums(), std::vector<bool>(4, true), people, frame, ctx);
}

int ExplainedNear(testing::PeopleRoom& scene, double x, double y) {
  const std::vector<ExplainedPerson> people = Explained(scene);
  int found = 0;
  for (const auto& p : people) found += std::hypot(p.x_m - x, p.y_m - y) < 0.25 ? 1 : 0;
  return found;
}

TEST(OccluderLearningTest, APersonHiddenByAPillarIsFoundOnceItsViewIsLearned) {
  const Walk walk(/*pillar=*/true);
  testing::PeopleRoom scene;  // no statics given
  // Behind the pillar camera 0 sees nothing: the person is missed.
  walk.Paint(scene, {{2.0, 1.5}});
  EXPECT_EQ(ExplainedNear(scene, 2.0, 1.5), 0);

  OccluderLearner learner(scene.columns, StrictColumns(), TestOptions());
  std::mt19937 rng(3);
  Context ctx(2);
  int64_t blocked_at = -1;
  for (int frame = 0; frame < 300; ++frame) {
    walk.Paint(scene, People(rng, 1, 1));
    Observe(learner, scene, frame, ctx);
    if (blocked_at < 0 && scene.columns.view(0, scene.columns.candidates().CellAt(2.0, 1.5)).blocked) blocked_at = frame;
  }
  EXPECT_GE(blocked_at, 0);
  EXPECT_GT(learner.blocked_views(), 0);
  // Only camera 0's views are learned, those behind the pillar (all but a few at the edges of
  // its shadow, where the given table's half of the column and the learned half differ).
  const FloorGrid& g = scene.columns.candidates();
  int learned = 0, agree = 0;
  for (int c = 0; c < 4; ++c) {
    for (int64_t k = 0; k < g.num_cells(); ++k) {
      if (!scene.columns.view(c, k).learned) continue;
      EXPECT_EQ(c, 0) << k;
      ++learned;
      agree += walk.truth.columns.view(c, k).blocked ? 1 : 0;
    }
  }
  EXPECT_GE(agree, 0.9 * learned) << agree << " of " << learned;
  walk.Paint(scene, {{2.0, 1.5}});
  EXPECT_EQ(ExplainedNear(scene, 2.0, 1.5), 1);
}

TEST(OccluderLearningTest, NothingIsLearnedInARoomWithoutOccluders) {
  const Walk walk(/*pillar=*/false);
  testing::PeopleRoom scene;
  OccluderLearner learner(scene.columns, StrictColumns(), TestOptions());
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> px(0, 319), py(0, 239);
  Context ctx(2);
  // A crowd for the room (4 to 6 people: their shadows meet in ghosts) and noise.
  for (int frame = 0; frame < 300; ++frame) {
    walk.Paint(scene, People(rng, 1, 3 + frame % 3));
    for (auto& im : scene.changes)
      for (int n = 0; n < 500; ++n) im(px(rng), py(rng)) ^= 1;
    Observe(learner, scene, frame, ctx);
  }
  EXPECT_EQ(learner.blocked_views(), 0);
}

TEST(OccluderLearningTest, APersonStandingStillInFrontOfAnotherIsNotLearned) {
  // Camera 0 sees a person standing at (1.0, 0.7) for the whole run; others walk behind them.
  const Walk walk(/*pillar=*/false);
  testing::PeopleRoom scene;
  OccluderLearner learner(scene.columns, StrictColumns(), TestOptions());
  std::mt19937 rng(9);
  Context ctx(1);
  for (int frame = 0; frame < 200; ++frame) {
    auto people = People(rng, 1, 0);
    people.emplace_back(1.0, 0.7);
    walk.Paint(scene, people);
    Observe(learner, scene, frame, ctx);
  }
  EXPECT_EQ(learner.blocked_views(), 0);
}

TEST(OccluderLearningTest, GivenStaticsStayAndLearnedBlocksMoveTheColumnFusion) {
  testing::PeopleRoom given(std::vector<Occluder>{Pillar()});
  const int64_t k = given.columns.candidates().CellAt(2.0, 1.5);
  ASSERT_TRUE(given.columns.view(0, k).blocked);
  given.columns.SetLearnedBlocked(0, k, false);  // a given static is not unlearned
  EXPECT_TRUE(given.columns.view(0, k).blocked);
  EXPECT_EQ(given.columns.revision(), 0u);

  testing::PeopleRoom scene;
  scene.Paint(2.0, 1.5);
  for (int y = 0; y < 240; ++y) std::fill_n(scene.changes[0].row(y), 320, uint8_t{0});
  ColumnFusion fusion(scene.columns);
  Context ctx(1);
  OccupancyMap map;
  const std::vector<bool> active(4, true);
  const ColumnFusionOptions strict = StrictColumns();
  fusion.Fuse(scene.Sums(), active, strict, ctx, map);
  EXPECT_EQ(map.state(k), CellState::kFree);
  scene.columns.SetLearnedBlocked(0, k, true);
  fusion.Fuse(scene.Sums(), active, strict, ctx, map);
  EXPECT_EQ(map.state(k), CellState::kOccupied);
  OccupancyMap reference;
  fusion.FuseReference(scene.Views(), active, strict, reference);
  EXPECT_EQ(map, reference);
  scene.columns.SetLearnedBlocked(0, k, false);
  fusion.Fuse(scene.Sums(), active, strict, ctx, map);
  EXPECT_EQ(map.state(k), CellState::kFree);
}

class OccluderFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("occluders_test_{}", ::getpid());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  // A learner that has learned camera 0's view behind the pillar, saved to `path`.
  void Learn(testing::PeopleRoom& scene, const fs::path& path) {
    const Walk walk(true);
    OccluderLearner learner(scene.columns, StrictColumns(), TestOptions());
    std::mt19937 rng(3);
    Context ctx(1);
    for (int frame = 0; frame < 150; ++frame) {
      walk.Paint(scene, People(rng, 1, 1));
      Observe(learner, scene, frame, ctx);
    }
    ASSERT_GT(learner.blocked_views(), 0);
    ASSERT_TRUE(learner.Save(path).ok());
  }
  fs::path dir_;
};

TEST_F(OccluderFileTest, SavedAndLoadedAgain) {
  testing::PeopleRoom scene;
  Learn(scene, dir_ / "a.txt");
  testing::PeopleRoom fresh;
  OccluderLearner loaded(fresh.columns, StrictColumns(), TestOptions());
  ASSERT_TRUE(loaded.Load(dir_ / "a.txt").ok());
  const FloorGrid& g = scene.columns.candidates();
  for (int c = 0; c < 4; ++c)
    for (int64_t k = 0; k < g.num_cells(); ++k) ASSERT_EQ(fresh.columns.view(c, k).blocked, scene.columns.view(c, k).blocked);
  EXPECT_EQ(loaded.frames_observed(), 150);
  ASSERT_TRUE(loaded.Save(dir_ / "b.txt").ok());
  EXPECT_EQ(ReadFileToString(dir_ / "a.txt").value(), ReadFileToString(dir_ / "b.txt").value());
}

TEST_F(OccluderFileTest, MissingStaleAndMalformedFilesAreNamed) {
  testing::PeopleRoom scene;
  Learn(scene, dir_ / "a.txt");
  const std::string good = ReadFileToString(dir_ / "a.txt").value();
  {
    OccluderLearner l(scene.columns, StrictColumns(), TestOptions());
    EXPECT_EQ(l.Load(dir_ / "none.txt").code(), StatusCode::kNotFound);
  }
  {  // another table: the candidates of 0.2 m
    testing::PeopleRoom other;
    std::vector<LutCameraInput> in;
    for (const auto& c : other.room.cameras) in.push_back({&c, {}});
    Context ctx(1);
    ColumnLutOptions coarse;
    coarse.step_m = 0.2;
    ColumnLut columns = BuildColumnLut(in, other.room.grid, 0.0, coarse, {}, ctx).value();
    OccluderLearner l(columns, StrictColumns(), TestOptions());
    bool stale = false;
    const Status s = l.Load(dir_ / "a.txt", &stale);
    EXPECT_EQ(s.code(), StatusCode::kDataLoss);
    EXPECT_TRUE(stale);
    EXPECT_NE(s.message().find("stale"), std::string::npos) << s.message();
  }
  const auto replace_line = [&](int line, const std::string& text) {
    std::string out;
    size_t at = 0;
    for (int n = 1; at < good.size(); ++n) {
      const size_t end = good.find('\n', at);
      out += n == line ? text : good.substr(at, end - at);
      out += '\n';
      at = end + 1;
    }
    return out;
  };
  const size_t views_at = good.find("views ");
  const std::string header_and_views = good.substr(0, good.find('\n', views_at) + 1);
  struct Case {
    std::string text, where;
  };
  const std::vector<Case> cases = {
      {"", ":1:"},
      {"not an occluders file\n", ":1:"},
      {replace_line(2, "fingerprint zz"), ":2:"},
      {replace_line(4, "frames 10 settled 20 most 0 blocked 0"), ":4:"},
      {replace_line(6, "0 5 x 1"), ":6:"},
      {replace_line(6, "9 5 1 1"), ":6:"},          // camera out of range
      {replace_line(6, "0 999999 1 1"), ":6:"},     // candidate out of range
      {replace_line(6, "0 5 70000 1"), ":6:"},      // episodes out of range
      {replace_line(7, good.substr(good.find('\n', views_at) + 1, good.find('\n', good.find('\n', views_at) + 1) -
                                                                     good.find('\n', views_at) - 1)),
       ":7:"},                                      // a view twice
      {header_and_views, ":6:"},                    // truncated: no view lines
      {good + "0 1 1 1\n", ""},                     // more lines than it says
  };
  for (const Case& c : cases) {
    const fs::path p = dir_ / "bad.txt";
    ASSERT_TRUE(WriteFileAtomic(p, c.text).ok());
    testing::PeopleRoom fresh;
    OccluderLearner l(fresh.columns, StrictColumns(), TestOptions());
    const Status s = l.Load(p);
    EXPECT_EQ(s.code(), StatusCode::kDataLoss) << c.text.substr(0, 200);
    EXPECT_NE(s.message().find("bad.txt" + c.where), std::string::npos) << s.message();
    EXPECT_EQ(l.blocked_views(), 0);  // nothing applied from a bad file
  }
}

TEST(OccluderLearningTest, OptionsAreParsedAndChecked) {
  OccluderLearningOptions o;
  EXPECT_TRUE(o.Validate().ok());
  EXPECT_FALSE(o.learn);
  o.max_changed = 1;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.min_episodes = 0;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.episode_frames = 0;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.max_contrary = -0.1;
  EXPECT_FALSE(o.Validate().ok());
}

}  // namespace
}  // namespace occmap
