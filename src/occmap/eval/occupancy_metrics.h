// Occupancy metrics: a computed occupancy map against a reference raster of the same grid (the
// simulator's footprint raster, or its ideal plane-hull raster), cell by cell.
//
// Only cells the computed map has seen (state != kUnseen) are evaluated; among those, cells the
// reference marks unseen are skipped too (counted apart). With "positive" = occupied, summed
// over every frame added:
//   IoU = TP / (TP + FP + FN), precision = TP / (TP + FP), recall = TP / (TP + FN)
// each NaN (null in JSON) when its denominator is 0.
//
// CellRaster is the per-cell form of a map read from a picture: one pixel per cell, +x right,
// +y up (image row 0 holds cell row cells_y - 1), grey levels given by OccupancyGrayCodes
// (default OccupancyMap::ToGrayImage's: 255 free, 0 occupied, 128 unseen, as the computed maps
// and the simulator's hull rasters; its footprint rasters are 255 object, 0 none:
// EvalOptions::footprint_codes). Any other level is an error naming the file and pixel.
//
//   OCCMAP_ASSIGN_OR_RETURN(CellRaster reference, ReadCellRaster("gt/hull/000012.png"));
//   OccupancyEvaluator evaluator;
//   evaluator.AddFrame(12, map, reference);   // then evaluator.Metrics().iou
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>
#include <vector>

#include "occmap/eval/eval_options.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

struct CellRaster {
  int cells_x = 0, cells_y = 0;
  std::vector<CellState> states;  // index j * cells_x + i, as FloorGrid; j = 0 is the bottom row

  static CellRaster FromMap(const OccupancyMap& map);
  friend bool operator==(const CellRaster&, const CellRaster&) = default;
};

// A raster from its picture; `source_name` names it in messages.
Result<CellRaster> CellRasterFromGray(ImageView<const uint8_t> image, const OccupancyGrayCodes& codes,
                                      std::string_view source_name);
// A raster from a picture file (PNG, ...; colour is converted to grey).
Result<CellRaster> ReadCellRaster(const std::filesystem::path& path, const OccupancyGrayCodes& codes = {});

struct FrameOccupancyCounts {
  int64_t frame = 0;
  int64_t tp = 0, fp = 0, fn = 0, tn = 0;  // over evaluated cells
  int64_t computed_unseen = 0;            // cells left out: the computed map did not see them
  int64_t reference_unseen = 0;           // cells left out: seen, but unseen in the reference
};

struct OccupancyMetrics {
  int64_t frames = 0;
  int64_t cells_evaluated = 0;  // tp + fp + fn + tn
  int64_t tp = 0, fp = 0, fn = 0, tn = 0;
  int64_t computed_unseen = 0, reference_unseen = 0;
  double iou = 0, precision = 0, recall = 0;  // NaN: undefined
  // Filled by EvaluateRun: computed maps with no reference raster of their frame (not evaluated).
  int64_t computed_frames_without_reference = 0;
};

class OccupancyEvaluator {
 public:
  // The two spans hold the same number of cells, in the same order (CHECKed).
  void AddFrame(int64_t frame, std::span<const CellState> computed, std::span<const CellState> reference);
  void AddFrame(int64_t frame, const OccupancyMap& computed, const CellRaster& reference);
  void AddFrame(int64_t frame, const CellRaster& computed, const CellRaster& reference);

  const std::vector<FrameOccupancyCounts>& frames() const { return frames_; }
  OccupancyMetrics Metrics() const;

 private:
  std::vector<FrameOccupancyCounts> frames_;
};

}  // namespace occmap
