// The plain driver of a fuzz target: feeds every file named on the command line (or found in
// a folder named there) to LLVMFuzzerTestOneInput once. Built with the normal compiler, it
// replays the committed corpora in the test suite: a crash or a sanitizer report fails it.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  std::vector<fs::path> files;
  for (int i = 1; i < argc; ++i) {
    if (fs::is_directory(argv[i])) {
      for (const auto& e : fs::recursive_directory_iterator(argv[i])) {
        if (e.is_regular_file()) files.push_back(e.path());
      }
    } else {
      files.emplace_back(argv[i]);
    }
  }
  if (files.empty()) {
    std::fprintf(stderr, "usage: %s FILE_OR_FOLDER...: no inputs found\n", argv[0]);
    return 2;
  }
  for (const auto& f : files) {
    std::ifstream in(f, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
  }
  // The targets' scratch files (fuzz/fuzz_util.h), not left behind by the suite.
  std::error_code ec;
  fs::remove_all(fs::temp_directory_path() / ("occmap-fuzz-" + std::to_string(::getpid())), ec);
  std::printf("%zu inputs replayed\n", files.size());
  return 0;
}
