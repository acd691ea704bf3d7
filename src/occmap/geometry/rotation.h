// Rotation helpers: Rodrigues vectors (OpenCV), Tsai/Willson Euler angles, orthonormality.
//
//   Eigen::Matrix3d cam_from_world = RotationFromRodrigues({1.76, 0.47, -0.33});
//   Eigen::Matrix3d r = TsaiRotation(rx, ry, rz);  // Rot_z(rz) * Rot_y(ry) * Rot_x(rx)
#pragma once

#include <Eigen/Core>

#include "occmap/util/status.h"

namespace occmap {

// Rotation matrix of a Rodrigues (axis * angle) vector, as cv::Rodrigues.
Eigen::Matrix3d RotationFromRodrigues(const Eigen::Vector3d& rvec);

// Willson's roll/pitch/yaw: R = Rot_z(Rz) * Rot_y(Ry) * Rot_x(Rx), angles in radians.
Eigen::Matrix3d TsaiRotation(double rx, double ry, double rz);

// Largest absolute entry of R * R^T - I; a rotation has ~1e-15.
double OrthonormalityError(const Eigen::Matrix3d& r);

// cam_from_world rotation of a camera at position_m looking at target_m: image columns to the
// right, rows downwards (towards -z of the world); looking straight down, columns along +x.
Eigen::Matrix3d LookAtRotation(const Eigen::Vector3d& position_m, const Eigen::Vector3d& target_m);

// OK for a proper rotation (|R R^T - I| <= 1e-6, det > 0), else a message with both figures.
Status ValidateRotation(const Eigen::Matrix3d& r);

}  // namespace occmap
