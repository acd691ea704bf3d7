#include "occmap/site/site_update.h"

#include <fmt/core.h>

#include <algorithm>
#include <yaml-cpp/yaml.h>

#include "occmap/util/file_util.h"
#include "occmap/util/yaml_util.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

// The index just past the flow collection that opens at text[open] ('{' or '['), skipping
// quoted strings; npos when it does not close.
size_t EndOfFlow(std::string_view text, size_t open) {
  int depth = 0;
  char quote = 0;
  for (size_t i = open; i < text.size(); ++i) {
    const char c = text[i];
    if (quote) {
      if (c == '\\' && quote == '"') {
        ++i;
      } else if (c == quote) {
        quote = 0;
      }
      continue;
    }
    if (c == '"' || c == '\'') {
      quote = c;
    } else if (c == '{' || c == '[') {
      ++depth;
    } else if (c == '}' || c == ']') {
      if (--depth == 0) return i + 1;
    }
  }
  return std::string_view::npos;
}

size_t LineStart(std::string_view text, size_t pos) {
  const size_t nl = pos == 0 ? std::string_view::npos : text.rfind('\n', pos - 1);
  return nl == std::string_view::npos ? 0 : nl + 1;
}

Result<YAML::Node> ParseYamlText(std::string_view text, const std::string& name) {
  try {
    return YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    return InvalidInput(fmt::format("{}:{}: not valid YAML: {}", name, e.mark.line + 1, e.msg));
  }
}

size_t LineEnd(std::string_view text, size_t pos) {
  const size_t nl = text.find('\n', pos);
  return nl == std::string_view::npos ? text.size() : nl;
}

// The end of the last line after the line ending at `from` that still belongs to a block:
// lines follow while `belongs(line, column of its first non-blank)`; blank and comment lines
// are passed over (they end nothing).
template <class Belongs>
size_t EndOfBlock(std::string_view text, size_t from, Belongs belongs) {
  size_t end = from;
  for (size_t line = from; line < text.size();) {
    const size_t start = line + 1;
    const size_t stop = LineEnd(text, start);
    const std::string_view l = text.substr(start, stop - start);
    const size_t first = l.find_first_not_of(" \t\r");
    line = stop;
    if (first == std::string_view::npos || l[first] == '#') continue;
    if (!belongs(l, first)) break;
    end = stop;
  }
  return end;
}

// The entry from its key at key_pos to its value's end removed: in a flow map with its comma,
// in a block map with its lines.
Result<std::string> RemoveEntry(std::string_view text, size_t map_pos, size_t key_pos, size_t end,
                                const std::string& name, int line) {
  if (map_pos < text.size() && text[map_pos] == '{') {
    size_t b = key_pos, e = end;
    const size_t after = text.find_first_not_of(" \t\r\n", e);
    if (after != std::string_view::npos && text[after] == ',') {
      e = text.find_first_not_of(" \t\r\n", after + 1);
    } else {
      const size_t before = text.find_last_not_of(" \t\r\n", b == 0 ? 0 : b - 1);
      if (before != std::string_view::npos && text[before] == ',') b = before;
    }
    return std::string(text.substr(0, b)) + std::string(text.substr(e));
  }
  const size_t start = LineStart(text, key_pos);
  if (text.substr(start, key_pos - start).find_first_not_of(" \t") != std::string_view::npos) {
    return InvalidInput(fmt::format("{}:{}: cannot remove the first key of a list item; edit the file", name, line));
  }
  const size_t stop = end < text.size() ? end + 1 : end;  // with its line break
  return std::string(text.substr(0, start)) + std::string(text.substr(stop));
}

// `map` (a node of `text`) with `key` set to `flow` (removed when `flow` is empty): the value replaced in place (a flow
// collection between its brackets, a block one with its more-indented lines, a scalar to the
// end of its line), or the key added after the map's last entry.
Result<std::string> SetMapValue(std::string_view text, const YAML::Node& map, std::string_view key,
                                std::string_view flow, const std::string& name) {
  const size_t map_pos = static_cast<size_t>(std::max(0, map.Mark().pos));
  for (auto it = map.begin(); it != map.end(); ++it) {
    if (!it->first.IsScalar() || it->first.as<std::string>() != key) continue;
    const size_t key_pos = static_cast<size_t>(it->first.Mark().pos);
    const YAML::Node value = it->second;
    const size_t colon = text.find(':', key_pos);
    if (colon == std::string_view::npos) {
      return InvalidInput(fmt::format("{}:{}: cannot find {}'s value", name, it->first.Mark().line + 1, key));
    }
    const int vpos = value.Mark().pos;
    const size_t value_pos = vpos < 0 ? colon + 1 : static_cast<size_t>(vpos);
    size_t begin = colon + 1, end = LineEnd(text, colon);
    if (value.IsDefined() && !value.IsNull() && value_pos < text.size() &&
        (text[value_pos] == '{' || text[value_pos] == '[') && value.Style() == YAML::EmitterStyle::Flow) {
      begin = value_pos;
      end = EndOfFlow(text, value_pos);
      if (end == std::string_view::npos) {
        return InvalidInput(fmt::format("{}:{}: {}'s value does not close", name, value.Mark().line + 1, key));
      }
      if (flow.empty()) return RemoveEntry(text, map_pos, key_pos, end, name, it->first.Mark().line + 1);
      return std::string(text.substr(0, begin)) + std::string(flow) + std::string(text.substr(end));
    }
    const bool flow_parent = map_pos < text.size() && text[map_pos] == '{';
    if (flow_parent && !value.IsMap() && !value.IsSequence()) {
      // A plain scalar in a flow map ends at the next ',' or '}'.
      end = std::min(text.find_first_of(",}", value_pos), LineEnd(text, value_pos));
      while (end > value_pos && (text[end - 1] == ' ' || text[end - 1] == '\t')) --end;
    } else if (value.IsMap() || value.IsSequence()) {
      const size_t key_col = key_pos - LineStart(text, key_pos);
      end = EndOfBlock(text, end, [&](std::string_view l, size_t first) {
        return first > key_col || (first == key_col && value.IsSequence() && l[first] == '-');
      });
    }
    if (flow.empty()) return RemoveEntry(text, map_pos, key_pos, end, name, it->first.Mark().line + 1);
    return std::string(text.substr(0, begin)) + " " + std::string(flow) + std::string(text.substr(end));
  }
  if (flow.empty()) return std::string(text);  // nothing to remove
  // Missing: added.
  if (map_pos < text.size() && text[map_pos] == '{') {
    const size_t close = EndOfFlow(text, map_pos);
    if (close == std::string_view::npos) return InvalidInput(fmt::format("{}:{}: a {{...}} does not close", name, map.Mark().line + 1));
    const std::string_view inside = text.substr(map_pos + 1, close - 1 - (map_pos + 1));
    const bool empty = inside.find_first_not_of(" \t\r\n") == std::string_view::npos;
    return std::string(text.substr(0, close - 1)) + (empty ? "" : ", ") + std::string(key) + ": " + std::string(flow) +
           std::string(text.substr(close - 1));
  }
  const size_t col = map_pos - LineStart(text, map_pos);
  // The end of the map's last content line.
  const size_t last = EndOfBlock(text, LineEnd(text, map_pos), [&](std::string_view l, size_t first) {
    return first >= col && l.substr(first, 3) != "---" && l.substr(first, 3) != "...";
  });
  return std::string(text.substr(0, last)) + "\n" + std::string(col, ' ') + std::string(key) + ": " +
         std::string(flow) + std::string(text.substr(last));
}

}  // namespace

Result<std::string> SetCameraValue(std::string_view text, const fs::path& site_path, std::string_view camera_id,
                                   std::string_view key, std::string_view flow) {
  const std::string name = site_path.string();
  OCCMAP_ASSIGN_OR_RETURN(YAML::Node root, ParseYamlText(text, name));
  if (!root.IsMap() || !root["cameras"] || !root["cameras"].IsSequence()) {
    return InvalidInput(fmt::format("{}: expected a site file with a list of cameras", name));
  }
  std::string list;
  for (const YAML::Node& cam : root["cameras"]) {
    if (!cam.IsMap() || !cam["id"] || !cam["id"].IsScalar()) continue;
    const std::string id = cam["id"].as<std::string>();
    if (id == camera_id) return SetMapValue(text, cam, key, flow, name);
    list += (list.empty() ? "" : ", ") + id;
  }
  return InvalidInput(fmt::format("{}: no camera '{}' (the site's cameras: {})", name, camera_id, list));
}

Result<std::string> SetTrackingValue(std::string_view text, const fs::path& site_path, std::string_view key,
                                     std::string_view flow) {
  const std::string name = site_path.string();
  OCCMAP_ASSIGN_OR_RETURN(YAML::Node root, ParseYamlText(text, name));
  if (!root.IsMap()) return InvalidInput(fmt::format("{}: expected a site file (a map)", name));
  const YAML::Node tracking = root["tracking"];
  if (tracking && tracking.IsMap()) return SetMapValue(text, tracking, key, flow, name);
  if (tracking && !tracking.IsNull()) {
    return InvalidInput(fmt::format("{}:{}: tracking: expected a map", name, tracking.Mark().line + 1));
  }
  return SetMapValue(text, root, "tracking", fmt::format("{{{}: {}}}", key, flow), name);
}

Result<SiteUpdate> WriteSiteText(const fs::path& site_path, std::string_view old_text, std::string new_text,
                                 const SiteLoadOptions& options) {
  auto site = ParseSite(new_text, site_path, options);
  if (!site.ok()) {
    return Status(site.status().code(),
                  fmt::format("the edited site does not load; nothing written: {}", site.status().message()));
  }
  SiteUpdate u;
  u.text = std::move(new_text);
  u.backup = site_path;
  u.backup += ".bak";
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(u.backup, old_text));
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(site_path, u.text));
  return u;
}

Result<fs::path> SiteDataRoot(const fs::path& site_path, const SiteLoadOptions& options) {
  if (options.data_root) return *options.data_root;
  OCCMAP_ASSIGN_OR_RETURN(YamlField root, LoadYamlFile(site_path));
  const fs::path site_dir = site_path.parent_path().empty() ? fs::path(".") : site_path.parent_path();
  if (auto f = root.Find("data_root")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string dr, f->AsString());
    return ResolvePath(site_dir, dr);
  }
  return site_dir;
}

Result<std::string> SitePathFor(const fs::path& site_path, const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(fs::path root, SiteDataRoot(site_path));
  std::error_code ec;
  const fs::path abs_root = fs::weakly_canonical(fs::absolute(root, ec), ec);
  const fs::path abs_path = fs::weakly_canonical(fs::absolute(path, ec), ec);
  const fs::path rel = abs_path.lexically_relative(abs_root);
  if (!rel.empty() && *rel.begin() != "..") return rel.generic_string();
  return abs_path.generic_string();
}

Result<std::string> ReplaceCameraCalibration(std::string_view text, const fs::path& site_path,
                                             std::string_view camera_id, std::string_view flow,
                                             const SiteLoadOptions& options) {
  const std::string name = site_path.string();
  YAML::Node root;
  try {
    root = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    return InvalidInput(fmt::format("{}:{}: not valid YAML: {}", name, e.mark.line + 1, e.msg));
  }
  if (!root.IsMap() || !root["cameras"] || !root["cameras"].IsSequence()) {
    return InvalidInput(fmt::format("{}: expected a site file with a list of cameras", name));
  }
  std::vector<std::string> ids;
  for (const YAML::Node& cam : root["cameras"]) {
    if (!cam.IsMap() || !cam["id"] || !cam["id"].IsScalar()) continue;
    const std::string id = cam["id"].as<std::string>();
    ids.push_back(id);
    if (id != camera_id) continue;
    // The key's position, then its value's: a flow map is replaced between its braces, a
    // block map from after the colon to its last more-indented line.
    size_t key_pos = std::string_view::npos, value_pos = 0;
    YAML::Node value;
    for (auto it = cam.begin(); it != cam.end(); ++it) {
      if (it->first.IsScalar() && it->first.as<std::string>() == "calibration") {
        key_pos = static_cast<size_t>(it->first.Mark().pos);
        value = it->second;
        value_pos = static_cast<size_t>(it->second.Mark().pos);
      }
    }
    if (key_pos == std::string_view::npos) {
      return InvalidInput(fmt::format("{}:{}: camera '{}' has no calibration entry to replace", name,
                                      cam.Mark().line + 1, id));
    }
    const size_t colon = text.find(':', key_pos);
    if (colon == std::string_view::npos || colon > value_pos) {
      return InvalidInput(fmt::format("{}:{}: cannot find the calibration's value", name, value.Mark().line + 1));
    }
    size_t replace_begin = 0, replace_end = 0;
    if (value.IsMap() && value.Style() == YAML::EmitterStyle::Flow && value_pos < text.size() &&
        text[value_pos] == '{') {
      replace_begin = value_pos;
      replace_end = EndOfFlow(text, value_pos);
      if (replace_end == std::string_view::npos) {
        return InvalidInput(fmt::format("{}:{}: the calibration's {{...}} does not close", name, value.Mark().line + 1));
      }
    } else if (value.IsMap()) {
      const size_t indent = value_pos - LineStart(text, value_pos);
      replace_begin = colon + 1;
      size_t line = text.find('\n', value_pos);
      replace_end = line == std::string_view::npos ? text.size() : line;
      while (line != std::string_view::npos) {
        const size_t start = line + 1;
        size_t end = text.find('\n', start);
        if (end == std::string_view::npos) end = text.size();
        const std::string_view l = text.substr(start, end - start);
        const size_t first = l.find_first_not_of(" \t\r");
        if (first == std::string_view::npos || l[first] == '#') {
          line = end < text.size() ? end : std::string_view::npos;
          continue;  // blank or comment: belongs to whatever follows
        }
        if (first < indent) break;
        replace_end = end;
        line = end < text.size() ? end : std::string_view::npos;
      }
    } else {
      return InvalidInput(fmt::format("{}:{}: camera '{}': calibration: expected a map", name, value.Mark().line + 1, id));
    }
    std::string out(text.substr(0, replace_begin));
    if (replace_begin == colon + 1) out += " ";
    out += flow;
    out += text.substr(replace_end);
    auto site = ParseSite(out, site_path, options);
    if (!site.ok()) {
      return Status(site.status().code(),
                    fmt::format("the site with camera '{}''s new calibration does not load; nothing written: {}", id,
                                site.status().message()));
    }
    return out;
  }
  std::string list;
  for (const auto& i : ids) list += (list.empty() ? "" : ", ") + i;
  return InvalidInput(fmt::format("{}: no camera '{}' (the site's cameras: {})", name, camera_id, list));
}

Result<SiteUpdate> UpdateSiteCameraCalibration(const fs::path& site_path, std::string_view camera_id,
                                               std::string_view flow, const SiteLoadOptions& options) {
  OCCMAP_ASSIGN_OR_RETURN(std::string old_text, ReadFileToString(site_path));
  SiteUpdate u;
  OCCMAP_ASSIGN_OR_RETURN(u.text, ReplaceCameraCalibration(old_text, site_path, camera_id, flow, options));
  u.backup = site_path;
  u.backup += ".bak";
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(u.backup, old_text));
  OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(site_path, u.text));
  return u;
}

}  // namespace occmap
