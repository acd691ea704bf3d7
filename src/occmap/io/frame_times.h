// Frame times of an image sequence: a text file beside the frames that gives each image's time,
// for sequences that are not taken at a fixed rate (a subsample of a video, a camera that drops
// frames). The tracker's motion model and the adaptive background's time constants then see the
// real time between frames instead of index / fps.
//
// The file (docs/formats.md, "Frame times"): one line per image, in order, from image 0;
// '#' starts a comment, blank lines are skipped. A line is either
//   TIME            the image's time
//   INDEX TIME      the same with the image's index, which must be the line's own (0, 1, 2, ...)
// (one form for the whole file). TIME is in seconds, or, when the site gives the file's rate
// (`timestamps: {file: frame_numbers.txt, fps: 25}`), a frame number of that rate
// (time = number / fps). Times strictly increase.
//
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<double> times_s, ReadFrameTimes("frame_numbers.txt", 25.0));
//   spec.timestamps_s = std::move(times_s);  // FrameSourceSpec
#pragma once

#include <filesystem>
#include <string_view>
#include <vector>

#include "occmap/util/status.h"

namespace occmap {

// The times in seconds of the text `text` (`source_name` names it in messages, with the line):
//   frame_numbers.txt:4: expected times that increase, found 35 after 40
// numbers_fps > 0: the values are frame numbers at that rate; 0: seconds.
Result<std::vector<double>> ParseFrameTimes(std::string_view text, std::string_view source_name, double numbers_fps);
// The same from a file (a regular file of at most 64 MiB).
Result<std::vector<double>> ReadFrameTimes(const std::filesystem::path& path, double numbers_fps);

// The mean rate of `times_s`: (n - 1) / (last - first); 0 with fewer than two times.
double MeanRateHz(const std::vector<double>& times_s);

}  // namespace occmap
