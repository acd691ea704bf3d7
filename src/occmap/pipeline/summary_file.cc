#include "occmap/pipeline/summary_file.h"

#include <cmath>
#include <string>

#include "occmap/util/file_util.h"

namespace occmap {
namespace {

using nlohmann::json;

// summary.json's tracking.lines: per counting line its name and crossings in and out so far.
json LinesJson(const std::vector<LineOptions>& lines, const std::vector<LineCounts>& counts) {
  json out = json::array();
  for (size_t l = 0; l < lines.size(); ++l) {
    const LineCounts c = l < counts.size() ? counts[l] : LineCounts{};
    out.push_back({{"name", lines[l].name}, {"in", c.in}, {"out", c.out}});
  }
  return out;
}

json LatencyJson(const LatencyFigures& f) {
  auto ms = [](double v) { return std::round(v * 1e3) / 1e3; };
  return {{"frame_sets", f.count}, {"p50", ms(f.p50_ms)}, {"p95", ms(f.p95_ms)}, {"p99", ms(f.p99_ms)},
          {"max", ms(f.max_ms)}};
}

}  // namespace

json BackgroundCacheJson(const BackgroundCacheFigures& f) {
  return {{"entry", f.entry},
          {"refreshes", f.refreshes},
          {"failures", f.failures},
          {"last_refresh_frame", f.last_refresh_frame ? json(*f.last_refresh_frame) : json(nullptr)},
          {"last_error", f.last_error.empty() ? json(nullptr) : json(f.last_error)}};
}

SummaryFile::SummaryFile(std::filesystem::path path, const Site& site, const RunOptions& options,
                         const FusionPlan& plan, const RunSummary& summary, const std::vector<CameraState>& cams,
                         int num_threads)
    : path_(std::move(path)), site_(site), track_(options.track) {
  json& s = static_;
  s["site"] = site.name;
  s["start_frame"] = options.start_frame;
  s["output_mode"] = ToString(options.output_mode);
  if (options.track) {
    s["tracking"] = {{"algorithm", std::string(ToString(site.tracking.algorithm))},
                     {"tracks", 0},
                     {"zones", site.tracking.zones.size()},
                     {"zone_events", 0},
                     {"lines", LinesJson(site.tracking.lines, {})}};
  }
  if (plan.adaptive) {
    const BackgroundOptions& bo = site.backgrounds;
    s["backgrounds"] = {{"adaptive", true}, {"learning", ToString(bo.learning)}, {"learn_s", bo.learn_s},
                        {"learn_samples", bo.learn_samples}, {"refresh_cache_s", bo.refresh_cache_s}, {"adapt_s", bo.adapt_s}, {"relight_s", bo.relight_s},
                        {"absorb_s", bo.absorb_s}, {"person_height_m", bo.person_height_m},
                        {"chroma", plan.chroma}, {"chroma_threshold", bo.chroma_threshold}, {"white_balance", bo.white_balance},
                        {"grow", {{"steps_px", bo.grow_steps_px}, {"threshold_share", bo.grow_threshold_share},
                                  {"seed_share", bo.grow_seed_share}}},
                        {"shadows", {{"enabled", bo.shadows.enabled}, {"min_ratio", bo.shadows.min_ratio},
                                     {"max_ratio", bo.shadows.max_ratio}, {"max_channel_spread", bo.shadows.max_channel_spread},
                                     {"texture_radius_px", bo.shadows.texture_radius_px},
                                     {"floor_check", bo.shadows.floor_check}, {"soft", bo.shadows.soft},
                                     {"soft_min_ratio", bo.shadows.soft_min_ratio},
                                     {"soft_max_ratio", bo.shadows.soft_max_ratio}}},
                        {"consensus", {{"pixels_checked", summary.consensus_pixels_checked},
                                       {"pixels_swapped", summary.consensus_pixels_swapped},
                                       {"pixels_settled", summary.consensus_pixels_settled}}},
                        {"settle", {{"enabled", bo.settle}, {"frame_sets", summary.settle_frame_sets},
                                    {"seconds", summary.settle_s}}}};
  }
  s["settings"] = {{"threshold", site.detection.threshold},
                   {"colour", site.detection.colour},
                   {"tolerance_px", site.detection.tolerance_px},
                   {"block_px", {site.detection.block_width_px, site.detection.block_height_px}},
                   {"block_rule", site.detection.block_rule == BlockRule::kHalf ? "half" : "any"},
                   {"fusion", ToString(site.fusion.method)},
                   {"fusion_path", plan.Describe(site)},
                   {"max_free_views", site.fusion.max_free_views},
                   {"sync", options.sync == FrameSync::kIndex ? "index" : "timestamp"},
                   {"sync_tolerance_s", options.sync_tolerance_s},
                   {"on_camera_failure", options.on_camera_failure == OnCameraFailure::kStop ? "stop" : "continue"},
                   {"blobs", {{"group_radius_m", site.objects.group_radius_m}, {"min_area_m2", site.objects.min_area_m2},
                              {"split", site.objects.split}, {"remove_ghosts", site.objects.remove_ghosts},
                              {"occluder_height_m", site.objects.occluder_height_m}}},
                   {"threads", num_threads},
                   {"grid", {{"origin_m", {site.grid.origin_x_m, site.grid.origin_y_m}},
                             {"cells", {site.grid.cells_x, site.grid.cells_y}},
                             {"cell_size_m", site.grid.cell_size_m}}}};
  s["tables"] = {{"cache", summary.lut_cache}, {"seconds", summary.lut_seconds}};
  for (const auto& c : cams) {
    static_cameras_.push_back({{"id", c.info.id}, {"source", c.info.source}, {"background", c.info.background}});
  }
}

Status SummaryFile::WriteRunning(const RunStats& stats) const {
  json j = static_;
  j["running"] = true;
  j["frames"] = stats.frames;
  j["seconds"] = stats.elapsed_s;
  j["frames_per_second"] = stats.frames_per_second;
  j["latency_ms"] = LatencyJson(stats.latency);
  if (track_) {
    j["tracking"]["tracks"] = stats.tracks;
    j["tracking"]["zone_events"] = stats.zone_events;
    j["tracking"]["lines"] = LinesJson(site_.tracking.lines, stats.lines);
  }
  json cj = json::array();
  for (size_t n = 0; n < static_cameras_.size(); ++n) {
    json e = static_cameras_[n];
    e["active"] = stats.cameras[n].active;
    e["connected"] = stats.cameras[n].connected;
    e["frames"] = stats.cameras[n].frames;
    e["dropped_frames"] = stats.cameras[n].dropped;
    e["reconnects"] = stats.cameras[n].reconnects;
    if (const auto& cache = stats.cameras[n].background_cache) e["background_cache"] = BackgroundCacheJson(*cache);
    cj.push_back(std::move(e));
  }
  j["cameras"] = std::move(cj);
  return WriteFileAtomic(path_, j.dump(2) + "\n");
}

Status SummaryFile::WriteFinal(const RunSummary& summary, const RunStats& stats, const std::vector<CameraState>& cams,
                               int64_t last_frame_index) const {
  json j = static_;
  j["running"] = false;
  j["frames"] = summary.frames;
  j["seconds"] = summary.seconds;
  j["frames_per_second"] = summary.frames_per_second;
  j["startup_seconds"] = summary.startup_s;
  j["steady_state"] = {{"frames", summary.steady_frames}, {"seconds", summary.steady_seconds},
                       {"frames_per_second", summary.steady_fps}};
  j["stage_seconds"] = {{"decode", summary.decode_s}, {"detect", summary.detect_s}, {"fuse", summary.fuse_s},
                        {"blobs", summary.blobs_s}, {"track", summary.track_s}, {"output", summary.output_s},
                        {"background", summary.background_s}, {"people", summary.people_s},
                        {"occluders", summary.occluders_s}, {"tables", summary.lut_seconds}};
  if (track_) {
    j["tracking"]["tracks"] = summary.tracks;
    j["tracking"]["zone_events"] = summary.zone_events;
    j["tracking"]["lines"] = LinesJson(site_.tracking.lines, stats.lines);
  }
  j["stop_reason"] = summary.stop_reason;
  j["latency_ms"] = LatencyJson(stats.latency);
  json cj = json::array();
  for (size_t n = 0; n < summary.cameras.size(); ++n) {
    const CameraRunInfo& c = summary.cameras[n];
    json e = {{"id", c.id}, {"source", c.source}, {"background", c.background}};
    if (const BackgroundModel* m = cams[n].model.get(); m != nullptr) {
      const BackgroundStats& st = m->stats();
      e["background_model"] = {
          {"updated_fraction", st.pixels > 0 ? static_cast<double>(st.pixels_updated) / static_cast<double>(st.pixels) : 0.0},
          {"mean_age_s", m->MeanAgeS(last_frame_index)},
          {"absorbed_pixel_events", st.pixels_absorbed},
          {"last_frame", {{"gain", st.transfer.gain}, {"offset", st.transfer.offset},
                          {"changed_fraction", st.changed_fraction}, {"shadow_fraction", st.shadow_fraction}}},
          {"shadow_look", {{"ratio", m->shadow_look().ratio}, {"pattern_rgb", m->shadow_look().pattern},
                           {"mass", m->shadow_look().mass}, {"peak_share", m->shadow_look().peak_share}}}};
      if (m->colour_transfer().fitted) {
        e["background_model"]["last_frame"]["rgb_gain"] = m->colour_transfer().gain;
        e["background_model"]["last_frame"]["rgb_offset"] = m->colour_transfer().offset;
      }
    }
    if (c.ended_at_frame) e["ended_at_frame"] = *c.ended_at_frame;
    if (!c.end_reason.empty()) e["end_reason"] = c.end_reason;
    if (c.left_out) e["left_out"] = *c.left_out;
    if (c.late_messages) e["late_messages"] = *c.late_messages;
    if (c.duplicate_messages) e["duplicate_messages"] = *c.duplicate_messages;
    if (c.refused_messages) e["refused_messages"] = *c.refused_messages;
    if (c.background_cache) e["background_cache"] = BackgroundCacheJson(*c.background_cache);
    e["frames"] = stats.cameras[n].frames;
    e["dropped_frames"] = stats.cameras[n].dropped;
    e["reconnects"] = stats.cameras[n].reconnects;
    cj.push_back(e);
  }
  j["cameras"] = cj;
  j["blobs"] = {{"total", summary.blobs_total},
                {"max_per_frame", summary.blobs_max_per_frame},
                {"mean_per_frame", summary.frames > 0 ? static_cast<double>(summary.blobs_total) / static_cast<double>(summary.frames) : 0.0}};
  j["outputs"] = summary.outputs;
  return WriteFileAtomic(path_, j.dump(2) + "\n");
}

}  // namespace occmap
