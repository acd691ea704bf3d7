// Fuzz target: the protections `occmap fuse` sends the edges' adaptive backgrounds as an edge
// takes them (pipeline/protection_message.h DecodeProtectionMessage), then what the edge does
// with one: the occupied runs marked in a map of the expected grid. The edge's site is fixed:
// table key 0x1234, settings key 0x5678, a grid of 100 cells (the protection_message test's).
//
// Input: one MQTT payload. A message that decodes must encode back to a message that decodes
// to the same fields.
#include <cstdlib>
#include <cstring>
#include <string_view>

#include "fuzz/fuzz_util.h"
#include "occmap/pipeline/protection_message.h"

namespace {

bool Same(double a, double b) { return std::memcmp(&a, &b, sizeof(a)) == 0; }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const occmap::ProtectionExpectation expect{0x1234, 0x5678, 100};
  auto m = occmap::DecodeProtectionMessage(occmap::fuzz::AsText(data, size), expect, "occmap/site/protection");
  if (!m.ok()) return 0;
  auto back = occmap::DecodeProtectionMessage(occmap::EncodeProtectionMessage(*m), expect, "round trip");
  if (!back.ok() || back->frame != m->frame || !Same(back->timestamp_s, m->timestamp_s) ||
      !Same(back->t_unix, m->t_unix) || back->boxes != m->boxes || back->persons_m != m->persons_m ||
      back->occupied != m->occupied) {
    std::abort();
  }
  occmap::FloorGrid grid;
  grid.cells_x = 10;
  grid.cells_y = 10;
  grid.cell_size_m = 0.1;
  occmap::OccupancyMap map(grid);
  occmap::MarkOccupied(m->occupied, map);
  if (occmap::OccupiedRuns(map) != m->occupied) std::abort();
  return 0;
}
