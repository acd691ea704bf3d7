// Luma and 4:2:0 chroma of RGB pictures: full-range BT.601 (JPEG's YCbCr), 8 bits, 128 the
// neutral chroma. The frame sources' convention (io/frame_source.h: Frame::gray, u, v) is this
// one, so that the chroma of a background PNG computed here compares with a frame's, whether
// the frame came from an image file or a video.
//
//   Y = 0.299 R + 0.587 G + 0.114 B
//   U = 128 - 0.168736 R - 0.331264 G + 0.5 B        (Cb)
//   V = 128 + 0.5 R - 0.418688 G - 0.081312 B        (Cr)
//
// in 14-bit fixed point (Y: 4899, 9617, 1868, OpenCV's RGB2GRAY weights; U: -2765, -5427,
// 8192; V: 8192, -6860, -1332; each row of weights sums to 16384 or 0, so grey gives Y = the
// grey level and U = V = 128 exactly), rounded half up, clamped to 0..255. A chroma sample
// covers a 2x2 block of pixels (block (i, j) = pixels 2i..2i+1 x 2j..2j+1) and is the mean of
// their U (V) values over the pixels of the block inside the image: chroma planes are
// ceil(width / 2) x ceil(height / 2).
//
//   Image<uint8_t> gray, u, v;
//   LumaFromRgb(rgb.view(), gray);
//   ChromaFromRgb(rgb.view(), u, v);   // u, v: (width + 1) / 2 x (height + 1) / 2
#pragma once

#include <cstdint>

#include "occmap/util/image.h"

namespace occmap {

// The size of a 4:2:0 chroma plane of a width x height picture: half, rounded up.
inline int ChromaPlaneSize(int luma_size) { return (luma_size + 1) / 2; }

// gray is reallocated when its size differs from rgb's.
void LumaFromRgb(ImageView<const Rgb8> rgb, Image<uint8_t>& gray);

// u and v are reallocated when their size differs from ChromaPlaneSize of rgb's.
void ChromaFromRgb(ImageView<const Rgb8> rgb, Image<uint8_t>& u, Image<uint8_t>& v);

}  // namespace occmap
