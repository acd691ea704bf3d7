// Backgrounds for real scenes: learned from busy video, kept up to date while the run goes on,
// and a change test that tells a cast shadow from an object.
//
// Colour is Y'CbCr, as video decoders give it: luma at full resolution, chroma planes (u = Cb,
// v = Cr) at half the width and height (4:2:0, sizes rounded up), full range, 128 = no colour.
// Chroma is optional: a grey source gives luma alone and every chroma test is skipped.
//
// Three parts, each a plain function or class over images (the pipeline wires them to the
// fused map, pipeline/background_maintenance.h):
// 1. The photometric transfer of a frame: the affine map background -> frame luma
//    (frame ~ gain * background + offset) fitted robustly each frame from each background
//    level's densest frame level over a sparse grid of pixels. Auto-exposure, clouds and lights switched on move every pixel at
//    once; the transfer follows them in one frame, so the per-pixel model does not need to.
// 2. Learning without an empty frame (BackgroundLearner): K frames sampled over a long window,
//    each normalised by its transfer to a provisional median, then one of four estimators:
//    kMedian (per-pixel median), kMode (the centre of the densest cluster of a pixel's samples:
//    what the pixel shows most of the time, even when people cover it for over half of it, as
//    long as no one person stays longer than the floor is seen), kMog2 and kKnn (OpenCV's
//    background subtractors' background images, for comparison).
// 3. BackgroundModel: the per-camera background (luma and chroma, 8.8 fixed point), the change
//    test with shadow suppression, and the update from a per-pixel protection map:
//      - unprotected and unchanged (or shadow): follows the frame with time constant adapt_s
//        (the sun moving, slow local light changes);
//      - unprotected, changed and steady for relight_s: taken as background (a light change no
//        object explains: the fused map sees nothing there);
//      - protected by an object that is not a person, changed and steady for absorb_s: taken
//        as background (a chair pushed and left);
//      - protected by a person: never updated (a person standing still stays a person).
//    What is taken as background keeps the look it replaced as the pixel's alternative (below),
//    so that what was absorbed and leaves (a person the map lost while they stood) is swapped
//    out again in relight_s, like the ghost of a learned-in person.
//
// The shadow test (Cucchiara et al. 2003, Horprasert et al. 1999, in Y'CbCr; the texture test
// as in Sanin et al. 2012): a changed pixel is a cast shadow when it is darker than the
// expected background by a ratio r in [min_ratio, max_ratio], its chroma is the background's
// its R, G and B are each dimmed by about the same ratio (within max_channel_spread: a shadow
// darkens the floor but keeps its colour), and, optionally, its neighbourhood keeps the
// background's texture (normalised cross-correlation of luma; off by default: in deep
// outdoor shadows the floor's texture drowns in noise and compression, and the test then
// rejects shadows and people alike). It fails where clothing is of the floor's hue and darker
// by a shadow's ratio (grey trousers on grey paving); without chroma only the ratio (and
// texture) is tested.
//
//   BackgroundModel model(options, shadows);
//   model.Reset(learned);                                  // a YuvImage
//   model.DetectChanges(frame, threshold, changes.view()); // 1 changed, 0 not
//   model.Update(frame, protection.view(), frame_index);   // after the fusion
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "occmap/util/image.h"
#include "occmap/util/status.h"
#include "occmap/util/yuv.h"

namespace occmap {

// A frame or background in Y'CbCr 4:2:0; u and v empty for grey.
struct YuvView {
  ImageView<const uint8_t> y, u, v;
  bool has_chroma() const { return !u.empty() && !v.empty(); }
};
struct YuvImage {
  Image<uint8_t> y, u, v;
  YuvView view() const {
    if (u.empty()) return {y.view(), {}, {}};
    return {y.view(), u.view(), v.view()};
  }
  bool has_chroma() const { return !u.empty(); }
};
// util/yuv.h's conversion (the frame sources' convention), and back (chroma of a 2 x 2 block
// shared by its pixels), for pictures of a background.
YuvImage YuvFromRgb(ImageView<const Rgb8> rgb);
Image<Rgb8> RgbFromYuv(const YuvView& yuv);

enum class BackgroundLearning { kMedian, kMode, kMog2, kKnn };
const char* ToString(BackgroundLearning method);
Result<BackgroundLearning> ParseBackgroundLearning(std::string_view name);  // message lists the names

struct ShadowOptions {
  bool enabled = true;
  double min_ratio = 0.15;     // a shadow keeps at least this share of the lit brightness
  double max_ratio = 0.85;     // and loses at least 1 - max_ratio of it
  // The scene's shadows are learned (ShadowLook): their ratio, within ratio_window of it, and
  // their colour pattern, each of R, G, B's ratio (less the pixel's mean ratio) within
  // max_channel_spread of it, taught by the pixels LearnShadows is given. Until learned (and
  // in scenes whose taught pixels share no ratio, or are too few: no cast shadows) nothing is
  // a shadow; without learning: any ratio in range, the pattern of white light.
  bool learn = true;
  double ratio_window = 0.2;
  double max_channel_spread = 0.06;
  // Soft shadows, learned or not: under diffuse light (overcast sky, indoors) a body near the
  // floor hides part of the sky and the floor around its feet dims by a ratio that grades from
  // about soft_min_ratio to 1, keeping its colour (the white pattern, or the learned one), with
  // no one ratio for a look to learn. Needs chroma (luma alone cannot tell them from clothing);
  // what a shaded side of a person passes is sent back by the floor check.
  bool soft = true;
  double soft_min_ratio = 0.7;
  double soft_max_ratio = 0.95;
  // Texture: over the (2 r + 1)^2 window around the pixel, a shadow's luma correlates with the
  // background's (normalised cross-correlation >= min_texture_correlation). Where the
  // background is flat (standard deviation under flat_std) texture cannot tell.
  int texture_radius_px = 0;   // 0: no texture test
  double min_texture_correlation = 0.5;
  double flat_std = 3.0;       // grey levels
  // Checked through the floor by the run (pipeline/background_maintenance.h, ShadowCheck): a
  // shadow pixel whose floor cell the other cameras see lit is a change (a person's shaded side).
  bool floor_check = true;
  Status Validate() const;
};

struct BackgroundOptions {
  // The adaptive model (photometric transfer, maintenance, shadow test) instead of the paper's
  // fixed background and plain |I - B| > T.
  bool adaptive = false;
  // Learning, when the site gives no background.
  BackgroundLearning learning = BackgroundLearning::kMode;
  double learn_s = 60;         // the window read at start-up
  // A live stream's learned background (with its alternatives) is written back to its cache
  // entry this often, and at a clean stop, so that a restart takes it as the scene is now
  // (pipeline/camera_inputs.h, BackgroundCacheRefresh); 0: never. Files' entries stay as learned.
  double refresh_cache_s = 300;
  int learn_samples = 60;      // frames sampled evenly over it (at most 255)
  int mode_radius = 6;         // kMode: half-width of a cluster, grey levels (after normalising)
  // kMode: a pixel's second cluster with at least this share of the samples is kept as its
  // alternative background (BackgroundModel::SetAlternative); 0: none.
  double alternative_min_share = 0.1;
  // File sources: before the run, the learning window is run once through the change test, the
  // fusion and the maintenance, and the run starts from the backgrounds as they are at its end
  // (pipeline/settle_backgrounds.h). People who stood from the first frame and left are then
  // floor from the first frame on, not only from when they leave.
  bool settle = true;
  // Maintenance.
  double adapt_s = 30;         // time constant of unprotected, unchanged pixels
  double relight_s = 2;        // unexplained steady changes become background after this
  double absorb_s = 30;        // still objects that are not people become background after this
  double person_height_m = 1.2;  // a detection changed up to this height is a person
  int chroma_threshold = 16;   // Cb/Cr difference that is a change by itself (0: luma only)
  // The photometric transfer per colour channel (ColourTransfer: the camera's white balance
  // follows the scene) rather than the luma's gain for the chroma too; with chroma only. Off by
  // default: on the real terrace footage it removes false chroma changes where a camera
  // rebalances, but the people's edges it also gives back cost the detector 0.01 of MODA.
  bool white_balance = false;
  // Hysteresis: a pixel next to a change (8-connected, repeated grow_steps_px times) is a change
  // at grow_threshold_share of the luma and chroma thresholds. A person's edges, blurred by the
  // lens and the codec, and clothing near the floor's shade fall under the threshold; next to
  // the rest of the person they are kept, while noise away from any change is not. Only changes
  // of at least grow_seed_share of the image grow (not specks such as a shadow's tip), and
  // shadow pixels are not grown into. 0 steps: off.
  int grow_steps_px = 3;
  double grow_threshold_share = 0.6;
  double grow_seed_share = 1e-4;
  ShadowOptions shadows;
  Status Validate() const;
};

// frame ~ gain * background + offset, in luma levels.
struct PhotometricTransfer {
  double gain = 1, offset = 0;
  int samples = 0;  // grid pixels used
  double Apply(double background) const { return gain * background + offset; }
  double Invert(double frame) const { return (frame - offset) / gain; }
};

// The camera's white balance as well as its exposure: frame ~ gain_c * background + offset_c
// for each of R, G and B (full-range BT.601, util/yuv.h), which moves the chroma of grey floor
// in proportion to its brightness when the camera rebalances its channels (a view filled with
// dark clothing). In Y'CbCr it is an affine map of (Y, Cb - 128, Cr - 128); its chroma rows
// give a pixel's expected chroma from its background's luma and chroma. `fitted` false: the
// luma transfer's gain applied to the chroma alone (a grey camera, or too few samples).
struct ColourTransfer {
  bool fitted = false;
  std::array<double, 3> gain{1, 1, 1}, offset{0, 0, 0};  // R, G, B
  // Cb - 128 and Cr - 128 of the frame = chroma[k][0] Y + chroma[k][1] (Cb - 128) +
  // chroma[k][2] (Cr - 128) + chroma_offset[k] of the background (k = 0: Cb, 1: Cr).
  std::array<std::array<double, 3>, 2> chroma{{{0, 1, 0}, {0, 0, 1}}};
  std::array<double, 2> chroma_offset{0, 0};
  int samples = 0;  // chroma blocks used
  // From per-channel gains and offsets (the fields above them).
  void DeriveChroma();
  // The background's chroma (8-bit Cb, Cr) of a frame's chroma given the background's luma: the
  // inverse of the chroma rows (luma's gain alone when not fitted), in 8.8 fixed point, clamped.
  std::array<int32_t, 2> InvertChroma(int background_y, int u, int v, double luma_gain) const;
};
// Fitted from the chroma blocks of a grid of step_px pixels, where `exclude` is zero (when not
// empty: the pixels the fused map protected in the last frame, people and objects, so that a
// view filling with people does not drag the fit), the block's top-left luma with its chroma
// taken as one RGB pixel of the background and of the frame: per channel the per-level densest
// line of EstimateTransfer. Not fitted when a channel has fewer than two usable bins, or when the
// channels moved alike (grey floor's chroma moves by less than 3 levels from 64 to 192 of luma:
// exposure alone, which the luma's gain models).
ColourTransfer EstimateColourTransfer(ImageView<const uint8_t> background_y, ImageView<const uint8_t> background_u,
                                      ImageView<const uint8_t> background_v, const YuvView& frame,
                                      ImageView<const uint8_t> exclude, int step_px = 4);
// Fitted from the pixels of a grid of step_px: per background level bin (8 levels) the centre
// of the densest 9-level window of frame levels (not the median: people of many shades who
// cover more than half of a floor level's pixels leave the floor the densest), then a weighted
// least-squares line through them, refitted without the bins further than 12 levels from it.
// Background levels under 8 or over 247 and bins whose densest level is clipped (under 5, over
// 250) are left out. Identity when fewer than two
// bins have enough pixels.
PhotometricTransfer EstimateTransfer(ImageView<const uint8_t> background_y, ImageView<const uint8_t> frame_y,
                                     int step_px = 4, ImageView<const uint8_t> exclude = {});

// Learns a background from frames of a busy scene (see the top of this file).
class BackgroundLearner {
 public:
  BackgroundLearner(int width, int height, bool chroma, int expected_samples);
  // Same size as given to the constructor (a CHECK); chroma when constructed with it.
  void Add(const YuvView& frame);
  int count() const { return count_; }
  // Sample k (0 <= k < count()), as added.
  YuvView Sample(int k) const;
  // Needs at least one frame (a CHECK). mode_radius is used by kMode. With kMode and
  // `alternative`, also each pixel's second densest cluster of samples (outside the first
  // cluster's levels) and in alternative->support its number of samples (0: none): what the
  // pixel showed for a while when it did not show its background, such as the floor beside a
  // person who stood most of the window (see BackgroundModel::SetAlternative).
  struct Alternative {
    YuvImage levels;
    Image<uint8_t> support;
  };
  YuvImage Learn(BackgroundLearning method, int mode_radius = 6, Alternative* alternative = nullptr) const;

 private:
  int width_, height_, cw_, ch_;
  bool chroma_;
  int count_ = 0;
  std::vector<uint8_t> y_, u_, v_;  // frame-major samples
};

// What a scene's cast shadows look like to a camera, learned from its frames: the brightness
// ratio that the darker changed pixels share (the mode of their ratios: a scene's shadows share
// one, clothing spreads over all) and their colour pattern (the share of the mean ratio each
// of R, G, B keeps, less their mean: 0, 0, 0 under white light, more blue under a blue sky).
struct ShadowLook {
  double ratio = 0;                          // 0: not learned yet
  std::array<float, 3> pattern{0, 0, 0};     // R, G, B ratios less their mean
  double mass = 0;                           // decayed count of the pixels it was learned from
  double peak_share = 0;                     // of them at the ratio's mode (6 % wide)
};

// What the change test found in the last frame, and what the updates did over the run.
struct BackgroundStats {
  int64_t frames = 0;
  double changed_fraction = 0;  // of the last frame's pixels
  double shadow_fraction = 0;   // changed in luma but explained as a shadow, last frame
  PhotometricTransfer transfer; // of the last frame
  int64_t pixels_updated = 0;   // pixels updated at least once since Reset
  int64_t pixels_absorbed = 0;  // absorptions (relight or still objects), counted per pixel event
  int64_t pixels = 0;
};

class BackgroundModel {
 public:
  // Protection values of Update's map, by rank (a pixel several people cover takes the highest).
  // kPerson: never updated. kWalkedPerson: a person the run saw walk in, so the floor under
  // them is known; never updated and never swapped with the alternative either.
  static constexpr uint8_t kFree = 0, kObject = 1, kPerson = 2, kWalkedPerson = 3;
  // Background levels taken as clipped at white or black (ExpectedLuma below).
  static constexpr int kClippedWhite = 250, kClippedBlack = 3;

  BackgroundModel(const BackgroundOptions& options, double fps);
  // Starts from a background (chroma optional; the frames must then have it too).
  void Reset(const YuvImage& background);
  // The learner's second clusters (after Reset). A changed pixel that shows its alternative
  // steadily for relight_s swaps it with its background unless the map marks it kWalkedPerson:
  // a person who stood through the learning window and then left is background again (otherwise
  // their ghost would stand as a person for ever), while a person seen walking in to stand where
  // the learner took them for the floor stays a person. Alternatives with fewer than
  // min_support samples are ignored. Update also keeps, as a pixel's alternative, the look that
  // each absorption replaces.
  void SetAlternative(const BackgroundLearner::Alternative& alternative, int min_support);
  // Pixel (x, y)'s background luma (8-bit), and its alternative's or -1 when it has none.
  int BackgroundLevel(int x, int y) const { return std::min(255, (by_[Index(x, y)] + 128) >> 8); }
  int AlternativeLevel(int x, int y) const { return alt_valid_[Index(x, y)] ? alt_y_[Index(x, y)] : -1; }
  // Pixel (x, y)'s background chroma (Cb, Cr, 8-bit, its 2 x 2 block's), and its alternative's;
  // 128, 128 without chroma.
  std::array<int, 2> BackgroundChroma(int x, int y) const;
  std::array<int, 2> AlternativeChroma(int x, int y) const;
  bool has_chroma() const { return chroma_; }
  // Exchanges (x, y)'s background and alternative (its chroma block's too when (x, y) is the
  // block's top-left pixel). No-op without an alternative.
  void SwapWithAlternative(int x, int y);
  // Forgets (x, y)'s alternative: which of the two is the floor has been decided.
  void DropAlternative(int x, int y) { alt_valid_[Index(x, y)] = 0; }
  // Whether (x, y)'s background looks like its alternative under a cast shadow: darker by a
  // ratio in the shadow test's range, of about the same chroma.
  bool BackgroundIsShadowOfAlternative(int x, int y) const;
  // Swaps every pixel whose background is its alternative's shadow (with the shadow test on):
  // the learner took for the floor the shadow of someone who stood near, which every camera saw
  // alike, so the cross-camera check cannot undo it; dark clothing of a standing person looks
  // the same and is undone too. Taking the lit cluster is the safe side: the shadow, when it is
  // back, is a shadow to the change test, while a shadow taken for the floor makes the lit floor
  // a change. Returns the pixels swapped.
  int64_t PreferLitAlternatives();

  int width() const { return width_; }
  int height() const { return height_; }
  bool empty() const { return width_ == 0; }

  // The background now, 8-bit (for pictures and saving).
  YuvImage Current() const;
  // The alternatives now (after SetAlternative), as the learner gives them: each pixel's level
  // (its chroma block's), with `support` where the pixel has one and 0 where it has none, so
  // that SetAlternative(CurrentAlternative(s), m) with m <= s restores them.
  BackgroundLearner::Alternative CurrentAlternative(uint8_t support) const;

  // Runs the change test over frames without keeping their changes: the shadow look (and the
  // transfer) learned from them before the first frame of a run.
  void WarmUp(const std::vector<YuvView>& frames, int threshold);
  // Estimates the frame's transfer, then writes 1 where the pixel changed, 0 elsewhere.
  // Shadows are 0 in `changes`; the classes are kept for Update.
  void DetectChanges(const YuvView& frame, int threshold, ImageView<uint8_t> changes);
  // The plain per-pixel loop of DetectChanges (no tables), for tests: the same output.
  void DetectChangesReference(const YuvView& frame, int threshold, ImageView<uint8_t> changes) const;

  // After the fusion, before Update: the frame's pixels that teach the shadow look (non-zero:
  // the pixel shows the floor darkened, as the map's cameras agree; pipeline/
  // background_maintenance.h, ShadowTeachers). Until the first call, the warm-up's look (taught
  // by every darker pixel) is used; from it on only taught pixels count, and a look they do not
  // confirm within the first seconds is dropped.
  void LearnShadows(const YuvView& frame, ImageView<const uint8_t> teach);
  // The last DetectChanges' class per pixel: kBackground, kChanged, kShadow or kSoftShadow; and, where it is
  // not kBackground, the frame/background brightness ratio x 255 of a pixel darker within the
  // shadows' range, else 0 (with the shadow test on).
  ImageView<const uint8_t> pixel_ratios() const { return {ratio_.data(), width_, height_, width_}; }
  ImageView<const uint8_t> pixel_classes() const { return {class_.data(), width_, height_, width_}; }
  // kSoftShadow: a soft shadow (ShadowOptions::soft), which the floor check keeps only where
  // another camera confirms its floor cell dark.
  enum Class : uint8_t { kBackground = 0, kChanged = 1, kShadow = 2, kSoftShadow = 3 };

  // After the fusion: protection per pixel (kFree, kObject, kPerson, kWalkedPerson), the
  // frame's index.
  void Update(const YuvView& frame, ImageView<const uint8_t> protection, int64_t frame_index);

  const BackgroundStats& stats() const { return stats_; }
  // Mean over pixels of the time since each was last set (learning counts as a set at the
  // first updated frame), at frame_index.
  double MeanAgeS(int64_t frame_index) const;
  const PhotometricTransfer& transfer() const { return transfer_; }
  const ColourTransfer& colour_transfer() const { return colour_; }
  const ShadowLook& shadow_look() const { return look_; }

 private:
  size_t Index(int x, int y) const { return static_cast<size_t>(y) * static_cast<size_t>(width_) + static_cast<size_t>(x); }

  // eu, ev: the pixel's expected chroma (ExpectedChroma).
  uint8_t Classify(int y, int u, int v, int by, int eu, int ev, int threshold) const;
  // Pixel (x, y)'s frame levels, its background's 8-bit luma and its expected chroma (128
  // without chroma).
  struct PixelLevels {
    int y, u, v, by, eu, ev;
  };
  PixelLevels LevelsAt(const YuvView& frame, int x, int y) const;
  // The thresholds of the hysteresis, from the detection's (at least 1 level; chroma 0: none).
  int GrowThreshold(int threshold) const;
  int64_t GrowSeedMinPixels() const;
  // Whether a pixel is changed at the hysteresis' thresholds (tl luma, tcl chroma), from its
  // frame values and its background's 8-bit levels, under the current transfer.
  bool WeakChange(int y, int u, int v, int by, int eu, int ev, int tl, int tcl) const;
  // A chroma block's expected frame chroma under the current transfer, from its background's
  // chroma (8-bit) and the luma of its top-left pixel; the same in the fast and the reference test.
  std::array<int, 2> ExpectedChroma(int block_y, int bu, int bv) const;
  // ExpectedChroma of every chroma block into expected_u_, expected_v_.
  void ExpectChroma();
  // The hysteresis over DetectChanges' output, classes and weak pixels; returns the pixels added.
  int64_t GrowChanges(ImageView<uint8_t> changes);
  // The colour part of the shadow test for a darker pixel; adds it to the learning sums when
  // `learn` is given. A frame's sums are applied at the start of the next DetectChanges, so
  // that the look a frame was tested with stays the model's until then (the reference test
  // reads it).
  static constexpr int kRatioBins = 50;  // the shadow ratio histogram over [0, 1)
  struct ShadowLearning {
    std::array<double, kRatioBins> histogram{};
    std::array<double, 3> pattern_sum{};
    double pattern_count = 0;
    bool pending = false;
  };
  bool FitsShadowLook(int y, int u, int v, int ey, int eu, int ev, ShadowLearning* learn) const;
  // The soft-shadow test (ShadowOptions::soft) of a darker pixel within its ratio range.
  bool FitsSoftShadow(int y, int u, int v, int ey, int eu, int ev) const;
  void LearnShadowLook(const ShadowLearning& frame);
  // The texture part of the shadow test at (x, y).
  bool TextureLikeBackground(ImageView<const uint8_t> frame_y, int x, int y) const;

  BackgroundOptions options_;
  double fps_;
  int width_ = 0, height_ = 0, cw_ = 0, ch_ = 0;
  bool chroma_ = false;
  std::vector<uint16_t> by_, bu_, bv_;   // 8.8 fixed point
  std::vector<uint8_t> class_;           // Class per luma pixel, last frame
  std::vector<uint8_t> ratio_;           // see pixel_ratios()
  std::vector<uint8_t> prev_y_;          // last frame's luma (steadiness)
  std::vector<uint16_t> steady_frames_;  // frames changed and steady in a row
  std::vector<uint8_t> alt_y_;            // the alternative background's luma, 0 when none
  std::vector<uint8_t> alt_valid_;
  std::vector<uint8_t> alt_u_, alt_v_;     // its chroma
  std::vector<uint16_t> alt_frames_;      // frames changed and showing the alternative in a row
  std::vector<int32_t> set_frame_;       // frame of the last set (-1: learning)
  int64_t first_frame_ = -1;             // of the first Update since Reset
  int64_t pixels_updated_ = 0;           // pixels whose set_frame_ is >= 0
  void MarkSet(size_t i, int32_t frame) {
    pixels_updated_ += set_frame_[i] < 0;
    set_frame_[i] = frame;
  }
  Image<uint8_t> bg8_;                   // the luma background in 8 bits, for the transfer
  PhotometricTransfer transfer_;
  int threshold_ = 0;  // of the last DetectChanges
  ColourTransfer colour_;                // of the last frame (fitted with white_balance and chroma)
  Image<uint8_t> bgu8_, bgv8_;           // the chroma background in 8 bits, for its fit
  std::vector<uint8_t> expected_u_, expected_v_;  // per chroma block, the last frame's
  // Pixels the last Update's map protected (people, objects): left out of the transfers' fits.
  Image<uint8_t> fit_exclude_;
  bool have_exclude_ = false;
  // The transfer in 16.16 fixed point (the offset with the rounding half added): the expected
  // luma of a background level, the same in the fast and the reference test.
  int32_t gain_q16_ = 65536, offset_q16_ = 32768;
  // A background clipped at white (or black) hides how bright the scene is there: an exposure
  // turned down may leave it clipped, or bring it under. Expected: halfway between the transfer's
  // value and the clip, so that either is within a threshold of it (a white wall in the sun).
  int ExpectedLuma(int level) const {
    const int e = std::clamp((gain_q16_ * level + offset_q16_) >> 16, 0, 255);
    if (level >= kClippedWhite) return (e + 256) >> 1;
    if (level <= kClippedBlack) return e >> 1;
    return e;
  }
  std::vector<uint8_t> chroma_changed_;  // per pixel of the current chroma row
  std::vector<uint8_t> update_rest_;     // Update: the pixels of the row its kernel left to it
  Image<uint8_t> grow_seeds_, grow_band_;  // GrowChanges: the changes that grow, dilated by a pixel
  Image<uint8_t> grow_weak_;               // DetectChanges' weak pixels (changes at the grow thresholds)
  ShadowLook look_;
  std::vector<double> ratio_histogram_;  // decayed, over [0, 1)
  ShadowLearning learning_;              // the last frame's sums
  bool warming_up_ = false;              // in WarmUp: every darker pixel teaches the look
  int64_t shadow_lessons_ = 0;           // LearnShadows calls since Reset
  BackgroundStats stats_;
  // Tables of the last frame's transfer, per background level.
  int pred_[256];          // expected frame luma
  int shadow_lo_[256], shadow_hi_[256];  // luma range of a shadow
  int soft_lo_[256], soft_hi_[256];      // luma range of a soft shadow (empty: off)
};

}  // namespace occmap
