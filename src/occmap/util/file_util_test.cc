#include "occmap/util/file_util.h"

#include <gtest/gtest.h>

#include "occmap/util/testing.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

TEST(FileUtil, AtomicWriteRoundTrips) {
  testing::TempDir dir;
  ASSERT_TRUE(WriteFileAtomic(dir / "a.txt", "hello").ok());
  auto text = ReadFileToString(dir / "a.txt");
  ASSERT_TRUE(text.ok());
  EXPECT_EQ(*text, "hello");
  ASSERT_TRUE(WriteFileAtomic(dir / "a.txt", "replaced").ok());
  EXPECT_EQ(*ReadFileToString(dir / "a.txt"), "replaced");
  // No temporary file is left behind.
  int count = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) ++count;
  EXPECT_EQ(count, 1);
}

TEST(FileUtil, WriteIntoMissingFolderFailsAndKeepsNothing) {
  testing::TempDir dir;
  const Status s = WriteFileAtomic(dir / "missing" / "a.txt", "x");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.code(), StatusCode::kIoError);
  EXPECT_NE(s.message().find("cannot create"), std::string::npos) << s.message();
}

TEST(FileUtil, MissingFileIsNotFoundWithItsName) {
  const auto r = ReadFileToString("/nonexistent/occmap.yaml");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "file not found: '/nonexistent/occmap.yaml'");
  EXPECT_EQ(ExitCodeFor(r.status()), 2);
}

TEST(FileUtil, DirectoryIsNotAFile) {
  testing::TempDir dir;
  const auto r = ReadFileToString(dir.path());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("expected a file, found a directory"), std::string::npos);
}

TEST(AtomicFileWriter, NothingAppearsUntilCommit) {
  testing::TempDir dir;
  {
    auto w = AtomicFileWriter::Open(dir / "d.jsonl");
    ASSERT_TRUE(w.ok());
    ASSERT_TRUE((*w)->Append("line 1\n").ok());
    EXPECT_FALSE(fs::exists(dir / "d.jsonl"));
    ASSERT_TRUE((*w)->Append("line 2\n").ok());
    ASSERT_TRUE((*w)->Commit().ok());
  }
  EXPECT_EQ(*ReadFileToString(dir / "d.jsonl"), "line 1\nline 2\n");
  {
    auto w = AtomicFileWriter::Open(dir / "abandoned.jsonl");
    ASSERT_TRUE((*w)->Append("half").ok());
  }  // destroyed without Commit: no file, no temporary
  int count = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) ++count;
  EXPECT_EQ(count, 1);
}

TEST(FileUtil, ResolvePathKeepsAbsoluteAndJoinsRelative) {
  EXPECT_EQ(ResolvePath("/a/b", "/c/d.xml"), fs::path("/c/d.xml"));
  EXPECT_EQ(ResolvePath("/a/b", "../c/d.xml"), fs::path("/a/c/d.xml"));
}

}  // namespace
}  // namespace occmap
