#include "occmap/io/frame_source.h"

#include <fmt/core.h>

#include <cmath>
#include <utility>

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

namespace {

class LoopingSource final : public FrameSource {
 public:
  LoopingSource(FrameSourceSpec spec, FrameSourceOptions options, std::unique_ptr<FrameSource> first)
      : spec_(std::move(spec)), options_(std::move(options)), inner_(std::move(first)) {}

  std::string Describe() const override { return inner_->Describe() + ", looped"; }
  ImageSize size() const override { return inner_->size(); }
  std::optional<double> fps() const override { return inner_->fps(); }
  std::optional<int64_t> next_index() const override {
    const auto next = inner_->next_index();
    if (!next) return std::nullopt;
    return *next + index_offset_;
  }

  Result<bool> Read(Frame& frame) override {
    OCCMAP_ASSIGN_OR_RETURN(bool got, inner_->Read(frame));
    if (!got) {
      if (pass_frames_ == 0) return false;  // an empty pass would loop for ever
      OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> again, OpenFrameSource(spec_, options_));
      if (again->size() != inner_->size()) {
        return InvalidInput(fmt::format("{}: read again for --loop, it is {}x{}, was {}x{}", Describe(),
                                        again->size().width, again->size().height, inner_->size().width,
                                        inner_->size().height));
      }
      inner_ = std::move(again);
      pass_frames_ = 0;
      OCCMAP_ASSIGN_OR_RETURN(got, inner_->Read(frame));
      if (!got) return false;
      // This pass follows the last frame out: the next index, a frame interval later.
      index_offset_ = last_index_ + 1 - frame.index;
      const double interval = fps() && *fps() > 0 ? 1.0 / *fps() : 0.0;
      time_shift_s_ = std::isfinite(last_s_) && std::isfinite(frame.timestamp_s)
                          ? last_s_ + interval - frame.timestamp_s : 0.0;
    }
    ++pass_frames_;
    frame.index += index_offset_;
    if (std::isfinite(frame.timestamp_s)) frame.timestamp_s += time_shift_s_;
    last_index_ = frame.index;
    last_s_ = frame.timestamp_s;
    return true;
  }

 private:
  FrameSourceSpec spec_;
  FrameSourceOptions options_;
  std::unique_ptr<FrameSource> inner_;
  int64_t pass_frames_ = 0;   // frames of this pass so far
  int64_t index_offset_ = 0;  // added to this pass's indices
  double time_shift_s_ = 0;   // added to this pass's timestamps
  int64_t last_index_ = -1;
  double last_s_ = std::nan("");
};

}  // namespace

Result<std::unique_ptr<FrameSource>> LoopFrameSource(const FrameSourceSpec& spec, const FrameSourceOptions& options,
                                                     std::unique_ptr<FrameSource> first) {
  if (spec.kind != FrameSourceSpec::Kind::kVideo && spec.kind != FrameSourceSpec::Kind::kImages) {
    return InvalidInput(fmt::format("{} source '{}': --loop is for video files and image sequences",
                                    ToString(spec.kind), RedactUrl(spec.location)));
  }
  return std::unique_ptr<FrameSource>(std::make_unique<LoopingSource>(spec, options, std::move(first)));
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
