// Fuzz target: the site file (site/site.h ParseSite), the one file a user writes. Relative
// paths resolve in the scratch folder, where nothing is: the reader's own checks are fuzzed.
#include "fuzz/fuzz_util.h"
#include "occmap/site/site.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto dir = occmap::fuzz::ScratchDir();
  (void)occmap::ParseSite(occmap::fuzz::AsText(data, size), dir / "site.yaml");
  return 0;
}
