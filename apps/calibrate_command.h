// `occmap calibrate`: the command-line wiring of calib/board_calibration.h (intrinsics from
// board views), calib/floor_calibration.h (a camera from known floor points) and
// site/site_update.h (--update-site). The command reads and writes the files; the library
// does the work.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "occmap/util/status.h"

namespace occmap {

struct CalibrateCommand {
  std::string camera_id = "camera";
  std::string out_dir = "calib";
  // Intrinsics from a board.
  std::vector<std::string> board_images;
  std::string board_video;
  int frame_step = 15;
  int max_views = 200;
  std::string board = "checkerboard";
  std::string board_size = "9x6";
  double square_m = 0;
  double marker_m = 0;
  std::string dictionary = "4x4_50";
  double max_blur_px = 2.0;
  bool estimate_k3 = false;
  std::string print_board;
  // A camera from floor points.
  std::string intrinsics_file;
  bool fit_lens = false;  // no intrinsics: focal length and k1, k2 from the floor points
  std::string points_file;
  std::string image;
  std::string image_size;
  std::string update_site;
  std::string overlay;
  // A fit with outliers or an RMS over max_rms_px writes no calibration and updates no site.
  double max_rms_px = 4.0;  // calib's kMaxUpdateRmsPx
  bool force = false;
  bool json_to_stdout = false;
};

// Adds the subcommand and its options to `app`.
CLI::App* AddCalibrateCommand(CLI::App& app, CalibrateCommand& cmd);

Status RunCalibrate(const CalibrateCommand& cmd, const std::string& data_root);

}  // namespace occmap
