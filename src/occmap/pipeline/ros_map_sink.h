// RosMapSink: the run's occupancy as ROS map_server maps (publish/ros_map.h), a FrameSink
// (frame_sink.h). In RosMapOptions::dir:
//   frame_NNNNNN.yaml / .pgm   the map of each frame listed in `frames` (unseen cells unknown)
//   static.yaml / static.pgm   the long run's static map: cells occupied in more than
//                              static_fraction of the frames that saw them; rewritten every
//                              static_every_s of stream time and at the end
// Each file is replaced atomically, so a robot reading static.yaml never sees half a map.
//
//   RosMapOptions ros{.dir = "out/ros_map", .frames = {120}};
//   run_options.sinks.push_back(std::make_shared<RosMapSink>(ros));
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <set>
#include <vector>

#include "occmap/pipeline/frame_sink.h"
#include "occmap/publish/ros_map.h"

namespace occmap {

struct RosMapOptions {
  std::filesystem::path dir;         // where the maps go (created)
  std::vector<int64_t> frames;       // frames whose own map is written (>= 0)
  double static_fraction = 0.5;      // in [0, 1)
  double static_every_s = 60;        // stream seconds between rewrites of static.yaml; 0: only at the end
  Status Validate() const;
};

class RosMapSink : public FrameSink {
 public:
  explicit RosMapSink(RosMapOptions options) : options_(std::move(options)) {}
  Status Open(const SinkStart& start) override;
  Status Consume(const FrameRecord& record, const RunStats& stats) override;
  Status Close(const RunStats& stats) override;
  const std::vector<std::filesystem::path>& written() const { return written_; }

 private:
  Status WriteStatic();

  RosMapOptions options_;
  std::set<int64_t> frames_;
  std::optional<StaticMapAccumulator> static_;
  std::optional<double> last_static_time_s_;
  std::vector<std::filesystem::path> written_;
};

}  // namespace occmap
