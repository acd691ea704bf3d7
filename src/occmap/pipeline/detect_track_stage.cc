#include "occmap/pipeline/detect_track_stage.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "occmap/objects/people_detections.h"

namespace occmap {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// RunOptions::sink_frames: each active camera's frame and its changes (after the tolerance),
// copied into the record (the slot is reused once this stage is done with it). A fuse's frame
// sets have changes and no frames: the changes alone.
void CopyFramesForSinks(const FrameSet& set, const GroundLut& lut, FrameRecord& record) {
  const size_t n_cams = set.frames.size();
  record.frames_gray.resize(n_cams);
  record.frames_rgb.resize(n_cams);
  record.change_masks.resize(n_cams);
  for (size_t n = 0; n < n_cams; ++n) {
    if (!set.active[n]) continue;
    const Frame& f = set.frames[n];
    record.frames_gray[n] = f.gray;
    record.frames_rgb[n] = f.rgb;
    if (!set.changes_ready) continue;
    const ImageSize size = lut.image_size(static_cast<int>(n));
    const int w = size.width, h = size.height;
    Image<uint8_t>& mask = record.change_masks[n];
    mask = Image<uint8_t>(w, h);
    const uint8_t* src = set.changes.data() + lut.pixel_offset(static_cast<int>(n));
    for (int y = 0; y < h; ++y) std::memcpy(mask.row(y), src + static_cast<ptrdiff_t>(y) * w, static_cast<size_t>(w));
  }
}

std::vector<ObjectDetector::CameraView> DetectorViews(const std::vector<CameraState>& cams) {
  std::vector<ObjectDetector::CameraView> views;
  for (const auto& c : cams) views.push_back({c.cam->camera.get(), &c.cam->mask});
  return views;
}

}  // namespace

Result<AnyTracker> AnyTracker::Create(const TrackerOptions& options) {
  AnyTracker t;
  if (options.algorithm == TrackerAlgorithm::kWindow) {
    OCCMAP_ASSIGN_OR_RETURN(WindowTracker w, WindowTracker::Create(options));
    t.window_ = std::make_unique<WindowTracker>(std::move(w));
  } else {
    OCCMAP_ASSIGN_OR_RETURN(MultiTargetTracker m, MultiTargetTracker::Create(options));
    t.multi_ = std::make_unique<MultiTargetTracker>(std::move(m));
  }
  return t;
}

Result<std::vector<Track>> AnyTracker::Update(const DetectedObjects& objects, double time_s) {
  if (!window_) return multi_->Update(objects, time_s);
  groups_.clear();
  for (const DetectionGroup& g : objects.groups) groups_.push_back(g.group);
  return window_->Update(groups_, objects.grown, time_s);
}

DetectTrackStage::DetectTrackStage(const Site& site, const RunOptions& options, const FusionPlan& plan,
                                   const GroundLut& lut, const std::vector<CameraState>& cams,
                                   const CameraChanges& changes, const ColumnLut* column_lut, double fps)
    : site_(site),
      options_(options),
      plan_(plan),
      lut_(lut),
      cams_(cams),
      changes_(changes),
      column_lut_(column_lut),
      fps_(fps),
      detector_(site.objects, site.plane_height_m, DetectorViews(cams)),
      trails_(site.tracking.trail_length),
      last_track_time_s_(-std::numeric_limits<double>::infinity()),
      mosaic_(site, options.mosaic_width_px),
      raw_(cams.size()),
      scratch_(cams.size()) {
  for (const auto& c : cams) camera_width_.push_back(static_cast<size_t>(c.cam->camera->image_size().width));
}

Result<std::unique_ptr<DetectTrackStage>> DetectTrackStage::Create(const Site& site, const RunOptions& options,
                                                                   const FusionPlan& plan, const GroundLut& lut,
                                                                   const std::vector<CameraState>& cams,
                                                                   const CameraChanges& changes,
                                                                   const ColumnLut* column_lut, double fps) {
  std::unique_ptr<DetectTrackStage> s(new DetectTrackStage(site, options, plan, lut, cams, changes, column_lut, fps));
  if (options.track) {
    OCCMAP_ASSIGN_OR_RETURN(AnyTracker t, AnyTracker::Create(site.tracking));
    s->tracker_ = std::move(t);
    OCCMAP_ASSIGN_OR_RETURN(ZoneMonitor z, ZoneMonitor::Create(site.tracking.zones, site.tracking.zone_count_every_frame));
    s->zones_ = std::move(z);
    OCCMAP_ASSIGN_OR_RETURN(LineCounter l, LineCounter::Create(site.tracking.lines));
    s->lines_ = std::move(l);
  }
  return s;
}

Status DetectTrackStage::Process(FrameSet& set, FrameRecord& record) {
  auto t0 = Clock::now();
  FindObjects(set);
  blobs_s_.Add(Since(t0));
  const int64_t frame_index = set.frame_index;
  const double time_s = std::isnan(set.timestamp_s) ? static_cast<double>(frame_index) / fps_ : set.timestamp_s;
  record.frame = frame_index;
  record.time_s = time_s;
  record.t_unix = set.t_unix;
  record.arrival = set.arrival;
  record.active = set.active;
  t0 = Clock::now();
  OCCMAP_RETURN_IF_ERROR(UpdateTracks(frame_index, time_s, record));
  track_s_.Add(Since(t0));
  t0 = Clock::now();
  Pictures(set, record);
  output_s_.Add(Since(t0));
  return Status::Ok();
}

// Detections (ObjectDetector: fragments grouped, described by their footprint, small ones
// dropped, large ones split at their necks, flat ones and ghosts removed). The tracker gets the
// kept groups with their splits, which it refines by its predictions. The elevated check reads
// single pixels' changes: from the change buffer when this frame has one, from the fusion's
// bits (fused with a tolerance), else (fully fused: grey, no tolerance, no masks) from frame
// and background.
void DetectTrackStage::FindObjects(FrameSet& set) {
  const ObjectDetector::ChangeLookup changed = [&](int n, int x, int y) {
    const CameraState& c = cams_[static_cast<size_t>(n)];
    if (set.bits_ready) return set.change_bits.Changed(n, x, y);
    if (set.changes_ready) {
      const size_t width = camera_width_[static_cast<size_t>(n)];
      return set.changes[lut_.pixel_offset(n) + static_cast<size_t>(y) * width + static_cast<size_t>(x)] != 0;
    }
    const int d = static_cast<int>(set.frames[static_cast<size_t>(n)].gray.view()(x, y)) -
                  static_cast<int>(c.background_gray.view()(x, y));
    return std::abs(d) > site_.detection.threshold;
  };
  change_buffers_.clear();
  for (size_t n = 0; n < cams_.size() && (set.changes_ready || set.bits_ready); ++n) {
    ObjectDetector::ChangeBuffer b;
    if (set.bits_ready) {
      b.unchanged_bits = set.change_bits.words.data() + set.change_bits.camera_word[n];
      b.row_words = set.change_bits.row_words[n];
    } else {
      b.pixels = set.changes.data() + lut_.pixel_offset(static_cast<int>(n));
      b.stride = camera_width_[n];
    }
    change_buffers_.push_back(b);
  }
  // With a people detector the floor's objects are not needed (the paper's window tracker
  // still reads the floor's groups).
  if (!plan_.people_detector || site_.tracking.algorithm == TrackerAlgorithm::kWindow) {
    detector_.Detect(set.map, set.active, changed, objects_, change_buffers_);
  }
  // People (the site's `people:` section): the explained people, or the column map's blobs.
  if (plan_.people_detector && site_.people.detector == PeopleDetector::kExplain) {
    PeopleDetections(set.people, column_lut_->candidates(), site_.tracking.person_radius_m(), objects_);
  } else if (plan_.people_detector) {
    ColumnMapDetections(set.column_map, objects_);
  }
}

// The tracker needs strictly increasing times: a repeated timestamp, as some streams give, is
// nudged forward by a microsecond.
Status DetectTrackStage::UpdateTracks(int64_t frame_index, double time_s, FrameRecord& record) {
  if (!tracker_) return Status::Ok();
  std::vector<Track>& tracks = record.tracks;
  const double track_time_s = std::max(time_s, last_track_time_s_ + 1e-6);
  last_track_time_s_ = track_time_s;
  OCCMAP_ASSIGN_OR_RETURN(tracks, tracker_->Update(objects_, track_time_s));
  // Zones count every live track; the outputs get the reported ones.
  record.zones = zones_->Update(frame_index, time_s, tracks);
  record.lines = lines_->Update(frame_index, time_s, tracks);
  std::erase_if(tracks, [&](const Track& t) { return !IsReported(t, site_.tracking.report_coasting_s); });
  trails_.Update(tracks);
  return Status::Ok();
}

// What the sinks get besides the figures: the map, the detections and the pictures.
void DetectTrackStage::Pictures(FrameSet& set, FrameRecord& record) {
  const std::vector<Detection>& blobs = objects_.detections;
  record.map = set.map;
  record.detections = blobs;
  if (options_.change_pngs) {
    record.change_pictures.resize(cams_.size());
    for (size_t n = 0; n < cams_.size(); ++n) {
      if (set.active[n]) record.change_pictures[n] = set.change_pictures[n];
    }
  }
  if (options_.sink_frames) CopyFramesForSinks(set, lut_, record);
  const bool first = options_.mosaic_video ? best_mosaic_.empty() : !best_frame_.kept;
  const bool best = first || blobs.size() > best_blobs_;
  if (options_.mosaic_video) {
    Image<Rgb8> picture = TakePicture();
    RenderMosaic(set, blobs, record.time_s, record.tracks, trails_.Trails(), picture);
    if (best) {
      best_mosaic_ = picture;
      best_blobs_ = blobs.size();
    }
    record.mosaic = std::move(picture);
  } else if (best && options_.mosaic_picture) {
    // mosaic.png only: the frame set is kept and drawn once at the end (a 7 x 1080p picture
    // with its changes costs more than the copy, and the best frame changes often early in a
    // run).
    FrameSet& kept = best_frame_.set;
    kept.frames = set.frames;
    kept.active = set.active;
    kept.map = set.map;
    kept.frame_index = set.frame_index;
    kept.changes_ready = set.changes_ready;
    if (set.changes_ready) kept.changes = set.changes;
    best_frame_.detections = blobs;
    best_frame_.tracks = record.tracks;
    best_frame_.trails = trails_.Trails();
    best_frame_.time_s = record.time_s;
    best_frame_.kept = true;
    best_blobs_ = blobs.size();
  }
}

// The mosaic picture of a frame set: its frames, their changes (computed here when the frame
// was fully fused), the map, detections and tracks.
void DetectTrackStage::RenderMosaic(FrameSet& set, const std::vector<Detection>& blobs, double time_s,
                                    const std::vector<Track>& tracks, const std::vector<Trail>& trails,
                                    Image<Rgb8>& picture) {
  const std::vector<Frame>& frames = set.frames;
  const std::vector<bool>& active = set.active;
  if (!set.changes_ready) {  // fully fused: the changes of this frame, for its picture
    changes_.EnsureBuffer(set);
    for (size_t n = 0; n < cams_.size(); ++n) {
      if (!active[n]) continue;
      changes_.Compute(set, n, raw_[n], scratch_[n], true);
      changes_.Quantise(set, n);
    }
    set.changes_ready = true;
  }
  std::vector<MosaicCamera> tiles;
  for (size_t n = 0; n < cams_.size(); ++n) {
    const CameraState& c = cams_[n];
    const ImageSize size = c.cam->camera->image_size();
    MosaicCamera t;
    t.id = c.cam->id;
    t.active = active[n];
    if (active[n]) {
      const ImageView<const uint8_t> changes = changes_.Slice(std::as_const(set), n);
      t.gray = frames[n].gray.view();
      if (c.is_mask && (frames[n].gray.width() != size.width || frames[n].gray.height() != size.height)) {
        t.gray = changes;
      }
      t.changes = changes;
      if (t.gray.width() != t.changes.width()) t.changes = {};
    }
    tiles.push_back(t);
  }
  mosaic_.Render(tiles, set.map, blobs, set.frame_index, time_s, tracks, trails, picture);
}

Image<Rgb8> DetectTrackStage::TakePicture() {
  std::lock_guard lock(pool_mutex_);
  if (pool_.empty()) return {};
  Image<Rgb8> picture = std::move(pool_.back());
  pool_.pop_back();
  return picture;
}

void DetectTrackStage::GivePicture(Image<Rgb8>&& picture) {
  std::lock_guard lock(pool_mutex_);
  if (!picture.empty() && pool_.size() < kOutputQueue + 2) pool_.push_back(std::move(picture));
}

const Image<Rgb8>& DetectTrackStage::BestMosaic() {
  if (best_frame_.kept) {
    RenderMosaic(best_frame_.set, best_frame_.detections, best_frame_.time_s, best_frame_.tracks, best_frame_.trails,
                 best_mosaic_);
    best_frame_.kept = false;
  }
  return best_mosaic_;
}

}  // namespace occmap
