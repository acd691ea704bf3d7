#include <gtest/gtest.h>

#include <map>

#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/renderer.h"
#include "occmap/util/testing.h"

namespace occmap::sim {
namespace {

TEST(WildtrackScene, PositionIdsMapToTheDatasetsGrid) {
  EXPECT_EQ(WildtrackPositionM(0), Eigen::Vector2d(-3.0, -9.0));
  EXPECT_NEAR((WildtrackPositionM(480 * 2 + 4) - Eigen::Vector2d(-2.9, -8.95)).norm(), 0, 1e-12);
}

TEST(WildtrackScene, PeopleStandAtTheirAnnotatedPositionsAtAnnotatedFrames) {
  OCCMAP_REQUIRE_DATASETS(root);
  WildtrackSceneOptions wt;
  wt.dataset_dir = root / "wildtrack";
  wt.first_frame = 100;
  BuiltinSceneOptions o;
  o.num_frames = 41;  // frames 100 .. 140: nine annotation files
  o.image_scale = 0.125;
  auto spec = MakeWildtrackSceneSpec(o, wt);
  ASSERT_TRUE(spec.ok()) << spec.status().message();
  EXPECT_EQ(spec->cameras.size(), 7u);
  EXPECT_EQ(spec->cameras[0].image_size(), (ImageSize{240, 135}));
  const Scene scene = Scene::Create(*spec).value();
  auto annotations = ReadWildtrackAnnotations(wt.dataset_dir / "annotations_positions");
  ASSERT_TRUE(annotations.ok());
  ASSERT_EQ(annotations->size(), 400u);
  std::map<int64_t, const WildtrackAnnotation*> by_frame;
  for (const auto& a : *annotations) by_frame[a.frame] = &a;
  int checked = 0;
  for (int64_t frame = 100; frame <= 140; frame += 5) {
    const SceneState state = scene.StateAt(frame - 100);
    const WildtrackAnnotation& a = *by_frame.at(frame);
    EXPECT_EQ(state.objects.size(), a.people.size()) << frame;
    for (const auto& person : a.people) {
      const auto it = std::find_if(state.objects.begin(), state.objects.end(),
                                   [&](const ObjectInstance& o2) { return o2.id == person.person_id + 1; });
      ASSERT_NE(it, state.objects.end()) << "person " << person.person_id << " at frame " << frame;
      EXPECT_NEAR((it->position_m - person.position_m).norm(), 0, 1e-9);
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
  // Between two annotations a person present in both is interpolated linearly.
  const WildtrackAnnotation& a0 = *by_frame.at(100);
  const WildtrackAnnotation& a1 = *by_frame.at(105);
  const SceneState mid = scene.StateAt(2);  // frame 102: 2/5 of the way
  for (const auto& p0 : a0.people) {
    for (const auto& p1 : a1.people) {
      if (p0.person_id != p1.person_id) continue;
      const auto it = std::find_if(mid.objects.begin(), mid.objects.end(),
                                   [&](const ObjectInstance& o2) { return o2.id == p0.person_id + 1; });
      ASSERT_NE(it, mid.objects.end());
      EXPECT_NEAR((it->position_m - (0.6 * p0.position_m + 0.4 * p1.position_m)).norm(), 0, 1e-9);
    }
  }
  // And people are rendered: camera C1 sees some of them.
  Context ctx(2);
  const CameraRenderer r(scene, 0, ctx);
  RenderedView view;
  r.Render(scene.StateAt(0), ctx, &view);
  int64_t changed = 0;
  for (int y = 0; y < view.ids.height(); ++y) {
    for (int x = 0; x < view.ids.width(); ++x) changed += view.ids(x, y) != 0;
  }
  EXPECT_GT(changed, 100);
}

TEST(WildtrackScene, MissingDatasetFolderIsNotFound) {
  occmap::testing::TempDir dir;
  WildtrackSceneOptions wt;
  wt.dataset_dir = dir / "nope";
  auto spec = MakeWildtrackSceneSpec({}, wt);
  EXPECT_EQ(spec.status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace occmap::sim
