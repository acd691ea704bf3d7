#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>
#include <vector>

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

// Issue 39: a FIFO, a folder or a loop of links each said as what it is, never opened.
TEST(FileUtil, CheckRegularFileSaysWhatAPathIsInstead) {
  testing::TempDir dir;
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0600), 0);
  fs::create_directory(dir / "folder");
  fs::create_symlink(dir / "loop-b", dir / "loop-a");
  fs::create_symlink(dir / "loop-a", dir / "loop-b");
  fs::create_symlink(dir / "gone", dir / "dangling");
  ASSERT_TRUE(WriteFileAtomic(dir / "file", "x").ok());
  fs::create_symlink(dir / "file", dir / "link");
  EXPECT_TRUE(CheckRegularFile(dir / "file").ok());
  EXPECT_TRUE(CheckRegularFile(dir / "link").ok());
  const struct {
    std::string name;
    StatusCode code;
    std::string message;
  } cases[] = {
      {"fifo", StatusCode::kInvalidInput, "'{0}/fifo': expected a regular file, found a FIFO"},
      {"folder", StatusCode::kInvalidInput, "'{0}/folder': expected a file, found a directory"},
      {"loop-a", StatusCode::kInvalidInput,
       "'{0}/loop-a': cannot be read: Too many levels of symbolic links (a loop of symbolic links)"},
      {"dangling", StatusCode::kNotFound,
       "file not found: '{0}/dangling' (a symbolic link to '{0}/gone', which does not exist)"},
      {"missing", StatusCode::kNotFound, "file not found: '{0}/missing'"},
  };
  for (const auto& c : cases) {
    const Status s = CheckRegularFile(dir / c.name);
    EXPECT_EQ(s.code(), c.code) << c.name;
    EXPECT_EQ(s.message(), fmt::format(fmt::runtime(c.message), dir.path().string())) << c.name;
    // Every reader says the same (a FIFO without a writer would block: it is not opened).
    EXPECT_EQ(ReadFileToString(dir / c.name).status().message(), s.message()) << c.name;
  }
  EXPECT_EQ(ExitCodeFor(CheckRegularFile(dir / "fifo")), 2);
  EXPECT_EQ(ExitCodeFor(CheckRegularFile(dir / "loop-a")), 2);
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

// A device or a FIFO as a site file: refused at once, before anything is read (/dev/zero would
// fill the memory, a FIFO would block the open forever).
TEST(FileUtil, NonRegularFilesAreRefusedWithoutReading) {
  const auto zero = ReadFileToString("/dev/zero");
  ASSERT_FALSE(zero.ok());
  EXPECT_EQ(zero.status().message(), "'/dev/zero': expected a regular file, found a character device");
  EXPECT_EQ(ExitCodeFor(zero.status()), 2);
  testing::TempDir dir;
  const fs::path fifo = dir / "site.yaml";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto r = ReadFileToString(fifo);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), fmt::format("'{}': expected a regular file, found a FIFO", fifo.string()));
}

TEST(FileUtil, FilesOverTheCapAreRefused) {
  testing::TempDir dir;
  ASSERT_TRUE(WriteFileAtomic(dir / "big.yaml", std::string(1001, 'x')).ok());
  EXPECT_TRUE(ReadFileToString(dir / "big.yaml", 1001).ok());
  const auto r = ReadFileToString(dir / "big.yaml", 1000);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), fmt::format("'{}': expected at most 1000 bytes, found 1001", (dir / "big.yaml").string()));
  EXPECT_EQ(ExitCodeFor(r.status()), 2);
}

// kill -9 leaves '.tmp-*' files; the next start removes those of dead processes only.
TEST(FileUtil, StaleTemporariesOfDeadProcessesAreRemoved) {
  testing::TempDir dir;
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ASSERT_GT(child, 0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);  // reaped: its pid names no process now
  const pid_t alive = ::getppid();
  fs::create_directories(dir / "backgrounds");
  const std::vector<std::string> stale = {fmt::format(".tmp-summary.json-{}-0", child),
                                          fmt::format(".tmp-mosaic-{}-3.mp4", child)};
  const std::vector<std::string> kept = {fmt::format(".tmp-summary.json-{}-0", alive), ".tmp-notes", "summary.json",
                                         fmt::format("tmp-x-{}-0", child), fmt::format(".tmp-{}-0", child)};
  for (const auto& n : stale) ASSERT_TRUE(WriteFileAtomic(dir / n, "x").ok());
  for (const auto& n : kept) ASSERT_TRUE(WriteFileAtomic(dir / n, "x").ok());
  ASSERT_TRUE(WriteFileAtomic(dir / "backgrounds" / stale[0], "x").ok());
  EXPECT_EQ(RemoveStaleTemporaries(dir.path(), /*recursive=*/false), 2);
  EXPECT_TRUE(fs::exists(dir / "backgrounds" / stale[0]));
  EXPECT_EQ(RemoveStaleTemporaries(dir.path(), /*recursive=*/true), 1);
  for (const auto& n : stale) EXPECT_FALSE(fs::exists(dir / n)) << n;
  for (const auto& n : kept) EXPECT_TRUE(fs::exists(dir / n)) << n;
}

TEST(CheckSafeFileName, AcceptsIdsOfEverySiteAndLettersBeyondAscii) {
  for (const char* id : {"C1", "cam_2", "gopro6.3", "Camera-4", "caf\xc3\xa9", "\xe5\x85\xa5\xe5\x8f\xa3"}) {
    EXPECT_EQ(CheckSafeFileName(id), std::nullopt) << id;
  }
}

TEST(CheckSafeFileName, NamesTheOffendingCharacterAndItsPosition) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"../../escaped", "character '.' (U+002E) at position 1 is not allowed first (letters, digits, '_', '-', '.')"},
      {"a/b", "character '/' (U+002F) at position 2 is not allowed (letters, digits, '_', '-', '.')"},
      {"a\\b", "character '\\' (U+005C) at position 2 is not allowed (letters, digits, '_', '-', '.')"},
      {"cam\n1", "character (U+000A) at position 4 is not allowed (letters, digits, '_', '-', '.')"},
      {std::string("ca\0m", 4), "character (U+0000) at position 3 is not allowed (letters, digits, '_', '-', '.')"},
      {"-x", "character '-' (U+002D) at position 1 is not allowed first (letters, digits, '_', '-', '.')"},
      {"a b", "character ' ' (U+0020) at position 2 is not allowed (letters, digits, '_', '-', '.')"},
      {"caf\xc3\xa9\xff", "expected UTF-8, found the byte 0xff at position 5"},
      {"a\xc0\xaf", "expected UTF-8, found the byte 0xc0 at position 2"},  // overlong '/'
      {"a\xe2\x80\xae", "character '\xe2\x80\xae' (U+202E) at position 2 is not allowed (letters, digits, '_', '-', '.')"},
      {"", "expected a non-empty name"},
      {std::string(65, 'a'), "expected at most 64 bytes, found 65"},
  };
  for (const auto& [name, message] : cases) EXPECT_EQ(CheckSafeFileName(name).value_or("ok"), message) << name;
}

TEST(FindInvalidUtf8, FindsTheFirstBadByte) {
  EXPECT_EQ(FindInvalidUtf8("plain"), std::nullopt);
  EXPECT_EQ(FindInvalidUtf8("caf\xc3\xa9 \xf0\x9f\x98\x80"), std::nullopt);
  EXPECT_EQ(FindInvalidUtf8("ab\x80"), 2u);              // a lone continuation byte
  EXPECT_EQ(FindInvalidUtf8("ab\xc3"), 2u);              // cut short
  EXPECT_EQ(FindInvalidUtf8("\xed\xa0\x80"), 0u);        // a UTF-16 surrogate
  EXPECT_EQ(FindInvalidUtf8("x\xf4\x90\x80\x80"), 1u);    // past U+10FFFF
  EXPECT_EQ(FindInvalidUtf8("x\xe0\x80\xaf"), 1u);        // overlong
}

TEST(FileUtil, ResolvePathKeepsAbsoluteAndJoinsRelative) {
  EXPECT_EQ(ResolvePath("/a/b", "/c/d.xml"), fs::path("/c/d.xml"));
  EXPECT_EQ(ResolvePath("/a/b", "../c/d.xml"), fs::path("/a/c/d.xml"));
}

}  // namespace
}  // namespace occmap
