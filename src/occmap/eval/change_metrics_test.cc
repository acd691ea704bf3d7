#include "occmap/eval/change_metrics.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;

// A mask from rows of text, top row first: '#' 255, 'x' 1 (non-zero counts as set), '.' 0.
Image<uint8_t> Mask(const std::vector<std::string>& rows) {
  Image<uint8_t> mask(static_cast<int>(rows[0].size()), static_cast<int>(rows.size()));
  for (int y = 0; y < mask.height(); ++y) {
    for (int x = 0; x < mask.width(); ++x) {
      const char c = rows[static_cast<size_t>(y)][static_cast<size_t>(x)];
      mask(x, y) = c == '#' ? 255 : c == 'x' ? 1 : 0;
    }
  }
  return mask;
}

void WriteMask(const fs::path& path, const std::vector<std::string>& rows) {
  fs::create_directories(path.parent_path());
  ASSERT_TRUE(WritePng(path, Mask(rows).view()).ok());
}

bool Contains(const std::vector<std::string>& notes, const std::string& note) {
  return std::find(notes.begin(), notes.end(), note) != notes.end();
}

TEST(CountChanges, CountsEveryPixelOnceAndShadowPixelsApart) {
  const Image<uint8_t> run = Mask({"##..", "##.."});
  const Image<uint8_t> gt = Mask({"#.#.", "x..."});
  const Image<uint8_t> shadow = Mask({"...#", ".##."});
  const ChangeCounts c = CountChanges(run.view(), gt.view(), shadow.view());
  EXPECT_EQ(c, (ChangeCounts{.tp = 2, .fp = 2, .fn = 1, .tn = 3, .shadow_pixels = 3, .shadow_changed = 1}));
  const ChangeCounts without_shadow = CountChanges(run.view(), gt.view());
  EXPECT_EQ(without_shadow, (ChangeCounts{.tp = 2, .fp = 2, .fn = 1, .tn = 3}));
}

TEST(CountChanges, WideRowsGiveTheSameCountsAsAPixelLoop) {
  // 1000 x 3 with a pattern that exercises the vectorised per-row sums.
  Image<uint8_t> run(1000, 3), gt(1000, 3), shadow(1000, 3);
  ChangeCounts expected;
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 1000; ++x) {
      run(x, y) = static_cast<uint8_t>((x * 7 + y) % 5 == 0 ? 200 : 0);
      gt(x, y) = static_cast<uint8_t>((x * 3 + y) % 4 == 0 ? 1 : 0);
      shadow(x, y) = static_cast<uint8_t>((x + y) % 6 == 0 ? 255 : 0);
      const bool r = run(x, y) != 0, g = gt(x, y) != 0, s = shadow(x, y) != 0;
      expected.tp += r && g;
      expected.fp += r && !g;
      expected.fn += !r && g;
      expected.tn += !r && !g;
      expected.shadow_pixels += s;
      expected.shadow_changed += s && r;
    }
  }
  EXPECT_EQ(CountChanges(run.view(), gt.view(), shadow.view()), expected);
}

TEST(MakeChangeMetrics, RatiosAreNaNWhenTheirDenominatorIsZero) {
  const ChangeMetrics none = MakeChangeMetrics(1, 0, ChangeCounts{.tn = 4});
  EXPECT_TRUE(std::isnan(none.precision));
  EXPECT_TRUE(std::isnan(none.recall));
  EXPECT_TRUE(std::isnan(none.f1));
  EXPECT_TRUE(std::isnan(none.shadow_changed_fraction));
  // Shadow masks read but empty: still undefined; with pixels: defined even when 0.
  EXPECT_TRUE(std::isnan(MakeChangeMetrics(1, 1, ChangeCounts{.tn = 4}).shadow_changed_fraction));
  EXPECT_EQ(MakeChangeMetrics(1, 1, ChangeCounts{.tn = 4, .shadow_pixels = 2}).shadow_changed_fraction, 0.0);
}

// A run with cameras C1, C2, C3 and a dataset with C1, C2, C4:
//   C1 frame 0: run "##.." / "##..", gt "#.#." / "#...", shadow "...#" / ".##."
//               -> TP 2, FP 2, FN 1, TN 3; shadow 3 pixels, 1 of them changed
//   C1 frame 1: run all unchanged, gt "####" / "...." (no shadow mask) -> FN 4, TN 4
//   C1 frame 2: run only -> not evaluated (a note)
//   C2 frame 0: run "xx" / "##", gt "#x" / ".." (no shadows folder) -> TP 2, FP 2
//   C3 (run only), C4 (dataset only): skipped with notes.
// C1: precision 2/4, recall 2/7, F1 4/11, shadow 1/3. C2: precision 1/2, recall 1, F1 2/3.
// Overall (frames 0 and 1): TP 4, FP 4, FN 5, TN 7: precision 1/2, recall 4/9, F1 8/17.
class ChangeMasksTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const fs::path run = run_changes(), gt = gt_dir();
    WriteMask(run / "C1" / "000000.png", {"##..", "##.."});
    WriteMask(run / "C1" / "000001.png", {"....", "...."});
    WriteMask(run / "C1" / "000002.png", {"....", "...."});
    WriteMask(run / "C2" / "000000.png", {"xx", "##"});
    WriteMask(run / "C3" / "000000.png", {"#"});
    WriteMask(gt / "changes" / "C1" / "000000.png", {"#.#.", "#..."});
    WriteMask(gt / "changes" / "C1" / "000001.png", {"####", "...."});
    WriteMask(gt / "shadows" / "C1" / "000000.png", {"...#", ".##."});
    WriteMask(gt / "changes" / "C2" / "000000.png", {"#x", ".."});
    WriteMask(gt / "changes" / "C4" / "000000.png", {"#"});
  }
  fs::path run_changes() const { return dir_ / "run" / "changes"; }
  fs::path gt_dir() const { return dir_ / "dataset" / "gt"; }

  testing::TempDir dir_;
};

TEST_F(ChangeMasksTest, CountsEachCameraAndTheSumExactly) {
  Context ctx(1);
  std::vector<std::string> notes;
  const Result<ChangeEvaluation> e = EvaluateChangeMasks(run_changes(), gt_dir(), ctx, notes);
  ASSERT_TRUE(e.ok()) << e.status().message();
  ASSERT_EQ(e->cameras.size(), 2u);

  EXPECT_EQ(e->cameras[0].id, "C1");
  const ChangeMetrics& c1 = e->cameras[0].metrics;
  EXPECT_EQ(c1.frames, 2);
  EXPECT_EQ(c1.shadow_frames, 1);
  EXPECT_EQ(c1.counts, (ChangeCounts{.tp = 2, .fp = 2, .fn = 5, .tn = 7, .shadow_pixels = 3, .shadow_changed = 1}));
  EXPECT_DOUBLE_EQ(c1.precision, 0.5);
  EXPECT_DOUBLE_EQ(c1.recall, 2.0 / 7.0);
  EXPECT_DOUBLE_EQ(c1.f1, 4.0 / 11.0);
  EXPECT_DOUBLE_EQ(c1.shadow_changed_fraction, 1.0 / 3.0);

  EXPECT_EQ(e->cameras[1].id, "C2");
  const ChangeMetrics& c2 = e->cameras[1].metrics;
  EXPECT_EQ(c2.frames, 1);
  EXPECT_EQ(c2.counts, (ChangeCounts{.tp = 2, .fp = 2}));
  EXPECT_DOUBLE_EQ(c2.f1, 2.0 / 3.0);
  EXPECT_TRUE(std::isnan(c2.shadow_changed_fraction));  // no shadow masks for C2

  const ChangeMetrics& all = e->overall;
  EXPECT_EQ(all.frames, 2);
  EXPECT_EQ(all.shadow_frames, 1);
  EXPECT_EQ(all.counts, (ChangeCounts{.tp = 4, .fp = 4, .fn = 5, .tn = 7, .shadow_pixels = 3, .shadow_changed = 1}));
  EXPECT_DOUBLE_EQ(all.precision, 0.5);
  EXPECT_DOUBLE_EQ(all.recall, 4.0 / 9.0);
  EXPECT_DOUBLE_EQ(all.f1, 8.0 / 17.0);
  EXPECT_DOUBLE_EQ(all.shadow_changed_fraction, 1.0 / 3.0);
}

TEST_F(ChangeMasksTest, CameraInOnlyOneFolderIsSkippedWithANote) {
  Context ctx(1);
  std::vector<std::string> notes;
  ASSERT_TRUE(EvaluateChangeMasks(run_changes(), gt_dir(), ctx, notes).ok());
  EXPECT_TRUE(Contains(notes, "changes: camera C3 is in the run's changes/ but not in the dataset's gt/changes/; skipped"));
  EXPECT_TRUE(Contains(notes, "changes: camera C4 is in the dataset's gt/changes/ but not in the run's changes/; skipped"));
  EXPECT_TRUE(Contains(notes, "changes: camera C1: 1 masks of the run have no gt/changes mask of their frame; not evaluated"));
  EXPECT_EQ(notes.size(), 3u);
}

TEST_F(ChangeMasksTest, ThreadsGiveTheSameCountsAsOneThread) {
  Context one(1), three(3);
  std::vector<std::string> notes1, notes3;
  const Result<ChangeEvaluation> a = EvaluateChangeMasks(run_changes(), gt_dir(), one, notes1);
  const Result<ChangeEvaluation> b = EvaluateChangeMasks(run_changes(), gt_dir(), three, notes3);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->overall.counts, b->overall.counts);
  ASSERT_EQ(a->cameras.size(), b->cameras.size());
  for (size_t c = 0; c < a->cameras.size(); ++c) EXPECT_EQ(a->cameras[c].metrics.counts, b->cameras[c].metrics.counts);
  EXPECT_EQ(notes1, notes3);
}

TEST_F(ChangeMasksTest, MasksOfDifferentSizesAreAnErrorNamingBothFiles) {
  WriteMask(gt_dir() / "changes" / "C2" / "000000.png", {"#x.", "..."});
  Context ctx(2);
  std::vector<std::string> notes;
  const Result<ChangeEvaluation> e = EvaluateChangeMasks(run_changes(), gt_dir(), ctx, notes);
  ASSERT_FALSE(e.ok());
  EXPECT_EQ(e.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(e.status().message(), (gt_dir() / "changes" / "C2" / "000000.png").string() + ": expected 2x2 pixels like " +
                                      (run_changes() / "C2" / "000000.png").string() + ", found 3x2");
}

TEST_F(ChangeMasksTest, ShadowMaskOfAnotherSizeIsAnErrorToo) {
  WriteMask(gt_dir() / "shadows" / "C1" / "000000.png", {"...#"});
  Context ctx(1);
  std::vector<std::string> notes;
  const Result<ChangeEvaluation> e = EvaluateChangeMasks(run_changes(), gt_dir(), ctx, notes);
  ASSERT_FALSE(e.ok());
  EXPECT_EQ(e.status().message(), (gt_dir() / "shadows" / "C1" / "000000.png").string() +
                                      ": expected 4x2 pixels like " + (run_changes() / "C1" / "000000.png").string() +
                                      ", found 4x1");
}

TEST_F(ChangeMasksTest, MaskThatIsNoPictureIsAnErrorNamingIt) {
  testing::WriteText(run_changes() / "C2" / "000000.png", "");
  Context ctx(2);
  std::vector<std::string> notes;
  const Result<ChangeEvaluation> e = EvaluateChangeMasks(run_changes(), gt_dir(), ctx, notes);
  ASSERT_FALSE(e.ok());
  const std::string path = (run_changes() / "C2" / "000000.png").string();
  EXPECT_EQ(e.status().message(), fmt::format("'{}': empty file, expected an image", path));
  testing::WriteText(run_changes() / "C2" / "000000.png", "not a picture");
  const Result<ChangeEvaluation> e2 = EvaluateChangeMasks(run_changes(), gt_dir(), ctx, notes);
  ASSERT_FALSE(e2.ok());
  EXPECT_EQ(e2.status().message(), fmt::format("'{}': cannot decode image (not a PNG/JPEG/... or truncated)", path));
}

TEST_F(ChangeMasksTest, WithoutShadowMasksTheShadowFractionIsUndefined) {
  fs::remove_all(gt_dir() / "shadows");
  Context ctx(1);
  std::vector<std::string> notes;
  const Result<ChangeEvaluation> e = EvaluateChangeMasks(run_changes(), gt_dir(), ctx, notes);
  ASSERT_TRUE(e.ok()) << e.status().message();
  EXPECT_EQ(e->overall.shadow_frames, 0);
  EXPECT_TRUE(std::isnan(e->overall.shadow_changed_fraction));
  EXPECT_TRUE(std::isnan(e->cameras[0].metrics.shadow_changed_fraction));
  EXPECT_EQ(e->overall.counts.tp, 4);
}

}  // namespace
}  // namespace occmap
