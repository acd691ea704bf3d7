#include "occmap/pipeline/ros_map_sink.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

#include "occmap/util/file_util.h"

namespace occmap {

Status RosMapOptions::Validate() const {
  if (dir.empty()) return InvalidInput("--ros-map: expected a folder");
  for (int64_t f : frames) {
    if (f < 0) return InvalidInput(fmt::format("--ros-map-frame: expected a frame >= 0, found {}", f));
  }
  if (!(static_fraction >= 0 && static_fraction < 1)) {
    return InvalidInput(fmt::format("--ros-map-static-fraction: expected a number in [0, 1), found {}", static_fraction));
  }
  if (!(static_every_s >= 0) || !std::isfinite(static_every_s)) {
    return InvalidInput(fmt::format("--ros-map-every-s: expected a number >= 0, found {}", static_every_s));
  }
  return Status::Ok();
}

Status RosMapSink::Open(const SinkStart& start) {
  OCCMAP_RETURN_IF_ERROR(options_.Validate());
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(options_.dir));
  frames_ = {options_.frames.begin(), options_.frames.end()};
  static_.emplace(start.site->grid);
  return Status::Ok();
}

Status RosMapSink::WriteStatic() {
  const std::filesystem::path path = options_.dir / "static.yaml";
  OCCMAP_RETURN_IF_ERROR(WriteRosMap(path, static_->StaticMap(options_.static_fraction)));
  if (std::find(written_.begin(), written_.end(), path) == written_.end()) {
    written_.push_back(path);
    written_.push_back(std::filesystem::path(path).replace_extension(".pgm"));
  }
  return Status::Ok();
}

Status RosMapSink::Consume(const FrameRecord& r, const RunStats& stats) {
  (void)stats;
  static_->Add(r.map);
  if (frames_.contains(r.frame)) {
    const std::filesystem::path path = options_.dir / fmt::format("frame_{:06d}.yaml", r.frame);
    OCCMAP_RETURN_IF_ERROR(WriteRosMap(path, RosMapFromOccupancy(r.map)));
    written_.push_back(path);
    written_.push_back(std::filesystem::path(path).replace_extension(".pgm"));
  }
  if (!last_static_time_s_) last_static_time_s_ = r.time_s;
  if (options_.static_every_s > 0 && r.time_s - *last_static_time_s_ >= options_.static_every_s) {
    last_static_time_s_ = r.time_s;
    OCCMAP_RETURN_IF_ERROR(WriteStatic());
  }
  return Status::Ok();
}

Status RosMapSink::Close(const RunStats& stats) {
  (void)stats;
  if (!static_ || static_->frames() == 0) return Status::Ok();
  return WriteStatic();
}

}  // namespace occmap
