// Row kernels of the adaptive model's hot loops (background_model.h): the plain reference of
// each, and the fast one, compiled again per kernel set (util/simd.h: portable, AVX2,
// AVX-512BW, chosen at run time), equal to the reference bit for bit (adaptive_change_kernels_
// test.cc). BackgroundModel keeps the meaning (which pixel follows the frame, by how much); the
// kernels only do the common case of its loops fast and leave the rest to it.
//
//   UpdateRowArgs a{...};                 // one row of BackgroundModel::Update
//   a.simple_pixels = UpdateFreeBackgroundRow(a);   // rest[x] = 1: the model's own loop does x
#pragma once

#include <cstdint>

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

}  // namespace occmap
