// The mosaic picture of a frame, like the paper's figures 6 and 8: each camera's image with its
// changed pixels tinted red, beside the occupancy map (white free, black occupied, grey
// unseen; +x right, +y up) with the cameras marked as grey circles, the blobs as red rings,
// zones as outlines, and tracks as coloured trails with their ids.
//
//   MosaicRenderer mosaic(site, 1280);
//   Image<Rgb8> picture = mosaic.Render(cameras, map, blobs, frame_index, time_s);
//   mosaic.Render(cameras, map, blobs, frame_index, time_s, tracks, trails, picture);  // reused
#pragma once

#include <string>
#include <vector>

#include "occmap/fusion/blobs.h"
#include "occmap/objects/detection.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/site/site.h"
#include "occmap/track/track.h"
#include "occmap/track/track_output.h"
#include "occmap/util/image.h"

namespace occmap {

struct MosaicCamera {
  std::string id;
  ImageView<const uint8_t> gray;     // the frame (or the mask, for mask sources)
  ImageView<const uint8_t> changes;  // 1 = changed; same size as gray
  bool active = true;
};

class MosaicRenderer {
 public:
  MosaicRenderer(const Site& site, int width_px);
  ImageSize size() const { return {width_, height_}; }
  // tracks and trails may be empty (no tracking); zones are drawn as outlines.
  Image<Rgb8> Render(const std::vector<MosaicCamera>& cameras, const OccupancyMap& map,
                     const std::vector<Detection>& blobs, int64_t frame, double time_s,
                     const std::vector<Track>& tracks = {}, const std::vector<Trail>& trails = {}) const;
  // The same into `out`, whose pixels are reused when it has the size already. A run renders
  // a picture per frame set: fresh buffers of a few MB each, taken on one thread and freed on
  // another, fragment the allocator's arenas until a long run's memory creeps up. Not
  // thread-safe (the drawing buffers are the renderer's).
  void Render(const std::vector<MosaicCamera>& cameras, const OccupancyMap& map, const std::vector<Detection>& blobs,
              int64_t frame, double time_s, const std::vector<Track>& tracks, const std::vector<Trail>& trails,
              Image<Rgb8>& out) const;

 private:
  struct Marker {
    std::string label;
    double x_m, y_m;
  };
  FloorGrid grid_;
  std::vector<Marker> markers_;
  std::vector<ZoneOptions> zones_;
  int width_ = 0, height_ = 0;
  int cols_ = 1, tile_w_ = 0, tile_h_ = 0, left_w_ = 0;
  // World -> panel mapping of the map (including camera positions).
  double x0_ = 0, y1_ = 0, px_per_m_ = 1;
  int panel_x_ = 0, panel_y_ = 0;
  // Drawing buffers kept between frames: the BGR canvas and a tile's resized frame and changes.
  mutable std::vector<uint8_t> canvas_, tile_gray_, tile_changes_;
};

}  // namespace occmap
