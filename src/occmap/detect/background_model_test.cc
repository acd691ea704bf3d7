#include "occmap/detect/background_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "occmap/util/simd_testing.h"

namespace occmap {
namespace {

// A textured background: levels 40..220 with structure (tiles) and grain.
YuvImage TexturedBackground(int w, int h, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> grain(-6, 6);
  YuvImage b;
  b.y = Image<uint8_t>(w, h);
  b.u = Image<uint8_t>(ChromaPlaneSize(w), ChromaPlaneSize(h));
  b.v = Image<uint8_t>(ChromaPlaneSize(w), ChromaPlaneSize(h));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) b.y(x, y) = static_cast<uint8_t>(40 + ((x / 8 + y / 8) % 6) * 30 + grain(rng) + 6);
  }
  for (int y = 0; y < b.u.height(); ++y) {
    for (int x = 0; x < b.u.width(); ++x) {
      b.u(x, y) = static_cast<uint8_t>(115 + (x / 4) % 3 * 5);
      b.v(x, y) = static_cast<uint8_t>(135 - (y / 4) % 3 * 4);
    }
  }
  return b;
}

uint8_t Clamp(double v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); }

// The background seen with a gain and offset, noise, and chroma scaled by the gain.
YuvImage Seen(const YuvImage& b, double gain, double offset, uint32_t seed, double noise = 1.5) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise);
  YuvImage f = b;
  for (int y = 0; y < b.y.height(); ++y) {
    for (int x = 0; x < b.y.width(); ++x) f.y(x, y) = Clamp(gain * b.y(x, y) + offset + n(rng));
  }
  for (int y = 0; y < b.u.height(); ++y) {
    for (int x = 0; x < b.u.width(); ++x) {
      f.u(x, y) = Clamp(128 + gain * (b.u(x, y) - 128.0));
      f.v(x, y) = Clamp(128 + gain * (b.v(x, y) - 128.0));
    }
  }
  return f;
}

// The background seen by a camera whose exposure and white balance moved: each of R, G, B
// times its gain (util/yuv.h's conversions both ways), with luma noise.
YuvImage SeenRgb(const YuvImage& b, std::array<double, 3> gains, uint32_t seed, double noise = 1.5) {
  Image<Rgb8> rgb = RgbFromYuv(b.view());
  for (int y = 0; y < rgb.height(); ++y) {
    for (int x = 0; x < rgb.width(); ++x) {
      Rgb8& p = rgb(x, y);
      p.r = Clamp(gains[0] * p.r);
      p.g = Clamp(gains[1] * p.g);
      p.b = Clamp(gains[2] * p.b);
    }
  }
  YuvImage f = YuvFromRgb(rgb.view());
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise);
  for (int y = 0; y < f.y.height(); ++y) {
    for (int x = 0; x < f.y.width(); ++x) f.y(x, y) = Clamp(f.y(x, y) + n(rng));
  }
  return f;
}

// Paints a block (luma and its chroma) with a colour.
void Paint(YuvImage& f, int x0, int y0, int x1, int y1, uint8_t y, uint8_t u, uint8_t v) {
  for (int r = y0; r < y1; ++r) {
    for (int c = x0; c < x1; ++c) {
      f.y(c, r) = y;
      f.u(c / 2, r / 2) = u;
      f.v(c / 2, r / 2) = v;
    }
  }
}

TEST(PhotometricTransfer, RecoversGainAndOffsetWithAThirdOfThePixelsCovered) {
  const YuvImage b = TexturedBackground(320, 240, 1);
  YuvImage f = Seen(b, 1.2, 10, 2);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> any(0, 255);
  // People: random blocks covering about a third of the picture.
  for (int k = 0; k < 20; ++k) {
    const int x = static_cast<int>(rng() % 300), y = static_cast<int>(rng() % 200);
    Paint(f, x, y, std::min(320, x + 30), std::min(240, y + 50), static_cast<uint8_t>(any(rng)), 128, 128);
  }
  int covered = 0;
  for (int y = 0; y < 240; ++y) {
    for (int x = 0; x < 320; ++x) covered += f.y(x, y) != Clamp(1.2 * b.y(x, y) + 10) && std::abs(f.y(x, y) - (1.2 * b.y(x, y) + 10)) > 8;
  }
  EXPECT_GT(covered, 320 * 240 / 4);
  const PhotometricTransfer t = EstimateTransfer(b.y.view(), f.y.view());
  EXPECT_NEAR(t.gain, 1.2, 0.03);
  EXPECT_NEAR(t.offset, 10, 3);
  EXPECT_GT(t.samples, 1000);
}

// A floor of few tones: in every 8-level bin of the background three pixels in four are at
// its first level, one at its last. Each bin's point is the mean of the pairs in its densest
// frame window, background and frame alike; the bin's mean background against that window
// (the first tones' frame level) put every point 2.3 levels low and the offset with them.
TEST(PhotometricTransfer, UnevenLevelsWithinABinDoNotBiasTheLine) {
  const int w = 320, h = 240;
  Image<uint8_t> background(w, h), frame(w, h);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 1);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int bin = 3 + static_cast<int>(rng() % 24);
      const int level = 8 * bin + (rng() % 4 == 0 ? 7 : 0);
      background(x, y) = static_cast<uint8_t>(level);
      frame(x, y) = Clamp(1.3 * level - 10 + noise(rng));
    }
  }
  const PhotometricTransfer t = EstimateTransfer(background.view(), frame.view());
  EXPECT_NEAR(t.gain, 1.3, 0.01);
  EXPECT_NEAR(t.offset, -10, 0.8);
}

TEST(PhotometricTransfer, IsTheIdentityWithoutEnoughSpread) {
  Image<uint8_t> flat(64, 64, 100), frame(64, 64, 140);
  const PhotometricTransfer t = EstimateTransfer(flat.view(), frame.view());
  EXPECT_EQ(t.gain, 1);
  EXPECT_EQ(t.offset, 0);
}

TEST(BackgroundLearner, ModeFindsTheFloorWhenPassersByCoverItMoreThanHalfTheTime) {
  const int w = 64, h = 48;
  const YuvImage truth = TexturedBackground(w, h, 5);
  BackgroundLearner learner(w, h, true, 40);
  std::mt19937 rng(6);
  std::uniform_int_distribution<int> bright(230, 255);
  for (int k = 0; k < 40; ++k) {
    YuvImage f = Seen(truth, 1.0, 0, 100 + k, 1.0);
    // 55 % of the samples: the left half is covered by passers-by of random bright clothes.
    if (k % 20 < 11) Paint(f, 0, 0, w / 2, h, static_cast<uint8_t>(bright(rng)), 90, 170);
    learner.Add(f.view());
  }
  const YuvImage mode = learner.Learn(BackgroundLearning::kMode, 6);
  const YuvImage median = learner.Learn(BackgroundLearning::kMedian);
  int mode_bad = 0, median_bad = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w / 2; ++x) {
      mode_bad += std::abs(mode.y(x, y) - truth.y(x, y)) > 4;
      median_bad += std::abs(median.y(x, y) - truth.y(x, y)) > 4;
    }
  }
  EXPECT_EQ(mode_bad, 0);
  EXPECT_GT(median_bad, w * h / 4);  // the median is taken by the crowd
  EXPECT_NEAR(mode.u(4, 4), truth.u(4, 4), 2);
  EXPECT_NEAR(mode.v(4, 4), truth.v(4, 4), 2);
}

TEST(BackgroundLearner, ModeKeepsTheSecondClusterAsTheAlternative) {
  const int w = 32, h = 16;
  const YuvImage truth = TexturedBackground(w, h, 8);
  BackgroundLearner learner(w, h, true, 30);
  for (int k = 0; k < 30; ++k) {
    YuvImage f = Seen(truth, 1.0, 0, 300 + k, 0.5);
    // A person stands on the left half for 24 of the 30 samples.
    if (k >= 6) Paint(f, 0, 0, w / 2, h, 250, 80, 180);
    learner.Add(f.view());
  }
  BackgroundLearner::Alternative alternative;
  const YuvImage mode = learner.Learn(BackgroundLearning::kMode, 6, &alternative);
  EXPECT_EQ(mode.y(3, 3), 250);                                 // the person won the window
  EXPECT_NEAR(alternative.levels.y(3, 3), truth.y(3, 3), 2);    // the floor is the alternative
  EXPECT_EQ(alternative.support(3, 3), 6);
  EXPECT_NEAR(alternative.levels.u(1, 1), truth.u(1, 1), 2);
  EXPECT_EQ(alternative.support(24, 3), 0);                     // the floor alone: no alternative

  // In the model: showing the alternative steadily for relight_s swaps it in, even where the
  // map protects a person (the ghost of a learned-in person who left).
  BackgroundOptions o;
  o.relight_s = 1;
  o.shadows.enabled = false;  // the floor is darker than the person: not a shadow here
  BackgroundModel model(o, 10);
  model.Reset(mode);
  model.SetAlternative(alternative, 3);
  EXPECT_EQ(model.AlternativeLevel(3, 3), alternative.levels.y(3, 3));
  EXPECT_EQ(model.AlternativeLevel(24, 3), -1);
  const YuvImage floor = Seen(truth, 1.0, 0, 400, 0.5);
  Image<uint8_t> changes(w, h), person(w, h, BackgroundModel::kPerson);
  int cleared_at = -1;
  for (int k = 0; k < 30 && cleared_at < 0; ++k) {
    model.DetectChanges(floor.view(), 20, changes.view());
    if (changes(3, 3) == 0) cleared_at = k;
    model.Update(floor.view(), person.view(), k);
  }
  EXPECT_GE(cleared_at, 10);
  EXPECT_LE(cleared_at, 11);
  EXPECT_EQ(model.AlternativeLevel(3, 3), 250);  // the person is the alternative now

  // A person the run saw walk in (kWalkedPerson) who stops there for a minute stays changed:
  // never swapped, never absorbed.
  BackgroundModel walked(o, 10);
  walked.Reset(mode);
  walked.SetAlternative(alternative, 3);
  Image<uint8_t> walked_person(w, h, BackgroundModel::kWalkedPerson);
  for (int k = 0; k < 600; ++k) {
    walked.DetectChanges(floor.view(), 20, changes.view());
    ASSERT_EQ(changes(3, 3), 1) << "frame " << k;
    walked.Update(floor.view(), walked_person.view(), k);
  }
  EXPECT_EQ(walked.AlternativeLevel(3, 3), alternative.levels.y(3, 3));
}

// What a run absorbs (here a person the map lost while they stood: free floor for relight_s)
// keeps the look it replaced as the alternative. When the person leaves, their ghost shows it
// again and is swapped out in relight_s, even where the map takes the ghost for a person;
// without the kept look a ghost protected as a person would stay for ever.
TEST(BackgroundModel, WhatIsAbsorbedKeepsTheLookItReplaced) {
  const int w = 48, h = 32;
  const YuvImage truth = TexturedBackground(w, h, 9);
  BackgroundOptions o;
  o.relight_s = 1;
  o.shadows.enabled = false;
  BackgroundModel model(o, 10);
  model.Reset(truth);
  EXPECT_EQ(model.AlternativeLevel(3, 3), -1);  // given backgrounds: no alternative
  YuvImage standing = Seen(truth, 1.0, 0, 500, 0.5);
  Paint(standing, 0, 0, w / 2, h, 250, 80, 180);
  const YuvImage floor = Seen(truth, 1.0, 0, 501, 0.5);
  Image<uint8_t> changes(w, h), free_floor(w, h, BackgroundModel::kFree), person(w, h, BackgroundModel::kPerson);
  int64_t k = 0;
  for (; k < 12; ++k) {  // lost by the map: absorbed after relight_s
    model.DetectChanges(standing.view(), 20, changes.view());
    model.Update(standing.view(), free_floor.view(), k);
  }
  model.DetectChanges(standing.view(), 20, changes.view());
  EXPECT_EQ(changes(3, 3), 0);
  EXPECT_EQ(model.BackgroundLevel(3, 3), 250);
  EXPECT_NEAR(model.AlternativeLevel(3, 3), truth.y(3, 3), 2);
  EXPECT_EQ(model.AlternativeLevel(40, 3), -1);  // never absorbed: still none
  int cleared_at = -1;
  for (int f = 0; f < 30 && cleared_at < 0; ++f, ++k) {  // they leave; the map calls the ghost a person
    model.DetectChanges(floor.view(), 20, changes.view());
    if (changes(3, 3) == 0) cleared_at = f;
    model.Update(floor.view(), person.view(), k);
  }
  EXPECT_GE(cleared_at, 10);
  EXPECT_LE(cleared_at, 11);
  EXPECT_EQ(model.AlternativeLevel(3, 3), 250);
  // A model started from a given background has no alternative chroma: swapping a kept look
  // exchanges luma alone.
  ASSERT_TRUE(truth.has_chroma());
  const int floor_level = model.BackgroundLevel(2, 2);
  model.SwapWithAlternative(2, 2);
  EXPECT_EQ(model.BackgroundLevel(2, 2), 250);
  EXPECT_EQ(model.AlternativeLevel(2, 2), floor_level);
}

TEST(BackgroundLearner, NormalisesExposureDriftBetweenSamples) {
  const int w = 96, h = 64;
  const YuvImage truth = TexturedBackground(w, h, 7);
  BackgroundLearner learner(w, h, false, 30);
  for (int k = 0; k < 30; ++k) {
    const double gain = 1.0 + 0.15 * std::sin(k * 0.5);
    YuvImage f = Seen(truth, gain, 0, 200 + k, 1.0);
    f.u = Image<uint8_t>();
    f.v = Image<uint8_t>();
    learner.Add(f.view());
  }
  for (BackgroundLearning m : {BackgroundLearning::kMode, BackgroundLearning::kMedian, BackgroundLearning::kMog2,
                               BackgroundLearning::kKnn}) {
    const YuvImage learned = learner.Learn(m, 6);
    ASSERT_FALSE(learned.has_chroma());
    double err = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) err += std::abs(learned.y(x, y) - truth.y(x, y));
    }
    // Within a few levels of the truth (the samples are normalised to a median of mixed gains).
    EXPECT_LT(err / (w * h), 6.0) << ToString(m);
  }
}

TEST(BackgroundModel, ShadowsAreNotChangesButObjectsOfTheSameBrightnessAre) {
  const int w = 32, h = 32;
  YuvImage b;
  b.y = Image<uint8_t>(w, h, 160);
  b.u = Image<uint8_t>(16, 16, 118);
  b.v = Image<uint8_t>(16, 16, 138);
  BackgroundOptions fixed;  // no learning: the test of one frame
  fixed.shadows.learn = false;
  BackgroundModel model(fixed, 10);
  model.Reset(b);
  YuvImage f = b;
  Paint(f, 0, 0, 8, 8, 80, static_cast<uint8_t>(128 + 0.5 * (118 - 128)), static_cast<uint8_t>(128 + 0.5 * (138 - 128)));  // shadow
  Paint(f, 8, 0, 16, 8, 80, 170, 100);   // a blue object as dark as the shadow
  Paint(f, 16, 0, 24, 8, 15, 128, 128);  // black clothes: darker than any shadow
  Paint(f, 24, 0, 32, 8, 220, 118, 138); // brighter: never a shadow
  Image<uint8_t> changes(w, h);
  model.DetectChanges(f.view(), 20, changes.view());
  EXPECT_EQ(changes(2, 2), 0);
  EXPECT_EQ(changes(10, 2), 1);
  EXPECT_EQ(changes(18, 2), 1);
  EXPECT_EQ(changes(26, 2), 1);
  EXPECT_EQ(changes(2, 20), 0);
  EXPECT_NEAR(model.stats().shadow_fraction, 64.0 / (w * h), 1e-9);

  BackgroundOptions no_shadows = fixed;
  no_shadows.shadows.enabled = false;
  BackgroundModel plain(no_shadows, 10);
  plain.Reset(b);
  plain.DetectChanges(f.view(), 20, changes.view());
  EXPECT_EQ(changes(2, 2), 1);
}

// Soft shadows (overcast light, contact shadows): darker by 0.7..0.95 of the floor, its colour
// kept, with no learned look. A tinted patch of that brightness, a darker patch (cast range,
// nothing learned) and a grey-only model (luma cannot tell clothing) are changes.
TEST(BackgroundModel, SoftShadowsKeepTheFloorsColourWithoutALearnedLook) {
  const int w = 32, h = 32;
  YuvImage b;
  b.y = Image<uint8_t>(w, h, 160);
  b.u = Image<uint8_t>(16, 16, 118);
  b.v = Image<uint8_t>(16, 16, 138);
  const auto dim = [](double r, int c) { return static_cast<uint8_t>(std::lround(128 + r * (c - 128))); };
  YuvImage f = b;
  Paint(f, 0, 0, 8, 8, 136, dim(0.85, 118), dim(0.85, 138));       // soft shadow, ratio 0.85
  Paint(f, 8, 0, 16, 8, 136, dim(0.85, 118) + 12, dim(0.85, 138));  // as bright, bluer: clothing
  Paint(f, 16, 0, 24, 8, 80, dim(0.5, 118), dim(0.5, 138));        // a cast shadow's ratio, not learned
  Paint(f, 24, 0, 32, 8, 120, dim(0.75, 118), dim(0.75, 138));     // soft, ratio 0.75
  BackgroundOptions o;  // the defaults: learning, nothing learned yet
  ASSERT_TRUE(o.shadows.soft);
  BackgroundModel model(o, 10);
  model.Reset(b);
  Image<uint8_t> changes(w, h), reference(w, h);
  model.DetectChanges(f.view(), 20, changes.view());
  model.DetectChangesReference(f.view(), 20, reference.view());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) ASSERT_EQ(changes(x, y), reference(x, y)) << x << "," << y;
  EXPECT_EQ(changes(2, 2), 0);
  EXPECT_EQ(model.pixel_classes()(2, 2), BackgroundModel::kSoftShadow);
  EXPECT_EQ(changes(10, 2), 1);
  EXPECT_EQ(changes(18, 2), 1);
  EXPECT_EQ(changes(26, 2), 0);
  EXPECT_EQ(model.pixel_classes()(26, 2), BackgroundModel::kSoftShadow);

  BackgroundOptions off = o;
  off.shadows.soft = false;
  BackgroundModel hard(off, 10);
  hard.Reset(b);
  hard.DetectChanges(f.view(), 20, changes.view());
  EXPECT_EQ(changes(2, 2), 1);
  EXPECT_EQ(changes(26, 2), 1);

  YuvImage grey_b = b, grey_f = f;
  grey_b.u = grey_b.v = grey_f.u = grey_f.v = Image<uint8_t>();
  BackgroundModel grey(o, 10);
  grey.Reset(grey_b);
  grey.DetectChanges(grey_f.view(), 20, changes.view());
  EXPECT_EQ(changes(2, 2), 1);

  BackgroundOptions bad = o;
  bad.shadows.soft_min_ratio = 0.96;
  EXPECT_FALSE(bad.shadows.Validate().ok());
}

TEST(BackgroundModel, HysteresisKeepsAnObjectsFaintEdgeButNotSpecksNoiseOrShadows) {
  const int w = 64, h = 64;
  YuvImage b;
  b.y = Image<uint8_t>(w, h, 160);
  b.u = Image<uint8_t>(32, 32, 118);
  b.v = Image<uint8_t>(32, 32, 138);
  YuvImage f = b;
  Paint(f, 10, 10, 30, 30, 80, 170, 100);  // an object, 400 pixels
  for (int y = 10; y < 30; ++y) {
    for (int x = 30; x < 34; ++x) f.y(x, y) = 173;  // its faint edge, 4 pixels wide, luma only
  }
  Paint(f, 10, 30, 30, 38, 80, static_cast<uint8_t>(128 + 0.5 * (118 - 128)), static_cast<uint8_t>(128 + 0.5 * (138 - 128)));  // its shadow
  Paint(f, 50, 50, 52, 52, 80, 170, 100);  // a speck of 4 pixels
  f.y(52, 50) = f.y(53, 50) = 173;          // and its faint edge
  f.y(50, 20) = 173;                        // faint, alone
  for (int steps : {1, 3}) {
    BackgroundOptions options;
    options.shadows.learn = false;  // the test of one frame
    options.grow_steps_px = steps;
    options.grow_threshold_share = 0.6;           // 12 of 20 levels: 13 is a change next to one
    options.grow_seed_share = 8.0 / (w * h);     // seeds of 8 pixels or more
    BackgroundModel model(options, 10);
    model.Reset(b);
    Image<uint8_t> changes(w, h), reference(w, h);
    model.DetectChanges(f.view(), 20, changes.view());
    model.DetectChangesReference(f.view(), 20, reference.view());
    EXPECT_TRUE(changes == reference);
    EXPECT_EQ(changes(20, 20), 1);
    EXPECT_EQ(changes(30, 20), 1) << steps;
    EXPECT_EQ(changes(31, 20), steps >= 2 ? 1 : 0) << steps;
    EXPECT_EQ(changes(32, 20), steps >= 3 ? 1 : 0) << steps;
    EXPECT_EQ(changes(33, 20), 0) << "beyond the steps";
    EXPECT_EQ(changes(20, 32), 0) << "the shadow is not grown into";
    EXPECT_EQ(changes(50, 50), 1) << "the speck is a change";
    EXPECT_EQ(changes(52, 50), 0) << "but does not grow";
    EXPECT_EQ(changes(50, 20), 0) << "faint alone";
    EXPECT_EQ(changes(8, 20), 0) << "unchanged next to the object";
    int64_t total = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) total += changes(x, y);
    }
    EXPECT_EQ(total, 400 + 20 * steps + 4);
  }
}

TEST(BackgroundModel, AShadowKeepsTheFloorsTextureAndFlatClothesDoNot) {
  const YuvImage b = TexturedBackground(64, 64, 21);  // tiles and grain
  BackgroundOptions with_texture;
  with_texture.shadows.texture_radius_px = 2;
  with_texture.shadows.learn = false;  // one frame
  BackgroundModel model(with_texture, 10);
  model.Reset(b);
  YuvImage f = Seen(b, 1.0, 0, 22, 0.5);
  // Left: a cast shadow (the floor at half its brightness, chroma scaled). Right: flat
  // trousers of the floor's hue and the shadow's brightness.
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 32; ++x) f.y(x, y) = static_cast<uint8_t>(b.y(x, y) / 2);
    for (int x = 32; x < 64; ++x) f.y(x, y) = static_cast<uint8_t>(b.y(24, 24) / 2);
  }
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 32; ++x) {
      f.u(x, y) = static_cast<uint8_t>(128 + (b.u(x, y) - 128) / 2);
      f.v(x, y) = static_cast<uint8_t>(128 + (b.v(x, y) - 128) / 2);
    }
  }
  Image<uint8_t> changes(64, 64);
  model.DetectChanges(f.view(), 20, changes.view());
  int shadow_changed = 0, trousers_changed = 0;
  for (int y = 4; y < 60; ++y) {
    for (int x = 4; x < 28; ++x) shadow_changed += changes(x, y);
    for (int x = 36; x < 60; ++x) trousers_changed += changes(x, y);
  }
  EXPECT_LT(shadow_changed, 56 * 24 / 20);   // under 5 %
  EXPECT_GT(trousers_changed, 56 * 24 / 2);  // most of the trousers (their dark tiles may pass)
}

// A flat grey floor (neutral chroma).
YuvImage GreyFloor(int w, int h, uint8_t level) {
  YuvImage b;
  b.y = Image<uint8_t>(w, h, level);
  b.u = Image<uint8_t>(ChromaPlaneSize(w), ChromaPlaneSize(h), 128);
  b.v = Image<uint8_t>(ChromaPlaneSize(w), ChromaPlaneSize(h), 128);
  return b;
}

// The learned look alone: grey clothes at 0.7 of a grey floor pass the soft-shadow test, which
// leaves them to the floor check (pipeline/background_maintenance.h).
BackgroundOptions CastShadowsOnly() {
  BackgroundOptions o;
  o.shadows.soft = false;
  return o;
}

TEST(BackgroundModel, LearnsTheRatioTheScenesShadowsShare) {
  // Frames whose darker changes are mostly shadows at 0.4 of the lit floor, some dark grey
  // clothes at 0.7: the look settles on 0.4, and the clothes are changes again.
  const int w = 96, h = 64;
  const YuvImage b = GreyFloor(w, h, 200);
  BackgroundModel model(CastShadowsOnly(), 10);
  model.Reset(b);
  YuvImage f = b;
  Paint(f, 0, 0, 64, 64, 80, 128, 128);    // shadow: 0.4
  Paint(f, 64, 0, 80, 64, 140, 128, 128);  // grey clothes: 0.7
  Image<uint8_t> changes(w, h);
  const Image<uint8_t> everyone(w, h, 1);  // every pixel teaches
  for (int k = 0; k < 5; ++k) {
    model.DetectChanges(f.view(), 20, changes.view());
    model.LearnShadows(f.view(), everyone.view());
  }
  EXPECT_EQ(changes(70, 10), 1);
  EXPECT_EQ(changes(10, 10), 0);
  EXPECT_NEAR(model.shadow_look().ratio, 0.4, 0.02);
  Image<uint8_t> reference(w, h);
  model.DetectChangesReference(f.view(), 20, reference.view());
  EXPECT_TRUE(reference == changes);
}

// Only the pixels the map says show the floor teach: clothing that outnumbers the shadows but
// teaches nothing leaves the look on the shadows' ratio.
TEST(BackgroundModel, OnlyTaughtPixelsMoveTheLook) {
  const int w = 96, h = 64;
  const YuvImage b = GreyFloor(w, h, 200);
  BackgroundModel model(CastShadowsOnly(), 10);
  model.Reset(b);
  YuvImage f = b;
  Paint(f, 0, 0, 24, 64, 80, 128, 128);    // shadow: 0.4
  Paint(f, 24, 0, 96, 64, 140, 128, 128);  // grey clothes: 0.7, three times the shadow's area
  Image<uint8_t> teach(w, h, 0);
  for (int y = 0; y < h; ++y) std::fill_n(teach.row(y), 24, uint8_t{1});
  Image<uint8_t> changes(w, h);
  for (int k = 0; k < 40; ++k) {
    model.DetectChanges(f.view(), 20, changes.view());
    model.LearnShadows(f.view(), teach.view());
  }
  EXPECT_NEAR(model.shadow_look().ratio, 0.4, 0.02);
  EXPECT_EQ(changes(10, 10), 0);
  EXPECT_EQ(changes(50, 10), 1);
  // Nothing taught in the first frames: a warm-up's look (here: the clothes') is dropped
  // after three lessons, so that a scene without cast shadows loses no object for long.
  BackgroundModel fresh(CastShadowsOnly(), 10);
  fresh.Reset(b);
  YuvImage clothes = b;
  Paint(clothes, 0, 0, 96, 64, 140, 128, 128);
  fresh.WarmUp({clothes.view(), clothes.view()}, 20);
  fresh.DetectChanges(clothes.view(), 20, changes.view());
  EXPECT_NEAR(fresh.shadow_look().ratio, 0.7, 0.02);
  EXPECT_EQ(changes(50, 10), 0);  // the clothes taken for a shadow meanwhile
  const Image<uint8_t> nobody(w, h, 0);
  int kept = 0;
  for (int k = 0; k < 30; ++k) {
    fresh.LearnShadows(clothes.view(), nobody.view());
    fresh.DetectChanges(clothes.view(), 20, changes.view());
    kept += fresh.shadow_look().ratio > 0;
  }
  EXPECT_EQ(fresh.shadow_look().ratio, 0.0);
  EXPECT_LE(kept, 3);
  EXPECT_EQ(changes(50, 10), 1);
  // A few taught pixels (a scene whose shadows are small in view) keep it for the while the
  // teachers need to gather theirs.
  BackgroundModel few(CastShadowsOnly(), 10);
  few.Reset(b);
  few.WarmUp({clothes.view(), clothes.view()}, 20);
  few.DetectChanges(clothes.view(), 20, changes.view());
  Image<uint8_t> some(w, h, 0);
  for (int y = 0; y < 5; ++y) std::fill_n(some.row(y), w, uint8_t{1});  // 480 pixels a frame
  for (int k = 0; k < 4; ++k) {  // taught mass 1780 by then: under the trusted 2000
    few.LearnShadows(clothes.view(), some.view());
    few.DetectChanges(clothes.view(), 20, changes.view());
  }
  EXPECT_NEAR(few.shadow_look().ratio, 0.7, 0.02);
}

// A learner that took someone's cast shadow for the floor (they stood near for most of the
// window, the lit floor the second cluster) is turned to the lit floor; a dark-clad person of
// another hue, a pixel lit above its alternative, and a model without the shadow test are not.
TEST(BackgroundModel, PreferLitAlternativesUndoesALearnedInShadow) {
  const int w = 32, h = 16;
  const YuvImage lit = GreyFloor(w, h, 180);
  YuvImage learned = lit;
  Paint(learned, 0, 0, 8, h, 72, 128, 128);     // the shadow: 0.4 of the floor, grey
  Paint(learned, 8, 0, 16, h, 72, 100, 170);    // a red coat as dark: another hue
  Paint(learned, 16, 0, 24, h, 220, 128, 128);  // brighter than its alternative
  BackgroundLearner::Alternative alternative;
  alternative.levels = lit;
  alternative.support = Image<uint8_t>(w, h, uint8_t{10});
  for (int y = 0; y < h; ++y) std::fill_n(alternative.support.row(y) + 24, 8, uint8_t{0});  // none
  auto model_with = [&](bool shadows) {
    BackgroundOptions o;
    o.shadows.enabled = shadows;
    auto m = std::make_unique<BackgroundModel>(o, 10);
    m->Reset(learned);
    m->SetAlternative(alternative, 3);
    return m;
  };
  auto model = model_with(true);
  EXPECT_TRUE(model->BackgroundIsShadowOfAlternative(2, 2));
  EXPECT_FALSE(model->BackgroundIsShadowOfAlternative(10, 2));
  EXPECT_EQ(model->PreferLitAlternatives(), 8 * h);
  EXPECT_EQ(model->BackgroundLevel(2, 2), 180);
  EXPECT_EQ(model->AlternativeLevel(2, 2), 72);  // the shadow kept as the alternative
  EXPECT_EQ(model->Current().u(1, 1), 128);
  EXPECT_EQ(model->BackgroundLevel(10, 2), 72);
  EXPECT_EQ(model->BackgroundLevel(18, 2), 220);
  EXPECT_EQ(model->BackgroundLevel(28, 2), 180);
  // The lit floor is no change now, and the shadow back is a shadow, not a change.
  Image<uint8_t> changes(w, h);
  model->DetectChanges(lit.view(), 20, changes.view());
  EXPECT_EQ(changes(2, 2), 0);
  EXPECT_EQ(model_with(false)->PreferLitAlternatives(), 0);
}

TEST(ColourTransfer, RecoversEachChannelsGainWithAThirdOfThePixelsCovered) {
  const YuvImage b = TexturedBackground(200, 150, 3);
  YuvImage f = SeenRgb(b, {1.45, 1.32, 1.15}, 4);
  // People in dark blue over a third of the view.
  for (int k = 0; k < 10; ++k) Paint(f, 20 * k, 40, 20 * k + 8, 150, 45, 150, 120);
  const YuvImage bg = b;
  const ColourTransfer t = EstimateColourTransfer(bg.y.view(), bg.u.view(), bg.v.view(), f.view(), {});
  ASSERT_TRUE(t.fitted);
  EXPECT_NEAR(t.gain[0] * 128 + t.offset[0], 1.45 * 128, 4);
  EXPECT_NEAR(t.gain[1] * 128 + t.offset[1], 1.32 * 128, 4);
  EXPECT_NEAR(t.gain[2] * 128 + t.offset[2], 1.15 * 128, 4);
  // Equal gains are the luma's gain on the chroma (the model without white balance).
  ColourTransfer grey;
  grey.gain = {1.2, 1.2, 1.2};
  grey.offset = {5, 5, 5};
  grey.DeriveChroma();
  EXPECT_NEAR(grey.chroma[0][1], 1.2, 1e-5);
  EXPECT_NEAR(grey.chroma[1][2], 1.2, 1e-5);
  EXPECT_NEAR(grey.chroma[0][0], 0, 1e-5);
  EXPECT_NEAR(grey.chroma[0][2], 0, 1e-5);
  EXPECT_NEAR(grey.chroma_offset[0], 0, 1e-5);
  // Its inverse brings the frame's chroma back.
  const auto back = t.InvertChroma(120, 128 + static_cast<int>(std::lround(t.chroma[0][0] * 120 + t.chroma_offset[0])),
                                   128 + static_cast<int>(std::lround(t.chroma[1][0] * 120 + t.chroma_offset[1])), 1.0);
  EXPECT_NEAR(back[0] / 256.0, 128, 1.5);
  EXPECT_NEAR(back[1] / 256.0, 128, 1.5);
}

// The camera rebalanced its channels as people filled its view: with the transfer per channel
// the floor is no change, while a shirt of another colour at the floor's brightness is.
TEST(BackgroundModel, AWhiteBalanceShiftIsNoChangeButAShirtOfAnotherColourIs) {
  const YuvImage b = TexturedBackground(160, 120, 11);
  // Warmer (no channel clipped: the linear model holds): grey floor's Cb drops by 0.09 of its luma.
  YuvImage f = SeenRgb(b, {1.1, 1.0, 0.85}, 12);
  const int tx = 60, ty = 40;  // a green shirt as bright as the floor under the rebalanced light
  Paint(f, tx, ty, tx + 16, ty + 24, f.y(tx, ty), 100, 100);
  for (bool white_balance : {false, true}) {
    BackgroundOptions options;
    options.white_balance = white_balance;
    BackgroundModel model(options, 10);
    model.Reset(b);
    Image<uint8_t> changes(160, 120);
    model.DetectChanges(f.view(), 20, changes.view());
    int shirt = 0;
    for (int y = ty; y < ty + 24; ++y) {
      for (int x = tx; x < tx + 16; ++x) shirt += changes(x, y);
    }
    EXPECT_GT(shirt, 16 * 24 * 9 / 10) << "white balance " << white_balance;
    if (white_balance) {
      EXPECT_TRUE(model.colour_transfer().fitted);
      EXPECT_LT(model.stats().changed_fraction, 0.05);
    } else {
      EXPECT_GT(model.stats().changed_fraction, 0.2);  // the luma's gain alone leaves the chroma shifted
    }
  }
}

// People who fill much of a view in one colour do not drag the transfer: the pixels the map
// protected in the last frame are left out of the next frame's fits, as long as at least half of
// the samples are left (a map that protects nearly everything, or wrongly after a bad fit, must
// not starve it).
TEST(BackgroundModel, TheTransferLeavesOutWhatTheMapProtected) {
  const int w = 160, h = 120;
  const YuvImage b = TexturedBackground(w, h, 21);
  for (const int covered_x : {72, 120}) {  // 45 % of the view, then 75 %
    YuvImage f = SeenRgb(b, {1.2, 1.2, 1.2}, 22);
    Image<uint8_t> protection(w, h, BackgroundModel::kFree);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < covered_x; ++x) protection(x, y) = BackgroundModel::kPerson;
    }
    // People whose coats follow the floor's levels dimly (0.6 of it): per background level
    // more tightly bunched than the noisy floor, so they, not the floor, are the densest.
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < covered_x; ++x) f.y(x, y) = static_cast<uint8_t>(0.6 * f.y(x, y));
    }
    BackgroundModel model(BackgroundOptions{}, 10);
    model.Reset(b);
    Image<uint8_t> changes(w, h);
    model.DetectChanges(f.view(), 20, changes.view());
    const double dragged = model.transfer().Apply(180);  // without the map (the first frame)
    model.Update(f.view(), protection.view(), 0);
    model.DetectChanges(f.view(), 20, changes.view());
    if (covered_x == 72) {
      // The floor is the densest level of each bin, coats or not; the map's exclusion keeps it.
      EXPECT_NEAR(dragged, 1.2 * 180, 2);
      EXPECT_NEAR(model.transfer().Apply(180), 1.2 * 180, 2);
    } else {
      EXPECT_EQ(model.transfer().Apply(180), dragged);  // too few left: all pixels, as without the map
    }
  }
}

// Every kernel set this CPU has (util/simd.h): the AVX2 row test and the portable one.
class BackgroundModelKernels : public KernelSetTest {};

INSTANTIATE_TEST_SUITE_P(KernelSets, BackgroundModelKernels, ::testing::Values("portable", "avx2"));

TEST_P(BackgroundModelKernels, DetectChangesEqualsItsReference) {
  for (bool chroma : {true, false}) {
    for (uint32_t seed = 0; seed < 4; ++seed) {
      const int w = 77, h = 53;  // odd sizes: the last chroma column and row cover one pixel
      YuvImage b = TexturedBackground(w, h, seed);
      // Odd seeds: the white balance moved too (the colour transfer's chroma rows).
      YuvImage f = seed % 2 == 0 ? Seen(b, 0.9 + 0.05 * seed, 5.0 * seed, 50 + seed, 4.0)
                                 : SeenRgb(b, {1.3, 1.1 + 0.05 * seed, 0.95}, 50 + seed, 4.0);
      std::mt19937 rng(seed);
      for (int k = 0; k < 6; ++k) {
        const int x = static_cast<int>(rng() % 60), y = static_cast<int>(rng() % 40);
        Paint(f, x, y, x + 12, y + 10, static_cast<uint8_t>(rng() % 256), static_cast<uint8_t>(rng() % 256),
              static_cast<uint8_t>(rng() % 256));
        Paint(f, y, x % 40, y + 9, x % 40 + 9, static_cast<uint8_t>(b.y(y, x % 40) / 2), 128, 128);
      }
      if (!chroma) {
        b.u = b.v = f.u = f.v = Image<uint8_t>();
      }
      // The default hysteresis (every change a seed at this size), seeds of 2 % of the image
      // (some of the blocks), none.
      for (const auto& [steps, seed_share] : {std::pair{3, 1e-4}, std::pair{2, 0.02}, std::pair{0, 0.0}}) {
        BackgroundOptions options;
        options.white_balance = true;
        options.grow_steps_px = steps;
        options.grow_seed_share = seed_share;
        BackgroundModel model(options, 10);
        model.Reset(b);
        Image<uint8_t> fast(w, h), reference(w, h);
        model.DetectChanges(f.view(), 18, fast.view());
        model.DetectChangesReference(f.view(), 18, reference.view());
        EXPECT_TRUE(fast == reference) << "chroma " << chroma << " seed " << seed << " steps " << steps;
      }
    }
  }
}

TEST(BackgroundModel, AGlobalStepOfFortyLevelsIsFollowedAtOnce) {
  const YuvImage b = TexturedBackground(160, 120, 9);
  BackgroundModel model(BackgroundOptions{}, 10);
  model.Reset(b);
  YuvImage f = Seen(b, 1.0, 40, 10);
  Image<uint8_t> changes(160, 120);
  model.DetectChanges(f.view(), 20, changes.view());
  EXPECT_LT(model.stats().changed_fraction, 0.01);
  EXPECT_NEAR(model.transfer().offset, 40, 3);
}

// A wall in the sun is clipped at white in the background: when the exposure drops by a tenth,
// the wall may stay clipped (it is brighter than the sensor shows) or come under the clip. Neither
// is a change; a person in front of it is. The fast test and its reference agree.
TEST(BackgroundModel, AWallClippedAtWhiteIsNoChangeWhenTheExposureDrops) {
  YuvImage b = TexturedBackground(160, 120, 5);
  Paint(b, 100, 0, 160, 60, 255, 128, 128);
  for (bool stays_clipped : {true, false}) {
    YuvImage f = Seen(b, 0.9, 0, 6);  // the wall at 229-230: under the clip
    if (stays_clipped) Paint(f, 100, 0, 160, 60, 255, 128, 128);
    Paint(f, 120, 20, 130, 50, 120, 128, 128);  // someone in front of the wall
    BackgroundModel model(BackgroundOptions{}, 10);
    model.Reset(b);
    Image<uint8_t> fast(160, 120), reference(160, 120);
    model.DetectChanges(f.view(), 20, fast.view());
    model.DetectChangesReference(f.view(), 20, reference.view());
    EXPECT_TRUE(fast == reference) << "stays clipped " << stays_clipped;
    EXPECT_NEAR(model.transfer().gain, 0.9, 0.03);
    int wall_changed = 0;
    for (int y = 0; y < 60; ++y) {
      // Away from the person and the hysteresis' band around them.
      for (int x = 100; x < 160; ++x) wall_changed += fast(x, y) != 0 && (x < 116 || x >= 134 || y < 16 || y >= 54);
    }
    EXPECT_EQ(wall_changed, 0) << "stays clipped " << stays_clipped;
    EXPECT_EQ(fast(125, 35), 1);
  }
}

// Frames of a background with one steady block changed; the block's protection as given.
struct UpdateRun {
  BackgroundModel model;
  YuvImage background, frame;
  Image<uint8_t> changes, protection;
  UpdateRun(const BackgroundOptions& o, uint8_t protect)
      : model(o, 10), background(TexturedBackground(64, 64, 11)), changes(64, 64), protection(64, 64, 0) {
    model.Reset(background);
    frame = Seen(background, 1.0, 0, 12, 0.0);
    Paint(frame, 16, 16, 32, 40, 240, 100, 160);
    for (int y = 16; y < 40; ++y) {
      for (int x = 16; x < 32; ++x) protection(x, y) = protect;
    }
  }
  // Runs n frames; returns the frame at which the block stopped being changed, or -1.
  int Run(int n) {
    for (int k = 0; k < n; ++k) {
      model.DetectChanges(frame.view(), 20, changes.view());
      if (changes(20, 20) == 0) return k;
      model.Update(frame.view(), protection.view(), k);
    }
    return -1;
  }
};

TEST(BackgroundModel, APersonStandingStillIsNeverAbsorbed) {
  BackgroundOptions o;
  o.absorb_s = 5;
  UpdateRun run(o, BackgroundModel::kPerson);
  EXPECT_EQ(run.Run(600), -1);  // 60 s at 10 fps
  EXPECT_EQ(run.model.stats().pixels_absorbed, 0);
}

TEST(BackgroundModel, AnObjectLeftStillIsAbsorbedAfterAbsorbS) {
  BackgroundOptions o;
  o.absorb_s = 5;
  UpdateRun run(o, BackgroundModel::kObject);
  const int at = run.Run(600);
  EXPECT_GE(at, 50);
  EXPECT_LE(at, 52);
  EXPECT_EQ(run.model.stats().pixels_absorbed, 16 * 24);
  EXPECT_NEAR(run.model.Current().y(20, 20), 240, 1);
}

TEST(BackgroundModel, AChangeNoObjectExplainsIsBackgroundAfterRelightS) {
  BackgroundOptions o;
  o.relight_s = 2;
  UpdateRun run(o, BackgroundModel::kFree);
  const int at = run.Run(100);
  EXPECT_GE(at, 20);
  EXPECT_LE(at, 22);
}

TEST(BackgroundModel, FreePixelsFollowSlowChangesAndReportTheirAge) {
  BackgroundOptions o;
  o.adapt_s = 2;
  BackgroundModel model(o, 10);
  YuvImage b = TexturedBackground(64, 64, 13);
  b.u = b.v = Image<uint8_t>();
  model.Reset(b);
  YuvImage f = b;
  // The left half brightens by 10 levels (under the threshold): the background follows.
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 32; ++x) f.y(x, y) = static_cast<uint8_t>(b.y(x, y) + 10);
  }
  Image<uint8_t> changes(64, 64), protection(64, 64, 0);
  for (int y = 0; y < 64; ++y) {
    for (int x = 48; x < 64; ++x) protection(x, y) = BackgroundModel::kObject;  // not updated
  }
  for (int k = 0; k < 100; ++k) {
    model.DetectChanges(f.view(), 20, changes.view());
    model.Update(f.view(), protection.view(), k);
  }
  const YuvImage now = model.Current();
  // The transfer takes part of the change as global; the pixels take the rest.
  const double expected_left = model.transfer().Invert(f.y(5, 5));
  EXPECT_NEAR(now.y(5, 5), expected_left, 1.5);
  EXPECT_EQ(now.y(50, 5), b.y(50, 5));
  EXPECT_NEAR(static_cast<double>(model.stats().pixels_updated) / static_cast<double>(model.stats().pixels), 0.75, 1e-9);
  EXPECT_NEAR(model.MeanAgeS(99), 0.25 * 9.9, 0.01);
}

TEST(BackgroundOptions, ValidateNamesTheField) {
  BackgroundOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.learn_samples = 0;
  EXPECT_EQ(o.Validate().message(), "backgrounds.learn_samples: expected 1..255, found 0");
  o = {};
  o.shadows.min_ratio = 0.95;
  EXPECT_EQ(o.Validate().message(),
            "backgrounds.shadows: expected 0 < min_ratio < max_ratio < 1, found min_ratio 0.95 and max_ratio 0.85");
  o = {};
  o.absorb_s = 0;
  EXPECT_EQ(o.Validate().message(), "backgrounds.absorb_s: expected > 0, found 0");
  o = {};
  o.grow_steps_px = 17;
  EXPECT_EQ(o.Validate().message(), "backgrounds.grow_steps_px: expected 0..16 pixels, found 17");
  o = {};
  o.grow_threshold_share = 0;
  EXPECT_EQ(o.Validate().message(), "backgrounds.grow_threshold_share: expected 0 < s <= 1, found 0");
  o = {};
  o.grow_seed_share = 2;
  EXPECT_EQ(o.Validate().message(), "backgrounds.grow_seed_share: expected 0..1, found 2");
  EXPECT_EQ(ParseBackgroundLearning("gmm").status().message(), "expected median, mode, mog2 or knn, found 'gmm'");
  EXPECT_EQ(*ParseBackgroundLearning("knn"), BackgroundLearning::kKnn);
}

}  // namespace
}  // namespace occmap
