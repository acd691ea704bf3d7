// Video files and live streams through libavformat (demux) and libavcodec (decode).
//
// Decoding runs with frame and slice threading; grey comes straight from the Y plane for the
// 8-bit YUV / NV12 / grey formats (a row copy, or a vectorised loop that expands limited-range
// 16..235 luma to 0..255), chroma straight from the U and V planes of yuv420p / yuvj420p (the
// same, 16..240 to 0..255); other formats, colour, and chroma of other formats go through
// libswscale with a cached context per conversion.
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavdevice/avdevice.h>
#include <libavformat/avformat.h>
#include <libavutil/pixdesc.h>
#include <libswscale/swscale.h>
}

#include <fcntl.h>
#include <fmt/core.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdarg>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <utility>

#include "occmap/io/ffmpeg_util.h"
#include "occmap/io/frame_source.h"
#include "occmap/io/limited_range.h"
#include "occmap/util/safe_files.h"
#include "occmap/util/yuv.h"

namespace occmap {

std::string RedactUrl(const std::string& url) {
  const size_t scheme = url.find("://");
  if (scheme == std::string::npos) return url;
  const size_t host_start = scheme + 3;
  const size_t host_end = std::min(url.find('/', host_start), url.size());
  size_t at = url.rfind('@', host_end);
  if (at == std::string::npos || at < host_start) {
    // A password with a raw '/' ends the authority early: redact up to the next '@' (a port
    // followed by an '@' in the path is redacted too; hiding more is the safe side).
    at = url.find('@', host_end);
    if (at == std::string::npos) return url;
  }
  const size_t colon = url.find(':', host_start);
  if (colon == std::string::npos || colon > at || colon > host_end) return url;
  return url.substr(0, colon + 1) + "***" + url.substr(at);
}

namespace {
namespace fs = std::filesystem;
using ffmpeg_internal::AvErrorWithLog;
using ffmpeg_internal::ClearLog;

struct InputDeleter {
  void operator()(AVFormatContext* p) const { avformat_close_input(&p); }
};
using ffmpeg_internal::CodecDeleter;
using ffmpeg_internal::FrameDeleter;
using ffmpeg_internal::PacketDeleter;
using ffmpeg_internal::SwsDeleter;


// "a PNG image" when FFmpeg's demuxer is one of its still-image readers ("png_pipe", "image2",
// "gif", ...), or nullptr: FFmpeg would decode an image as a video of one frame.
const char* ImageFormatName(const AVInputFormat* format) {
  if (format == nullptr || format->name == nullptr) return nullptr;
  const std::string_view name = format->name;
  static constexpr std::pair<std::string_view, const char*> kNamed[] = {
      {"png_pipe", "a PNG image"},   {"apng", "a PNG image"},      {"jpeg_pipe", "a JPEG image"},
      {"jpegls_pipe", "a JPEG image"}, {"jpegxl_pipe", "a JPEG XL image"}, {"gif", "a GIF image"},
      {"gif_pipe", "a GIF image"},   {"bmp_pipe", "a BMP image"},   {"tiff_pipe", "a TIFF image"},
      {"webp_pipe", "a WebP image"}};
  for (const auto& [demuxer, text] : kNamed) {
    if (name == demuxer) return text;
  }
  if (name == "image2" || name == "image2pipe" || name.ends_with("_pipe")) return "an image file";
  return nullptr;
}

bool IsFullRangeFormat(AVPixelFormat format) {
  return format == AV_PIX_FMT_YUVJ420P || format == AV_PIX_FMT_YUVJ422P || format == AV_PIX_FMT_YUVJ444P ||
         format == AV_PIX_FMT_YUVJ440P || format == AV_PIX_FMT_YUVJ411P;
}

// True when plane 0 holds 8-bit luma one byte per pixel (YUV planar, NV12/NV21, GRAY8).
bool HasPlainLumaPlane(AVPixelFormat format) {
  const AVPixFmtDescriptor* desc = av_pix_fmt_desc_get(format);
  if (desc == nullptr || desc->nb_components < 1) return false;
  constexpr uint64_t kExcluded = AV_PIX_FMT_FLAG_RGB | AV_PIX_FMT_FLAG_PAL | AV_PIX_FMT_FLAG_BITSTREAM |
                                 AV_PIX_FMT_FLAG_HWACCEL | AV_PIX_FMT_FLAG_FLOAT | AV_PIX_FMT_FLAG_BAYER;
  const AVComponentDescriptor& luma = desc->comp[0];
  return (desc->flags & kExcluded) == 0 && luma.plane == 0 && luma.step == 1 && luma.depth == 8 && luma.shift == 0 &&
         luma.offset == 0;
}

bool IsFullRange(const AVFrame& frame) {
  const auto format = static_cast<AVPixelFormat>(frame.format);
  if (frame.color_range == AVCOL_RANGE_JPEG || IsFullRangeFormat(format)) return true;
  if (frame.color_range == AVCOL_RANGE_MPEG) return false;
  const AVPixFmtDescriptor* desc = av_pix_fmt_desc_get(format);
  // Unspecified: YUV video is limited range by convention, grey and RGB are full range.
  return desc != nullptr && (desc->nb_components <= 2 || (desc->flags & AV_PIX_FMT_FLAG_RGB) != 0);
}

// One cached libswscale conversion at the frame's size, rebuilt when the input changes.
class SwsConverter {
 public:
  Status Convert(const AVFrame& frame, AVPixelFormat dst_format, uint8_t* dst, int dst_stride_bytes) {
    uint8_t* dst_planes[4] = {dst, nullptr, nullptr, nullptr};
    const int dst_strides[4] = {dst_stride_bytes, 0, 0, 0};
    return Convert(frame, dst_format, dst_planes, dst_strides, /*dst_full_range=*/true);
  }

  // dst_planes / dst_strides_bytes: one entry per plane of dst_format, the rest null / 0.
  // dst_full_range false: YUV output in limited range (16..235 / 16..240).
  Status Convert(const AVFrame& frame, AVPixelFormat dst_format, uint8_t* const dst_planes[4],
                 const int dst_strides_bytes[4], bool dst_full_range) {
    const Key key{frame.width, frame.height, frame.format, IsFullRange(frame), frame.colorspace, dst_full_range};
    if (context_ == nullptr || !(key == key_)) {
      context_.reset(sws_getContext(frame.width, frame.height, static_cast<AVPixelFormat>(frame.format), frame.width,
                                    frame.height, dst_format, SWS_BILINEAR | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INT,
                                    nullptr, nullptr, nullptr));
      if (context_ == nullptr) {
        return InvalidInput(fmt::format("cannot convert pixel format '{}' to '{}'",
                                        av_get_pix_fmt_name(static_cast<AVPixelFormat>(frame.format)),
                                        av_get_pix_fmt_name(dst_format)));
      }
      // Source matrix and range as the stream says (unspecified -> BT.601); output as asked.
      // Fails harmlessly (returns -1) for RGB inputs, which have no matrix.
      const int* coefficients = sws_getCoefficients(static_cast<int>(frame.colorspace));
      sws_setColorspaceDetails(context_.get(), coefficients, key.full_range ? 1 : 0,
                               sws_getCoefficients(SWS_CS_DEFAULT), dst_full_range ? 1 : 0, 0, 1 << 16, 1 << 16);
      key_ = key;
    }
    sws_scale(context_.get(), frame.data, frame.linesize, 0, frame.height, dst_planes, dst_strides_bytes);
    return Status::Ok();
  }

 private:
  struct Key {
    int width = 0, height = 0, format = -1;
    bool full_range = false;
    AVColorSpace colorspace = AVCOL_SPC_UNSPECIFIED;
    bool dst_full_range = true;
    bool operator==(const Key&) const = default;
  };
  std::unique_ptr<SwsContext, SwsDeleter> context_;
  Key key_;
};

// A live stream gives up after this many undecodable pictures in a row.
constexpr int kMaxStreamDecodeErrors = 250;

class VideoSource final : public FrameSource {
 public:
  VideoSource(std::string location, bool stream, const FrameSourceOptions& options)
      : location_(std::move(location)), stream_(stream), options_(options) {
    name_ = fmt::format("{} '{}'", stream_ ? "stream" : "video", RedactUrl(location_));
  }

  ~VideoSource() override {
    codec_.reset();
    format_.reset();
    CloseFifo();
  }
  VideoSource(const VideoSource&) = delete;
  VideoSource& operator=(const VideoSource&) = delete;

  Status Open();

  std::string Describe() const override {
    std::string text = fmt::format("{} ({}, {}x{}", name_, codec_name_, size_.width, size_.height);
    if (fps_) text += fmt::format(", {:.4g} fps", *fps_);
    return text + ")";
  }
  ImageSize size() const override { return size_; }
  std::optional<double> fps() const override { return fps_; }
  std::optional<int64_t> frame_count() const override { return frame_count_; }
  std::optional<int64_t> next_index() const override { return next_index_; }

  Result<bool> Read(Frame& frame) override {
    OCCMAP_ASSIGN_OR_RETURN(const bool got, DecodeNext());
    if (!got) return false;
    const int64_t index = next_index_++;
    OCCMAP_RETURN_IF_ERROR(ConvertFrame(index, frame));
    frame.index = index;
    const int64_t pts = frame_->best_effort_timestamp;
    if (pts != AV_NOPTS_VALUE) {
      frame.timestamp_s = static_cast<double>(pts) * av_q2d(time_base_);
    } else {
      frame.timestamp_s = fps_ ? static_cast<double>(index) / *fps_ : std::nan("");
    }
    return true;
  }

  // Decodes and discards (no conversion). Going back re-opens a file and decodes from its start.
  Status SkipTo(int64_t index) override {
    if (index < 0) {
      return InvalidInput(fmt::format("{}: cannot skip to frame {}: expected an index >= 0", name_, index));
    }
    if (index < next_index_) {
      if (stream_) {
        return InvalidInput(fmt::format("{}: cannot skip back to frame {} in a live stream (next frame is {})", name_,
                                        index, next_index_));
      }
      OCCMAP_RETURN_IF_ERROR(Open());
    }
    while (next_index_ < index) {
      OCCMAP_ASSIGN_OR_RETURN(const bool got, DecodeNext());
      if (!got) {
        return InvalidInput(
            fmt::format("{}: cannot skip to frame {}: the video ends after {} frames", name_, index, next_index_));
      }
      ++next_index_;
    }
    return Status::Ok();
  }

 private:
  // Leaves the next decoded picture in frame_. false at the end of the stream; a pending
  // read error (truncated file) is returned after the frames already decoded.
  Result<bool> DecodeNext();
  Status ConvertFrame(int64_t index, Frame& out);
  Status ConvertChroma(int64_t index, Frame& out);
  Status OpenOnce();
  Status OpenError(const char* what, int error) const;
  Status FrameError(int64_t index, const std::string& what) const {
    return DataLoss(fmt::format("{}: frame {}: {}", name_, index, what));
  }

  // FFmpeg's pipe: protocol leaves the descriptor open: closed here, after the input.
  void CloseFifo() {
    if (fifo_fd_ < 0) return;
    format_.reset();
    ::close(fifo_fd_);
    fifo_fd_ = -1;
  }
  void ArmDeadline() {
    deadline_ = std::chrono::steady_clock::now() + std::chrono::milliseconds(options_.stream_timeout_ms);
  }
  static int Interrupt(void* opaque) {
    const auto* self = static_cast<VideoSource*>(opaque);
    if (self->options_.cancel != nullptr && self->options_.cancel->load(std::memory_order_relaxed)) return 1;
    return std::chrono::steady_clock::now() > self->deadline_ ? 1 : 0;
  }

  std::string location_;
  bool stream_;
  FrameSourceOptions options_;
  std::string name_;  // for messages: "video 'c1.mp4'"

  std::unique_ptr<AVFormatContext, InputDeleter> format_;
  std::unique_ptr<AVCodecContext, CodecDeleter> codec_;
  std::unique_ptr<AVFrame, FrameDeleter> frame_;
  std::unique_ptr<AVPacket, PacketDeleter> packet_;
  SwsConverter gray_converter_;
  SwsConverter rgb_converter_;
  SwsConverter chroma_converter_;  // formats other than yuv420p / yuvj420p
  Image<uint8_t> chroma_luma_;     // the Y plane of chroma_converter_'s output (not used)
  int stream_index_ = -1;
  AVRational time_base_{0, 1};
  std::string codec_name_;
  ImageSize size_;
  std::optional<double> fps_;
  std::optional<int64_t> frame_count_;

  int64_t next_index_ = 0;
  bool draining_ = false;      // the NULL packet has been sent
  bool finished_ = false;      // the decoder returned EOF
  std::string pending_error_;  // a read error to report once the decoder is drained
  std::chrono::steady_clock::time_point deadline_;
  int decode_errors_in_a_row_ = 0;
  int fifo_fd_ = -1;  // a stream from a local FIFO (see OpenOnce)
};

Status VideoSource::OpenError(const char* what, int error) const {
  std::string message = fmt::format("{}: {}: {}", name_, what, AvErrorWithLog(error));
  if (error == AVERROR_EXIT) {
    return IoError(fmt::format("{}: {}: no answer within {} ms", name_, what, options_.stream_timeout_ms));
  }
  if (error == AVERROR(ENOENT)) return NotFound(message);
  if (fifo_fd_ >= 0 && error == AVERROR_EOF) {  // read(2) of a FIFO gives 0 once its writer is gone
    return IoError(fmt::format("{}: {}: the FIFO's writer closed it", name_, what));
  }
  if (error == AVERROR(ENOMEM)) return ResourceExhausted(message);
  if (error == AVERROR(EACCES) || error == AVERROR(EPERM)) return InvalidInput(message);
  if (stream_) return IoError(message);
  if (error == AVERROR_INVALIDDATA || error == AVERROR_EOF) {
    message += "; the file is not a video, or is truncated or corrupt";
  }
  return DataLoss(message);
}

Status VideoSource::Open() {
  Status status = OpenOnce();
  if (!status.ok()) {  // leave nothing half-open behind (DecodeNext checks codec_)
    codec_.reset();
    format_.reset();
    CloseFifo();
  }
  return status;
}

Status VideoSource::OpenOnce() {
  ffmpeg_internal::InitFfmpeg();
  format_.reset();
  codec_.reset();
  next_index_ = 0;
  draining_ = false;
  finished_ = false;
  pending_error_.clear();
  ClearLog();

  const AVInputFormat* input_format = nullptr;
  if (stream_) {
    static std::once_flag once;
    std::call_once(once, [] {
      avdevice_register_all();
      avformat_network_init();
    });
    if (location_.starts_with("/dev/video")) input_format = av_find_input_format("video4linux2");
  } else {
    // A FIFO (or a device) is refused without opening it: open(2) of a FIFO with no writer
    // blocks for good, out of reach of FFmpeg's interrupt callback (issue 39).
    std::error_code ec;
    if (fs::is_directory(location_, ec)) {
      return InvalidInput(fmt::format("{}: expected a video file, found a folder", name_));
    }
    if (Status s = CheckRegularFile(location_); !s.ok()) {
      if (s.code() == StatusCode::kNotFound) return s;
      std::string what = s.message();  // "'<location>': expected ..." -> "video '<location>': expected ..."
      if (const std::string quoted = fmt::format("'{}': ", location_); what.starts_with(quoted)) what.erase(0, quoted.size());
      return Status(s.code(), fmt::format("{}: {}", name_, what));
    }
  }

  // A stream from a local FIFO (`ffmpeg ... -f mpegts cam.fifo`): opened here without blocking
  // and given to FFmpeg as pipe:FD, so that waiting for a writer, or for data, polls the
  // interrupt callback (the timeout, the run's stop) instead of blocking in open(2) or read(2).
  std::string url = location_;
  CloseFifo();
  if (stream_ && location_.find("://") == std::string::npos) {
    std::error_code ec;
    if (fs::is_fifo(location_, ec)) {
      fifo_fd_ = ::open(location_.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
      if (fifo_fd_ < 0) return IoError(fmt::format("{}: cannot open: {}", name_, std::strerror(errno)));
      url = fmt::format("pipe:{}", fifo_fd_);
      // Until a writer sends something: read(2) gives 0 (the end) while the FIFO has no writer.
      ArmDeadline();
      for (;;) {
        pollfd ready{fifo_fd_, POLLIN, 0};
        if (::poll(&ready, 1, 50) > 0) break;  // data, or a writer came and went (the end, told below)
        if (Interrupt(this) != 0) {
          return IoError(fmt::format("{}: cannot open: no data within {} ms (the FIFO has no writer, or it is silent)",
                                     name_, options_.stream_timeout_ms));
        }
      }
    }
  }

  AVFormatContext* raw = avformat_alloc_context();
  if (raw == nullptr) return ResourceExhausted(fmt::format("{}: out of memory", name_));
  if (stream_) {
    raw->interrupt_callback.callback = &VideoSource::Interrupt;
    raw->interrupt_callback.opaque = this;
  }
  ArmDeadline();
  int error = avformat_open_input(&raw, url.c_str(), input_format, nullptr);
  if (error < 0) return OpenError("cannot open", error);  // raw is freed by FFmpeg
  format_.reset(raw);
  if (!stream_) {
    if (const char* image = ImageFormatName(format_->iformat)) {
      return InvalidInput(fmt::format("{}: expected a video file, found {} (give still images as `images:`)", name_,
                                      image));
    }
  }
  ArmDeadline();
  error = avformat_find_stream_info(format_.get(), nullptr);
  if (error < 0) return OpenError("cannot read the stream parameters", error);

  const AVCodec* decoder = nullptr;
  stream_index_ = av_find_best_stream(format_.get(), AVMEDIA_TYPE_VIDEO, -1, -1, &decoder, 0);
  if (stream_index_ == AVERROR_STREAM_NOT_FOUND) {
    return InvalidInput(
        fmt::format("{}: expected a video stream, found none among its {} streams", name_, format_->nb_streams));
  }
  if (stream_index_ < 0 || decoder == nullptr) {
    AVCodecID codec = AV_CODEC_ID_NONE;
    for (unsigned i = 0; i < format_->nb_streams && codec == AV_CODEC_ID_NONE; ++i) {
      if (format_->streams[i]->codecpar->codec_type == AVMEDIA_TYPE_VIDEO)
        codec = format_->streams[i]->codecpar->codec_id;
    }
    if (codec == AV_CODEC_ID_NONE) {  // e.g. an MP4 cut inside its index
      return DataLoss(
          fmt::format("{}: expected a known video codec, found none (the file is truncated or corrupt)", name_));
    }
    return InvalidInput(
        fmt::format("{}: this FFmpeg has no decoder for the video codec '{}'", name_, avcodec_get_name(codec)));
  }
  for (unsigned i = 0; i < format_->nb_streams; ++i) {
    if (static_cast<int>(i) != stream_index_) format_->streams[i]->discard = AVDISCARD_ALL;
  }
  const AVStream* stream = format_->streams[stream_index_];
  codec_name_ = avcodec_get_name(stream->codecpar->codec_id);
  size_ = {stream->codecpar->width, stream->codecpar->height};
  if (size_.width <= 0 || size_.height <= 0) {
    return DataLoss(fmt::format("{}: expected a frame size, found {}x{} (the file is truncated or corrupt)", name_,
                                size_.width, size_.height));
  }
  time_base_ = stream->time_base;
  AVRational rate = stream->avg_frame_rate;
  if (rate.num <= 0 || rate.den <= 0) rate = stream->r_frame_rate;
  fps_.reset();
  if (rate.num > 0 && rate.den > 0) fps_ = av_q2d(rate);
  frame_count_.reset();
  if (!stream_ && stream->nb_frames > 0) frame_count_ = stream->nb_frames;

  codec_.reset(avcodec_alloc_context3(decoder));
  if (codec_ == nullptr) return ResourceExhausted(fmt::format("{}: out of memory", name_));
  error = avcodec_parameters_to_context(codec_.get(), stream->codecpar);
  if (error < 0) return OpenError("cannot set up the decoder", error);
  codec_->pkt_timebase = stream->time_base;
  codec_->thread_count = options_.decoder_threads > 0
                             ? options_.decoder_threads
                             : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  codec_->thread_type = FF_THREAD_FRAME | FF_THREAD_SLICE;
  error = avcodec_open2(codec_.get(), decoder, nullptr);
  if (error < 0) return OpenError(fmt::format("cannot open the {} decoder", codec_name_).c_str(), error);

  if (frame_ == nullptr) frame_.reset(av_frame_alloc());
  if (packet_ == nullptr) packet_.reset(av_packet_alloc());
  if (frame_ == nullptr || packet_ == nullptr) return ResourceExhausted(fmt::format("{}: out of memory", name_));
  return Status::Ok();
}

Result<bool> VideoSource::DecodeNext() {
  if (codec_ == nullptr) return IoError(fmt::format("{}: not open (re-opening it for SkipTo failed)", name_));
  while (!finished_) {
    int error = avcodec_receive_frame(codec_.get(), frame_.get());
    if (error >= 0) {
      decode_errors_in_a_row_ = 0;
      return true;
    }
    if (error == AVERROR_EOF) {
      finished_ = true;
      break;
    }
    if (error != AVERROR(EAGAIN)) {
      // A damaged picture: fatal in a file; skipped in a live stream, unless nothing decodes.
      if (!stream_ || ++decode_errors_in_a_row_ > kMaxStreamDecodeErrors) {
        return FrameError(next_index_, "cannot decode: " + AvErrorWithLog(error));
      }
      if (!draining_) continue;
    }
    if (draining_) {  // EAGAIN after the flush packet: the decoder has nothing more
      finished_ = true;
      break;
    }
    if (stream_) ArmDeadline();
    ClearLog();
    error = av_read_frame(format_.get(), packet_.get());
    if (error < 0) {
      if (error == AVERROR_EXIT) {
        pending_error_ = fmt::format("no data within {} ms", options_.stream_timeout_ms);
      } else if (error != AVERROR_EOF) {
        pending_error_ = "cannot read: " + AvErrorWithLog(error);
      }
      // Flush: the frames still inside the decoder (frame threads, B-frames) come out first.
      avcodec_send_packet(codec_.get(), nullptr);
      draining_ = true;
      continue;
    }
    if (packet_->stream_index != stream_index_) {
      av_packet_unref(packet_.get());
      continue;
    }
    if ((packet_->flags & AV_PKT_FLAG_CORRUPT) != 0 && !stream_) {
      // A file cut short: the last packet is incomplete. Keep the frames before it.
      av_packet_unref(packet_.get());
      pending_error_ = "truncated or corrupt data (the file ends inside this frame)";
      avcodec_send_packet(codec_.get(), nullptr);
      draining_ = true;
      continue;
    }
    error = avcodec_send_packet(codec_.get(), packet_.get());
    av_packet_unref(packet_.get());
    if (error < 0 && error != AVERROR(EAGAIN) && !stream_) {
      return FrameError(next_index_, "cannot decode: " + AvErrorWithLog(error));
    }
  }
  if (!pending_error_.empty()) {
    const std::string what = std::exchange(pending_error_, std::string());
    if (stream_) return IoError(fmt::format("{}: frame {}: {}", name_, next_index_, what));
    return FrameError(next_index_, what);
  }
  return false;
}

Status VideoSource::ConvertFrame(int64_t index, Frame& out) {
  const AVFrame& picture = *frame_;
  if (picture.width != size_.width || picture.height != size_.height) {
    return InvalidInput(fmt::format("{}: frame {}: expected {}x{} (the size of the first frame), found {}x{}", name_,
                                    index, size_.width, size_.height, picture.width, picture.height));
  }
  if (out.gray.width() != size_.width || out.gray.height() != size_.height) {
    out.gray = Image<uint8_t>(size_.width, size_.height);
  }
  const auto format = static_cast<AVPixelFormat>(picture.format);
  if (HasPlainLumaPlane(format)) {
    const bool full_range = IsFullRange(picture);
    for (int y = 0; y < size_.height; ++y) {
      const uint8_t* src = picture.data[0] + static_cast<ptrdiff_t>(y) * picture.linesize[0];
      uint8_t* dst = out.gray.row(y);
      if (full_range) {
        std::memcpy(dst, src, static_cast<size_t>(size_.width));
      } else {
        ExpandLimitedRangeLuma(src, dst, size_.width);
      }
    }
  } else {
    Status status =
        gray_converter_.Convert(picture, AV_PIX_FMT_GRAY8, out.gray.row(0), static_cast<int>(out.gray.stride_elems()));
    if (!status.ok()) return status.WithContext(fmt::format("{}: frame {}", name_, index));
  }
  if (options_.chroma) {
    OCCMAP_RETURN_IF_ERROR(ConvertChroma(index, out));
  } else {
    out.u = Image<uint8_t>();
    out.v = Image<uint8_t>();
  }
  if (!options_.colour) {
    out.rgb = Image<Rgb8>();
    return Status::Ok();
  }
  if (out.rgb.width() != size_.width || out.rgb.height() != size_.height) {
    out.rgb = Image<Rgb8>(size_.width, size_.height);
  }
  Status status = rgb_converter_.Convert(picture, AV_PIX_FMT_RGB24, reinterpret_cast<uint8_t*>(out.rgb.row(0)),
                                         static_cast<int>(out.rgb.stride_elems() * 3));
  if (!status.ok()) return status.WithContext(fmt::format("{}: frame {}", name_, index));
  return Status::Ok();
}

Status VideoSource::ConvertChroma(int64_t index, Frame& out) {
  const AVFrame& picture = *frame_;
  const int chroma_width = ChromaPlaneSize(size_.width), chroma_height = ChromaPlaneSize(size_.height);
  for (Image<uint8_t>* plane : {&out.u, &out.v}) {
    if (plane->width() != chroma_width || plane->height() != chroma_height) {
      *plane = Image<uint8_t>(chroma_width, chroma_height);
    }
  }
  const auto format = static_cast<AVPixelFormat>(picture.format);
  if (format == AV_PIX_FMT_YUV420P || format == AV_PIX_FMT_YUVJ420P) {
    const bool full_range = IsFullRange(picture);
    for (int p = 1; p <= 2; ++p) {
      Image<uint8_t>& plane = p == 1 ? out.u : out.v;
      for (int y = 0; y < chroma_height; ++y) {
        const uint8_t* src = picture.data[p] + static_cast<ptrdiff_t>(y) * picture.linesize[p];
        if (full_range) {
          std::memcpy(plane.row(y), src, static_cast<size_t>(chroma_width));
        } else {
          ExpandLimitedRangeChroma(src, plane.row(y), chroma_width);
        }
      }
    }
    return Status::Ok();
  }
  if (chroma_luma_.width() != size_.width || chroma_luma_.height() != size_.height) {
    chroma_luma_ = Image<uint8_t>(size_.width, size_.height);
  }
  uint8_t* const planes[4] = {chroma_luma_.row(0), out.u.row(0), out.v.row(0), nullptr};
  const int strides[4] = {static_cast<int>(chroma_luma_.stride_elems()), static_cast<int>(out.u.stride_elems()),
                          static_cast<int>(out.v.stride_elems()), 0};
  // A limited-range source stays limited through libswscale (whose own range conversion of
  // chroma is off by about 1 level) and is expanded as the yuv420p planes above: the same
  // chroma whichever layout the decoder gives.
  const bool full_range = IsFullRange(picture);
  Status status = chroma_converter_.Convert(picture, AV_PIX_FMT_YUV420P, planes, strides, full_range);
  if (!status.ok()) return status.WithContext(fmt::format("{}: frame {}", name_, index));
  if (!full_range) {
    for (Image<uint8_t>* plane : {&out.u, &out.v}) {
      for (int y = 0; y < chroma_height; ++y) ExpandLimitedRangeChroma(plane->row(y), plane->row(y), chroma_width);
    }
  }
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<FrameSource>> OpenVideoSource(const std::string& location, bool stream,
                                                     const FrameSourceOptions& options) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  auto source = std::make_unique<VideoSource>(location, stream, options);
  OCCMAP_RETURN_IF_ERROR(source->Open());
  return std::unique_ptr<FrameSource>(std::move(source));
}

}  // namespace occmap
