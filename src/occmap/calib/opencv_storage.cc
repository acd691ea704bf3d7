#include "occmap/calib/opencv_storage.h"

#include <fmt/core.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <sstream>
#include <vector>

#include "occmap/calib/units.h"
#include "occmap/geometry/rotation.h"
#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"
#include "occmap/util/text_guard.h"
#include "occmap/util/yaml_util.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

// OpenCV 4.6's XML parser dereferences a null pointer when an attribute's '=' is followed by
// anything but a quote (`<?xml version=` at the end of a file: a SEGV found by
// fuzz/opencv_calibration_fuzzer): such text is refused before it gets there.
Status CheckXmlAttributes(std::string_view text, const fs::path& path) {
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos || text[first] != '<') return Status::Ok();  // YAML or JSON
  bool in_tag = false;
  for (size_t i = first; i < text.size(); ++i) {
    if (!in_tag) {
      if (text.substr(i, 4) == "<!--") {
        const size_t end = text.find("-->", i + 4);
        if (end == std::string_view::npos) break;
        i = end + 2;
      } else if (text[i] == '<') {
        in_tag = true;
      }
      continue;
    }
    if (text[i] == '>') {
      in_tag = false;
    } else if (text[i] == '"' || text[i] == '\'') {
      const size_t end = text.find(text[i], i + 1);
      if (end == std::string_view::npos) break;
      i = end;
    } else if (text[i] == '=') {
      const size_t next = text.find_first_not_of(" \t\r\n", i + 1);
      if (next == std::string_view::npos || (text[next] != '"' && text[next] != '\'')) {
        const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(i), '\n');
        return InvalidInput(fmt::format("'{}':{}: expected a quoted attribute value after '=', found {}",
                                        path.string(), line,
                                        next == std::string_view::npos ? std::string("the end of the file")
                                                                       : fmt::format("'{}'", text[next])));
      }
    }
  }
  return Status::Ok();
}

// OpenCV keeps both values of a repeated key and reads the first: a file with two camera_matrix
// would be half ignored, so a repeated key is refused (as the site file's are).
Status CheckUniqueKeys(const cv::FileNode& node, const fs::path& path, const std::string& where, int depth) {
  if (depth > kMaxNestingDepth) return Status::Ok();  // CheckNesting bounds it first
  if (node.isMap()) {
    std::vector<std::string> keys = node.keys();
    std::vector<std::string> sorted = keys;
    std::sort(sorted.begin(), sorted.end());
    if (auto dup = std::adjacent_find(sorted.begin(), sorted.end()); dup != sorted.end()) {
      return InvalidInput(fmt::format("'{}': {}duplicate key '{}' (keys must be unique)", path.string(),
                                      where.empty() ? "" : where + ": ", Excerpt(*dup)));
    }
    for (const std::string& k : keys) {
      OCCMAP_RETURN_IF_ERROR(CheckUniqueKeys(node[k], path, where.empty() ? k : where + "." + k, depth + 1));
    }
  } else if (node.isSeq()) {
    size_t i = 0;
    for (const cv::FileNode& e : node) {  // an iterator: node[i] walks from the start each time
      if (e.isMap() || e.isSeq()) OCCMAP_RETURN_IF_ERROR(CheckUniqueKeys(e, path, fmt::format("{}[{}]", where, i), depth + 1));
      ++i;
    }
  }
  return Status::Ok();
}

Result<cv::FileStorage> Open(const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
  if (text.find_first_not_of(" \t\r\n") == std::string::npos) {
    return InvalidInput(fmt::format("'{}': empty file, expected an OpenCV FileStorage calibration",
                                    path.string()));
  }
  // OpenCV 4.6's parser reads past a NUL byte (a SEGV found by fuzz/opencv_calibration_fuzzer).
  if (const size_t nul = text.find('\0'); nul != std::string::npos) {
    return InvalidInput(fmt::format("'{}': expected an OpenCV FileStorage text file, found a NUL byte at offset {}",
                                    path.string(), nul));
  }
  OCCMAP_RETURN_IF_ERROR(CheckXmlAttributes(text, path));
  // OpenCV's parsers recurse once per level: an XML file 30,000 deep (210 KB) overflows the stack.
  const char first = text[text.find_first_not_of(" \t\r\n")];
  const TextSyntax syntax = first == '<' ? TextSyntax::kXml : first == '{' ? TextSyntax::kJson : TextSyntax::kYaml;
  OCCMAP_RETURN_IF_ERROR(CheckNesting(text, syntax, kMaxNestingDepth, fmt::format("'{}'", path.string())));
  try {
    cv::FileStorage storage(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
    if (!storage.isOpened()) {
      return InvalidInput(fmt::format("'{}': not an OpenCV FileStorage file (XML/YAML/JSON)", path.string()));
    }
    OCCMAP_RETURN_IF_ERROR(CheckUniqueKeys(storage.root(), path, "", 0));
    return storage;
  } catch (const cv::Exception& e) {
    return InvalidInput(fmt::format("'{}': cannot parse OpenCV FileStorage: {}", path.string(), e.err));
  }
}

// Numbers of a node: an opencv-matrix, a sequence, a single number, or plain text holding
// space-separated numbers (WILDTRACK writes rvec/tvec that way).
Result<std::vector<double>> Numbers(const cv::FileNode& node, const fs::path& path,
                                    std::string_view name, int* rows = nullptr, int* cols = nullptr) {
  auto where = [&] { return fmt::format("'{}': {}", path.string(), name); };
  if (node.empty() || node.isNone()) return InvalidInput(fmt::format("{}: missing", where()));
  std::vector<double> values;
  try {
    if (node.isMap()) {
      // An opencv-matrix read here, not by OpenCV: a wrong count or a 'nan' gets its own message
      // instead of OpenCV's internal assertion text, and rows or cols that are not integers never
      // reach cv::Mat::create (OpenCV 4.6 took `<rows>[3</rows>` for 2^31 + 2 rows and asked for
      // 51 GB: found by fuzz/opencv_calibration_fuzzer).
      for (const char* key : {"rows", "cols", "data"}) {
        const cv::FileNode field = node[key];
        if (field.empty() || field.isNone()) {
          return InvalidInput(fmt::format("{}: expected an opencv-matrix (rows, cols, data), found no {}", where(), key));
        }
        if (std::string_view(key) != "data" && !field.isInt()) {
          return InvalidInput(fmt::format("{}: {}: expected an integer, found {}", where(), key,
                                          field.isString() ? fmt::format("'{}'", Excerpt(static_cast<std::string>(field)))
                                          : field.isReal() ? fmt::format("{}", static_cast<double>(field))
                                                           : std::string("a list or a map")));
        }
      }
      const int r = static_cast<int>(node["rows"]), c = static_cast<int>(node["cols"]);
      if (r < 0 || c < 0 || r > 10000 || c > 10000) {
        return InvalidInput(fmt::format("{}: expected rows and cols in 0..10000, found {}x{}", where(), r, c));
      }
      const cv::FileNode data = node["data"];
      auto add = [&](const cv::FileNode& e) -> Status {
        if (e.isReal() || e.isInt()) {
          values.push_back(static_cast<double>(e));
        } else if (e.isString()) {
          std::istringstream in(static_cast<std::string>(e));
          std::string token;
          while (in >> token) {
            auto v = ParseFiniteDouble(token);
            if (!v) return InvalidInput(fmt::format("{}: data: expected a finite number, found '{}'", where(), Excerpt(token)));
            values.push_back(*v);
          }
        } else {
          return InvalidInput(fmt::format("{}: data: expected numbers, found a non-number element", where()));
        }
        return Status::Ok();
      };
      if (data.isSeq()) {
        for (const auto& e : data) OCCMAP_RETURN_IF_ERROR(add(e));
      } else {
        OCCMAP_RETURN_IF_ERROR(add(data));
      }
      if (values.size() != static_cast<size_t>(r) * static_cast<size_t>(c)) {
        return InvalidInput(fmt::format("{}: expected rows x cols = {} x {} = {} numbers in data, found {}", where(), r,
                                        c, static_cast<size_t>(r) * static_cast<size_t>(c), values.size()));
      }
      if (rows) *rows = r;
      if (cols) *cols = c;
    } else if (node.isSeq()) {
      for (const auto& e : node) {
        if (e.isString()) {
          return InvalidInput(fmt::format("{}: expected a finite number, found '{}'", where(),
                                          Excerpt(static_cast<std::string>(e))));
        }
        if (!e.isReal() && !e.isInt()) {
          return InvalidInput(fmt::format("{}: expected numbers, found a non-number element", where()));
        }
        values.push_back(static_cast<double>(e));
      }
    } else if (node.isReal() || node.isInt()) {
      values.push_back(static_cast<double>(node));
    } else if (node.isString()) {
      std::istringstream in(static_cast<std::string>(node));
      std::string token;
      while (in >> token) {
        auto v = ParseFiniteDouble(token);
        if (!v) return InvalidInput(fmt::format("{}: expected a finite number, found '{}'", where(), Excerpt(token)));
        values.push_back(*v);
      }
    }
  } catch (const cv::Exception& e) {
    return InvalidInput(fmt::format("{}: cannot read: {}", where(), e.err));
  }
  for (double v : values) {
    if (!std::isfinite(v)) return InvalidInput(fmt::format("{}: expected finite numbers, found {}", where(), v));
  }
  if (rows && values.size() > 0 && *rows == 0) {
    *rows = static_cast<int>(values.size());
    *cols = 1;
  }
  return values;
}

}  // namespace

Result<OpenCvIntrinsics> ReadOpenCvIntrinsics(const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(cv::FileStorage storage, Open(path));
  int rows = 0, cols = 0;
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> k, Numbers(storage["camera_matrix"], path, "camera_matrix", &rows, &cols));
  if (k.size() != 9 || rows * cols != 9) {
    return InvalidInput(fmt::format("'{}': camera_matrix: expected a 3x3 matrix, found {}x{}", path.string(), rows, cols));
  }
  OpenCvIntrinsics intr;
  intr.fx_px = k[0];
  intr.skew_px = k[1];
  intr.cx_px = k[2];
  intr.fy_px = k[4];
  intr.cy_px = k[5];
  if (k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1) {
    return InvalidInput(fmt::format(
        "'{}': camera_matrix: expected [fx s cx; 0 fy cy; 0 0 1], found last rows [{} {} {}; {} {} {}]",
        path.string(), k[3], k[4], k[5], k[6], k[7], k[8]));
  }
  if (!(intr.fx_px > 0) || !(intr.fy_px > 0)) {
    return InvalidInput(fmt::format("'{}': camera_matrix: expected positive focal lengths, found fx = {}, fy = {}",
                                    path.string(), intr.fx_px, intr.fy_px));
  }
  const cv::FileNode dist_node = storage["distortion_coefficients"];
  if (!dist_node.empty() && !dist_node.isNone()) {
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> d, Numbers(dist_node, path, "distortion_coefficients"));
    if (d.size() != 4 && d.size() != 5 && d.size() != 8 && d.size() != 12 && d.size() != 14) {
      return InvalidInput(fmt::format("'{}': distortion_coefficients: expected 4, 5, 8, 12 or 14 values, found {}",
                                      path.string(), d.size()));
    }
    for (size_t i = 0; i < d.size(); ++i) {
      if (i < 5) {
        intr.distortion[i] = d[i];
      } else if (d[i] != 0) {
        return InvalidInput(fmt::format(
            "'{}': distortion_coefficients: only k1 k2 p1 p2 k3 are supported, found coefficient {} = {}",
            path.string(), i + 1, d[i]));
      }
    }
  }
  const cv::FileNode w = storage["image_width"], h = storage["image_height"];
  if (!w.empty() && !h.empty() && w.isInt() && h.isInt()) {
    intr.image_size = ImageSize{static_cast<int>(w), static_cast<int>(h)};
  }
  return intr;
}

Result<OpenCvExtrinsics> ReadOpenCvExtrinsics(const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(cv::FileStorage storage, Open(path));
  OpenCvExtrinsics e;
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> r, Numbers(storage["rvec"], path, "rvec"));
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> t, Numbers(storage["tvec"], path, "tvec"));
  if (r.size() != 3) return InvalidInput(fmt::format("'{}': rvec: expected 3 numbers, found {}", path.string(), r.size()));
  if (t.size() != 3) return InvalidInput(fmt::format("'{}': tvec: expected 3 numbers, found {}", path.string(), t.size()));
  e.rvec = Eigen::Vector3d(r[0], r[1], r[2]);
  // Angles past a few turns lose all precision in sin/cos (and 1e300 overflows the norm to inf).
  if (!(e.rvec.norm() <= 1000)) {
    return InvalidInput(fmt::format("'{}': rvec: expected a rotation vector of at most 1000 rad, found [{}, {}, {}]",
                                    path.string(), r[0], r[1], r[2]));
  }
  e.tvec_in_file_units = Eigen::Vector3d(t[0], t[1], t[2]);
  return e;
}

Result<PinholeParameters> ReadOpenCvCalibration(const fs::path& intrinsic_path,
                                                const fs::path& extrinsic_path,
                                                double metres_per_unit,
                                                std::optional<ImageSize> image_size) {
  OCCMAP_ASSIGN_OR_RETURN(OpenCvIntrinsics intr, ReadOpenCvIntrinsics(intrinsic_path));
  OCCMAP_ASSIGN_OR_RETURN(OpenCvExtrinsics extr, ReadOpenCvExtrinsics(extrinsic_path));
  PinholeParameters p;
  if (intr.image_size) {
    p.image_size = *intr.image_size;
  } else if (image_size) {
    p.image_size = *image_size;
  } else {
    return InvalidInput(fmt::format("'{}': no image_width/image_height; give the calibrated image size",
                                    intrinsic_path.string()));
  }
  p.fx_px = intr.fx_px;
  p.fy_px = intr.fy_px;
  p.cx_px = intr.cx_px;
  p.cy_px = intr.cy_px;
  p.skew_px = intr.skew_px;
  p.distortion = intr.distortion;
  p.cam_from_world_rotation = RotationFromRodrigues(extr.rvec);
  p.cam_from_world_translation_m = extr.tvec_in_file_units * metres_per_unit;
  // Each error names the file it comes from: extrinsics and rotation from the extrinsic file.
  if (Status s = p.Validate(); !s.ok()) {
    const bool extrinsic = s.message().starts_with("extrinsics") || s.message().starts_with("rotation");
    return s.WithContext(extrinsic ? fmt::format("'{}': rvec/tvec", extrinsic_path.string())
                                   : fmt::format("'{}'", intrinsic_path.string()));
  }
  return p;
}

Status WriteOpenCvIntrinsics(const OpenCvIntrinsics& in, const fs::path& path) {
  try {
    cv::FileStorage intr(".xml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    cv::Mat k = (cv::Mat_<double>(3, 3) << in.fx_px, in.skew_px, in.cx_px, 0, in.fy_px, in.cy_px, 0, 0, 1);
    cv::Mat d(1, 5, CV_64F);
    for (int i = 0; i < 5; ++i) d.at<double>(i) = in.distortion[i];
    intr << "camera_matrix" << k << "distortion_coefficients" << d;
    if (in.image_size) intr << "image_width" << in.image_size->width << "image_height" << in.image_size->height;
    return WriteFileAtomic(path, intr.releaseAndGetString());
  } catch (const cv::Exception& e) {
    return IoError(fmt::format("'{}': cannot write intrinsics: {}", path.string(), e.err));
  }
}

Status WriteOpenCvCalibration(const PinholeParameters& p, double metres_per_unit,
                              const fs::path& intrinsic_path, const fs::path& extrinsic_path) {
  try {
    OpenCvIntrinsics in;
    in.fx_px = p.fx_px;
    in.fy_px = p.fy_px;
    in.cx_px = p.cx_px;
    in.cy_px = p.cy_px;
    in.skew_px = p.skew_px;
    in.distortion = p.distortion;
    in.image_size = p.image_size;
    OCCMAP_RETURN_IF_ERROR(WriteOpenCvIntrinsics(in, intrinsic_path));

    const Eigen::AngleAxisd aa(p.cam_from_world_rotation);
    const Eigen::Vector3d rvec = aa.axis() * aa.angle();
    const Eigen::Vector3d tvec = p.cam_from_world_translation_m / metres_per_unit;
    cv::FileStorage extr(".xml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    extr << "rvec" << (cv::Mat_<double>(3, 1) << rvec.x(), rvec.y(), rvec.z());
    extr << "tvec" << (cv::Mat_<double>(3, 1) << tvec.x(), tvec.y(), tvec.z());
    return WriteFileAtomic(extrinsic_path, extr.releaseAndGetString());
  } catch (const cv::Exception& e) {
    return IoError(fmt::format("'{}': cannot write calibration: {}", intrinsic_path.string(), e.err));
  }
}

}  // namespace occmap
