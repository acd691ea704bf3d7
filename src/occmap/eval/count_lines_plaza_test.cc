// Counting lines (track/count_lines.h) against the simulator's ground truth: here, where both
// sim and track are below.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <map>
#include <random>
#include <set>

#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/scene.h"
#include "occmap/track/count_lines.h"

namespace occmap {
namespace {

LineOptions Line(std::string name, Eigen::Vector2d from_m, Eigen::Vector2d to_m, double hysteresis_m,
                 bool once_per_track) {
  LineOptions l;
  l.name = std::move(name);
  l.from_m = from_m;
  l.to_m = to_m;
  l.hysteresis_m = hysteresis_m;
  l.once_per_track = once_per_track;
  return l;
}

Track At(int64_t id, double x_m, double y_m) {
  Track t;
  t.id = id;
  t.x_m = x_m;
  t.y_m = y_m;
  return t;
}

// The simulator's plaza (people crossing, standing alone and in groups for 20-50 s) with three
// lines across it. The truth, from the exact paths: each person who goes from one side to the
// other (farther than the band from the line on both: a group's member who steps 5 cm over the
// line to stand in its ring has not crossed it) counts once in each direction they do so. The
// tracks: the true positions with a tracker's jitter (Gaussian, 10 cm, seeded). The defaults
// (20 cm band, once per track and direction) give the truth exactly; counting every crossing
// without a band (before) counts the jitter of people standing or walking near a line.
TEST(LineCounterOnThePlaza, EachPersonCrossingCountsOnce) {
  sim::BuiltinSceneOptions scene_options;
  scene_options.people = 16;
  scene_options.duration_s = 120;
  Result<sim::Scene> scene = sim::Scene::Create(sim::MakePlazaSceneSpec(scene_options));
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  const FloorGrid& g = scene->grid();
  std::vector<LineOptions> banded, bare;
  for (int k = 1; k <= 3; ++k) {
    const double x_m = g.origin_x_m + g.size_x_m() * k / 4;
    // Far beyond the grid: people walk in from outside it, and the truth takes the whole line.
    const Eigen::Vector2d from(x_m, g.origin_y_m - 100), to(x_m, g.origin_y_m + g.cells_y * g.cell_size_m + 100);
    banded.push_back(Line("x" + std::to_string(k), from, to, LineOptions{}.hysteresis_m, LineOptions{}.once_per_track));
    bare.push_back(Line("x" + std::to_string(k), from, to, 0, false));
  }
  Result<LineCounter> counter = LineCounter::Create(banded), before = LineCounter::Create(bare);
  ASSERT_TRUE(counter.ok() && before.ok());

  // Per line, the (person, direction) pairs of the truth: the side of x_m a person is on,
  // frame to frame ("in" = towards -x, left of the upward line).
  std::vector<std::set<std::pair<int64_t, bool>>> truth(banded.size());
  std::vector<std::map<int64_t, int>> true_side(banded.size());  // per line: the last side off the band
  std::mt19937 rng(7);
  std::normal_distribution<double> jitter_m(0.0, 0.1);
  int64_t true_crossings = 0;
  for (int64_t f = 0; f < scene->num_frames(); ++f) {
    const GroundTruthFrame gt = sim::ToGroundTruth(scene->StateAt(f));
    std::vector<Track> tracks;
    for (const GroundTruthObject& o : gt.objects) {
      if (o.object_class != "person") continue;
      for (size_t l = 0; l < banded.size(); ++l) {
        const double offset_m = o.x_m - banded[l].from_m.x();
        if (std::abs(offset_m) <= banded[l].hysteresis_m) continue;
        const int side = offset_m < 0 ? 1 : -1;  // left of the upward line: towards -x
        int& last = true_side[l][o.id];
        if (last != 0 && last != side) {
          truth[l].insert({o.id, side > 0});
          ++true_crossings;
        }
        last = side;
      }
      Track t = At(o.id + 1, o.x_m + jitter_m(rng), o.y_m + jitter_m(rng));
      t.object_class = "person";
      tracks.push_back(t);
    }
    counter->Update(f, gt.time_s, tracks);
    before->Update(f, gt.time_s, tracks);
  }
  int64_t expected_total = 0;
  for (size_t l = 0; l < banded.size(); ++l) {
    LineCounts expected;
    for (const auto& [id, in] : truth[l]) (in ? expected.in : expected.out) += 1;
    expected_total += expected.in + expected.out;
    EXPECT_EQ(counter->counts()[l], expected) << banded[l].name;
  }
  ASSERT_GE(expected_total, 20) << "the lines are crossed";
  int64_t before_total = 0, counted_total = 0;
  for (const LineCounts& c : before->counts()) before_total += c.in + c.out;
  for (const LineCounts& c : counter->counts()) counted_total += c.in + c.out;
  EXPECT_GT(before_total, expected_total) << "every crossing, no band: the jitter counts";
  std::cout << "plaza, 3 lines: " << expected_total << " people-directions (" << true_crossings
            << " true crossings); counted " << counted_total << " with the defaults, " << before_total
            << " counting every crossing without a band\n";
}

}  // namespace
}  // namespace occmap
