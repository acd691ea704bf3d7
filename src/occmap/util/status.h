// Status and Result<T>: how bad input and failed I/O travel up to main().
//
// The library never prints and never exits. A function that can fail on bad input returns a
// Status (or a Result<T> carrying either a value or a Status). The message names the file, the
// line or field, what was expected and what was found, e.g.
//   site.yaml:14: cameras[2].calibration.intrinsic: file not found: 'intr_C3.xml'
// main() is the one place that turns a Status into text and an exit code (ExitCodeFor).
//
//   Result<int> ParseCount(std::string_view s);
//   OCCMAP_ASSIGN_OR_RETURN(int n, ParseCount(text));
//   if (n < 0) return InvalidInput(fmt::format("count: expected >= 0, found {}", n));
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace occmap {

enum class StatusCode {
  kOk = 0,
  kInvalidInput,       // malformed file, option or stream content (exit code 2)
  kNotFound,           // a named input does not exist (exit code 2)
  kDataLoss,           // a file is truncated or corrupt (exit code 2)
  kResourceExhausted,  // the input asks for more memory than allowed (exit code 2)
  kIoError,            // an output could not be written (exit code 1)
  kInternal,           // our own failure that is not a bug in the input (exit code 1)
};

class [[nodiscard]] Status {
 public:
  Status() = default;  // OK
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return Status(); }
  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }

  // Returns a copy whose message is "<context>: <message>", to add where an error happened.
  Status WithContext(std::string_view context) const;

  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

Status InvalidInput(std::string message);
Status NotFound(std::string message);
Status DataLoss(std::string message);
Status ResourceExhausted(std::string message);
Status IoError(std::string message);
Status Internal(std::string message);

// Process exit code for a failed status: 2 for bad input, 1 otherwise.
int ExitCodeFor(const Status& status);

[[noreturn]] void CheckFailed(const char* file, int line, const char* condition,
                              std::string_view message);

template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : data_(std::move(value)) {}  // NOLINT: implicit by design
  Result(Status status) : data_(std::move(status)) {  // NOLINT: implicit by design
    if (std::get<Status>(data_).ok()) CheckFailed(__FILE__, __LINE__, "!status.ok()", "Result from OK status");
  }

  bool ok() const { return std::holds_alternative<T>(data_); }
  const Status& status() const {
    static const Status kOkStatus;
    return ok() ? kOkStatus : std::get<Status>(data_);
  }
  T& value() & { CheckOk(); return std::get<T>(data_); }
  const T& value() const& { CheckOk(); return std::get<T>(data_); }
  T&& value() && { CheckOk(); return std::get<T>(std::move(data_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

 private:
  void CheckOk() const {
    if (!ok()) CheckFailed(__FILE__, __LINE__, "ok()", std::get<Status>(data_).message());
  }
  std::variant<T, Status> data_;
};

}  // namespace occmap

// Our own bugs: abort with a message. Never used to validate input.
#define OCCMAP_CHECK(cond, msg)                                               \
  do {                                                                        \
    if (!(cond)) ::occmap::CheckFailed(__FILE__, __LINE__, #cond, (msg));     \
  } while (false)

#ifdef NDEBUG
#define OCCMAP_DCHECK(cond, msg) \
  do {                           \
  } while (false)
#else
#define OCCMAP_DCHECK(cond, msg) OCCMAP_CHECK(cond, msg)
#endif

#define OCCMAP_CONCAT_INNER(a, b) a##b
#define OCCMAP_CONCAT(a, b) OCCMAP_CONCAT_INNER(a, b)

#define OCCMAP_RETURN_IF_ERROR(expr)             \
  do {                                           \
    ::occmap::Status occmap_status_ = (expr);    \
    if (!occmap_status_.ok()) return occmap_status_; \
  } while (false)

#define OCCMAP_ASSIGN_OR_RETURN_IMPL(result, lhs, expr) \
  auto result = (expr);                                 \
  if (!result.ok()) return result.status();             \
  lhs = std::move(result).value()

#define OCCMAP_ASSIGN_OR_RETURN(lhs, expr) \
  OCCMAP_ASSIGN_OR_RETURN_IMPL(OCCMAP_CONCAT(occmap_result_, __LINE__), lhs, expr)
