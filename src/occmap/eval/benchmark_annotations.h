// Benchmark annotations: the ground truth of WILDTRACK and MultiviewX as those datasets ship it
// (annotations_positions/*.json), read as occmap ground truth, so that a run over the real
// frames is scored with the field's protocol (CLEAR MOD at 0.5 m, CLEAR MOT and IDF1 with
// personID as the identity) by the same evaluators as the simulator's datasets.
//
// The files: one per annotated frame, named by its frame number in digits (WILDTRACK
// 00000000.json, 00000005.json, ...: 8 digits, numbers counting 10 fps frames, one file every
// 5; MultiviewX 00000.json, 00001.json, ...: 5 digits, every frame). Each holds a JSON list of
// people:
//   [{"personID": 122, "positionID": 456826,
//     "views": [{"viewNum": 0, "xmin": 1510, "ymin": 139, "xmax": 1561, "ymax": 299}, ...]}, ...]
// personID (integer >= 0, unique within a file) and positionID (integer, a cell of the
// dataset's grid) are required; views is optional (a list of boxes: viewNum 0..views-1 and
// integer corners, xmin <= xmax and ymin <= ymax, or all four -1 where the person is not in that
// view). Unknown keys are ignored; files not ending in .json too.
//
// Positions, in occmap's world (metres; the frame the datasets' calibrations define, which
// occmap's sites/wildtrack.yaml, sites/multiviewx.yaml and `occmap synth --scene wildtrack`
// use), from the datasets' own formulas:
//   WILDTRACK   x = 0.01 (-300 + 2.5 (id % 480)), y = 0.01 (-900 + 2.5 (id / 480))
//               (480 x 1440 cells of 2.5 cm from (-3, -9) m; ids 0..691199; 7 views)
//   MultiviewX  x = (id % 1000) / 40, y = (id / 1000) / 40
//               (1000 x 640 cells of 2.5 cm from (0, 0) m; ids 0..639999; 6 views)
//   terrace     x = -0.5 + 0.25 (id % 30 + 0.5), y = -1.5 + 0.25 (id / 30 + 0.5)
//               (the EPFL terrace sequence: 30 x 44 cells of 25 cm; ids 0..1319; 4 views;
//               files of 6 digits numbered by the frames' index, 000000.json, one per image)
// (integer division). WILDTRACK's and MultiviewX's formulas give a cell's corner, as the
// datasets' own evaluation uses; the terrace's its centre (its positions project onto the feet).
//
// Frames (BenchmarkMapping): a run numbers its frames 0, 1, ... from its sources' first image
// (`occmap run --start K` starts at K). Annotation file n holds run frame k when
//   n = first_frame + frame_step * k,
// frame_step a whole number or a fraction P/Q. The defaults fit a run over the images the
// datasets distribute (one per annotation file): WILDTRACK frame_step 5 (Image_subsets/C1 holds
// 00000000.png, 00000005.png, ...: run frame k is file 5k), MultiviewX 1. A run over 10 fps
// WILDTRACK frames (the simulator's wildtrack scene, from its --first-frame F) takes
// frame_step 1 and first_frame F; over 60 fps video frame_step 1/6.
// Which files count: those whose number is in the range (the run's first to last frame by
// default, BenchmarkEvalOptions::annotation_range to give it) and falls on a run frame; an
// annotated frame in the range that the run has no line for counts all its people as misses.
// The others are left out and counted in the report.
//
//   BenchmarkEvalOptions benchmark;                       // format from the file names
//   OCCMAP_ASSIGN_OR_RETURN(EvaluationReport report,
//                           EvaluateRunOnBenchmark("Wildtrack", "occmap-out", benchmark, EvalOptions{}, ctx));
//   double moda = report.detection->moda;
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "occmap/eval/eval_options.h"
#include "occmap/eval/report.h"
#include "occmap/sim/ground_truth.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

enum class BenchmarkFormat { kWildtrack, kMultiviewX, kTerrace };

// "wildtrack", "multiviewx", "terrace".
std::string_view BenchmarkFormatName(BenchmarkFormat format);
// The name as BenchmarkFormatName gives it; anything else is an error naming `field`.
Result<BenchmarkFormat> ParseBenchmarkFormat(std::string_view text, std::string_view field = "format");

// A dataset's annotation grid and conventions.
struct BenchmarkGrid {
  std::string_view title;   // "WILDTRACK", "MultiviewX"
  int64_t cells_x = 0, cells_y = 0;  // position ids 0 .. cells_x * cells_y - 1
  double origin_x_m = 0, origin_y_m = 0, cell_size_m = 0;
  int views = 0;             // cameras: viewNum 0 .. views - 1
  int file_digits = 0;       // digits of a file name (written; detection by file names)
  int64_t default_frame_step = 1;  // annotation numbers per run frame over the distributed images
  bool at_cell_centre = false;     // an id names its cell's centre (else its corner)
  bool identities = true;          // personID is a person across frames (else within a file only)
};
const BenchmarkGrid& GridOf(BenchmarkFormat format);

// The floor position of a position id in metres (the formulas above). CHECKs that the id is on
// the grid (the reader has validated it).
Eigen::Vector2d BenchmarkPositionM(BenchmarkFormat format, int64_t position_id);

// A person's box in one view, in pixels (it may reach beyond the image: WILDTRACK has
// xmin -549, ymax 2751); all four -1 when the person is not in that view.
struct AnnotatedBox {
  int view = 0;
  int64_t xmin = -1, ymin = -1, xmax = -1, ymax = -1;
  bool visible() const { return !(xmin == -1 && ymin == -1 && xmax == -1 && ymax == -1); }
};

struct AnnotatedPerson {
  int64_t person_id = 0;
  int64_t position_id = 0;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  std::vector<AnnotatedBox> views;  // as in the file (may be empty)
};

struct AnnotationFrame {
  int64_t number = 0;  // the file's number
  std::vector<AnnotatedPerson> people;
};

struct BenchmarkAnnotations {
  std::filesystem::path folder;
  BenchmarkFormat format = BenchmarkFormat::kWildtrack;
  std::vector<AnnotationFrame> frames;  // by number, increasing
};

// The people of one file's text; `source_name` names it in messages:
//   Wildtrack/annotations_positions/00000005.json: [3].positionID: expected an integer 0..691199 (WILDTRACK's 480 x 1440 grid), found 700000
Result<std::vector<AnnotatedPerson>> ParseAnnotationFile(std::string_view text, std::string_view source_name,
                                                         BenchmarkFormat format);

// Every NNN.json of `folder` (the annotations_positions folder itself), by number. With no
// format given, it is told from the file names: 8 digits WILDTRACK, 5 digits MultiviewX (an
// error asks for the format otherwise). Errors: folder missing (NotFound); no *.json; a *.json
// whose name is not digits; two files of one number; any file ParseAnnotationFile refuses.
Result<BenchmarkAnnotations> ReadBenchmarkAnnotations(const std::filesystem::path& folder,
                                                      std::optional<BenchmarkFormat> format = std::nullopt);

// Writes each frame to folder/<number, GridOf(format).file_digits digits>.json, as the datasets
// do (personID, positionID, views). The folder is created if needed.
Status WriteBenchmarkAnnotations(const std::filesystem::path& folder, BenchmarkFormat format,
                                 const std::vector<AnnotationFrame>& frames);

// The annotation folder of `dataset`: dataset/annotations_positions when that is a folder, else
// dataset itself when it holds a *.json named by digits; nullopt otherwise.
std::optional<std::filesystem::path> FindAnnotationFolder(const std::filesystem::path& dataset);

// How annotation file numbers map to a run's frame numbers: number = first_frame + step * frame,
// step = step_num / step_den.
struct BenchmarkMapping {
  int64_t first_frame = 0;  // the annotation number of run frame 0
  int64_t step_num = 1, step_den = 1;
  Status Validate() const;  // first_frame 0..10^12 - 1; step_num, step_den 1..10^6
  // The run frame of annotation number n, or nullopt when n falls before run frame 0 or between
  // two run frames.
  std::optional<int64_t> RunFrameOf(int64_t number) const;
  // The annotation number of run frame k when it is a whole number.
  std::optional<int64_t> NumberOf(int64_t frame) const;
  std::string StepText() const;  // "5", "1/6"
};

// "5", "1/6": a whole number or a fraction of whole numbers >= 1 (`field` names the option).
Result<std::pair<int64_t, int64_t>> ParseFrameStep(std::string_view text, std::string_view field = "frame step");
// "1800:1995": two annotation numbers, first <= last.
Result<std::pair<int64_t, int64_t>> ParseAnnotationRange(std::string_view text,
                                                         std::string_view field = "annotation range");

struct BenchmarkEvalOptions {
  std::optional<BenchmarkFormat> format;  // nullopt: told from the file names
  int64_t first_frame = 0;                // BenchmarkMapping::first_frame
  // Annotation numbers per run frame, as (P, Q) for P/Q; nullopt: the format's default_frame_step.
  std::optional<std::pair<int64_t, int64_t>> frame_step;
  // Inclusive range of annotation numbers evaluated; nullopt: from the run's first frame to its
  // last (over detections.jsonl and tracks.jsonl).
  std::optional<std::pair<int64_t, int64_t>> annotation_range;
  Status Validate() const;
};

// The annotated frames to evaluate as ground truth of run frames (frame = the run frame, objects
// of class "person" with id = personID at the position), in the inclusive range of annotation
// numbers [range_first, range_last]; fills the counts of `summary` (files, evaluated, left out).
std::vector<GroundTruthFrame> AnnotationsToGroundTruth(const BenchmarkAnnotations& annotations,
                                                       const BenchmarkMapping& mapping, int64_t range_first,
                                                       int64_t range_last, AnnotationSummary& summary);

// `occmap eval DATASET RUN` on a benchmark: DATASET is a dataset root holding
// annotations_positions/ or that folder itself (FindAnnotationFolder). Detection and tracking
// metrics as EvaluateRun's; the report's `annotations` says what was read and how it was mapped,
// its notes what was left out.
Result<EvaluationReport> EvaluateRunOnBenchmark(const std::filesystem::path& dataset,
                                                const std::filesystem::path& run_dir,
                                                const BenchmarkEvalOptions& benchmark, const EvalOptions& options,
                                                Context& ctx);
Result<EvaluationReport> EvaluateRunOnBenchmark(const std::filesystem::path& dataset,
                                                const std::filesystem::path& run_dir,
                                                const BenchmarkEvalOptions& benchmark = {},
                                                const EvalOptions& options = {});

}  // namespace occmap
