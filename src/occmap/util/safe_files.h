// Guards on the files occmap reads and the names it writes: size caps, non-regular files
// refused, names safe as file names, temporaries of killed runs removed.
//
// Every reader goes through ReadFileToString (util/file_util.h), which refuses folders,
// devices, FIFOs and sockets without opening them and holds files to a size cap:
//   OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, kMaxTextFileBytes));
//   if (auto bad = CheckSafeFileName(id)) return field.Error(*bad);
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "occmap/util/status.h"

namespace occmap {

// Every reader's cap: no input of occmap is this large, and a file that claims to be (a growing
// log, a device) is refused before it fills the memory.
inline constexpr uint64_t kMaxReadBytes = uint64_t{1} << 30;  // 1 GiB
// Text descriptions (site, scene, calibration files) are small.
inline constexpr uint64_t kMaxTextFileBytes = uint64_t{64} << 20;  // 64 MiB

// Reads a regular file (symbolic links followed) of at most `max_bytes`: a folder, a device
// (/dev/zero), a FIFO or a socket is refused without opening it (a FIFO would block forever).
// ReadFileToString(path) is this with kMaxReadBytes.
Result<std::string> ReadFileToString(const std::filesystem::path& path, uint64_t max_bytes);

// OK when `path` (symbolic links followed) is a regular file, checked without opening it; else
// what it is, naming the path: "file not found: 'p'" (kNotFound; a symbolic link to a missing
// file says so), "'p': expected a file, found a directory", "'p': expected a regular file, found
// a FIFO" (a device, a socket), "'p': cannot be read: Too many levels of symbolic links (a loop
// of symbolic links)" (kInvalidInput).
Status CheckRegularFile(const std::filesystem::path& path);

// Removes the '.tmp-<name>-<pid>-<n>' files that util/file_util and io/video_writer write, in
// `dir` (and its sub-folders when `recursive`), whose process is gone: what a killed run
// (kill -9) could not remove. Files of running processes and every other name are left alone.
// Returns how many were removed; errors are ignored (a clean-up never stops a run).
int RemoveStaleTemporaries(const std::filesystem::path& dir, bool recursive);

// Names that become file names (camera ids, site names: backgrounds/<id>.png, cache files):
// 1..64 bytes of valid UTF-8 in a safe alphabet: ASCII letters and digits, '_', '-', '.', and
// letters beyond ASCII (U+00C0 and up, bar invisible and direction marks U+2000..U+206F,
// U+FE00..U+FE0F, U+FEFF, U+FFF0..U+FFFF); no leading '.' or '-'. No '/', '\', spaces, control
// characters or NUL. Returns what is wrong, with the character and its 1-based position
// ("character '/' (U+002F) at position 3 is not allowed ..."), or nothing when the name is safe.
std::optional<std::string> CheckSafeFileName(std::string_view name);

// The offset of the first byte that is not part of valid UTF-8 (overlong forms and surrogates
// included), or nothing.
std::optional<size_t> FindInvalidUtf8(std::string_view text);

}  // namespace occmap
