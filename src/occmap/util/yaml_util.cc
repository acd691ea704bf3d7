#include "occmap/util/yaml_util.h"

#include "occmap/util/text_guard.h"

#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <unordered_map>

#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"

namespace occmap {

YamlField::YamlField(YAML::Node node, std::shared_ptr<const std::string> file, std::string path)
    : node_(std::move(node)), file_(std::move(file)), path_(std::move(path)) {}

int YamlField::line() const {
  if (!node_.IsDefined()) return 0;
  const YAML::Mark mark = node_.Mark();
  return mark.line >= 0 ? mark.line + 1 : 0;
}

std::string YamlField::Where() const {
  std::string where = *file_;
  if (const int l = line(); l > 0) where += fmt::format(":{}", l);
  if (!path_.empty()) where += ": " + path_;
  return where;
}

Status YamlField::Error(std::string_view what) const {
  return InvalidInput(fmt::format("{}: {}", Where(), what));
}

std::string YamlField::DescribeFound() const {
  if (IsNull()) return "nothing";
  if (node_.IsScalar()) return fmt::format("'{}'", Excerpt(node_.Scalar()));
  if (node_.IsSequence()) return fmt::format("a list of {}", node_.size());
  if (node_.IsMap()) return "a map";
  return "an unknown node";
}

bool YamlField::Has(std::string_view key) const {
  return node_.IsMap() && node_[std::string(key)].IsDefined() && !node_[std::string(key)].IsNull();
}

std::optional<YamlField> YamlField::Find(std::string_view key) const {
  if (!Has(key)) return std::nullopt;
  return YamlField(node_[std::string(key)], file_,
                   path_.empty() ? std::string(key) : fmt::format("{}.{}", path_, key));
}

Result<YamlField> YamlField::Get(std::string_view key) const {
  if (!node_.IsMap()) return Error(fmt::format("expected a map with '{}', found {}", key, DescribeFound()));
  if (auto f = Find(key)) return *f;
  return Error(fmt::format("missing required field '{}'", key));
}

Result<YamlField> YamlField::At(size_t index) const {
  if (!node_.IsSequence()) return Error(fmt::format("expected a list, found {}", DescribeFound()));
  if (index >= node_.size()) return Error(fmt::format("index {} out of range", index));
  return YamlField(node_[index], file_, fmt::format("{}[{}]", path_, index));
}

std::optional<double> ParseFiniteDouble(std::string_view text) {
  while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  double value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || text.empty()) return std::nullopt;
  if (!std::isfinite(value)) return std::nullopt;
  return value;
}

std::optional<int64_t> ParseInt(std::string_view text) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  int64_t value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

Result<double> YamlField::AsDouble() const {
  if (!node_.IsScalar()) return Error(fmt::format("expected a number, found {}", DescribeFound()));
  if (auto v = ParseFiniteDouble(node_.Scalar())) return *v;
  return Error(fmt::format("expected a finite number, found '{}'", Excerpt(node_.Scalar())));
}

Result<int64_t> YamlField::AsInt() const {
  if (!node_.IsScalar()) return Error(fmt::format("expected an integer, found {}", DescribeFound()));
  if (auto v = ParseInt(node_.Scalar())) return *v;
  return Error(fmt::format("expected an integer, found '{}'", Excerpt(node_.Scalar())));
}

Result<bool> YamlField::AsBool() const {
  if (node_.IsScalar()) {
    const std::string& s = node_.Scalar();
    if (s == "true" || s == "yes" || s == "on") return true;
    if (s == "false" || s == "no" || s == "off") return false;
  }
  return Error(fmt::format("expected true or false, found {}", DescribeFound()));
}

Result<std::string> YamlField::AsString() const {
  if (!node_.IsScalar()) return Error(fmt::format("expected a text value, found {}", DescribeFound()));
  return node_.Scalar();
}

Result<std::vector<double>> YamlField::AsDoubles(size_t expected_size) const {
  if (!node_.IsSequence()) {
    return Error(expected_size > 0
                     ? fmt::format("expected a list of {} numbers, found {}", expected_size, DescribeFound())
                     : fmt::format("expected a list of numbers, found {}", DescribeFound()));
  }
  if (expected_size > 0 && node_.size() != expected_size) {
    return Error(fmt::format("expected a list of {} numbers, found {}", expected_size, node_.size()));
  }
  if (node_.size() == 0) return Error("expected a non-empty list of numbers, found an empty list");
  std::vector<double> values;
  values.reserve(node_.size());
  for (size_t i = 0; i < node_.size(); ++i) {
    OCCMAP_ASSIGN_OR_RETURN(YamlField element, At(i));
    OCCMAP_ASSIGN_OR_RETURN(double v, element.AsDouble());
    values.push_back(v);
  }
  return values;
}

Result<double> YamlField::GetDouble(std::string_view key) const {
  OCCMAP_ASSIGN_OR_RETURN(YamlField f, Get(key));
  return f.AsDouble();
}
Result<double> YamlField::GetDouble(std::string_view key, double default_value) const {
  if (auto f = Find(key)) return f->AsDouble();
  return default_value;
}
Result<int64_t> YamlField::GetInt(std::string_view key) const {
  OCCMAP_ASSIGN_OR_RETURN(YamlField f, Get(key));
  return f.AsInt();
}
Result<int64_t> YamlField::GetInt(std::string_view key, int64_t default_value) const {
  if (auto f = Find(key)) return f->AsInt();
  return default_value;
}
Result<bool> YamlField::GetBool(std::string_view key, bool default_value) const {
  if (auto f = Find(key)) return f->AsBool();
  return default_value;
}
Result<std::string> YamlField::GetString(std::string_view key) const {
  OCCMAP_ASSIGN_OR_RETURN(YamlField f, Get(key));
  return f.AsString();
}
Result<std::string> YamlField::GetString(std::string_view key, std::string_view default_value) const {
  if (auto f = Find(key)) return f->AsString();
  return std::string(default_value);
}
Result<std::vector<double>> YamlField::GetDoubles(std::string_view key, size_t expected_size) const {
  OCCMAP_ASSIGN_OR_RETURN(YamlField f, Get(key));
  return f.AsDoubles(expected_size);
}

Status YamlField::CheckKeys(std::initializer_list<std::string_view> allowed) const {
  return CheckKeys(std::vector<std::string>(allowed.begin(), allowed.end()));
}

Status YamlField::CheckKeys(const std::vector<std::string>& allowed) const {
  if (!node_.IsMap()) return Error(fmt::format("expected a map, found {}", DescribeFound()));
  for (const auto& kv : node_) {
    // A key that is empty, a list or a map (`{!tag : 1}`, `? [a]`): yaml-cpp's as<> would throw.
    if (!kv.first.IsScalar()) {
      const YamlField where(kv.first, file_, path_);
      return where.Error(fmt::format("expected a field name, found {}", where.DescribeFound()));
    }
    const std::string key = kv.first.Scalar();
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    std::string best;
    int best_distance = 3;
    for (const auto& a : allowed) {
      const int d = EditDistance(key, a);
      if (d < best_distance) {
        best_distance = d;
        best = a;
      }
    }
    YamlField where(kv.first, file_, path_);
    std::string known;
    for (size_t i = 0; i < allowed.size(); ++i) known += (i ? ", " : "") + allowed[i];
    return where.Error(best.empty()
                           ? fmt::format("unknown field '{}' (expected one of: {})", Excerpt(key), known)
                           : fmt::format("unknown field '{}' (did you mean '{}'?)", Excerpt(key), best));
  }
  return Status::Ok();
}

int EditDistance(std::string_view a, std::string_view b) {
  std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] != b[j - 1])});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

namespace {

// Bounds on the tree walk below: nesting (an alias inside its own anchor could loop) and nodes
// visited (aliases of aliases multiply: a "billion laughs" file).
constexpr int kMaxYamlDepth = 256;
constexpr int64_t kMaxYamlNodes = 2'000'000;

// yaml-cpp 0.7 keeps the first of two equal keys and drops the second without a word: a site
// whose second `threshold:` is silently ignored. Every map is checked for repeated keys.
Status CheckDuplicateKeys(const YAML::Node& node, const std::string& file, const std::string& path, int depth,
                          int64_t& visited) {
  if (++visited > kMaxYamlNodes) {
    return InvalidInput(fmt::format("{}: expected at most {} YAML nodes (aliases included), found more", file, kMaxYamlNodes));
  }
  if (depth > kMaxYamlDepth) {
    return InvalidInput(fmt::format("{}:{}: {}: expected at most {} levels of nesting, found more", file,
                                    node.Mark().line + 1, path, kMaxYamlDepth));
  }
  if (node.IsSequence()) {
    for (size_t i = 0; i < node.size(); ++i) {
      OCCMAP_RETURN_IF_ERROR(CheckDuplicateKeys(node[i], file, fmt::format("{}[{}]", path, i), depth + 1, visited));
    }
  } else if (node.IsMap()) {
    std::unordered_map<std::string, int> seen;  // key -> line
    for (const auto& kv : node) {
      std::string key = kv.first.IsScalar() ? kv.first.Scalar() : std::string();
      const int line = kv.first.Mark().line + 1;
      if (kv.first.IsScalar()) {
        if (const auto [it, fresh] = seen.emplace(key, line); !fresh) {
          return InvalidInput(fmt::format("{}:{}: {}{}duplicate key '{}' (first at line {}; YAML keys must be unique)",
                                          file, line, path, path.empty() ? "" : ": ", Excerpt(key), it->second));
        }
      }
      const std::string child = path.empty() ? key : fmt::format("{}.{}", path, key);
      OCCMAP_RETURN_IF_ERROR(CheckDuplicateKeys(kv.second, file, child, depth + 1, visited));
    }
  }
  return Status::Ok();
}

}  // namespace

Result<YamlField> ParseYaml(std::string_view text, std::string file_name) {
  auto file = std::make_shared<const std::string>(std::move(file_name));
  // YAML files are UTF-8; yaml-cpp passes any byte through, and a stray one in an id or a name
  // would only fail much later (writing JSON), far from the file.
  if (const auto bad = FindInvalidUtf8(text)) {
    const std::string_view before = text.substr(0, *bad);
    const size_t line = static_cast<size_t>(std::count(before.begin(), before.end(), '\n')) + 1;
    const size_t line_start = before.rfind('\n') == std::string_view::npos ? 0 : before.rfind('\n') + 1;
    return InvalidInput(fmt::format("{}:{}:{}: expected UTF-8 text, found the byte 0x{:02x}", *file, line,
                                    *bad - line_start + 1, static_cast<unsigned char>(text[*bad])));
  }
  try {
    YAML::Node root = YAML::Load(std::string(text));
    int64_t visited = 0;
    OCCMAP_RETURN_IF_ERROR(CheckDuplicateKeys(root, *file, "", 0, visited));
    return YamlField(root, file, "");
  } catch (const YAML::Exception& e) {
    return InvalidInput(fmt::format("{}:{}:{}: YAML syntax error: {}", *file, e.mark.line + 1,
                                    e.mark.column + 1, e.msg));
  }
}

Result<YamlField> LoadYamlFile(const std::filesystem::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
  return ParseYaml(text, path.string());
}

}  // namespace occmap
