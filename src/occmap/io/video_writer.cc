#include "occmap/io/video_writer.h"

#include "occmap/io/ffmpeg_util.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <fcntl.h>
#include <fmt/core.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace occmap {

// Defined in video_source.cc: FFmpeg's log kept quiet, error texts with its last log line.

namespace {
namespace fs = std::filesystem;
using ffmpeg_internal::AvErrorWithLog;

// Closes the file (when the muxer opened one) and frees the context.
struct OutputDeleter {
  void operator()(AVFormatContext* p) const {
    if (p->pb != nullptr && (p->oformat->flags & AVFMT_NOFILE) == 0) avio_closep(&p->pb);
    avformat_free_context(p);
  }
};
using ffmpeg_internal::CodecDeleter;
using ffmpeg_internal::FrameDeleter;
using ffmpeg_internal::PacketDeleter;
using ffmpeg_internal::SwsDeleter;
struct Dictionary {
  Dictionary() = default;
  Dictionary(const Dictionary&) = delete;
  Dictionary& operator=(const Dictionary&) = delete;
  ~Dictionary() { av_dict_free(&dict); }
  AVDictionary* dict = nullptr;
};

constexpr int kX264Crf = 23;                     // x264's default quality: visually good, compact
constexpr const char* kX264Preset = "veryfast";  // fast to encode; files somewhat larger than "medium"
constexpr int kMpeg4QScale = 4;                  // MPEG-4 part 2 constant quantiser (2 = best, 31 = worst)

class VideoWriterImpl final : public VideoWriter {
 public:
  explicit VideoWriterImpl(fs::path path) : path_(std::move(path)) {}
  ~VideoWriterImpl() override {
    if (!closed_) Abandon();
  }

  Status Open(ImageSize size, double fps, const VideoWriterOptions& options);
  Status Write(ImageView<const Rgb8> frame) override;
  Status Close() override;
  Status Finish() override;
  std::string codec_name() const override { return codec_name_; }

 private:
  // Sends `frame` (nullptr: flush) to the encoder and writes every packet it gives back.
  Status Encode(const AVFrame* frame);
  // Frees the FFmpeg objects and removes the temporary file.
  void Abandon() {
    codec_.reset();
    format_.reset();
    if (!tmp_path_.empty() && !fragmented_) {  // a fragmented file stays: valid to its last fragment
      std::error_code ec;
      fs::remove(tmp_path_, ec);
    }
    closed_ = true;
  }
  Status Fail(Status status) {
    Abandon();
    return status;
  }
  std::string Where() const { return fmt::format("'{}'", path_.string()); }

  fs::path path_;
  fs::path tmp_path_;
  ImageSize size_;   // as given to Open
  ImageSize coded_;  // rounded up to even numbers
  std::string codec_name_;
  std::unique_ptr<AVFormatContext, OutputDeleter> format_;
  std::unique_ptr<AVCodecContext, CodecDeleter> codec_;
  std::unique_ptr<AVFrame, FrameDeleter> yuv_;
  std::unique_ptr<AVPacket, PacketDeleter> packet_;
  std::unique_ptr<SwsContext, SwsDeleter> sws_;
  std::vector<uint8_t> staging_;  // padded copy of the RGB frame (see Write)
  AVStream* stream_ = nullptr;  // owned by format_
  int64_t frames_written_ = 0;
  bool closed_ = false;
  bool finished_ = false;  // Finish worked: the temporary is whole and synced, not renamed
  bool fragmented_ = false;  // VideoWriterOptions::fragmented: tmp_path_ is path_ itself
};

Status VideoWriterImpl::Open(ImageSize size, double fps, const VideoWriterOptions& options) {
  ffmpeg_internal::InitFfmpeg();
  ffmpeg_internal::ClearLog();
  if (size.width <= 0 || size.height <= 0 || size.width > 16384 || size.height > 16384) {
    return InvalidInput(
        fmt::format("{}: video size: expected 1..16384 x 1..16384, found {}x{}", Where(), size.width, size.height));
  }
  if (!std::isfinite(fps) || fps <= 0 || fps > 1000) {
    return InvalidInput(fmt::format("{}: frame rate: expected 0 < fps <= 1000, found {}", Where(), fps));
  }
  size_ = size;
  coded_ = {size.width + (size.width & 1), size.height + (size.height & 1)};

  const AVOutputFormat* container = av_guess_format(nullptr, path_.filename().c_str(), nullptr);
  if (container == nullptr || path_.extension().empty()) {
    return InvalidInput(fmt::format("{}: expected a video file extension (.mp4, .mkv, .avi, .mov), found '{}'", Where(),
                                    path_.extension().string()));
  }
  if (options.crf < -1 || options.crf > 51) {
    return InvalidInput(
        fmt::format("{}: crf: expected -1 (the default, {}) or 0..51, found {}", Where(), kX264Crf, options.crf));
  }
  if (!options.encoder.empty() && options.encoder != "libx264" && options.encoder != "mpeg4") {
    return InvalidInput(
        fmt::format("{}: encoder: expected '', 'libx264' or 'mpeg4', found '{}'", Where(), options.encoder));
  }
  const AVCodec* encoder = nullptr;
  for (const auto& [name, id] : {std::pair{"libx264", AV_CODEC_ID_H264}, std::pair{"mpeg4", AV_CODEC_ID_MPEG4}}) {
    if (encoder != nullptr || (!options.encoder.empty() && options.encoder != name)) continue;
    if (avformat_query_codec(container, id, FF_COMPLIANCE_NORMAL) != 1) continue;
    encoder = avcodec_find_encoder_by_name(name);
  }
  if (encoder == nullptr) {
    return InvalidInput(fmt::format("{}: the '{}' container cannot take {} video (or this FFmpeg lacks the encoder)",
                                    Where(), container->name,
                                    options.encoder.empty() ? "H.264 (libx264) or MPEG-4" : options.encoder));
  }
  codec_name_ = encoder->name;

  const std::string_view container_name(container->name);
  fragmented_ = options.fragmented;
  if (fragmented_ && container_name != "mp4" && container_name != "mov") {
    return InvalidInput(fmt::format("{}: fragmented output needs an .mp4 or .mov file, found the '{}' container", Where(),
                                    container_name));
  }
  static std::atomic<uint64_t> counter{0};
  const fs::path dir = path_.has_parent_path() ? path_.parent_path() : fs::path(".");
  tmp_path_ = fragmented_ ? path_
                          : dir / fmt::format(".tmp-{}-{}-{}{}", path_.stem().string(), ::getpid(), counter++,
                                              path_.extension().string());

  AVFormatContext* raw = nullptr;
  int error = avformat_alloc_output_context2(&raw, container, nullptr, tmp_path_.c_str());
  if (error < 0 || raw == nullptr) {
    return Fail(IoError(fmt::format("{}: cannot set up the muxer: {}", Where(), AvErrorWithLog(error))));
  }
  format_.reset(raw);
  stream_ = avformat_new_stream(format_.get(), nullptr);
  codec_.reset(avcodec_alloc_context3(encoder));
  yuv_.reset(av_frame_alloc());
  packet_.reset(av_packet_alloc());
  if (stream_ == nullptr || codec_ == nullptr || yuv_ == nullptr || packet_ == nullptr) {
    return Fail(ResourceExhausted(fmt::format("{}: out of memory", Where())));
  }

  const AVRational frame_rate = av_d2q(fps, 1001000);
  codec_->width = coded_.width;
  codec_->height = coded_.height;
  codec_->pix_fmt = AV_PIX_FMT_YUV420P;
  codec_->framerate = frame_rate;
  codec_->time_base = av_inv_q(frame_rate);
  codec_->gop_size = std::clamp(static_cast<int>(std::lround(2 * fps)), 1, 600);  // a key frame every 2 s
  // AVI stores no presentation times, so frames must leave the encoder in display order.
  if (std::string_view(container->name) == "avi") codec_->max_b_frames = 0;
  codec_->sample_aspect_ratio = {1, 1};
  // BT.601 matrix, limited range: what libswscale produces by default and what every player
  // assumes for yuv420p; written into the stream so that readers need not guess.
  codec_->color_range = AVCOL_RANGE_MPEG;
  codec_->colorspace = AVCOL_SPC_SMPTE170M;
  codec_->color_primaries = AVCOL_PRI_SMPTE170M;
  codec_->color_trc = AVCOL_TRC_SMPTE170M;
  if ((container->flags & AVFMT_GLOBALHEADER) != 0) codec_->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  Dictionary codec_options;
  if (codec_name_ == "libx264") {
    av_dict_set(&codec_options.dict, "preset", kX264Preset, 0);
    av_dict_set_int(&codec_options.dict, "crf", options.crf >= 0 ? options.crf : kX264Crf, 0);
  } else {
    codec_->flags |= AV_CODEC_FLAG_QSCALE;
    // A crf as a quantiser: x264's scale doubles the step every 6, from crf 23 at the default 4.
    const int qscale = options.crf >= 0 ? std::clamp(static_cast<int>(std::lround(kMpeg4QScale * std::exp2((options.crf - kX264Crf) / 6.0))), 2, 31)
                                        : kMpeg4QScale;
    codec_->global_quality = FF_QP2LAMBDA * qscale;
  }
  error = avcodec_open2(codec_.get(), encoder, &codec_options.dict);
  if (error < 0) {
    return Fail(
        IoError(fmt::format("{}: cannot open the {} encoder: {}", Where(), codec_name_, AvErrorWithLog(error))));
  }
  error = avcodec_parameters_from_context(stream_->codecpar, codec_.get());
  if (error < 0) return Fail(IoError(fmt::format("{}: cannot set up the stream: {}", Where(), AvErrorWithLog(error))));
  stream_->time_base = codec_->time_base;
  stream_->avg_frame_rate = frame_rate;

  if ((container->flags & AVFMT_NOFILE) == 0) {
    error = avio_open(&format_->pb, tmp_path_.c_str(), AVIO_FLAG_WRITE);
    if (error < 0) {
      return Fail(
          IoError(fmt::format("{}: cannot create '{}': {}", Where(), tmp_path_.string(), AvErrorWithLog(error))));
    }
  }
  Dictionary muxer_options;
  // MP4/MOV: the index goes in front (a second pass at Close), so that a cut file still plays.
  // Fragmented: an empty index in front and a fragment per key frame, each flushed to the file
  // as it is finished, so that the file plays up to its last fragment at any time.
  if (fragmented_) {
    // skip_trailer: no fragment index (mfra) at the end, which the muxer would keep in memory
    // for the whole run (an entry per fragment); players find the fragments without it.
    av_dict_set(&muxer_options.dict, "movflags", "+frag_keyframe+empty_moov+default_base_moof+skip_trailer", 0);
    format_->flush_packets = 1;
  } else {
    av_dict_set(&muxer_options.dict, "movflags", "+faststart", 0);
  }
  error = avformat_write_header(format_.get(), &muxer_options.dict);
  if (error < 0) return Fail(IoError(fmt::format("{}: cannot write the header: {}", Where(), AvErrorWithLog(error))));

  yuv_->format = AV_PIX_FMT_YUV420P;
  yuv_->width = coded_.width;
  yuv_->height = coded_.height;
  yuv_->color_range = AVCOL_RANGE_MPEG;
  yuv_->colorspace = AVCOL_SPC_SMPTE170M;
  error = av_frame_get_buffer(yuv_.get(), 0);
  if (error < 0)
    return Fail(ResourceExhausted(fmt::format("{}: cannot allocate a frame: {}", Where(), AvErrorWithLog(error))));

  sws_.reset(sws_getContext(size_.width, size_.height, AV_PIX_FMT_RGB24, size_.width, size_.height, AV_PIX_FMT_YUV420P,
                            SWS_BILINEAR | SWS_ACCURATE_RND, nullptr, nullptr, nullptr));
  if (sws_ == nullptr) return Fail(Internal(fmt::format("{}: cannot set up the RGB to YUV conversion", Where())));
  const int* bt601 = sws_getCoefficients(SWS_CS_ITU601);
  sws_setColorspaceDetails(sws_.get(), bt601, /*srcRange=*/1, bt601, /*dstRange=*/0, 0, 1 << 16, 1 << 16);
  return Status::Ok();
}

Status VideoWriterImpl::Write(ImageView<const Rgb8> frame) {
  if (closed_ || finished_) return Internal(fmt::format("{}: Write after Finish or Close (or after a failed write)", Where()));
  if (frame.width() != size_.width || frame.height() != size_.height) {
    return InvalidInput(fmt::format("{}: frame {}: expected {}x{} (the size given to Open), found {}x{}", Where(),
                                    frames_written_, size_.width, size_.height, frame.width(), frame.height()));
  }
  // The encoder may still hold a reference to the previous picture.
  int error = av_frame_make_writable(yuv_.get());
  if (error < 0)
    return Fail(ResourceExhausted(fmt::format("{}: cannot allocate a frame: {}", Where(), AvErrorWithLog(error))));
  // libswscale's SIMD reads may run past the end of a row; an image whose rows end exactly at
  // the end of its allocation (width * 3 a multiple of the row alignment) would be read out of
  // bounds. So the rows go through a staging buffer with a padded stride and 64 spare bytes.
  const size_t row_bytes = static_cast<size_t>(frame.width()) * 3;
  const size_t staging_stride = (row_bytes + 63) / 64 * 64;
  staging_.resize(staging_stride * static_cast<size_t>(frame.height()) + 64);
  for (int y = 0; y < frame.height(); ++y) {
    std::memcpy(staging_.data() + staging_stride * static_cast<size_t>(y), frame.row(y), row_bytes);
  }
  const uint8_t* src[4] = {staging_.data(), nullptr, nullptr, nullptr};
  const int src_stride[4] = {static_cast<int>(staging_stride), 0, 0, 0};
  sws_scale(sws_.get(), src, src_stride, 0, size_.height, yuv_->data, yuv_->linesize);
  // Odd sizes: repeat the last column and row of luma (libswscale fills the chroma of the
  // half pixel already), which compresses better than black.
  uint8_t* luma = yuv_->data[0];
  const ptrdiff_t pitch = yuv_->linesize[0];
  if (coded_.width != size_.width) {
    for (int y = 0; y < size_.height; ++y) luma[y * pitch + size_.width] = luma[y * pitch + size_.width - 1];
  }
  if (coded_.height != size_.height) {
    std::memcpy(luma + size_.height * pitch, luma + (size_.height - 1) * pitch, static_cast<size_t>(coded_.width));
  }
  yuv_->pts = frames_written_;
  OCCMAP_RETURN_IF_ERROR(Encode(yuv_.get()));
  ++frames_written_;
  return Status::Ok();
}

Status VideoWriterImpl::Encode(const AVFrame* frame) {
  ffmpeg_internal::ClearLog();
  int error = avcodec_send_frame(codec_.get(), frame);
  if (error < 0) {
    return Fail(
        IoError(fmt::format("{}: frame {}: cannot encode: {}", Where(), frames_written_, AvErrorWithLog(error))));
  }
  while (true) {
    error = avcodec_receive_packet(codec_.get(), packet_.get());
    if (error == AVERROR(EAGAIN) || error == AVERROR_EOF) return Status::Ok();
    if (error < 0) {
      return Fail(
          IoError(fmt::format("{}: frame {}: cannot encode: {}", Where(), frames_written_, AvErrorWithLog(error))));
    }
    av_packet_rescale_ts(packet_.get(), codec_->time_base, stream_->time_base);
    packet_->stream_index = stream_->index;
    error = av_interleaved_write_frame(format_.get(), packet_.get());  // takes the packet's data
    if (error < 0) return Fail(IoError(fmt::format("{}: cannot write: {}", Where(), AvErrorWithLog(error))));
  }
}

Status VideoWriterImpl::Finish() {
  if (closed_) return Internal(fmt::format("{}: Finish called after Close (or after a failed write)", Where()));
  if (finished_) return Status::Ok();
  OCCMAP_RETURN_IF_ERROR(Encode(nullptr));
  int error = av_write_trailer(format_.get());
  if (error < 0) return Fail(IoError(fmt::format("{}: cannot finish the file: {}", Where(), AvErrorWithLog(error))));
  if (format_->pb != nullptr) {
    error = avio_closep(&format_->pb);
    if (error < 0) return Fail(IoError(fmt::format("{}: cannot write: {}", Where(), AvErrorWithLog(error))));
  }
  if (!fragmented_) {  // flush to disk before the rename, as WriteFileAtomic does
    const int fd = ::open(tmp_path_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0 || ::fsync(fd) != 0) {
      const int err = errno;
      if (fd >= 0) ::close(fd);
      return Fail(IoError(fmt::format("{}: flush failed: {}", Where(), std::strerror(err))));
    }
    ::close(fd);
  }
  finished_ = true;
  return Status::Ok();
}

Status VideoWriterImpl::Close() {
  if (closed_) return Internal(fmt::format("{}: Close called twice (or after a failed write)", Where()));
  OCCMAP_RETURN_IF_ERROR(Finish());
  if (fragmented_) {  // written in place: nothing to rename, and it stays
    tmp_path_.clear();
    codec_.reset();
    format_.reset();
    closed_ = true;
    return Status::Ok();
  }
  if (::rename(tmp_path_.c_str(), path_.c_str()) != 0) {
    return Fail(IoError(fmt::format("{}: cannot rename into place: {}", Where(), std::strerror(errno))));
  }
  tmp_path_.clear();
  codec_.reset();
  format_.reset();
  closed_ = true;
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<VideoWriter>> VideoWriter::Open(const std::filesystem::path& path, ImageSize size, double fps) {
  return Open(path, size, fps, VideoWriterOptions());
}

Result<std::unique_ptr<VideoWriter>> VideoWriter::Open(const std::filesystem::path& path, ImageSize size, double fps,
                                                       const VideoWriterOptions& options) {
  auto writer = std::make_unique<VideoWriterImpl>(path);
  OCCMAP_RETURN_IF_ERROR(writer->Open(size, fps, options));
  return std::unique_ptr<VideoWriter>(std::move(writer));
}

}  // namespace occmap
