#include "occmap/objects/object_options.h"

#include <fmt/core.h>

#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <type_traits>

namespace occmap {
namespace {

// A problem with one field: the key and what was expected (for both Validate and the parser).
struct Problem {
  std::string_view key;
  std::string expected;
};

// The `blobs:` fields' checks, in the site parser's historical order.
std::optional<Problem> CheckBlobs(const ObjectOptions& o) {
  for (double h : o.support_heights_m) {
    if (!(h > 0 && h < 10)) return Problem{"support_heights_m", fmt::format("expected heights in (0, 10) m, found {}", h)};
  }
  if (!(o.min_support >= 0 && o.min_support <= 1)) {
    return Problem{"min_support", fmt::format("expected a fraction in [0, 1], found {}", o.min_support)};
  }
  if (!(o.support_slack_m >= 0)) return Problem{"support_slack_m", fmt::format("expected >= 0 m, found {}", o.support_slack_m)};
  if (!(o.occluder_height_m > 0)) {
    return Problem{"occluder_height_m", fmt::format("expected > 0 m, found {}", o.occluder_height_m)};
  }
  if (!(o.min_clear_views >= 1 && o.min_clear_views <= 64)) {
    return Problem{"min_clear_views", fmt::format("expected 1..64 cameras, found {}", o.min_clear_views)};
  }
  if (!(o.group_radius_m >= 0 && o.group_radius_m <= 5)) {
    return Problem{"group_radius_m", fmt::format("expected 0..5 m, found {}", o.group_radius_m)};
  }
  if (!(o.min_area_m2 >= 0)) return Problem{"min_area_m2", fmt::format("expected >= 0, found {}", o.min_area_m2)};
  if (!(o.standing_radius_m >= 0 && o.standing_radius_m <= 2)) {
    return Problem{"standing_radius_m", fmt::format("expected 0..2 m, found {}", o.standing_radius_m)};
  }
  return std::nullopt;
}

// The `tracking:` keys: each number with its range, as TrackerOptions describes its own.
struct Range {
  double lo;
  bool lo_open;
  double hi = std::numeric_limits<double>::infinity();

  bool Contains(double v) const { return std::isfinite(v) && (lo_open ? v > lo : v >= lo) && v <= hi; }
  std::string Describe(bool integer) const {
    const char* what = integer ? "an integer" : "a number";
    if (std::isinf(hi)) return fmt::format("{} {} {}", what, lo_open ? ">" : ">=", lo);
    return fmt::format("{} in {}{}, {}]", what, lo_open ? "(" : "[", lo, hi);
  }
};

template <typename Options, typename Fn>
void VisitTrackingNumbers(Options& o, Fn&& fn) {
  fn("person_diameter_m", o.person_diameter_m, Range{0, true});
  fn("min_detection_area_m2", o.min_detection_area_m2, Range{0, false});
  fn("max_people_per_blob", o.max_people_per_blob, Range{1, false, 1000});
  fn("split_area_margin", o.split_area_margin, Range{0, false, 1});
  fn("split_min_neck_m", o.split_min_neck_m, Range{0, true});
  fn("split_min_peak_radius_m", o.split_min_peak_radius_m, Range{0, false});
}

}  // namespace

double ObjectOptions::person_area_m2() const {
  return std::numbers::pi * person_diameter_m * person_diameter_m / 4.0;
}

Status ObjectOptions::Validate() const {
  if (auto p = CheckBlobs(*this)) return InvalidInput(fmt::format("blobs.{}: {}", p->key, p->expected));
  Status status;
  VisitTrackingNumbers(*this, [&](std::string_view key, const auto& value, const Range& range) {
    if (!status.ok() || range.Contains(static_cast<double>(value))) return;
    status = InvalidInput(fmt::format("tracking.{}: expected {}, found {}", key,
                                      range.Describe(std::is_integral_v<std::decay_t<decltype(value)>>),
                                      static_cast<double>(value)));
  });
  return status;
}

Status ParseObjectOptions(const YamlField& f, ObjectOptions& options) {
  if (f.IsNull()) return Status::Ok();
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"group_radius_m", "min_area_m2", "split", "remove_ghosts", "occluder_height_m",
                                      "min_clear_views", "support_heights_m", "min_support", "support_slack_m",
                                      "standing_radius_m"}));
  ObjectOptions o = options;
  OCCMAP_ASSIGN_OR_RETURN(o.split, f.GetBool("split", o.split));
  OCCMAP_ASSIGN_OR_RETURN(o.remove_ghosts, f.GetBool("remove_ghosts", o.remove_ghosts));
  OCCMAP_ASSIGN_OR_RETURN(o.occluder_height_m, f.GetDouble("occluder_height_m", o.occluder_height_m));
  OCCMAP_ASSIGN_OR_RETURN(const int64_t clear_views, f.GetInt("min_clear_views", o.min_clear_views));
  if (clear_views < 1 || clear_views > 64) {
    return f.Find("min_clear_views")->Error(fmt::format("expected 1..64 cameras, found {}", clear_views));
  }
  o.min_clear_views = static_cast<int>(clear_views);
  if (f.Find("support_heights_m")) {
    OCCMAP_ASSIGN_OR_RETURN(o.support_heights_m, f.GetDoubles("support_heights_m"));
  }
  OCCMAP_ASSIGN_OR_RETURN(o.min_support, f.GetDouble("min_support", o.min_support));
  OCCMAP_ASSIGN_OR_RETURN(o.support_slack_m, f.GetDouble("support_slack_m", o.support_slack_m));
  OCCMAP_ASSIGN_OR_RETURN(o.group_radius_m, f.GetDouble("group_radius_m", o.group_radius_m));
  OCCMAP_ASSIGN_OR_RETURN(o.min_area_m2, f.GetDouble("min_area_m2", o.min_area_m2));
  OCCMAP_ASSIGN_OR_RETURN(o.standing_radius_m, f.GetDouble("standing_radius_m", o.standing_radius_m));
  if (auto p = CheckBlobs(o)) return f.Find(p->key).value_or(f).Error(p->expected);
  options = std::move(o);
  return Status::Ok();
}

Status ParseObjectKeysOfTracking(const YamlField& field, ObjectOptions& options) {
  if (field.IsNull()) return Status::Ok();
  if (!field.IsMap()) return field.CheckKeys({});  // the error: expected a map, found ...
  ObjectOptions parsed = options;
  Status status;
  VisitTrackingNumbers(parsed, [&](std::string_view key, auto& value, const Range& range) {
    if (!status.ok()) return;
    const std::optional<YamlField> f = field.Find(key);
    if (!f) return;
    using T = std::decay_t<decltype(value)>;
    double v = 0;
    if constexpr (std::is_integral_v<T>) {
      Result<int64_t> r = f->AsInt();
      if (!r.ok()) {
        status = r.status();
        return;
      }
      v = static_cast<double>(*r);
    } else {
      Result<double> r = f->AsDouble();
      if (!r.ok()) {
        status = r.status();
        return;
      }
      v = *r;
    }
    if (!range.Contains(v)) {
      status = f->Error(fmt::format("expected {}, found {}", range.Describe(std::is_integral_v<T>), f->node().Scalar()));
      return;
    }
    value = static_cast<T>(v);
  });
  OCCMAP_RETURN_IF_ERROR(status);
  options = std::move(parsed);
  return Status::Ok();
}

}  // namespace occmap
