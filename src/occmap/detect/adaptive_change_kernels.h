// Row kernels of the adaptive model's hot loops (background_model.h): the plain reference of
// each, and the fast one, compiled again per kernel set (util/simd.h: portable, AVX2,
// AVX-512BW, chosen at run time), equal to the reference bit for bit (adaptive_change_kernels_
// test.cc). BackgroundModel keeps the meaning (which pixel follows the frame, by how much); the
// kernels only do the common case of its loops fast and leave the rest to it. No two of a
// kernel's arrays may overlap (the fast paths are compiled as if they do not).
//
//   UpdateRowArgs a{...};                 // one row of BackgroundModel::Update
//   a.simple_pixels = UpdateFreeBackgroundRow(a);   // rest[x] = 1: the model's own loop does x
//   ChromaFlagsRow(...); ChangeTestRow(args);       // one row of DetectChanges, with its weak test
//   GrowChangesFromWeak(changes, weak, classes, steps, min_seed_px, scratch);  // its hysteresis
#pragma once

#include <cstdint>
#include <vector>

#include "occmap/util/image.h"

namespace occmap {

// One row of the background's upkeep (BackgroundModel::Update) for its common pixels: classed
// background (BackgroundModel::kBackground) and free (kFree) in the protection map. Those follow
// the frame: luma (8.8) by += (inv_y[level] - by) * alpha / 65536 (rounded half up, the division
// truncated towards zero as in C), steadiness 0, last set at `frame`, previous luma = level; on
// a chroma row (`chroma` not null) the chroma block whose top-left pixel (even x) is such a pixel
// follows the frame's chroma likewise through inv_c (only when `inv_c` is given: the luma's gain
// alone; with a fitted colour transfer those pixels are left to the model, rest = 1). Every other
// pixel is left untouched and gets rest[x] = 1 (0 for the pixels done). Needs alpha <= 32767
// (the products stay in 32 bits); returns the pixels whose last set was -1 (never).
struct UpdateRowArgs {
  int width = 0;
  const uint8_t* frame_y = nullptr;     // the frame's luma row
  const uint8_t* protection = nullptr;  // the protection map's row
  const uint8_t* classes = nullptr;     // the last change test's classes
  uint16_t* background_y = nullptr;     // 8.8
  uint8_t* previous_y = nullptr;
  uint16_t* steady_frames = nullptr;
  int32_t* set_frame = nullptr;
  const int32_t* inv_y = nullptr;       // 256 entries: frame level -> background 8.8
  int32_t alpha = 0;                    // in 1/65536
  int32_t frame = 0;
  // Chroma rows (the luma row is even): the frame's chroma row and the background's (8.8).
  const uint8_t* frame_u = nullptr;
  const uint8_t* frame_v = nullptr;
  uint16_t* background_u = nullptr;
  uint16_t* background_v = nullptr;
  const int32_t* inv_c = nullptr;       // 256 entries, or null: chroma top-left pixels left to the model
  uint8_t* rest = nullptr;              // out: 1 where the model's loop must do the pixel
};
int64_t UpdateFreeBackgroundRow(const UpdateRowArgs& a);
int64_t UpdateFreeBackgroundRowReference(const UpdateRowArgs& a);

// One chroma row of the change test: flags[x] for the luma row's pixels x (both of a chroma
// pixel's columns, `width` of them) = 1 when |u - eu| or |v - ev| > strong, plus 2 when either
// is > weak (the hysteresis' chroma threshold; weak <= 0: never).
void ChromaFlagsRow(int width, const uint8_t* frame_u, const uint8_t* frame_v, const uint8_t* expected_u,
                    const uint8_t* expected_v, int strong, int weak, uint8_t* flags);
void ChromaFlagsRowReference(int width, const uint8_t* frame_u, const uint8_t* frame_v, const uint8_t* expected_u,
                             const uint8_t* expected_v, int strong, int weak, uint8_t* flags);

// One row of BackgroundModel::DetectChanges before its shadow test, in one pass: the expected
// luma of each background level under the transfer (clamp((gain_q16 b + offset_q16) >> 16),
// halfway to the clip where b is clipped: BackgroundModel::ExpectedLuma), classes[x] =
// changes[x] = 1 where |frame - expected| > threshold or chroma_flags' bit 0 is set (0
// elsewhere), and weak[x] = 1 where the pixel is not changed but is at the hysteresis'
// thresholds (|frame - expected| > weak_threshold or chroma_flags' bit 1). Returns the changes.
struct ChangeRowArgs {
  int width = 0;
  const uint8_t* frame_y = nullptr;
  const uint8_t* background_y = nullptr;  // 8-bit
  const uint8_t* chroma_flags = nullptr;  // ChromaFlagsRow's (all 0 without chroma)
  int32_t gain_q16 = 65536, offset_q16 = 32768;  // the offset with the rounding half
  int threshold = 0, weak_threshold = 0;
  uint8_t* classes = nullptr;
  uint8_t* changes = nullptr;
  uint8_t* weak = nullptr;
};
int ChangeTestRow(const ChangeRowArgs& a);
int ChangeTestRowReference(const ChangeRowArgs& a);

// The hysteresis of BackgroundModel::DetectChanges on masks alone: seeds are the 8-connected
// components of `changes` (non-zero) of at least min_seed_pixels; then `steps` times, the weak
// pixels (non-zero in `weak`) 8-next to a seed become changes and seeds (changes = 1, classes =
// 1, BackgroundModel::kChanged, weak = 0), stopping early at a step that adds none. Returns the
// pixels added. `seeds` and `band` are scratch images of the size (made when empty).
// GrowChangesFromWeakReference: the same by a flood fill and a per-pixel neighbourhood test.
int64_t GrowChangesFromWeak(ImageView<uint8_t> changes, ImageView<uint8_t> weak, ImageView<uint8_t> classes, int steps,
                            int64_t min_seed_pixels, Image<uint8_t>& seeds, Image<uint8_t>& band);
int64_t GrowChangesFromWeakReference(ImageView<uint8_t> changes, ImageView<uint8_t> weak, ImageView<uint8_t> classes,
                                     int steps, int64_t min_seed_pixels);

}  // namespace occmap
