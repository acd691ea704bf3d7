// CameraChanges: a camera's changes for one frame set, into the set's change buffer (global
// pixel ids, GroundLut::pixel_offset): equation 4 on grey or RGB frames, the adaptive model's
// test, or a foreground mask resampled, then the tolerance (DilateChanges). The fusion stage
// (fusion_stage.h) computes them for the fusion; the detect/track stage (detect_track_stage.h)
// for the mosaic of a frame set that was fully fused (FastFusion without a change buffer).
//
//   CameraChanges changes(site, cams, plan.colour, options.change_pngs);
//   changes.EnsureBuffer(set);
//   changes.Compute(set, n, raw, scratch, /*dilate=*/true);
//   ImageView<const uint8_t> c0 = changes.Slice(set, 0);
#pragma once

#include <cstdint>
#include <vector>

#include "occmap/pipeline/camera_inputs.h"
#include "occmap/pipeline/frame_set.h"
#include "occmap/site/site.h"
#include "occmap/util/image.h"

namespace occmap {

class CameraChanges {
 public:
  // change_pngs: the changes before the tolerance are kept (`raw`), never the one-pass path.
  // The buffer holds cams' pixels one camera after the other, as GroundLut::pixel_offset
  // (the run's tables) for the site's cameras; an edge process holds its own cameras only.
  CameraChanges(const Site& site, const std::vector<CameraState>& cams, bool colour, bool change_pngs);
  uint32_t offset(size_t n) const { return offsets_[n]; }
  uint32_t total_pixels() const { return offsets_.back(); }

  // set.changes sized for every camera's pixels (allocated once, then reused).
  void EnsureBuffer(FrameSet& set) const;
  // Camera n's slice of set.changes (its image size, its own rows).
  ImageView<uint8_t> Slice(FrameSet& set, size_t n) const;
  ImageView<const uint8_t> Slice(const FrameSet& set, size_t n) const;
  // Camera n's changes of set.frames[n] into its slice. dilate false leaves the tolerance to the
  // caller (the changes then in `raw` when tolerance_px > 0). raw and scratch: the caller's
  // buffers, kept between frames (one pair per camera when cameras run in parallel).
  void Compute(FrameSet& set, size_t n, Image<uint8_t>& raw, std::vector<uint8_t>& scratch, bool dilate) const;
  // The tolerance (detection.tolerance_px) of camera n's raw changes into its slice; a camera with
  // the adaptive model widens only the changes on its floor mask (DilateFloorChanges).
  void Widen(size_t n, ImageView<const uint8_t> raw, ImageView<uint8_t> slice, std::vector<uint8_t>& scratch) const;
  // Camera n's finished slice (after the tolerance and the shadows' floor check) per block of
  // detection.block_px (QuantiseChanges); nothing with blocks of 1 x 1. Every reader of the
  // changes (the floor, the people, an edge's message) reads them so.
  void Quantise(FrameSet& set, size_t n) const;

 private:
  const Site& site_;
  const std::vector<CameraState>& cams_;
  std::vector<uint32_t> offsets_;  // cams.size() + 1
  const bool colour_;
  const bool change_pngs_;
};

}  // namespace occmap
