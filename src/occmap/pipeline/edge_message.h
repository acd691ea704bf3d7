// EdgeMessage: what an `occmap edge` process publishes per camera and frame for `occmap fuse`
// (issue 17): the camera's changes after the tolerance, its rows coded as fax machines code
// theirs (ITU-T T.6 modes) and those modes range-coded in context, never the image. The fusion
// needs nothing else for the floor's AND, the vote rule, the elevated check and the people's
// fusions: they all read the change buffer.
//
// Binary, little-endian, version 5:
//   "OCME"  u16 schema version  u16 kind (0 changes, 1 end of the camera's source)
//   u64 table key (GroundLutKey of the site: cameras, masks, grid)
//   u64 settings key (the detection section: threshold, tolerance, colour, backgrounds)
//   u32 camera index  u32 width  u32 height  i64 frame index
//   f64 timestamp_s (NaN: none)  f64 t_unix  f64 fps (the source's, 0: none)
//   u32 number of modes  u32 payload bytes  u8 block width  u8 block height (detection.block_px,
//   1 or 2 each: the changes come in blocks alike, coded one pixel per block)
//   payload (below), then u64 checksum: HashBytes of every byte before it (version 5)
//   the payload: the rows' T.6 modes (0 vertical 0, 1-3 vertical +1..+3, 4-6 vertical -1..-3,
//   7 pass, 8 horizontal) and the horizontal modes' run lengths, coded by an adaptive binary
//   range coder whose contexts are the colour and the mode that made b1 in the row above
//   (docs/formats.md)
// A fuse process refuses a message of another schema version, whose checksum does not match,
// or built for other tables or other detection settings, with a message naming what differs.
//
//   std::string bytes = EncodeEdgeMessage(msg);                  // edge
//   OCCMAP_ASSIGN_OR_RETURN(EdgeMessage m, DecodeEdgeMessage(bytes, expect, topic));   // fuse
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/site/site.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

constexpr uint16_t kEdgeSchemaVersion = 5;

enum class EdgeMessageKind : uint16_t { kChanges = 0, kEnd = 1 };

struct EdgeMessage {
  EdgeMessageKind kind = EdgeMessageKind::kChanges;
  uint64_t table_key = 0;
  uint64_t settings_key = 0;
  uint32_t camera = 0;
  uint32_t width = 0, height = 0;
  int64_t frame = 0;
  double timestamp_s = 0;
  double t_unix = 0;
  double fps = 0;  // the camera source's frame rate (0: none): times of frames without timestamps
  // 1 or 2 each: `changes` come in blocks of block_w x block_h pixels alike (QuantiseChanges),
  // coded one pixel per block (a block is changed when any of its pixels is); decoded, every
  // pixel of a block holds its value.
  uint8_t block_w = 1, block_h = 1;
  // kChanges: width * height bytes, 1 changed, 0 not (decoded), or any non-zero changed (to encode).
  std::vector<uint8_t> changes;
  // The fuse's: the message as received, its changes decoded again when its frame set is fused
  // (a message waiting for its frame set then holds kilobytes, not an image).
  std::string encoded;
};

// What a fuse process accepts: its own keys, and each camera's image size.
struct EdgeExpectation {
  uint64_t table_key = 0;
  uint64_t settings_key = 0;
  std::vector<ImageSize> camera_sizes;
};

// The site's keys, as an edge and a fuse process of the same site file compute them.
uint64_t EdgeTableKey(const Site& site);
uint64_t EdgeSettingsKey(const Site& site);

// changes: the camera's slice, row-major without padding (width * height).
std::string EncodeEdgeMessage(const EdgeMessage& message);
// Another frame index, timestamp and t_unix in an encoded message (the bench's simulated
// cameras send recorded messages again).
void RestampEdgeMessage(std::string& bytes, int64_t frame, double timestamp_s, double t_unix);
// Another site's keys, camera index and frame rate in an encoded message (the bench's simulated
// cameras: one camera's recorded messages sent again as another camera of a larger site).
void RekeyEdgeMessage(std::string& bytes, uint64_t table_key, uint64_t settings_key, uint32_t camera, double fps);
// The checksum of a message whose bytes were changed in place made true again (Restamp and
// Rekey do it; the fuzz target, to reach the decoder with its mutations).
void SealEdgeMessage(std::string& bytes);
// source names the message in errors (e.g. its topic).
Result<EdgeMessage> DecodeEdgeMessage(std::string_view bytes, const EdgeExpectation& expect,
                                      std::string_view source);
// The fuse's two halves of DecodeEdgeMessage: the header, checked as it checks it (`changes`
// left empty), when a message arrives; its changes, decoded straight into the frame set's change
// buffer, when its frame set is fused (a message is decoded once, into no image of its own: at
// 64 cameras a decode on arrival and another into a fresh image were most of the fuse's CPU).
Result<EdgeMessage> DecodeEdgeHeader(std::string_view bytes, const EdgeExpectation& expect, std::string_view source);
// bytes: a message of changes that DecodeEdgeHeader accepted; out: its width * height pixels,
// row-major (1 changed, 0 not). On an error out holds no meaning.
Status DecodeEdgeChanges(std::string_view bytes, std::span<uint8_t> out, std::string_view source);

}  // namespace occmap
