// Fuzz target: the run-output readers of `occmap eval` (eval/run_outputs.h): detections.jsonl
// and tracks.jsonl.
#include "fuzz/fuzz_util.h"
#include "occmap/eval/run_outputs.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text = occmap::fuzz::AsText(data, size);
  (void)occmap::ParseDetections(text, "detections.jsonl");
  (void)occmap::ParseTracks(text, "tracks.jsonl");
  return 0;
}
