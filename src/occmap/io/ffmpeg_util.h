// What the FFmpeg-based readers and writers share: error text, FFmpeg's log kept quiet (the
// library never prints) with its last error line kept for our messages, and RAII deleters.
//
//   ffmpeg_internal::InitFfmpeg();
//   std::unique_ptr<AVFrame, ffmpeg_internal::FrameDeleter> frame(av_frame_alloc());
//   return DataLoss("decode failed: " + ffmpeg_internal::AvErrorWithLog(error));
#pragma once

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/frame.h>
#include <libswscale/swscale.h>
}

#include <string>

namespace occmap::ffmpeg_internal {

// Installs the process-wide av_log callback (once).
void InitFfmpeg();
std::string AvError(int error);
// The FFmpeg error text, plus the last line FFmpeg logged on this thread when there is one:
// "Invalid data found when processing input (moov atom not found)". Clears the log line.
std::string AvErrorWithLog(int error);
void ClearLog();

struct CodecDeleter {
  void operator()(AVCodecContext* p) const { avcodec_free_context(&p); }
};
struct FrameDeleter {
  void operator()(AVFrame* p) const { av_frame_free(&p); }
};
struct PacketDeleter {
  void operator()(AVPacket* p) const { av_packet_free(&p); }
};
struct SwsDeleter {
  void operator()(SwsContext* p) const { sws_freeContext(p); }
};

}  // namespace occmap::ffmpeg_internal
