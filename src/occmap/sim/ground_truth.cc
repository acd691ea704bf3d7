#include "occmap/sim/ground_truth.h"

#include <fmt/core.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "occmap/util/file_util.h"
#include "occmap/util/text_guard.h"

namespace occmap {
namespace fs = std::filesystem;
using nlohmann::json;

std::string GroundTruthLine(const GroundTruthFrame& f) {
  json objects = json::array();
  for (const auto& o : f.objects) {
    json fp = json::array();
    for (const auto& p : o.footprint_m) fp.push_back({std::round(p.x() * 1e5) / 1e5, std::round(p.y() * 1e5) / 1e5});
    objects.push_back({{"id", o.id},
                       {"class", o.object_class},
                       {"x_m", std::round(o.x_m * 1e5) / 1e5},
                       {"y_m", std::round(o.y_m * 1e5) / 1e5},
                       {"footprint_m", fp}});
  }
  return json{{"frame", f.frame}, {"time_s", f.time_s}, {"objects", objects}}.dump();
}

Status WriteGroundTruth(const fs::path& path, const std::vector<GroundTruthFrame>& frames) {
  std::string text;
  for (const auto& f : frames) text += GroundTruthLine(f) + "\n";
  return WriteFileAtomic(path, text);
}

Result<std::vector<GroundTruthFrame>> ReadGroundTruth(const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path));
  std::vector<GroundTruthFrame> frames;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  auto bad = [&](const std::string& what) {
    return InvalidInput(fmt::format("{}:{}: {}", path.string(), line_no, what));
  };
  auto number = [&](const json& j, const char* key, double* out) -> Status {
    if (!j.contains(key) || !j[key].is_number()) return bad(fmt::format("{}: expected a number", key));
    *out = j[key].get<double>();
    if (!std::isfinite(*out)) return bad(fmt::format("{}: expected a finite number", key));
    return Status::Ok();
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (NestingDepth(line, TextSyntax::kJson) > kMaxNestingDepth) {
      return bad(fmt::format("nesting deeper than {} levels", kMaxNestingDepth));
    }
    json j;
    try {
      j = json::parse(line);
    } catch (const json::exception& e) {  // syntax, and numbers out of range (1e999)
      return bad(fmt::format("JSON syntax error: {}", e.what()));
    }
    if (!j.is_object()) return bad("expected a JSON object per line");
    GroundTruthFrame f;
    if (!j.contains("frame") || !j["frame"].is_number_integer()) return bad("frame: expected an integer");
    f.frame = j["frame"].get<int64_t>();
    OCCMAP_RETURN_IF_ERROR(number(j, "time_s", &f.time_s));
    if (!j.contains("objects") || !j["objects"].is_array()) return bad("objects: expected a list");
    for (const auto& o : j["objects"]) {
      GroundTruthObject obj;
      if (!o.is_object() || !o.contains("id") || !o["id"].is_number_integer()) return bad("objects[].id: expected an integer");
      obj.id = o["id"].get<int64_t>();
      if (o.contains("class")) {
        if (!o["class"].is_string()) return bad("objects[].class: expected a text");
        obj.object_class = o["class"].get<std::string>();
      }
      OCCMAP_RETURN_IF_ERROR(number(o, "x_m", &obj.x_m));
      OCCMAP_RETURN_IF_ERROR(number(o, "y_m", &obj.y_m));
      if (o.contains("footprint_m")) {
        if (!o["footprint_m"].is_array()) return bad("objects[].footprint_m: expected a list of [x, y]");
        for (const auto& p : o["footprint_m"]) {
          if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number()) {
            return bad("objects[].footprint_m: expected [x, y] pairs");
          }
          obj.footprint_m.emplace_back(p[0].get<double>(), p[1].get<double>());
        }
      }
      f.objects.push_back(std::move(obj));
    }
    if (!frames.empty() && f.frame <= frames.back().frame) {
      return bad(fmt::format("frame {}: expected frames in increasing order (previous {})", f.frame, frames.back().frame));
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

}  // namespace occmap
