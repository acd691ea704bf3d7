// Test-only helpers for the simulator's tests: small scenes built in code.
#pragma once

#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/scene.h"

namespace occmap::sim::sim_testing {

// The lab at a reduced image size (scale 0.25: 160x120) and a few frames: fast to render.
inline Scene SmallLab(double scale = 0.25, int64_t frames = 100, uint64_t seed = 1) {
  BuiltinSceneOptions o;
  o.image_scale = scale;
  o.num_frames = frames;
  o.seed = seed;
  return Scene::Create(MakeLabSceneSpec(o)).value();
}

// A 4 x 3 m room, one camera looking down from above and one from the side, and one object.
inline SceneSpec OneObjectSpec(ObjectClass c, const Eigen::Vector2d& at = {2.0, 1.5}) {
  SceneSpec s;
  s.name = "one";
  s.num_frames = 3;
  s.grid = FloorGrid{.origin_x_m = 0, .origin_y_m = 0, .cells_x = 80, .cells_y = 60, .cell_size_m = 0.05};
  Material floor;
  floor.colour = {0.5f, 0.5f, 0.5f};
  s.floor.push_back({-0.5, -0.5, 4.5, 3.5, floor});
  s.room.x_min_m = -0.5;
  s.room.y_min_m = -0.5;
  s.room.x_max_m = 4.5;
  s.room.y_max_m = 3.5;
  s.room.wall.colour = {0.8f, 0.8f, 0.8f};
  s.room.ceiling.colour = {0.9f, 0.9f, 0.9f};
  s.cameras.push_back(LookAtPinhole("top", {2.0, 1.4, 2.9}, {2.0, 1.5, 0.0}, {160, 120}, 120));
  s.cameras.push_back(LookAtPinhole("side", {-0.3, -0.3, 2.5}, {2.0, 1.5, 0.0}, {160, 120}, 130, {-0.1, 0.02, 0, 0, 0}));
  s.photometry.noise_sigma = 0;
  MovingObjectSpec o;
  o.id = 7;
  o.object_class = c;
  o.appearance = RandomAppearance(c, 1, 7, floor.colour, 0.0);
  o.path = {{0.0, at, false}, {10.0, at, false}};
  s.objects.push_back(o);
  return s;
}

}  // namespace occmap::sim::sim_testing
