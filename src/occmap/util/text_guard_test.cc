#include "occmap/util/text_guard.h"

#include <gtest/gtest.h>

#include <string>

namespace occmap {
namespace {

std::string Repeat(std::string_view s, int n) {
  std::string out;
  for (int i = 0; i < n; ++i) out += s;
  return out;
}

TEST(TextGuard, JsonDepthCountsBracketsOutsideStrings) {
  EXPECT_EQ(NestingDepth(R"({"a": [[1, 2], {"b": "[[[[\"]]"}]})", TextSyntax::kJson), 3);
  EXPECT_EQ(NestingDepth("42", TextSyntax::kJson), 0);
}

TEST(TextGuard, DeepJsonIsRefusedWithItsLine) {
  const std::string deep = "{\n\"a\":\n" + Repeat("[", 100000) + Repeat("]", 100000) + "}";
  const Status s = CheckNesting(deep, TextSyntax::kJson, kMaxNestingDepth, "body");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.message(), "body:3: nesting deeper than 64 levels; refused before parsing");
  EXPECT_TRUE(CheckNesting(Repeat("[", 64) + Repeat("]", 64), TextSyntax::kJson, 64, "b").ok());
  EXPECT_FALSE(CheckNesting(Repeat("[", 65) + Repeat("]", 65), TextSyntax::kJson, 64, "b").ok());
}

TEST(TextGuard, XmlDepthCountsElementsNotCommentsOrEmptyElements) {
  const std::string xml = R"(<?xml version="1.0"?>
<!-- <a><b><c> -->
<opencv_storage>
<camera_matrix type_id="opencv-matrix"><rows>3</rows><data a="x>y"><![CDATA[<p><q>]]></data><e/></camera_matrix>
</opencv_storage>)";
  EXPECT_EQ(NestingDepth(xml, TextSyntax::kXml), 3);
  const std::string deep = "<opencv_storage>" + Repeat("<a>", 30000) + Repeat("</a>", 30000) + "</opencv_storage>";
  EXPECT_EQ(NestingDepth(deep, TextSyntax::kXml), 30001);
  EXPECT_FALSE(CheckNesting(deep, TextSyntax::kXml, kMaxNestingDepth, "f.xml").ok());
}

TEST(TextGuard, YamlDepthCountsFlowAndBlockNesting) {
  const std::string yaml = R"(%YAML:1.0
---
camera_matrix: !!opencv-matrix
   rows: 3
   data: [ 1., 0., 2.,
      0., 1., 2. ]  # a comment with [[[[
name: "a [ b"
list:
  - - x
    - y
)";
  // An upper bound: the entry after the last "- " counts as a level too (map, seq, seq, x).
  EXPECT_EQ(NestingDepth(yaml, TextSyntax::kYaml), 4);
  const std::string flow = "%YAML:1.0\na: " + Repeat("[", 50000) + Repeat("]", 50000) + "\n";
  const Status s = CheckNesting(flow, TextSyntax::kYaml, kMaxNestingDepth, "f.yml");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.message(), "f.yml:2: nesting deeper than 64 levels; refused before parsing");
  EXPECT_FALSE(CheckNesting("a:\n" + Repeat("- ", 100) + "x\n", TextSyntax::kYaml, kMaxNestingDepth, "f").ok());
}

TEST(TextGuard, ExcerptCutsLongTextAtACharacterStart) {
  EXPECT_EQ(Excerpt("short"), "short");
  EXPECT_EQ(Excerpt(std::string(10 << 20, 'x'), 4), "xxxx... (10485760 bytes)");
  // "é" is two bytes: a cut inside it backs off to its start.
  EXPECT_EQ(Excerpt("aé", 2), "a... (3 bytes)");
}

}  // namespace
}  // namespace occmap
