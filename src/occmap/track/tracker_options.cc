#include "occmap/track/tracker_options.h"

#include <fmt/core.h>

#include <cmath>
#include <numbers>
#include <type_traits>

namespace occmap {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// An interval of allowed values: lo < v (lo_open) or lo <= v, and v <= hi (hi_open: v < hi).
struct Range {
  double lo = -kInf;
  bool lo_open = false;
  double hi = kInf;
  bool hi_open = false;

  bool Contains(double v) const {
    return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  }
  std::string Describe(bool integer) const {
    const char* what = integer ? "an integer" : "a number";
    if (hi == kInf) return fmt::format("{} {} {}", what, lo_open ? ">" : ">=", lo);
    return fmt::format("{} in {}{}, {}{}", what, lo_open ? "(" : "[", lo, hi, hi_open ? ")" : "]");
  }
};

constexpr Range kPositive{0, true};
constexpr Range kNonNegative{0, false};
constexpr Range kAtLeastOne{1, false};

// Every scalar number of TrackerOptions with its YAML key and range, shared by Validate and
// the parser. Options is TrackerOptions or const TrackerOptions; fn(key, value&, range).
template <typename Options, typename Fn>
void VisitNumbers(Options& o, Fn&& fn) {
  fn("max_speed_mps", o.max_speed_mps, kPositive);
  fn("person_diameter_m", o.person_diameter_m, kPositive);
  fn("acceleration_psd_m2ps3", o.acceleration_psd_m2ps3, kNonNegative);
  fn("measurement_sigma_m", o.measurement_sigma_m, kPositive);
  fn("spread_noise_weight", o.spread_noise_weight, kNonNegative);
  fn("guided_split_sigma_m", o.guided_split_sigma_m, kNonNegative);
  fn("initial_speed_sigma_mps", o.initial_speed_sigma_mps, kPositive);
  fn("gate_chi2", o.gate_chi2, kPositive);
  fn("confirm_hits", o.confirm_hits, kAtLeastOne);
  fn("confirm_frames", o.confirm_frames, kAtLeastOne);
  fn("max_coast_s", o.max_coast_s, kNonNegative);
  fn("report_coasting_s", o.report_coasting_s, kNonNegative);
  fn("birth_min_separation_m", o.birth_min_separation_m, kNonNegative);
  fn("class_hysteresis", o.class_hysteresis, Range{0, false, 1, true});
  fn("class_area_smoothing", o.class_area_smoothing, Range{0, true, 1, false});
  fn("window_object_radius_m", o.window_object_radius_m, kPositive);
  fn("window_lost_timeout_s", o.window_lost_timeout_s, kNonNegative);
  fn("window_min_new_area_m2", o.window_min_new_area_m2, kNonNegative);
  fn("trail_length", o.trail_length, kAtLeastOne);
}

// A problem with one element of a list: which sub-field ("" for the element) and what.
struct Problem {
  std::string key;
  std::string what;
};

std::optional<Problem> CheckZone(const ZoneOptions& zone) {
  if (zone.name.empty()) return Problem{"name", "expected a non-empty name"};
  if (zone.polygon_m.size() < 3) {
    return Problem{"polygon", fmt::format("expected at least 3 vertices, found {}", zone.polygon_m.size())};
  }
  double twice_area = 0;
  for (size_t k = 0; k < zone.polygon_m.size(); ++k) {
    const Eigen::Vector2d& a = zone.polygon_m[k];
    const Eigen::Vector2d& b = zone.polygon_m[(k + 1) % zone.polygon_m.size()];
    if (!a.allFinite()) return Problem{"polygon", fmt::format("vertex {} is not finite", k)};
    twice_area += a.x() * b.y() - b.x() * a.y();
  }
  if (!(std::abs(twice_area) > 1e-12)) return Problem{"polygon", "expected a polygon with a non-zero area"};
  if (zone.dwell_s && !(*zone.dwell_s > 0)) {
    return Problem{"dwell_s", fmt::format("expected a number > 0, found {}", *zone.dwell_s)};
  }
  return std::nullopt;
}

std::optional<Problem> CheckClass(const std::vector<ObjectClassOptions>& classes, size_t k) {
  const ObjectClassOptions& c = classes[k];
  if (c.name.empty()) return Problem{"name", "expected a non-empty name"};
  for (size_t m = 0; m < k; ++m) {
    if (classes[m].name == c.name) return Problem{"name", fmt::format("duplicate class name '{}'", c.name)};
  }
  if (!(c.max_area_m2 > 0)) return Problem{"max_area_m2", fmt::format("expected a number > 0, found {}", c.max_area_m2)};
  if (k > 0 && std::isinf(classes[k - 1].max_area_m2)) {
    return Problem{"", fmt::format("expected no class after '{}', which leaves out max_area_m2 (only the last class may)",
                                   classes[k - 1].name)};
  }
  if (k > 0 && !(c.max_area_m2 > classes[k - 1].max_area_m2)) {
    return Problem{"max_area_m2", fmt::format("expected more than the previous class's {} m^2 (classes in increasing "
                                              "order of area), found {}",
                                              classes[k - 1].max_area_m2, c.max_area_m2)};
  }
  return std::nullopt;
}

std::optional<Problem> CheckZoneName(const std::vector<ZoneOptions>& zones, size_t k) {
  for (size_t m = 0; m < k; ++m) {
    if (zones[m].name == zones[k].name) return Problem{"name", fmt::format("duplicate zone name '{}'", zones[k].name)};
  }
  return std::nullopt;
}

std::optional<Problem> CheckLine(const std::vector<LineOptions>& lines, size_t k) {
  const LineOptions& line = lines[k];
  if (line.name.empty()) return Problem{"name", "expected a non-empty name"};
  for (size_t m = 0; m < k; ++m) {
    if (lines[m].name == line.name) return Problem{"name", fmt::format("duplicate line name '{}'", line.name)};
  }
  if (!line.from_m.allFinite()) return Problem{"from", "expected finite coordinates"};
  if (!line.to_m.allFinite()) return Problem{"to", "expected finite coordinates"};
  // 1 mm: a shorter line has no direction worth the name.
  if (!((line.to_m - line.from_m).norm() >= 1e-3)) {
    return Problem{"to", fmt::format("expected a point at least 1 mm from 'from', found {} m from it",
                                     (line.to_m - line.from_m).norm())};
  }
  if (!(line.hysteresis_m >= 0 && line.hysteresis_m <= 2)) {
    return Problem{"hysteresis_m", fmt::format("expected 0..2 m, found {}", line.hysteresis_m)};
  }
  return std::nullopt;
}

std::string ElementPath(std::string_view list, size_t k, const std::string& key) {
  return key.empty() ? fmt::format("tracking.{}[{}]", list, k) : fmt::format("tracking.{}[{}].{}", list, k, key);
}

std::string ConfirmProblem(const TrackerOptions& o) {
  return fmt::format("expected at most confirm_frames ({}), found {}", o.confirm_frames, o.confirm_hits);
}

// Reads a list element's sub-field for a located message ("" = the element itself).
YamlField SubField(const YamlField& element, const std::string& key) {
  if (key.empty()) return element;
  if (auto f = element.Find(key)) return *f;
  return element;
}

}  // namespace

std::string_view ToString(TrackerAlgorithm algorithm) {
  switch (algorithm) {
    case TrackerAlgorithm::kMultiTarget: return "multi_target";
    case TrackerAlgorithm::kWindow: return "window";
  }
  return "?";
}

double TrackerOptions::person_area_m2() const {
  return std::numbers::pi * person_diameter_m * person_diameter_m / 4.0;
}

Status TrackerOptions::Validate() const {
  Status status;
  VisitNumbers(*this, [&](std::string_view key, const auto& value, const Range& range) {
    if (!status.ok()) return;
    const double v = static_cast<double>(value);
    if (!std::isfinite(v) || !range.Contains(v)) {
      status = InvalidInput(fmt::format("tracking.{}: expected {}, found {}", key,
                                        range.Describe(std::is_integral_v<std::decay_t<decltype(value)>>), v));
    }
  });
  OCCMAP_RETURN_IF_ERROR(status);
  if (confirm_hits > confirm_frames) return InvalidInput("tracking.confirm_hits: " + ConfirmProblem(*this));
  for (size_t k = 0; k < classes.size(); ++k) {
    if (auto p = CheckClass(classes, k)) return InvalidInput(fmt::format("{}: {}", ElementPath("classes", k, p->key), p->what));
  }
  for (size_t k = 0; k < zones.size(); ++k) {
    auto p = CheckZone(zones[k]);
    if (!p) p = CheckZoneName(zones, k);
    if (p) return InvalidInput(fmt::format("{}: {}", ElementPath("zones", k, p->key), p->what));
  }
  for (size_t k = 0; k < lines.size(); ++k) {
    if (auto p = CheckLine(lines, k)) return InvalidInput(fmt::format("{}: {}", ElementPath("lines", k, p->key), p->what));
  }
  return Status::Ok();
}

Status ParseTrackerOptions(const YamlField& field, TrackerOptions& options, std::span<const std::string_view> other_keys) {
  if (field.IsNull()) return Status::Ok();
  std::vector<std::string> keys = {"algorithm", "classes", "zones", "zone_count_every_frame", "lines"};
  VisitNumbers(options, [&](std::string_view key, auto&, const Range&) { keys.emplace_back(key); });
  for (std::string_view key : other_keys) keys.emplace_back(key);
  OCCMAP_RETURN_IF_ERROR(field.CheckKeys(keys));

  TrackerOptions parsed = options;
  if (auto f = field.Find("algorithm")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string name, f->AsString());
    if (name == "multi_target") {
      parsed.algorithm = TrackerAlgorithm::kMultiTarget;
    } else if (name == "window") {
      parsed.algorithm = TrackerAlgorithm::kWindow;
    } else {
      return f->Error(fmt::format("expected 'multi_target' or 'window', found '{}'", name));
    }
  }

  Status status;
  VisitNumbers(parsed, [&](std::string_view key, auto& value, const Range& range) {
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
  if (parsed.confirm_hits > parsed.confirm_frames) {
    if (auto f = field.Find("confirm_hits")) return f->Error(ConfirmProblem(parsed));
    return field.Find("confirm_frames")
        .value_or(field)
        .Error(fmt::format("expected at least confirm_hits ({}), found {}", parsed.confirm_hits, parsed.confirm_frames));
  }
  {
    OCCMAP_ASSIGN_OR_RETURN(parsed.zone_count_every_frame,
                            field.GetBool("zone_count_every_frame", parsed.zone_count_every_frame));
  }

  if (auto list = field.Find("classes")) {
    if (!list->IsSequence()) return list->Error("expected a list of {name, max_area_m2}");
    parsed.classes.clear();
    for (size_t k = 0; k < list->size(); ++k) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField element, list->At(k));
      OCCMAP_RETURN_IF_ERROR(element.CheckKeys({"name", "max_area_m2"}));
      ObjectClassOptions c;
      OCCMAP_ASSIGN_OR_RETURN(c.name, element.GetString("name"));
      OCCMAP_ASSIGN_OR_RETURN(c.max_area_m2, element.GetDouble("max_area_m2", kInf));
      parsed.classes.push_back(std::move(c));
      if (auto p = CheckClass(parsed.classes, k)) return SubField(element, p->key).Error(p->what);
    }
  }

  if (auto list = field.Find("zones")) {
    if (!list->IsSequence()) return list->Error("expected a list of {name, polygon, dwell_s}");
    parsed.zones.clear();
    for (size_t k = 0; k < list->size(); ++k) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField element, list->At(k));
      OCCMAP_RETURN_IF_ERROR(element.CheckKeys({"name", "polygon", "dwell_s"}));
      ZoneOptions zone;
      OCCMAP_ASSIGN_OR_RETURN(zone.name, element.GetString("name"));
      OCCMAP_ASSIGN_OR_RETURN(YamlField polygon, element.Get("polygon"));
      if (!polygon.IsSequence()) return polygon.Error("expected a list of [x, y] vertices in metres");
      for (size_t v = 0; v < polygon.size(); ++v) {
        OCCMAP_ASSIGN_OR_RETURN(YamlField vertex, polygon.At(v));
        OCCMAP_ASSIGN_OR_RETURN(std::vector<double> xy, vertex.AsDoubles(2));
        zone.polygon_m.emplace_back(xy[0], xy[1]);
      }
      if (auto d = element.Find("dwell_s")) {
        OCCMAP_ASSIGN_OR_RETURN(double dwell_s, d->AsDouble());
        zone.dwell_s = dwell_s;
      }
      parsed.zones.push_back(std::move(zone));
      auto p = CheckZone(parsed.zones.back());
      if (!p) p = CheckZoneName(parsed.zones, k);
      if (p) return SubField(element, p->key).Error(p->what);
    }
  }

  if (auto list = field.Find("lines")) {
    if (!list->IsSequence()) return list->Error("expected a list of {name, from, to}");
    parsed.lines.clear();
    for (size_t k = 0; k < list->size(); ++k) {
      OCCMAP_ASSIGN_OR_RETURN(YamlField element, list->At(k));
      OCCMAP_RETURN_IF_ERROR(element.CheckKeys({"name", "from", "to", "hysteresis_m", "once_per_track"}));
      LineOptions line;
      OCCMAP_ASSIGN_OR_RETURN(line.name, element.GetString("name"));
      OCCMAP_ASSIGN_OR_RETURN(std::vector<double> from, element.GetDoubles("from", 2));
      OCCMAP_ASSIGN_OR_RETURN(std::vector<double> to, element.GetDoubles("to", 2));
      line.from_m = {from[0], from[1]};
      line.to_m = {to[0], to[1]};
      OCCMAP_ASSIGN_OR_RETURN(line.hysteresis_m, element.GetDouble("hysteresis_m", line.hysteresis_m));
      OCCMAP_ASSIGN_OR_RETURN(line.once_per_track, element.GetBool("once_per_track", line.once_per_track));
      parsed.lines.push_back(std::move(line));
      if (auto p = CheckLine(parsed.lines, k)) return SubField(element, p->key).Error(p->what);
    }
  }

  // Everything was checked with its location above; this is the safety net.
  OCCMAP_RETURN_IF_ERROR(parsed.Validate().WithContext(field.Where()));
  options = std::move(parsed);
  return Status::Ok();
}

}  // namespace occmap
