#include "occmap/objects/object_frame.h"

#include "occmap/util/status.h"

namespace occmap {

std::vector<Detection> GuidedDetections(const ObjectFrame& frame,
                                        const std::vector<Eigen::Vector2d>& predicted_positions_m) {
  if (frame.groups.empty() || predicted_positions_m.empty()) return frame.detections;
  // Per group: 0 not decided yet, 1 its own detections, 2 guided (already given).
  std::vector<uint8_t> state(frame.groups.size(), 0);
  std::vector<Detection> out;
  out.reserve(frame.detections.size());
  for (const Detection& d : frame.detections) {
    if (d.group < 0) {
      out.push_back(d);
      continue;
    }
    OCCMAP_CHECK(static_cast<size_t>(d.group) < frame.groups.size(), "GuidedDetections: a detection of no group");
    const size_t g = static_cast<size_t>(d.group);
    if (state[g] == 0) {
      const DetectionGroup& group = frame.groups[g];
      const std::vector<Eigen::Vector2d> inside =
          PredictionsOnBlob(frame.grid, group.group, group.split, frame.guide_radius_m, predicted_positions_m);
      state[g] = 1;
      if (inside.size() >= 2 && inside.size() > group.split.peaks) {
        state[g] = 2;
        const Blob& whole = group.footprint;
        const std::vector<Detection> guided = GuidedCut(whole.x_m, whole.y_m, whole.area_m2, whole.cells, inside);
        for (Detection cut : guided) {
          cut.group = d.group;
          out.push_back(cut);
        }
        continue;
      }
    }
    if (state[g] == 1) out.push_back(d);
  }
  return out;
}

}  // namespace occmap
