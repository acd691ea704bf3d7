// The lines of the small line-based text files occmap reads (floor points, frame times), as
// their parsers see them: numbered from 1, a '#' and what follows it cut, blanks trimmed at
// both ends, blank lines skipped. One loop, so that every such file treats comments, CRLF and
// a missing last newline the same way.
//
//   OCCMAP_RETURN_IF_ERROR(ForEachTextLine(text, [&](int64_t line_number, std::string_view line) {
//     return line == "ok" ? Status::Ok() : InvalidInput(fmt::format("{}:{}: expected ok", name, line_number));
//   }));
#pragma once

#include <cstdint>
#include <functional>
#include <string_view>

#include "occmap/util/status.h"

namespace occmap {

// `text` without leading and trailing spaces, tabs and carriage returns.
std::string_view TrimBlanks(std::string_view text);

// Calls `fn` on each line of `text` that is not blank once its comment is cut, in order, with
// its 1-based number; stops at the first error `fn` returns and returns it.
Status ForEachTextLine(std::string_view text, const std::function<Status(int64_t line_number, std::string_view line)>& fn);

}  // namespace occmap
