// The elevated check's fast path: each camera's changes read in place from its buffer (a byte
// image or ChangeBits' unchanged bits), no call per pixel. The same states as the reference
// (SupportState through the ChangeLookup, elevated_check.cc); ObjectDetectorTest checks both
// layouts against it.
#include "occmap/objects/elevated_check.h"

namespace occmap {

int ElevatedCheck::SupportStateFromBuffers(size_t h, int64_t cell, int32_t* pixels,
                                           std::span<const ChangeBuffer> buffers) {
  int seeing = 0;
  for (size_t n : active_cameras_) {
    const int32_t p = SupportPixel(h, n, cell, pixels);
    if (p < 0) continue;
    ++seeing;
    const size_t x = PixelX(p), y = PixelY(p);  // no division, no virtual call
    const ChangeBuffer& b = buffers[n];
    if (b.unchanged_bits != nullptr) {
      if ((b.unchanged_bits[y * b.row_words + x / 64] >> (x % 64)) & 1u) return 0;
    } else if (b.pixels[y * b.stride + x] == 0) {
      return 0;
    }
  }
  return seeing > 0 ? 1 : -1;
}

}  // namespace occmap
