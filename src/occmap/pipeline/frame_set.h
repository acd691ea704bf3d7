// FrameSet: one slot of a run's ring (pipeline/run.cc): the frames of all cameras for one
// instant, filled by the FrameReader, and what the fusion stage makes of them, read by the post
// stage. Buffers are reused from one instant to the next: memory stays flat.
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/fusion/view_explainer.h"
#include "occmap/io/frame_source.h"

namespace occmap {

struct FrameSet {
  int64_t frame_index = 0;
  // Stream time: the timestamp of the first camera with a frame in this set (NaN: none has one;
  // the run then takes frame_index / fps).
  double timestamp_s = 0;
  std::chrono::steady_clock::time_point arrival;  // its frames decoded (the latency's start)
  double t_unix = 0;                              // the same instant on the wall clock
  std::vector<Frame> frames;     // per camera
  std::vector<bool> active;      // the camera's frame is there (stream not ended, synchronised)
  OccupancyMap map;              // the fused map of this instant
  std::vector<uint8_t> changes;  // the change buffer (global pixel ids), allocated when first needed
  bool changes_ready = false;    // `changes` holds this instant's changes (not so when fully fused)
  bool changes_given = false;    // the source filled `changes` (occmap fuse): no change detection
  ChangeBits change_bits;        // FastFusion::FuseTolerant's changes after the tolerance, as bits
  bool bits_ready = false;       // `change_bits` holds this instant's changes
  std::vector<Image<uint8_t>> change_pictures;  // --change-pngs: per camera, 255 changed (before the tolerance)
  OccupancyMap column_map;
  std::vector<ExplainedPerson> people;
};

}  // namespace occmap
