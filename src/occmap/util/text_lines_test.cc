#include "occmap/util/text_lines.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

namespace occmap {
namespace {

std::vector<std::pair<int64_t, std::string>> Lines(std::string_view text) {
  std::vector<std::pair<int64_t, std::string>> out;
  EXPECT_TRUE(ForEachTextLine(text, [&](int64_t n, std::string_view line) {
                out.emplace_back(n, std::string(line));
                return Status::Ok();
              }).ok());
  return out;
}

TEST(TextLines, CommentsBlanksAndBlankLinesAreSkippedWithTheirNumbersKept) {
  using L = std::vector<std::pair<int64_t, std::string>>;
  EXPECT_EQ(Lines("a\n\n  # note\n\tb c  # why\r\n\r\nd"), (L{{1, "a"}, {4, "b c"}, {6, "d"}}));
  EXPECT_EQ(Lines("a\n"), (L{{1, "a"}}));
  EXPECT_EQ(Lines(""), L{});
  EXPECT_EQ(Lines("\n\n#\n"), L{});
}

TEST(TextLines, StopsAtTheFirstError) {
  std::vector<int64_t> seen;
  const Status s = ForEachTextLine("1\n2\n3\n", [&](int64_t n, std::string_view) {
    seen.push_back(n);
    return n == 2 ? InvalidInput("f:2: bad") : Status::Ok();
  });
  EXPECT_EQ(s.message(), "f:2: bad");
  EXPECT_EQ(seen, (std::vector<int64_t>{1, 2}));
}

TEST(TextLines, TrimBlanksCutsSpacesTabsAndCarriageReturns) {
  EXPECT_EQ(TrimBlanks(" \t x y\r "), "x y");
  EXPECT_EQ(TrimBlanks(" \r\t"), "");
}

}  // namespace
}  // namespace occmap
