#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <charconv>
#include <csignal>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <fstream>

#include <fmt/core.h>

namespace occmap {
namespace fs = std::filesystem;

Status CheckRegularFile(const fs::path& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (st.type() == fs::file_type::not_found) {
    std::error_code link_ec;
    if (fs::is_symlink(fs::symlink_status(path, link_ec))) {
      const fs::path target = fs::read_symlink(path, link_ec);
      return NotFound(fmt::format("file not found: '{}' (a symbolic link to '{}', which does not exist)", path.string(),
                                  target.string()));
    }
    return NotFound(fmt::format("file not found: '{}'", path.string()));
  }
  if (ec || st.type() == fs::file_type::none || st.type() == fs::file_type::unknown) {  // ELOOP, EACCES on a folder
    const bool loop = ec == std::errc::too_many_symbolic_link_levels;
    return InvalidInput(fmt::format("'{}': cannot be read: {}{}", path.string(), ec ? ec.message() : "unknown file type",
                                    loop ? " (a loop of symbolic links)" : ""));
  }
  if (fs::is_directory(st)) {
    return InvalidInput(fmt::format("'{}': expected a file, found a directory", path.string()));
  }
  if (!fs::is_regular_file(st)) {
    const char* kind = fs::is_fifo(st)            ? "a FIFO"
                       : fs::is_character_file(st) ? "a character device"
                       : fs::is_block_file(st)     ? "a block device"
                       : fs::is_socket(st)         ? "a socket"
                                                   : "not a regular file";
    return InvalidInput(fmt::format("'{}': expected a regular file, found {}", path.string(), kind));
  }
  return Status::Ok();
}

Result<std::string> ReadFileToString(const fs::path& path, uint64_t max_bytes) {
  OCCMAP_RETURN_IF_ERROR(CheckRegularFile(path));
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (!ec && size > max_bytes) {
    return ResourceExhausted(fmt::format("'{}': expected at most {} bytes, found {}", path.string(), max_bytes, size));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return NotFound(fmt::format("'{}': cannot open: {}", path.string(), std::strerror(errno)));
  }
  // Read in blocks (istreambuf_iterator goes a character at a time: 10x slower on big tables).
  std::string data;
  if (!ec) data.reserve(static_cast<size_t>(size));
  char buffer[1 << 16];
  while (in.read(buffer, sizeof(buffer)) || in.gcount() > 0) {
    data.append(buffer, static_cast<size_t>(in.gcount()));
    // A file that grows while it is read is held to the same cap.
    if (data.size() > max_bytes) {
      return ResourceExhausted(fmt::format("'{}': expected at most {} bytes, found more", path.string(), max_bytes));
    }
  }
  if (in.bad()) return DataLoss(fmt::format("'{}': read error", path.string()));
  return data;
}

Result<std::string> ReadFileToString(const fs::path& path) { return ReadFileToString(path, kMaxReadBytes); }

int RemoveStaleTemporaries(const fs::path& dir, bool recursive) {
  int removed = 0;
  auto consider = [&](const fs::directory_entry& e) {
    const std::string name = e.path().filename().string();
    if (name.rfind(".tmp-", 0) != 0) return;
    // '.tmp-<name>-<pid>-<n>[.ext]': the pid is the field before the last '-'.
    const size_t last = name.rfind('-');
    const size_t before = last == std::string::npos || last == 0 ? std::string::npos : name.rfind('-', last - 1);
    if (before == std::string::npos || before < 5) return;
    int pid = 0;
    const char* first = name.data() + before + 1;
    const char* end = name.data() + last;
    if (std::from_chars(first, end, pid).ptr != end || pid <= 0) return;
    std::error_code ec;
    if (!e.is_regular_file(ec)) return;
    if (pid != ::getpid() && ::kill(pid, 0) != 0 && errno == ESRCH && fs::remove(e.path(), ec)) ++removed;
  };
  std::error_code ec;
  if (recursive) {
    for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      consider(*it);
    }
  } else {
    for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) consider(*it);
  }
  return removed;
}

namespace {

fs::path TempPathFor(const fs::path& path) {
  static std::atomic<uint64_t> counter{0};
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  return dir / fmt::format(".tmp-{}-{}-{}", path.filename().string(), ::getpid(), counter++);
}

Status WriteAll(int fd, const fs::path& path, const void* data, size_t size) {
  const auto* p = static_cast<const char*>(data);
  size_t written = 0;
  while (written < size) {
    const ssize_t n = ::write(fd, p + written, size - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      return IoError(fmt::format("'{}': write failed: {}", path.string(), std::strerror(errno)));
    }
    written += static_cast<size_t>(n);
  }
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<AtomicFileWriter>> AtomicFileWriter::Open(const fs::path& path) {
  const fs::path tmp = TempPathFor(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return IoError(fmt::format("'{}': cannot create: {}", path.string(), std::strerror(errno)));
  return std::unique_ptr<AtomicFileWriter>(new AtomicFileWriter(path, tmp, fd));
}

AtomicFileWriter::~AtomicFileWriter() {
  if (fd_ >= 0) ::close(fd_);
  if (!tmp_.empty()) ::unlink(tmp_.c_str());
}

Status AtomicFileWriter::Append(std::string_view text) {
  if (fd_ < 0) return Internal(fmt::format("'{}': append after finish", path_.string()));
  return WriteAll(fd_, path_, text.data(), text.size());
}

Status AtomicFileWriter::Finish() {
  if (finished_) return Status::Ok();
  if (fd_ < 0) return Internal(fmt::format("'{}': finished after a failure", path_.string()));
  const int fd = fd_;
  fd_ = -1;
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp_.c_str());
    tmp_.clear();
    return IoError(fmt::format("'{}': flush failed: {}", path_.string(), std::strerror(err)));
  }
  finished_ = true;
  return Status::Ok();
}

Status AtomicFileWriter::Commit() {
  if (finished_ && tmp_.empty()) return Internal(fmt::format("'{}': committed twice", path_.string()));
  OCCMAP_RETURN_IF_ERROR(Finish());
  const fs::path tmp = std::move(tmp_);
  tmp_.clear();
  if (::rename(tmp.c_str(), path_.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    return IoError(fmt::format("'{}': cannot rename into place: {}", path_.string(), std::strerror(err)));
  }
  return Status::Ok();
}

Status WriteFileAtomic(const fs::path& path, std::span<const std::byte> bytes) {
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<AtomicFileWriter> writer, AtomicFileWriter::Open(path));
  OCCMAP_RETURN_IF_ERROR(writer->Append(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size())));
  return writer->Commit();
}

Status WriteFileAtomic(const fs::path& path, std::string_view text) {
  return WriteFileAtomic(path, std::as_bytes(std::span(text.data(), text.size())));
}

std::optional<size_t> FindInvalidUtf8(std::string_view text) {
  const auto* p = reinterpret_cast<const unsigned char*>(text.data());
  const size_t n = text.size();
  size_t i = 0;
  while (i < n) {
    const unsigned char c = p[i];
    if (c < 0x80) {
      ++i;
      continue;
    }
    size_t len = 0;
    uint32_t cp = 0;
    if (c >= 0xC2 && c <= 0xDF) {
      len = 2;
      cp = c & 0x1F;
    } else if (c >= 0xE0 && c <= 0xEF) {
      len = 3;
      cp = c & 0x0F;
    } else if (c >= 0xF0 && c <= 0xF4) {
      len = 4;
      cp = c & 0x07;
    } else {
      return i;  // a continuation byte, an overlong lead (C0, C1) or beyond U+10FFFF (F5..FF)
    }
    if (i + len > n) return i;
    for (size_t k = 1; k < len; ++k) {
      if ((p[i + k] & 0xC0) != 0x80) return i;
      cp = (cp << 6) | (p[i + k] & 0x3F);
    }
    // Overlong forms, UTF-16 surrogates and code points past U+10FFFF.
    if ((len == 3 && cp < 0x800) || (len == 4 && (cp < 0x10000 || cp > 0x10FFFF)) || (cp >= 0xD800 && cp <= 0xDFFF)) {
      return i;
    }
    i += len;
  }
  return std::nullopt;
}

std::optional<std::string> CheckSafeFileName(std::string_view name) {
  constexpr size_t kMaxBytes = 64;
  if (name.empty()) return "expected a non-empty name";
  if (name.size() > kMaxBytes) return fmt::format("expected at most {} bytes, found {}", kMaxBytes, name.size());
  const auto* p = reinterpret_cast<const unsigned char*>(name.data());
  size_t i = 0;
  for (int position = 1; i < name.size(); ++position) {
    const unsigned char c = p[i];
    if (c < 0x80) {
      const bool ok = std::isalnum(c) || c == '_' || c == '-' || c == '.';
      if (!ok || (position == 1 && (c == '.' || c == '-'))) {
        const std::string shown = c >= 0x20 && c < 0x7F ? fmt::format("'{}' ", static_cast<char>(c)) : std::string();
        return fmt::format("character {}(U+{:04X}) at position {} is not allowed{} (letters, digits, '_', '-', '.')",
                           shown, c, position, ok ? " first" : "");
      }
      ++i;
      continue;
    }
    size_t len = c >= 0xF0 ? 4 : c >= 0xE0 ? 3 : c >= 0xC0 ? 2 : 1;
    uint32_t cp = len == 4 ? (c & 0x07u) : len == 3 ? (c & 0x0Fu) : (c & 0x1Fu);
    bool valid = len > 1 && c >= 0xC2 && c <= 0xF4 && i + len <= name.size();
    for (size_t k = 1; valid && k < len; ++k) {
      valid = (p[i + k] & 0xC0) == 0x80;
      cp = (cp << 6) | (p[i + k] & 0x3Fu);
    }
    valid = valid && !(len == 3 && cp < 0x800) && !(len == 4 && (cp < 0x10000 || cp > 0x10FFFF)) &&
            !(cp >= 0xD800 && cp <= 0xDFFF);
    if (!valid) return fmt::format("expected UTF-8, found the byte 0x{:02x} at position {}", c, position);
    const bool allowed = cp >= 0xC0 && !(cp >= 0x2000 && cp <= 0x206F) && !(cp >= 0xFE00 && cp <= 0xFE0F) &&
                         cp != 0xFEFF && !(cp >= 0xFFF0 && cp <= 0xFFFF);
    if (!allowed) {
      return fmt::format("character '{}' (U+{:04X}) at position {} is not allowed (letters, digits, '_', '-', '.')",
                         name.substr(i, len), cp, position);
    }
    i += len;
  }
  return std::nullopt;
}

Status EnsureDirectory(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) {
    return IoError(fmt::format("'{}': cannot create folder: {}", dir.string(),
                               ec ? ec.message() : "not a folder"));
  }
  return Status::Ok();
}

fs::path ResolvePath(const fs::path& base_dir, const fs::path& path) {
  if (path.is_absolute()) return path.lexically_normal();
  return (base_dir / path).lexically_normal();
}

}  // namespace occmap
