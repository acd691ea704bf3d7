// ProtectionMessage: what `occmap fuse` publishes per fused frame set of a site with adaptive
// backgrounds (site `backgrounds.adaptive`), for the `occmap edge` processes that keep those
// backgrounds (issue 17). An adaptive background follows the frame only where the fused map says
// nothing stands (background_maintenance.h); the map and the test that tells a person from an
// object need every camera, so the fuse computes the protected boxes (BackgroundProtection) and
// each edge draws them into its own cameras. With them: the persons' positions and the map's
// occupied cells (what ShadowTeachers reads besides the cameras' own classes).
//
// Binary, little-endian, version 1, on <prefix>/protection:
//   "OCMP"  u16 schema version  u16 reserved (0)
//   u64 table key  u64 settings key (as the edge messages': EdgeTableKey, EdgeSettingsKey)
//   i64 frame index  f64 timestamp_s (NaN: none)  f64 t_unix (the frame set's capture)
//   u32 boxes  u32 persons  u32 occupied runs
//   boxes x (f64 x_m, f64 y_m, f64 radius_m, u8 value: 1 object, 2 person, 3 walked person)
//   persons x (f64 x_m, f64 y_m)
//   runs x (varint gap, varint cells): the occupied cells, row-major cell indexes, in order,
//   apart, inside the grid; gap: from the previous run's end (the first run's: from cell 0);
//   varints as LEB128 (7 bits a byte, least significant first), at most 32 bits
// An edge refuses a message of another schema version, or made for other tables or settings,
// naming what differs; a malformed one names the field.
//
//   std::string bytes = EncodeProtectionMessage(m);                                    // fuse
//   OCCMAP_ASSIGN_OR_RETURN(ProtectionMessage m, DecodeProtectionMessage(bytes, expect, topic));  // edge
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/pipeline/background_maintenance.h"
#include "occmap/util/status.h"

namespace occmap {

constexpr uint16_t kProtectionSchemaVersion = 1;

struct ProtectionMessage {
  uint64_t table_key = 0;
  uint64_t settings_key = 0;
  int64_t frame = 0;
  double timestamp_s = 0;
  double t_unix = 0;
  std::vector<ProtectedBox> boxes;
  std::vector<Eigen::Vector2d> persons_m;
  std::vector<std::pair<uint32_t, uint32_t>> occupied;  // runs: (first cell, cells)
};

struct ProtectionExpectation {
  uint64_t table_key = 0;
  uint64_t settings_key = 0;
  int64_t num_cells = 0;  // of the site's grid
};

std::string EncodeProtectionMessage(const ProtectionMessage& message);
// source names the message in errors (e.g. its topic).
Result<ProtectionMessage> DecodeProtectionMessage(std::string_view bytes, const ProtectionExpectation& expect,
                                                  std::string_view source);

// The map's occupied cells as runs, and back (every other cell of `map` left as it is).
std::vector<std::pair<uint32_t, uint32_t>> OccupiedRuns(const OccupancyMap& map);
void MarkOccupied(const std::vector<std::pair<uint32_t, uint32_t>>& runs, OccupancyMap& map);

}  // namespace occmap
