#include "occmap/publish/ros_map.h"

#include <fmt/core.h>

#include <cctype>
#include <cmath>
#include <cstring>

#include "occmap/util/file_util.h"
#include "occmap/util/yaml_util.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;

uint8_t PixelValue(RosCell c) {
  switch (c) {
    case RosCell::kFree: return kRosFreeValue;
    case RosCell::kOccupied: return kRosOccupiedValue;
    case RosCell::kUnknown: return kRosUnknownValue;
  }
  return kRosUnknownValue;
}

// A number with as many digits as it needs to read back exactly.
std::string Exact(double v) { return fmt::format("{}", v + 0.0); }

// Reads the next header token of a PGM (skipping whitespace and # comments).
bool NextToken(std::string_view data, size_t& pos, std::string& token) {
  while (pos < data.size()) {
    if (data[pos] == '#') {
      while (pos < data.size() && data[pos] != '\n') ++pos;
    } else if (std::isspace(static_cast<unsigned char>(data[pos]))) {
      ++pos;
    } else {
      break;
    }
  }
  token.clear();
  while (pos < data.size() && !std::isspace(static_cast<unsigned char>(data[pos])) && data[pos] != '#') token += data[pos++];
  return !token.empty();
}

struct Pgm {
  int width = 0, height = 0;
  std::string_view pixels;
};

Result<Pgm> ParsePgm(std::string_view data, const std::string& name) {
  size_t pos = 0;
  std::string token;
  if (!NextToken(data, pos, token) || token != "P5") {
    return InvalidInput(fmt::format("{}: expected a binary PGM (P5), found '{}'", name, token.substr(0, 8)));
  }
  int values[3] = {0, 0, 0};
  const char* what[3] = {"width", "height", "maximum value"};
  for (int k = 0; k < 3; ++k) {
    if (!NextToken(data, pos, token)) return DataLoss(fmt::format("{}: truncated header: no {}", name, what[k]));
    const std::optional<int64_t> v = ParseInt(token);
    if (!v || *v < 1 || *v > (k == 2 ? 65535 : 1 << 20)) {
      return InvalidInput(fmt::format("{}: expected a positive {}, found '{}'", name, what[k], token));
    }
    values[k] = static_cast<int>(*v);
  }
  if (values[2] != 255) return InvalidInput(fmt::format("{}: expected 8-bit pixels (maximum value 255), found {}", name, values[2]));
  ++pos;  // the single whitespace before the pixels
  Pgm pgm{values[0], values[1], {}};
  const size_t size = static_cast<size_t>(pgm.width) * static_cast<size_t>(pgm.height);
  if (pos > data.size() || data.size() - pos < size) {
    return DataLoss(fmt::format("{}: truncated: expected {} x {} = {} pixels, found {}", name, pgm.width, pgm.height, size,
                                pos > data.size() ? 0 : data.size() - pos));
  }
  pgm.pixels = data.substr(pos, size);
  return pgm;
}

}  // namespace

RosMap RosMapFromOccupancy(const OccupancyMap& map) {
  RosMap out;
  out.grid = map.grid();
  out.cells.resize(map.states().size());
  for (size_t k = 0; k < out.cells.size(); ++k) {
    switch (map.states()[k]) {
      case CellState::kFree: out.cells[k] = RosCell::kFree; break;
      case CellState::kOccupied: out.cells[k] = RosCell::kOccupied; break;
      case CellState::kUnseen: out.cells[k] = RosCell::kUnknown; break;
    }
  }
  return out;
}

Status WriteRosMap(const fs::path& yaml_path, const RosMap& map) {
  OCCMAP_CHECK(map.cells.size() == static_cast<size_t>(map.grid.num_cells()), "RosMap: cells do not match the grid");
  const int w = map.grid.cells_x, h = map.grid.cells_y;
  std::string pgm = fmt::format("P5\n# occmap map, {} m/pixel\n{} {}\n255\n", Exact(map.grid.cell_size_m), w, h);
  const size_t header = pgm.size();
  pgm.resize(header + static_cast<size_t>(w) * static_cast<size_t>(h));
  for (int r = 0; r < h; ++r) {
    const int j = h - 1 - r;  // the first row is the top: the largest y
    char* row = pgm.data() + header + static_cast<size_t>(r) * static_cast<size_t>(w);
    for (int i = 0; i < w; ++i) row[i] = static_cast<char>(PixelValue(map.at(i, j)));
  }
  fs::path pgm_path = yaml_path;
  pgm_path.replace_extension(".pgm");
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(pgm_path, pgm));
  const std::string yaml = fmt::format(
      "image: {}\nmode: trinary\nresolution: {}\norigin: [{}, {}, {}]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
      pgm_path.filename().string(), Exact(map.grid.cell_size_m), Exact(map.grid.origin_x_m), Exact(map.grid.origin_y_m),
      Exact(map.yaw_rad));
  return WriteFileAtomic(yaml_path, yaml);
}

Result<RosMap> ReadRosMap(const fs::path& yaml_path) {
  OCCMAP_ASSIGN_OR_RETURN(YamlField root, LoadYamlFile(yaml_path));
  if (!root.IsMap()) return root.Error("expected a map_server map (image, resolution, origin, ...)");
  OCCMAP_ASSIGN_OR_RETURN(std::string mode, root.GetString("mode", "trinary"));
  if (mode != "trinary") return root.Find("mode")->Error(fmt::format("expected 'trinary' (the only mode read), found '{}'", mode));
  OCCMAP_ASSIGN_OR_RETURN(YamlField resolution, root.Get("resolution"));
  OCCMAP_ASSIGN_OR_RETURN(double resolution_m, resolution.AsDouble());
  if (!(resolution_m > 0)) return resolution.Error(fmt::format("expected a number > 0, found {}", resolution_m));
  OCCMAP_ASSIGN_OR_RETURN(std::vector<double> origin, root.GetDoubles("origin", 3));
  OCCMAP_ASSIGN_OR_RETURN(int64_t negate, root.GetInt("negate", 0));
  if (negate != 0 && negate != 1) return root.Find("negate")->Error(fmt::format("expected 0 or 1, found {}", negate));
  OCCMAP_ASSIGN_OR_RETURN(YamlField occupied_field, root.Get("occupied_thresh"));
  OCCMAP_ASSIGN_OR_RETURN(double occupied_thresh, occupied_field.AsDouble());
  OCCMAP_ASSIGN_OR_RETURN(YamlField free_field, root.Get("free_thresh"));
  OCCMAP_ASSIGN_OR_RETURN(double free_thresh, free_field.AsDouble());
  if (!(occupied_thresh >= 0 && occupied_thresh <= 1)) {
    return occupied_field.Error(fmt::format("expected a number in [0, 1], found {}", occupied_thresh));
  }
  if (!(free_thresh >= 0 && free_thresh <= occupied_thresh)) {
    return free_field.Error(fmt::format("expected a number in [0, occupied_thresh = {}], found {}", occupied_thresh, free_thresh));
  }
  OCCMAP_ASSIGN_OR_RETURN(YamlField image_field, root.Get("image"));
  OCCMAP_ASSIGN_OR_RETURN(std::string image, image_field.AsString());
  const fs::path image_path = ResolvePath(yaml_path.has_parent_path() ? yaml_path.parent_path() : fs::path("."), image);
  if (std::error_code ec; !fs::is_regular_file(image_path, ec)) {
    return Status(StatusCode::kNotFound, fmt::format("{}: file not found: '{}'", image_field.Where(), image_path.string()));
  }
  OCCMAP_ASSIGN_OR_RETURN(std::string data, ReadFileToString(image_path));
  OCCMAP_ASSIGN_OR_RETURN(Pgm pgm, ParsePgm(data, image_path.string()));

  RosMap map;
  map.grid = FloorGrid{origin[0], origin[1], pgm.width, pgm.height, resolution_m};
  map.yaw_rad = origin[2];
  OCCMAP_RETURN_IF_ERROR(map.grid.Validate().WithContext(yaml_path.string()));
  map.cells.resize(static_cast<size_t>(map.grid.num_cells()));
  for (int r = 0; r < pgm.height; ++r) {
    const int j = pgm.height - 1 - r;
    for (int i = 0; i < pgm.width; ++i) {
      const double v = static_cast<unsigned char>(pgm.pixels[static_cast<size_t>(r) * pgm.width + i]);
      const double p = negate ? v / 255.0 : (255.0 - v) / 255.0;
      const RosCell c = p > occupied_thresh ? RosCell::kOccupied : p < free_thresh ? RosCell::kFree : RosCell::kUnknown;
      map.cells[static_cast<size_t>(j) * pgm.width + i] = c;
    }
  }
  return map;
}

void StaticMapAccumulator::Add(const OccupancyMap& map) {
  OCCMAP_CHECK(map.grid() == grid_, "StaticMapAccumulator: a map of another grid");
  const std::vector<CellState>& states = map.states();
  const size_t n = states.size();
  for (size_t k = 0; k < n; ++k) {
    seen_[k] += states[k] != CellState::kUnseen;
    occupied_[k] += states[k] == CellState::kOccupied;
  }
  ++frames_;
}

RosMap StaticMapAccumulator::StaticMap(double occupied_fraction) const {
  RosMap out;
  out.grid = grid_;
  out.cells.resize(seen_.size());
  for (size_t k = 0; k < seen_.size(); ++k) {
    if (seen_[k] == 0) {
      out.cells[k] = RosCell::kUnknown;
    } else {
      out.cells[k] = static_cast<double>(occupied_[k]) > occupied_fraction * static_cast<double>(seen_[k]) ? RosCell::kOccupied
                                                                                                            : RosCell::kFree;
    }
  }
  return out;
}

}  // namespace occmap
