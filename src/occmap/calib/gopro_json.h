// Reader for the JSON calibrations of ../shared/datasets/gopro4: an intrinsic file with `K`
// (3x3), `distCoeffs` ([[k1 k2 p1 p2 k3]] or a flat list) and `image_shape` ([height, width]);
// an extrinsic file with `R` (3x3, world -> camera), `t` (3) and `unit` ("cm", "mm" or "m";
// fields such as `Hr`, `date`, `description` are ignored).
//
//   OCCMAP_ASSIGN_OR_RETURN(PinholeParameters p, ReadGoProCalibration(intr, extr, std::nullopt));
#pragma once

#include <filesystem>
#include <optional>

#include "occmap/geometry/pinhole_camera.h"
#include "occmap/util/status.h"

namespace occmap {

// unit_override: metres per unit to use when the extrinsic file has no `unit` field; when it
// has one and an override is given they must agree.
Result<PinholeParameters> ReadGoProCalibration(const std::filesystem::path& intrinsic_path,
                                               const std::filesystem::path& extrinsic_path,
                                               std::optional<double> metres_per_unit);

Status WriteGoProCalibration(const PinholeParameters& params,
                             const std::filesystem::path& intrinsic_path,
                             const std::filesystem::path& extrinsic_path);

}  // namespace occmap
