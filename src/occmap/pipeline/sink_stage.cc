#include "occmap/pipeline/sink_stage.h"

#include <algorithm>

#include "occmap/pipeline/output_files.h"

namespace occmap {
namespace {

double Since(SinkStage::Clock::time_point t0) {
  return std::chrono::duration<double>(SinkStage::Clock::now() - t0).count();
}

LatencyFigures Figures(const LatencyHistogram& h) {
  LatencyFigures f;
  f.count = h.count();
  f.p50_ms = 1e3 * h.Percentile(0.50);
  f.p95_ms = 1e3 * h.Percentile(0.95);
  f.p99_ms = 1e3 * h.Percentile(0.99);
  f.max_ms = 1e3 * h.max_s();
  f.sum_ms = 1e3 * h.sum_s();
  return f;
}

}  // namespace

SinkStage::SinkStage(std::vector<std::shared_ptr<FrameSink>> sinks, std::vector<std::string> camera_ids,
                     const RunOptions& options, const SummaryFile* summary_file, Clock::time_point t_start,
                     RunningFigures running_figures)
    : sinks_(std::move(sinks)),
      options_(options),
      summary_file_(summary_file),
      t_start_(t_start),
      running_figures_(std::move(running_figures)) {
  stats_.cameras.resize(camera_ids.size());
  for (size_t n = 0; n < camera_ids.size(); ++n) stats_.cameras[n].id = std::move(camera_ids[n]);
}

SinkStage::~SinkStage() { (void)Close(stats_.stop_reason); }

Status SinkStage::Open(const SinkStart& start) {
  for (const auto& sink : sinks_) {
    OCCMAP_RETURN_IF_ERROR(sink->Open(start));
    ++open_;
  }
  return Status::Ok();
}

Status SinkStage::Consume(FrameRecord& r) {
  const auto t0 = Clock::now();
  ++stats_.frames;
  stats_.elapsed_s = Since(t_start_);
  for (size_t n = 0; n < stats_.cameras.size(); ++n) stats_.cameras[n].frames += r.active[n] ? 1 : 0;
  if (running_figures_) running_figures_(r, stats_);
  stats_.stages.output += write_s_;
  const int64_t max_before = max_track_id_;
  for (const Track& t : r.tracks) {
    if (t.id > max_before) ++stats_.tracks;
    max_track_id_ = std::max(max_track_id_, t.id);
  }
  stats_.zone_events += static_cast<int64_t>(r.zones.events.size());
  if (!r.lines.counts.empty()) stats_.lines = r.lines.counts;
  blobs_total_ += static_cast<int64_t>(r.detections.size());
  blobs_max_ = std::max(blobs_max_, static_cast<int64_t>(r.detections.size()));
  if (stats_.frames == 1) t_first_written_ = t0;
  stats_.frames_per_second =
      stats_.frames >= 2
          ? static_cast<double>(stats_.frames - 1) / std::chrono::duration<double>(t0 - t_first_written_).count()
          : 0;
  MakeJsonLines(r, options_.wall_clock_times);
  for (const auto& sink : sinks_) OCCMAP_RETURN_IF_ERROR(sink->Consume(r, stats_));
  latency_.Add(std::chrono::duration<double>(Clock::now() - r.arrival).count());
  stats_.latency = Figures(latency_);
  // The running summary (live outputs only: atomic ones appear at the end, all at once).
  if (summary_file_ != nullptr && options_.output_mode == OutputMode::kLive && options_.summary_every_s > 0 &&
      (stats_.frames == 1 || Since(t_summary_written_) >= options_.summary_every_s)) {
    OCCMAP_RETURN_IF_ERROR(summary_file_->WriteRunning(stats_));
    t_summary_written_ = Clock::now();
  }
  write_s_ += Since(t0);
  return Status::Ok();
}

OutputFilesOptions RunFileOptions(const Site& site, const RunOptions& options, ImageSize mosaic_size) {
  OutputFilesOptions file_options;
  file_options.mode = options.output_mode;
  file_options.track = options.track;
  file_options.events = options.track && (!site.tracking.zones.empty() || !site.tracking.lines.empty());
  file_options.occupancy_video = options.occupancy_video;
  file_options.occupancy_pngs = options.occupancy_pngs;
  file_options.mosaic_video = options.mosaic_video;
  file_options.mosaic_size = mosaic_size;
  file_options.change_pngs = options.change_pngs;
  file_options.wall_clock_times = options.wall_clock_times;
  return file_options;
}

std::vector<std::shared_ptr<FrameSink>> RunSinks(std::shared_ptr<FrameSink> files, const RunOptions& options) {
  std::vector<std::shared_ptr<FrameSink>> sinks = {std::move(files)};
  for (const auto& sink : options.sinks) {
    if (sink) sinks.push_back(sink);
  }
  return sinks;
}

SinkStart RunSinkStart(const Site& site, const GroundLut& lut, const RunOptions& options, double fps,
                       const std::vector<std::string>& camera_ids) {
  SinkStart start;
  start.site = &site;
  start.lut = &lut;
  start.out_dir = options.out_dir;
  start.fps = fps;
  start.track = options.track;
  start.wall_clock_times = options.wall_clock_times;
  start.camera_ids = camera_ids;
  return start;
}

Status SinkStage::Close(const std::string& stop_reason) {
  Status first;
  if (closed_) return first;
  closed_ = true;
  stats_.stop_reason = stop_reason;
  stats_.elapsed_s = Since(t_start_);
  for (size_t k = 0; k < open_; ++k) {
    Status s = sinks_[k]->Close(stats_);
    if (first.ok() && !s.ok()) first = std::move(s);
  }
  return first;
}

}  // namespace occmap
