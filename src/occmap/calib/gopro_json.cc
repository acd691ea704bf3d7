#include "occmap/calib/gopro_json.h"

#include <fmt/core.h>

#include <cmath>
#include <set>
#include <string>
#include <nlohmann/json.hpp>
#include <vector>

#include "occmap/calib/units.h"
#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"
#include "occmap/util/text_guard.h"

namespace occmap {
namespace fs = std::filesystem;
using nlohmann::json;
namespace {

Result<json> ParseJson(const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
  // dump() and copies recurse once per level: a 100,000-deep array would overflow the stack.
  OCCMAP_RETURN_IF_ERROR(CheckNesting(text, TextSyntax::kJson, kMaxNestingDepth, fmt::format("'{}'", path.string())));
  try {
    // nlohmann-json keeps the last of a repeated key: refused instead, as the site file does.
    std::vector<std::set<std::string>> keys;  // of each open object
    std::string duplicate;
    const json::parser_callback_t note_keys = [&](int, json::parse_event_t event, json& parsed) {
      if (event == json::parse_event_t::object_start) {
        keys.emplace_back();
      } else if (event == json::parse_event_t::object_end && !keys.empty()) {
        keys.pop_back();
      } else if (event == json::parse_event_t::key && !keys.empty() && duplicate.empty() &&
                 !keys.back().insert(parsed.get<std::string>()).second) {
        duplicate = parsed.get<std::string>();
      }
      return true;
    };
    json j = json::parse(text, note_keys);
    if (!duplicate.empty()) {
      return InvalidInput(fmt::format("'{}': duplicate key '{}' (keys must be unique)", path.string(), Excerpt(duplicate)));
    }
    if (!j.is_object()) return InvalidInput(fmt::format("'{}': expected a JSON object", path.string()));
    return j;
  } catch (const json::parse_error& e) {
    return InvalidInput(fmt::format("'{}': JSON syntax error at byte {}: {}", path.string(), e.byte, e.what()));
  } catch (const json::exception& e) {  // a number out of range (1e999): was an abort
    return InvalidInput(fmt::format("'{}': JSON syntax error: {}", path.string(), e.what()));
  }
}

// A matrix of `rows` x `cols` finite numbers (rows = 1 also accepts a flat list).
Result<std::vector<double>> Matrix(const json& j, const fs::path& path, const char* key, int rows, int cols) {
  const std::string where = fmt::format("'{}': {}", path.string(), key);
  if (!j.contains(key)) return InvalidInput(fmt::format("{}: missing", where));
  const json& m = j.at(key);
  std::vector<double> values;
  auto add_row = [&](const json& row) -> Status {
    if (!row.is_array()) return InvalidInput(fmt::format("{}: expected a list of numbers", where));
    for (const auto& v : row) {
      if (!v.is_number()) return InvalidInput(fmt::format("{}: expected numbers, found {}", where, Excerpt(v.dump())));
      const double d = v.get<double>();
      if (!std::isfinite(d)) return InvalidInput(fmt::format("{}: expected finite numbers, found {}", where, d));
      values.push_back(d);
    }
    return Status::Ok();
  };
  if (!m.is_array()) return InvalidInput(fmt::format("{}: expected a {}x{} matrix, found {}", where, rows, cols, Excerpt(m.dump())));
  if (!m.empty() && m.front().is_array()) {
    if (static_cast<int>(m.size()) != rows) {
      return InvalidInput(fmt::format("{}: expected a {}x{} matrix, found {} rows", where, rows, cols, m.size()));
    }
    for (const auto& row : m) {
      if (!row.is_array() || static_cast<int>(row.size()) != cols) {
        return InvalidInput(fmt::format("{}: expected a {}x{} matrix, found a row of {}", where, rows, cols,
                                        row.is_array() ? std::to_string(row.size()) : Excerpt(row.dump())));
      }
      OCCMAP_RETURN_IF_ERROR(add_row(row));
    }
  } else {
    if (static_cast<int>(m.size()) != rows * cols) {
      return InvalidInput(fmt::format("{}: expected {} numbers, found {}", where, rows * cols, m.size()));
    }
    OCCMAP_RETURN_IF_ERROR(add_row(m));
  }
  return values;
}

}  // namespace

Result<PinholeParameters> ReadGoProCalibration(const fs::path& intrinsic_path, const fs::path& extrinsic_path,
                                               std::optional<double> metres_per_unit) {
  OCCMAP_ASSIGN_OR_RETURN(json intr, ParseJson(intrinsic_path));
  OCCMAP_ASSIGN_OR_RETURN(json extr, ParseJson(extrinsic_path));
  PinholeParameters p;
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> k, Matrix(intr, intrinsic_path, "K", 3, 3));
  if (k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1) {
    return InvalidInput(fmt::format("'{}': K: expected [fx s cx; 0 fy cy; 0 0 1]", intrinsic_path.string()));
  }
  p.fx_px = k[0];
  p.skew_px = k[1];
  p.cx_px = k[2];
  p.fy_px = k[4];
  p.cy_px = k[5];
  if (intr.contains("distCoeffs")) {
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> d, Matrix(intr, intrinsic_path, "distCoeffs", 1, 5));
    for (int i = 0; i < 5; ++i) p.distortion[i] = d[i];
  }
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> shape, Matrix(intr, intrinsic_path, "image_shape", 1, 2));
  // Bounded as the other readers' sizes (1..65535): an int past that is undefined behaviour.
  if (shape[0] != std::floor(shape[0]) || shape[1] != std::floor(shape[1]) || shape[0] <= 0 || shape[1] <= 0 ||
      shape[0] > 65535 || shape[1] > 65535) {
    return InvalidInput(fmt::format("'{}': image_shape: expected whole numbers 1..65535 [height, width], found [{}, {}]",
                                    intrinsic_path.string(), shape[0], shape[1]));
  }
  p.image_size = {static_cast<int>(shape[1]), static_cast<int>(shape[0])};

  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> r, Matrix(extr, extrinsic_path, "R", 3, 3));
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> t, Matrix(extr, extrinsic_path, "t", 1, 3));
  double m_per_unit = 0;
  if (extr.contains("unit")) {
    if (!extr["unit"].is_string()) {
      return InvalidInput(fmt::format("'{}': unit: expected a text such as \"cm\"", extrinsic_path.string()));
    }
    auto unit = MetresPerUnit(extr["unit"].get<std::string>());
    if (!unit.ok()) return unit.status().WithContext(fmt::format("'{}'", extrinsic_path.string()));
    m_per_unit = *unit;
    if (metres_per_unit && std::abs(*metres_per_unit - m_per_unit) > 1e-12) {
      return InvalidInput(fmt::format("'{}': unit: the file says '{}' but the site declares {} m per unit",
                                      extrinsic_path.string(), extr["unit"].get<std::string>(), *metres_per_unit));
    }
  } else if (metres_per_unit) {
    m_per_unit = *metres_per_unit;
  } else {
    return InvalidInput(fmt::format("'{}': no `unit` field; declare the calibration's unit in the site file",
                                    extrinsic_path.string()));
  }
  p.cam_from_world_rotation << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
  p.cam_from_world_translation_m = Eigen::Vector3d(t[0], t[1], t[2]) * m_per_unit;
  // Each error names the file it comes from: R and t are the extrinsic file's.
  if (Status s = p.Validate(); !s.ok()) {
    const bool extrinsic = s.message().starts_with("extrinsics") || s.message().starts_with("rotation");
    return s.WithContext(extrinsic ? fmt::format("'{}': R/t", extrinsic_path.string())
                                   : fmt::format("'{}'", intrinsic_path.string()));
  }
  return p;
}

Status WriteGoProCalibration(const PinholeParameters& p, const fs::path& intrinsic_path,
                             const fs::path& extrinsic_path) {
  json intr;
  intr["K"] = {{p.fx_px, p.skew_px, p.cx_px}, {0.0, p.fy_px, p.cy_px}, {0.0, 0.0, 1.0}};
  intr["distCoeffs"] = {std::vector<double>(p.distortion.begin(), p.distortion.end())};
  intr["image_shape"] = {p.image_size.height, p.image_size.width};
  json extr;
  extr["unit"] = "m";
  const auto& r = p.cam_from_world_rotation;
  extr["R"] = {{r(0, 0), r(0, 1), r(0, 2)}, {r(1, 0), r(1, 1), r(1, 2)}, {r(2, 0), r(2, 1), r(2, 2)}};
  const auto& t = p.cam_from_world_translation_m;
  extr["t"] = {t.x(), t.y(), t.z()};
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(intrinsic_path, intr.dump(2)));
  return WriteFileAtomic(extrinsic_path, extr.dump(2));
}

}  // namespace occmap
