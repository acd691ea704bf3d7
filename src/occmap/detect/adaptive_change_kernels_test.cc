#include "occmap/detect/adaptive_change_kernels.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "occmap/detect/background_model.h"
#include "occmap/util/simd_testing.h"

namespace occmap {
namespace {

class AdaptiveKernels : public KernelSetTest {};
INSTANTIATE_TEST_SUITE_P(KernelSets, AdaptiveKernels, ::testing::Values("portable", "avx2", "avx512"));

// A row's state and inputs, random, with the classes and protections of a busy scene.
struct UpdateRow {
  int width;
  std::vector<uint8_t> fy, prot, cls, prev, rest, fu, fv;
  std::vector<uint16_t> by, steady, bu, bv;
  std::vector<int32_t> set_frame;
  UpdateRowArgs Args(const std::array<int32_t, 256>& inv_y, const std::array<int32_t, 256>* inv_c, int32_t alpha,
                     bool chroma) {
    return {.width = width, .frame_y = fy.data(), .protection = prot.data(), .classes = cls.data(),
            .background_y = by.data(), .previous_y = prev.data(), .steady_frames = steady.data(),
            .set_frame = set_frame.data(), .inv_y = inv_y.data(), .alpha = alpha, .frame = 77,
            .frame_u = chroma ? fu.data() : nullptr, .frame_v = chroma ? fv.data() : nullptr,
            .background_u = chroma ? bu.data() : nullptr, .background_v = chroma ? bv.data() : nullptr,
            .inv_c = inv_c == nullptr ? nullptr : inv_c->data(), .rest = rest.data()};
  }
};

UpdateRow RandomRow(int width, std::mt19937& rng) {
  UpdateRow r;
  r.width = width;
  const size_t n = static_cast<size_t>(width), cn = static_cast<size_t>((width + 1) / 2);
  auto bytes = [&](size_t k, int mod) {
    std::vector<uint8_t> v(k);
    for (auto& b : v) b = static_cast<uint8_t>(rng() % static_cast<unsigned>(mod));
    return v;
  };
  r.fy = bytes(n, 256);
  r.prev = bytes(n, 256);
  r.fu = bytes(cn, 256);
  r.fv = bytes(cn, 256);
  r.rest = bytes(n, 2);
  r.prot.resize(n);
  r.cls.resize(n);
  for (size_t i = 0; i < n; ++i) {
    r.prot[i] = rng() % 4 == 0 ? static_cast<uint8_t>(rng() % 4) : 0;  // mostly free
    r.cls[i] = rng() % 5 == 0 ? static_cast<uint8_t>(rng() % 3) : 0;   // mostly background
  }
  r.by.resize(n);
  r.steady.resize(n);
  r.set_frame.resize(n);
  for (size_t i = 0; i < n; ++i) {
    r.by[i] = static_cast<uint16_t>(rng());
    r.steady[i] = static_cast<uint16_t>(rng() % 100);
    r.set_frame[i] = static_cast<int32_t>(rng() % 3) - 1;
  }
  r.bu.resize(cn);
  r.bv.resize(cn);
  for (size_t i = 0; i < cn; ++i) {
    r.bu[i] = static_cast<uint16_t>(rng());
    r.bv[i] = static_cast<uint16_t>(rng());
  }
  return r;
}

void ExpectSame(const UpdateRow& a, const UpdateRow& b) {
  EXPECT_EQ(a.by, b.by);
  EXPECT_EQ(a.prev, b.prev);
  EXPECT_EQ(a.steady, b.steady);
  EXPECT_EQ(a.set_frame, b.set_frame);
  EXPECT_EQ(a.bu, b.bu);
  EXPECT_EQ(a.bv, b.bv);
  EXPECT_EQ(a.rest, b.rest);
}

// Every width up to past two vectors, chroma rows with and without the fitted colour transfer,
// transfers and time constants that clip and that round both ways.
TEST_P(AdaptiveKernels, UpdateRowEqualsTheReference) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 400; ++trial) {
    const int width = 1 + trial % 150;
    const double gain = 0.5 + static_cast<double>(rng() % 1000) / 500.0, offset = static_cast<double>(rng() % 80) - 40;
    std::array<int32_t, 256> inv_y{}, inv_c{};
    for (int l = 0; l < 256; ++l) {
      inv_y[static_cast<size_t>(l)] = std::clamp(static_cast<int32_t>(std::lround((l - offset) / gain * 256)), 0, 65535);
      inv_c[static_cast<size_t>(l)] = std::clamp(static_cast<int32_t>(std::lround((128 + (l - 128) / gain) * 256)), 0, 65535);
    }
    const int32_t alpha = trial % 7 == 0 ? 32767 : 1 + static_cast<int32_t>(rng() % 2000);
    const bool chroma = trial % 3 != 0;
    const bool fitted = trial % 5 == 0;
    UpdateRow ref = RandomRow(width, rng), fast = ref;
    const int64_t n_ref = UpdateFreeBackgroundRowReference(ref.Args(inv_y, fitted ? nullptr : &inv_c, alpha, chroma));
    const int64_t n_fast = UpdateFreeBackgroundRow(fast.Args(inv_y, fitted ? nullptr : &inv_c, alpha, chroma));
    ASSERT_EQ(n_ref, n_fast) << "trial " << trial;
    ExpectSame(ref, fast);
    if (HasFailure()) FAIL() << "trial " << trial << " width " << width;
  }
}

// Random chroma rows of every width up to past two vectors, thresholds with the weak one off.
TEST_P(AdaptiveKernels, ChromaFlagsRowEqualsTheReference) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 300; ++trial) {
    const int width = 1 + trial % 140, cw = (width + 1) / 2;
    std::vector<uint8_t> fu(static_cast<size_t>(cw)), fv(fu), eu(fu), ev(fu);
    for (auto* v : {&fu, &fv, &eu, &ev}) {
      for (auto& b : *v) b = static_cast<uint8_t>(128 + static_cast<int>(rng() % 60) - 30 + (rng() % 50 == 0 ? 120 : 0));
    }
    const int strong = 1 + static_cast<int>(rng() % 30), weak = trial % 4 == 0 ? 0 : static_cast<int>(rng() % 20);
    std::vector<uint8_t> ref(static_cast<size_t>(width), 9), fast(ref);
    ChromaFlagsRowReference(width, fu.data(), fv.data(), eu.data(), ev.data(), strong, weak, ref.data());
    ChromaFlagsRow(width, fu.data(), fv.data(), eu.data(), ev.data(), strong, weak, fast.data());
    ASSERT_EQ(ref, fast) << "trial " << trial << " width " << width;
  }
}

// Transfers that clip at both ends, clipped background levels, chroma flags of all four kinds.
TEST_P(AdaptiveKernels, ChangeTestRowEqualsTheReference) {
  std::mt19937 rng(13);
  for (int trial = 0; trial < 400; ++trial) {
    const int width = 1 + trial % 150;
    const size_t n = static_cast<size_t>(width);
    std::vector<uint8_t> fy(n), by(n), cc(n);
    for (size_t i = 0; i < n; ++i) {
      fy[i] = static_cast<uint8_t>(rng());
      by[i] = rng() % 8 == 0 ? static_cast<uint8_t>(rng() % 2 == 0 ? 250 + rng() % 6 : rng() % 4) : static_cast<uint8_t>(rng());
      cc[i] = static_cast<uint8_t>(rng() % 4);
    }
    ChangeRowArgs a{.width = width, .frame_y = fy.data(), .background_y = by.data(), .chroma_flags = cc.data(),
                    .gain_q16 = static_cast<int32_t>(65536 * (0.3 + static_cast<double>(rng() % 1000) / 250.0)),
                    .offset_q16 = static_cast<int32_t>(rng() % (160 << 16)) - (80 << 16) + 32768,
                    .threshold = static_cast<int>(rng() % 40), .weak_threshold = static_cast<int>(rng() % 25)};
    std::vector<uint8_t> cls_r(n, 7), out_r(n, 7), weak_r(n, 7), cls_f(n, 7), out_f(n, 7), weak_f(n, 7);
    ChangeRowArgs ref = a, fast = a;
    ref.classes = cls_r.data();
    ref.changes = out_r.data();
    ref.weak = weak_r.data();
    fast.classes = cls_f.data();
    fast.changes = out_f.data();
    fast.weak = weak_f.data();
    ASSERT_EQ(ChangeTestRowReference(ref), ChangeTestRow(fast)) << "trial " << trial;
    ASSERT_EQ(cls_r, cls_f) << "trial " << trial;
    ASSERT_EQ(out_r, out_f) << "trial " << trial;
    ASSERT_EQ(weak_r, weak_f) << "trial " << trial;
  }
}

// Random blobs of changes (some under the seed size, some touching only corner to corner, some
// at the image's edges) with weak pixels around and away from them.
TEST_P(AdaptiveKernels, GrowChangesFromWeakEqualsTheReference) {
  std::mt19937 rng(17);
  Image<uint8_t> seeds, band;  // kept over trials: sizes change, stale contents must not matter
  for (int trial = 0; trial < 120; ++trial) {
    const int w = 1 + static_cast<int>(rng() % 90), h = 1 + static_cast<int>(rng() % 40);
    Image<uint8_t> changes(w, h, 0), weak(w, h, 0), classes(w, h, 0);
    const int blobs = static_cast<int>(rng() % 8);
    for (int k = 0; k < blobs; ++k) {
      const int x0 = static_cast<int>(rng() % static_cast<unsigned>(w)), y0 = static_cast<int>(rng() % static_cast<unsigned>(h));
      const int bw = 1 + static_cast<int>(rng() % 12), bh = 1 + static_cast<int>(rng() % 8);
      for (int y = y0; y < std::min(h, y0 + bh); ++y) {
        for (int x = x0; x < std::min(w, x0 + bw); ++x) {
          if (rng() % 5 != 0) changes(x, y) = 1;
        }
      }
    }
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (changes(x, y) != 0) {
          classes(x, y) = 1;
        } else {
          weak(x, y) = rng() % 3 == 0 ? 1 : 0;
          classes(x, y) = rng() % 10 == 0 ? 2 : 0;  // a shadow: not weak, left as it is
          if (classes(x, y) == 2) weak(x, y) = 0;
        }
      }
    }
    const int steps = static_cast<int>(rng() % 5);
    const int64_t min_seed = 1 + static_cast<int64_t>(rng() % 20);
    Image<uint8_t> changes_f = changes, weak_f = weak, classes_f = classes;
    const int64_t n_ref = GrowChangesFromWeakReference(changes.view(), weak.view(), classes.view(), steps, min_seed);
    const int64_t n_fast =
        GrowChangesFromWeak(changes_f.view(), weak_f.view(), classes_f.view(), steps, min_seed, seeds, band);
    ASSERT_EQ(n_ref, n_fast) << "trial " << trial;
    ASSERT_TRUE(changes == changes_f) << "trial " << trial;
    ASSERT_TRUE(weak == weak_f) << "trial " << trial;
    ASSERT_TRUE(classes == classes_f) << "trial " << trial;
  }
}

// A change of 9 pixels grows into a weak line beside it a pixel per step; a change of 2 pixels
// (under the seed size) and a weak pixel out of reach do not.
TEST(AdaptiveKernelsReference, GrowsFromLargeChangesOnlyAPixelPerStep) {
  Image<uint8_t> changes(12, 5, 0), weak(12, 5, 0), classes(12, 5, 0);
  for (int y = 1; y < 4; ++y) {
    for (int x = 0; x < 3; ++x) changes(x, y) = classes(x, y) = 1;
    for (int x = 3; x < 7; ++x) weak(x, y) = 1;
  }
  changes(10, 0) = changes(11, 0) = classes(10, 0) = classes(11, 0) = 1;
  weak(10, 1) = 1;
  weak(8, 4) = 1;
  const int64_t added = GrowChangesFromWeakReference(changes.view(), weak.view(), classes.view(), 2, 5);
  EXPECT_EQ(added, 6);
  EXPECT_EQ(changes(4, 2), 1);
  EXPECT_EQ(classes(4, 2), 1);
  EXPECT_EQ(weak(4, 2), 0);
  EXPECT_EQ(changes(5, 2), 0) << "beyond two steps";
  EXPECT_EQ(changes(10, 1), 0) << "next to a change under the seed size";
  EXPECT_EQ(changes(8, 4), 0);
}

// The reference is the model's own rule: a free background pixel moves towards the frame by
// alpha / 65536 of the distance (rounded, truncated towards zero), the others stay.
TEST(AdaptiveKernelsReference, FollowsTheFrameOnlyWhereFreeAndUnchanged) {
  std::array<int32_t, 256> inv{};
  for (int l = 0; l < 256; ++l) inv[static_cast<size_t>(l)] = l << 8;
  UpdateRow r;
  r.width = 3;
  r.fy = {200, 200, 0};
  r.prot = {0, BackgroundModel::kPerson, 0};
  r.cls = {0, 0, 0};
  r.prev = {1, 1, 1};
  r.rest = {9, 9, 9};
  r.by = {100 << 8, 100 << 8, 100 << 8};
  r.steady = {5, 5, 5};
  r.set_frame = {-1, -1, 3};
  const int64_t newly = UpdateFreeBackgroundRowReference(r.Args(inv, nullptr, 6554, false));  // 0.1
  EXPECT_EQ(newly, 1);
  EXPECT_EQ(r.by[0], (100 << 8) + (100 * 256 * 6554 + 32768) / 65536);
  EXPECT_EQ(r.by[1], 100 << 8);
  EXPECT_EQ(r.by[2], (100 << 8) + (-100 * 256 * 6554 + 32768) / 65536);  // towards zero
  EXPECT_EQ(r.rest, (std::vector<uint8_t>{0, 1, 0}));
  EXPECT_EQ(r.steady, (std::vector<uint16_t>{0, 5, 0}));
  EXPECT_EQ(r.set_frame, (std::vector<int32_t>{77, -1, 77}));
  EXPECT_EQ(r.prev, (std::vector<uint8_t>{200, 1, 0}));
}

}  // namespace
}  // namespace occmap
