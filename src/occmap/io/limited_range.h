// Limited-range ("MPEG", studio swing) 8-bit YUV to full range, one row at a time: how the
// video source turns decoded yuv420p planes into Frame::gray, u and v (io/frame_source.h).
//
//   luma   16..235 -> 0..255: (y - 16) x 298 / 256, rounded (BT.601's fixed-point factor for
//          255/219; at most 1 level from the exact ratio)
//   chroma 16..240 -> 0..255: round((c - 16) x 255 / 224), 128 stays 128 (exact)
// Values outside the range are clamped to it first. Each fast version is vectorised (and
// compiled again for AVX2, run when the kernel set allows, util/simd.h) and equals its plain
// reference on every input, on every kernel set (a test).
//
//   ExpandLimitedRangeChroma(frame->data[1] + y * frame->linesize[1], u.row(y), u.width());
#pragma once

#include <cstdint>

namespace occmap {

void ExpandLimitedRangeLuma(const uint8_t* src, uint8_t* dst, int width);
void ExpandLimitedRangeChroma(const uint8_t* src, uint8_t* dst, int width);

// The plain formulas, one value at a time: the references of the two above.
uint8_t ExpandLimitedRangeLumaReference(uint8_t y);
uint8_t ExpandLimitedRangeChromaReference(uint8_t c);

}  // namespace occmap
