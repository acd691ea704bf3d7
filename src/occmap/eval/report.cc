#include "occmap/eval/report.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace occmap {
namespace {

using nlohmann::json;

json Ratio(double v) {
  if (!std::isfinite(v)) return nullptr;
  return std::round(v * 1e6) / 1e6;
}

json DetectionJson(const DetectionMetrics& m, const std::vector<FrameDetectionCounts>& frames,
                   const std::optional<AnnotationSummary>& annotations) {
  json per_frame = json::array();
  for (const FrameDetectionCounts& c : frames) {
    json f = {{"frame", c.frame}, {"gt", c.gt}, {"detections", c.detections}, {"tp", c.tp}, {"fp", c.fp}, {"fn", c.fn}};
    if (annotations) f["annotation_file"] = annotations->NumberOf(c.frame);
    per_frame.push_back(std::move(f));
  }
  return {{"frames", m.frames},
          {"gt", m.gt},
          {"detections", m.detections},
          {"tp", m.tp},
          {"fp", m.fp},
          {"fn", m.fn},
          {"moda", Ratio(m.moda)},
          {"modp", Ratio(m.modp)},
          {"precision", Ratio(m.precision)},
          {"recall", Ratio(m.recall)},
          {"mean_distance_m", Ratio(m.mean_distance_m)},
          {"gt_frames_missing_from_run", m.gt_frames_missing_from_run},
          {"run_frames_without_gt", m.run_frames_without_gt},
          {"per_frame", per_frame}};
}

json TrackingJson(const TrackingMetrics& m) {
  return {{"frames", m.frames},
          {"gt", m.gt},
          {"predictions", m.predictions},
          {"tp", m.tp},
          {"fp", m.fp},
          {"fn", m.fn},
          {"id_switches", m.id_switches},
          {"fragmentations", m.fragmentations},
          {"gt_trajectories", m.gt_trajectories},
          {"track_trajectories", m.track_trajectories},
          {"mostly_tracked", m.mostly_tracked},
          {"partially_tracked", m.partially_tracked},
          {"mostly_lost", m.mostly_lost},
          {"mota", Ratio(m.mota)},
          {"motp_m", Ratio(m.motp_m)},
          {"motp_closeness", Ratio(m.motp_closeness)},
          {"idtp", m.idtp},
          {"idfp", m.idfp},
          {"idfn", m.idfn},
          {"idf1", Ratio(m.idf1)},
          {"idp", Ratio(m.idp)},
          {"idr", Ratio(m.idr)},
          {"gt_frames_missing_from_run", m.gt_frames_missing_from_run},
          {"run_frames_without_gt", m.run_frames_without_gt}};
}

std::string StepText(const AnnotationSummary& a) {
  return a.step_den == 1 ? fmt::format("{}", a.step_num) : fmt::format("{}/{}", a.step_num, a.step_den);
}

json AnnotationsJson(const AnnotationSummary& a) {
  return {{"format", a.format},
          {"folder", a.folder},
          {"files", a.files},
          {"first_file", a.first_file},
          {"last_file", a.last_file},
          {"first_frame", a.first_frame},
          {"frame_step", StepText(a)},
          {"range", a.range_last < a.range_first ? json(nullptr) : json::array({a.range_first, a.range_last})},
          {"range_from", a.range_given ? "option" : "run"},
          {"files_evaluated", a.files_evaluated},
          {"people_evaluated", a.people_evaluated},
          {"files_outside_range", a.files_outside_range},
          {"files_between_frames", a.files_between_frames}};
}

json OccupancyJson(const std::optional<OccupancyMetrics>& o) {
  if (!o) return nullptr;
  const OccupancyMetrics& m = *o;
  return {{"frames", m.frames},
          {"cells_evaluated", m.cells_evaluated},
          {"tp", m.tp},
          {"fp", m.fp},
          {"fn", m.fn},
          {"tn", m.tn},
          {"computed_unseen", m.computed_unseen},
          {"reference_unseen", m.reference_unseen},
          {"iou", Ratio(m.iou)},
          {"precision", Ratio(m.precision)},
          {"recall", Ratio(m.recall)},
          {"computed_frames_without_reference", m.computed_frames_without_reference}};
}

json ChangeCountsJson(const ChangeMetrics& m) {
  return {{"frames", m.frames},
          {"shadow_frames", m.shadow_frames},
          {"tp", m.counts.tp},
          {"fp", m.counts.fp},
          {"fn", m.counts.fn},
          {"tn", m.counts.tn},
          {"shadow_pixels", m.counts.shadow_pixels},
          {"shadow_changed", m.counts.shadow_changed},
          {"precision", Ratio(m.precision)},
          {"recall", Ratio(m.recall)},
          {"f1", Ratio(m.f1)},
          {"shadow_changed_fraction", Ratio(m.shadow_changed_fraction)}};
}

json ChangesJson(const ChangeEvaluation& e) {
  json j = ChangeCountsJson(e.overall);
  json cameras = json::array();
  for (const CameraChangeMetrics& c : e.cameras) {
    json camera = ChangeCountsJson(c.metrics);
    camera["id"] = c.id;
    cameras.push_back(std::move(camera));
  }
  j["cameras"] = std::move(cameras);
  return j;
}

void OccupancyNotes(const char* name, const std::optional<OccupancyMetrics>& o, std::vector<std::string>& notes) {
  if (!o) return;
  if (o->tp + o->fp + o->fn == 0) {
    notes.push_back(fmt::format("{} IoU undefined: no evaluated cell is occupied in either map", name));
  }
  if (o->tp + o->fp == 0) notes.push_back(fmt::format("{} precision undefined: the computed maps mark no evaluated cell occupied", name));
  if (o->tp + o->fn == 0) notes.push_back(fmt::format("{} recall undefined: the reference marks no evaluated cell occupied", name));
}

// Table cells: a name left-aligned, a value right-aligned.
std::string Int(int64_t v) { return fmt::format("{}", v); }
std::string Real(double v) { return std::isfinite(v) ? fmt::format("{:.4f}", v) : std::string("n/a"); }

void Row(std::string& out, const std::string& name1, const std::string& value1, const std::string& name2 = "",
         const std::string& value2 = "") {
  if (name2.empty()) {
    out += fmt::format("  {:<22}{:>12}\n", name1, value1);
  } else {
    out += fmt::format("  {:<22}{:>12}    {:<22}{:>12}\n", name1, value1, name2, value2);
  }
}

}  // namespace

EvaluationReport MakeEvaluationReport(const EvalOptions& options, const DetectionEvaluator* detection,
                                      const TrackingEvaluator* tracking, const OccupancyEvaluator* footprint,
                                      const OccupancyEvaluator* hull) {
  EvaluationReport r;
  r.match_threshold_m = options.match_threshold_m;
  if (detection != nullptr) {
    r.detection = detection->Metrics();
    r.detection_frames = detection->frames();
    r.gt_frames = std::max(r.gt_frames, r.detection->frames);
  }
  if (tracking != nullptr) {
    r.tracking = tracking->Metrics();
    r.gt_frames = std::max(r.gt_frames, r.tracking->frames);
  }
  if (footprint != nullptr) r.footprint = footprint->Metrics();
  if (hull != nullptr) r.hull = hull->Metrics();
  return r;
}

std::vector<std::string> EvaluationNotes(const EvaluationReport& report) {
  std::vector<std::string> notes = report.notes;
  if (const auto& d = report.detection) {
    if (d->gt == 0) notes.push_back("MODA and recall undefined: no ground-truth objects in the evaluated frames");
    if (d->tp == 0) notes.push_back("MODP and mean distance undefined: no detection matched");
    if (d->detections == 0) notes.push_back("detection precision undefined: no detections");
  }
  if (const auto& t = report.tracking) {
    if (t->gt == 0) notes.push_back("MOTA and IDR undefined: no ground-truth objects in the evaluated frames");
    if (t->tp == 0) notes.push_back("MOTP undefined: no track matched");
    if (t->predictions == 0) notes.push_back("IDP undefined: no tracks");
    if (t->gt + t->predictions == 0) notes.push_back("IDF1 undefined: neither ground truth nor tracks");
  }
  OccupancyNotes("footprint", report.footprint, notes);
  OccupancyNotes("hull", report.hull, notes);
  if (const auto& c = report.changes) {
    const ChangeCounts& n = c->overall.counts;
    if (c->overall.frames == 0) notes.push_back("change metrics undefined: no frame has both a run mask and a gt/changes mask");
    if (c->overall.frames > 0 && n.tp + n.fp == 0) notes.push_back("change precision undefined: the run's masks mark no pixel changed");
    if (c->overall.frames > 0 && n.tp + n.fn == 0) notes.push_back("change recall undefined: the gt/changes masks mark no pixel changed");
    if (c->overall.shadow_frames > 0 && n.shadow_pixels == 0) {
      notes.push_back("shadow_changed_fraction undefined: the gt/shadows masks mark no pixel");
    }
  }
  return notes;
}

nlohmann::json EvaluationReportJson(const EvaluationReport& report) {
  json j = {{"dataset", report.dataset},
          {"run", report.run},
          {"match_threshold_m", report.match_threshold_m},
          {"gt_frames", report.gt_frames},
          {"detection", report.detection ? DetectionJson(*report.detection, report.detection_frames, report.annotations)
                                         : json(nullptr)},
          {"tracking", report.tracking ? TrackingJson(*report.tracking) : json(nullptr)},
          {"occupancy", {{"footprint", OccupancyJson(report.footprint)}, {"hull", OccupancyJson(report.hull)}}},
          {"notes", EvaluationNotes(report)}};
  if (report.changes) j["changes"] = ChangesJson(*report.changes);
  if (report.annotations) j["annotations"] = AnnotationsJson(*report.annotations);
  return j;
}

std::string EvaluationReportText(const EvaluationReport& report) {
  std::string out = "occmap evaluation\n";
  if (!report.dataset.empty()) out += fmt::format("  dataset  {}\n", report.dataset);
  if (!report.run.empty()) out += fmt::format("  run      {}\n", report.run);
  if (const auto& a = report.annotations) {
    out += fmt::format("  ground truth: {} annotations, {} files ({}..{}); file = {} + {} x run frame\n", a->format,
                       a->files, a->first_file, a->last_file, a->first_frame, StepText(*a));
    if (a->range_last < a->range_first) {
      out += "  evaluated: no annotation file (the run has no frames)\n";
    } else {
      out += fmt::format("  evaluated: {} files, {} people, numbers {}..{} ({})\n", a->files_evaluated,
                         a->people_evaluated, a->range_first, a->range_last,
                         a->range_given ? "the range given" : "the run's frames");
    }
  }
  out += fmt::format("  match when distance <= {:.3f} m; {} frames of ground truth\n", report.match_threshold_m,
                     report.gt_frames);

  out += "\ndetection (CLEAR MOD)\n";
  if (const auto& d = report.detection) {
    Row(out, "frames", Int(d->frames), "ground truth (N_gt)", Int(d->gt));
    Row(out, "detections", Int(d->detections), "true positives", Int(d->tp));
    Row(out, "false positives", Int(d->fp), "misses", Int(d->fn));
    Row(out, "MODA", Real(d->moda), "MODP", Real(d->modp));
    Row(out, "precision", Real(d->precision), "recall", Real(d->recall));
    Row(out, "mean distance (m)", Real(d->mean_distance_m));
  } else {
    out += "  not evaluated\n";
  }

  out += "\ntracking (CLEAR MOT, identity)\n";
  if (const auto& t = report.tracking) {
    Row(out, "frames", Int(t->frames), "ground truth (N_gt)", Int(t->gt));
    Row(out, "track positions", Int(t->predictions), "true positives", Int(t->tp));
    Row(out, "false positives", Int(t->fp), "misses", Int(t->fn));
    Row(out, "ID switches", Int(t->id_switches), "fragmentations", Int(t->fragmentations));
    Row(out, "MOTA", Real(t->mota), "MOTP (m)", Real(t->motp_m));
    Row(out, "MOTP (1 - d/t)", Real(t->motp_closeness), "IDF1", Real(t->idf1));
    Row(out, "IDP", Real(t->idp), "IDR", Real(t->idr));
    Row(out, "IDTP", Int(t->idtp), "IDFP / IDFN", fmt::format("{} / {}", t->idfp, t->idfn));
    Row(out, "GT trajectories", Int(t->gt_trajectories), "tracks", Int(t->track_trajectories));
    Row(out, "mostly tracked", Int(t->mostly_tracked), "partially tracked", Int(t->partially_tracked));
    Row(out, "mostly lost", Int(t->mostly_lost));
  } else {
    out += "  not evaluated\n";
  }

  out += "\noccupancy (cells the computed map sees)\n";
  if (report.footprint || report.hull) {
    auto cell = [](const std::optional<OccupancyMetrics>& o, auto field) -> std::string {
      return o ? field(*o) : std::string("-");
    };
    auto row = [&](const char* name, auto field) {
      out += fmt::format("  {:<22}{:>12}{:>14}\n", name, cell(report.footprint, field), cell(report.hull, field));
    };
    out += fmt::format("  {:<22}{:>12}{:>14}\n", "", "footprint", "hull");
    row("frames", [](const OccupancyMetrics& m) { return Int(m.frames); });
    row("cells evaluated", [](const OccupancyMetrics& m) { return Int(m.cells_evaluated); });
    row("true positives", [](const OccupancyMetrics& m) { return Int(m.tp); });
    row("false positives", [](const OccupancyMetrics& m) { return Int(m.fp); });
    row("misses", [](const OccupancyMetrics& m) { return Int(m.fn); });
    row("IoU", [](const OccupancyMetrics& m) { return Real(m.iou); });
    row("precision", [](const OccupancyMetrics& m) { return Real(m.precision); });
    row("recall", [](const OccupancyMetrics& m) { return Real(m.recall); });
  } else {
    out += "  not evaluated\n";
  }

  if (const auto& c = report.changes) {
    out += "\nchanges (pixels of the run's change masks against gt/changes)\n";
    out += fmt::format("  {:<16}{:>8}{:>12}{:>12}{:>12}{:>16}\n", "camera", "frames", "precision", "recall", "F1",
                       "shadow changed");
    auto row = [&](const std::string& name, const ChangeMetrics& m) {
      out += fmt::format("  {:<16}{:>8}{:>12}{:>12}{:>12}{:>16}\n", name, m.frames, Real(m.precision), Real(m.recall),
                         Real(m.f1), m.shadow_frames > 0 ? Real(m.shadow_changed_fraction) : std::string("-"));
    };
    row("all", c->overall);
    for (const CameraChangeMetrics& camera : c->cameras) row(camera.id, camera.metrics);
  }

  const std::vector<std::string> notes = EvaluationNotes(report);
  if (!notes.empty()) {
    out += "\nnotes\n";
    for (const std::string& n : notes) out += fmt::format("  - {}\n", n);
  }
  return out;
}

}  // namespace occmap
