#include "occmap/fusion/people_options.h"

#include <gtest/gtest.h>

namespace occmap {
namespace {

Status Parse(const std::string& text, PeopleOptions& o) {
  auto yaml = ParseYaml(text, "site.yaml");
  if (!yaml.ok()) return yaml.status();
  return ParsePeopleOptions(*yaml, 4, o);
}

TEST(PeopleOptionsTest, DefaultsAndEveryKey) {
  PeopleOptions o;
  ASSERT_TRUE(Parse("{}", o).ok());
  EXPECT_TRUE(o.enabled);
  EXPECT_EQ(o.detector, PeopleDetector::kExplain);
  EXPECT_DOUBLE_EQ(o.column.band_low_m, 0.8);
  EXPECT_TRUE(o.Validate(4).ok());
  PeopleOptions p;
  const Status s = Parse(
      "detector: column\nheight_m: 1.8\nstep_m: 0.05\n"
      "column: {band_m: [0.5, 1.6], radius_m: 0.12, min_changed: 0.6, max_free_views: 1, max_rows: 10}\n"
      "explain: {radius_m: 0.2, unchanged_weight: 0.5, min_gain: 1.0, min_separation_m: 0.4, moves: 0, "
      "move_radius_m: 0.3, max_people: 50, max_rows: 20, ground_band: 0.1, ground_weight: 0.5}\n"
      "occluders: {learn: true, max_changed: 0.05, min_others: 3, episode_frames: 10, min_episodes: 4, "
      "max_contrary: 0.1}\n",
      p);
  ASSERT_TRUE(s.ok()) << s.message();
  EXPECT_EQ(p.detector, PeopleDetector::kColumn);
  EXPECT_DOUBLE_EQ(p.columns.height_m, 1.8);
  EXPECT_DOUBLE_EQ(p.column.band_high_m, 1.6);
  EXPECT_EQ(p.column.max_free_views, 1);
  EXPECT_EQ(p.explain.moves, 0);
  EXPECT_EQ(p.explain.max_people, 50);
  EXPECT_EQ(p.explain.max_rows, 20);
  EXPECT_DOUBLE_EQ(p.explain.ground_band, 0.1);
  EXPECT_DOUBLE_EQ(p.explain.ground_weight, 0.5);
  EXPECT_TRUE(p.occluders.learn);
  EXPECT_DOUBLE_EQ(p.occluders.max_changed, 0.05);
  EXPECT_EQ(p.occluders.min_others, 3);
  EXPECT_EQ(p.occluders.episode_frames, 10);
  EXPECT_EQ(p.occluders.min_episodes, 4);
  EXPECT_DOUBLE_EQ(p.occluders.max_contrary, 0.1);
  EXPECT_FALSE(o.occluders.learn);  // off without the key
}

TEST(PeopleOptionsTest, BadValuesNameTheirField) {
  for (const char* bad : {"detector: pom", "column: {band_m: [1.2, 0.4]}", "column: {band_m: [0.5, 2.5]}",
                          "explain: {radius_m: 0}", "explain: {ground_band: 2}", "explain: {moves: -1}", "height_m: 0", "step_m: 3",
                          "column: {max_free_views: 4}", "colum: {}",
                          "occluders: {learn: maybe}", "occluders: {min_episodes: 0}", "occluders: {max_changed: 1}",
                          "occluders: {lern: true}"}) {
    PeopleOptions o;
    const Status s = Parse(bad, o);
    EXPECT_FALSE(s.ok()) << bad;
    EXPECT_NE(s.message().find("site.yaml"), std::string::npos) << bad << ": " << s.message();
  }
}

}  // namespace
}  // namespace occmap
