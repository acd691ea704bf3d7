#include "occmap/io/frame_times.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "occmap/io/frame_source.h"
#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

TEST(FrameTimes, SecondsOnePerLine) {
  auto times = ParseFrameTimes("0\n0.2\n# a comment\n\n0.5   # after a value\n", "t.txt", 0);
  ASSERT_TRUE(times.ok()) << times.status().message();
  EXPECT_EQ(*times, (std::vector<double>{0, 0.2, 0.5}));
  EXPECT_NEAR(MeanRateHz(*times), 4.0, 1e-12);
}

TEST(FrameTimes, IndexedFrameNumbersAtARate) {
  // The terrace dataset's frame_numbers.txt: "index video_frame_number" at 25 fps.
  auto times = ParseFrameTimes("# index original_frame_number (25 fps)\n0 10\n1 15\r\n2 25\n", "f.txt", 25);
  ASSERT_TRUE(times.ok()) << times.status().message();
  EXPECT_EQ(*times, (std::vector<double>{10.0 / 25, 15.0 / 25, 25.0 / 25}));
}

TEST(FrameTimes, MalformedFilesNameTheLine) {
  const struct {
    const char* text;
    double fps;
    const char* message;
  } cases[] = {
      {"", 0, "f.txt: expected a time per image, found none"},
      {"# only\n", 0, "f.txt: expected a time per image, found none"},
      {"0\n0.1\n0.1\n", 0, "f.txt:3: expected times that increase, found 0.1 after 0.1"},
      {"0 10\n1 5\n", 25, "f.txt:2: expected times that increase, found 5 after 10"},
      {"0 10\n2 15\n", 25, "f.txt:2: expected image index 1 (one line per image, in order), found 2"},
      {"0 10\n15\n", 25, "f.txt:2: expected 'INDEX TIME' as on the first line, found '15'"},
      {"1 2 3\n", 0, "f.txt:1: expected 'TIME' or 'INDEX TIME', found '1 2 3'"},
      {"zero\n", 0, "f.txt:1: expected a time in seconds, found 'zero'"},
      {"x 10\n", 25, "f.txt:1: expected an image index, found 'x'"},
      {"0 nan\n", 25, "f.txt:1: expected a frame number, found 'nan'"},
      {"0 1e999\n", 25, "f.txt:1: expected a frame number, found '1e999'"},
  };
  for (const auto& c : cases) {
    auto times = ParseFrameTimes(c.text, "f.txt", c.fps);
    ASSERT_FALSE(times.ok()) << c.text;
    EXPECT_EQ(times.status().message(), c.message) << c.text;
  }
  EXPECT_FALSE(ParseFrameTimes("0\n", "f.txt", -1).ok());
}

TEST(FrameTimes, ReadFromAFileAndAFolderIsRefused) {
  testing::TempDir dir;
  testing::WriteText(dir / "t.txt", "0.0\n0.5\n");
  auto times = ReadFrameTimes(dir / "t.txt", 0);
  ASSERT_TRUE(times.ok()) << times.status().message();
  EXPECT_EQ(times->size(), 2u);
  EXPECT_FALSE(ReadFrameTimes(dir.path(), 0).ok());
  EXPECT_FALSE(ReadFrameTimes(dir / "missing.txt", 0).ok());
}

TEST(FrameTimes, ImageSequenceTakesItsTimesAndTheirMeanRate) {
  testing::TempDir dir;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(WritePng(dir / fmt::format("f_{}.png", i), Image<uint8_t>(8, 6, static_cast<uint8_t>(i)).view()).ok());
  }
  FrameSourceSpec spec{FrameSourceSpec::Kind::kImages, (dir / "f_%d.png").string()};
  spec.timestamps_s = {0.4, 0.6, 1.4};
  auto source = OpenFrameSource(spec, {});
  ASSERT_TRUE(source.ok()) << source.status().message();
  ASSERT_TRUE((*source)->fps().has_value());
  EXPECT_NEAR(*(*source)->fps(), 2.0, 1e-12);
  Frame frame;
  std::vector<double> seen;
  while (true) {
    auto got = (*source)->Read(frame);
    ASSERT_TRUE(got.ok()) << got.status().message();
    if (!*got) break;
    seen.push_back(frame.timestamp_s);
  }
  EXPECT_EQ(seen, spec.timestamps_s);

  // Fewer times than images: the image without one is an error, not a guess.
  spec.timestamps_s = {0.4, 0.6};
  source = OpenFrameSource(spec, {});
  ASSERT_TRUE(source.ok());
  ASSERT_TRUE((*source)->Read(frame).ok());
  ASSERT_TRUE((*source)->Read(frame).ok());
  auto third = (*source)->Read(frame);
  ASSERT_FALSE(third.ok());
  EXPECT_NE(third.status().message().find("its timestamps give the times of 2 images, none for this one"),
            std::string::npos)
      << third.status().message();

  // fps and times together are refused.
  spec.fps = 10;
  EXPECT_FALSE(OpenFrameSource(spec, {}).ok());
}

}  // namespace
}  // namespace occmap
