#include "occmap/site/site_lut.h"

#include <fmt/core.h>

#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"

namespace occmap {
namespace fs = std::filesystem;

fs::path SiteLutPath(const Site& site, const fs::path& cache_dir) {
  std::string stem;
  for (char c : site.name) stem += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_') ? c : '_';
  if (stem.empty()) stem = "site";
  if (site.lut.plane_height_m != 0) stem += fmt::format("-z{:.3f}", site.lut.plane_height_m);
  return cache_dir / (stem + ".lut");
}

Result<CachedLut> LoadOrBuildSiteLut(const Site& site, const fs::path& cache_dir, Context& ctx) {
  if (!cache_dir.empty()) {
    // Temporaries of killed runs (a table is up to tens of MB): the cache's own folders only.
    RemoveStaleTemporaries(cache_dir, /*recursive=*/false);
    RemoveStaleTemporaries(cache_dir / "backgrounds", /*recursive=*/false);
  }
  return LoadOrBuildGroundLut(cache_dir.empty() ? fs::path() : SiteLutPath(site, cache_dir), site.LutInputs(),
                              site.grid, site.lut, ctx);
}

GridCoverage SummarizeCoverage(const GroundLut& lut) {
  GridCoverage g;
  g.cells = lut.grid().num_cells();
  std::vector<int64_t> exactly(lut.num_cameras() + 1, 0);
  for (uint8_t v : lut.view_count()) ++exactly[v];
  g.cells_seen_by_at_least.assign(exactly.size(), 0);
  int64_t running = 0;
  for (int k = static_cast<int>(exactly.size()) - 1; k >= 0; --k) {
    running += exactly[k];
    g.cells_seen_by_at_least[k] = running;
  }
  return g;
}

std::string CoverageTable(const Site& site, const GroundLut& lut) {
  auto pct = [](int64_t part, int64_t whole) { return whole > 0 ? 100.0 * static_cast<double>(part) / static_cast<double>(whole) : 0.0; };
  std::string out = fmt::format("{:<10} {:>10} {:>7} {:>7} {:>8} {:>7} {:>11} {:>11} {:>7}\n", "camera", "image",
                                "masked", "no ray", "off grid", "mapped", "cells(rays)", "cells(+fix)", "% grid");
  const int64_t cells = lut.grid().num_cells();
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const CameraCoverage& c = lut.coverage()[n];
    const ImageSize s = lut.image_size(n);
    out += fmt::format("{:<10} {:>10} {:>6.1f}% {:>6.1f}% {:>7.1f}% {:>6.1f}% {:>11} {:>11} {:>6.1f}%\n",
                       site.cameras[n].id, fmt::format("{}x{}", s.width, s.height), pct(c.pixels_masked, c.pixels),
                       pct(c.pixels_no_ray, c.pixels), pct(c.pixels_off_grid, c.pixels), pct(c.pixels_mapped, c.pixels),
                       c.cells_from_rays, c.cells_added, pct(c.cells_seen, cells));
  }
  const GridCoverage g = SummarizeCoverage(lut);
  out += fmt::format("map: {} cells;", g.cells);
  for (size_t k = 1; k < g.cells_seen_by_at_least.size(); ++k) {
    out += fmt::format(" >={} cam: {:.1f}%", k, pct(g.cells_seen_by_at_least[k], g.cells));
    if (k + 1 < g.cells_seen_by_at_least.size()) out += ",";
  }
  out += "\n";
  return out;
}

std::vector<CameraMarker> SiteCameraMarkers(const Site& site) {
  std::vector<CameraMarker> markers;
  for (const auto& c : site.cameras) {
    if (auto center = c.camera->CenterInWorld()) markers.push_back({c.id, center->head<2>()});
  }
  return markers;
}

}  // namespace occmap
