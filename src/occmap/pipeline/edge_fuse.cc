#include "occmap/pipeline/edge_fuse.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <deque>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <thread>

#include "occmap/pipeline/camera_changes.h"
#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/detect_track_stage.h"
#include "occmap/pipeline/edge_align.h"
#include "occmap/pipeline/edge_message.h"
#include "occmap/pipeline/frame_reader.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/fusion_stage.h"
#include "occmap/pipeline/mqtt_link.h"
#include "occmap/pipeline/protection_message.h"
#include "occmap/pipeline/settle_backgrounds.h"
#include "occmap/pipeline/sink_stage.h"
#include "occmap/pipeline/summary_file.h"
#include "occmap/site/site_lut.h"
#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"
#include "occmap/util/thread_pool.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
double UnixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string Prefix(const Site& site, const std::string& given) {
  return given.empty() ? "occmap/" + TopicSlug(site.name) : given;
}

// The fuse's progress message (docs/formats.md): {"schema":1,"frame":F,"t_unix":T}, F the last
// frame set fused (frame index), T when it was said (wall clock).
struct FuseProgress {
  int64_t frame = 0;
  double t_unix = 0;
};

std::string EncodeProgress(const FuseProgress& p) {
  return nlohmann::ordered_json{{"schema", 1}, {"frame", p.frame}, {"t_unix", std::round(p.t_unix * 1000) / 1000}}.dump();
}

// Empty (cleared), another schema or a malformed payload: none.
std::optional<FuseProgress> DecodeProgress(const std::string& payload) {
  const nlohmann::json j = nlohmann::json::parse(payload, nullptr, /*allow_exceptions=*/false);
  auto number = [&](const char* key) { return j.is_object() && j.contains(key) && j[key].is_number(); };
  if (!number("schema") || j["schema"] != 1 || !number("frame") || !j["frame"].is_number_integer() || !number("t_unix")) {
    return std::nullopt;
  }
  return FuseProgress{j["frame"].get<int64_t>(), j["t_unix"].get<double>()};
}

// An edge's messages over files past the fuse's last progress, to send again when the fuse is
// back after the broker went away: a broker restarted without persistence loses what it held
// and what the edges sent before the fuse subscribed again (whole frame sets lost under load).
// Bounded: beyond kMaxBytes the oldest go (a fuse far behind), and the fuse may miss those.
class Unconfirmed {
 public:
  static constexpr size_t kMaxBytes = size_t{64} << 20;
  void Add(int64_t frame, const std::string& topic, const std::string& bytes) {
    entries_.push_back({frame, topic, bytes});
    bytes_ += bytes.size();
    while (bytes_ > kMaxBytes) Pop();
  }
  // The fuse has fused frame set `frame`: what came before it is no longer needed.
  void Fused(int64_t frame) {
    fused_ = std::max(fused_, frame);
    while (!entries_.empty() && entries_.front().frame <= fused_) Pop();
  }
  int64_t fused() const { return fused_; }
  // Publishes again every message past the fuse's progress; the count.
  Result<int64_t> SendAgain(MqttLink& link) {
    int64_t n = 0;
    for (const Entry& e : entries_) {
      if (e.frame <= fused_) continue;
      OCCMAP_RETURN_IF_ERROR(link.Publish(e.topic, e.bytes));
      ++n;
    }
    return n;
  }

 private:
  struct Entry {
    int64_t frame;
    std::string topic, bytes;
  };
  void Pop() {
    bytes_ -= entries_.front().bytes.size();
    entries_.pop_front();
  }
  std::deque<Entry> entries_;
  size_t bytes_ = 0;
  int64_t fused_ = std::numeric_limits<int64_t>::min();
};

// Adaptive backgrounds at an edge (edge_fuse.h): the shadows' floor check and teachers over
// this edge's cameras (the tables' other cameras abstain), and each frame's update with the
// fuse's latest protection drawn into this edge's cameras, or, without one, with every changed
// pixel protected as a person.
class EdgeBackgrounds {
 public:
  EdgeBackgrounds(const Site& site, const GroundLut& lut, std::vector<CameraState>& cams, const std::vector<size_t>& index,
                  const CameraChanges& changes, const EdgeOptions& o, bool live)
      : site_(site),
        lut_(lut),
        cams_(cams),
        index_(index),
        changes_(changes),
        o_(o),
        live_(live),
        expect_{EdgeTableKey(site), EdgeSettingsKey(site), site.grid.num_cells()},
        protection_(CameraModels(cams), site.plane_height_m, Options(site)),
        map_(site.grid),
        views_(cams.size()),
        classes_(site.cameras.size()),
        ratios_(site.cameras.size()),
        check_changes_(site.cameras.size()) {
    const BackgroundOptions& bo = site.backgrounds;
    if (bo.shadows.enabled && bo.shadows.floor_check) shadow_check_.emplace(lut);
    if (bo.shadows.enabled && bo.shadows.learn) teachers_.emplace(lut);
  }

  bool shadow_check() const { return shadow_check_.has_value(); }

  // After every active camera's Compute(dilate=false): shadows whose floor this edge's other
  // cameras see lit are changes; then the tolerance, as FusionStage::DetectChanges.
  void CheckShadows(FrameSet& set, std::vector<Image<uint8_t>>& raw, std::vector<std::vector<uint8_t>>& scratch) {
    const int r = site_.detection.tolerance_px;
    std::fill(classes_.begin(), classes_.end(), ImageView<const uint8_t>());
    std::fill(check_changes_.begin(), check_changes_.end(), ImageView<uint8_t>());
    for (size_t k = 0; k < cams_.size(); ++k) {
      if (!set.active[k] || !cams_[k].model) continue;
      classes_[index_[k]] = cams_[k].model->pixel_classes();
      check_changes_[index_[k]] = r > 0 ? raw[k].view() : changes_.Slice(set, k);
    }
    shadow_check_->Apply(classes_, check_changes_);
    if (r == 0) return;
    for (size_t k = 0; k < cams_.size(); ++k) {
      if (set.active[k]) changes_.Widen(k, raw[k].view(), changes_.Slice(set, k), scratch[k]);
    }
  }

  // A message on <prefix>/protection; a refused one is said once per reason.
  void Receive(const MqttReceived& r) {
    auto m = DecodeProtectionMessage(r.payload, expect_, r.topic);
    if (!m.ok()) {
      if (refused_.insert(m.status().message()).second) {
        std::fputs(fmt::format("occmap edge: refused: {}\n", m.status().message()).c_str(), stderr);
      }
      return;
    }
    latest_ = std::move(m).value();
    latest_arrival_ = Clock::now();
    drawn_ = false;
    ++received_;
  }
  int64_t received() const { return received_; }
  int64_t unprotected() const { return unprotected_; }

  // Over files: the protection frame `frame` is updated with has arrived (none is due before
  // the first frame + lag).
  bool Ready(int64_t frame) const {
    const int64_t due = frame - o_.protection_lag_frames;
    return due < o_.run.start_frame || (latest_ && latest_->frame >= due);
  }

  void Update(FrameSet& set, Context& ctx) {
    const bool protect = latest_ && (live_ ? Since(latest_arrival_) <= o_.protection_stale_s
                                           : latest_->frame >= set.frame_index - o_.protection_lag_frames &&
                                                 latest_->frame <= set.frame_index);
    const bool teach = protect && teachers_.has_value();
    if (protect && !drawn_) {
      protection_.Draw(latest_->boxes, latest_->persons_m);
      std::fill(map_.states().begin(), map_.states().end(), CellState::kUnseen);
      MarkOccupied(latest_->occupied, map_);
      drawn_ = true;
    } else if (!protect) {
      for (size_t k = 0; k < cams_.size(); ++k) {
        views_[k] = set.active[k] ? std::as_const(changes_).Slice(std::as_const(set), k) : ImageView<const uint8_t>();
      }
      protection_.ProtectChanges(views_);
      drawn_ = false;
      ++unprotected_;
    }
    if (teach) {
      std::fill(classes_.begin(), classes_.end(), ImageView<const uint8_t>());
      std::fill(ratios_.begin(), ratios_.end(), ImageView<const uint8_t>());
      for (size_t k = 0; k < cams_.size(); ++k) {
        if (!set.active[k] || !cams_[k].model) continue;
        classes_[index_[k]] = cams_[k].model->pixel_classes();
        ratios_[index_[k]] = cams_[k].model->pixel_ratios();
      }
      teachers_->Compute(classes_, ratios_, map_, protection_.person_positions(), ShadowTeachers::kPersonRadiusM);
    }
    ParallelFor(ctx, 0, static_cast<int64_t>(cams_.size()), [&](int64_t b, int64_t e, int) {
      for (int64_t k = b; k < e; ++k) {
        if (!set.active[k] || !cams_[k].model) continue;
        const YuvView frame = FrameYuv(set.frames[k]);
        if (teach) cams_[k].model->LearnShadows(frame, teachers_->image(index_[k]).view());
        cams_[k].model->Update(frame, protection_.image(static_cast<size_t>(k)).view(), set.frame_index);
      }
    });
  }

 private:
  static std::vector<const CameraModel*> CameraModels(const std::vector<CameraState>& cams) {
    std::vector<const CameraModel*> models;
    for (const CameraState& c : cams) models.push_back(c.cam->camera.get());
    return models;
  }
  static ProtectionOptions Options(const Site& site) {
    ProtectionOptions po;
    po.person_height_m = site.backgrounds.person_height_m;
    return po;
  }

  const Site& site_;
  const GroundLut& lut_;
  std::vector<CameraState>& cams_;
  const std::vector<size_t>& index_;
  const CameraChanges& changes_;
  const EdgeOptions& o_;
  const bool live_;
  const ProtectionExpectation expect_;
  BackgroundProtection protection_;  // this edge's cameras
  OccupancyMap map_;                 // the fuse's occupied cells (the shadow teachers read them)
  std::optional<ShadowCheck> shadow_check_;
  std::optional<ShadowTeachers> teachers_;
  std::optional<ProtectionMessage> latest_;
  Clock::time_point latest_arrival_;
  bool drawn_ = false;
  int64_t received_ = 0, unprotected_ = 0;
  std::set<std::string> refused_;
  std::vector<ImageView<const uint8_t>> views_;                        // per edge camera
  std::vector<ImageView<const uint8_t>> classes_, ratios_;             // per site camera
  std::vector<ImageView<uint8_t>> check_changes_;                      // per site camera
};

// An edge of every camera settles its learned backgrounds as `occmap run` does: the same pass,
// its cameras in the site's order (as the run's tables and fusion stage hold them).
Status SettleAtEdge(const Site& site, const RunOptions& options, const FusionPlan& plan, const GroundLut& lut,
                    std::vector<CameraState>& cams, const std::vector<size_t>& index, Context& ctx,
                    EdgeSummary& summary) {
  if (std::none_of(cams.begin(), cams.end(), [](const CameraState& c) { return c.settles; })) return Status::Ok();
  std::vector<CameraState> ordered(cams.size());
  for (size_t k = 0; k < cams.size(); ++k) ordered[index[k]] = std::move(cams[k]);
  const double fps = ordered[0].source->fps().value_or(10.0);
  Result<SettleFigures> settled = SettleLearnedBackgrounds(site, options, plan, lut, ordered, fps, ctx);
  for (size_t k = 0; k < cams.size(); ++k) cams[k] = std::move(ordered[index[k]]);
  if (!settled.ok()) return settled.status();
  summary.settle_frame_sets = settled->frame_sets;
  summary.settle_s = settled->seconds;
  return Status::Ok();
}

}  // namespace

std::string EdgeTopic(const std::string& prefix, const std::string& camera_id) {
  return prefix + "/edge/" + TopicSlug(camera_id);
}

std::string ProtectionTopic(const std::string& prefix) { return prefix + "/protection"; }

std::string ProgressTopic(const std::string& prefix) { return prefix + "/fuse/progress"; }

Result<EdgeSummary> RunEdge(const Site& site, const EdgeOptions& given, Context& ctx) {
  EdgeOptions o = given;  // start_frame moves up to the fuse's progress
  OCCMAP_RETURN_IF_ERROR(o.run.Validate());
  OCCMAP_RETURN_IF_ERROR(site.detection.Validate());
  if (site.backgrounds.adaptive) OCCMAP_RETURN_IF_ERROR(site.backgrounds.Validate());
  if (o.protection_lag_frames < 0) {
    return InvalidInput(fmt::format("--protection-lag: expected >= 0 frames, found {}", o.protection_lag_frames));
  }
  if (!(o.protection_wait_s >= 0)) {
    return InvalidInput(fmt::format("--protection-wait-s: expected >= 0, found {}", o.protection_wait_s));
  }
  if (!(o.protection_stale_s > 0)) {
    return InvalidInput(fmt::format("--protection-stale-s: expected > 0, found {}", o.protection_stale_s));
  }
  if (!(o.follow_fuse_s >= 0)) return InvalidInput(fmt::format("--follow-fuse-s: expected >= 0, found {}", o.follow_fuse_s));
  const auto t_start = Clock::now();
  std::vector<size_t> index;
  for (const std::string& id : o.cameras) {
    auto it = std::find_if(site.cameras.begin(), site.cameras.end(), [&](const SiteCamera& c) { return c.id == id; });
    if (it == site.cameras.end()) {
      std::string ids;
      for (const SiteCamera& c : site.cameras) ids += (ids.empty() ? "" : ", ") + c.id;
      return InvalidInput(fmt::format("--cameras: expected camera ids of site '{}' ({}), found '{}'", site.name, ids, id));
    }
    const size_t n = static_cast<size_t>(it - site.cameras.begin());
    if (std::find(index.begin(), index.end(), n) != index.end()) {
      return InvalidInput(fmt::format("--cameras: camera '{}' given twice", id));
    }
    index.push_back(n);
  }
  if (index.empty()) {
    for (size_t n = 0; n < site.cameras.size(); ++n) index.push_back(n);
  }
  // The fuse process fuses change buffers: the edge computes them as a run with them does.
  const FusionPlan plan = ChooseFusionPath(site, /*needs_change_buffer=*/true);
  const std::string prefix = Prefix(site, o.topic_prefix);
  const std::string client_id = o.client_id.empty() ? fmt::format("occmap-edge-{}-{}", TopicSlug(site.name),
                                                                  TopicSlug(site.cameras[index[0]].id))
                                                     : o.client_id;
  const std::string protection_topic = ProtectionTopic(prefix);
  const std::string progress_topic = ProgressTopic(prefix);
  const bool over_files = std::none_of(index.begin(), index.end(), [&](size_t n) {
    return site.cameras[n].source.kind == FrameSourceSpec::Kind::kStream;
  });
  const bool follow_fuse = over_files && o.follow_fuse_s > 0;
  std::vector<std::string> subscriptions;
  if (plan.adaptive) subscriptions.push_back(protection_topic);
  if (follow_fuse) subscriptions.push_back(progress_topic);
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<MqttLink> link, MqttLink::Start(o.broker, client_id, subscriptions));
  // Over files, a fuse already fusing (its retained progress, sent right after the subscription)
  // is joined at its next frame set: frames before it would only be dropped as late.
  std::vector<MqttReceived> early;  // protections that came meanwhile
  std::optional<FuseProgress> progress;
  if (follow_fuse) {
    const auto t0 = Clock::now();
    while (!link->subscribed() && Since(t0) < 5 && !(o.run.stop != nullptr && o.run.stop->load())) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    const auto t1 = Clock::now();
    while (link->subscribed() && !progress && Since(t1) < 0.3) {
      auto r = link->Pop(std::chrono::milliseconds(20));
      if (!r) continue;
      if (r->topic == progress_topic) {
        progress = DecodeProgress(r->payload);
      } else {
        early.push_back(std::move(*r));
      }
    }
    if (progress && !(std::abs(UnixNow() - progress->t_unix) <= o.follow_fuse_s && progress->frame + 1 > o.run.start_frame)) {
      progress.reset();  // an old one (a fuse killed), or behind --start
    }
  }
  // Settling learned backgrounds replays the window through the fusion (settle_backgrounds.h):
  // an edge of every camera of the site fuses it itself, as the run does; an edge of some of
  // them cannot tell a person who left from one another camera of the site still sees.
  const bool whole_site = index.size() == site.cameras.size();
  RunOptions open_options = o.run;
  open_options.settle_learned_backgrounds = o.run.settle_learned_backgrounds && whole_site;
  OCCMAP_ASSIGN_OR_RETURN(std::vector<CameraState> cams, OpenCameras(site, open_options, plan, ctx, index));
  // Opened (backgrounds learned or reused) from --start as on the first start; then skipped to
  // the fuse's latest progress (it went on while the cameras opened).
  if (progress) {
    for (auto r = link->Pop(std::chrono::milliseconds(0)); r; r = link->Pop(std::chrono::milliseconds(0))) {
      if (r->topic != progress_topic) {
        early.push_back(std::move(*r));
      } else if (auto later = DecodeProgress(r->payload); later && later->frame > progress->frame) {
        progress = later;
      }
    }
    for (size_t k = 0; k < cams.size(); ++k) {
      if (Status s = cams[k].source->SkipTo(progress->frame + 1); !s.ok()) {
        return s.WithContext(fmt::format("camera {}: skipping to the fuse's frame set {}", cams[k].cam->id, progress->frame + 1));
      }
    }
    std::fputs(fmt::format("occmap edge: the fuse has fused frame set {}: starting at frame {}\n", progress->frame,
                           progress->frame + 1)
                   .c_str(),
               stderr);
    o.run.start_frame = progress->frame + 1;
  }
  // Asked before the reader takes the live streams' sources.
  std::vector<double> fps;
  for (const CameraState& c : cams) fps.push_back(c.source->fps().value_or(0.0));
  FrameReader reader(cams, o.run, ctx.num_threads(), RunSourceOptions(plan, ctx.num_threads(), static_cast<int>(cams.size())));
  const CameraChanges changes(site, cams, plan.colour, /*change_pngs=*/false);
  EdgeSummary summary;
  // Adaptive backgrounds: the learned ones checked against each other over this edge's cameras
  // (the tables of the whole site: the checks go through the floor), then kept from the fuse's
  // protections.
  std::optional<CachedLut> lut;
  std::optional<EdgeBackgrounds> backgrounds;
  // The live cameras' cached backgrounds follow their models (camera_inputs.h); a best effort:
  // the cache is a head start for a restart, not an output.
  BackgroundCacheRefresh refresh(site.backgrounds, fps.empty() || fps[0] <= 0 ? 10.0 : fps[0], o.run.warning);
  if (plan.adaptive) {
    OCCMAP_ASSIGN_OR_RETURN(CachedLut cached, LoadOrBuildSiteLut(site, o.run.cache_dir, ctx));
    if (!cached.write_error.empty()) {
      WarnCacheNotWritten(o.run.warning, "table cache", SiteLutPath(site, o.run.cache_dir), cached.write_error);
    }
    lut.emplace(std::move(cached));
    const ConsensusResult r = CheckLearnedBackgrounds(site, lut->lut, cams, index);  // over this edge's cameras
    summary.consensus_pixels_checked = r.pixels_checked;
    summary.consensus_pixels_swapped = r.pixels_swapped;
    OCCMAP_RETURN_IF_ERROR(SettleAtEdge(site, open_options, plan, lut->lut, cams, index, ctx, summary));
  }
  // What a restarted edge did before it can publish (learned again, or reused from the cache).
  std::string backgrounds_said;
  for (const CameraState& c : cams) backgrounds_said += fmt::format("{}{}: {}", backgrounds_said.empty() ? "" : "; ", c.cam->id, c.info.background);
  summary.startup_s = Since(t_start);
  std::fputs(fmt::format("occmap edge: cameras ready after {:.1f} s; backgrounds: {}\n", summary.startup_s, backgrounds_said).c_str(),
             stderr);
  FrameSet set;
  set.frames.resize(cams.size());
  set.active.assign(cams.size(), false);
  std::vector<Image<uint8_t>> raw(cams.size());
  std::vector<std::vector<uint8_t>> scratch(cams.size());
  EdgeMessage m;
  m.table_key = EdgeTableKey(site);
  m.settings_key = EdgeSettingsKey(site);
  std::vector<std::string> topics;
  for (const CameraState& c : cams) topics.push_back(EdgeTopic(prefix, c.cam->id));
  auto stop_requested = [&] { return o.run.stop != nullptr && o.run.stop->load(); };
  // A live frame's time on this host's wall clock: its arrival (the fuse aligns live cameras
  // of many hosts by it).
  bool any_live = false;
  std::vector<bool> live(cams.size());
  for (size_t k = 0; k < cams.size(); ++k) {
    live[k] = cams[k].cam->source.kind == FrameSourceSpec::Kind::kStream;
    any_live = any_live || live[k];
  }
  const double live_epoch_unix =
      UnixNow() - std::chrono::duration<double>(Clock::now() - reader.live_epoch()).count();
  if (plan.adaptive) {
    backgrounds.emplace(site, lut->lut, cams, index, changes, o, any_live);
    // The first protection must not go by unheard.
    for (int k = 0; k < 100 && !link->subscribed() && !stop_requested(); ++k) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  int64_t next_frame = o.run.start_frame;
  bool away = false;
  bool waiting = true;  // for the fuse's protections (files); false after a wait gave up, until one arrives
  int64_t received_when_given_up = 0;
  int64_t connects_seen = link->connects();  // connections to the broker by the last frame's end
  Clock::time_point away_since;
  int64_t lost_while_away = 0;
  // While the broker is away, files wait for it (nothing is lost); live streams go on and the
  // frame sets read meanwhile are not sent (counted).
  auto broker_ready = [&] {
    if (!link->connected() && !away) {
      away = true;
      away_since = Clock::now();
      lost_while_away = 0;
      std::fputs(fmt::format("occmap edge: the broker went away at frame {}\n", next_frame).c_str(), stderr);
    }
    while (!any_live && !link->connected() && !stop_requested()) link->WaitConnected(std::chrono::milliseconds(100));
    if (link->connected() && away) {
      std::fputs(fmt::format("occmap edge: the broker is back after {:.1f} s; {} frame sets not sent\n",
                             Since(away_since), lost_while_away)
                     .c_str(),
                 stderr);
      away = false;
    }
    return link->connected();
  };
  // Over files (following the fuse's progress): after a reconnection, the fuse's word on the new
  // connection (a progress it sent while subscribed, not the broker's retained copy), then what
  // it has not fused sent again (it drops what it has as duplicates).
  Unconfirmed unconfirmed;
  int64_t fuse_heard_on = -1;  // the connection that brought the fuse's last live progress
  int64_t resent_on = link->connects();
  auto take = [&](const MqttReceived& r) {
    if (r.topic == progress_topic) {
      if (auto p = DecodeProgress(r.payload); p && !r.retained) {
        unconfirmed.Fused(p->frame);
        fuse_heard_on = r.connection;
      }
    } else if (backgrounds && r.topic == protection_topic) {
      backgrounds->Receive(r);
    }
  };
  auto resend_after_reconnect = [&]() -> Status {
    const int64_t connection = link->connects();
    if (!follow_fuse || connection == resent_on || !link->connected()) return Status::Ok();
    if (resent_on == 0) {  // the first connection (the broker was not there at the start)
      resent_on = connection;
      return Status::Ok();
    }
    const auto t0 = Clock::now();
    while (fuse_heard_on != connection && link->connects() == connection && Since(t0) < o.follow_fuse_s &&
           !stop_requested()) {
      if (auto r = link->Pop(std::chrono::milliseconds(50))) take(*r);
    }
    if (link->connects() != connection) return Status::Ok();  // gone again: at the next connection
    resent_on = connection;
    if (fuse_heard_on != connection) {
      std::fputs(fmt::format("occmap edge: no progress from the fuse {:.0f} s after the broker came back: nothing sent again\n",
                             o.follow_fuse_s)
                     .c_str(),
                 stderr);
      return Status::Ok();
    }
    OCCMAP_ASSIGN_OR_RETURN(const int64_t n, unconfirmed.SendAgain(*link));
    summary.resent += n;
    std::fputs(fmt::format("occmap edge: the fuse is back at frame set {}: {} messages past it sent again\n",
                           unconfirmed.fused(), n)
                   .c_str(),
               stderr);
    return Status::Ok();
  };
  while (!stop_requested() && reader.Read(set)) {
    next_frame = set.frame_index + 1;
    ++summary.frame_sets;
    if (!broker_ready()) {
      ++summary.lost;
      ++lost_while_away;
      continue;
    }
    OCCMAP_RETURN_IF_ERROR(resend_after_reconnect());
    changes.EnsureBuffer(set);
    const bool check_shadows = backgrounds && backgrounds->shadow_check();
    for (size_t k = 0; k < cams.size(); ++k) {
      if (set.active[k]) changes.Compute(set, k, raw[k], scratch[k], /*dilate=*/!check_shadows);
    }
    if (check_shadows) backgrounds->CheckShadows(set, raw, scratch);
    for (size_t k = 0; k < cams.size(); ++k) {
      if (set.active[k]) changes.Quantise(set, k);
    }
    for (size_t k = 0; k < cams.size(); ++k) {
      if (!set.active[k]) continue;
      const ImageSize size = cams[k].cam->camera->image_size();
      m.kind = EdgeMessageKind::kChanges;
      m.camera = static_cast<uint32_t>(index[k]);
      m.width = static_cast<uint32_t>(size.width);
      m.height = static_cast<uint32_t>(size.height);
      m.frame = set.frame_index;
      m.timestamp_s = live[k] ? live_epoch_unix + set.frames[k].timestamp_s : set.frames[k].timestamp_s;
      m.t_unix = live[k] ? m.timestamp_s : set.t_unix;
      m.fps = fps[k];
      m.block_w = static_cast<uint8_t>(site.detection.block_width_px);
      m.block_h = static_cast<uint8_t>(site.detection.block_height_px);
      const uint8_t* first = set.changes.data() + changes.offset(k);
      m.changes.assign(first, first + static_cast<size_t>(size.width) * size.height);
      const std::string bytes = EncodeEdgeMessage(m);
      OCCMAP_RETURN_IF_ERROR(link->Publish(topics[k], bytes));
      if (follow_fuse) unconfirmed.Add(set.frame_index, topics[k], bytes);
      ++summary.messages;
    }
    if (backgrounds) {
      for (const MqttReceived& r : early) backgrounds->Receive(r);
      early.clear();
    }
    for (auto r = link->Pop(std::chrono::milliseconds(0)); r; r = link->Pop(std::chrono::milliseconds(0))) take(*r);
    if (backgrounds) {  // the fuse's protection: over files, the one due for this frame is waited for
      if (!any_live && waiting && !backgrounds->Ready(set.frame_index)) {
        const auto t0 = Clock::now();
        // A broker that went away since the last frame may have lost the due protection (the
        // fuse waits for this edge's next frame then): a reconnection ends the wait.
        bool reconnected = false;
        while (!backgrounds->Ready(set.frame_index) && !stop_requested() && Since(t0) < o.protection_wait_s) {
          if (auto r = link->Pop(std::chrono::milliseconds(50))) take(*r);
          if ((reconnected = link->connects() != connects_seen && link->connected())) break;
        }
        if (!backgrounds->Ready(set.frame_index) && !stop_requested()) {
          std::fputs((reconnected ? fmt::format("occmap edge: the broker is back; the protection for frame {} lost with "
                                                "it: changed pixels protected until one arrives\n",
                                                set.frame_index)
                                  : fmt::format("occmap edge: no protection from the fuse for frame {} after {:.0f} s: "
                                                "changed pixels protected until one arrives\n",
                                                set.frame_index, o.protection_wait_s))
                         .c_str(),
                     stderr);
          waiting = false;
          received_when_given_up = backgrounds->received();
        }
      }
      if (!waiting && backgrounds->received() > received_when_given_up) waiting = true;
      connects_seen = link->connects();
      backgrounds->Update(set, ctx);
      refresh.After(set.frame_index, cams);
    }
  }
  refresh.Now(next_frame - 1, cams);  // the models as they are at the stop, for the next start
  for (size_t k = 0; k < cams.size(); ++k) {
    if (auto f = refresh.figures(k)) summary.background_cache.emplace_back(cams[k].cam->id, std::move(*f));
  }
  // The end of every source (not on a stop request: a restarted edge goes on where it was).
  if (!stop_requested()) {
    while (!link->connected() && !stop_requested()) link->WaitConnected(std::chrono::milliseconds(100));
    OCCMAP_RETURN_IF_ERROR(resend_after_reconnect());
    for (size_t k = 0; k < cams.size(); ++k) {
      m.kind = EdgeMessageKind::kEnd;
      m.camera = static_cast<uint32_t>(index[k]);
      m.frame = next_frame;
      m.changes.clear();
      OCCMAP_RETURN_IF_ERROR(link->Publish(topics[k], EncodeEdgeMessage(m)));
      ++summary.messages;
    }
  }
  if (!link->WaitPublished(std::chrono::seconds(10))) summary.lost += link->unacked();
  summary.bytes = link->bytes_published();
  summary.reconnects = std::max<int64_t>(0, link->connects() - 1);
  if (backgrounds) {
    summary.protections = backgrounds->received();
    summary.unprotected_updates = backgrounds->unprotected();
  }
  summary.seconds = Since(t_start);
  summary.stop_reason = !reader.stop_reason().empty() ? reader.stop_reason() : stop_requested() ? "stop requested" : "stopped";
  if (!reader.failure().ok()) return reader.failure();
  return summary;
}

Result<RunSummary> RunFuse(const Site& site, const FuseOptions& o, Context& ctx, const ProgressCallback& progress) {
  OCCMAP_RETURN_IF_ERROR(o.run.Validate());
  OCCMAP_RETURN_IF_ERROR(site.detection.Validate());
  OCCMAP_RETURN_IF_ERROR(site.fusion.Validate(static_cast<int>(site.cameras.size())));
  if (!(o.latency_budget_s > 0)) return InvalidInput(fmt::format("--latency-budget-s: expected > 0, found {}", o.latency_budget_s));
  if (!(o.dead_after_s > 0)) return InvalidInput(fmt::format("--dead-after-s: expected > 0, found {}", o.dead_after_s));
  if (!(o.start_wait_s >= 0)) return InvalidInput(fmt::format("--start-wait-s: expected >= 0, found {}", o.start_wait_s));
  const auto t_start = Clock::now();
  auto stop_requested = [&] { return o.run.stop != nullptr && o.run.stop->load(); };
  RunOptions options = o.run;
  // No frames reach the fuse: nothing to draw the mosaic from. The sinks may still have each
  // camera's changes as the edge sent them (sink_frames: the web view's tiles).
  options.mosaic_video = options.mosaic_picture = options.change_pngs = false;
  RunSummary summary;
  const FusionPlan plan = ChooseFusionPath(site, /*needs_change_buffer=*/true);
  summary.fusion_path = plan.Describe(site);
  const size_t n_cams = site.cameras.size();
  const std::string prefix = Prefix(site, o.topic_prefix);
  std::vector<CameraState> cams(n_cams);
  std::vector<ImageSize> sizes;
  for (size_t n = 0; n < n_cams; ++n) {
    cams[n].cam = &site.cameras[n];
    cams[n].is_mask = site.cameras[n].source.kind == FrameSourceSpec::Kind::kMasks;
    cams[n].info.id = site.cameras[n].id;
    cams[n].info.source = "edge: " + EdgeTopic(prefix, site.cameras[n].id);
    cams[n].info.background = "at the edge";
    sizes.push_back(site.cameras[n].camera->image_size());
  }
  const EdgeExpectation expect{EdgeTableKey(site), EdgeSettingsKey(site), sizes};
  // Subscribed first: the edges' messages wait in the link (and, while it is away, at the
  // broker: a persistent session) while the tables are built.
  const std::string client_id = o.client_id.empty() ? "occmap-fuse-" + TopicSlug(prefix) : o.client_id;
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<MqttLink> link,
                          MqttLink::Start(o.broker, client_id, {prefix + "/edge/+"}, /*persistent=*/true));
  const auto t_lut = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(CachedLut cached, LoadOrBuildSiteLut(site, options.cache_dir, ctx));
  if (!cached.write_error.empty()) {
    WarnCacheNotWritten(options.warning, "table cache", SiteLutPath(site, options.cache_dir), cached.write_error);
  }
  summary.lut_cache = ToString(cached.outcome);
  summary.lut_seconds = Since(t_lut);
  const GroundLut& lut = cached.lut;
  // The fusion stage's tables (FastFusion's, the people's columns: 16 s at 64 cameras of 960x540)
  // from the site file, before any message: made on the first one, they held up every frame set
  // queued meanwhile (p99 17.7 s over a 64-camera run). Its frame rate only paces the adaptive
  // backgrounds' ages: the edges keep those backgrounds, the fuse none.
  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<FusionStage> fusion,
                          FusionStage::Create(site, options, plan, lut, cams, /*fps=*/0, ctx));
  while (!link->subscribed() && !stop_requested()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::fputs(fmt::format("occmap fuse: subscribed to {}/edge/+ on mqtt://{}:{}\n", prefix, o.broker.host, o.broker.port).c_str(),
             stderr);
  // A progress left by an earlier fuse that did not end (killed) must not move a starting edge.
  const std::string progress_topic = ProgressTopic(prefix);
  OCCMAP_RETURN_IF_ERROR(link->Publish(progress_topic, "", /*retain=*/true));
  std::map<std::string, size_t> camera_of_topic;
  for (size_t n = 0; n < n_cams; ++n) camera_of_topic[EdgeTopic(prefix, site.cameras[n].id)] = n;

  const bool all_streams = std::all_of(site.cameras.begin(), site.cameras.end(), [](const SiteCamera& c) {
    return c.source.kind == FrameSourceSpec::Kind::kStream;
  });
  AlignOptions align;
  align.sync = o.sync ? *o.sync : all_streams ? FrameSync::kTimestamp : FrameSync::kIndex;
  if (o.sync_tolerance_s > 0) align.tolerance_s = o.sync_tolerance_s;
  align.latency_budget_s = o.latency_budget_s;
  align.dead_after_s = o.dead_after_s;
  align.start_wait_s = o.start_wait_s;
  align.first_frame = options.start_frame;
  FrameSetAligner aligner(n_cams, align, t_start);
  std::set<std::string> refused_topics;
  std::vector<int64_t> refused(n_cams, 0);  // per camera: messages refused (damaged, foreign, broken rows)
  double fps = 0;
  auto refuse = [&](size_t camera, const std::string& topic, const std::string& why) {
    ++refused[camera];
    if (refused_topics.insert(topic).second) std::fputs(fmt::format("occmap fuse: refused: {}\n", why).c_str(), stderr);
  };
  auto receive = [&](const MqttReceived& r) {
    auto topic = camera_of_topic.find(r.topic);
    if (topic == camera_of_topic.end()) return;
    auto m = DecodeEdgeHeader(r.payload, expect, r.topic);
    if (!m.ok()) return refuse(topic->second, r.topic, m.status().message());
    if (m->camera != topic->second) {
      return refuse(topic->second, r.topic,
                    fmt::format("{}: camera index {} on camera {}'s topic", r.topic, m->camera, topic->second));
    }
    if (m->kind == EdgeMessageKind::kEnd) return aligner.End(m->camera, m->frame, r.arrival);
    if (align.sync == FrameSync::kTimestamp && std::isnan(m->timestamp_s)) {
      return refuse(topic->second, r.topic,
                    fmt::format("{}: a frame without a timestamp; align by frame index (--sync index)", r.topic));
    }
    if (fps == 0 && m->fps > 0) {
      fps = m->fps;
      if (o.sync_tolerance_s == 0) aligner.set_tolerance(align.tolerance_s = 0.9 / fps);
    }
    // Kept coded until its frame set is fused, then decoded once, into the set's change buffer:
    // whenever the fuse falls behind, frame sets wait here (64 cameras of 960x540 held 11 GB
    // decoded).
    m->encoded = r.payload;
    aligner.Add(std::move(m).value(), r.arrival);
  };
  // The detect/track stage and the outputs need the frame rate (times of frames without
  // timestamps): from the first message.
  while (aligner.idle() && !aligner.all_ended() && !stop_requested()) {
    if (auto r = link->Pop(std::chrono::milliseconds(50))) receive(*r);
  }
  if (fps == 0) fps = 10;
  std::fputs(fmt::format("occmap fuse: frame sets aligned by {}\n",
                         align.sync == FrameSync::kIndex ? std::string("frame index")
                                                         : fmt::format("timestamp within {:.3f} s", align.tolerance_s))
                 .c_str(),
             stderr);

  OCCMAP_ASSIGN_OR_RETURN(std::unique_ptr<DetectTrackStage> post,
                          DetectTrackStage::Create(site, options, plan, lut, cams, fusion->changes(), fusion->column_lut(), fps));
  const fs::path out = options.out_dir;
  OCCMAP_RETURN_IF_ERROR(EnsureDirectory(out));
  RemoveStaleTemporaries(out, /*recursive=*/true);
  auto files = std::make_shared<OutputFiles>(RunFileOptions(site, options, post->mosaic_size()));
  const std::vector<std::shared_ptr<FrameSink>> sinks = RunSinks(files, options);
  std::vector<std::string> camera_ids;
  for (const auto& c : cams) camera_ids.push_back(c.cam->id);
  const SummaryFile summary_file(out / "summary.json", site, options, plan, summary, cams, ctx.num_threads());
  auto running_figures = [&](const FrameRecord& r, RunStats& stats) {
    const auto now = Clock::now();
    for (size_t n = 0; n < n_cams; ++n) {
      stats.cameras[n].active = !aligner.ended(n);
      stats.cameras[n].connected = aligner.alive(n, now);
      // The fuse's drops are messages: late, duplicate or refused (summary.json has them apart).
      stats.cameras[n].dropped = aligner.late(n) + aligner.duplicates(n) + refused[n];
      stats.cameras[n].background_age_s = std::numeric_limits<double>::quiet_NaN();
    }
    (void)r;
    stats.stages = {0, fusion->detect_s(), fusion->fuse_s(), post->blobs_s(), post->track_s(), post->output_s(),
                    0, fusion->people_s(), summary.lut_seconds};
  };
  SinkStage sink_stage(sinks, camera_ids, options, &summary_file, t_start, running_figures);
  OCCMAP_RETURN_IF_ERROR(sink_stage.Open(RunSinkStart(site, lut, options, fps, camera_ids)));

  FrameSet set;
  set.frames.resize(n_cams);
  set.active.assign(n_cams, false);
  set.map = OccupancyMap(site.grid);
  const CameraChanges& changes = fusion->changes();
  std::optional<Clock::time_point> t_first_set;
  const std::string protection_topic = ProtectionTopic(prefix);
  ProtectionMessage protection;
  int64_t protections = 0, protection_bytes = 0;
  protection.table_key = EdgeTableKey(site);
  protection.settings_key = EdgeSettingsKey(site);
  Status failure;
  // By frame index (files): the last frame set fused, retained, for edges that start late.
  const bool say_progress = align.sync == FrameSync::kIndex;
  std::optional<FuseProgress> progress_said;
  Clock::time_point progress_said_at;
  int64_t said_subscribed_on = -1;  // the connection subscribed when it was last said
  auto say = [&](int64_t frame) -> Status {
    progress_said = FuseProgress{frame, UnixNow()};
    progress_said_at = Clock::now();
    if (link->subscribed()) said_subscribed_on = link->connects();
    return link->Publish(progress_topic, EncodeProgress(*progress_said), /*retain=*/true);
  };
  auto emit = [&](AlignedSet& a) -> Status {
    if (!t_first_set) t_first_set = Clock::now();
    set.frame_index = a.frame;
    set.timestamp_s = align.sync == FrameSync::kTimestamp ? a.time : std::nan("");
    // The latency counts from the frames' capture (the earliest of the set, on the edges'
    // clocks) when the clocks agree; else from the first message's arrival here.
    double captured_unix = std::numeric_limits<double>::infinity();
    changes.EnsureBuffer(set);
    for (size_t n = 0; n < n_cams; ++n) {
      set.active[n] = a.cameras[n].has_value();
      if (!set.active[n]) continue;
      const EdgeMessage& m = *a.cameras[n];
      const std::string topic = EdgeTopic(prefix, site.cameras[n].id);
      const Status decoded = DecodeEdgeChanges(
          m.encoded, std::span<uint8_t>(set.changes.data() + changes.offset(n), changes.offset(n + 1) - changes.offset(n)),
          topic);
      if (!decoded.ok()) {  // a broken payload: the camera is left out of this set (its cells unseen)
        set.active[n] = false;
        refuse(n, topic, decoded.message());
        continue;
      }
      if (std::isnan(set.timestamp_s)) set.timestamp_s = m.timestamp_s;
      captured_unix = std::min(captured_unix, m.t_unix);
    }
    set.t_unix = captured_unix;
    const double age_s = UnixNow() - captured_unix;
    set.arrival = age_s >= 0 && age_s < 3600 ? Clock::now() - std::chrono::duration_cast<Clock::duration>(
                                                                  std::chrono::duration<double>(age_s))
                                             : a.first_arrival;
    set.changes_given = true;
    fusion->Process(set, ctx);
    if (const BackgroundProtection* p = fusion->protection()) {  // for the edges' adaptive backgrounds
      protection.frame = set.frame_index;
      protection.timestamp_s = set.timestamp_s;
      protection.t_unix = set.t_unix;
      protection.boxes = p->boxes();
      protection.persons_m = p->person_positions();
      protection.occupied = OccupiedRuns(set.map);
      const std::string bytes = EncodeProtectionMessage(protection);
      protection_bytes += static_cast<int64_t>(bytes.size());
      ++protections;
      OCCMAP_RETURN_IF_ERROR(link->Publish(protection_topic, bytes));
    }
    FrameRecord record;
    OCCMAP_RETURN_IF_ERROR(post->Process(set, record));
    OCCMAP_RETURN_IF_ERROR(sink_stage.Consume(record));
    if (say_progress) OCCMAP_RETURN_IF_ERROR(say(set.frame_index));
    ++summary.frames;
    if (progress) progress({summary.frames, std::nullopt, Since(t_start)});
    return Status::Ok();
  };
  auto frame_limit = [&] { return options.max_frames > 0 && summary.frames >= options.max_frames; };
  std::vector<bool> was_alive(n_cams, true);
  int64_t resumed_on = link->connects();
  while (failure.ok() && !stop_requested() && !frame_limit()) {
    // Everything queued: a set is judged on every message that has arrived.
    for (auto r = link->Pop(std::chrono::milliseconds(10)); r; r = link->Pop(std::chrono::milliseconds(0))) receive(*r);
    const auto now = Clock::now();
    // While the broker is away no camera can be heard: no set is judged. Back, the silence was
    // not the cameras' (the edges send again what the broker may have lost: RunEdge).
    if (!link->connected()) {
      if (aligner.all_ended() && aligner.idle()) break;
      continue;
    }
    if (link->connects() != resumed_on) {
      resumed_on = link->connects();
      aligner.Resume(now);
    }
    // Say when a camera is given up on and when it is back.
    for (size_t n = 0; n < n_cams; ++n) {
      const bool alive = aligner.alive(n, now) || aligner.ended(n) || !aligner.heard(n);
      if (alive == was_alive[n]) continue;
      was_alive[n] = alive;
      std::fputs(fmt::format("occmap fuse: camera {} {} at frame set {}\n", site.cameras[n].id,
                             alive ? "is back" : fmt::format("silent for {} s, left out", o.dead_after_s), summary.frames)
                     .c_str(),
                 stderr);
    }
    while (failure.ok() && !frame_limit()) {
      std::optional<AlignedSet> a = aligner.Next(now);
      if (!a) break;
      failure = emit(*a);
    }
    // Said again while waiting: an edge takes only a young progress (an old one may be a killed
    // fuse's). And at once when subscribed again after a reconnection: edges that reconnected
    // wait for it to send again what the broker may have lost (RunEdge).
    if (failure.ok() && progress_said &&
        (Clock::now() - progress_said_at > std::chrono::seconds(1) ||
         (link->subscribed() && link->connects() != said_subscribed_on))) {
      failure = say(progress_said->frame);
    }
    if (aligner.all_ended() && aligner.idle()) break;
  }
  if (say_progress) {  // ended: no progress for the next run's edges
    const Status cleared = link->Publish(progress_topic, "", /*retain=*/true);
    if (failure.ok()) failure = cleared;
    link->WaitPublished(std::chrono::seconds(2));
  }
  const RunStats& stats = sink_stage.stats();
  summary.stop_reason = !failure.ok()                                                      ? failure.message()
                        : stop_requested()                                                 ? "stop requested"
                        : options.max_frames > 0 && summary.frames >= options.max_frames ? "frame limit"
                                                                                         : "end of streams";
  if (!failure.ok()) files->Abandon();
  Status closed = sink_stage.Close(summary.stop_reason);
  if (failure.ok()) failure = closed;
  for (const fs::path& p : files->written()) summary.outputs.push_back(p.string());
  // What `people: {occluders: {learn: true}}` learned, as `occmap run` saves it: occluders.txt
  // and the cache the next run (or fuse) starts from.
  if (failure.ok()) failure = fusion->SaveLearnedOccluders(out, summary.outputs);
  if (!failure.ok()) summary.stop_reason = failure.message();
  summary.latency = stats.latency;
  summary.detect_s = fusion->detect_s();
  summary.fuse_s = fusion->fuse_s();
  summary.people_s = fusion->people_s();
  summary.occluders_s = fusion->occluders_s();
  summary.blobs_s = post->blobs_s();
  summary.track_s = post->track_s();
  summary.output_s = post->output_s() + sink_stage.write_s();
  if (t_first_set) summary.startup_s = std::chrono::duration<double>(*t_first_set - t_start).count();
  summary.tracks = stats.tracks;
  summary.zone_events = stats.zone_events;
  summary.blobs_total = sink_stage.blobs_total();
  summary.blobs_max_per_frame = sink_stage.blobs_max_per_frame();
  summary.seconds = Since(t_start);
  summary.frames_per_second = summary.seconds > 0 ? static_cast<double>(summary.frames) / summary.seconds : 0;
  for (size_t n = 0; n < n_cams; ++n) {
    CameraRunInfo info = cams[n].info;
    if (aligner.ended(n)) info.ended_at_frame = aligner.ended_at(n);
    info.left_out = aligner.left_out(n);
    info.late_messages = aligner.late(n);
    info.duplicate_messages = aligner.duplicates(n);
    info.refused_messages = refused[n];
    summary.cameras.push_back(info);
  }
  if (protections > 0) {
    std::fputs(fmt::format("occmap fuse: {} protections sent to the edges' adaptive backgrounds, {:.0f} bytes each\n",
                           protections, static_cast<double>(protection_bytes) / static_cast<double>(protections))
                   .c_str(),
               stderr);
  }
  const int64_t refused_total = std::accumulate(refused.begin(), refused.end(), int64_t{0});
  if (aligner.duplicates() > 0 || refused_total > 0) {
    std::fputs(fmt::format("occmap fuse: {} duplicate messages (copies of one pending or fused) and {} refused messages "
                           "dropped\n",
                           aligner.duplicates(), refused_total)
                   .c_str(),
               stderr);
  }
  if (aligner.late() > 0) {
    std::fputs(fmt::format("occmap fuse: {} messages came after their frame set was fused (dropped)\n", aligner.late()).c_str(),
               stderr);
  }
  summary.outputs.push_back(summary_file.path().string());
  const Status written = summary_file.WriteFinal(summary, stats, cams, options.start_frame);
  OCCMAP_RETURN_IF_ERROR(failure);
  OCCMAP_RETURN_IF_ERROR(written);
  return summary;
}

}  // namespace occmap
