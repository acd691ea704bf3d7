// Change detection, the paper's equation 4: D = 1 where |I - B| > T, else 0.
//
// Change masks are 8-bit, 1 = changed, 0 = unchanged (any non-zero value reads as changed).
// The grey variant compares luma; the colour variant marks a pixel changed when any of its
// R, G, B differences exceeds T. An optional tolerance dilates the change mask by r pixels (a
// (2r+1) x (2r+1) square): on real masks a strict AND of slightly misregistered cameras loses
// thin objects, and a few pixels of tolerance recovers them.
//
// The comparison is strict: |I - B| == T is unchanged, T + 1 is changed (equation 4; the
// paper's pseudo-code writes "< T" for the unchanged test, which differs only at |I - B| == T;
// occmap follows the equation). Outputs are exactly 1 or 0. Views may have any stride; only
// the width x height pixels of `out` are written.
//
// Each operation has a plain reference (the paper's loop, kept as the oracle) and the fast
// version used on the run path; tests check they are bit-identical.
//
//   Image<uint8_t> change(w, h);
//   DetectChangesGray(frame.view(), background.view(), /*threshold=*/30, change.view());
//   DilateChanges(change.view(), /*radius_px=*/2, dilated.view(), scratch);
#pragma once

#include <cstdint>
#include <vector>

#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

// When a block of pixels is changed (QuantiseChanges): any of its pixels changed, or at least
// half of them (2 of a 2x2 block; a clipped block's own pixels).
enum class BlockRule { kAny, kHalf };

struct ChangeDetectionOptions {
  static constexpr int kMaxTolerancePx = 64;

  int threshold = 30;     // T, grey levels 0..254 (255 would never report a change)
  bool colour = false;    // compare R, G, B rather than luma
  int tolerance_px = 0;   // dilation radius r, 0..kMaxTolerancePx
  // Changes decided per block of block_width_px x block_height_px pixels (each 1 or 2) after the
  // tolerance, a block changed by block_rule (QuantiseChanges): an edge message then codes one
  // pixel per block (block height 2: half the rows).
  int block_width_px = 1;
  int block_height_px = 1;
  BlockRule block_rule = BlockRule::kAny;
  bool blocks() const { return block_width_px > 1 || block_height_px > 1; }
  Status Validate() const;
};

// out(x, y) = |frame - background| > threshold. All three images have the same size;
// threshold in 0..255 (a CHECK: validate with ChangeDetectionOptions first).
void DetectChangesGray(ImageView<const uint8_t> frame, ImageView<const uint8_t> background, int threshold,
                       ImageView<uint8_t> out);
void DetectChangesGrayReference(ImageView<const uint8_t> frame, ImageView<const uint8_t> background,
                                int threshold, ImageView<uint8_t> out);

// out(x, y) = max over channels |frame - background| > threshold.
void DetectChangesRgb(ImageView<const Rgb8> frame, ImageView<const Rgb8> background, int threshold,
                      ImageView<uint8_t> out);
void DetectChangesRgbReference(ImageView<const Rgb8> frame, ImageView<const Rgb8> background, int threshold,
                               ImageView<uint8_t> out);

// Square dilation by radius_px: out(x, y) = 1 when any pixel of in within the window
// [x - r, x + r] x [y - r, y + r], clipped to the image, is non-zero, else 0. radius_px = 0
// copies (as 1 / 0). radius_px is at most 127 (window counts are kept in bytes); `out` has
// in's size and must not alias `in`. Separable: a row pass into `scratch` (resized as needed,
// reused across frames: no allocation once it has grown) and a column pass, each a running
// count of set pixels in the window, so the cost does not depend on r.
void DilateChanges(ImageView<const uint8_t> in, int radius_px, ImageView<uint8_t> out,
                   std::vector<uint8_t>& scratch);
// DilateChanges, but a floor pixel (floor_mask non-zero; empty: every pixel) is widened from
// the floor's changes only: a change off the floor (a wall, a shelf, the sky) is not widened
// into the floor's pixels, whose cells it would otherwise mark (a shadow on a wall by the
// floor's edge). Pixels off the floor are widened as DilateChanges does (people's columns).
void DilateFloorChanges(ImageView<const uint8_t> in, ImageView<const uint8_t> floor_mask, int radius_px,
                        ImageView<uint8_t> out, std::vector<uint8_t>& scratch);
// DetectChangesGray then DilateChanges by radius_px, in one pass over the rows (the changes
// of 2r + 1 rows are kept in `scratch`, reused across frames): the same output, without
// writing and re-reading a whole change image. Costs (2r + 1) row ORs per row: meant for the
// small tolerances of real sites.
void DetectChangesGrayDilated(ImageView<const uint8_t> frame, ImageView<const uint8_t> background, int threshold,
                              int radius_px, ImageView<uint8_t> out, std::vector<uint8_t>& scratch);
// Brute force over the (2r+1)^2 window of every pixel.
void DilateChangesReference(ImageView<const uint8_t> in, int radius_px, ImageView<uint8_t> out);
// Brute force of DilateFloorChanges.
void DilateFloorChangesReference(ImageView<const uint8_t> in, ImageView<const uint8_t> floor_mask, int radius_px,
                                 ImageView<uint8_t> out);

// Changes per block of block_w x block_h pixels (each 1 or 2), in place: every pixel of a block
// (the blocks start at (0, 0); those at the right and bottom edges are clipped) becomes 1 when
// the block is changed by `rule` (any non-zero pixel, or at least half of them non-zero), else 0.
// Blocks of 1 x 1 leave `changes` as it is. An edge message then codes one pixel per block
// (pipeline/edge_message.h), and the fuse expands it back to this.
void QuantiseChanges(ImageView<uint8_t> changes, int block_w, int block_h, BlockRule rule = BlockRule::kAny);
void QuantiseChangesReference(ImageView<uint8_t> changes, int block_w, int block_h, BlockRule rule = BlockRule::kAny);

// Converts a foreground mask from another tool (any 8-bit image, non-zero = foreground) to a
// change mask (1 / 0), resampling to out's size when they differ: nearest pixel under the
// pixel-centre convention (geometry/camera_model.h), out (x, y) reads in at
// u = (x + 0.5) * w_in / w_out - 0.5 (and likewise v), rounded to the nearest pixel with
// halves going up, i.e. in column floor((x + 0.5) * w_in / w_out), computed exactly in
// integers. So a 4x upsampling turns each pixel into a 4 x 4 block, and a quarter-size
// resampling reads pixel (4x + 2, 4y + 2). Neither image may be empty unless both are.
void MaskToChanges(ImageView<const uint8_t> mask, ImageView<uint8_t> out);

}  // namespace occmap
