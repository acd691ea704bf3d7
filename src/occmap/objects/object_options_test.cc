#include "occmap/objects/object_options.h"

#include <gtest/gtest.h>

#include <cmath>

namespace occmap {
namespace {

// Parses the `blobs:` and `tracking:` sections of `text` (a whole site file) over `options`.
Status Parse(const std::string& text, ObjectOptions& options) {
  Result<YamlField> root = ParseYaml(text, "site.yaml");
  if (!root.ok()) return root.status();
  if (auto f = root->Find("blobs")) OCCMAP_RETURN_IF_ERROR(ParseObjectOptions(*f, options));
  if (auto f = root->Find("tracking")) OCCMAP_RETURN_IF_ERROR(ParseObjectKeysOfTracking(*f, options));
  return Status::Ok();
}

TEST(ObjectOptions, DefaultsAreValid) {
  const ObjectOptions options;
  EXPECT_TRUE(options.Validate().ok()) << options.Validate().ToString();
  EXPECT_NEAR(options.person_area_m2(), M_PI * 0.0625, 1e-12);
  EXPECT_EQ(options.person_radius_m(), 0.25);
}

TEST(ObjectOptions, ValidateNamesTheSectionTheFieldAndTheValue) {
  ObjectOptions options;
  options.group_radius_m = 7;
  EXPECT_EQ(options.Validate().message(), "blobs.group_radius_m: expected 0..5 m, found 7");
  options = {};
  options.support_heights_m = {0.5, -1};
  EXPECT_EQ(options.Validate().message(), "blobs.support_heights_m: expected heights in (0, 10) m, found -1");
  options = {};
  options.max_people_per_blob = 0;
  EXPECT_EQ(options.Validate().message(), "tracking.max_people_per_blob: expected an integer in [1, 1000], found 0");
  options = {};
  options.split_min_neck_m = 0;
  EXPECT_EQ(options.Validate().message(), "tracking.split_min_neck_m: expected a number > 0, found 0");
  options = {};
  options.person_diameter_m = NAN;
  EXPECT_EQ(options.Validate().message(), "tracking.person_diameter_m: expected a number > 0, found nan");
}

TEST(ParseObjectOptions, ReadsBothSectionsAndIgnoresTheTrackersKeys) {
  ObjectOptions options;
  const Status status = Parse(R"(
blobs:
  group_radius_m: 0.2
  min_area_m2: 0.015
  split: false
  remove_ghosts: false
  occluder_height_m: 1.6
  min_clear_views: 1
  support_heights_m: [0.35, 1.0]
  min_support: 0.3
  support_slack_m: 0.04
  standing_radius_m: 0.25
tracking:
  algorithm: window
  max_speed_mps: 3
  person_diameter_m: 0.6
  min_detection_area_m2: 0.05
  max_people_per_blob: 4
  split_area_margin: 0.3
  split_min_neck_m: 0.07
  split_min_peak_radius_m: 0.1
)",
                              options);
  ASSERT_TRUE(status.ok()) << status.ToString();
  EXPECT_EQ(options.group_radius_m, 0.2);
  EXPECT_EQ(options.min_area_m2, 0.015);
  EXPECT_FALSE(options.split);
  EXPECT_FALSE(options.remove_ghosts);
  EXPECT_EQ(options.occluder_height_m, 1.6);
  EXPECT_EQ(options.min_clear_views, 1);
  EXPECT_EQ(options.support_heights_m, (std::vector<double>{0.35, 1.0}));
  EXPECT_EQ(options.min_support, 0.3);
  EXPECT_EQ(options.support_slack_m, 0.04);
  EXPECT_EQ(options.standing_radius_m, 0.25);
  EXPECT_EQ(options.person_diameter_m, 0.6);
  EXPECT_EQ(options.min_detection_area_m2, 0.05);
  EXPECT_EQ(options.max_people_per_blob, 4);
  EXPECT_EQ(options.split_area_margin, 0.3);
  EXPECT_EQ(options.split_min_neck_m, 0.07);
  EXPECT_EQ(options.split_min_peak_radius_m, 0.1);
  EXPECT_TRUE(options.Validate().ok());
}

TEST(ParseObjectOptions, EmptySectionsKeepTheValues) {
  ObjectOptions options;
  options.group_radius_m = 0.1;
  EXPECT_TRUE(Parse("blobs: {}\ntracking: {}\n", options).ok());
  EXPECT_TRUE(Parse("blobs:\ntracking:\n", options).ok());
  EXPECT_EQ(options.group_radius_m, 0.1);
  EXPECT_EQ(options.person_diameter_m, 0.5);
}

TEST(ParseObjectOptions, MalformedInputsGiveLocatedMessagesAndLeaveTheOptionsAlone) {
  const struct {
    const char* yaml;
    const char* message;
  } cases[] = {
      {"blobs: 3", "site.yaml:1: blobs: expected a map, found '3'"},
      {"blobs:\n  group_radius: 0.2", "site.yaml:2: blobs: unknown field 'group_radius' (did you mean 'group_radius_m'?)"},
      {"blobs:\n  group_radius_m: 6", "site.yaml:2: blobs.group_radius_m: expected 0..5 m, found 6"},
      {"blobs:\n  min_area_m2: -1", "site.yaml:2: blobs.min_area_m2: expected >= 0, found -1"},
      {"blobs:\n  standing_radius_m: 3", "site.yaml:2: blobs.standing_radius_m: expected 0..2 m, found 3"},
      {"blobs:\n  split: maybe", "site.yaml:2: blobs.split: expected true or false, found 'maybe'"},
      {"blobs:\n  support_heights_m: [0.5, 12]", "site.yaml:2: blobs.support_heights_m: expected heights in (0, 10) m, found 12"},
      {"blobs:\n  min_support: 1.5", "site.yaml:2: blobs.min_support: expected a fraction in [0, 1], found 1.5"},
      {"blobs:\n  occluder_height_m: 0", "site.yaml:2: blobs.occluder_height_m: expected > 0 m, found 0"},
      {"blobs:\n  min_clear_views: 0", "site.yaml:2: blobs.min_clear_views: expected 1..64 cameras, found 0"},
      {"blobs:\n  min_clear_views: 1.5", "site.yaml:2: blobs.min_clear_views: expected an integer, found '1.5'"},
      {"tracking: 3", "site.yaml:1: tracking: expected a map, found '3'"},
      {"tracking:\n  person_diameter_m: -1", "site.yaml:2: tracking.person_diameter_m: expected a number > 0, found -1"},
      {"tracking:\n  max_people_per_blob: 2.5", "site.yaml:2: tracking.max_people_per_blob: expected an integer, found '2.5'"},
      {"tracking:\n  split_area_margin: 2", "site.yaml:2: tracking.split_area_margin: expected a number in [0, 1], found 2"},
  };
  for (const auto& c : cases) {
    ObjectOptions options;
    options.group_radius_m = 0.3;
    const Status status = Parse(c.yaml, options);
    EXPECT_EQ(status.message(), c.message) << c.yaml;
    EXPECT_EQ(options.group_radius_m, 0.3) << c.yaml;
    EXPECT_EQ(options.person_diameter_m, 0.5) << c.yaml;
  }
}

}  // namespace
}  // namespace occmap
