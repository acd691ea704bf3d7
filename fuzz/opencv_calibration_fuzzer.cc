// Fuzz target: OpenCV FileStorage calibrations (calib/opencv_storage.h): intrinsic and
// extrinsic files, the input split at its first NUL byte, then the two read together.
#include "fuzz/fuzz_util.h"
#include "occmap/calib/opencv_storage.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto [intr_text, extr_text] = occmap::fuzz::SplitAtNul(occmap::fuzz::AsText(data, size));
  const auto intr = occmap::fuzz::WriteScratch("intr.xml", intr_text);
  const auto extr = occmap::fuzz::WriteScratch("extr.xml", extr_text);
  (void)occmap::ReadOpenCvIntrinsics(intr);
  (void)occmap::ReadOpenCvExtrinsics(extr);
  (void)occmap::ReadOpenCvCalibration(intr, extr, 0.01, occmap::ImageSize{640, 480});
  return 0;
}
