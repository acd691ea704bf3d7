#include "occmap/util/image.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

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
  flipped[24] = static_cast<char>(flipped[24] ^ 0x01);  // IHDR's bit depth
  ASSERT_TRUE(WriteFileAtomic(dir / "crc.png", flipped).ok());
  auto crc = ReadGrayImage(dir / "crc.png");
  ASSERT_FALSE(crc.ok());
  EXPECT_EQ(crc.status().message(), fmt::format("'{}': corrupt PNG: chunk 'IHDR' at byte 8 fails its CRC", (dir / "crc.png").string()));
}

// A chunk type's raw bytes made the message invalid UTF-8: the web API's reply (dump()) threw
// (found by the serve_api fuzz target). Shown as escapes.
TEST(ImageIo, AChunkTypeThatIsNotTextIsShownEscaped) {
  const std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + std::string("\0\0\0\0", 4) + "IH\x94R" + "crc!";
  const Status s = CheckEncodedImage(png, "view.png");
  EXPECT_EQ(s.message(), "'view.png': expected the PNG's IHDR chunk first, found 'IH\\x94R'");
}

// A 1 MB PNG of 30000 x 30000 pixels decoded to 1.85 GB: its header says so first.
TEST(ImageIo, OversizeImagesAreRefusedFromTheirHeader) {
  testing::TempDir dir;
  Image<uint8_t> gray(64, 48, 100);
  ASSERT_TRUE(WritePng(dir / "g.png", gray.view()).ok());
  std::string png = *ReadFileToString(dir / "g.png");
  for (int i : {16, 20}) {  // width, height: 30000 each
    png[i] = 0, png[i + 1] = 0, png[i + 2] = static_cast<char>(30000 >> 8), png[i + 3] = static_cast<char>(30000 & 0xFF);
  }
  ASSERT_TRUE(WriteFileAtomic(dir / "bomb.png", png).ok());
  auto bomb = ReadGrayImage(dir / "bomb.png");
  ASSERT_FALSE(bomb.ok());
  EXPECT_EQ(bomb.status().message(),
            fmt::format("'{}': PNG of 30000x30000 pixels, expected at most 33554432 pixels (8192 x 4096); refused before "
                        "decoding", (dir / "bomb.png").string()));
  EXPECT_EQ(ExitCodeFor(bomb.status()), 2);

  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", cv::Mat(48, 64, CV_8UC1, cv::Scalar(90)), jpeg));
  std::string j(jpeg.begin(), jpeg.end());
  EXPECT_TRUE(CheckEncodedImage(j, "ok.jpg").ok());
  const size_t sof = j.find("\xFF\xC0");
  ASSERT_NE(sof, std::string::npos);
  j[sof + 5] = static_cast<char>(0xFF), j[sof + 6] = static_cast<char>(0xFF);  // height 65535
  j[sof + 7] = static_cast<char>(0xFF), j[sof + 8] = static_cast<char>(0xFF);  // width 65535
  const Status s = CheckEncodedImage(j, "bomb.jpg");
  EXPECT_EQ(s.code(), StatusCode::kResourceExhausted);
  EXPECT_NE(s.message().find("JPEG of 65535x65535 pixels"), std::string::npos) << s.message();

  std::string bmp = "BM" + std::string(24, '\0');
  bmp[18] = bmp[19] = bmp[22] = bmp[23] = static_cast<char>(0x7F);  // 32639 x 32639
  EXPECT_EQ(CheckEncodedImage(bmp, "bomb.bmp").code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(CheckEncodedImage("P5\n# big\n30000 30000\n255\n", "bomb.pgm").code(), StatusCode::kResourceExhausted);
}

// OpenCV decodes a JPEG cut short without a word (the missing rows grey).
TEST(ImageIo, TruncatedJpegIsRejected) {
  testing::TempDir dir;
  cv::Mat noise(120, 160, CV_8UC1);
  cv::randu(noise, 0, 255);
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", noise, jpeg));
  const std::string bytes(jpeg.begin(), jpeg.end());
  ASSERT_TRUE(WriteFileAtomic(dir / "whole.jpg", bytes).ok());
  EXPECT_TRUE(ReadGrayImage(dir / "whole.jpg").ok());
  for (size_t keep : {bytes.size() / 2, bytes.size() - 2, size_t{200}}) {
    ASSERT_TRUE(WriteFileAtomic(dir / "cut.jpg", std::string_view(bytes).substr(0, keep)).ok());
    auto cut = ReadGrayImage(dir / "cut.jpg");
    ASSERT_FALSE(cut.ok()) << keep;
    EXPECT_EQ(cut.status().message(),
              fmt::format("'{}': truncated JPEG: {} bytes, no end marker (EOI)", (dir / "cut.jpg").string(), keep));
  }
  // Bytes after the end marker (some cameras append their own) are no truncation.
  ASSERT_TRUE(WriteFileAtomic(dir / "tail.jpg", bytes + "trailing bytes").ok());
  EXPECT_TRUE(ReadGrayImage(dir / "tail.jpg").ok());
}

}  // namespace
}  // namespace occmap
