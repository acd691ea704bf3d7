// The lookup-table file: a versioned binary cache of GroundLut, keyed by GroundLutKey.
//
// Layout (little-endian; see docs/formats.md):
//   header, 48 bytes: magic "OCCMLUT\0", u32 format version, u32 header bytes (48),
//                     u64 key, u64 payload bytes, u64 payload checksum (Hasher), u64 reserved
//   payload: grid, plane height, per-camera image size, coverage and tables, then L2 and
//            view counts; every array as u64 element count + raw elements.
// A file is trusted only when magic, version, key, size and checksum match and the decoded
// tables pass GroundLut::CheckConsistency. LoadOrBuildGroundLut reuses a valid file and
// rebuilds (and rewrites, atomically) a missing, stale or corrupt one, saying which; a file
// that cannot be written is no error (CachedLut::write_error says why).
//
//   OCCMAP_ASSIGN_OR_RETURN(CachedLut cached,
//       LoadOrBuildGroundLut(cache_dir / "wildtrack.lut", cams, grid, options, ctx));
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "occmap/lut/ground_lut.h"

namespace occmap {

inline constexpr uint32_t kLutFileVersion = 2;  // 2: no L2 in the file (derived on load)

Status SaveGroundLut(const std::filesystem::path& path, const GroundLut& lut, uint64_t key);

// kNotFound when the file is missing; kDataLoss when it is corrupt, truncated, of another
// format version, or for another key (stale) - the message says which.
// *stale (when given) is set when the file is intact but was built for other inputs.
Result<GroundLut> LoadGroundLut(const std::filesystem::path& path, uint64_t expected_key, bool* stale = nullptr);

enum class LutCacheOutcome { kLoaded, kBuiltNoFile, kRebuiltStale, kRebuiltCorrupt, kBuiltNoCache };

struct CachedLut {
  GroundLut lut;
  uint64_t key = 0;
  LutCacheOutcome outcome = LutCacheOutcome::kBuiltNoCache;
  std::string reason;     // why a file was not used, when it was not
  // Why the file could not be written (the tables are used all the same: a cache is a head
  // start, never an output); empty when it was, or with no cache.
  std::string write_error;
  double build_seconds = 0;  // 0 when loaded
  double load_seconds = 0;
};

// cache_path empty: build without any file.
Result<CachedLut> LoadOrBuildGroundLut(const std::filesystem::path& cache_path,
                                       const std::vector<LutCameraInput>& cameras, const FloorGrid& grid,
                                       const LutOptions& options, Context& ctx);

const char* ToString(LutCacheOutcome outcome);

}  // namespace occmap
