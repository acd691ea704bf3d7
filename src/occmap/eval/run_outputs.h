// Readers of the per-frame outputs of a run that evaluation compares with the ground truth:
//
//   detections.jsonl (written by `occmap run`), one line per frame:
//     {"frame": 12, "time_s": 0.48, "blobs": [{"x_m": 1.5, "y_m": 2.0, "area_m2": 0.12, "cells": 192}]}
//   tracks.jsonl (written by the tracker), one line per frame:
//     {"frame": 12, "time_s": 0.48, "tracks": [{"id": 3, "x_m": 1.5, "y_m": 2.0, "vx_mps": 0.4,
//                                               "vy_mps": 0.0, "class": "person"}]}
//
// Required: frame (integer >= 0, increasing line by line), time_s (number), blobs / tracks
// (a list, possibly empty), and per entry x_m, y_m (numbers) and a track's id (integer, unique
// within its frame). Optional: area_m2 (number >= 0; absent = unknown, NaN), cells (integer
// >= 0), vx_mps, vy_mps (numbers, default 0), class (text, default ""). Blank lines are
// skipped; unknown keys are ignored. Every error names the file, line and field, what was
// expected and what was found:
//   run/detections.jsonl:3: blobs[1].x_m: expected a number, found "1.5"
//
// Numbered pictures (occupancy/NNNNNN.png, changes/<camera>/NNNNNN.png) are listed by
// ListFramePngs: every *.png whose name is digits only is frame int(name).
//
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<DetectionFrame> detections, ReadDetections(run / "detections.jsonl"));
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<TrackFrame> tracks, ReadTracks(run / "tracks.jsonl"));
//   for (const TrackRecord& t : tracks[0].tracks) ... t.id, t.x_m ...
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "occmap/util/status.h"

namespace occmap {

struct DetectedBlob {
  double x_m = 0, y_m = 0;
  double area_m2 = std::numeric_limits<double>::quiet_NaN();  // NaN: not in the file
  int64_t cells = -1;                                          // -1: not in the file
};

struct DetectionFrame {
  int64_t frame = 0;
  double time_s = 0;
  std::vector<DetectedBlob> blobs;
};

struct TrackRecord {
  int64_t id = 0;
  double x_m = 0, y_m = 0;
  double vx_mps = 0, vy_mps = 0;
  std::string object_class;
};

struct TrackFrame {
  int64_t frame = 0;
  double time_s = 0;
  std::vector<TrackRecord> tracks;
};

// `source_name` names the text in messages (the file's path for the readers).
Result<std::vector<DetectionFrame>> ParseDetections(std::string_view text, std::string_view source_name);
Result<std::vector<DetectionFrame>> ReadDetections(const std::filesystem::path& path);
Result<std::vector<TrackFrame>> ParseTracks(std::string_view text, std::string_view source_name);
Result<std::vector<TrackFrame>> ReadTracks(const std::filesystem::path& path);

// (frame, path) of every NNNNNN.png (digits only, any number of them) in dir, by frame; other
// files are ignored. Two files of one frame (000012.png and 12.png) are an error that calls
// them `what` ("map", "mask").
Result<std::vector<std::pair<int64_t, std::filesystem::path>>> ListFramePngs(const std::filesystem::path& dir,
                                                                              std::string_view what);

}  // namespace occmap
