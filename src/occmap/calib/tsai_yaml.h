// Reader for Tsai parameter sets in YAML (as ../shared/datasets/tsai-terrace/terrace_cameras.yaml):
// either a single camera's keys at the top level, or one block per camera (`c0:`, `c1:` ...)
// selected by name. Keys: image_width, image_height, Ncx, Nfx, dx, dy, Cx, Cy, sx, f, kappa1,
// Tx, Ty, Tz, Rx, Ry, Rz (Willson's units: mm, pixels, radians, 1/mm^2). Optional dpx, dpy,
// r1..r9 and camera_centre_world are checked against the values derived from the others, so a
// file edited by hand cannot silently disagree with itself. Tx/Ty/Tz are world lengths in the
// declared unit (default mm) and are converted to metres here.
//
//   OCCMAP_ASSIGN_OR_RETURN(TsaiParameters p, ReadTsaiYaml("terrace_cameras.yaml", "c0", 0.001));
#pragma once

#include <filesystem>
#include <string>

#include "occmap/geometry/tsai_camera.h"
#include "occmap/util/status.h"

namespace occmap {

// camera: the block name, or "" for a file holding one camera at the top level.
Result<TsaiParameters> ReadTsaiYaml(const std::filesystem::path& path, const std::string& camera,
                                    double metres_per_unit = 0.001);

// Writes one camera's block (round trip and export).
Status WriteTsaiYaml(const TsaiParameters& params, double rx, double ry, double rz,
                     const std::string& camera, const std::filesystem::path& path,
                     double metres_per_unit = 0.001);

}  // namespace occmap
