#include "occmap/io/frame_times.h"

#include <fmt/core.h>

#include <charconv>
#include <cmath>
#include <string>
#include <system_error>

#include "occmap/util/safe_files.h"
#include "occmap/util/text_lines.h"

namespace occmap {
namespace {

// The whitespace-separated words of a line, at most three (a third is an error).
std::vector<std::string_view> Words(std::string_view line) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < line.size() && words.size() < 3) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

std::string Cut(std::string_view text) {
  constexpr size_t kMax = 40;
  return text.size() <= kMax ? std::string(text) : std::string(text.substr(0, kMax)) + "...";
}

}  // namespace

Result<std::vector<double>> ParseFrameTimes(std::string_view text, std::string_view source_name, double numbers_fps) {
  if (!(numbers_fps >= 0) || !std::isfinite(numbers_fps)) {
    return InvalidInput(fmt::format("{}: expected a rate >= 0 for its frame numbers, found {}", source_name, numbers_fps));
  }
  std::vector<double> times_s;
  int form = 0;  // words per line, fixed by the first line
  OCCMAP_RETURN_IF_ERROR(ForEachTextLine(text, [&](int64_t line_number, std::string_view line) -> Status {
    const std::vector<std::string_view> words = Words(line);
    const auto where = [&] { return fmt::format("{}:{}", source_name, line_number); };
    if (words.size() > 2) {
      return InvalidInput(fmt::format("{}: expected 'TIME' or 'INDEX TIME', found '{}'", where(), Cut(line)));
    }
    if (form == 0) form = static_cast<int>(words.size());
    if (static_cast<int>(words.size()) != form) {
      return InvalidInput(fmt::format("{}: expected {} as on the first line, found '{}'", where(),
                                      form == 1 ? "'TIME'" : "'INDEX TIME'", Cut(line)));
    }
    if (form == 2) {
      int64_t index = -1;
      const std::string_view w = words[0];
      const auto [p, ec] = std::from_chars(w.data(), w.data() + w.size(), index);
      if (ec != std::errc() || p != w.data() + w.size()) {
        return InvalidInput(fmt::format("{}: expected an image index, found '{}'", where(), Cut(w)));
      }
      if (index != static_cast<int64_t>(times_s.size())) {
        return InvalidInput(fmt::format("{}: expected image index {} (one line per image, in order), found {}", where(),
                                        times_s.size(), index));
      }
    }
    const std::string value_text(words.back());
    double value = 0;
    const auto [p, ec] = std::from_chars(value_text.data(), value_text.data() + value_text.size(), value);
    if (ec != std::errc() || p != value_text.data() + value_text.size() || !std::isfinite(value)) {
      return InvalidInput(fmt::format("{}: expected a {}, found '{}'", where(),
                                      numbers_fps > 0 ? "frame number" : "time in seconds", Cut(value_text)));
    }
    const double time_s = numbers_fps > 0 ? value / numbers_fps : value;
    if (!times_s.empty() && !(time_s > times_s.back())) {
      return InvalidInput(fmt::format("{}: expected times that increase, found {} after {}", where(), value,
                                      numbers_fps > 0 ? times_s.back() * numbers_fps : times_s.back()));
    }
    times_s.push_back(time_s);
    return Status::Ok();
  }));
  if (times_s.empty()) return InvalidInput(fmt::format("{}: expected a time per image, found none", source_name));
  return times_s;
}

Result<std::vector<double>> ReadFrameTimes(const std::filesystem::path& path, double numbers_fps) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
  return ParseFrameTimes(text, path.string(), numbers_fps);
}

double MeanRateHz(const std::vector<double>& times_s) {
  if (times_s.size() < 2) return 0;
  return static_cast<double>(times_s.size() - 1) / (times_s.back() - times_s.front());
}

}  // namespace occmap
