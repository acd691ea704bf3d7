// ServeSession: what `occmap serve` runs behind its HTTP API (serve/web_server.h): the site's
// pipeline (RunSite) on a thread of its own with a LiveStateSink among its sinks, the setup
// actions of the pages (calibrating a camera from clicked floor points, saving calibrations,
// masks, zones and lines into the site file) and the restart of the pipeline on the saved site
// (its tables are loaded or built on the pipeline's thread: the server stays up meanwhile).
//
//   ServeSessionOptions o;  o.site_path = "site.yaml";  o.run.out_dir = "out";
//   OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<ServeSession> s, ServeSession::Create(o));
//   s->Start();  ...  s->Stop();
#pragma once

#include <fmt/core.h>

#include <atomic>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "occmap/calib/board_calibration.h"
#include "occmap/calib/floor_calibration.h"
#include "occmap/pipeline/run.h"
#include "occmap/serve/live_state.h"
#include "occmap/site/site.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

// What the HTTP server asks of the system behind it (a fake in the server's tests).
class ServeBackend {
 public:
  virtual ~ServeBackend() = default;
  virtual LiveState& state() = 0;
  // Increases whenever the site was saved (the pages are told with a `site` event).
  virtual int64_t site_version() const = 0;
  virtual nlohmann::json SiteJson() const = 0;
  // summary.json of the output folder ({} before the first one).
  virtual nlohmann::json StatsJson() const = 0;
  // POST /api/calibrate and PUT /api/site (docs/formats.md, "Web API"); errors are bad input.
  virtual Result<nlohmann::json> Calibrate(const nlohmann::json& body) = 0;
  virtual Result<nlohmann::json> UpdateSite(const nlohmann::json& body) = 0;
  // Camera `camera_id`'s latest frame with the floor grid of its calibration (the pending
  // result of Calibrate when `pending`) as JPEG; NotFound for an unknown camera.
  virtual Result<std::string> GridJpeg(const std::string& camera_id, bool pending) = 0;
  // The camera's mask as the site loaded it (a picture or polygons), web_api.h's
  // MaskOverlayPng; NotFound for an unknown camera or one without a mask.
  virtual Result<std::string> MaskPng(const std::string& camera_id) {
    return NotFound(fmt::format("camera '{}' has no mask", camera_id));
  }
  // The board route to a camera's intrinsics (docs/formats.md, "Web API"): views captured from
  // its live frame or uploaded, each inspected as it comes, then cv::calibrateCamera on them;
  // the intrinsics are kept for the camera's next POST /api/calibrate.
  virtual Result<nlohmann::json> BoardViews(const std::string& camera_id) {
    return NotFound(fmt::format("no board views for '{}'", camera_id));
  }
  virtual Result<nlohmann::json> AddBoardView(const nlohmann::json& body) {
    (void)body;
    return NotFound("board views are not kept here");
  }
  // index < 0: every view and the kept intrinsics.
  virtual Result<nlohmann::json> RemoveBoardViews(const std::string& camera_id, int index) {
    (void)index;
    return NotFound(fmt::format("no board views for '{}'", camera_id));
  }
  virtual Result<nlohmann::json> CalibrateBoard(const nlohmann::json& body) {
    (void)body;
    return NotFound("board views are not kept here");
  }
  // View `index` of the camera's board views with the corners found drawn, as JPEG.
  virtual Result<std::string> BoardViewJpeg(const std::string& camera_id, int index) {
    (void)index;
    return NotFound(fmt::format("no board views for '{}'", camera_id));
  }
};

struct ServeSessionOptions {
  std::filesystem::path site_path;
  SiteLoadOptions load;
  RunOptions run;  // out_dir, cache, ...; the session adds its sink, sink_frames and stop
  int threads = 0;
  // File inputs at their frame rate (a live view), not as fast as they decode.
  bool pace = true;
  // Applied to every loaded site (the command line's overrides of the file).
  std::function<Status(Site&)> adjust_site;
};

class ServeSession : public ServeBackend {
 public:
  static Result<std::unique_ptr<ServeSession>> Create(ServeSessionOptions options);
  ~ServeSession() override;
  ServeSession(const ServeSession&) = delete;
  ServeSession& operator=(const ServeSession&) = delete;

  void Start();  // the pipeline on the current site
  void Stop();   // stops the pipeline (outputs closed) and waits for it
  // The last run's summary and error (after it ended).
  std::optional<RunSummary> last_summary() const;
  Status last_error() const;

  LiveState& state() override { return *state_; }
  int64_t site_version() const override { return site_version_.load(); }
  nlohmann::json SiteJson() const override;
  nlohmann::json StatsJson() const override;
  Result<nlohmann::json> Calibrate(const nlohmann::json& body) override;
  Result<nlohmann::json> UpdateSite(const nlohmann::json& body) override;
  Result<std::string> GridJpeg(const std::string& camera_id, bool pending) override;
  Result<std::string> MaskPng(const std::string& camera_id) override;
  Result<nlohmann::json> BoardViews(const std::string& camera_id) override;
  Result<nlohmann::json> AddBoardView(const nlohmann::json& body) override;
  Result<nlohmann::json> RemoveBoardViews(const std::string& camera_id, int index) override;
  Result<nlohmann::json> CalibrateBoard(const nlohmann::json& body) override;
  Result<std::string> BoardViewJpeg(const std::string& camera_id, int index) override;

  static constexpr size_t kMaxBoardViews = 40;  // a camera's views kept at once (grey, in memory)

 private:
  explicit ServeSession(ServeSessionOptions options);
  Result<std::shared_ptr<const Site>> LoadCurrentSite() const;
  void StartLocked();
  void StopLocked();
  std::shared_ptr<const Site> site() const;

  struct Pending {
    FloorCalibration calibration;
    std::vector<FloorPoint> points;
  };
  // A camera's board views: the pictures, their latest inspection, the intrinsics found.
  struct BoardSet {
    std::vector<std::string> names;
    std::vector<std::shared_ptr<const Image<uint8_t>>> images;
    std::vector<BoardView> inspected;
    std::vector<bool> used;  // by the latest calibration
    std::vector<std::optional<ImageSize>> scaled_from;  // the size uploaded, when scaled to the set's
    IntrinsicsOptions options;
    std::optional<IntrinsicsCalibration> calibration;
    int next_number = 1;
  };
  nlohmann::json BoardJsonLocked(const std::string& camera_id, const BoardSet& b) const;
  const SiteCamera* FindCamera(const Site& site, const std::string& camera_id) const;

  ServeSessionOptions options_;
  std::shared_ptr<LiveState> state_;
  Context ctx_;
  mutable std::mutex mu_;  // site_, site_text_, pending_, summary_, error_
  std::shared_ptr<const Site> site_;
  std::string site_text_;
  std::map<std::string, Pending> pending_;
  std::map<std::string, BoardSet> boards_;  // under mu_
  std::mutex board_mu_;  // one board inspection or calibration at a time (they take seconds)
  std::optional<RunSummary> summary_;
  Status error_;
  std::atomic<int64_t> site_version_{1};
  std::mutex run_mu_;  // the pipeline thread's start and stop; one site edit at a time
  std::thread thread_;
  std::atomic<bool> stop_run_{false};
};

}  // namespace occmap
