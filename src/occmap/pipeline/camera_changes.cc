#include "occmap/pipeline/camera_changes.h"

#include "occmap/detect/background.h"
#include "occmap/detect/change_detection.h"

namespace occmap {

CameraChanges::CameraChanges(const Site& site, const std::vector<CameraState>& cams, bool colour, bool change_pngs)
    : site_(site), cams_(cams), colour_(colour), change_pngs_(change_pngs) {
  offsets_.push_back(0);
  for (const CameraState& c : cams) {
    const ImageSize size = c.cam->camera->image_size();
    offsets_.push_back(offsets_.back() + static_cast<uint32_t>(size.width * size.height));
  }
}

void CameraChanges::EnsureBuffer(FrameSet& set) const {
  if (set.changes.size() != static_cast<size_t>(total_pixels())) set.changes.assign(total_pixels(), 0);
}

ImageView<uint8_t> CameraChanges::Slice(FrameSet& set, size_t n) const {
  const ImageSize size = cams_[n].cam->camera->image_size();
  return ImageView<uint8_t>(set.changes.data() + offsets_[n], size.width, size.height,
                            size.width);
}

ImageView<const uint8_t> CameraChanges::Slice(const FrameSet& set, size_t n) const {
  const ImageSize size = cams_[n].cam->camera->image_size();
  return ImageView<const uint8_t>(set.changes.data() + offsets_[n], size.width,
                                  size.height, size.width);
}

void CameraChanges::Compute(FrameSet& set, size_t n, Image<uint8_t>& raw, std::vector<uint8_t>& scratch,
                            bool dilate) const {
  const CameraState& c = cams_[n];
  const ImageSize size = c.cam->camera->image_size();
  ImageView<uint8_t> slice = Slice(set, n);
  const int r = site_.detection.tolerance_px;
  const int threshold = site_.detection.threshold;
  const Frame& frame = set.frames[n];
  if (r > 0 && r <= 4 && !c.is_mask && !colour_ && !c.model && !change_pngs_) {
    // small tolerances on grey: one pass, no raw image
    DetectChangesGrayDilated(frame.gray.view(), c.background_gray.view(), threshold, r, slice, scratch);
    return;
  }
  if (r > 0 && (raw.width() != size.width || raw.height() != size.height)) raw = Image<uint8_t>(size.width, size.height);
  ImageView<uint8_t> target = r > 0 ? raw.view() : slice;
  if (c.is_mask) {
    MaskToChanges(frame.gray.view(), target);
  } else if (c.model) {
    c.model->DetectChanges(FrameYuv(frame), threshold, target);
  } else if (colour_) {
    DetectChangesRgb(frame.rgb.view(), c.background_rgb.view(), threshold, target);
  } else {
    DetectChangesGray(frame.gray.view(), c.background_gray.view(), threshold, target);
  }
  if (r > 0 && dilate) Widen(n, raw.view(), slice, scratch);
}

void CameraChanges::Quantise(FrameSet& set, size_t n) const {
  const ChangeDetectionOptions& d = site_.detection;
  if (d.blocks()) QuantiseChanges(Slice(set, n), d.block_width_px, d.block_height_px, d.block_rule);
}

void CameraChanges::Widen(size_t n, ImageView<const uint8_t> raw, ImageView<uint8_t> slice,
                          std::vector<uint8_t>& scratch) const {
  const CameraState& c = cams_[n];
  const int r = site_.detection.tolerance_px;
  // The adaptive model keeps its background up from the map's free cells: off the floor no cell
  // says so, and cast shadows fall on walls too. Those changes are not widened onto the floor.
  if (c.model && !c.cam->mask.empty()) {
    DilateFloorChanges(raw, c.cam->mask.view(), r, slice, scratch);
  } else {
    DilateChanges(raw, r, slice, scratch);
  }
}

}  // namespace occmap
