#include "occmap/util/text_guard.h"

#include <fmt/core.h>

#include <algorithm>
#include <limits>
#include <vector>

namespace occmap {
namespace {

struct Deepest {
  int depth = 0;
  size_t offset = 0;  // where a depth over the stop was first reached
};

// Each scanner returns the deepest nesting, stopping at the first point deeper than `stop`.
Deepest ScanJson(std::string_view t, int stop) {
  Deepest d;
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < t.size(); ++i) {
    const char c = t[i];
    if (in_string) {
      if (c == '\\') {
        ++i;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > d.depth) d = {depth, i};
      if (depth > stop) return d;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return d;
}

Deepest ScanXml(std::string_view t, int stop) {
  Deepest d;
  int depth = 0;
  // Skips from `i` past the end marker; false at the end of the text.
  auto skip_past = [&](size_t& i, std::string_view end) {
    const size_t e = t.find(end, i);
    if (e == std::string_view::npos) return false;
    i = e + end.size() - 1;
    return true;
  };
  for (size_t i = 0; i < t.size(); ++i) {
    if (t[i] != '<') continue;
    const std::string_view rest = t.substr(i);
    if (rest.starts_with("<!--")) {
      if (!skip_past(i, "-->")) break;
    } else if (rest.starts_with("<![CDATA[")) {
      if (!skip_past(i, "]]>")) break;
    } else if (rest.starts_with("<?")) {
      if (!skip_past(i, "?>")) break;
    } else if (rest.starts_with("<!")) {
      if (!skip_past(i, ">")) break;
    } else if (rest.starts_with("</")) {
      if (depth > 0) --depth;
      if (!skip_past(i, ">")) break;
    } else {
      const size_t start = i;
      char quote = 0;
      size_t j = i + 1;
      for (; j < t.size(); ++j) {
        if (quote) {
          if (t[j] == quote) quote = 0;
        } else if (t[j] == '"' || t[j] == '\'') {
          quote = t[j];
        } else if (t[j] == '>') {
          break;
        }
      }
      if (j >= t.size()) break;
      i = j;
      if (t[j - 1] != '/') {
        if (++depth > d.depth) d = {depth, start};
        if (depth > stop) return d;
      }
    }
  }
  return d;
}

Deepest ScanYaml(std::string_view t, int stop) {
  Deepest d;
  std::vector<size_t> block;  // the columns of the open block levels, increasing
  int flow = 0;
  size_t pos = 0;
  while (pos < t.size()) {
    size_t end = t.find('\n', pos);
    if (end == std::string_view::npos) end = t.size();
    const std::string_view line = t.substr(pos, end - pos);
    size_t col = line.find_first_not_of(' ');
    const bool blank = col == std::string_view::npos || line[col] == '#' || line[col] == '\r' ||
                       (col == 0 && (line[0] == '%' || line.starts_with("---") || line.starts_with("...")));
    if (!blank) {
      if (flow == 0) {
        while (!block.empty() && block.back() > col) block.pop_back();
        if (block.empty() || block.back() < col) block.push_back(col);
        // Entries opened on this line: "- - x", "? - x".
        while (col + 1 < line.size() && (line[col] == '-' || line[col] == '?') &&
               (line[col + 1] == ' ' || line[col + 1] == '\t')) {
          col = line.find_first_not_of(" \t", col + 1);
          if (col == std::string_view::npos) break;
          block.push_back(col);
        }
      }
      if (static_cast<int>(block.size()) + flow > d.depth) d = {static_cast<int>(block.size()) + flow, pos};
      if (d.depth > stop) return d;
      char quote = 0;
      for (size_t i = col == std::string_view::npos ? line.size() : col; i < line.size(); ++i) {
        const char c = line[i];
        if (quote) {
          if (quote == '"' && c == '\\') {
            ++i;
          } else if (c == quote) {
            quote = 0;
          }
        } else if (c == '"' || c == '\'') {
          if (i == 0 || line[i - 1] == ' ' || line[i - 1] == '[' || line[i - 1] == '{' || line[i - 1] == ',' ||
              line[i - 1] == ':') {
            quote = c;
          }
        } else if (c == '#' && (i == 0 || line[i - 1] == ' ' || line[i - 1] == '\t')) {
          break;
        } else if (c == '[' || c == '{') {
          ++flow;
          if (static_cast<int>(block.size()) + flow > d.depth) d = {static_cast<int>(block.size()) + flow, pos + i};
          if (d.depth > stop) return d;
        } else if ((c == ']' || c == '}') && flow > 0) {
          --flow;
        }
      }
    }
    pos = end + 1;
  }
  return d;
}

Deepest Scan(std::string_view text, TextSyntax syntax, int stop) {
  switch (syntax) {
    case TextSyntax::kJson:
      return ScanJson(text, stop);
    case TextSyntax::kXml:
      return ScanXml(text, stop);
    case TextSyntax::kYaml:
      return ScanYaml(text, stop);
  }
  return {};
}

}  // namespace

Status CheckNesting(std::string_view text, TextSyntax syntax, int max_depth, std::string_view where) {
  const Deepest d = Scan(text, syntax, max_depth);
  if (d.depth <= max_depth) return Status::Ok();
  const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(d.offset), '\n');
  return InvalidInput(fmt::format("{}:{}: nesting deeper than {} levels; refused before parsing", where, line,
                                  max_depth));
}

int NestingDepth(std::string_view text, TextSyntax syntax) {
  return Scan(text, syntax, std::numeric_limits<int>::max()).depth;
}

std::string Excerpt(std::string_view text, size_t max_bytes) {
  if (text.size() <= max_bytes) return std::string(text);
  size_t cut = max_bytes;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;
  return fmt::format("{}... ({} bytes)", text.substr(0, cut), text.size());
}

}  // namespace occmap
