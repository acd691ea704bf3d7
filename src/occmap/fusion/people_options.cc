#include "occmap/fusion/people_options.h"

#include <fmt/core.h>

namespace occmap {

const char* ToString(PeopleDetector d) {
  switch (d) {
    case PeopleDetector::kFloor: return "floor";
    case PeopleDetector::kColumn: return "column";
    case PeopleDetector::kExplain: return "explain";
  }
  return "?";
}

Status PeopleOptions::Validate(int num_cameras) const {
  OCCMAP_RETURN_IF_ERROR(columns.Validate(FloorGrid{}));
  OCCMAP_RETURN_IF_ERROR(column.Validate(columns.height_m, num_cameras).WithContext("column"));
  OCCMAP_RETURN_IF_ERROR(explain.Validate().WithContext("explain"));
  return occluders.Validate().WithContext("occluders");
}

Status ParsePeopleOptions(const YamlField& f, int num_cameras, PeopleOptions& o) {
  o.enabled = true;
  OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"detector", "height_m", "step_m", "column", "explain", "occluders"}));
  OCCMAP_ASSIGN_OR_RETURN(std::string detector, f.GetString("detector", ToString(o.detector)));
  if (detector == "floor") {
    o.detector = PeopleDetector::kFloor;
  } else if (detector == "column") {
    o.detector = PeopleDetector::kColumn;
  } else if (detector == "explain") {
    o.detector = PeopleDetector::kExplain;
  } else {
    return f.Find("detector")->Error(fmt::format("expected floor, column or explain, found '{}'", detector));
  }
  OCCMAP_ASSIGN_OR_RETURN(o.columns.height_m, f.GetDouble("height_m", o.columns.height_m));
  OCCMAP_ASSIGN_OR_RETURN(o.columns.step_m, f.GetDouble("step_m", o.columns.step_m));
  if (Status s = o.columns.Validate(FloorGrid{}); !s.ok()) return f.Error(s.message());
  if (auto c = f.Find("column")) {
    OCCMAP_RETURN_IF_ERROR(c->CheckKeys({"band_m", "radius_m", "min_changed", "max_free_views", "min_changed_views", "min_views",
                                            "max_rows"}));
    if (c->Has("band_m")) {
      OCCMAP_ASSIGN_OR_RETURN(std::vector<double> band, c->GetDoubles("band_m", 2));
      o.column.band_low_m = band[0];
      o.column.band_high_m = band[1];
    }
    OCCMAP_ASSIGN_OR_RETURN(o.column.radius_m, c->GetDouble("radius_m", o.column.radius_m));
    OCCMAP_ASSIGN_OR_RETURN(o.column.min_changed, c->GetDouble("min_changed", o.column.min_changed));
    OCCMAP_ASSIGN_OR_RETURN(int64_t k, c->GetInt("max_free_views", o.column.max_free_views));
    o.column.max_free_views = static_cast<int>(std::clamp<int64_t>(k, -1, 1000));
    OCCMAP_ASSIGN_OR_RETURN(int64_t views, c->GetInt("min_changed_views", o.column.min_changed_views));
    o.column.min_changed_views = static_cast<int>(std::clamp<int64_t>(views, -1, 1000));
    OCCMAP_ASSIGN_OR_RETURN(int64_t min_views, c->GetInt("min_views", o.column.min_views));
    o.column.min_views = static_cast<int>(std::clamp<int64_t>(min_views, -1, 1000));
    OCCMAP_ASSIGN_OR_RETURN(int64_t rows, c->GetInt("max_rows", o.column.max_rows));
    o.column.max_rows = static_cast<int>(std::clamp<int64_t>(rows, -1, 100000));
    if (Status s = o.column.Validate(o.columns.height_m, num_cameras); !s.ok()) return c->Error(s.message());
  } else if (Status s = o.column.Validate(o.columns.height_m, num_cameras); !s.ok()) {
    return f.Error(fmt::format("column: {}", s.message()));
  }
  if (auto e = f.Find("explain")) {
    OCCMAP_RETURN_IF_ERROR(e->CheckKeys(
        {"radius_m", "unchanged_weight", "min_gain", "min_separation_m", "moves", "move_radius_m", "max_people",
         "max_rows", "ground_band", "ground_weight"}));
    OCCMAP_ASSIGN_OR_RETURN(o.explain.radius_m, e->GetDouble("radius_m", o.explain.radius_m));
    OCCMAP_ASSIGN_OR_RETURN(o.explain.unchanged_weight, e->GetDouble("unchanged_weight", o.explain.unchanged_weight));
    OCCMAP_ASSIGN_OR_RETURN(o.explain.min_gain, e->GetDouble("min_gain", o.explain.min_gain));
    OCCMAP_ASSIGN_OR_RETURN(o.explain.min_separation_m, e->GetDouble("min_separation_m", o.explain.min_separation_m));
    OCCMAP_ASSIGN_OR_RETURN(int64_t moves, e->GetInt("moves", o.explain.moves));
    o.explain.moves = static_cast<int>(std::clamp<int64_t>(moves, -1, 1000));
    OCCMAP_ASSIGN_OR_RETURN(o.explain.move_radius_m, e->GetDouble("move_radius_m", o.explain.move_radius_m));
    OCCMAP_ASSIGN_OR_RETURN(int64_t most, e->GetInt("max_people", o.explain.max_people));
    o.explain.max_people = static_cast<int>(std::clamp<int64_t>(most, -1, 1000000));
    OCCMAP_ASSIGN_OR_RETURN(o.explain.ground_band, e->GetDouble("ground_band", o.explain.ground_band));
    OCCMAP_ASSIGN_OR_RETURN(o.explain.ground_weight, e->GetDouble("ground_weight", o.explain.ground_weight));
    OCCMAP_ASSIGN_OR_RETURN(int64_t rows, e->GetInt("max_rows", o.explain.max_rows));
    o.explain.max_rows = static_cast<int>(std::clamp<int64_t>(rows, -1, 100000));
    if (Status s = o.explain.Validate(); !s.ok()) return e->Error(s.message());
  }
  if (auto e = f.Find("occluders")) OCCMAP_RETURN_IF_ERROR(ParseOccluderLearningOptions(*e, o.occluders));
  return Status::Ok();
}

}  // namespace occmap
