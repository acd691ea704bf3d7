// Fuzz target: the simulator's scene file (sim/scene_yaml.h), then the scene's own validation.
#include "fuzz/fuzz_util.h"
#include "occmap/sim/scene_yaml.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto spec = occmap::sim::ParseSceneYaml(occmap::fuzz::AsText(data, size), "scene.yaml");
  if (spec.ok()) (void)spec->Validate();
  return 0;
}
