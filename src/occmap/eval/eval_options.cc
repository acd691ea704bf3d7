#include "occmap/eval/eval_options.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace occmap {

Status OccupancyGrayCodes::Validate() const {
  if (free == occupied || free == unseen || occupied == unseen) {
    return InvalidInput(fmt::format("grey codes: expected three different levels, found free {}, occupied {}, unseen {}",
                                    free, occupied, unseen));
  }
  return Status::Ok();
}

Status EvalOptions::Validate() const {
  if (!(std::isfinite(match_threshold_m) && match_threshold_m > 0)) {
    return InvalidInput(fmt::format("match_threshold_m: expected a distance > 0 m, found {}", match_threshold_m));
  }
  if (!(std::isfinite(min_detection_area_m2) && min_detection_area_m2 >= 0)) {
    return InvalidInput(fmt::format("min_detection_area_m2: expected an area >= 0, found {}", min_detection_area_m2));
  }
  if (!(mostly_lost_ratio >= 0 && mostly_lost_ratio <= mostly_tracked_ratio && mostly_tracked_ratio <= 1)) {
    return InvalidInput(fmt::format(
        "mostly_lost_ratio, mostly_tracked_ratio: expected 0 <= lost <= tracked <= 1, found {} and {}",
        mostly_lost_ratio, mostly_tracked_ratio));
  }
  OCCMAP_RETURN_IF_ERROR(computed_codes.Validate().WithContext("computed_codes"));
  OCCMAP_RETURN_IF_ERROR(footprint_codes.Validate().WithContext("footprint_codes"));
  OCCMAP_RETURN_IF_ERROR(hull_codes.Validate().WithContext("hull_codes"));
  return Status::Ok();
}

bool EvalOptions::EvaluatesClass(const std::string& object_class) const {
  return object_classes.empty() ||
         std::find(object_classes.begin(), object_classes.end(), object_class) != object_classes.end();
}

}  // namespace occmap
