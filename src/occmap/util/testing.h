// Test helpers: where the shared datasets are, and a temporary folder per test.
//
//   TEST(Foo, ReadsWildtrack) {
//     OCCMAP_REQUIRE_DATASETS(root);   // skips with a message when ../shared is absent
//     ... root / "wildtrack" ...
//   }
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <optional>
#include <string>

namespace occmap::testing {

// The shared datasets folder (env OCCMAP_DATASETS, set by CTest), if it exists.
std::optional<std::filesystem::path> DatasetsDir();

// A fresh empty folder under the system temp dir, removed when the object dies.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

void WriteText(const std::filesystem::path& path, const std::string& text);

}  // namespace occmap::testing

#define OCCMAP_REQUIRE_DATASETS(var)                                                      \
  const auto var##_opt = ::occmap::testing::DatasetsDir();                                \
  if (!var##_opt) GTEST_SKIP() << "shared datasets not found (../shared/datasets); skipped"; \
  const std::filesystem::path var = *var##_opt
