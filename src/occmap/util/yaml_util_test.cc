#include "occmap/util/yaml_util.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

namespace occmap {
namespace {

YamlField Parse(const std::string& text) { return ParseYaml(text, "t.yaml").value(); }

TEST(YamlField, ReadsTypedValues) {
  const YamlField root = Parse("a: 1.5\nb: 7\nc: [1, 2, 3]\nd: true\ne: text\n");
  EXPECT_EQ(*root.GetDouble("a"), 1.5);
  EXPECT_EQ(*root.GetInt("b"), 7);
  EXPECT_EQ(*root.GetDoubles("c", 3), (std::vector<double>{1, 2, 3}));
  EXPECT_TRUE(*root.GetBool("d", false));
  EXPECT_EQ(*root.GetString("e"), "text");
  EXPECT_EQ(*root.GetDouble("missing", 2.0), 2.0);
}

struct BadCase {
  const char* text;
  const char* expected_message;
};

class YamlFieldBadInput : public ::testing::TestWithParam<BadCase> {};

TEST_P(YamlFieldBadInput, NamesFileLineFieldExpectedAndFound) {
  const YamlField root = Parse(GetParam().text);
  Status s;
  auto floor = root.Get("floor");
  if (!floor.ok()) {
    s = floor.status();
  } else {
    s = floor->CheckKeys({"cell_size_m", "size_m"});
    if (s.ok()) s = floor->GetDouble("cell_size_m").status();
    if (s.ok()) s = floor->GetDoubles("size_m", 2).status();
  }
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.message(), GetParam().expected_message);
}

INSTANTIATE_TEST_SUITE_P(
    Table, YamlFieldBadInput,
    ::testing::Values(
        BadCase{"other: 1\n", "t.yaml:1: missing required field 'floor'"},
        BadCase{"floor:\n  cell_size_m: abc\n  size_m: [1, 2]\n",
                "t.yaml:2: floor.cell_size_m: expected a finite number, found 'abc'"},
        BadCase{"floor:\n  cell_size_m: .nan\n  size_m: [1, 2]\n",
                "t.yaml:2: floor.cell_size_m: expected a finite number, found '.nan'"},
        BadCase{"floor:\n  cell_size_m: nan\n  size_m: [1, 2]\n",
                "t.yaml:2: floor.cell_size_m: expected a finite number, found 'nan'"},
        BadCase{"floor:\n  cell_size_m: 0.1\n  size_m: [1, 2, 3]\n",
                "t.yaml:3: floor.size_m: expected a list of 2 numbers, found 3"},
        BadCase{"floor:\n  cell_size_m: 0.1\n  size_m: 4\n",
                "t.yaml:3: floor.size_m: expected a list of 2 numbers, found '4'"},
        BadCase{"floor:\n  cell_size: 0.1\n",
                "t.yaml:2: floor: unknown field 'cell_size' (did you mean 'cell_size_m'?)"},
        BadCase{"floor:\n  colour: red\n",
                "t.yaml:2: floor: unknown field 'colour' (expected one of: cell_size_m, size_m)"},
        BadCase{"floor: 3\n", "t.yaml:1: floor: expected a map, found '3'"},
        // Keys that are not names (found by the scene_yaml fuzzer: yaml-cpp threw).
        BadCase{"floor: {!t_m: [1, 2], size_m: 3}\n", "t.yaml:1: floor: expected a field name, found a list of 2"},
        BadCase{"floor:\n  ?\n  : 1\n", "t.yaml:3: floor: expected a field name, found a map"},
        BadCase{"floor:\n  ? [a, b]\n  : 1\n", "t.yaml:2: floor: expected a field name, found a list of 2"}));

TEST(YamlField, SyntaxErrorNamesLineAndColumn) {
  const auto r = ParseYaml("a: [1, 2\nb: 3\n", "bad.yaml");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message().rfind("bad.yaml:", 0), 0u) << r.status().message();
  EXPECT_NE(r.status().message().find("YAML syntax error"), std::string::npos);
}

// yaml-cpp 0.7 keeps the first of two equal keys without a word: both are refused, at any depth.
TEST(ParseYaml, DuplicateKeysAreRefusedWithBothLines) {
  const auto top = ParseYaml("a: 1\nb: 2\na: 3\n", "d.yaml");
  ASSERT_FALSE(top.ok());
  EXPECT_EQ(top.status().message(), "d.yaml:3: duplicate key 'a' (first at line 1; YAML keys must be unique)");
  const auto nested = ParseYaml("x:\n  - {k: 1}\n  - k: 1\n    j: 2\n    k: 3\n", "d.yaml");
  ASSERT_FALSE(nested.ok());
  EXPECT_EQ(nested.status().message(), "d.yaml:5: x[1]: duplicate key 'k' (first at line 3; YAML keys must be unique)");
  EXPECT_TRUE(ParseYaml("a: {k: 1}\nb: {k: 1}\n", "d.yaml").ok());  // equal keys in different maps
}

TEST(ParseYaml, BytesThatAreNotUtf8AreRefusedWithLineAndColumn) {
  const auto r = ParseYaml("a: 1\nname: ca\xffm\n", "u.yaml");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "u.yaml:2:9: expected UTF-8 text, found the byte 0xff");
  EXPECT_EQ(ExitCodeFor(r.status()), 2);
  EXPECT_TRUE(ParseYaml("name: caf\xc3\xa9\n", "u.yaml").ok());
}

TEST(ParseYaml, AliasBombsAndDeepNestingAreRefused) {
  std::string bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n";
  for (char c = 'b'; c <= 'h'; ++c) {
    bomb += fmt::format("{0}: &{0} [", c);
    for (int i = 0; i < 10; ++i) bomb += fmt::format("{}*{}", i ? ", " : "", static_cast<char>(c - 1));
    bomb += "]\n";
  }
  const auto r = ParseYaml(bomb, "b.yaml");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "b.yaml: expected at most 2000000 YAML nodes (aliases included), found more");
  const auto deep = ParseYaml("a: " + std::string(300, '[') + std::string(300, ']') + "\n", "n.yaml");
  ASSERT_FALSE(deep.ok());
  EXPECT_NE(deep.status().message().find("expected at most 256 levels of nesting"), std::string::npos)
      << deep.status().message();
}

TEST(ParseFiniteDouble, RejectsPartialAndNonFinite) {
  EXPECT_EQ(ParseFiniteDouble("1e3"), 1000.0);
  EXPECT_EQ(ParseFiniteDouble("-0.5"), -0.5);
  EXPECT_FALSE(ParseFiniteDouble("1.5x"));
  EXPECT_FALSE(ParseFiniteDouble("inf"));
  EXPECT_FALSE(ParseFiniteDouble(""));
  EXPECT_FALSE(ParseFiniteDouble("1e999"));
}

}  // namespace
}  // namespace occmap
