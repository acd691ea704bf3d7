#include "occmap/io/frame_source.h"

#include <fmt/core.h>

namespace occmap {

const char* ToString(FrameSourceSpec::Kind kind) {
  switch (kind) {
    case FrameSourceSpec::Kind::kNone:
      return "none";
    case FrameSourceSpec::Kind::kImages:
      return "images";
    case FrameSourceSpec::Kind::kVideo:
      return "video";
    case FrameSourceSpec::Kind::kStream:
      return "stream";
    case FrameSourceSpec::Kind::kMasks:
      return "masks";
  }
  return "unknown";
}

Status FrameSourceOptions::Validate() const {
  if (decoder_threads < 0) {
    return InvalidInput(fmt::format("decoder_threads: expected >= 0 (0 = all cores), found {}", decoder_threads));
  }
  if (!std::isfinite(image_fps) || image_fps < 0) {
    return InvalidInput(
        fmt::format("image_fps: expected a finite value >= 0 (0 = no timestamps), found {}", image_fps));
  }
  if (stream_timeout_ms <= 0) {
    return InvalidInput(fmt::format("stream_timeout_ms: expected > 0, found {}", stream_timeout_ms));
  }
  for (size_t i = 0; i < image_times_s.size(); ++i) {
    if (!std::isfinite(image_times_s[i]) || (i > 0 && !(image_times_s[i] > image_times_s[i - 1]))) {
      return InvalidInput(fmt::format("image_times_s[{}]: expected a finite time after the one before, found {}", i,
                                      image_times_s[i]));
    }
  }
  return Status::Ok();
}

Status FrameSource::SkipTo(int64_t index) {
  if (index < 0) {
    return InvalidInput(fmt::format("{}: cannot skip to frame {}: expected an index >= 0", Describe(), index));
  }
  const std::optional<int64_t> next = next_index();
  if (!next) {
    return InvalidInput(
        fmt::format("{}: cannot skip to frame {}: the source does not know its position", Describe(), index));
  }
  if (index < *next) {
    return InvalidInput(fmt::format("{}: cannot skip back to frame {} (next frame is {})", Describe(), index, *next));
  }
  Frame scratch;
  for (int64_t i = *next; i < index; ++i) {
    OCCMAP_ASSIGN_OR_RETURN(const bool got, Read(scratch));
    if (!got) {
      return InvalidInput(
          fmt::format("{}: cannot skip to frame {}: the source ends after {} frames", Describe(), index, i));
    }
  }
  return Status::Ok();
}

Result<std::unique_ptr<FrameSource>> OpenFrameSource(const FrameSourceSpec& spec, const FrameSourceOptions& options) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  if (spec.location.empty()) {
    return InvalidInput(fmt::format("{} source: expected a location (path, pattern or URL), found an empty string",
                                    ToString(spec.kind)));
  }
  if (!std::isfinite(spec.fps) || spec.fps < 0) {
    return InvalidInput(fmt::format("{} source: fps: expected a finite value >= 0, found {}", ToString(spec.kind), spec.fps));
  }
  if (spec.fps > 0 && !spec.timestamps_s.empty()) {
    return InvalidInput(fmt::format("{} source '{}': expected fps or timestamps, found both", ToString(spec.kind),
                                    spec.location));
  }
  FrameSourceOptions with_fps = options;
  if (spec.fps > 0) with_fps.image_fps = spec.fps;
  if (!spec.timestamps_s.empty()) with_fps.image_times_s = spec.timestamps_s;
  switch (spec.kind) {
    case FrameSourceSpec::Kind::kImages:
      return OpenImageSequence(spec.location, /*masks=*/false, with_fps);
    case FrameSourceSpec::Kind::kMasks:
      return OpenImageSequence(spec.location, /*masks=*/true, with_fps);
    case FrameSourceSpec::Kind::kVideo:
      return OpenVideoSource(spec.location, /*stream=*/false, options);
    case FrameSourceSpec::Kind::kStream:
      return OpenVideoSource(spec.location, /*stream=*/true, options);
    case FrameSourceSpec::Kind::kNone:
      break;
  }
  return InvalidInput(
      fmt::format("frame source '{}': expected a kind (images, video, stream or masks), found none", spec.location));
}

}  // namespace occmap
