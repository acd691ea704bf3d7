#include "occmap/io/frame_source.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"
#include "occmap/util/yuv.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

using Kind = FrameSourceSpec::Kind;

constexpr int kWidth = 32, kHeight = 24;

// A grey picture whose pixels all carry `value` except a gradient in row 0 (so that a wrong
// decode would not go unnoticed).
Image<uint8_t> Picture(uint8_t value, int width = kWidth, int height = kHeight) {
  Image<uint8_t> image(width, height, value);
  for (int x = 0; x < width; ++x) image(x, 0) = static_cast<uint8_t>(x);
  return image;
}

void WritePicture(const fs::path& path, uint8_t value, int width = kWidth, int height = kHeight) {
  ASSERT_TRUE(WritePng(path, Picture(value, width, height).view()).ok()) << path;
}

Result<std::unique_ptr<FrameSource>> Open(Kind kind, const fs::path& location, FrameSourceOptions options = {}) {
  return OpenFrameSource({kind, location.string()}, options);
}

// Reads to the end and returns the centre value of each frame; fails the test on an error.
std::vector<int> CentreValues(FrameSource& source, std::vector<int64_t>* indices = nullptr) {
  std::vector<int> values;
  Frame frame;
  while (true) {
    auto got = source.Read(frame);
    if (!got.ok()) {
      ADD_FAILURE() << got.status().message();
      break;
    }
    if (!*got) break;
    values.push_back(frame.gray(frame.gray.width() / 2, frame.gray.height() / 2));
    if (indices != nullptr) indices->push_back(frame.index);
  }
  return values;
}

TEST(ImageSequence, PatternStartingAtZeroReadsUntilTheFirstMissingFile) {
  testing::TempDir dir;
  for (int i : {0, 1, 2, 3, 4, 6}) WritePicture(dir / fmt::format("f_{:03d}.png", i), static_cast<uint8_t>(10 * i));
  const fs::path pattern = dir / "f_%03d.png";
  auto source = Open(Kind::kImages, pattern);
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->Describe(), fmt::format("image sequence '{}' (from 0, 32x24)", pattern.string()));
  EXPECT_EQ((*source)->size(), (ImageSize{kWidth, kHeight}));
  EXPECT_EQ((*source)->frame_count(), std::nullopt);
  EXPECT_EQ((*source)->fps(), std::nullopt);
  std::vector<int64_t> indices;
  EXPECT_EQ(CentreValues(**source, &indices), (std::vector<int>{0, 10, 20, 30, 40}));
  EXPECT_EQ(indices, (std::vector<int64_t>{0, 1, 2, 3, 4}));
}

TEST(ImageSequence, PatternStartingAtOneIsFoundAndNumberedFromZero) {
  testing::TempDir dir;
  for (int i : {1, 2, 3}) WritePicture(dir / fmt::format("c{}.png", i), static_cast<uint8_t>(100 + i));
  auto source = Open(Kind::kImages, dir / "c%d.png");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->Describe(), fmt::format("image sequence '{}' (from 1, 32x24)", (dir / "c%d.png").string()));
  std::vector<int64_t> indices;
  EXPECT_EQ(CentreValues(**source, &indices), (std::vector<int>{101, 102, 103}));
  EXPECT_EQ(indices, (std::vector<int64_t>{0, 1, 2}));
}

TEST(ImageSequence, PatternWithAFrameAtNeitherZeroNorOneIsNotFound) {
  testing::TempDir dir;
  WritePicture(dir / "f_2.png", 1);
  auto source = Open(Kind::kImages, dir / "f_%d.png");
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(source.status().message(),
            fmt::format("no frame found for pattern '{}': expected '{}' or '{}'", (dir / "f_%d.png").string(),
                        (dir / "f_0.png").string(), (dir / "f_1.png").string()));
}

TEST(ImageSequence, PatternFlagsWidthsAndLiteralPercentFormatLikePrintf) {
  testing::TempDir dir;
  WritePicture(dir / "50%_  0.png", 7);
  WritePicture(dir / "50%_  1.png", 8);
  WritePicture(dir / "p_0000.png", 9);
  WritePicture(dir / "q_1  .png", 11);
  auto source = Open(Kind::kImages, dir / "50%%_%3d.png");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ(CentreValues(**source), (std::vector<int>{7, 8}));
  source = Open(Kind::kImages, dir / "p_%.4lld.png");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ(CentreValues(**source), (std::vector<int>{9}));
  source = Open(Kind::kImages, dir / "q_%-3u.png");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ(CentreValues(**source), (std::vector<int>{11}));
}

TEST(ImageSequence, BadPatternsAreRejectedWithMessages) {
  testing::TempDir dir;
  const std::string d = dir.path().string();
  const std::string expected =
      "expected a printf-style pattern with exactly one integer conversion such as "
      "'frame_%06d.png', found";
  const struct {
    std::string pattern;
    std::string message;
  } cases[] = {
      {"%d%d.png", fmt::format("'{}/%d%d.png': {} more than one conversion", d, expected)},
      {"f_%s.png", fmt::format("'{}/f_%s.png': {} the non-integer conversion '%s'", d, expected)},
      {"f_%+d.png", fmt::format("'{}/f_%+d.png': {} the unsupported flag '+' in '%+'", d, expected)},
      {"f_%100d.png", fmt::format("'{}/f_%100d.png': {} a width or precision above 64", d, expected)},
      {"f_%06", fmt::format("'{}/f_%06': {} an unfinished conversion '%06' at the end", d, expected)},
      {"100%%.png", fmt::format("'{}/100%%.png': {} no conversion", d, expected)},
      {"no_conversion.png",
       fmt::format("'{}/no_conversion.png': not found: expected an image file, a folder, or a printf-style pattern "
                   "with one integer conversion such as 'frame_%06d.png'",
                   d)},
  };
  for (const auto& c : cases) {
    auto source = Open(Kind::kImages, dir / c.pattern);
    ASSERT_FALSE(source.ok()) << c.pattern;
    EXPECT_EQ(source.status().message(), c.message);
  }
}

TEST(ImageSequence, FolderIsReadInNameOrderSkippingOtherFiles) {
  testing::TempDir dir;
  WritePicture(dir / "b.png", 2);
  WritePicture(dir / "a.png", 1);
  WritePicture(dir / "d.jpeg", 4);  // PNG bytes: the decoder goes by content, the listing by name
  WritePicture(dir / "c.PNG", 3);
  testing::WriteText(dir / "notes.txt", "not an image");
  fs::create_directory(dir / "sub.png");
  auto source = Open(Kind::kImages, dir.path());
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->Describe(), fmt::format("image folder '{}' (4 files, 32x24)", dir.path().string()));
  EXPECT_EQ((*source)->frame_count(), 4);
  EXPECT_EQ(CentreValues(**source), (std::vector<int>{1, 2, 3, 4}));
}

TEST(ImageSequence, FolderWithoutImagesIsAnError) {
  testing::TempDir dir;
  testing::WriteText(dir / "notes.txt", "not an image");
  auto source = Open(Kind::kImages, dir.path());
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().message(),
            fmt::format("'{}': expected a folder with .png/.jpg/.jpeg files, found none", dir.path().string()));
}

TEST(ImageSequence, SingleFileIsAOneFrameSequence) {
  testing::TempDir dir;
  WritePicture(dir / "one.png", 42);
  auto source = Open(Kind::kImages, dir / "one.png");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->Describe(), fmt::format("image '{}' (32x24)", (dir / "one.png").string()));
  EXPECT_EQ((*source)->frame_count(), 1);
  Frame frame;
  ASSERT_TRUE(*(*source)->Read(frame));
  EXPECT_TRUE(frame.gray == Picture(42));
  EXPECT_EQ(frame.index, 0);
  EXPECT_TRUE(std::isnan(frame.timestamp_s));
  EXPECT_FALSE(*(*source)->Read(frame));
}

// --loop: three pictures at 10 fps read as an endless camera, indices and times running on.
TEST(LoopFrameSource, ReadsTheSourceAgainWithIndicesAndTimesGoingOn) {
  testing::TempDir dir;
  for (int i = 0; i < 3; ++i) WritePicture(dir / fmt::format("f_{}.png", i), static_cast<uint8_t>(10 * (i + 1)));
  FrameSourceSpec spec{Kind::kImages, (dir / "f_%d.png").string()};
  spec.fps = 10;
  auto first = OpenFrameSource(spec, {});
  ASSERT_TRUE(first.ok()) << first.status().message();
  auto looped = LoopFrameSource(spec, {}, std::move(first).value());
  ASSERT_TRUE(looped.ok()) << looped.status().message();
  FrameSource& source = **looped;
  EXPECT_EQ(source.frame_count(), std::nullopt);
  EXPECT_NE(source.Describe().find(", looped"), std::string::npos) << source.Describe();
  Frame frame;
  for (int k = 0; k < 8; ++k) {
    ASSERT_EQ(source.next_index(), k);
    auto got = source.Read(frame);
    ASSERT_TRUE(got.ok()) << got.status().message();
    ASSERT_TRUE(*got) << "frame " << k;
    EXPECT_EQ(frame.index, k);
    EXPECT_NEAR(frame.timestamp_s, 0.1 * k, 1e-9) << "frame " << k;
    EXPECT_EQ(frame.gray(16, 12), 10 * (k % 3 + 1)) << "frame " << k;
  }
  // Skipping goes through the passes too.
  ASSERT_TRUE(source.SkipTo(20).ok());
  ASSERT_TRUE(*source.Read(frame));
  EXPECT_EQ(frame.index, 20);
  EXPECT_EQ(frame.gray(16, 12), 10 * (20 % 3 + 1));
}

TEST(LoopFrameSource, StreamsAndMasksAreRefused) {
  auto looped = LoopFrameSource({Kind::kStream, "udp://127.0.0.1:9"}, {}, nullptr);
  ASSERT_FALSE(looped.ok());
  EXPECT_EQ(looped.status().message(), "stream source 'udp://127.0.0.1:9': --loop is for video files and image sequences");
}

TEST(ImageSequence, FrameOfAnotherSizeIsAnErrorNamingTheFileAndBothSizes) {
  testing::TempDir dir;
  WritePicture(dir / "f_0.png", 1);
  WritePicture(dir / "f_1.png", 2, 30, 24);
  const fs::path pattern = dir / "f_%d.png";
  auto source = Open(Kind::kImages, pattern);
  ASSERT_TRUE(source.ok()) << source.status().message();
  Frame frame;
  ASSERT_TRUE(*(*source)->Read(frame));
  auto got = (*source)->Read(frame);
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(got.status().message(),
            fmt::format("image sequence '{}': frame 1: '{}': expected 32x24 (the size of the first frame), found 30x24",
                        pattern.string(), (dir / "f_1.png").string()));
}

TEST(ImageSequence, CorruptFileInTheMiddleIsAnErrorNamingTheFileAndIndex) {
  testing::TempDir dir;
  WritePicture(dir / "f_0.png", 1);
  WritePicture(dir / "f_1.png", 2);
  testing::WriteText(dir / "f_2.png", "\x89PNG garbage");
  WritePicture(dir / "f_3.png", 4);
  const fs::path pattern = dir / "f_%d.png";
  auto source = Open(Kind::kImages, pattern);
  ASSERT_TRUE(source.ok()) << source.status().message();
  Frame frame;
  ASSERT_TRUE(*(*source)->Read(frame));
  ASSERT_TRUE(*(*source)->Read(frame));
  auto got = (*source)->Read(frame);
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.status().code(), StatusCode::kDataLoss);
  EXPECT_EQ(got.status().message(),
            fmt::format("image sequence '{}': frame 2: '{}': cannot decode image (not a PNG/JPEG/... or truncated)",
                        pattern.string(), (dir / "f_2.png").string()));
}

TEST(ImageSequence, SkipToGoesForwardBackAndToTheEnd) {
  testing::TempDir dir;
  for (int i = 0; i < 5; ++i) WritePicture(dir / fmt::format("f_{}.png", i), static_cast<uint8_t>(i));
  const fs::path pattern = dir / "f_%d.png";
  for (const fs::path& location : {pattern, dir.path()}) {
    SCOPED_TRACE(location.string());
    auto source = Open(Kind::kImages, location);
    ASSERT_TRUE(source.ok()) << source.status().message();
    Frame frame;
    for (const int64_t target : {int64_t{3}, int64_t{1}, int64_t{0}, int64_t{4}}) {
      ASSERT_TRUE((*source)->SkipTo(target).ok());
      EXPECT_EQ((*source)->next_index(), target);
      ASSERT_TRUE(*(*source)->Read(frame));
      EXPECT_EQ(frame.index, target);
      EXPECT_EQ(frame.gray(5, 5), target);
    }
    ASSERT_TRUE((*source)->SkipTo(5).ok());
    EXPECT_FALSE(*(*source)->Read(frame));
  }
  auto source = Open(Kind::kImages, pattern);
  ASSERT_TRUE(source.ok());
  EXPECT_EQ(
      (*source)->SkipTo(7).message(),
      fmt::format("image sequence '{}': cannot skip to frame 7: the sequence ends after 5 frames", pattern.string()));
  EXPECT_EQ((*source)->SkipTo(-1).message(),
            fmt::format("image sequence '{}': cannot skip to frame -1: expected an index >= 0", pattern.string()));
}

TEST(ImageSequence, ImageFpsGivesTimestamps) {
  testing::TempDir dir;
  for (int i = 0; i < 3; ++i) WritePicture(dir / fmt::format("f_{}.png", i), 0);
  FrameSourceOptions options;
  options.image_fps = 4;
  auto source = Open(Kind::kImages, dir / "f_%d.png", options);
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->fps(), 4.0);
  Frame frame;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(*(*source)->Read(frame));
    EXPECT_EQ(frame.timestamp_s, i * 0.25);
  }
}

TEST(ImageSequence, ColourOptionFillsRgbAndGreyIsItsLuma) {
  testing::TempDir dir;
  Image<Rgb8> rgb(kWidth, kHeight);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) rgb(x, y) = {static_cast<uint8_t>(8 * x), static_cast<uint8_t>(10 * y), 200};
  }
  ASSERT_TRUE(WritePng(dir / "c.png", rgb.view()).ok());
  FrameSourceOptions options;
  options.colour = true;
  auto source = Open(Kind::kImages, dir / "c.png", options);
  ASSERT_TRUE(source.ok()) << source.status().message();
  Frame frame;
  ASSERT_TRUE(*(*source)->Read(frame));
  EXPECT_TRUE(frame.rgb == rgb);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const Rgb8 p = rgb(x, y);
      EXPECT_NEAR(frame.gray(x, y), 0.299 * p.r + 0.587 * p.g + 0.114 * p.b, 0.51) << x << "," << y;
    }
  }
}

// 2x2 blocks of known colours, left to right: white, red, green, blue, two red and two blue.
Image<Rgb8> ColourBlocks() {
  const Rgb8 white{255, 255, 255}, red{255, 0, 0}, green{0, 255, 0}, blue{0, 0, 255};
  const Rgb8 blocks[5][4] = {{white, white, white, white}, {red, red, red, red}, {green, green, green, green},
                             {blue, blue, blue, blue},     {red, blue, blue, red}};
  Image<Rgb8> rgb(10, 2);
  for (int i = 0; i < 5; ++i) {
    rgb(2 * i, 0) = blocks[i][0];
    rgb(2 * i + 1, 0) = blocks[i][1];
    rgb(2 * i, 1) = blocks[i][2];
    rgb(2 * i + 1, 1) = blocks[i][3];
  }
  return rgb;
}

TEST(ImageSequence, ChromaOptionGivesTheBt601ChromaOfKnownColours) {
  testing::TempDir dir;
  const Image<Rgb8> rgb = ColourBlocks();
  ASSERT_TRUE(WritePng(dir / "c.png", rgb.view()).ok());
  FrameSourceOptions options;
  options.chroma = true;
  auto source = Open(Kind::kImages, dir / "c.png", options);
  ASSERT_TRUE(source.ok()) << source.status().message();
  Frame frame;
  ASSERT_TRUE(*(*source)->Read(frame));
  ASSERT_EQ(frame.u.width(), 5);
  ASSERT_EQ(frame.u.height(), 1);
  ASSERT_EQ(frame.v.width(), 5);
  ASSERT_EQ(frame.v.height(), 1);
  // Full-range BT.601: U = 128 - 0.168736 R - 0.331264 G + 0.5 B, V = 128 + 0.5 R - 0.418688 G
  // - 0.081312 B, rounded and clamped (red's V 255.5 -> 255); the last block is the mean.
  const int expected_u[5] = {128, 85, 44, 255, 170};
  const int expected_v[5] = {128, 255, 21, 107, 181};
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(frame.u(i, 0), expected_u[i]) << "block " << i;
    EXPECT_EQ(frame.v(i, 0), expected_v[i]) << "block " << i;
  }
  // Grey is the Y of the same formulas; no colour was asked for.
  Image<uint8_t> luma;
  LumaFromRgb(rgb.view(), luma);
  EXPECT_TRUE(frame.gray == luma);
  EXPECT_TRUE(frame.rgb.empty());
}

TEST(ImageSequence, ChromaOfAnOddSizeCoversTheLastColumnAndRow) {
  testing::TempDir dir;
  Image<Rgb8> rgb(641, 481);
  for (int y = 0; y < rgb.height(); ++y) {
    for (int x = 0; x < rgb.width(); ++x) {
      rgb(x, y) = {static_cast<uint8_t>(x * 3 + y), static_cast<uint8_t>(255 - y / 2), static_cast<uint8_t>((x ^ y) & 255)};
    }
  }
  ASSERT_TRUE(WritePng(dir / "f_000000.png", rgb.view()).ok());
  ASSERT_TRUE(WritePng(dir / "f_000001.png", rgb.view()).ok());
  FrameSourceOptions options;
  options.chroma = true;
  options.colour = true;
  auto source = Open(Kind::kImages, dir / "f_%06d.png", options);
  ASSERT_TRUE(source.ok()) << source.status().message();
  Image<uint8_t> u, v;
  ChromaFromRgb(rgb.view(), u, v);
  Frame frame;
  for (int k = 0; k < 2; ++k) {  // the first frame (decoded by Open) and a later one
    ASSERT_TRUE(*(*source)->Read(frame));
    EXPECT_EQ(frame.u.width(), 321);
    EXPECT_EQ(frame.u.height(), 241);
    EXPECT_TRUE(frame.u == u);
    EXPECT_TRUE(frame.v == v);
    EXPECT_TRUE(frame.rgb == rgb);
  }
}

TEST(ImageSequence, ChromaOffLeavesUAndVEmpty) {
  testing::TempDir dir;
  ASSERT_TRUE(WritePng(dir / "c.png", ColourBlocks().view()).ok());
  for (const bool colour : {false, true}) {
    FrameSourceOptions options;
    options.colour = colour;
    auto source = Open(Kind::kImages, dir / "c.png", options);
    ASSERT_TRUE(source.ok()) << source.status().message();
    Frame frame;
    frame.u = Image<uint8_t>(5, 1);  // a reused frame loses its old planes
    ASSERT_TRUE(*(*source)->Read(frame));
    EXPECT_TRUE(frame.u.empty());
    EXPECT_TRUE(frame.v.empty());
  }
}

TEST(MaskSource, MasksAreReadAsTheyAreAndNeverInColour) {
  testing::TempDir dir;
  Image<uint8_t> mask(kWidth, kHeight, 0);
  for (int y = 4; y < 12; ++y) {
    for (int x = 3; x < 9; ++x) mask(x, y) = 255;
  }
  mask(0, 0) = 1;
  ASSERT_TRUE(WritePng(dir / "m_0.png", mask.view()).ok());
  FrameSourceOptions options;
  options.colour = true;
  options.chroma = true;
  auto source = Open(Kind::kMasks, dir / "m_%d.png", options);
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->Describe(), fmt::format("mask sequence '{}' (from 0, 32x24)", (dir / "m_%d.png").string()));
  Frame frame;
  ASSERT_TRUE(*(*source)->Read(frame));
  EXPECT_TRUE(frame.gray == mask);
  EXPECT_TRUE(frame.rgb.empty());
  EXPECT_TRUE(frame.u.empty());
  EXPECT_TRUE(frame.v.empty());
}

TEST(MaskSource, ReadsTheGopro4BackgroundSubtractionMask) {
  OCCMAP_REQUIRE_DATASETS(root);
  const fs::path path = root / "gopro4" / "bgsub_gopro6.0.png";
  auto source = Open(Kind::kMasks, path);
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->size(), (ImageSize{480, 270}));
  EXPECT_EQ((*source)->frame_count(), 1);
  EXPECT_EQ((*source)->Describe(), fmt::format("mask '{}' (480x270)", path.string()));
  Frame frame;
  ASSERT_TRUE(*(*source)->Read(frame));
  EXPECT_TRUE(frame.gray == *ReadGrayImage(path));
  EXPECT_FALSE(*(*source)->Read(frame));
}

// A source of `count` 1x1 frames whose value is their index; knows its position or not.
class CountingSource : public FrameSource {
 public:
  CountingSource(int64_t count, bool knows_position) : count_(count), knows_position_(knows_position) {}
  std::string Describe() const override { return "counting source"; }
  ImageSize size() const override { return {1, 1}; }
  std::optional<int64_t> next_index() const override {
    if (knows_position_) return next_;
    return std::nullopt;
  }
  Result<bool> Read(Frame& frame) override {
    if (next_ >= count_) return false;
    frame.index = next_;
    frame.gray = Image<uint8_t>(1, 1, static_cast<uint8_t>(next_++));
    return true;
  }

 private:
  int64_t count_;
  bool knows_position_;
  int64_t next_ = 0;
};

TEST(FrameSource, DefaultSkipToReadsAndDiscardsForward) {
  CountingSource source(5, /*knows_position=*/true);
  ASSERT_TRUE(source.SkipTo(3).ok());
  Frame frame;
  ASSERT_TRUE(*source.Read(frame));
  EXPECT_EQ(frame.index, 3);
  EXPECT_EQ(source.SkipTo(1).message(), "counting source: cannot skip back to frame 1 (next frame is 4)");
  EXPECT_EQ(source.SkipTo(9).message(), "counting source: cannot skip to frame 9: the source ends after 5 frames");

  CountingSource blind(5, /*knows_position=*/false);
  EXPECT_EQ(blind.SkipTo(2).message(), "counting source: cannot skip to frame 2: the source does not know its position");
}

TEST(OpenFrameSource, RejectsAMissingKindAnEmptyLocationAndBadOptions) {
  auto source = OpenFrameSource({Kind::kNone, "x.mp4"}, {});
  EXPECT_EQ(source.status().message(),
            "frame source 'x.mp4': expected a kind (images, video, stream or masks), found none");
  source = OpenFrameSource({Kind::kVideo, ""}, {});
  EXPECT_EQ(source.status().message(),
            "video source: expected a location (path, pattern or URL), found an empty string");
  FrameSourceOptions options;
  options.decoder_threads = -1;
  source = OpenFrameSource({Kind::kVideo, "x.mp4"}, options);
  EXPECT_EQ(source.status().message(), "decoder_threads: expected >= 0 (0 = all cores), found -1");
  options = {};
  options.image_fps = -2;
  source = OpenFrameSource({Kind::kImages, "x_%d.png"}, options);
  EXPECT_EQ(source.status().message(), "image_fps: expected a finite value >= 0 (0 = no timestamps), found -2");
}

TEST(OpenFrameSource, KindNamesReadAsWords) {
  EXPECT_STREQ(ToString(Kind::kImages), "images");
  EXPECT_STREQ(ToString(Kind::kVideo), "video");
  EXPECT_STREQ(ToString(Kind::kStream), "stream");
  EXPECT_STREQ(ToString(Kind::kMasks), "masks");
  EXPECT_STREQ(ToString(Kind::kNone), "none");
}

// Messages and summaries show where a source is, never a camera's password.
TEST(RedactUrl, HidesTheStreamPasswordOnly) {
  EXPECT_EQ(RedactUrl("rtsp://admin:s3cret@10.0.0.7:554/stream1"), "rtsp://admin:***@10.0.0.7:554/stream1");
  EXPECT_EQ(RedactUrl("rtsp://admin:s3cret@cam"), "rtsp://admin:***@cam");
  EXPECT_EQ(RedactUrl("rtsp://admin@cam/1"), "rtsp://admin@cam/1");            // no password
  EXPECT_EQ(RedactUrl("udp://127.0.0.1:23001?pkt_size=1316"), "udp://127.0.0.1:23001?pkt_size=1316");
  EXPECT_EQ(RedactUrl("http://cam/a@b.mjpg"), "http://cam/a@b.mjpg");           // @ in the path
  EXPECT_EQ(RedactUrl("frames/c1.mp4"), "frames/c1.mp4");
  EXPECT_EQ(RedactUrl("rtsp://admin:pa/ss@cam/1"), "rtsp://admin:***@cam/1");     // '/' in the password
  EXPECT_EQ(RedactUrl("rtsp://admin:a/b/c@10.0.0.7:554/s"), "rtsp://admin:***@10.0.0.7:554/s");
  EXPECT_EQ(RedactUrl("http://cam:8080/a@b.mjpg"), "http://cam:***@b.mjpg");       // over-redacted
  EXPECT_EQ(RedactUrl("http://cam:8080/a.mjpg"), "http://cam:8080/a.mjpg");
}

}  // namespace
}  // namespace occmap
