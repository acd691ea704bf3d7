// Guards on text handed to recursive parsers and on values echoed in messages.
//
// The parsers occmap uses recurse once per nesting level while parsing (OpenCV's FileStorage)
// or while printing and copying what they parsed (nlohmann-json's dump()): a 200 KB text
// nested 100,000 deep overflows the stack. CheckNesting reads the text once, without recursion,
// and refuses nesting deeper than a limit no real input comes near, before any parser sees it.
// Excerpt cuts a value for a message, so that a 10 MB field is never echoed whole.
//
//   OCCMAP_RETURN_IF_ERROR(CheckNesting(text, TextSyntax::kJson, kMaxNestingDepth, path.string()));
//   return InvalidInput(fmt::format("{}: expected a number, found {}", where, Excerpt(j.dump())));
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "occmap/util/status.h"

namespace occmap {

// Deeper than any file or request occmap reads (a site request's polygons are 4 deep, an
// OpenCV matrix 3), and shallow enough for any parser's recursion on a thread's stack.
inline constexpr int kMaxNestingDepth = 64;

enum class TextSyntax {
  kJson,  // [ ] and { } outside strings
  kXml,   // elements: <a> opens, </a> closes; <a/>, <?...?>, <!...>, comments and CDATA do not nest
  kYaml,  // flow [ ] { } outside quotes and comments, plus block nesting: indentation levels and
          // the "- " / "? " entries opened on one line ("- - - x" is 3 deep)
};

// Ok when no point of `text` is nested deeper than `max_depth`; else an InvalidInput naming
// `where` and the line: "'f.xml':12: nesting deeper than 64 levels; refused before parsing".
// An unbalanced text is left to the parser (it says what is wrong better).
Status CheckNesting(std::string_view text, TextSyntax syntax, int max_depth, std::string_view where);

// The deepest nesting of `text` (as CheckNesting counts it), for tests.
int NestingDepth(std::string_view text, TextSyntax syntax);

// `text` when it has at most `max_bytes` bytes, else its first bytes (cut at a character's
// start, never inside a UTF-8 sequence) followed by "... (N bytes)".
std::string Excerpt(std::string_view text, size_t max_bytes = 120);

}  // namespace occmap
