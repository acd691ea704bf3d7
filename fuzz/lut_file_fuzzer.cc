// Fuzz target: the table cache file (lut/lut_file.h). The key is taken from the input's own
// header so that inputs get past the staleness check into the payload.
#include <cstring>

#include "fuzz/fuzz_util.h"
#include "occmap/lut/lut_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  uint64_t key = 0;
  if (size >= 24) std::memcpy(&key, data + 16, 8);
  const auto path = occmap::fuzz::WriteScratch("table.lut", occmap::fuzz::AsText(data, size));
  bool stale = false;
  (void)occmap::LoadGroundLut(path, key, &stale);
  return 0;
}
