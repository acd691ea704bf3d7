// Fuzz target: the ground-truth readers of `occmap eval`: a dataset's ground_truth.jsonl
// (sim/ground_truth.h) and a benchmark's annotation file (eval/benchmark_annotations.h).
#include "fuzz/fuzz_util.h"
#include "occmap/eval/benchmark_annotations.h"
#include "occmap/sim/ground_truth.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text = occmap::fuzz::AsText(data, size);
  const auto path = occmap::fuzz::WriteScratch("ground_truth.jsonl", text);
  (void)occmap::ReadGroundTruth(path);
  (void)occmap::ParseAnnotationFile(text, "00000000.json", occmap::BenchmarkFormat::kWildtrack);
  return 0;
}
