// The lookup tables of a site: built or loaded from the cache, and described for people.
//
//   OCCMAP_ASSIGN_OR_RETURN(CachedLut cached, LoadOrBuildSiteLut(site, cache_dir, ctx));
//   std::cout << CoverageTable(site, cached.lut);
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "occmap/lut/lut_file.h"
#include "occmap/lut/visibility_image.h"
#include "occmap/site/site.h"

namespace occmap {

// The cache file for a site's tables: <cache_dir>/<name>.lut, or <name>-z<height>.lut for a
// plane above the floor. A changed site makes the file stale; it is then rebuilt.
std::filesystem::path SiteLutPath(const Site& site, const std::filesystem::path& cache_dir);

// cache_dir empty: no cache file.
Result<CachedLut> LoadOrBuildSiteLut(const Site& site, const std::filesystem::path& cache_dir, Context& ctx);

// Figures for the whole map.
struct GridCoverage {
  int64_t cells = 0;
  std::vector<int64_t> cells_seen_by_at_least;  // [k] = cells seen by >= k cameras, k = 0..N
};
GridCoverage SummarizeCoverage(const GroundLut& lut);

// A fixed-width text table of the per-camera coverage figures and the map totals.
std::string CoverageTable(const Site& site, const GroundLut& lut);

// Camera markers (optical centres) for pictures of the floor.
std::vector<CameraMarker> SiteCameraMarkers(const Site& site);

}  // namespace occmap
