// Fuzz target: GoPro JSON calibrations (calib/gopro_json.h): intrinsic and extrinsic JSON, the
// input split at its first NUL byte.
#include "fuzz/fuzz_util.h"
#include "occmap/calib/gopro_json.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto [intr_text, extr_text] = occmap::fuzz::SplitAtNul(occmap::fuzz::AsText(data, size));
  const auto intr = occmap::fuzz::WriteScratch("intr.json", intr_text);
  const auto extr = occmap::fuzz::WriteScratch("extr.json", extr_text);
  (void)occmap::ReadGoProCalibration(intr, extr, std::nullopt);
  (void)occmap::ReadGoProCalibration(intr, extr, 0.01);
  return 0;
}
