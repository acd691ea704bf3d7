// Helpers for the fuzz targets (fuzz/*_fuzzer.cc): readers that take a path get the input
// through a file of this process's own, rewritten for every input.
//
// Each target defines LLVMFuzzerTestOneInput; built with clang's -fsanitize=fuzzer (the `fuzz`
// preset, scripts/fuzz.sh) it is a libFuzzer binary, built with the normal compiler and
// fuzz/regression_main.cc it replays the committed corpus in the test suite.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace occmap::fuzz {

// A scratch folder of this process (removed by the OS's tmp cleaning; names hold the pid).
inline const std::filesystem::path& ScratchDir() {
  static const std::filesystem::path dir = [] {
    auto d = std::filesystem::temp_directory_path() / ("occmap-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

// Writes `bytes` to ScratchDir()/name and returns the path.
inline std::filesystem::path WriteScratch(const std::string& name, std::string_view bytes) {
  const auto path = ScratchDir() / name;
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path;
}

inline std::string_view AsText(const uint8_t* data, size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// Two inputs from one: split at the first NUL byte (the second part empty without one).
inline std::pair<std::string_view, std::string_view> SplitAtNul(std::string_view text) {
  const size_t nul = text.find('\0');
  if (nul == std::string_view::npos) return {text, {}};
  return {text.substr(0, nul), text.substr(nul + 1)};
}

}  // namespace occmap::fuzz
