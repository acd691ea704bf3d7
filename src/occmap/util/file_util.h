// File helpers: whole-file reads with clear errors, and atomic writes.
//
// Every output of occmap is written atomically: the bytes go to a temporary file in the same
// folder, are flushed to disk, and the file is renamed over the target. A failed or
// interrupted run never leaves a half-written output; at worst a stray '.tmp-*' file.
//
//   OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path));
//   OCCMAP_RETURN_IF_ERROR(WriteFileAtomic(out / "summary.json", json_text));
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "occmap/util/status.h"

namespace occmap {

Result<std::string> ReadFileToString(const std::filesystem::path& path);

Status WriteFileAtomic(const std::filesystem::path& path, std::span<const std::byte> bytes);
Status WriteFileAtomic(const std::filesystem::path& path, std::string_view text);

// Streams an output to a temporary file next to `path`; Commit() flushes it to disk and renames
// it into place. Destroyed without Commit(), it removes the temporary: a failed or interrupted
// run never leaves a half-written file under the final name. Several outputs that appear
// together or not at all: Finish() each (flushed to disk, a full disk found then), and Commit()
// them only when every Finish worked.
class AtomicFileWriter {
 public:
  static Result<std::unique_ptr<AtomicFileWriter>> Open(const std::filesystem::path& path);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;
  Status Append(std::string_view text);
  Status Finish();  // flushed and closed, not renamed yet; after a failure the temporary is gone
  Status Commit();  // Finish (when not done) then the rename
  const std::filesystem::path& path() const { return path_; }

 private:
  AtomicFileWriter(std::filesystem::path path, std::filesystem::path tmp, int fd)
      : path_(std::move(path)), tmp_(std::move(tmp)), fd_(fd) {}
  std::filesystem::path path_, tmp_;  // tmp_ empty once renamed or removed
  int fd_ = -1;
  bool finished_ = false;
};

// Creates the folder and its parents; an error names the folder.
Status EnsureDirectory(const std::filesystem::path& dir);

// Resolves `path` against `base_dir` unless it is absolute; normalises '..' lexically.
std::filesystem::path ResolvePath(const std::filesystem::path& base_dir,
                                  const std::filesystem::path& path);

}  // namespace occmap
