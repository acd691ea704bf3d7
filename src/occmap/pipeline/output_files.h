// OutputFiles: the run's per-frame files in out_dir, as a FrameSink (pipeline/frame_sink.h):
//   detections.jsonl   one line per frame set: {"frame", "time_s", "blobs": [{x_m, y_m, area_m2, cells}]}
//   tracks.jsonl       one line per frame set (track/track_output.h), with tracking
//   tracks_mot.csv     the tracks as MOTChallenge ground-plane rows, with tracking
//   events.jsonl       zone events and line crossings, one line each, with tracking and zones or lines
//   occupancy.mp4      the map per frame set (white free, black occupied, grey unseen)
//   occupancy/NNNNNN.png, changes/<camera>/NNNNNN.png, mosaic.mp4   when asked for
// The lines are what eval/run_outputs.h reads (a round-trip test holds them together).
//
// Two modes (OutputMode):
//   kLive    (the default of `occmap run`) each file is created at its final name when the run
//            starts and every frame set's text is appended with one write(2) of whole lines, so
//            a reader tailing the file never sees a partial line and a killed run (kill -9)
//            leaves every file valid up to its last line. A write that fails (a full disk: a
//            short write, then ENOSPC) is taken back: the file is cut to its last whole line,
//            and every line file to the frame set before (they agree), and the run stops with
//            the error. Videos are fragmented MP4 written in place, playable up to their last
//            fragment (a key frame every 2 s).
//   kAtomic  every file goes to a temporary next to it and is renamed into place at Close: the
//            outputs appear all at once, or (a failed run) not at all. Close finishes every
//            file (flushed, synced: a full disk is found here) before it renames any.
// Nothing is fsync'ed per frame set: what was written survives the process (kill -9), and Close
// syncs each file once.
//
//   OutputFiles files(options);
//   OCCMAP_RETURN_IF_ERROR(files.Open(start));
//   OCCMAP_RETURN_IF_ERROR(files.Consume(record, stats));   // per frame set
//   OCCMAP_RETURN_IF_ERROR(files.Close(stats));             // files.written(): the files
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "occmap/io/video_writer.h"
#include "occmap/pipeline/frame_sink.h"
#include "occmap/util/file_util.h"

namespace occmap {

enum class OutputMode { kLive, kAtomic };
const char* ToString(OutputMode mode);  // "live", "atomic"

// `line` (a JSON object) with "t_unix" (seconds since 1970, to 1 us) as its first key.
std::string WithTUnix(std::string_view line, double t_unix);

// Fills r.tracks_line and r.event_lines from r's tracks, zone and line events, each with
// "t_unix" first when wall_clock_times.
void MakeJsonLines(FrameRecord& r, bool wall_clock_times);

// One line of detections.jsonl, without the newline (positions to 0.1 mm, areas to 0.01 cm2,
// time to 1 us).
std::string DetectionsJsonLine(int64_t frame, double time_s, const std::vector<Detection>& detections);

// A text output appended to while the run goes on (kLive: at its final name, one write(2) per
// Append; kAtomic: through a temporary, renamed at Close). Destroyed without Close, a kAtomic
// file leaves nothing; a kLive one keeps what was written.
class TextOutput {
 public:
  static Result<std::unique_ptr<TextOutput>> Open(const std::filesystem::path& path, OutputMode mode);
  ~TextOutput();
  TextOutput(const TextOutput&) = delete;
  TextOutput& operator=(const TextOutput&) = delete;
  // `text` is whole lines; in kLive mode they reach the file in one write, or (the write failed
  // part way) the file is cut back to what it held before.
  Status Append(std::string_view text);
  // kLive: the bytes in the file; TakeBack cuts it to `size` (an earlier size()).
  uint64_t size() const { return size_; }
  Status TakeBack(uint64_t size);
  Status Finish();  // kAtomic: flushed, not renamed (AtomicFileWriter::Finish); kLive: nothing
  Status Close();
  const std::filesystem::path& path() const { return path_; }

 private:
  TextOutput(std::filesystem::path path, int fd) : path_(std::move(path)), fd_(fd) {}
  std::filesystem::path path_;
  std::unique_ptr<AtomicFileWriter> atomic_;
  int fd_ = -1;  // kLive
  uint64_t size_ = 0;
};

struct OutputFilesOptions {
  OutputMode mode = OutputMode::kLive;
  bool track = true;              // tracks.jsonl, tracks_mot.csv (and events.jsonl with zones)
  bool events = false;            // events.jsonl (the site has zones or counting lines)
  bool occupancy_video = true;    // occupancy.mp4
  bool occupancy_pngs = false;    // occupancy/NNNNNN.png
  bool mosaic_video = false;      // mosaic.mp4 from FrameRecord::mosaic
  ImageSize mosaic_size;          // with mosaic_video
  bool change_pngs = false;       // changes/<camera>/NNNNNN.png from FrameRecord::change_pictures
  VideoWriterOptions video;       // encoder choice; `fragmented` follows the mode
  bool wall_clock_times = true;   // "t_unix" (FrameRecord::t_unix) on every JSON line
};

class OutputFiles : public FrameSink {
 public:
  explicit OutputFiles(OutputFilesOptions options) : options_(std::move(options)) {}
  ~OutputFiles() override;
  Status Open(const SinkStart& start) override;
  Status Consume(const FrameRecord& record, const RunStats& stats) override;
  // Closes every file (kAtomic: commits them); after a failure the kAtomic files are dropped.
  Status Close(const RunStats& stats) override;
  // Drops what is not committed (kAtomic: the temporaries) instead of closing: a failed run.
  void Abandon();
  // The files written so far (after Close: all of them).
  const std::vector<std::filesystem::path>& written() const { return written_; }

 private:
  OutputFilesOptions options_;
  std::filesystem::path out_;
  std::vector<std::string> camera_ids_;
  int map_scale_ = 1;
  std::unique_ptr<TextOutput> detections_, tracks_, mot_, events_;
  std::unique_ptr<VideoWriter> occupancy_video_, mosaic_video_;
  std::vector<std::filesystem::path> written_;
  std::string text_;  // a frame set's lines, buffer kept
  bool failed_ = false;
};

}  // namespace occmap
