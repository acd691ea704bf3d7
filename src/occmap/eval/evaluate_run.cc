#include "occmap/eval/evaluate_run.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>
#include <system_error>
#include <utility>

#include "occmap/eval/change_metrics.h"
#include "occmap/eval/run_outputs.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

bool IsDirectory(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

Status CheckUniqueObjectIds(const std::vector<GroundTruthFrame>& frames, std::string_view source) {
  for (const GroundTruthFrame& f : frames) {
    std::set<int64_t> ids;
    for (const GroundTruthObject& o : f.objects) {
      if (!ids.insert(o.id).second) {
        return InvalidInput(fmt::format("{}: frame {}: objects[].id: expected ids unique within a frame, found {} twice",
                                        source, f.frame, o.id));
      }
    }
  }
  return Status::Ok();
}

struct FrameWalk {
  int64_t gt_frames_missing = 0;   // ground-truth frames with no line in the run
  int64_t objects_missing = 0;     // their objects (after the class filter)
  int64_t run_frames_without_gt = 0;
};

// Walks the ground-truth frames and the run's lines (both in increasing frame order), calling
// add(gt_frame, run_frame or nullptr) for every frame evaluated.
template <typename RunFrame, typename Add>
FrameWalk WalkFrames(const std::vector<GroundTruthFrame>& gt, const std::vector<RunFrame>& run,
                     const EvalOptions& options, const Add& add) {
  FrameWalk walk;
  size_t r = 0;
  for (const GroundTruthFrame& g : gt) {
    while (r < run.size() && run[r].frame < g.frame) {
      ++walk.run_frames_without_gt;
      ++r;
    }
    if (r < run.size() && run[r].frame == g.frame) {
      add(g, &run[r]);
      ++r;
      continue;
    }
    ++walk.gt_frames_missing;
    walk.objects_missing += static_cast<int64_t>(GroundTruthPositions(g, options).size());
    if (!options.skip_frames_missing_from_run) add(g, static_cast<const RunFrame*>(nullptr));
  }
  walk.run_frames_without_gt += static_cast<int64_t>(run.size() - r);
  return walk;
}

void WalkNotes(const char* file, const FrameWalk& walk, const EvalOptions& options, std::vector<std::string>& notes) {
  if (walk.gt_frames_missing > 0) {
    notes.push_back(fmt::format("{}: {} ground-truth frames have no line; their {} objects {}", file,
                                walk.gt_frames_missing, walk.objects_missing,
                                options.skip_frames_missing_from_run ? "are left out (skip_frames_missing_from_run)"
                                                                     : "count as misses"));
  }
  if (walk.run_frames_without_gt > 0) {
    notes.push_back(fmt::format("{}: {} lines are of frames without ground truth; not evaluated", file,
                                walk.run_frames_without_gt));
  }
}

// The run against `gt`; the reference rasters (occupancy, change masks) are read from
// dataset_dir when it is given.
Result<EvaluationReport> EvaluateRunImpl(const std::vector<GroundTruthFrame>& gt, std::string dataset_name,
                                         const fs::path* dataset_dir, const fs::path& run_dir, const EvalOptions& options,
                                         Context& ctx) {
  EvaluationReport report;
  report.dataset = std::move(dataset_name);
  report.run = run_dir.string();
  report.match_threshold_m = options.match_threshold_m;
  report.gt_frames = static_cast<int64_t>(gt.size());

  const fs::path detections_path = run_dir / "detections.jsonl";
  const fs::path tracks_path = run_dir / "tracks.jsonl";
  const fs::path occupancy_dir = run_dir / "occupancy";
  bool anything = false;

  if (IsFile(detections_path)) {
    anything = true;
    OCCMAP_ASSIGN_OR_RETURN(const std::vector<DetectionFrame> run, ReadDetections(detections_path));
    DetectionEvaluator evaluator(options);
    const FrameWalk walk = WalkFrames(gt, run, options, [&](const GroundTruthFrame& g, const DetectionFrame* d) {
      std::vector<Eigen::Vector2d> detections_m;
      if (d != nullptr) {
        for (const DetectedBlob& b : d->blobs) {
          if (!(b.area_m2 < options.min_detection_area_m2)) detections_m.emplace_back(b.x_m, b.y_m);  // NaN area kept
        }
      }
      evaluator.AddFrame(g, detections_m);
    });
    report.detection = evaluator.Metrics();
    report.detection->gt_frames_missing_from_run = walk.gt_frames_missing;
    report.detection->run_frames_without_gt = walk.run_frames_without_gt;
    report.detection_frames = evaluator.frames();
    WalkNotes("detections.jsonl", walk, options, report.notes);
  } else {
    report.notes.push_back("no detections.jsonl in the run: detection not evaluated");
  }

  if (IsFile(tracks_path)) {
    anything = true;
    OCCMAP_ASSIGN_OR_RETURN(const std::vector<TrackFrame> run, ReadTracks(tracks_path));
    TrackingEvaluator evaluator(options);
    const FrameWalk walk = WalkFrames(gt, run, options, [&](const GroundTruthFrame& g, const TrackFrame* t) {
      evaluator.AddFrame(g, t != nullptr ? t->tracks : std::vector<TrackRecord>{});
    });
    report.tracking = evaluator.Metrics();
    report.tracking->gt_frames_missing_from_run = walk.gt_frames_missing;
    report.tracking->run_frames_without_gt = walk.run_frames_without_gt;
    WalkNotes("tracks.jsonl", walk, options, report.notes);
  } else {
    report.notes.push_back("no tracks.jsonl in the run: tracking not evaluated");
  }

  if (dataset_dir == nullptr) {
    report.notes.push_back("the ground truth is positions only: occupancy and change masks not evaluated");
    if (!anything) {
      return NotFound(fmt::format("{}: nothing to evaluate against {}: expected detections.jsonl or tracks.jsonl",
                                  run_dir.string(), report.dataset));
    }
    return report;
  }

  std::vector<std::pair<int64_t, fs::path>> maps;
  if (IsDirectory(occupancy_dir)) {
    OCCMAP_ASSIGN_OR_RETURN(maps, ListFramePngs(occupancy_dir, "map"));
  }
  if (maps.empty()) {
    report.notes.push_back("no occupancy/NNNNNN.png in the run: occupancy not evaluated");
  } else {
    anything = true;
    struct Reference {
      const char* name;
      fs::path dir;
      OccupancyGrayCodes codes;
      std::optional<OccupancyMetrics>* metrics;
      OccupancyEvaluator evaluator;
      int64_t missing = 0;
    };
    Reference refs[] = {{"footprint", *dataset_dir / "gt" / "footprint", options.footprint_codes, &report.footprint, {}, 0},
                        {"hull", *dataset_dir / "gt" / "hull", options.hull_codes, &report.hull, {}, 0}};
    for (Reference& ref : refs) {
      if (!IsDirectory(ref.dir)) {
        report.notes.push_back(fmt::format("no gt/{} folder in the dataset: occupancy against it not evaluated", ref.name));
      }
    }
    for (const auto& [frame, map_path] : maps) {
      std::optional<CellRaster> computed;
      for (Reference& ref : refs) {
        if (!IsDirectory(ref.dir)) continue;
        const fs::path ref_path = ref.dir / fmt::format("{:06d}.png", frame);
        if (!IsFile(ref_path)) {
          ++ref.missing;
          continue;
        }
        if (!computed) {
          OCCMAP_ASSIGN_OR_RETURN(computed, ReadCellRaster(map_path, options.computed_codes));
        }
        OCCMAP_ASSIGN_OR_RETURN(const CellRaster reference, ReadCellRaster(ref_path, ref.codes));
        if (reference.cells_x != computed->cells_x || reference.cells_y != computed->cells_y) {
          return InvalidInput(fmt::format("{}: expected {}x{} cells like {}, found {}x{}", ref_path.string(),
                                          computed->cells_x, computed->cells_y, map_path.string(), reference.cells_x,
                                          reference.cells_y));
        }
        ref.evaluator.AddFrame(frame, *computed, reference);
      }
    }
    for (Reference& ref : refs) {
      if (!IsDirectory(ref.dir)) continue;
      *ref.metrics = ref.evaluator.Metrics();
      (*ref.metrics)->computed_frames_without_reference = ref.missing;
      if (ref.missing > 0) {
        report.notes.push_back(fmt::format("occupancy: {} computed maps have no gt/{} raster of their frame; not evaluated",
                                           ref.missing, ref.name));
      }
    }
  }

  const fs::path changes_dir = run_dir / "changes";
  if (IsDirectory(changes_dir)) {
    anything = true;
    if (!IsDirectory(*dataset_dir / "gt" / "changes")) {
      report.notes.push_back("no gt/changes folder in the dataset: change masks not evaluated");
    } else {
      OCCMAP_ASSIGN_OR_RETURN(report.changes, EvaluateChangeMasks(changes_dir, *dataset_dir / "gt", ctx, report.notes));
    }
  }

  if (!anything) {
    return NotFound(fmt::format("{}: nothing to evaluate: expected detections.jsonl, tracks.jsonl, occupancy/NNNNNN.png "
                                "or changes/<camera>/NNNNNN.png",
                                run_dir.string()));
  }
  return report;
}

}  // namespace

Result<EvaluationReport> EvaluateRun(const fs::path& dataset_dir, const fs::path& run_dir, const EvalOptions& options) {
  Context serial(1);  // the calling thread only: no worker threads
  return EvaluateRun(dataset_dir, run_dir, options, serial);
}

Result<EvaluationReport> EvaluateRun(const fs::path& dataset_dir, const fs::path& run_dir, const EvalOptions& options,
                                     Context& ctx) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  fs::path gt_path = dataset_dir / "ground_truth.jsonl";
  if (!IsFile(gt_path) && IsFile(dataset_dir / "gt" / "ground_truth.jsonl")) gt_path = dataset_dir / "gt" / "ground_truth.jsonl";
  if (!IsFile(gt_path)) {
    return NotFound(fmt::format("{}: no ground truth: expected ground_truth.jsonl or gt/ground_truth.jsonl", dataset_dir.string()));
  }
  OCCMAP_ASSIGN_OR_RETURN(const std::vector<GroundTruthFrame> gt, ReadGroundTruth(gt_path));
  OCCMAP_RETURN_IF_ERROR(CheckUniqueObjectIds(gt, gt_path.string()));
  return EvaluateRunImpl(gt, dataset_dir.string(), &dataset_dir, run_dir, options, ctx);
}

Result<EvaluationReport> EvaluateRunAgainst(const std::vector<GroundTruthFrame>& gt, std::string_view dataset_name,
                                            const fs::path& run_dir, const EvalOptions& options, Context& ctx) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  for (size_t k = 1; k < gt.size(); ++k) {
    if (gt[k].frame <= gt[k - 1].frame) {
      return InvalidInput(fmt::format("{}: frames: expected increasing frame numbers, found {} after {}", dataset_name,
                                      gt[k].frame, gt[k - 1].frame));
    }
  }
  OCCMAP_RETURN_IF_ERROR(CheckUniqueObjectIds(gt, dataset_name));
  return EvaluateRunImpl(gt, std::string(dataset_name), nullptr, run_dir, options, ctx);
}

}  // namespace occmap
