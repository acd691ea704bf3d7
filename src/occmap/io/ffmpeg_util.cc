#include "occmap/io/ffmpeg_util.h"

#include <fmt/core.h>

#include <cstdarg>
#include <mutex>
#include <string>
#include <utility>

namespace occmap {

namespace ffmpeg_internal {

namespace {
thread_local std::string last_log_error;

void CaptureLog(void* avcl, int level, const char* format, va_list args) {
  if (level > AV_LOG_ERROR) return;
  char line[512];
  int print_prefix = 0;
  va_list copy;
  va_copy(copy, args);
  av_log_format_line2(avcl, level, format, copy, line, sizeof(line), &print_prefix);
  va_end(copy);
  std::string text(line);
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  if (!text.empty()) last_log_error = std::move(text);
}
}  // namespace

void InitFfmpeg() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_callback(&CaptureLog); });
}

std::string AvError(int error) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  if (av_strerror(error, text, sizeof(text)) < 0) return fmt::format("FFmpeg error {}", error);
  return text;
}

// The FFmpeg error text, plus the last line FFmpeg logged on this thread when there is one:
// "Invalid data found when processing input (moov atom not found)". Clears the log line.
std::string AvErrorWithLog(int error) {
  std::string text = AvError(error);
  if (!last_log_error.empty()) text += fmt::format(" ({})", std::exchange(last_log_error, std::string()));
  return text;
}

void ClearLog() { last_log_error.clear(); }

}  // namespace ffmpeg_internal

}  // namespace occmap
