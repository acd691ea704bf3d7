#include "occmap/track/tracker_options.h"

#include <gtest/gtest.h>

#include <cmath>

namespace occmap {
namespace {

// Parses `text` (a whole site file holding `tracking:`) over the defaults.
Status Parse(const std::string& text, TrackerOptions& options) {
  Result<YamlField> root = ParseYaml(text, "site.yaml");
  if (!root.ok()) return root.status();
  Result<YamlField> tracking = root->Get("tracking");
  if (!tracking.ok()) return tracking.status();
  return ParseTrackerOptions(*tracking, options);
}

TEST(TrackerOptions, DefaultsAreValid) {
  const TrackerOptions options;
  EXPECT_TRUE(options.Validate().ok()) << options.Validate().ToString();
  EXPECT_NEAR(options.person_area_m2(), M_PI * 0.0625, 1e-12);
}

TEST(TrackerOptions, ValidateNamesTheFieldAndTheValue) {
  TrackerOptions options;
  options.confirm_hits = 0;
  EXPECT_EQ(options.Validate().message(), "tracking.confirm_hits: expected an integer >= 1, found 0");
  options = {};
  options.class_area_smoothing = 0;
  EXPECT_EQ(options.Validate().message(), "tracking.class_area_smoothing: expected a number in (0, 1], found 0");
  options = {};
  options.confirm_hits = 6;
  EXPECT_EQ(options.Validate().message(), "tracking.confirm_hits: expected at most confirm_frames (5), found 6");
  options = {};
  options.classes = {{"person", 0.4}, {"robot", 0.1}};
  EXPECT_EQ(options.Validate().message(),
            "tracking.classes[1].max_area_m2: expected more than the previous class's 0.4 m^2 (classes in increasing "
            "order of area), found 0.1");
  options = {};
  options.zones = {{"a", {{0, 0}, {1, 0}, {1, 1}}, std::nullopt}, {"a", {{0, 0}, {1, 0}, {1, 1}}, std::nullopt}};
  EXPECT_EQ(options.Validate().message(), "tracking.zones[1].name: duplicate zone name 'a'");
}

TEST(ParseTrackerOptions, ReadsEveryKindOfField) {
  TrackerOptions options;
  const Status status = Parse(R"(
tracking:
  algorithm: window
  max_speed_mps: 3
  confirm_hits: 2
  confirm_frames: 4
  max_coast_s: 0.75
  report_coasting_s: 0.25
  zone_count_every_frame: true
  classes: [{name: robot, max_area_m2: 0.14}, {name: person, max_area_m2: 0.45}, {name: cart}]
  zones:
    - {name: door, polygon: [[0, 0], [1.5, 0], [1.5, 1], [0, 1]], dwell_s: 5}
    - name: desk
      polygon: [[2, 2], [3, 2], [3, 3]]
  lines:
    - {name: gate, from: [0, -1], to: [0.5, 2]}
    - {name: door, from: [3, 0], to: [3, 1], hysteresis_m: 0.35, once_per_track: false}
)",
                              options);
  ASSERT_TRUE(status.ok()) << status.ToString();
  EXPECT_EQ(options.algorithm, TrackerAlgorithm::kWindow);
  EXPECT_EQ(options.max_speed_mps, 3.0);
  EXPECT_EQ(options.confirm_hits, 2);
  EXPECT_EQ(options.confirm_frames, 4);
  EXPECT_EQ(options.max_coast_s, 0.75);
  EXPECT_EQ(options.report_coasting_s, 0.25);
  EXPECT_TRUE(options.zone_count_every_frame);
  EXPECT_EQ(options.person_diameter_m, 0.5) << "absent keys keep their defaults";
  ASSERT_EQ(options.classes.size(), 3u);
  EXPECT_EQ(options.classes[0].name, "robot");
  EXPECT_EQ(options.classes[1].max_area_m2, 0.45);
  EXPECT_TRUE(std::isinf(options.classes[2].max_area_m2));
  ASSERT_EQ(options.zones.size(), 2u);
  EXPECT_EQ(options.zones[0].name, "door");
  ASSERT_EQ(options.zones[0].polygon_m.size(), 4u);
  EXPECT_EQ(options.zones[0].polygon_m[1], Eigen::Vector2d(1.5, 0));
  EXPECT_EQ(options.zones[0].dwell_s, 5.0);
  EXPECT_FALSE(options.zones[1].dwell_s.has_value());
  ASSERT_EQ(options.lines.size(), 2u);
  EXPECT_EQ(options.lines[0].name, "gate");
  EXPECT_EQ(options.lines[0].from_m, Eigen::Vector2d(0, -1));
  EXPECT_EQ(options.lines[0].to_m, Eigen::Vector2d(0.5, 2));
  EXPECT_EQ(options.lines[0].hysteresis_m, 0.2);
  EXPECT_TRUE(options.lines[0].once_per_track);
  EXPECT_EQ(options.lines[1].hysteresis_m, 0.35);
  EXPECT_FALSE(options.lines[1].once_per_track);
}

TEST(ParseTrackerOptions, AnEmptySectionKeepsTheDefaults) {
  TrackerOptions options;
  options.max_speed_mps = 1.5;
  const Result<YamlField> root = ParseYaml("tracking:\n", "site.yaml");
  ASSERT_TRUE(root.ok());
  const YamlField empty(root->node()["tracking"], std::make_shared<const std::string>("site.yaml"), "tracking");
  ASSERT_TRUE(empty.IsNull());
  EXPECT_TRUE(ParseTrackerOptions(empty, options).ok());
  EXPECT_EQ(options.max_speed_mps, 1.5);
  EXPECT_TRUE(Parse("tracking: {}", options).ok());
  EXPECT_EQ(options.max_speed_mps, 1.5);
}

TEST(ParseTrackerOptions, TheObjectDetectorsKeysAreAcceptedOnlyWhenPassedAsOtherKeys) {
  // The site passes the object detector's keys of the section (objects/object_options.h).
  const std::string_view split_keys[] = {"split_min_neck_m"};
  const Result<YamlField> root = ParseYaml("tracking:\n  split_min_neck_m: 0.1\n", "site.yaml");
  ASSERT_TRUE(root.ok());
  TrackerOptions options;
  EXPECT_TRUE(ParseTrackerOptions(*root->Find("tracking"), options, split_keys).ok());
  EXPECT_EQ(ParseTrackerOptions(*root->Find("tracking"), options).message(),
            "site.yaml:2: tracking: unknown field 'split_min_neck_m' (expected one of: algorithm, classes, zones, "
            "zone_count_every_frame, lines, max_speed_mps, person_diameter_m, acceleration_psd_m2ps3, measurement_sigma_m, "
            "spread_noise_weight, guided_split_sigma_m, initial_speed_sigma_mps, gate_chi2, confirm_hits, "
            "confirm_frames, max_coast_s, report_coasting_s, birth_min_separation_m, class_hysteresis, "
            "class_area_smoothing, window_object_radius_m, window_lost_timeout_s, window_min_new_area_m2, "
            "trail_length)");
}

TEST(ParseTrackerOptions, MalformedInputsGiveLocatedMessagesAndLeaveTheOptionsAlone) {
  const struct {
    const char* yaml;
    const char* message;
  } cases[] = {
      {"tracking: 3", "site.yaml:1: tracking: expected a map, found '3'"},
      {"tracking:\n  max_sped_mps: 2", "site.yaml:2: tracking: unknown field 'max_sped_mps' (did you mean 'max_speed_mps'?)"},
      {"tracking:\n  colour: red", "site.yaml:2: tracking: unknown field 'colour' (expected one of: algorithm, classes, zones, "
                                   "zone_count_every_frame, lines, max_speed_mps, person_diameter_m, "
                                   "acceleration_psd_m2ps3, measurement_sigma_m, spread_noise_weight, guided_split_sigma_m, "
                                   "initial_speed_sigma_mps, gate_chi2, confirm_hits, confirm_frames, max_coast_s, "
                                   "report_coasting_s, birth_min_separation_m, class_hysteresis, class_area_smoothing, window_object_radius_m, "
                                   "window_lost_timeout_s, window_min_new_area_m2, trail_length)"},
      {"tracking:\n  algorithm: kalman", "site.yaml:2: tracking.algorithm: expected 'multi_target' or 'window', found 'kalman'"},
      {"tracking:\n  max_speed_mps: fast", "site.yaml:2: tracking.max_speed_mps: expected a finite number, found 'fast'"},
      {"tracking:\n  report_coasting_s: -0.1", "site.yaml:2: tracking.report_coasting_s: expected a number >= 0, found -0.1"},
      {"tracking:\n  max_speed_mps: -1", "site.yaml:2: tracking.max_speed_mps: expected a number > 0, found -1"},
      {"tracking:\n  max_speed_mps: .nan", "site.yaml:2: tracking.max_speed_mps: expected a finite number, found '.nan'"},
      {"tracking:\n  confirm_hits: 2.5", "site.yaml:2: tracking.confirm_hits: expected an integer, found '2.5'"},
      {"tracking:\n  confirm_hits: 0", "site.yaml:2: tracking.confirm_hits: expected an integer >= 1, found 0"},
      {"tracking:\n  class_hysteresis: 1", "site.yaml:2: tracking.class_hysteresis: expected a number in [0, 1), found 1"},
      {"tracking:\n  confirm_frames: 2", "site.yaml:2: tracking.confirm_frames: expected at least confirm_hits (3), found 2"},
      {"tracking:\n  confirm_hits: 4\n  confirm_frames: 3",
       "site.yaml:2: tracking.confirm_hits: expected at most confirm_frames (3), found 4"},
      {"tracking:\n  zone_count_every_frame: maybe",
       "site.yaml:2: tracking.zone_count_every_frame: expected true or false, found 'maybe'"},
      {"tracking:\n  classes: {name: robot}", "site.yaml:2: tracking.classes: expected a list of {name, max_area_m2}"},
      {"tracking:\n  classes:\n    - {name: robot, max_area: 0.1}",
       "site.yaml:3: tracking.classes[0]: unknown field 'max_area' (expected one of: name, max_area_m2)"},
      {"tracking:\n  classes:\n    - {max_area_m2: 0.1}", "site.yaml:3: tracking.classes[0]: missing required field 'name'"},
      {"tracking:\n  classes:\n    - {name: cart}\n    - {name: robot, max_area_m2: 0.1}",
       "site.yaml:4: tracking.classes[1]: expected no class after 'cart', which leaves out max_area_m2 (only the last "
       "class may)"},
      {"tracking:\n  classes:\n    - {name: robot, max_area_m2: 0.1}\n    - {name: robot, max_area_m2: 0.2}",
       "site.yaml:4: tracking.classes[1].name: duplicate class name 'robot'"},
      {"tracking:\n  zones:\n    - {name: door}", "site.yaml:3: tracking.zones[0]: missing required field 'polygon'"},
      {"tracking:\n  zones:\n    - {name: door, polygon: [[0, 0], [1, 0]]}",
       "site.yaml:3: tracking.zones[0].polygon: expected at least 3 vertices, found 2"},
      {"tracking:\n  zones:\n    - {name: door, polygon: [[0, 0], [1, 0], [1]]}",
       "site.yaml:3: tracking.zones[0].polygon[2]: expected a list of 2 numbers, found 1"},
      {"tracking:\n  zones:\n    - {name: door, polygon: [[0, 0], [1, 0], [2, 0]]}",
       "site.yaml:3: tracking.zones[0].polygon: expected a polygon with a non-zero area"},
      {"tracking:\n  zones:\n    - {name: door, polygon: [[0, 0], [1, 0], [1, 1]], dwell_s: 0}",
       "site.yaml:3: tracking.zones[0].dwell_s: expected a number > 0, found 0"},
      {"tracking:\n  zones:\n    - {name: door, polygon: [[0, 0], [1, 0], [1, 1]], dwel_s: 3}",
       "site.yaml:3: tracking.zones[0]: unknown field 'dwel_s' (did you mean 'dwell_s'?)"},
      {"tracking:\n  zones:\n    - {name: a, polygon: [[0, 0], [1, 0], [1, 1]]}\n    - {name: a, polygon: [[0, 0], [1, 0], [1, 1]]}",
       "site.yaml:4: tracking.zones[1].name: duplicate zone name 'a'"},
      {"tracking:\n  lines: {name: door}", "site.yaml:2: tracking.lines: expected a list of {name, from, to}"},
      {"tracking:\n  lines:\n    - {name: door, from: [0, 0]}", "site.yaml:3: tracking.lines[0]: missing required field 'to'"},
      {"tracking:\n  lines:\n    - {name: door, from: [0, 0], to: [1]}",
       "site.yaml:3: tracking.lines[0].to: expected a list of 2 numbers, found 1"},
      {"tracking:\n  lines:\n    - {name: door, from: [0, 0], to: [0, 0.0001]}",
       "site.yaml:3: tracking.lines[0].to: expected a point at least 1 mm from 'from', found 0.0001 m from it"},
      {"tracking:\n  lines:\n    - {name: door, from: [0, 0], to: [1, 0], width: 2}",
       "site.yaml:3: tracking.lines[0]: unknown field 'width' (expected one of: name, from, to, hysteresis_m, once_per_track)"},
      {"tracking:\n  lines:\n    - {name: door, from: [0, 0], to: [1, 0], hysteresis_m: 3}",
       "site.yaml:3: tracking.lines[0].hysteresis_m: expected 0..2 m, found 3"},
      {"tracking:\n  lines:\n    - {name: a, from: [0, 0], to: [1, 0]}\n    - {name: a, from: [0, 1], to: [1, 1]}",
       "site.yaml:4: tracking.lines[1].name: duplicate line name 'a'"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.yaml);
    TrackerOptions options;
    options.max_speed_mps = 1.25;
    const Status status = Parse(c.yaml, options);
    ASSERT_FALSE(status.ok());
    EXPECT_EQ(status.code(), StatusCode::kInvalidInput);
    EXPECT_EQ(status.message(), c.message);
    EXPECT_EQ(options.max_speed_mps, 1.25) << "options must not change on error";
    EXPECT_TRUE(options.zones.empty());
  }
}

}  // namespace
}  // namespace occmap
