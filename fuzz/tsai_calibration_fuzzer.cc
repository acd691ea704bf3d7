// Fuzz target: Tsai calibrations in YAML (calib/tsai_yaml.h), a file of one camera or of several.
#include "fuzz/fuzz_util.h"
#include "occmap/calib/tsai_yaml.h"
#include "occmap/geometry/tsai_camera.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = occmap::fuzz::WriteScratch("tsai.yaml", occmap::fuzz::AsText(data, size));
  for (const char* camera : {"", "c1"}) {
    auto p = occmap::ReadTsaiYaml(path, camera, 0.001);
    if (p.ok()) (void)occmap::TsaiCamera::Create(*p);
  }
  return 0;
}
