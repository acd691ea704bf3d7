// DetectTrackStage: the third stage of a run (pipeline/run.h), on its own thread. Input: a
// FrameSet the fusion stage has fused (fusion_stage.h). Output: the FrameRecord the sinks get
// (frame_sink.h): the frame's detections (ObjectDetector, or the people's fusions), the
// tracker's reported tracks, zone and line events, and the pictures the outputs ask for (the
// mosaic, change PNGs, the frames for a sink that shows them). It keeps the frame set with the
// most detections for mosaic.png (BestMosaic, after the last frame set).
//
//   OCCMAP_ASSIGN_OR_RETURN(auto post, DetectTrackStage::Create(site, options, plan, lut, cams, fusion, fps));
//   OCCMAP_RETURN_IF_ERROR(post->Process(set, record));   // per frame set, in frame order
//   post->GivePicture(std::move(record.mosaic));           // the writer hands pictures back
#pragma once

#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "occmap/lut/column_lut.h"
#include "occmap/objects/object_detector.h"
#include "occmap/pipeline/camera_changes.h"
#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/frame_set.h"
#include "occmap/pipeline/frame_sink.h"
#include "occmap/pipeline/fusion_path.h"
#include "occmap/pipeline/mosaic.h"
#include "occmap/pipeline/run.h"
#include "occmap/pipeline/shared_figure.h"
#include "occmap/track/count_lines.h"
#include "occmap/track/multi_target_tracker.h"
#include "occmap/track/track_output.h"
#include "occmap/track/window_tracker.h"
#include "occmap/track/zones.h"

namespace occmap {

// The site's tracker, whichever algorithm it names.
class AnyTracker {
 public:
  static Result<AnyTracker> Create(const TrackerOptions& options);
  // The multi-target tracker measures the detections; the paper's window tracker reads the
  // groups' cells in the grown map.
  Result<std::vector<Track>> Update(const DetectedObjects& objects, double time_s);

 private:
  std::unique_ptr<WindowTracker> window_;
  std::unique_ptr<MultiTargetTracker> multi_;
  std::vector<Blob> groups_;  // the window tracker's input, buffer kept
};

// Frame sets whose outputs may wait for the writer (each up to a mosaic picture, ~3 MB).
constexpr size_t kOutputQueue = 4;

class DetectTrackStage {
 public:
  // column_lut: the fusion stage's (the people's candidate positions), null without people.
  static Result<std::unique_ptr<DetectTrackStage>> Create(const Site& site, const RunOptions& options,
                                                          const FusionPlan& plan, const GroundLut& lut,
                                                          const std::vector<CameraState>& cams,
                                                          const CameraChanges& changes, const ColumnLut* column_lut,
                                                          double fps);
  DetectTrackStage(const DetectTrackStage&) = delete;
  DetectTrackStage& operator=(const DetectTrackStage&) = delete;

  // record: a fresh FrameRecord, filled here.
  Status Process(FrameSet& set, FrameRecord& record);
  // A mosaic picture the sinks are done with, drawn over again (any thread).
  void GivePicture(Image<Rgb8>&& picture);
  // After the last frame set: the mosaic of the frame set with the most detections (drawn now
  // when the mosaic video was off), empty when there was none.
  const Image<Rgb8>& BestMosaic();
  ImageSize mosaic_size() const { return mosaic_.size(); }
  // Seconds so far (any thread may read them while the stage runs).
  double blobs_s() const { return blobs_s_.get(); }
  double track_s() const { return track_s_.get(); }
  double output_s() const { return output_s_.get(); }

 private:
  DetectTrackStage(const Site& site, const RunOptions& options, const FusionPlan& plan, const GroundLut& lut,
                   const std::vector<CameraState>& cams, const CameraChanges& changes, const ColumnLut* column_lut,
                   double fps);
  void FindObjects(FrameSet& set);
  Status UpdateTracks(int64_t frame_index, double time_s, FrameRecord& record);
  void Pictures(FrameSet& set, FrameRecord& record);
  void RenderMosaic(FrameSet& set, const std::vector<Detection>& blobs, double time_s, const std::vector<Track>& tracks,
                    const std::vector<Trail>& trails, Image<Rgb8>& picture);
  Image<Rgb8> TakePicture();

  const Site& site_;
  const RunOptions& options_;
  const FusionPlan plan_;
  const GroundLut& lut_;
  const std::vector<CameraState>& cams_;
  const CameraChanges& changes_;
  const ColumnLut* column_lut_;
  const double fps_;
  ObjectDetector detector_;
  DetectedObjects objects_;
  std::vector<size_t> camera_width_;  // read per pixel by the elevated check: no virtual call there
  std::vector<ObjectDetector::ChangeBuffer> change_buffers_;  // the elevated check's fast path
  // Tracking.
  std::optional<AnyTracker> tracker_;
  std::optional<ZoneMonitor> zones_;
  std::optional<LineCounter> lines_;
  TrailHistory trails_;
  double last_track_time_s_;
  // Pictures.
  MosaicRenderer mosaic_;
  std::vector<Image<uint8_t>> raw_;  // the mosaic's changes of a fully fused frame, per camera
  std::vector<std::vector<uint8_t>> scratch_;
  // Mosaic pictures handed back by the writer, drawn over again (MosaicRenderer::Render): a few
  // buffers for a whole run instead of a fresh one of several MB per frame set.
  std::mutex pool_mutex_;
  std::vector<Image<Rgb8>> pool_;
  Image<Rgb8> best_mosaic_;
  size_t best_blobs_ = 0;
  // Without mosaic video: the frame set with the most detections so far and what its picture
  // shows, drawn at the end.
  struct KeptFrame {
    FrameSet set;
    std::vector<Detection> detections;
    std::vector<Track> tracks;
    std::vector<Trail> trails;
    double time_s = 0;
    bool kept = false;
  } best_frame_;
  SharedFigure blobs_s_, track_s_, output_s_;
};

}  // namespace occmap
