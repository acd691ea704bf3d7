#include "occmap/util/testing.h"

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <random>

namespace occmap::testing {
namespace fs = std::filesystem;

std::optional<fs::path> DatasetsDir() {
  const char* env = std::getenv("OCCMAP_DATASETS");
  fs::path dir = env != nullptr ? fs::path(env) : fs::path("../shared/datasets");
  std::error_code ec;
  if (fs::is_directory(dir / "wildtrack", ec)) return fs::canonical(dir);
  return std::nullopt;
}

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  std::random_device rd;
  path_ = fs::temp_directory_path() /
          ("occmap-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + "-" +
           std::to_string(rd()));
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

}  // namespace occmap::testing
