// Scene files (YAML) for custom simulated scenes: read with located messages, written back
// exactly (SceneToYaml writes every value explicitly; reading its output gives the same spec).
//
//   version: 1                        # optional; only 1 exists
//   name: corridor
//   seed: 7                           # optional, default 1: clothing, textures, noise
//   fps: 10                           # optional, default 10
//   frames: 100                       # optional, default 100 (or duration_s: 10)
//   description: text                 # optional
//   floor:                            # the monitored area = the site's grid
//     origin_m: [0, 0]
//     size_m: [5, 4]                  # or cells: [250, 200]
//     cell_size_m: 0.02
//     pieces:                         # optional; default one carpet over the room
//       - {area_m: [x0, y0, x1, y1], material: {colour: [0.45, 0.47, 0.52], pattern: carpet, variation: 0.2}}
//   room:                             # optional; default walls 0.5 m around the area, 3 m high
//     walls_m: [x0, y0, x1, y1]       # inner faces of the four walls
//     height_m: 3.0
//     wall: {material}                # optional
//     ceiling: {material}             # optional
//     # outdoor: true (no walls or ceiling), sky_colour: [r, g, b]
//   cameras:                          # 1 to 255
//     - id: cam1                      # letters, digits, '_', '-', '.'
//       model: pinhole                # or tsai
//       image_size: [640, 480]
//       position_m: [0, 0, 2.7]       # pose: position_m and look_at_m, or
//       look_at_m: [4, 3, 0]          #   rotation (3x3 cam_from_world rows) and translation_m
//       focal_px: 420                 # pinhole: focal_px or fx_px + fy_px; cx_px, cy_px (default
//       distortion: [-0.12, 0.03, 0, 0, 0]   # the image centre); k1 k2 p1 p2 k3; skew_px
//       # tsai: f_mm, cell_mm (or dx_mm + dy_mm), kappa1_per_mm2, sx, ncx, nfx, cx_px, cy_px
//   statics:                          # optional
//     - {name: pillar, shape: cylinder, centre_m: [2, 2], size_m: [0.4, 0.4], height_m: 2.6}
//       # shape: box | cylinder | planter; yaw_deg, base_m (box), material
//   objects:                          # optional
//     - id: 1                         # 1..65535, unique (the id buffer value)
//       class: person                 # person | chair | robot | box
//       height_m: 1.8                 # optional appearance (drawn from the seed otherwise):
//       colours: {top: [0.8, 0.1, 0.1], bottom: [0.2, 0.2, 0.3]}   # width_m, depth_m, skin, hair, shoes
//       path:
//         - {at_m: [1, 1], t_s: 0}
//         - {at_m: [4, 1], speed_m_s: 1.2}   # arrive at walking speed, or t_s
//         - {wait_s: 2}                        # stand still
//         - {at_m: [4, 3], t_s: 9, gap: true}  # leave, come back here at 9 s
//   lighting:                         # optional
//     ambient: 0.5
//     ambient_colour: [0.9, 0.95, 1.1]  # optional, per channel 0..2 (default white [1, 1, 1]):
//     direct_colour: [1.05, 1, 0.9]     # the sky's and the light's colours
//     light: {type: directional, direction_to_light: [0.3, 0.2, 1], intensity: 0.5}
//     # or {type: point, position_m: [x, y, z], intensity: 0.6, falloff_per_m2: 0.02}
//   photometry:                       # optional
//     noise_sigma: 2                  # grey levels
//     exposure_drift: 0               # relative amplitude (0 = off), exposure_period_s: 30
//     shadows: false
//     background_noise: true
//     contact_shadows: {strength: 0.5, radius_m: 0.22, reach_m: 1.5}   # optional (off): the sky
//                                     # an object hides from the floor around it (scene.h)
//     camera:                         # optional: a real camera (scene.h CameraResponseSpec;
//       auto_exposure: true           #   every key optional, each off by default)
//       target_luma: 0                # grey levels; 0 = the empty view's
//       max_gain: 4
//       white_balance: 0.6            # grey-world strength 0..1
//       time_constant_s: 0.4          # how fast both follow the content
//       read_noise: 1.2               # grey levels
//       shot_noise: 0.04              # variance per grey level
//       supersample: 2                # rays per pixel along each axis, area-averaged
//       jpeg_quality: 75              # image sequences as JPEG (0 = PNG)
//       video_crf: 28                 # videos: H.264 crf (-1 = 23)
//
// A material: {colour: [r, g, b] (0..1), pattern: plain | tiles | carpet | books | noise,
// colour2, scale_m, variation, seed}. Unknown keys are errors with a "did you mean"; every
// error reads "file:line: field: expected ..., found ...".
//
//   OCCMAP_ASSIGN_OR_RETURN(sim::SceneSpec spec, sim::LoadSceneYaml("corridor.yaml"));
//   std::string text = sim::SceneToYaml(spec);
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "occmap/sim/scene.h"
#include "occmap/util/status.h"

namespace occmap::sim {

Result<SceneSpec> LoadSceneYaml(const std::filesystem::path& path);
Result<SceneSpec> ParseSceneYaml(std::string_view text, const std::string& file_name);
std::string SceneToYaml(const SceneSpec& spec);

}  // namespace occmap::sim
