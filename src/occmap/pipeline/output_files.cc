#include "occmap/pipeline/output_files.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#include <fmt/core.h>

#include "occmap/track/track_output.h"
#include "occmap/util/image_io.h"

namespace occmap {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// The map's grey picture (OccupancyMap::ToGrayImage) enlarged by `scale`, in RGB for video.
Image<Rgb8> OccupancyPicture(const Image<uint8_t>& gray, int scale) {
  Image<Rgb8> out(gray.width() * scale, gray.height() * scale);
  for (int y = 0; y < out.height(); ++y) {
    const uint8_t* src = gray.row(y / scale);
    Rgb8* dst = out.row(y);
    for (int x = 0; x < out.width(); ++x) {
      const uint8_t v = src[x / scale];
      dst[x] = {v, v, v};
    }
  }
  return out;
}

}  // namespace

const char* ToString(OutputMode mode) { return mode == OutputMode::kLive ? "live" : "atomic"; }

std::string WithTUnix(std::string_view line, double t_unix) {
  if (line.size() < 2 || line.front() != '{') return std::string(line);
  const std::string stamp = fmt::format("{{\"t_unix\":{:.6f}", t_unix);
  return stamp + (line[1] == '}' ? "" : ",") + std::string(line.substr(1));
}

void MakeJsonLines(FrameRecord& r, bool wall_clock_times) {
  auto stamped = [&](std::string line) { return wall_clock_times ? WithTUnix(line, r.t_unix) : line; };
  r.tracks_line = stamped(TracksJsonLine(r.frame, r.time_s, r.tracks));
  r.event_lines.clear();
  for (const ZoneEvent& e : r.zones.events) r.event_lines.push_back(stamped(ZoneEventJsonLine(e)));
  for (const LineEvent& e : r.lines.events) r.event_lines.push_back(stamped(LineEventJsonLine(e)));
}

std::string DetectionsJsonLine(int64_t frame, double time_s, const std::vector<Detection>& detections) {
  json line = {{"frame", frame}, {"time_s", std::round(time_s * 1e6) / 1e6}, {"blobs", json::array()}};
  for (const Detection& b : detections) {
    line["blobs"].push_back({{"x_m", std::round(b.x_m * 1e4) / 1e4},
                             {"y_m", std::round(b.y_m * 1e4) / 1e4},
                             {"area_m2", std::round(b.area_m2 * 1e5) / 1e5},
                             {"cells", b.cells}});
  }
  return line.dump();
}

Result<std::unique_ptr<TextOutput>> TextOutput::Open(const fs::path& path, OutputMode mode) {
  if (mode == OutputMode::kAtomic) {
    OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<AtomicFileWriter> atomic, AtomicFileWriter::Open(path));
    std::unique_ptr<TextOutput> out(new TextOutput(path, -1));
    out->atomic_ = std::move(atomic);
    return out;
  }
  // O_APPEND: every write lands at the end, whole, whatever else holds the file.
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return IoError(fmt::format("'{}': cannot create: {}", path.string(), std::strerror(errno)));
  return std::unique_ptr<TextOutput>(new TextOutput(path, fd));
}

TextOutput::~TextOutput() {
  if (fd_ >= 0) ::close(fd_);
}

Status TextOutput::Append(std::string_view text) {
  if (atomic_) return atomic_->Append(text);
  if (fd_ < 0) return Internal(fmt::format("'{}': append after close", path_.string()));
  // One write for the whole text; a short write (a full disk gives one before ENOSPC) is
  // continued, and a failure cuts the file back: a reader never sees a partial line.
  size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd_, text.data() + written, text.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      const Status cut = TakeBack(size_);
      return IoError(fmt::format("'{}': write failed: {}{}", path_.string(), std::strerror(err),
                                 cut.ok() ? "" : fmt::format(" (and {})", cut.message())));
    }
    written += static_cast<size_t>(n);
  }
  size_ += text.size();
  return Status::Ok();
}

Status TextOutput::TakeBack(uint64_t size) {
  if (atomic_ || fd_ < 0) return Status::Ok();
  if (::ftruncate(fd_, static_cast<off_t>(size)) != 0) {
    return IoError(fmt::format("'{}': cannot cut back to {} bytes: {}", path_.string(), size, std::strerror(errno)));
  }
  size_ = size;
  return Status::Ok();
}

Status TextOutput::Finish() { return atomic_ ? atomic_->Finish() : Status::Ok(); }

Status TextOutput::Close() {
  if (atomic_) {
    Status s = atomic_->Commit();
    atomic_.reset();
    return s;
  }
  if (fd_ < 0) return Status::Ok();
  const int fd = fd_;
  fd_ = -1;
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    return IoError(fmt::format("'{}': flush failed: {}", path_.string(), std::strerror(errno)));
  }
  return Status::Ok();
}

OutputFiles::~OutputFiles() = default;

Status OutputFiles::Open(const SinkStart& start) {
  out_ = start.out_dir;
  camera_ids_ = start.camera_ids;
  const FloorGrid& grid = start.site->grid;
  map_scale_ = std::max(1, 400 / std::max(grid.cells_x, grid.cells_y));
  const OutputMode mode = options_.mode;
  OCCMAP_ASSIGN_OR_RETURN(detections_, TextOutput::Open(out_ / "detections.jsonl", mode));
  if (options_.track) {
    OCCMAP_ASSIGN_OR_RETURN(tracks_, TextOutput::Open(out_ / "tracks.jsonl", mode));
    OCCMAP_ASSIGN_OR_RETURN(mot_, TextOutput::Open(out_ / "tracks_mot.csv", mode));
    if (options_.events) {
      OCCMAP_ASSIGN_OR_RETURN(events_, TextOutput::Open(out_ / "events.jsonl", mode));
    }
  }
  VideoWriterOptions video = options_.video;
  video.fragmented = mode == OutputMode::kLive;
  if (options_.occupancy_video) {
    OCCMAP_ASSIGN_OR_RETURN(occupancy_video_, VideoWriter::Open(out_ / "occupancy.mp4",
                                                                {grid.cells_x * map_scale_, grid.cells_y * map_scale_},
                                                                start.fps, video));
  }
  if (options_.mosaic_video) {
    OCCMAP_ASSIGN_OR_RETURN(mosaic_video_, VideoWriter::Open(out_ / "mosaic.mp4", options_.mosaic_size, start.fps, video));
  }
  if (options_.occupancy_pngs) OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out_ / "occupancy"));
  if (options_.change_pngs) {
    for (const std::string& id : camera_ids_) OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out_ / "changes" / id));
  }
  return Status::Ok();
}

Status OutputFiles::Consume(const FrameRecord& r, const RunStats& stats) {
  (void)stats;
  // A failure (a full disk) takes the frame set back from every line file: they end at the same
  // frame set, each with a whole line, and the run stops with the error.
  const std::unique_ptr<TextOutput>* line_files[] = {&detections_, &tracks_, &mot_, &events_};
  uint64_t sizes[4] = {};
  for (size_t k = 0; k < 4; ++k) sizes[k] = *line_files[k] ? (*line_files[k])->size() : 0;
  auto fail = [&](Status s) {
    failed_ = true;
    if (options_.mode == OutputMode::kAtomic) return s;
    std::string cut;
    for (size_t k = 0; k < 4; ++k) {
      if (!*line_files[k]) continue;
      if (const Status t = (*line_files[k])->TakeBack(sizes[k]); !t.ok()) cut += "; " + t.message();
    }
    return IoError(fmt::format("{}: frame {} not written; the line files end at the frame set before it, whole{}",
                               s.message(), r.frame, cut));
  };
  text_ = DetectionsJsonLine(r.frame, r.time_s, r.detections);
  if (options_.wall_clock_times) text_ = WithTUnix(text_, r.t_unix);
  text_ += '\n';
  if (Status s = detections_->Append(text_); !s.ok()) return fail(s);
  if (tracks_) {
    text_ = r.tracks_line;
    text_ += '\n';
    if (Status s = tracks_->Append(text_); !s.ok()) return fail(s);
    if (Status s = mot_->Append(MotGroundPlaneRows(r.frame, r.tracks)); !s.ok()) return fail(s);
  }
  if (events_ && !r.event_lines.empty()) {
    text_.clear();
    for (const std::string& line : r.event_lines) {
      text_ += line;
      text_ += '\n';
    }
    if (Status s = events_->Append(text_); !s.ok()) return fail(s);
  }
  if (occupancy_video_ || options_.occupancy_pngs) {
    const Image<uint8_t> gray = r.map.ToGrayImage();
    if (occupancy_video_) {
      if (Status s = occupancy_video_->Write(OccupancyPicture(gray, map_scale_).view()); !s.ok()) return fail(s);
    }
    if (options_.occupancy_pngs) {
      if (Status s = WritePng(out_ / "occupancy" / fmt::format("{:06d}.png", r.frame), gray.view()); !s.ok()) return fail(s);
    }
  }
  if (mosaic_video_) {
    if (Status s = mosaic_video_->Write(r.mosaic.view()); !s.ok()) return fail(s);
  }
  for (size_t n = 0; n < r.change_pictures.size() && n < camera_ids_.size(); ++n) {
    if (r.change_pictures[n].empty()) continue;
    const fs::path p = out_ / "changes" / camera_ids_[n] / fmt::format("{:06d}.png", r.frame);
    if (Status s = WritePng(p, r.change_pictures[n].view()); !s.ok()) return fail(s);
  }
  return Status::Ok();
}

void OutputFiles::Abandon() {
  // kAtomic: the temporaries go with their writers; kLive: the files keep what was written.
  detections_.reset();
  tracks_.reset();
  mot_.reset();
  events_.reset();
  occupancy_video_.reset();
  mosaic_video_.reset();
}

Status OutputFiles::Close(const RunStats& stats) {
  (void)stats;
  if (failed_ && options_.mode == OutputMode::kAtomic) {
    Abandon();
    return Status::Ok();
  }
  Status first;
  auto keep = [&](Status s) {
    if (first.ok() && !s.ok()) first = std::move(s);
  };
  if (options_.mode == OutputMode::kAtomic) {  // all or nothing: every file finished before any is renamed
    for (std::unique_ptr<TextOutput>* f : {&detections_, &tracks_, &mot_, &events_}) {
      if (*f) keep((*f)->Finish());
    }
    for (std::unique_ptr<VideoWriter>* v : {&occupancy_video_, &mosaic_video_}) {
      if (*v && first.ok()) keep((*v)->Finish());
    }
    if (!first.ok()) {
      Abandon();
      return IoError(fmt::format("{} (atomic outputs: none written)", first.message()));
    }
  }
  // The order of the outputs in the summary's list.
  if (detections_) {
    keep(detections_->Close());
    written_.push_back(detections_->path());
    detections_.reset();
  }
  if (occupancy_video_) {
    keep(occupancy_video_->Close());
    written_.push_back(out_ / "occupancy.mp4");
    occupancy_video_.reset();
  }
  if (mosaic_video_) {
    keep(mosaic_video_->Close());
    written_.push_back(out_ / "mosaic.mp4");
    mosaic_video_.reset();
  }
  for (std::unique_ptr<TextOutput>* f : {&tracks_, &mot_, &events_}) {
    if (!*f) continue;
    keep((*f)->Close());
    written_.push_back((*f)->path());
    f->reset();
  }
  return first;
}

}  // namespace occmap
