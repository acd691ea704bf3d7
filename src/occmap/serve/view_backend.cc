#include "occmap/serve/view_backend.h"

#include <fmt/core.h>

#include <utility>

#include "occmap/serve/web_api.h"
#include "occmap/util/file_util.h"

namespace occmap {

using nlohmann::json;

ViewBackend::ViewBackend(std::shared_ptr<LiveState> state, const Site& site, std::string site_text,
                         std::filesystem::path out_dir, std::string who)
    : state_(std::move(state)), site_(site), site_text_(std::move(site_text)), out_dir_(std::move(out_dir)),
      who_(std::move(who)) {}

json ViewBackend::SiteJson() const { return occmap::SiteJson(site_, site_text_); }

json ViewBackend::StatsJson() const {
  auto text = ReadFileToString(out_dir_ / "summary.json");
  if (!text.ok()) return json::object();
  json j = json::parse(*text, nullptr, false);
  return j.is_discarded() ? json::object() : j;
}

Result<json> ViewBackend::Calibrate(const json& /*body*/) {
  return InvalidInput(fmt::format("{} shows a view only: calibrate with `occmap serve` or `occmap calibrate` on the "
                                  "site file, then restart the edges and {}",
                                  who_, who_));
}

Result<json> ViewBackend::UpdateSite(const json& /*body*/) {
  return InvalidInput(fmt::format("{} shows a view only: edit the site file '{}' (every edge reads it too), then "
                                  "restart the edges and {}",
                                  who_, site_.file.string(), who_));
}

Result<std::string> ViewBackend::GridJpeg(const std::string& camera_id, bool /*pending*/) {
  return NotFound(fmt::format("{} has no pictures of camera '{}': its edges send changes, not frames", who_, camera_id));
}

}  // namespace occmap
