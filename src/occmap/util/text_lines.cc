#include "occmap/util/text_lines.h"

namespace occmap {

std::string_view TrimBlanks(std::string_view text) {
  const size_t b = text.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return {};
  const size_t e = text.find_last_not_of(" \t\r");
  return text.substr(b, e - b + 1);
}

Status ForEachTextLine(std::string_view text, const std::function<Status(int64_t line_number, std::string_view line)>& fn) {
  int64_t line_number = 0;
  size_t pos = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    if (const size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    line = TrimBlanks(line);
    if (line.empty()) continue;
    OCCMAP_RETURN_IF_ERROR(fn(line_number, line));
  }
  return Status::Ok();
}

}  // namespace occmap
