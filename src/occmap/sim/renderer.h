// CameraRenderer: ray casting of a Scene through one of its cameras' own models.
//
// Every pixel's ray is CameraModel::BackProject(pixel centre) (so lens distortion is real, and
// a pixel with no ray renders black and is never floor). At construction the static set is
// cast once: per pixel the ray, the distance to the first static surface, its radiance (and the
// direct-light part of it, for cast shadows), and the floor mask. Per frame only the moving
// objects are cast: the image is cut into 16 x 16 tiles, each with a cone containing its rays;
// an object is tried in a tile only when its bounding sphere meets the tile's cone, and in a
// pixel only when the ray meets its bounding cylinder before the static surface (depth test).
//
// Output per frame: RGB (radiance x exposure x 255 + Gaussian noise, rounded and clamped) and
// the id buffer: 0 where the pixel sees the static scene, else the id of the moving object it
// sees. The perfect change mask of a camera is ids != 0. Cast shadows (option) darken floor
// pixels but do not change ids: a floor pixel whose ray towards the light meets a moving object
// loses its direct light. On request the shadow mask marks those pixels (255: a moving object's
// shadow darkens the static floor there and no moving object is seen; 0 elsewhere). With
// shadows on, static objects shadow the static scene too, once at construction: such a point
// keeps its ambient light only, and a moving object's shadow over it darkens nothing more (nor
// is it in the shadow mask). Per frame, a tile's floor points are tested only against the
// objects whose shadow region on the floor (under a directional light the exact shadow of the
// object's bounding cylinder, a stadium; under a point light a box) meets the tile's floor box,
// and a point only against those whose region holds it.
//
// Radiance is shading (primitives.h Shade) of the albedo, 0..1 before exposure. Noise: one
// 64-bit hash of (seed, camera, frame, pixel) gives three Gaussian samples (an inverse-CDF table
// of 65536 entries): identical on any number of threads. Exposure drift: gain
// 1 + a sin(2 pi t / period + phase_camera). Backgrounds (empty scene) have gain 1 and, when
// the scene asks for it, noise from their own stream (frame -1).
//
// Contact shadows (scene.h ContactShadowSpec, option): a static floor pixel no moving object
// covers loses part of its ambient light near each object; the shadow mask marks it where that
// removes at least 1/16 of the pixel's radiance (the darkening a detector could see; a fainter
// halo is not marked). Per frame a tile's floor points are tested only against the objects
// whose reach meets the tile's floor box.
//
// A real camera (scene.h CameraResponseSpec::processes_frames): the frame is cast at supersample
// times the image size (the camera model resized by CameraModel::Resized's rule), every output
// pixel the mean radiance of its s x s rays, its id the most frequent moving object's when
// objects cover at least half of them (else 0), its shadow flag the majority's, and its floor
// mask too; then the mean radiance of the frame (pixels with a ray) gives the exposure and white
// balance gains (camera_response.h: from the CameraResponse passed in, frames in order, or the
// frame's settled gains without one); value = gain_c x drift x radiance x 255, plus Gaussian
// noise of variance noise_sigma^2 + read_noise^2 + shot_noise x value, rounded and clamped.
// Backgrounds get the empty view's settled gains (no drift). Without a real camera the path
// and its bits are the ideal camera's above.
//
// TracePixelReference is the plain loop (one ray, every primitive, no cache or culling): the
// oracle of the fast path in tests.
//
//   sim::CameraRenderer renderer(scene, /*camera_index=*/0, ctx);
//   sim::RenderedView view;
//   renderer.Render(scene.StateAt(12), ctx, &view);   // view.rgb, view.ids
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "occmap/sim/camera_response.h"
#include "occmap/sim/scene.h"
#include "occmap/util/image.h"
#include "occmap/util/thread_pool.h"

namespace occmap::sim {

struct RenderedView {
  Image<Rgb8> rgb;
  Image<uint16_t> ids;  // 0 = static scene, else the moving object's id
  // Only when Render is asked for it (else left as it is): 255 where a moving object's cast
  // shadow darkens a static floor pixel that no moving object covers, else 0.
  Image<uint8_t> shadow;
  // The gain applied per channel (exposure x white balance x drift; the ideal camera's drift
  // gain on every channel).
  Eigen::Vector3d gains = Eigen::Vector3d::Ones();
};

// The change mask of a view: 255 where ids != 0, else 0.
Image<uint8_t> ChangeMask(const Image<uint16_t>& ids);

class CameraRenderer {
 public:
  static constexpr int kTilePx = 16;

  // Casts the static scene through camera `camera_index` (rows in parallel on ctx).
  CameraRenderer(const Scene& scene, size_t camera_index, Context& ctx);

  ImageSize size() const { return size_; }
  // 255 where the pixel's ray first meets the floor inside the monitored area (the grid),
  // 0 where it meets walls, furniture, static occluders, floor outside the area, or nothing.
  const Image<uint8_t>& floor_mask() const { return floor_mask_; }
  // The empty scene (no moving objects), exposure gain 1; noise from the background stream
  // when the scene's photometry.background_noise is set and `noise` is true.
  Image<Rgb8> Background(bool noise = true) const;
  // Renders the moving objects of `state` over the static scene; fills out->shadow too when
  // `shadow_mask` is set (all 0 when the scene has no shadows). With a real camera, `response`
  // carries the exposure and white balance from frame to frame (frames in order; nullptr: the
  // frame's settled gains).
  void Render(const SceneState& state, Context& ctx, RenderedView* out, bool noise = true,
              bool shadow_mask = false, CameraResponse* response = nullptr) const;
  // A camera response for this view, before its first frame (the empty view's mean radiance).
  CameraResponse NewResponse() const;

  // The rays cast per pixel along each axis (the scene's camera.supersample).
  int supersample() const { return supersample_; }
  // Pre-noise radiance of the static scene at a pixel of the cast (at supersample x the size).
  Eigen::Vector3f StaticRadiance(int x, int y) const { return bg_[Index(x, y)]; }

 private:
  size_t Index(int x, int y) const {
    return static_cast<size_t>(y) * static_cast<size_t>(render_size_.width) + static_cast<size_t>(x);
  }
  double Gain(double time_s) const;
  uint8_t Quantize(float value, float noise) const;
  // Casts the moving objects of `state` tile by tile (rows of tiles in parallel), calling
  // sink(x, y, index, radiance, id, in_shadow) once per pixel of the cast.
  template <typename Sink>
  void Cast(const SceneState& state, Context& ctx, Sink&& sink) const;
  // A real camera's frame (see above).
  void RenderRealCamera(const SceneState& state, Context& ctx, RenderedView* out, bool noise, bool shadow_mask,
                        CameraResponse* response) const;
  // Linear radiance at the output size: the s x s mean of `cast` (or `cast` itself).
  std::vector<Eigen::Vector3f> AreaMean(const std::vector<Eigen::Vector3f>& cast) const;
  Eigen::Vector3d MeanRadiance(const std::vector<Eigen::Vector3f>& radiance) const;
  void Expose(const std::vector<Eigen::Vector3f>& radiance, const Eigen::Vector3d& gains, bool add_noise,
              uint64_t stream, Context* ctx, Image<Rgb8>* out) const;

  Scene scene_;
  size_t camera_index_ = 0;
  ImageSize size_;         // the image's
  int supersample_ = 1;
  ImageSize render_size_;  // the cast's: supersample_ x size_
  std::vector<uint8_t> out_has_ray_;  // per image pixel: any of its rays (real camera only)
  std::vector<Eigen::Vector3f> ambient_;  // the ambient part of static floor radiance (only with contact shadows)
  Eigen::Vector3d origin_;
  std::vector<Eigen::Vector3d> dir_;  // unit; zero when the pixel has no ray
  std::vector<uint8_t> has_ray_;
  std::vector<double> static_t_;      // +inf: nothing
  std::vector<uint8_t> static_surface_;  // 0 nothing (sky), 1 floor, 2 other static
  std::vector<Eigen::Vector3f> bg_;      // static radiance
  std::vector<Eigen::Vector3f> direct_;  // its direct-light part (only with shadows; 0 where a static object shades it)
  Image<uint8_t> floor_mask_;
  struct TileCone {
    Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
    double half_angle_rad = -1;  // < 0: no rays in the tile
  };
  // The bounding box of a tile's floor points that direct light reaches (only with shadows;
  // lo > hi: none).
  struct TileFloor {
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = Eigen::Vector2d::Constant(-1e300);
  };
  int tiles_x_ = 0, tiles_y_ = 0;
  std::vector<TileCone> tiles_;
  std::vector<TileFloor> tile_floor_;
  std::vector<TileFloor> tile_contact_floor_;  // every static floor point (only with contact shadows)
  Eigen::Vector3d empty_mean_ = Eigen::Vector3d::Zero();  // the empty view's mean radiance (real camera)
  double exposure_phase_rad_ = 0;
};

struct PixelTrace {
  bool has_ray = false;
  uint16_t id = 0;                 // moving object seen, 0 = static
  Surface surface = Surface::kStatic;  // what the ray meets first (kStatic also for nothing)
  bool hit_anything = false;
  Eigen::Vector3f radiance = Eigen::Vector3f::Zero();  // without shadows, exposure or noise
  double t = 0;
};

// The reference: BackProject, then every static and moving primitive of the state.
PixelTrace TracePixelReference(const Scene& scene, size_t camera_index, const SceneState& state,
                               const Eigen::Vector2d& pixel);

// Radiance seen by a ray that meets nothing (sky outdoors, black indoors).
Eigen::Vector3f MissRadiance(const SceneSpec& spec, const Eigen::Vector3d& direction);

}  // namespace occmap::sim
