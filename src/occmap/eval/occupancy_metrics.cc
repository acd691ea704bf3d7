#include "occmap/eval/occupancy_metrics.h"

#include <fmt/core.h>

#include "occmap/eval/detection_metrics.h"
#include "occmap/util/image_io.h"

namespace occmap {

CellRaster CellRaster::FromMap(const OccupancyMap& map) {
  return {map.grid().cells_x, map.grid().cells_y, map.states()};
}

Result<CellRaster> CellRasterFromGray(ImageView<const uint8_t> image, const OccupancyGrayCodes& codes,
                                      std::string_view source_name) {
  OCCMAP_RETURN_IF_ERROR(codes.Validate());
  CellRaster raster;
  raster.cells_x = image.width();
  raster.cells_y = image.height();
  raster.states.resize(static_cast<size_t>(raster.cells_x) * static_cast<size_t>(raster.cells_y));
  for (int y = 0; y < image.height(); ++y) {
    const uint8_t* row = image.row(y);
    const int j = raster.cells_y - 1 - y;  // +y up: image row 0 holds the last cell row
    CellState* cells = raster.states.data() + static_cast<size_t>(j) * static_cast<size_t>(raster.cells_x);
    for (int i = 0; i < image.width(); ++i) {
      const uint8_t v = row[i];
      if (v == codes.free) {
        cells[i] = CellState::kFree;
      } else if (v == codes.occupied) {
        cells[i] = CellState::kOccupied;
      } else if (v == codes.unseen) {
        cells[i] = CellState::kUnseen;
      } else {
        return InvalidInput(fmt::format("{}: pixel ({}, {}): expected {} (free), {} (occupied) or {} (unseen), found {}",
                                        source_name, i, y, codes.free, codes.occupied, codes.unseen, v));
      }
    }
  }
  return raster;
}

Result<CellRaster> ReadCellRaster(const std::filesystem::path& path, const OccupancyGrayCodes& codes) {
  OCCMAP_ASSIGN_OR_RETURN(Image<uint8_t> image, ReadGrayImage(path));
  return CellRasterFromGray(image.view(), codes, path.string());
}

void OccupancyEvaluator::AddFrame(int64_t frame, std::span<const CellState> computed,
                                  std::span<const CellState> reference) {
  OCCMAP_CHECK(computed.size() == reference.size(),
               fmt::format("computed map of {} cells against a reference of {}", computed.size(), reference.size()));
  FrameOccupancyCounts c;
  c.frame = frame;
  for (size_t k = 0; k < computed.size(); ++k) {
    if (computed[k] == CellState::kUnseen) {
      ++c.computed_unseen;
      continue;
    }
    if (reference[k] == CellState::kUnseen) {
      ++c.reference_unseen;
      continue;
    }
    const bool said = computed[k] == CellState::kOccupied, truth = reference[k] == CellState::kOccupied;
    if (said && truth) {
      ++c.tp;
    } else if (said) {
      ++c.fp;
    } else if (truth) {
      ++c.fn;
    } else {
      ++c.tn;
    }
  }
  frames_.push_back(c);
}

void OccupancyEvaluator::AddFrame(int64_t frame, const OccupancyMap& computed, const CellRaster& reference) {
  OCCMAP_CHECK(computed.grid().cells_x == reference.cells_x && computed.grid().cells_y == reference.cells_y,
               fmt::format("computed map of {}x{} cells against a reference of {}x{}", computed.grid().cells_x,
                           computed.grid().cells_y, reference.cells_x, reference.cells_y));
  AddFrame(frame, computed.states(), reference.states);
}

void OccupancyEvaluator::AddFrame(int64_t frame, const CellRaster& computed, const CellRaster& reference) {
  OCCMAP_CHECK(computed.cells_x == reference.cells_x && computed.cells_y == reference.cells_y,
               fmt::format("computed map of {}x{} cells against a reference of {}x{}", computed.cells_x,
                           computed.cells_y, reference.cells_x, reference.cells_y));
  AddFrame(frame, computed.states, reference.states);
}

OccupancyMetrics OccupancyEvaluator::Metrics() const {
  OccupancyMetrics m;
  for (const FrameOccupancyCounts& c : frames_) {
    ++m.frames;
    m.tp += c.tp;
    m.fp += c.fp;
    m.fn += c.fn;
    m.tn += c.tn;
    m.computed_unseen += c.computed_unseen;
    m.reference_unseen += c.reference_unseen;
  }
  m.cells_evaluated = m.tp + m.fp + m.fn + m.tn;
  const auto tp = static_cast<double>(m.tp);
  m.iou = RatioOrNaN(tp, static_cast<double>(m.tp + m.fp + m.fn));
  m.precision = RatioOrNaN(tp, static_cast<double>(m.tp + m.fp));
  m.recall = RatioOrNaN(tp, static_cast<double>(m.tp + m.fn));
  return m;
}

}  // namespace occmap
