#include "occmap/site/site_location.h"

#include <fmt/core.h>

#include "occmap/util/yaml_util.h"

namespace occmap {

std::string SiteCameraLocation(const Site& site, size_t camera_index, std::string_view field) {
  const std::string fallback = fmt::format("cameras[{}].{}", camera_index, field);
  if (site.file.empty()) return fallback;
  auto root = LoadYamlFile(site.file);
  if (!root.ok()) return fallback;
  auto cams = root->Get("cameras");
  if (!cams.ok()) return fallback;
  auto cam = cams->At(camera_index);
  if (!cam.ok()) return fallback;
  if (auto f = cam->Find(field)) return f->Where();
  return fmt::format("{}: {}", cam->Where(), fallback);
}

}  // namespace occmap
