#include "occmap/eval/benchmark_annotations.h"

#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <system_error>
#include <tuple>

#include "occmap/eval/evaluate_run.h"
#include "occmap/eval/run_outputs.h"
#include "occmap/util/file_util.h"
#include "occmap/util/text_guard.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

using nlohmann::json;

// Bounds that keep number x step in int64: frame steps P/Q with P, Q <= 10^6, annotation
// numbers of at most 12 digits, run frames below 10^12.
constexpr int64_t kMaxStepTerm = 1'000'000;
constexpr size_t kMaxFileDigits = 12;
constexpr int64_t kMaxNumber = 999'999'999'999;

const BenchmarkGrid kWildtrackGrid{.title = "WILDTRACK",
                                   .cells_x = 480,
                                   .cells_y = 1440,
                                   .origin_x_m = -3.0,
                                   .origin_y_m = -9.0,
                                   .cell_size_m = 0.025,
                                   .views = 7,
                                   .file_digits = 8,
                                   .default_frame_step = 5};
const BenchmarkGrid kMultiviewXGrid{.title = "MultiviewX",
                                    .cells_x = 1000,
                                    .cells_y = 640,
                                    .origin_x_m = 0.0,
                                    .origin_y_m = 0.0,
                                    .cell_size_m = 0.025,
                                    .views = 6,
                                    .file_digits = 5,
                                    .default_frame_step = 1};
// The EPFL terrace sequence as ../shared/datasets/terrace-video ships it: a 25 cm grid whose
// ids name cell centres, in the Tsai calibration's world (millimetres / 1000).
const BenchmarkGrid kTerraceGrid{.title = "EPFL terrace",
                                 .cells_x = 30,
                                 .cells_y = 44,
                                 .origin_x_m = -0.5,
                                 .origin_y_m = -1.5,
                                 .cell_size_m = 0.25,
                                 .views = 4,
                                 .file_digits = 6,
                                 .default_frame_step = 1,
                                 .at_cell_centre = true,
                                 .identities = false};
constexpr BenchmarkFormat kFormats[] = {BenchmarkFormat::kWildtrack, BenchmarkFormat::kMultiviewX,
                                        BenchmarkFormat::kTerrace};

// How a value (or its absence) reads in a message: its JSON text, shortened.
std::string Found(const json* value) {
  if (value == nullptr) return "nothing";
  std::string text = value->dump();
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  return text;
}

const json* Get(const json& object, const char* key) {
  const auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

// "<source>: <field>: expected <expected>, found <found>".
Status FieldError(std::string_view source, std::string_view field, std::string_view expected, std::string_view found) {
  return InvalidInput(fmt::format("{}: {}: expected {}, found {}", source, field, expected, found));
}

// object[key] as an integer in [min_value, max_value].
Status Integer(std::string_view source, const json& object, const char* key, const std::string& field,
               int64_t min_value, int64_t max_value, std::string_view expected, int64_t* out) {
  const json* v = Get(object, key);
  bool ok = v != nullptr && v->is_number_integer();
  if (ok && v->is_number_unsigned()) ok = v->get<uint64_t>() <= static_cast<uint64_t>(max_value);
  if (ok) {
    *out = v->get<int64_t>();
    ok = *out >= min_value && *out <= max_value;
  }
  return ok ? Status::Ok() : FieldError(source, field, expected, Found(v));
}

// Digits only, 1..kMaxFileDigits of them.
std::optional<int64_t> NumberOfName(std::string_view stem) {
  if (stem.empty() || stem.size() > kMaxFileDigits) return std::nullopt;
  int64_t number = 0;
  const auto [ptr, err] = std::from_chars(stem.data(), stem.data() + stem.size(), number);
  if (err != std::errc() || ptr != stem.data() + stem.size() || stem.front() == '-' || stem.front() == '+') {
    return std::nullopt;
  }
  return number;
}

bool IsFile(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

bool IsDirectory(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

// The run's first and last frame over detections.jsonl and tracks.jsonl; nullopt when it has no
// line. NotFound when it has neither file.
Result<std::optional<std::pair<int64_t, int64_t>>> RunFrameSpan(const fs::path& run_dir, std::string_view against) {
  const fs::path detections_path = run_dir / "detections.jsonl";
  const fs::path tracks_path = run_dir / "tracks.jsonl";
  if (!IsFile(detections_path) && !IsFile(tracks_path)) {
    return NotFound(fmt::format("{}: nothing to evaluate against {}: expected detections.jsonl or tracks.jsonl",
                                run_dir.string(), against));
  }
  std::optional<std::pair<int64_t, int64_t>> span;
  auto add = [&](int64_t first, int64_t last) {
    span = span ? std::pair(std::min(span->first, first), std::max(span->second, last)) : std::pair(first, last);
  };
  if (IsFile(detections_path)) {
    OCCMAP_ASSIGN_OR_RETURN(const std::vector<DetectionFrame> frames, ReadDetections(detections_path));
    if (!frames.empty()) add(frames.front().frame, frames.back().frame);
  }
  if (IsFile(tracks_path)) {
    OCCMAP_ASSIGN_OR_RETURN(const std::vector<TrackFrame> frames, ReadTracks(tracks_path));
    if (!frames.empty()) add(frames.front().frame, frames.back().frame);
  }
  if (span && span->second > kMaxNumber) {
    return InvalidInput(fmt::format("{}: frame: expected run frames <= {} to map to annotation numbers, found {}",
                                    run_dir.string(), kMaxNumber, span->second));
  }
  return span;
}

// "A<separator>B" (or "A" alone when `single` is given: B = *single), both in [min_value, max_value].
Result<std::pair<int64_t, int64_t>> ParseIntegerPair(std::string_view text, char separator, std::string_view field,
                                                     std::string_view expected, int64_t min_value, int64_t max_value,
                                                     std::optional<int64_t> single = std::nullopt) {
  const size_t at = text.find(separator);
  if (at == std::string_view::npos && single && !text.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(const auto pair, ParseIntegerPair(std::string(text) + separator + std::to_string(*single),
                                                              separator, field, expected, min_value, max_value));
    return pair;
  }
  const std::string_view parts[2] = {text.substr(0, at),
                                     at == std::string_view::npos ? std::string_view() : text.substr(at + 1)};
  int64_t values[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    const std::string_view part = parts[k];
    const auto [ptr, err] = std::from_chars(part.data(), part.data() + part.size(), values[k]);
    if (part.empty() || err != std::errc() || ptr != part.data() + part.size() || values[k] < min_value ||
        values[k] > max_value) {
      return InvalidInput(fmt::format("{}: expected {}, found '{}'", field, expected, text));
    }
  }
  return std::pair(values[0], values[1]);
}

}  // namespace

std::string_view BenchmarkFormatName(BenchmarkFormat format) {
  switch (format) {
    case BenchmarkFormat::kWildtrack: return "wildtrack";
    case BenchmarkFormat::kMultiviewX: return "multiviewx";
    case BenchmarkFormat::kTerrace: return "terrace";
  }
  return "?";
}

Result<BenchmarkFormat> ParseBenchmarkFormat(std::string_view text, std::string_view field) {
  for (BenchmarkFormat f : kFormats) {
    if (text == BenchmarkFormatName(f)) return f;
  }
  return InvalidInput(fmt::format("{}: expected wildtrack, multiviewx or terrace, found '{}'", field, text));
}

const BenchmarkGrid& GridOf(BenchmarkFormat format) {
  switch (format) {
    case BenchmarkFormat::kWildtrack: return kWildtrackGrid;
    case BenchmarkFormat::kMultiviewX: return kMultiviewXGrid;
    case BenchmarkFormat::kTerrace: return kTerraceGrid;
  }
  OCCMAP_CHECK(false, "unknown benchmark format");
  return kWildtrackGrid;
}

Eigen::Vector2d BenchmarkPositionM(BenchmarkFormat format, int64_t position_id) {
  const BenchmarkGrid& g = GridOf(format);
  OCCMAP_CHECK(position_id >= 0 && position_id < g.cells_x * g.cells_y, "position id off the grid");
  // The datasets' own formulas (WILDTRACK in centimetres), so that positions agree to the bit
  // with sim::WildtrackPositionM and with other tools using them.
  if (format == BenchmarkFormat::kWildtrack) {
    return {0.01 * (-300.0 + 2.5 * static_cast<double>(position_id % 480)),
            0.01 * (-900.0 + 2.5 * static_cast<double>(position_id / 480))};
  }
  if (format == BenchmarkFormat::kMultiviewX) {
    return {static_cast<double>(position_id % 1000) / 40.0, static_cast<double>(position_id / 1000) / 40.0};
  }
  const double offset = g.at_cell_centre ? 0.5 : 0.0;
  return {g.origin_x_m + g.cell_size_m * (static_cast<double>(position_id % g.cells_x) + offset),
          g.origin_y_m + g.cell_size_m * (static_cast<double>(position_id / g.cells_x) + offset)};
}

Result<std::vector<AnnotatedPerson>> ParseAnnotationFile(std::string_view text, std::string_view source_name,
                                                         BenchmarkFormat format) {
  const BenchmarkGrid& grid = GridOf(format);
  // Found() prints values with dump(), which recurses once per level.
  OCCMAP_RETURN_IF_ERROR(CheckNesting(text, TextSyntax::kJson, kMaxNestingDepth, source_name));
  json j;
  try {
    j = json::parse(text);
  } catch (const json::parse_error& e) {
    return InvalidInput(fmt::format("{}: expected a JSON list of people, found invalid JSON at byte {}", source_name, e.byte));
  } catch (const json::exception& e) {  // a number out of range (1e999)
    return InvalidInput(fmt::format("{}: expected a JSON list of people, found invalid JSON: {}", source_name, e.what()));
  }
  if (!j.is_array()) return InvalidInput(fmt::format("{}: expected a list of people, found {}", source_name, Found(&j)));
  const int64_t cells = grid.cells_x * grid.cells_y;
  const std::string position_expected = fmt::format("an integer 0..{} (a cell of {}'s {} x {} grid)", cells - 1,
                                                    grid.title, grid.cells_x, grid.cells_y);
  const std::string view_expected = fmt::format("an integer 0..{} ({} has {} views)", grid.views - 1, grid.title, grid.views);
  constexpr int64_t kMin = std::numeric_limits<int64_t>::min(), kMax = std::numeric_limits<int64_t>::max();
  std::vector<AnnotatedPerson> people;
  std::map<int64_t, size_t> index_of_person;
  for (size_t k = 0; k < j.size(); ++k) {
    const json& p = j[k];
    const std::string at = fmt::format("[{}]", k);
    if (!p.is_object()) {
      return FieldError(source_name, at, "an object {\"personID\", \"positionID\", \"views\"}", Found(&p));
    }
    AnnotatedPerson person;
    OCCMAP_RETURN_IF_ERROR(Integer(source_name, p, "personID", at + ".personID", 0, kMax, "an integer >= 0", &person.person_id));
    if (const auto [it, inserted] = index_of_person.emplace(person.person_id, k); !inserted) {
      return FieldError(source_name, at + ".personID", "ids unique within a file",
                        fmt::format("{} again (also [{}])", person.person_id, it->second));
    }
    OCCMAP_RETURN_IF_ERROR(
        Integer(source_name, p, "positionID", at + ".positionID", 0, cells - 1, position_expected, &person.position_id));
    person.position_m = BenchmarkPositionM(format, person.position_id);
    if (const json* views = Get(p, "views"); views != nullptr) {
      if (!views->is_array()) return FieldError(source_name, at + ".views", "a list of boxes", Found(views));
      for (size_t v = 0; v < views->size(); ++v) {
        const json& b = (*views)[v];
        const std::string view_at = fmt::format("{}.views[{}]", at, v);
        if (!b.is_object()) {
          return FieldError(source_name, view_at, "an object {\"viewNum\", \"xmin\", \"ymin\", \"xmax\", \"ymax\"}", Found(&b));
        }
        AnnotatedBox box;
        int64_t view = 0;
        OCCMAP_RETURN_IF_ERROR(Integer(source_name, b, "viewNum", view_at + ".viewNum", 0, grid.views - 1, view_expected, &view));
        box.view = static_cast<int>(view);
        const std::pair<const char*, int64_t*> corners[] = {
            {"xmin", &box.xmin}, {"ymin", &box.ymin}, {"xmax", &box.xmax}, {"ymax", &box.ymax}};
        for (const auto& [key, value] : corners) {
          OCCMAP_RETURN_IF_ERROR(Integer(source_name, b, key, view_at + "." + key, kMin, kMax, "an integer", value));
        }
        if (box.visible() && (box.xmin > box.xmax || box.ymin > box.ymax)) {
          return FieldError(source_name, view_at, "xmin <= xmax and ymin <= ymax (or all -1: not in this view)",
                            fmt::format("x {}..{}, y {}..{}", box.xmin, box.xmax, box.ymin, box.ymax));
        }
        person.views.push_back(box);
      }
    }
    people.push_back(std::move(person));
  }
  return people;
}

Result<BenchmarkAnnotations> ReadBenchmarkAnnotations(const fs::path& folder, std::optional<BenchmarkFormat> format) {
  if (!IsDirectory(folder)) return NotFound(fmt::format("{}: annotation folder not found", folder.string()));
  std::vector<fs::path> paths;
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().extension() == ".json" && IsFile(it->path())) paths.push_back(it->path());
  }
  if (ec) return IoError(fmt::format("{}: cannot list the folder: {}", folder.string(), ec.message()));
  if (paths.empty()) {
    return InvalidInput(fmt::format("{}: expected annotation files named by their frame number (00000005.json), found none",
                                    folder.string()));
  }
  std::sort(paths.begin(), paths.end());
  struct File {
    int64_t number;
    fs::path path;
  };
  std::vector<File> files;
  std::map<size_t, std::string> names_by_digits;  // digits -> an example name
  for (const fs::path& p : paths) {
    const std::string stem = p.stem().string();
    const std::optional<int64_t> number = NumberOfName(stem);
    if (!number) {
      return InvalidInput(fmt::format("{}: file name: expected the frame number in digits (00000005.json), found '{}'",
                                      p.string(), p.filename().string()));
    }
    files.push_back({*number, p});
    names_by_digits.emplace(stem.size(), p.filename().string());
  }
  std::stable_sort(files.begin(), files.end(), [](const File& a, const File& b) { return a.number < b.number; });
  for (size_t k = 1; k < files.size(); ++k) {
    if (files[k].number == files[k - 1].number) {
      return InvalidInput(fmt::format("{}: expected one file per frame, found {} and {} for frame {}", folder.string(),
                                      files[k - 1].path.filename().string(), files[k].path.filename().string(),
                                      files[k].number));
    }
  }
  if (!format) {
    for (BenchmarkFormat f : kFormats) {
      if (names_by_digits.size() == 1 && names_by_digits.begin()->first == static_cast<size_t>(GridOf(f).file_digits)) {
        format = f;
      }
    }
    if (!format) {
      std::string found;
      for (const auto& [digits, name] : names_by_digits) {
        found += fmt::format("{}{} digits ({})", found.empty() ? "" : ", ", digits, name);
      }
      return InvalidInput(fmt::format(
          "{}: format: expected file names of 8 digits (WILDTRACK), 5 digits (MultiviewX) or 6 digits (EPFL terrace), found {}; give the format",
          folder.string(), found));
    }
  }
  BenchmarkAnnotations out;
  out.folder = folder;
  out.format = *format;
  out.frames.reserve(files.size());
  for (const File& f : files) {
    OCCMAP_ASSIGN_OR_RETURN(const std::string text, ReadFileToString(f.path));
    OCCMAP_ASSIGN_OR_RETURN(std::vector<AnnotatedPerson> people, ParseAnnotationFile(text, f.path.string(), *format));
    out.frames.push_back({f.number, std::move(people)});
  }
  return out;
}

Status WriteBenchmarkAnnotations(const fs::path& folder, BenchmarkFormat format, const std::vector<AnnotationFrame>& frames) {
  const BenchmarkGrid& grid = GridOf(format);
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(folder));
  for (const AnnotationFrame& frame : frames) {
    if (frame.number < 0) return InvalidInput(fmt::format("frame number: expected >= 0, found {}", frame.number));
    json people = json::array();
    for (const AnnotatedPerson& p : frame.people) {
      if (p.position_id < 0 || p.position_id >= grid.cells_x * grid.cells_y || p.person_id < 0) {
        return InvalidInput(fmt::format("frame {}: person {}: positionID {} is not a cell of {}'s grid", frame.number,
                                        p.person_id, p.position_id, grid.title));
      }
      json views = json::array();
      for (const AnnotatedBox& b : p.views) {
        views.push_back({{"viewNum", b.view}, {"xmax", b.xmax}, {"xmin", b.xmin}, {"ymax", b.ymax}, {"ymin", b.ymin}});
      }
      people.push_back({{"personID", p.person_id}, {"positionID", p.position_id}, {"views", std::move(views)}});
    }
    const fs::path path = folder / fmt::format("{:0{}d}.json", frame.number, grid.file_digits);
    OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(path, people.dump(4) + "\n"));
  }
  return Status::Ok();
}

std::optional<fs::path> FindAnnotationFolder(const fs::path& dataset) {
  if (IsDirectory(dataset / "annotations_positions")) return dataset / "annotations_positions";
  std::error_code ec;
  for (fs::directory_iterator it(dataset, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path& p = it->path();
    if (p.extension() == ".json" && NumberOfName(p.stem().string()) && IsFile(p)) return dataset;
  }
  return std::nullopt;
}

Status BenchmarkMapping::Validate() const {
  if (first_frame < 0 || first_frame > kMaxNumber) {
    return InvalidInput(fmt::format("first frame: expected an annotation number 0..{}, found {}", kMaxNumber, first_frame));
  }
  if (step_num < 1 || step_den < 1 || step_num > kMaxStepTerm || step_den > kMaxStepTerm) {
    return InvalidInput(fmt::format("frame step: expected a whole number or a fraction P/Q with 1 <= P, Q <= {}, found {}/{}",
                                    kMaxStepTerm, step_num, step_den));
  }
  return Status::Ok();
}

std::optional<int64_t> BenchmarkMapping::RunFrameOf(int64_t number) const {
  const int64_t d = number - first_frame;
  if (d < 0 || (d * step_den) % step_num != 0) return std::nullopt;
  return d * step_den / step_num;
}

std::optional<int64_t> BenchmarkMapping::NumberOf(int64_t frame) const {
  if ((frame * step_num) % step_den != 0) return std::nullopt;
  return first_frame + frame * step_num / step_den;
}

std::string BenchmarkMapping::StepText() const {
  return step_den == 1 ? fmt::format("{}", step_num) : fmt::format("{}/{}", step_num, step_den);
}

Result<std::pair<int64_t, int64_t>> ParseFrameStep(std::string_view text, std::string_view field) {
  const std::string expected = fmt::format("a whole number or a fraction P/Q (5, 1/6) of whole numbers 1..{}", kMaxStepTerm);
  const Result<std::pair<int64_t, int64_t>> step = ParseIntegerPair(text, '/', field, expected, 1, kMaxStepTerm, 1);
  if (!step.ok()) return InvalidInput(fmt::format("{}: expected {}, found '{}'", field, expected, text));
  return step;
}

Result<std::pair<int64_t, int64_t>> ParseAnnotationRange(std::string_view text, std::string_view field) {
  const std::string expected = "FIRST:LAST, two annotation numbers 0..999999999999 with FIRST <= LAST (1800:1995)";
  OCCMAP_ASSIGN_OR_RETURN(const auto range,
                          ParseIntegerPair(text, ':', field, expected, 0, kMaxNumber));
  if (range.first > range.second) return InvalidInput(fmt::format("{}: expected {}, found '{}'", field, expected, text));
  return range;
}

Status BenchmarkEvalOptions::Validate() const {
  BenchmarkMapping mapping{.first_frame = first_frame};
  if (frame_step) std::tie(mapping.step_num, mapping.step_den) = *frame_step;
  OCCMAP_RETURN_IF_ERROR(mapping.Validate());
  if (annotation_range && !(annotation_range->first >= 0 && annotation_range->first <= annotation_range->second &&
                            annotation_range->second <= kMaxNumber)) {
    return InvalidInput(fmt::format("annotation range: expected FIRST:LAST with 0 <= FIRST <= LAST <= 999999999999, found {}:{}",
                                    annotation_range->first, annotation_range->second));
  }
  return Status::Ok();
}

std::vector<GroundTruthFrame> AnnotationsToGroundTruth(const BenchmarkAnnotations& annotations,
                                                       const BenchmarkMapping& mapping, int64_t range_first,
                                                       int64_t range_last, AnnotationSummary& summary) {
  OCCMAP_CHECK(mapping.Validate().ok(), "invalid mapping");
  summary.format = std::string(BenchmarkFormatName(annotations.format));
  summary.folder = annotations.folder.string();
  summary.first_frame = mapping.first_frame;
  summary.step_num = mapping.step_num;
  summary.step_den = mapping.step_den;
  summary.range_first = range_first;
  summary.range_last = range_last;
  summary.files = static_cast<int64_t>(annotations.frames.size());
  summary.first_file = annotations.frames.empty() ? 0 : annotations.frames.front().number;
  summary.last_file = annotations.frames.empty() ? 0 : annotations.frames.back().number;
  summary.files_evaluated = summary.people_evaluated = summary.files_outside_range = summary.files_between_frames = 0;
  std::vector<GroundTruthFrame> gt;
  for (const AnnotationFrame& a : annotations.frames) {
    if (a.number < range_first || a.number > range_last) {
      ++summary.files_outside_range;
      continue;
    }
    const std::optional<int64_t> frame = mapping.RunFrameOf(a.number);
    if (!frame) {
      ++summary.files_between_frames;
      continue;
    }
    GroundTruthFrame g;
    g.frame = *frame;
    g.time_s = 0;  // not used by the evaluation; the datasets give no clock
    for (const AnnotatedPerson& p : a.people) {
      g.objects.push_back({.id = p.person_id,
                           .object_class = "person",
                           .x_m = p.position_m.x(),
                           .y_m = p.position_m.y(),
                           .footprint_m = {}});
    }
    ++summary.files_evaluated;
    summary.people_evaluated += static_cast<int64_t>(a.people.size());
    gt.push_back(std::move(g));
  }
  return gt;
}

Result<EvaluationReport> EvaluateRunOnBenchmark(const fs::path& dataset, const fs::path& run_dir,
                                                const BenchmarkEvalOptions& benchmark, const EvalOptions& options) {
  Context serial(1);  // the calling thread only: no worker threads
  return EvaluateRunOnBenchmark(dataset, run_dir, benchmark, options, serial);
}

Result<EvaluationReport> EvaluateRunOnBenchmark(const fs::path& dataset, const fs::path& run_dir,
                                                const BenchmarkEvalOptions& benchmark, const EvalOptions& options,
                                                Context& ctx) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  OCCMAP_RETURN_IF_ERROR(benchmark.Validate());
  const std::optional<fs::path> folder = FindAnnotationFolder(dataset);
  if (!folder) {
    return NotFound(fmt::format("{}: no annotations: expected an annotations_positions folder or files named by their "
                                "frame number (00000005.json)",
                                dataset.string()));
  }
  OCCMAP_ASSIGN_OR_RETURN(const BenchmarkAnnotations annotations, ReadBenchmarkAnnotations(*folder, benchmark.format));
  BenchmarkMapping mapping{.first_frame = benchmark.first_frame,
                           .step_num = GridOf(annotations.format).default_frame_step,
                           .step_den = 1};
  if (benchmark.frame_step) std::tie(mapping.step_num, mapping.step_den) = *benchmark.frame_step;

  // The annotation numbers evaluated: given, or those of the run's first to last frame.
  int64_t range_first = 0, range_last = -1;
  std::optional<std::pair<int64_t, int64_t>> span;
  if (benchmark.annotation_range) {
    std::tie(range_first, range_last) = *benchmark.annotation_range;
  } else {
    OCCMAP_ASSIGN_OR_RETURN(span, RunFrameSpan(run_dir, folder->string()));
    if (span) {
      // first + ceil(first frame x step) .. first + floor(last frame x step)
      range_first = mapping.first_frame + (span->first * mapping.step_num + mapping.step_den - 1) / mapping.step_den;
      range_last = mapping.first_frame + span->second * mapping.step_num / mapping.step_den;
    }
  }
  AnnotationSummary summary;
  summary.range_given = benchmark.annotation_range.has_value();
  std::vector<GroundTruthFrame> gt = AnnotationsToGroundTruth(annotations, mapping, range_first, range_last, summary);
  const std::string mapping_text =
      fmt::format("annotation number = {} + {} x run frame", mapping.first_frame, mapping.StepText());
  if (gt.empty()) {
    const std::string files_text = fmt::format("{} has {} files numbered {}..{}", folder->string(), summary.files,
                                               summary.first_file, summary.last_file);
    if (benchmark.annotation_range) {
      return InvalidInput(fmt::format("annotation range: expected annotated frames on run frames ({}) in {}:{}, found "
                                      "none; {}",
                                      mapping_text, range_first, range_last, files_text));
    }
    if (!span) return InvalidInput(fmt::format("{}: expected frames to evaluate, found an empty run", run_dir.string()));
    return InvalidInput(fmt::format("{}: expected annotated frames among the run's frames {}..{} (numbers {}..{} with {}), "
                                    "found none; {}: check the frame step and first frame",
                                    run_dir.string(), span->first, span->second, range_first, range_last, mapping_text,
                                    files_text));
  }
  OCCMAP_ASSIGN_OR_RETURN(EvaluationReport report, EvaluateRunAgainst(gt, folder->string(), run_dir, options, ctx));
  if (!GridOf(annotations.format).identities && report.tracking) {
    // Identity measures against ids that name a person within one file only would be noise.
    report.tracking.reset();
    report.notes.push_back(fmt::format("tracking not evaluated: the {} annotations' personID is an index within each "
                                       "file, not a person across frames",
                                       GridOf(annotations.format).title));
  }
  if (summary.files_outside_range > 0) {
    report.notes.push_back(fmt::format("annotations: {} of {} files are outside the numbers evaluated, {}..{} ({}); left out",
                                       summary.files_outside_range, summary.files, range_first, range_last,
                                       summary.range_given ? "the range given" : "the run's frames"));
  }
  if (summary.files_between_frames > 0) {
    report.notes.push_back(fmt::format("annotations: {} files in {}..{} fall on no run frame ({}); left out",
                                       summary.files_between_frames, range_first, range_last, mapping_text));
  }
  report.annotations = std::move(summary);
  return report;
}

}  // namespace occmap
