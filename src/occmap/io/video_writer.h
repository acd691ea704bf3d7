// VideoWriter: encodes RGB frames to a video file with FFmpeg's libav* (H.264 when the
// encoder is available, MPEG-4 part 2 otherwise), written atomically: frames go to a temporary
// file next to the target, renamed into place by Close(). A writer destroyed without Close()
// removes its temporary file, so an interrupted run never leaves a half-written video.
//
//   OCCMAP_ASSIGN_OR_RETURN(auto writer, VideoWriter::Open("mosaic.mp4", {1280, 720}, 10.0));
//   OCCMAP_RETURN_IF_ERROR(writer->Write(rgb.view()));
//   OCCMAP_RETURN_IF_ERROR(writer->Close());
//
// With VideoWriterOptions::fragmented the file is written in place instead, playable at any time.
//
// The container comes from the file extension (.mp4, .mkv, .avi, .mov); MP4/MOV files have
// their index in front ("faststart"). Pictures are stored as yuv420p, BT.601, limited range,
// tagged as such; H.264 at constant quality (x264 crf 23 unless VideoWriterOptions::crf, preset
// veryfast), MPEG-4 at a constant quantiser of 4. Odd sizes are padded to even ones by
// repeating the last column / row, so a reader sees the padded size. Frame i has the timestamp
// i / fps. FFmpeg's own log is kept quiet (see frame_source.h). A writer is used from one thread at a time.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "occmap/geometry/camera_model.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

struct VideoWriterOptions {
  // "" = "libx264" when FFmpeg has it and the container takes H.264, else "mpeg4".
  // "libx264" or "mpeg4" ask for that encoder (an error when it cannot be used).
  std::string encoder;
  // Write straight into `path` as fragmented MP4 (a fragment at every key frame, every 2 s;
  // .mp4/.mov only) instead of a temporary renamed at Close: a player reads the file up to its
  // last whole fragment while it is written and after the process dies (kill -9). Close then
  // only flushes the last fragment. For live runs (pipeline/output_files.h).
  bool fragmented = false;
  // H.264's constant rate factor, 0 (lossless) .. 51 (worst); -1 = 23. MPEG-4 takes it as the
  // quantiser 4 x 2^((crf - 23) / 6), within 2..31.
  int crf = -1;
};

class VideoWriter {
 public:
  // size: width and height are rounded up to even numbers (yuv420p); frames are padded.
  static Result<std::unique_ptr<VideoWriter>> Open(const std::filesystem::path& path, ImageSize size, double fps);
  static Result<std::unique_ptr<VideoWriter>> Open(const std::filesystem::path& path, ImageSize size, double fps,
                                                   const VideoWriterOptions& options);
  virtual ~VideoWriter() = default;
  virtual Status Write(ImageView<const Rgb8> frame) = 0;  // frame size == the size given to Open
  // Flushes the encoder, finalises the container, syncs the file and renames it into place.
  // After a failed Write, Finish or Close the temporary file is already removed; call nothing more.
  virtual Status Close() = 0;
  // All of Close but the rename (a full disk is found here): outputs that appear together or
  // not at all are each finished, then closed only when every one finished. Close then renames.
  virtual Status Finish() = 0;
  virtual std::string codec_name() const = 0;  // the encoder: "libx264" or "mpeg4"
};

}  // namespace occmap
