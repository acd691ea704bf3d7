// YamlField: a YAML node that knows its file, line and field path, for error messages.
//
// Every accessor validates: a number must parse completely and be finite, a list must have the
// expected length, a map may only hold known keys (a typo gets a "did you mean"). Errors read
//   site.yaml:14: cameras[2].calibration.focal: expected a finite number, found 'abc'
//
//   OCCMAP_ASSIGN_OR_RETURN(YamlField root, LoadYamlFile("site.yaml"));
//   OCCMAP_RETURN_IF_ERROR(root.CheckKeys({"floor", "cameras"}));
//   OCCMAP_ASSIGN_OR_RETURN(double cell_m, root.Get("floor")->GetDouble("cell_size_m"));
#pragma once

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "occmap/util/status.h"

namespace occmap {

class YamlField {
 public:
  YamlField(YAML::Node node, std::shared_ptr<const std::string> file, std::string path);

  const YAML::Node& node() const { return node_; }
  const std::string& path() const { return path_; }
  const std::string& file() const { return *file_; }
  int line() const;  // 1-based; 0 when unknown
  // "file:line: path" (the path part omitted at the root).
  std::string Where() const;
  // InvalidInput status "<Where()>: <what>".
  Status Error(std::string_view what) const;

  bool IsMap() const { return node_.IsMap(); }
  bool IsSequence() const { return node_.IsSequence(); }
  bool IsScalar() const { return node_.IsScalar(); }
  bool IsNull() const { return !node_.IsDefined() || node_.IsNull(); }
  size_t size() const { return node_.size(); }

  bool Has(std::string_view key) const;
  std::optional<YamlField> Find(std::string_view key) const;
  Result<YamlField> Get(std::string_view key) const;  // error when missing
  Result<YamlField> At(size_t index) const;           // sequence element

  Result<double> AsDouble() const;  // finite
  Result<int64_t> AsInt() const;
  Result<bool> AsBool() const;
  Result<std::string> AsString() const;
  // A sequence of finite numbers; expected_size 0 accepts any non-empty length.
  Result<std::vector<double>> AsDoubles(size_t expected_size = 0) const;

  Result<double> GetDouble(std::string_view key) const;
  Result<double> GetDouble(std::string_view key, double default_value) const;
  Result<int64_t> GetInt(std::string_view key) const;
  Result<int64_t> GetInt(std::string_view key, int64_t default_value) const;
  Result<bool> GetBool(std::string_view key, bool default_value) const;
  Result<std::string> GetString(std::string_view key) const;
  Result<std::string> GetString(std::string_view key, std::string_view default_value) const;
  Result<std::vector<double>> GetDoubles(std::string_view key, size_t expected_size = 0) const;

  // Requires a map whose keys are all in `allowed`.
  Status CheckKeys(std::initializer_list<std::string_view> allowed) const;
  Status CheckKeys(const std::vector<std::string>& allowed) const;

 private:
  std::string DescribeFound() const;
  YAML::Node node_;
  std::shared_ptr<const std::string> file_;
  std::string path_;
};

// Parses a YAML file; a syntax error names the file, line and column.
Result<YamlField> LoadYamlFile(const std::filesystem::path& path);
// Parses YAML text; `file_name` is used in messages.
Result<YamlField> ParseYaml(std::string_view text, std::string file_name);

// Checked number parsing (std::from_chars): the whole text must be a finite number.
std::optional<double> ParseFiniteDouble(std::string_view text);
std::optional<int64_t> ParseInt(std::string_view text);

// Edit distance, for "did you mean" suggestions.
int EditDistance(std::string_view a, std::string_view b);

}  // namespace occmap
