#include "occmap/util/image.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <cstdint>

#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

TEST(Image, RowsAre64ByteAligned) {
  Image<uint8_t> gray(37, 5);
  Image<Rgb8> rgb(37, 5);
  Image<uint32_t> words(3, 3);
  for (int y = 0; y < 5; ++y) {
    EXPECT_EQ(reinterpret_cast<uintptr_t>(gray.row(y)) % 64, 0u);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(rgb.row(y)) % 64, 0u);
  }
  EXPECT_EQ(reinterpret_cast<uintptr_t>(words.row(2)) % 64, 0u);
  EXPECT_GE(gray.stride_elems(), 37);
}

TEST(Image, CopyAndCompare) {
  Image<uint8_t> a(10, 4, 7);
  a(3, 2) = 9;
  Image<uint8_t> b = a;
  EXPECT_EQ(a, b);
  b(0, 0) = 1;
  EXPECT_FALSE(a == b);
  EXPECT_EQ(b.view()(3, 2), 9);
}

TEST(Image, CopyIntoAnImageOfTheSameSizeOrLargerKeepsItsBuffer) {
  Image<uint8_t> a(100, 40, 7), b(100, 40, 1), big(200, 80, 3);
  const uint8_t* buffer = b.view().data();
  b = a;  // same size: the same buffer, a's pixels
  EXPECT_EQ(b.view().data(), buffer);
  EXPECT_EQ(a, b);
  const uint8_t* big_buffer = big.view().data();
  big = a;  // smaller: the buffer kept, the size and pixels a's
  EXPECT_EQ(big.view().data(), big_buffer);
  EXPECT_EQ(big.width(), 100);
  EXPECT_EQ(big.height(), 40);
  EXPECT_EQ(big, a);
  Image<uint8_t> moved = std::move(b);  // a moved-from image allocates again when copied into
  b = big;
  EXPECT_EQ(b, a);
  EXPECT_NE(b.view().data(), moved.view().data());
  Image<uint8_t> small(3, 2, 5);
  small = big;  // larger: a new buffer
  EXPECT_EQ(small, a);
}

TEST(ImageIo, PngRoundTripGrayAndRgb) {
  testing::TempDir dir;
  Image<uint8_t> gray(31, 17);
  Image<Rgb8> rgb(31, 17);
  for (int y = 0; y < 17; ++y) {
    for (int x = 0; x < 31; ++x) {
      gray(x, y) = static_cast<uint8_t>(x * 8 + y);
      rgb(x, y) = {static_cast<uint8_t>(x), static_cast<uint8_t>(y), static_cast<uint8_t>(x + y)};
    }
  }
  ASSERT_TRUE(WritePng(dir / "g.png", gray.view()).ok());
  ASSERT_TRUE(WritePng(dir / "c.png", rgb.view()).ok());
  auto g = ReadGrayImage(dir / "g.png");
  auto c = ReadRgbImage(dir / "c.png");
  ASSERT_TRUE(g.ok() && c.ok());
  EXPECT_EQ(*g, gray);
  EXPECT_EQ(*c, rgb);
}

TEST(ImageIo, MalformedFilesGiveClearErrors) {
  testing::TempDir dir;
  testing::WriteText(dir / "empty.png", "");
  testing::WriteText(dir / "text.png", "this is not an image");
  auto missing = ReadGrayImage(dir / "missing.png");
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
  auto empty = ReadGrayImage(dir / "empty.png");
  EXPECT_NE(empty.status().message().find("empty file, expected an image"), std::string::npos);
  auto text = ReadGrayImage(dir / "text.png");
  EXPECT_NE(text.status().message().find("cannot decode image"), std::string::npos);
  EXPECT_EQ(ExitCodeFor(text.status()), 2);
}

TEST(ImageIo, TruncatedPngIsRejected) {
  testing::TempDir dir;
  Image<uint8_t> gray(64, 64, 100);
  ASSERT_TRUE(WritePng(dir / "g.png", gray.view()).ok());
  const std::string bytes = *ReadFileToString(dir / "g.png");
  ASSERT_TRUE(WriteFileAtomic(dir / "cut.png", std::string_view(bytes).substr(0, bytes.size() / 2)).ok());
  auto cut = ReadGrayImage(dir / "cut.png");
  ASSERT_FALSE(cut.ok());
  EXPECT_EQ(cut.status().code(), StatusCode::kDataLoss);
  // Told by our own chunk walk, before libpng (which would print "libpng error: ..." itself).
  EXPECT_NE(cut.status().message().find("truncated PNG: chunk 'IDAT'"), std::string::npos) << cut.status().message();
  std::string flipped = bytes;
  flipped[20] = static_cast<char>(flipped[20] ^ 0x01);  // IHDR's width
  ASSERT_TRUE(WriteFileAtomic(dir / "crc.png", flipped).ok());
  auto crc = ReadGrayImage(dir / "crc.png");
  ASSERT_FALSE(crc.ok());
  EXPECT_EQ(crc.status().message(), fmt::format("'{}': corrupt PNG: chunk 'IHDR' at byte 8 fails its CRC", (dir / "crc.png").string()));
}

}  // namespace
}  // namespace occmap
