// SummaryFile: a run's summary.json (pipeline/run.h lists its fields; docs/formats.md).
// The parts known before the first frame set (site, settings, tables, cameras) are made once;
// the running summary ("running": true, rewritten atomically every RunOptions::summary_every_s
// by the sink stage) adds the figures so far, the final one everything.
//
//   SummaryFile file(out / "summary.json", site, options, plan, summary, cams, ctx.num_threads());
//   OCCMAP_RETURN_IF_ERROR(file.WriteRunning(stats));        // while running
//   OCCMAP_RETURN_IF_ERROR(file.WriteFinal(summary, stats, cams, last_frame_index));
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include <nlohmann/json.hpp>

#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/frame_sink.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/run.h"

namespace occmap {

// A camera's `background_cache` (what refreshing its cached background did), as summary.json
// and the MQTT <prefix>/stats (mqtt_sink.h) carry it: {"entry", "refreshes", "failures",
// "last_refresh_frame", "last_error"}, the last two null when there is none.
nlohmann::json BackgroundCacheJson(const BackgroundCacheFigures& f);

class SummaryFile {
 public:
  // summary: the figures known before the first frame set (tables, the backgrounds' consensus).
  SummaryFile(std::filesystem::path path, const Site& site, const RunOptions& options, const FusionPlan& plan,
              const RunSummary& summary, const std::vector<CameraState>& cams, int num_threads);
  // The running figures ("running": true).
  Status WriteRunning(const RunStats& stats) const;
  // The final summary ("running": false); summary.outputs must name every output but this one.
  // last_frame_index: the adaptive backgrounds' last update (their mean age then).
  Status WriteFinal(const RunSummary& summary, const RunStats& stats, const std::vector<CameraState>& cams,
                    int64_t last_frame_index) const;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  const Site& site_;
  bool track_;
  nlohmann::json static_;
  std::vector<nlohmann::json> static_cameras_;
};

}  // namespace occmap
