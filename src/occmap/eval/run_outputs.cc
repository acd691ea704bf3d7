#include "occmap/eval/run_outputs.h"

#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>
#include <system_error>

#include "occmap/util/file_util.h"
#include "occmap/util/text_guard.h"

namespace occmap {
namespace {

using nlohmann::json;

// One line of a JSON-lines file: typed field access with located messages
// "<source>:<line>: <field>: expected <what>, found <value>".
class Line {
 public:
  Line(std::string_view source, int line_no) : source_(source), line_no_(line_no) {}

  Status Error(std::string_view field, std::string_view expected, std::string_view found) const {
    if (field.empty()) return InvalidInput(fmt::format("{}:{}: expected {}, found {}", source_, line_no_, expected, found));
    return InvalidInput(fmt::format("{}:{}: {}: expected {}, found {}", source_, line_no_, field, expected, found));
  }

  // How a value (or its absence) reads in a message: its JSON text, shortened.
  static std::string Found(const json* value) {
    if (value == nullptr) return "nothing";
    std::string text = value->dump();
    if (text.size() > 40) text = text.substr(0, 37) + "...";
    return text;
  }

  static const json* Get(const json& object, const char* key) {
    const auto it = object.find(key);
    return it == object.end() ? nullptr : &*it;
  }

  Status Integer(const json& object, const char* key, const std::string& field, int64_t min_value,
                 std::string_view expected, int64_t* out) const {
    const json* v = Get(object, key);
    bool ok = v != nullptr && v->is_number_integer();
    if (ok && v->is_number_unsigned()) ok = v->get<uint64_t>() <= static_cast<uint64_t>(std::numeric_limits<int64_t>::max());
    if (ok) {
      *out = v->get<int64_t>();
      ok = *out >= min_value;
    }
    return ok ? Status::Ok() : Error(field, expected, Found(v));
  }

  Status Number(const json& object, const char* key, const std::string& field, double min_value,
                std::string_view expected, double* out) const {
    const json* v = Get(object, key);
    if (v == nullptr || !v->is_number()) return Error(field, expected, Found(v));
    *out = v->get<double>();
    if (!std::isfinite(*out) || *out < min_value) return Error(field, expected, Found(v));
    return Status::Ok();
  }

  // The line's object, its frame (> previous_frame when there is one), time and entry list.
  Status Frame(const json& j, const int64_t* previous_frame, const char* list_key, int64_t* frame, double* time_s,
               const json** list) const {
    if (!j.is_object()) return Error("", "a JSON object", Found(&j));
    OCCMAP_RETURN_IF_ERROR(Integer(j, "frame", "frame", 0, "an integer >= 0", frame));
    if (previous_frame != nullptr && *frame <= *previous_frame) {
      return Error("frame", fmt::format("a frame after {} (frames increase line by line)", *previous_frame),
                   std::to_string(*frame));
    }
    OCCMAP_RETURN_IF_ERROR(Number(j, "time_s", "time_s", -std::numeric_limits<double>::infinity(), "a number", time_s));
    *list = Get(j, list_key);
    if (*list == nullptr || !(*list)->is_array()) return Error(list_key, "a list", Found(*list));
    return Status::Ok();
  }

 private:
  std::string_view source_;
  int line_no_;
};

// Calls parse_line(line, json) for each non-blank line of text.
template <typename ParseLine>
Status ForEachJsonLine(std::string_view text, std::string_view source, const ParseLine& parse_line) {
  int line_no = 0;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line_text = text.substr(start, end - start);
    start = end + 1;
    ++line_no;
    if (line_text.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    const Line line(source, line_no);
    // Found() prints values with dump(), which recurses once per level.
    if (NestingDepth(line_text, TextSyntax::kJson) > kMaxNestingDepth) {
      return line.Error("", "a JSON object", fmt::format("nesting deeper than {} levels", kMaxNestingDepth));
    }
    json j;
    try {
      j = json::parse(line_text);
    } catch (const json::parse_error& e) {
      return line.Error("", "a JSON object", fmt::format("invalid JSON at column {}", e.byte));
    } catch (const json::exception& e) {  // a number out of range (1e999)
      return line.Error("", "a JSON object", fmt::format("invalid JSON: {}", e.what()));
    }
    OCCMAP_RETURN_IF_ERROR(parse_line(line, j));
  }
  return Status::Ok();
}

}  // namespace

Result<std::vector<DetectionFrame>> ParseDetections(std::string_view text, std::string_view source_name) {
  std::vector<DetectionFrame> frames;
  const Status status = ForEachJsonLine(text, source_name, [&](const Line& line, const json& j) -> Status {
    DetectionFrame f;
    const json* blobs = nullptr;
    OCCMAP_RETURN_IF_ERROR(line.Frame(j, frames.empty() ? nullptr : &frames.back().frame, "blobs", &f.frame, &f.time_s, &blobs));
    for (size_t k = 0; k < blobs->size(); ++k) {
      const json& b = (*blobs)[k];
      const std::string at = fmt::format("blobs[{}]", k);
      if (!b.is_object()) return line.Error(at, "an object {\"x_m\", \"y_m\", ...}", Line::Found(&b));
      DetectedBlob blob;
      OCCMAP_RETURN_IF_ERROR(line.Number(b, "x_m", at + ".x_m", -std::numeric_limits<double>::infinity(), "a number", &blob.x_m));
      OCCMAP_RETURN_IF_ERROR(line.Number(b, "y_m", at + ".y_m", -std::numeric_limits<double>::infinity(), "a number", &blob.y_m));
      if (b.contains("area_m2")) OCCMAP_RETURN_IF_ERROR(line.Number(b, "area_m2", at + ".area_m2", 0.0, "a number >= 0", &blob.area_m2));
      if (b.contains("cells")) OCCMAP_RETURN_IF_ERROR(line.Integer(b, "cells", at + ".cells", 0, "an integer >= 0", &blob.cells));
      f.blobs.push_back(blob);
    }
    frames.push_back(std::move(f));
    return Status::Ok();
  });
  if (!status.ok()) return status;
  return frames;
}

Result<std::vector<TrackFrame>> ParseTracks(std::string_view text, std::string_view source_name) {
  std::vector<TrackFrame> frames;
  const double kAny = -std::numeric_limits<double>::infinity();
  const Status status = ForEachJsonLine(text, source_name, [&](const Line& line, const json& j) -> Status {
    TrackFrame f;
    const json* tracks = nullptr;
    OCCMAP_RETURN_IF_ERROR(line.Frame(j, frames.empty() ? nullptr : &frames.back().frame, "tracks", &f.frame, &f.time_s, &tracks));
    std::set<int64_t> ids;
    for (size_t k = 0; k < tracks->size(); ++k) {
      const json& t = (*tracks)[k];
      const std::string at = fmt::format("tracks[{}]", k);
      if (!t.is_object()) return line.Error(at, "an object {\"id\", \"x_m\", \"y_m\", ...}", Line::Found(&t));
      TrackRecord r;
      OCCMAP_RETURN_IF_ERROR(line.Integer(t, "id", at + ".id", std::numeric_limits<int64_t>::min(), "an integer", &r.id));
      if (!ids.insert(r.id).second) {
        return line.Error(at + ".id", "an id not used by another track of the frame", std::to_string(r.id) + " again");
      }
      OCCMAP_RETURN_IF_ERROR(line.Number(t, "x_m", at + ".x_m", kAny, "a number", &r.x_m));
      OCCMAP_RETURN_IF_ERROR(line.Number(t, "y_m", at + ".y_m", kAny, "a number", &r.y_m));
      if (t.contains("vx_mps")) OCCMAP_RETURN_IF_ERROR(line.Number(t, "vx_mps", at + ".vx_mps", kAny, "a number", &r.vx_mps));
      if (t.contains("vy_mps")) OCCMAP_RETURN_IF_ERROR(line.Number(t, "vy_mps", at + ".vy_mps", kAny, "a number", &r.vy_mps));
      if (t.contains("class")) {
        const json& c = t["class"];
        if (!c.is_string()) return line.Error(at + ".class", "a text", Line::Found(&c));
        r.object_class = c.get<std::string>();
      }
      f.tracks.push_back(std::move(r));
    }
    frames.push_back(std::move(f));
    return Status::Ok();
  });
  if (!status.ok()) return status;
  return frames;
}

Result<std::vector<DetectionFrame>> ReadDetections(const std::filesystem::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path));
  return ParseDetections(text, path.string());
}

Result<std::vector<TrackFrame>> ReadTracks(const std::filesystem::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path));
  return ParseTracks(text, path.string());
}

Result<std::vector<std::pair<int64_t, std::filesystem::path>>> ListFramePngs(const std::filesystem::path& dir,
                                                                              std::string_view what) {
  namespace fs = std::filesystem;
  std::vector<std::pair<int64_t, fs::path>> files;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path& p = it->path();
    std::error_code file_ec;
    if (p.extension() != ".png" || !fs::is_regular_file(p, file_ec)) continue;
    const std::string stem = p.stem().string();
    int64_t frame = 0;
    const auto [ptr, err] = std::from_chars(stem.data(), stem.data() + stem.size(), frame);
    if (stem.empty() || err != std::errc() || ptr != stem.data() + stem.size() || frame < 0) continue;
    files.emplace_back(frame, p);
  }
  if (ec) return InvalidInput(fmt::format("{}: cannot list the folder: {}", dir.string(), ec.message()));
  std::sort(files.begin(), files.end());
  for (size_t k = 1; k < files.size(); ++k) {
    if (files[k].first == files[k - 1].first) {
      return InvalidInput(fmt::format("{}: expected one {} per frame, found {} and {} for frame {}", dir.string(), what,
                                      files[k - 1].second.filename().string(), files[k].second.filename().string(),
                                      files[k].first));
    }
  }
  return files;
}

}  // namespace occmap
