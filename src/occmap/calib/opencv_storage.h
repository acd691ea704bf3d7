// Readers for OpenCV FileStorage calibrations (XML or YAML), as in WILDTRACK and MultiviewX:
// an intrinsic file with `camera_matrix` (3x3) and `distortion_coefficients` (4, 5, or more
// values; only k1 k2 p1 p2 k3 are supported, further terms must be 0), and an extrinsic file
// with `rvec` and `tvec` (world -> camera, x_cam = R(rvec) x_world + tvec), either as
// opencv-matrix nodes or as plain space-separated text (WILDTRACK). tvec is in the declared
// length unit and is converted to metres here.
//
//   OCCMAP_ASSIGN_OR_RETURN(PinholeParameters p,
//       ReadOpenCvCalibration("intr_C1.xml", "extr_C1.xml", /*metres_per_unit=*/0.01, {1920, 1080}));
#pragma once

#include <filesystem>
#include <optional>

#include "occmap/geometry/pinhole_camera.h"
#include "occmap/util/status.h"

namespace occmap {

struct OpenCvIntrinsics {
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0, skew_px = 0;
  std::array<double, 5> distortion = {0, 0, 0, 0, 0};
  std::optional<ImageSize> image_size;  // when the file has image_width / image_height
};

struct OpenCvExtrinsics {
  Eigen::Vector3d rvec = Eigen::Vector3d::Zero();
  Eigen::Vector3d tvec_in_file_units = Eigen::Vector3d::Zero();
};

Result<OpenCvIntrinsics> ReadOpenCvIntrinsics(const std::filesystem::path& path);
Result<OpenCvExtrinsics> ReadOpenCvExtrinsics(const std::filesystem::path& path);

// Both files, with the world length unit of tvec, and the image size (required when the
// intrinsic file does not carry one; must agree when it does).
Result<PinholeParameters> ReadOpenCvCalibration(const std::filesystem::path& intrinsic_path,
                                                const std::filesystem::path& extrinsic_path,
                                                double metres_per_unit,
                                                std::optional<ImageSize> image_size);

// Writes an intrinsic file alone (camera_matrix, distortion_coefficients, image_width/height).
Status WriteOpenCvIntrinsics(const OpenCvIntrinsics& intrinsics, const std::filesystem::path& path);

// Writes the pair back (used by round-trip tests and `occmap` tools that export calibrations).
Status WriteOpenCvCalibration(const PinholeParameters& params, double metres_per_unit,
                              const std::filesystem::path& intrinsic_path,
                              const std::filesystem::path& extrinsic_path);

}  // namespace occmap
