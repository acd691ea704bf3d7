// ViewBackend: the web view (WebServer's pages and API) of a pipeline someone else runs, such as
// `occmap fuse --listen`: its LiveState fed by a LiveStateSink among that pipeline's sinks, the
// site as loaded, summary.json of its output folder. A view only: calibration and site edits are
// refused (the site file is shared by the edges and the fuse; edit it, then restart them), and it
// has no camera pictures (a fuse receives changes, never frames).
//
//   auto state = std::make_shared<LiveState>();
//   run_options.sinks.push_back(std::make_shared<LiveStateSink>(state));
//   ViewBackend backend(state, site, site_text, run_options.out_dir, "occmap fuse");
//   WebServer server(web_options, backend, EmbeddedWebAssets());
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "occmap/serve/live_state.h"
#include "occmap/serve/serve_session.h"
#include "occmap/site/site.h"

namespace occmap {

class ViewBackend : public ServeBackend {
 public:
  // `who` names the pipeline in the refusals ("occmap fuse").
  ViewBackend(std::shared_ptr<LiveState> state, const Site& site, std::string site_text, std::filesystem::path out_dir,
              std::string who);

  LiveState& state() override { return *state_; }
  int64_t site_version() const override { return 0; }
  nlohmann::json SiteJson() const override;
  nlohmann::json StatsJson() const override;
  Result<nlohmann::json> Calibrate(const nlohmann::json& body) override;
  Result<nlohmann::json> UpdateSite(const nlohmann::json& body) override;
  Result<std::string> GridJpeg(const std::string& camera_id, bool pending) override;

 private:
  std::shared_ptr<LiveState> state_;
  const Site& site_;
  std::string site_text_;
  std::filesystem::path out_dir_;
  std::string who_;
};

}  // namespace occmap
