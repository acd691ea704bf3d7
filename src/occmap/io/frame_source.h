// FrameSource: frames of one camera from image sequences, video files, live streams or
// precomputed foreground masks.
//
// Video and streams are decoded with FFmpeg's libav* directly: frame threading on the
// decoder's threads, grey taken straight from the Y plane (no colour conversion unless colour
// is asked for), chroma (when asked for) straight from the U and V planes of yuv420p video,
// presentation timestamps in seconds. Image sequences are a printf-style
// pattern (`frames/c1_%06d.png`, first index found automatically, 0 or 1), a folder (its
// PNG/JPEG files in name order) or one image file. A mask source reads 8-bit foreground masks
// the same way.
//
// Read() returns false at the end of the stream and an error (naming the source and the frame
// index) for a frame that cannot be read: a truncated video, a corrupt image, a frame whose
// size differs from the first one.
//
//   OCCMAP_ASSIGN_OR_RETURN(auto source, OpenFrameSource({FrameSourceSpec::Kind::kVideo, "c1.mp4"}, {}));
//   Frame frame;
//   while (true) { OCCMAP_ASSIGN_OR_RETURN(bool got, source->Read(frame)); if (!got) break; ... }
//
// Conventions:
// - Frame::index counts the frames of the source from 0 (for a pattern that starts at file 1,
//   index 0 is file 1).
// - Frame::gray is full-range luma, 0..255, whatever the source: limited-range (16..235) video
//   is expanded, so a grey level means the same thing for video and image files. For masks it
//   is the mask file as it is (non-zero = foreground).
// - Frame::u and v (with FrameSourceOptions::chroma) are 4:2:0 chroma, Cb and Cr: one sample
//   per 2x2 block of pixels (ceil(width / 2) x ceil(height / 2), block (i, j) = pixels
//   2i..2i+1 x 2j..2j+1), full range 0..255 with 128 = neutral (grey), BT.601, as JPEG's
//   YCbCr: the convention of util/yuv.h, where gray is its Y. Image files: computed from the
//   RGB pixels (util/yuv.h: ChromaFromRgb, the mean over each block; gray = LumaFromRgb, Y of
//   the same formulas). yuv420p / yuvj420p video: the decoder's U and V planes, limited range
//   (16..240) expanded to 0..255 around 128 (io/limited_range.h); other pixel formats through
//   libswscale to full-range yuv420p. The two agree within a few levels on the same picture
//   (encoding losses). Never filled for masks.
// - Every frame of a source has the size of its first frame; a frame of another size is an
//   error, not a silent resize.
// - A source is used from one thread at a time.
// - FFmpeg's log never reaches stderr (the library never prints): the first video source or
//   writer installs a process-wide av_log callback that keeps the last error line of each
//   thread for our messages, e.g. "... Invalid data found when processing input (moov atom
//   not found)".
// - Video: timestamp_s = best_effort_timestamp x the stream's time base (index / fps when the
//   container has none). A truncated or corrupt file gives the frames before the damage, then
//   a kDataLoss error naming the file and the frame index. Live streams skip damaged pictures,
//   and a read that blocks longer than stream_timeout_ms fails with kIoError.
#pragma once

#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "occmap/geometry/camera_model.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

struct FrameSourceSpec {
  // kImages: pattern, folder or image file. kVideo: a video file. kStream: anything
  // avformat_open_input accepts (rtsp://, http://, a /dev/video* device through v4l2).
  // kMasks: like kImages, 8-bit foreground masks.
  enum class Kind { kNone, kImages, kVideo, kStream, kMasks };
  Kind kind = Kind::kNone;
  std::string location;  // path, printf-style pattern, folder, or URL / device
  // Image sequences and masks: their frame rate (> 0 gives timestamps index / fps, overriding
  // FrameSourceOptions::image_fps); 0: none. Video and streams keep their own.
  double fps = 0;
  // Image sequences and masks: each image's time in seconds (io/frame_times.h), from image 0;
  // empty: none. Exclusive with fps.
  std::vector<double> timestamps_s = {};
};

const char* ToString(FrameSourceSpec::Kind kind);

struct Frame {
  int64_t index = -1;                 // frame number within its source, from 0
  double timestamp_s = std::nan("");  // presentation time when the source has one
  Image<uint8_t> gray;                // always filled (for masks: the mask itself)
  Image<Rgb8> rgb;                    // filled only when colour was asked for (never for masks)
  Image<uint8_t> u, v;                // chroma (Cb, Cr), filled only when asked for (never for masks)
};

struct FrameSourceOptions {
  bool colour = false;      // also fill Frame::rgb (ignored for masks)
  bool chroma = false;      // also fill Frame::u and v (ignored for masks)
  int decoder_threads = 0;  // FFmpeg frame threads; 0 = all cores
  // Image sequences and masks: timestamp_s = index / image_fps when > 0 (fps() reports it);
  // NaN otherwise. Video and streams take their own timestamps and ignore it.
  double image_fps = 0;
  // Image sequences and masks: timestamp_s = image_times_s[index] when not empty (an image
  // beyond its end is an error), and fps() their mean rate; overrides image_fps.
  std::vector<double> image_times_s = {};
  // Streams: an open or a read that blocks longer than this fails (kIoError) rather than hang.
  int stream_timeout_ms = 10000;
  // Streams: when set and true, a blocked open or read gives up at once (kIoError), so that a
  // reader thread can be stopped without waiting for the time-out.
  const std::atomic<bool>* cancel = nullptr;

  Status Validate() const;
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // For messages: "video 'c1.mp4' (h264, 1920x1080, 25 fps)".
  virtual std::string Describe() const = 0;
  virtual ImageSize size() const = 0;
  virtual std::optional<double> fps() const { return std::nullopt; }
  virtual std::optional<int64_t> frame_count() const { return std::nullopt; }  // when known
  // The index of the frame the next Read returns, when the source knows it (all sources of
  // OpenFrameSource do).
  virtual std::optional<int64_t> next_index() const { return std::nullopt; }
  // Reads the next frame, reusing frame's buffers. false at the end of the stream.
  virtual Result<bool> Read(Frame& frame) = 0;
  // Skips to frame `index` (the next Read returns it; index == the number of frames is the end
  // of the stream). An error when the source ends before `index`, or when it cannot go back.
  // Default: read and discard (needs next_index()).
  virtual Status SkipTo(int64_t index);
};

Result<std::unique_ptr<FrameSource>> OpenFrameSource(const FrameSourceSpec& spec, const FrameSourceOptions& options);

// `first` (opened from spec and options) read again from its start each time it ends, for ever:
// a video file or image sequence as an endless camera (`--loop`). Indices go on counting and
// timestamps go on increasing (each pass shifted by the previous passes' length: their last
// timestamp plus a frame interval); a source that ends without a frame ends the loop too.
// Streams and masks are refused.
Result<std::unique_ptr<FrameSource>> LoopFrameSource(const FrameSourceSpec& spec, const FrameSourceOptions& options,
                                                     std::unique_ptr<FrameSource> first);

// A source location for messages: a URL's password replaced ("rtsp://user:secret@cam/1" ->
// "rtsp://user:***@cam/1"); anything else as it is.
std::string RedactUrl(const std::string& url);

// The two families behind OpenFrameSource, for callers that know what they open.
// `masks` selects the mask flavour of an image sequence (kMasks).
Result<std::unique_ptr<FrameSource>> OpenImageSequence(const std::string& location, bool masks,
                                                       const FrameSourceOptions& options);
// `stream` selects live-stream handling (kStream): devices, network time-outs, no frame count,
// corrupt packets skipped rather than fatal.
Result<std::unique_ptr<FrameSource>> OpenVideoSource(const std::string& location, bool stream,
                                                     const FrameSourceOptions& options);

}  // namespace occmap
