#include <fmt/core.h>
#include <gtest/gtest.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/pixdesc.h>
#include <libswscale/swscale.h>
}

#include "occmap/io/frame_source.h"
#include "occmap/io/video_writer.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"
#include "occmap/util/yuv.h"

namespace occmap {
namespace {
namespace fs = std::filesystem;

uint8_t Clamp8(double v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); }

// Frame t of a test clip: a smooth texture whose brightness changes with t, and a bright
// square moving right and down. Values stay within 20..235 (no clipping in limited range).
Image<Rgb8> ClipFrame(int width, int height, int t) {
  Image<Rgb8> image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double base = 90 + 25 * std::sin(x * 0.35) + 25 * std::cos(y * 0.27) + 2.5 * t;
      image(x, y) = {Clamp8(base + 15), Clamp8(base), Clamp8(base - 15 + 10 * std::sin((x + y) * 0.2))};
    }
  }
  const int x0 = 8 + 4 * t, y0 = 10 + 2 * t;
  for (int y = y0; y < std::min(height, y0 + 24); ++y) {
    for (int x = x0; x < std::min(width, x0 + 24); ++x) image(x, y) = {230, 225, 200};
  }
  return image;
}

double Luma(const Rgb8& p) { return 0.299 * p.r + 0.587 * p.g + 0.114 * p.b; }

double MeanAbsGrayError(const Image<uint8_t>& gray, const Image<Rgb8>& rgb) {
  double sum = 0;
  for (int y = 0; y < rgb.height(); ++y) {
    for (int x = 0; x < rgb.width(); ++x) sum += std::abs(gray(x, y) - Luma(rgb(x, y)));
  }
  return sum / (rgb.width() * rgb.height());
}

double MeanAbsRgbError(const Image<Rgb8>& a, const Image<Rgb8>& b) {
  double sum = 0;
  for (int y = 0; y < b.height(); ++y) {
    for (int x = 0; x < b.width(); ++x) {
      sum += std::abs(a(x, y).r - b(x, y).r) + std::abs(a(x, y).g - b(x, y).g) + std::abs(a(x, y).b - b(x, y).b);
    }
  }
  return sum / (3.0 * b.width() * b.height());
}

constexpr int kWidth = 160, kHeight = 120, kFrames = 20;
constexpr double kFps = 25;

void WriteClip(const fs::path& path, int frames = kFrames, ImageSize size = {kWidth, kHeight}, double fps = kFps,
               const VideoWriterOptions& options = {}) {
  auto writer = VideoWriter::Open(path, size, fps, options);
  ASSERT_TRUE(writer.ok()) << writer.status().message();
  for (int t = 0; t < frames; ++t) {
    const Status status = (*writer)->Write(ClipFrame(size.width, size.height, t).view());
    ASSERT_TRUE(status.ok()) << status.message();
  }
  const Status status = (*writer)->Close();
  ASSERT_TRUE(status.ok()) << status.message();
}

// Reads to the end; the status of the first failed Read, if any, goes to *error.
std::vector<Frame> ReadAll(FrameSource& source, Status* error = nullptr) {
  std::vector<Frame> frames;
  while (true) {
    Frame frame;
    auto got = source.Read(frame);
    if (!got.ok()) {
      if (error != nullptr)
        *error = got.status();
      else
        ADD_FAILURE() << got.status().message();
      break;
    }
    if (!*got) break;
    frames.push_back(std::move(frame));
  }
  return frames;
}

Result<std::unique_ptr<FrameSource>> OpenVideo(const fs::path& path, FrameSourceOptions options = {}) {
  return OpenFrameSource({FrameSourceSpec::Kind::kVideo, path.string()}, options);
}

std::vector<std::string> FilesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(VideoRoundTrip, WrittenH264DecodesBackWithItsFramesTimestampsAndLuma) {
  testing::TempDir dir;
  WriteClip(dir / "clip.mp4");
  auto source = OpenVideo(dir / "clip.mp4");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->Describe(), fmt::format("video '{}' (h264, 160x120, 25 fps)", (dir / "clip.mp4").string()));
  EXPECT_EQ((*source)->size(), (ImageSize{kWidth, kHeight}));
  EXPECT_EQ((*source)->fps(), kFps);
  EXPECT_EQ((*source)->frame_count(), kFrames);

  const std::vector<Frame> frames = ReadAll(**source);
  ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames));
  for (int t = 0; t < kFrames; ++t) {
    const Frame& frame = frames[static_cast<size_t>(t)];
    EXPECT_EQ(frame.index, t);
    EXPECT_NEAR(frame.timestamp_s, t / kFps, 1e-3) << "frame " << t;
    ASSERT_EQ(frame.gray.width(), kWidth);
    ASSERT_EQ(frame.gray.height(), kHeight);
    EXPECT_TRUE(frame.rgb.empty());
    EXPECT_LT(MeanAbsGrayError(frame.gray, ClipFrame(kWidth, kHeight, t)), 3.0) << "frame " << t;
  }
}

TEST(VideoRoundTrip, EveryContainerKeepsFramesInOrderWithTheirTimestamps) {
  testing::TempDir dir;
  for (const char* name : {"clip.mkv", "clip.avi", "clip.mov"}) {
    SCOPED_TRACE(name);
    WriteClip(dir / name, 8, {kWidth, kHeight}, 12.5);
    auto source = OpenVideo(dir / name);
    ASSERT_TRUE(source.ok()) << source.status().message();
    EXPECT_EQ((*source)->fps(), 12.5);
    const std::vector<Frame> frames = ReadAll(**source);
    ASSERT_EQ(frames.size(), 8u);
    for (int t = 0; t < 8; ++t) {
      const Frame& frame = frames[static_cast<size_t>(t)];
      EXPECT_NEAR(frame.timestamp_s, t / 12.5, 1e-3) << "frame " << t;
      EXPECT_LT(MeanAbsGrayError(frame.gray, ClipFrame(kWidth, kHeight, t)), 3.0) << "frame " << t;
    }
  }
}

TEST(VideoRoundTrip, ColourFramesAreCloseToTheRgbSource) {
  testing::TempDir dir;
  WriteClip(dir / "clip.mkv");
  FrameSourceOptions options;
  options.colour = true;
  auto source = OpenVideo(dir / "clip.mkv", options);
  ASSERT_TRUE(source.ok()) << source.status().message();
  const std::vector<Frame> frames = ReadAll(**source);
  ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames));
  for (int t = 0; t < kFrames; ++t) {
    const Frame& frame = frames[static_cast<size_t>(t)];
    ASSERT_EQ(frame.rgb.width(), kWidth);
    ASSERT_EQ(frame.rgb.height(), kHeight);
    const Image<Rgb8> source_rgb = ClipFrame(kWidth, kHeight, t);
    EXPECT_LT(MeanAbsRgbError(frame.rgb, source_rgb), 4.0) << "frame " << t;
    EXPECT_LT(MeanAbsGrayError(frame.gray, source_rgb), 3.0) << "frame " << t;
  }
}

TEST(VideoRoundTrip, Mpeg4EncoderDecodesBackCloseToTheSource) {
  testing::TempDir dir;
  VideoWriterOptions options;
  options.encoder = "mpeg4";
  auto writer = VideoWriter::Open(dir / "clip.avi", {kWidth, kHeight}, kFps, options);
  ASSERT_TRUE(writer.ok()) << writer.status().message();
  EXPECT_EQ((*writer)->codec_name(), "mpeg4");
  writer->reset();
  WriteClip(dir / "clip.avi", kFrames, {kWidth, kHeight}, kFps, options);
  auto source = OpenVideo(dir / "clip.avi");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->Describe(), fmt::format("video '{}' (mpeg4, 160x120, 25 fps)", (dir / "clip.avi").string()));
  const std::vector<Frame> frames = ReadAll(**source);
  ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames));
  for (int t = 0; t < kFrames; ++t) {
    const Frame& frame = frames[static_cast<size_t>(t)];
    EXPECT_NEAR(frame.timestamp_s, t / kFps, 1e-3) << "frame " << t;
    EXPECT_LT(MeanAbsGrayError(frame.gray, ClipFrame(kWidth, kHeight, t)), 3.0) << "frame " << t;
  }
}

TEST(VideoSource, OneAndTwoDecoderThreadsGiveIdenticalGreyFrames) {
  testing::TempDir dir;
  WriteClip(dir / "clip.mp4");
  std::vector<std::vector<Frame>> runs;
  for (int threads : {1, 2}) {
    FrameSourceOptions options;
    options.decoder_threads = threads;
    auto source = OpenVideo(dir / "clip.mp4", options);
    ASSERT_TRUE(source.ok()) << source.status().message();
    runs.push_back(ReadAll(**source));
  }
  ASSERT_EQ(runs[0].size(), static_cast<size_t>(kFrames));
  ASSERT_EQ(runs[1].size(), runs[0].size());
  for (size_t i = 0; i < runs[0].size(); ++i) {
    EXPECT_TRUE(runs[0][i].gray == runs[1][i].gray) << "frame " << i;
    EXPECT_EQ(runs[0][i].timestamp_s, runs[1][i].timestamp_s) << "frame " << i;
  }
}

TEST(VideoSource, TruncatedFileGivesDataLossNamingTheFileOrFewerFrames) {
  testing::TempDir dir;
  for (const char* name : {"clip.mp4", "clip.mkv"}) {
    WriteClip(dir / name);
    const std::string bytes = *ReadFileToString(dir / name);
    for (const size_t cut : {bytes.size() * 6 / 10, size_t{2048}}) {
      SCOPED_TRACE(fmt::format("{} cut at {} of {} bytes", name, cut, bytes.size()));
      const fs::path path = dir / fmt::format("cut-{}-{}", cut, name);
      ASSERT_TRUE(WriteFileAtomic(path, std::string_view(bytes).substr(0, cut)).ok());
      auto source = OpenVideo(path);
      Status error;
      size_t frames = 0;
      if (source.ok()) {
        frames = ReadAll(**source, &error).size();
        EXPECT_LT(frames, static_cast<size_t>(kFrames));
      } else {
        error = source.status();
      }
      if (!error.ok()) {
        EXPECT_EQ(error.code(), StatusCode::kDataLoss) << error.message();
        EXPECT_NE(error.message().find(path.string()), std::string::npos) << error.message();
        if (source.ok()) {
          EXPECT_NE(error.message().find(fmt::format("frame {}", frames)), std::string::npos) << error.message();
        }
      }
    }
  }
}

TEST(VideoSource, GarbageFileIsAClearError) {
  testing::TempDir dir;
  std::string garbage;
  for (int i = 0; i < 20000; ++i) garbage.push_back(static_cast<char>((i * 7919 + i / 13) & 0xff));
  ASSERT_TRUE(WriteFileAtomic(dir / "garbage.mp4", garbage).ok());
  auto source = OpenVideo(dir / "garbage.mp4");
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().code(), StatusCode::kDataLoss);
  const std::string prefix =
      fmt::format("video '{}': cannot open: Invalid data found when processing input", (dir / "garbage.mp4").string());
  EXPECT_EQ(source.status().message().rfind(prefix, 0), 0u) << source.status().message();

  testing::WriteText(dir / "text.mkv", "this is not a video\n");
  source = OpenVideo(dir / "text.mkv");
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().code(), StatusCode::kDataLoss) << source.status().message();

  source = OpenVideo(dir.path());
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().message(),
            fmt::format("video '{}': expected a video file, found a folder", dir.path().string()));
}

// A 4x2 24-bit BMP: 54 bytes of headers, then rows of 12 bytes (a multiple of 4, no padding).
std::string TinyBmp() {
  std::string bmp(54 + 2 * 12, '\x40');
  auto put32 = [&](size_t at, uint32_t v) {
    for (int i = 0; i < 4; ++i) bmp[at + i] = static_cast<char>((v >> (8 * i)) & 0xff);
  };
  std::fill(bmp.begin(), bmp.begin() + 54, '\0');
  bmp[0] = 'B';
  bmp[1] = 'M';
  put32(2, static_cast<uint32_t>(bmp.size()));
  put32(10, 54);  // pixel data offset
  put32(14, 40);  // BITMAPINFOHEADER
  put32(18, 4);
  put32(22, 2);
  put32(26, 1 | (24 << 16));  // 1 plane, 24 bits per pixel
  put32(34, 2 * 12);
  return bmp;
}

TEST(VideoSource, StillImageIsRefusedNotDecodedAsAOneFrameVideo) {
  testing::TempDir dir;
  ASSERT_TRUE(WritePng(dir / "grey.png", ClipFrame(32, 24, 0).view()).ok());
  ASSERT_TRUE(WriteFileAtomic(dir / "still.bmp", TinyBmp()).ok());
  // The name says video: the contents decide.
  fs::copy_file(dir / "grey.png", dir / "disguised.mp4");
  const std::pair<const char*, const char*> cases[] = {
      {"grey.png", "a PNG image"}, {"disguised.mp4", "a PNG image"}, {"still.bmp", "a BMP image"}};
  for (const auto& [file, found] : cases) {
    auto source = OpenVideo(dir / file);
    ASSERT_FALSE(source.ok()) << file;
    EXPECT_EQ(source.status().code(), StatusCode::kInvalidInput) << file;
    EXPECT_EQ(source.status().message(),
              fmt::format("video '{}': expected a video file, found {} (give still images as `images:`)",
                          (dir / file).string(), found));
  }
}

TEST(VideoSource, MissingFileIsNotFound) {
  auto source = OpenVideo("/nonexistent/c1.mp4");
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(source.status().message(), "file not found: '/nonexistent/c1.mp4'");
}

TEST(VideoSource, SkipToReturnsTheRequestedFrameForwardAndBack) {
  testing::TempDir dir;
  WriteClip(dir / "clip.mp4");
  auto reference = OpenVideo(dir / "clip.mp4");
  ASSERT_TRUE(reference.ok()) << reference.status().message();
  const std::vector<Frame> all = ReadAll(**reference);
  ASSERT_EQ(all.size(), static_cast<size_t>(kFrames));

  auto source = OpenVideo(dir / "clip.mp4");
  ASSERT_TRUE(source.ok());
  Frame frame;
  for (const int64_t target : {int64_t{7}, int64_t{12}, int64_t{3}, int64_t{19}}) {
    ASSERT_TRUE((*source)->SkipTo(target).ok()) << target;
    EXPECT_EQ((*source)->next_index(), target);
    ASSERT_TRUE(*(*source)->Read(frame));
    EXPECT_EQ(frame.index, target);
    EXPECT_EQ(frame.timestamp_s, all[static_cast<size_t>(target)].timestamp_s);
    EXPECT_TRUE(frame.gray == all[static_cast<size_t>(target)].gray) << "frame " << target;
  }
  ASSERT_TRUE((*source)->SkipTo(kFrames).ok());  // the end
  EXPECT_FALSE(*(*source)->Read(frame));
  const Status past = (*source)->SkipTo(kFrames + 5);
  EXPECT_EQ(past.message(), fmt::format("video '{}': cannot skip to frame 25: the video ends after 20 frames",
                                        (dir / "clip.mp4").string()));
}

// Writes `frames` clip frames as uncompressed video in `pixel_format` (NUT container), converted
// from RGB by libswscale with BT.601 and the given range: pictures as a camera could deliver them.
void WriteRawVideo(const fs::path& path, AVPixelFormat pixel_format, bool full_range, int frames,
                   ImageSize size = {kWidth, kHeight}) {
  const int width = size.width, height = size.height;
  AVFormatContext* format = nullptr;
  ASSERT_GE(avformat_alloc_output_context2(&format, nullptr, "nut", path.c_str()), 0);
  const AVCodec* encoder = avcodec_find_encoder(AV_CODEC_ID_RAWVIDEO);
  AVStream* stream = avformat_new_stream(format, nullptr);
  AVCodecContext* codec = avcodec_alloc_context3(encoder);
  codec->width = width;
  codec->height = height;
  codec->pix_fmt = pixel_format;
  codec->time_base = {1, static_cast<int>(kFps)};
  ASSERT_GE(avcodec_open2(codec, encoder, nullptr), 0);
  ASSERT_GE(avcodec_parameters_from_context(stream->codecpar, codec), 0);
  stream->time_base = codec->time_base;
  ASSERT_GE(avio_open(&format->pb, path.c_str(), AVIO_FLAG_WRITE), 0);
  ASSERT_GE(avformat_write_header(format, nullptr), 0);
  SwsContext* sws = sws_getContext(width, height, AV_PIX_FMT_RGB24, width, height, pixel_format,
                                   SWS_BILINEAR | SWS_ACCURATE_RND, nullptr, nullptr, nullptr);
  const int* bt601 = sws_getCoefficients(SWS_CS_ITU601);
  sws_setColorspaceDetails(sws, bt601, 1, bt601, full_range ? 1 : 0, 0, 1 << 16, 1 << 16);
  AVFrame* frame = av_frame_alloc();
  frame->format = pixel_format;
  frame->width = width;
  frame->height = height;
  ASSERT_GE(av_frame_get_buffer(frame, 0), 0);
  AVPacket* packet = av_packet_alloc();
  for (int t = 0; t <= frames; ++t) {
    if (t < frames) {
      const Image<Rgb8> rgb = ClipFrame(width, height, t);
      const uint8_t* src[4] = {reinterpret_cast<const uint8_t*>(rgb.row(0)), nullptr, nullptr, nullptr};
      const int src_stride[4] = {static_cast<int>(rgb.stride_elems() * 3), 0, 0, 0};
      ASSERT_GE(av_frame_make_writable(frame), 0);
      sws_scale(sws, src, src_stride, 0, height, frame->data, frame->linesize);
      frame->pts = t;
    }
    ASSERT_GE(avcodec_send_frame(codec, t < frames ? frame : nullptr), 0);
    while (avcodec_receive_packet(codec, packet) >= 0) {
      av_packet_rescale_ts(packet, codec->time_base, stream->time_base);
      packet->stream_index = 0;
      ASSERT_GE(av_interleaved_write_frame(format, packet), 0);
    }
  }
  ASSERT_GE(av_write_trailer(format), 0);
  av_packet_free(&packet);
  av_frame_free(&frame);
  sws_freeContext(sws);
  avcodec_free_context(&codec);
  avio_closep(&format->pb);
  avformat_free_context(format);
}

TEST(VideoSource, EveryPixelFormatGivesFullRangeLumaAndRgb) {
  testing::TempDir dir;
  // Plain 8-bit luma planes (row copy / range expansion) and formats that need libswscale.
  const struct {
    AVPixelFormat format;
    bool full_range;
  } cases[] = {{AV_PIX_FMT_YUV420P, false}, {AV_PIX_FMT_NV12, false},       {AV_PIX_FMT_GRAY8, true},
               {AV_PIX_FMT_RGB24, true},    {AV_PIX_FMT_YUV420P10LE, false}, {AV_PIX_FMT_YUV444P, false}};
  constexpr int kRawFrames = 3;
  for (const auto& c : cases) {
    SCOPED_TRACE(av_get_pix_fmt_name(c.format));
    const fs::path path = dir / fmt::format("{}.nut", av_get_pix_fmt_name(c.format));
    WriteRawVideo(path, c.format, c.full_range, kRawFrames);
    FrameSourceOptions options;
    options.colour = true;
    auto source = OpenVideo(path, options);
    ASSERT_TRUE(source.ok()) << source.status().message();
    const std::vector<Frame> frames = ReadAll(**source);
    ASSERT_EQ(frames.size(), static_cast<size_t>(kRawFrames));
    for (int t = 0; t < kRawFrames; ++t) {
      const Image<Rgb8> rgb = ClipFrame(kWidth, kHeight, t);
      const Frame& frame = frames[static_cast<size_t>(t)];
      EXPECT_LT(MeanAbsGrayError(frame.gray, rgb), 1.0) << "frame " << t;
      // Grey pictures carry no colour; 4:2:0 blurs colour edges.
      if (c.format != AV_PIX_FMT_GRAY8) {
        EXPECT_LT(MeanAbsRgbError(frame.rgb, rgb), 3.0) << "frame " << t;
      }
    }
  }
}

// |a - b| over two planes of the same size: its mean, and the share of samples within 2.
struct PlaneDifference {
  double mean = 0;
  double within_2 = 0;
};
PlaneDifference Difference(const Image<uint8_t>& a, const Image<uint8_t>& b) {
  PlaneDifference d;
  EXPECT_EQ(a.width(), b.width());
  EXPECT_EQ(a.height(), b.height());
  if (a.width() != b.width() || a.height() != b.height()) return {1e9, 0};
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      const int e = std::abs(a(x, y) - b(x, y));
      d.mean += e;
      d.within_2 += e <= 2 ? 1 : 0;
    }
  }
  d.mean /= a.width() * a.height();
  d.within_2 /= a.width() * a.height();
  return d;
}

TEST(VideoSource, EveryPixelFormatGivesChromaCloseToTheRgbFilesChroma) {
  testing::TempDir dir;
  // yuv420p straight from the planes (limited range expanded); the others through libswscale.
  // Grey video has neutral chroma. 33x25: odd planes, rounded up. (NUT keeps no range tag:
  // full-range yuvj420p would read back as limited, so it is not among the cases.)
  const struct {
    AVPixelFormat format;
    bool full_range;
    ImageSize size;
  } cases[] = {{AV_PIX_FMT_YUV420P, false, {kWidth, kHeight}},      {AV_PIX_FMT_YUV420P, false, {33, 25}},
               {AV_PIX_FMT_NV12, false, {kWidth, kHeight}},         {AV_PIX_FMT_YUV444P, false, {kWidth, kHeight}},
               {AV_PIX_FMT_YUV420P10LE, false, {kWidth, kHeight}}, {AV_PIX_FMT_RGB24, true, {kWidth, kHeight}},
               {AV_PIX_FMT_GRAY8, true, {kWidth, kHeight}}};
  constexpr int kRawFrames = 2;
  for (const auto& c : cases) {
    SCOPED_TRACE(fmt::format("{} {}x{}", av_get_pix_fmt_name(c.format), c.size.width, c.size.height));
    const fs::path path = dir / fmt::format("{}_{}.nut", av_get_pix_fmt_name(c.format), c.size.width);
    WriteRawVideo(path, c.format, c.full_range, kRawFrames, c.size);
    FrameSourceOptions options;
    options.chroma = true;
    auto source = OpenVideo(path, options);
    ASSERT_TRUE(source.ok()) << source.status().message();
    const std::vector<Frame> frames = ReadAll(**source);
    ASSERT_EQ(frames.size(), static_cast<size_t>(kRawFrames));
    for (int t = 0; t < kRawFrames; ++t) {
      const Frame& frame = frames[static_cast<size_t>(t)];
      Image<uint8_t> u, v;
      ChromaFromRgb(ClipFrame(c.size.width, c.size.height, t).view(), u, v);
      if (c.format == AV_PIX_FMT_GRAY8) {
        u = Image<uint8_t>(u.width(), u.height(), 128);
        v = Image<uint8_t>(v.width(), v.height(), 128);
      }
      ASSERT_EQ(frame.u.width(), (c.size.width + 1) / 2);
      ASSERT_EQ(frame.u.height(), (c.size.height + 1) / 2);
      const PlaneDifference du = Difference(frame.u, u), dv = Difference(frame.v, v);
      // Rounding in the two conversions (limited range: about half a level), and at the
      // square's sharp edges the sample positions of libswscale's 4:2:0 (up to 30 levels there).
      EXPECT_LT(du.mean, 1.5) << "frame " << t;
      EXPECT_LT(dv.mean, 1.5) << "frame " << t;
      EXPECT_GE(du.within_2, 0.9) << "frame " << t;
      EXPECT_GE(dv.within_2, 0.9) << "frame " << t;
      EXPECT_TRUE(frame.rgb.empty());
    }
  }
}

// 32x32 tiles of six colours (3 x 2 tiles): flat areas where H.264 keeps chroma well.
Image<Rgb8> ColourTiles(int width, int height) {
  const Rgb8 colours[6] = {{200, 40, 40}, {40, 170, 60}, {50, 60, 200}, {220, 200, 60}, {60, 190, 200}, {150, 120, 100}};
  Image<Rgb8> rgb(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) rgb(x, y) = colours[(y / 32 * 3 + x / 32) % 6];
  }
  return rgb;
}

TEST(VideoRoundTrip, H264ChromaIsWithinAFewLevelsOfThePngChroma) {
  testing::TempDir dir;
  const ImageSize size{96, 64};
  const Image<Rgb8> tiles = ColourTiles(size.width, size.height);
  {
    auto writer = VideoWriter::Open(dir / "tiles.mp4", size, kFps);
    ASSERT_TRUE(writer.ok()) << writer.status().message();
    for (int t = 0; t < 3; ++t) ASSERT_TRUE((*writer)->Write(tiles.view()).ok());
    ASSERT_TRUE((*writer)->Close().ok());
  }
  ASSERT_TRUE(WritePng(dir / "tiles.png", tiles.view()).ok());
  FrameSourceOptions options;
  options.chroma = true;
  auto video = OpenVideo(dir / "tiles.mp4", options);
  ASSERT_TRUE(video.ok()) << video.status().message();
  auto png = OpenFrameSource({FrameSourceSpec::Kind::kImages, (dir / "tiles.png").string()}, options);
  ASSERT_TRUE(png.ok()) << png.status().message();
  Frame from_png;
  ASSERT_TRUE(*(*png)->Read(from_png));
  const std::vector<Frame> frames = ReadAll(**video);
  ASSERT_EQ(frames.size(), 3u);
  for (const Frame& frame : frames) {
    ASSERT_EQ(frame.u.width(), 48);
    ASSERT_EQ(frame.u.height(), 32);
    // Inside the tiles (chroma samples 2 or more away from a tile's edge).
    int max_error = 0;
    for (int j = 0; j < 32; ++j) {
      for (int i = 0; i < 48; ++i) {
        if (i % 16 < 2 || i % 16 > 13 || j % 16 < 2 || j % 16 > 13) continue;
        max_error = std::max({max_error, std::abs(frame.u(i, j) - from_png.u(i, j)),
                              std::abs(frame.v(i, j) - from_png.v(i, j))});
      }
    }
    EXPECT_LE(max_error, 3);
    EXPECT_LT(Difference(frame.u, from_png.u).mean, 1.5);
    EXPECT_LT(Difference(frame.v, from_png.v).mean, 1.5);
    EXPECT_LE(Difference(frame.gray, from_png.gray).mean, 1.5);
  }
}

TEST(VideoSource, ChromaOffLeavesUAndVEmpty) {
  testing::TempDir dir;
  WriteClip(dir / "clip.mp4", 2);
  auto source = OpenVideo(dir / "clip.mp4");
  ASSERT_TRUE(source.ok()) << source.status().message();
  Frame frame;
  frame.u = Image<uint8_t>(4, 4);  // a reused frame loses its old planes
  frame.v = Image<uint8_t>(4, 4);
  ASSERT_TRUE(*(*source)->Read(frame));
  EXPECT_TRUE(frame.u.empty());
  EXPECT_TRUE(frame.v.empty());
}

TEST(StreamSource, ReadsAnythingAvformatOpensWithoutAFrameCount) {
  testing::TempDir dir;
  WriteClip(dir / "clip.mkv");
  auto source = OpenFrameSource({FrameSourceSpec::Kind::kStream, (dir / "clip.mkv").string()}, {});
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->Describe(), fmt::format("stream '{}' (h264, 160x120, 25 fps)", (dir / "clip.mkv").string()));
  EXPECT_EQ((*source)->frame_count(), std::nullopt);
  EXPECT_EQ(ReadAll(**source).size(), static_cast<size_t>(kFrames));
  EXPECT_EQ((*source)->SkipTo(3).message(),
            fmt::format("stream '{}': cannot skip back to frame 3 in a live stream (next frame is 20)",
                        (dir / "clip.mkv").string()));
}

TEST(StreamSource, RefusedConnectionIsAnIoErrorThatHidesThePassword) {
  auto source = OpenFrameSource({FrameSourceSpec::Kind::kStream, "rtsp://user:secret@127.0.0.1:1/cam"}, {});
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().code(), StatusCode::kIoError);
  EXPECT_EQ(source.status().message().rfind("stream 'rtsp://user:***@127.0.0.1:1/cam': cannot open: ", 0), 0u)
      << source.status().message();
  EXPECT_EQ(source.status().message().find("secret"), std::string::npos) << source.status().message();
}

TEST(StreamSource, SilentServerTimesOutInsteadOfHanging) {
  // A socket that listens but never answers: the kernel accepts the connection, nobody speaks.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof(address);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&address), length), 0);
  ASSERT_EQ(::listen(fd, 4), 0);
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length), 0);
  const std::string url = fmt::format("http://127.0.0.1:{}/cam.mp4", ntohs(address.sin_port));
  FrameSourceOptions options;
  options.stream_timeout_ms = 300;
  auto source = OpenFrameSource({FrameSourceSpec::Kind::kStream, url}, options);
  ::close(fd);
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().code(), StatusCode::kIoError);
  EXPECT_EQ(source.status().message(), fmt::format("stream '{}': cannot open: no answer within 300 ms", url));
}

// Issue 39: a FIFO where a video file is expected blocked `occmap run` and `calibrate
// --board-video` for good (open(2) waits for a writer): refused without opening it.
TEST(VideoSource, AFifoIsRefusedWithoutOpeningIt) {
  testing::TempDir dir;
  ASSERT_EQ(::mkfifo((dir / "c1.mp4").c_str(), 0600), 0);
  auto source = OpenVideo(dir / "c1.mp4");
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.status().code(), StatusCode::kInvalidInput);
  EXPECT_EQ(source.status().message(),
            fmt::format("video '{}': expected a regular file, found a FIFO", (dir / "c1.mp4").string()));
}

// A stream from a FIFO (another program writes MPEG-TS or Matroska into it): read as it comes,
// to its end when the writer closes.
TEST(StreamSource, AFifoIsReadUntilItsWriterCloses) {
  testing::TempDir dir;
  WriteClip(dir / "clip.mkv");
  const std::string clip = *ReadFileToString(dir / "clip.mkv");
  const fs::path fifo = dir / "cam.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Read-write: a writer from the start (no race with the source's open), never a reader.
  const int writer = ::open(fifo.c_str(), O_RDWR | O_CLOEXEC);
  ASSERT_GE(writer, 0);
  // The writer closes only once the source has the FIFO open: a FIFO's buffered bytes are
  // dropped when its last open end closes, and a clip smaller than the pipe's buffer is written
  // before the source opens it.
  std::atomic<bool> opened{false};
  std::thread feed([&] {
    for (size_t at = 0; at < clip.size();) {
      const ssize_t n = ::write(writer, clip.data() + at, clip.size() - at);
      if (n <= 0) break;
      at += static_cast<size_t>(n);
    }
    while (!opened.load()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ::close(writer);
  });
  auto source = OpenFrameSource({FrameSourceSpec::Kind::kStream, fifo.string()}, {});
  opened = true;
  const size_t frames = source.ok() ? ReadAll(**source).size() : 0;
  feed.join();
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ(frames, static_cast<size_t>(kFrames));
}

// Issue 39: a stream from a FIFO blocked in open(2) (no writer) or read(2) (a silent writer),
// deaf to the stream timeout and to the run's stop (SIGTERM).
TEST(StreamSource, AFifoWithoutAWriterOrWithASilentOneIsAnErrorNotAHang) {
  testing::TempDir dir;
  const fs::path fifo = dir / "cam.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  FrameSourceOptions options;
  options.stream_timeout_ms = 300;
  const std::string none =
      fmt::format("stream '{}': cannot open: no data within 300 ms (the FIFO has no writer, or it is silent)", fifo.string());
  auto alone = OpenFrameSource({FrameSourceSpec::Kind::kStream, fifo.string()}, options);
  ASSERT_FALSE(alone.ok());
  EXPECT_EQ(alone.status().code(), StatusCode::kIoError);
  EXPECT_EQ(alone.status().message(), none);

  const int writer = ::open(fifo.c_str(), O_RDWR | O_CLOEXEC);  // holds the FIFO open, writes nothing
  ASSERT_GE(writer, 0);
  auto silent = OpenFrameSource({FrameSourceSpec::Kind::kStream, fifo.string()}, options);
  ASSERT_FALSE(silent.ok());
  EXPECT_EQ(silent.status().message(), none);
  // A few bytes, then silence: FFmpeg's reads wait without blocking, to the timeout.
  ASSERT_EQ(::write(writer, "\x1a\x45\xdf\xa3", 4), 4);
  auto stalled = OpenFrameSource({FrameSourceSpec::Kind::kStream, fifo.string()}, options);
  ASSERT_FALSE(stalled.ok());
  EXPECT_EQ(stalled.status().message(), fmt::format("stream '{}': cannot open: no answer within 300 ms", fifo.string()));
  // A stop (the run's SIGTERM sets it) ends the wait however long the timeout.
  std::atomic<bool> stop{false};
  options.stream_timeout_ms = 3'600'000;
  options.cancel = &stop;
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    stop = true;
  });
  auto stopped = OpenFrameSource({FrameSourceSpec::Kind::kStream, fifo.string()}, options);
  stopper.join();
  EXPECT_FALSE(stopped.ok());
  ::close(writer);
}

TEST(VideoWriter, OddSizeIsPaddedToEven) {
  testing::TempDir dir;
  WriteClip(dir / "odd.mp4", 5, {81, 61}, 10);
  auto source = OpenVideo(dir / "odd.mp4");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ((*source)->size(), (ImageSize{82, 62}));
  const std::vector<Frame> frames = ReadAll(**source);
  ASSERT_EQ(frames.size(), 5u);
  // The padding repeats the last column and row.
  const Frame& last = frames.back();
  double diff = 0;
  for (int y = 0; y < 61; ++y) diff += std::abs(last.gray(81, y) - last.gray(80, y));
  for (int x = 0; x < 81; ++x) diff += std::abs(last.gray(x, 61) - last.gray(x, 60));
  EXPECT_LT(diff / (61 + 81), 4.0);
}

TEST(VideoWriter, DestroyedWithoutCloseLeavesNoFileAndNoTemporary) {
  testing::TempDir dir;
  {
    auto writer = VideoWriter::Open(dir / "abandoned.mp4", {kWidth, kHeight}, kFps);
    ASSERT_TRUE(writer.ok()) << writer.status().message();
    ASSERT_TRUE((*writer)->Write(ClipFrame(kWidth, kHeight, 0).view()).ok());
    EXPECT_EQ(FilesIn(dir.path()).size(), 1u);  // the temporary
  }
  EXPECT_TRUE(FilesIn(dir.path()).empty());
}

TEST(VideoWriter, CloseRenamesTheFinishedFileIntoPlace) {
  testing::TempDir dir;
  auto writer = VideoWriter::Open(dir / "out.mp4", {kWidth, kHeight}, kFps);
  ASSERT_TRUE(writer.ok()) << writer.status().message();
  EXPECT_EQ((*writer)->codec_name(), "libx264");
  for (int t = 0; t < 3; ++t) ASSERT_TRUE((*writer)->Write(ClipFrame(kWidth, kHeight, t).view()).ok());
  std::vector<std::string> names = FilesIn(dir.path());
  ASSERT_EQ(names.size(), 1u);
  EXPECT_EQ(names[0].rfind(".tmp-out-", 0), 0u) << names[0];
  EXPECT_FALSE(fs::exists(dir / "out.mp4"));
  ASSERT_TRUE((*writer)->Close().ok());
  EXPECT_EQ(FilesIn(dir.path()), std::vector<std::string>{"out.mp4"});
  writer->reset();
  EXPECT_EQ(FilesIn(dir.path()), std::vector<std::string>{"out.mp4"});
  auto source = OpenVideo(dir / "out.mp4");
  ASSERT_TRUE(source.ok()) << source.status().message();
  EXPECT_EQ(ReadAll(**source).size(), 3u);
}

TEST(VideoWriter, AHigherCrfGivesASmallerFileAndLargerErrors) {
  testing::TempDir dir;
  double previous_error = -1;
  uintmax_t previous_size = 0;
  for (int crf : {12, 28, 44}) {
    const fs::path path = dir / fmt::format("crf{}.mp4", crf);
    VideoWriterOptions options;
    options.crf = crf;
    WriteClip(path, kFrames, {kWidth, kHeight}, kFps, options);
    auto source = OpenVideo(path, {.colour = true});
    ASSERT_TRUE(source.ok()) << source.status().message();
    const std::vector<Frame> frames = ReadAll(**source);
    ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames));
    double error = 0;
    for (int t = 0; t < kFrames; ++t) error += MeanAbsRgbError(frames[static_cast<size_t>(t)].rgb, ClipFrame(kWidth, kHeight, t));
    const uintmax_t size = fs::file_size(path);
    if (previous_error >= 0) {
      EXPECT_GT(error, previous_error) << "crf " << crf;
      EXPECT_LT(size, previous_size) << "crf " << crf;
    }
    previous_error = error;
    previous_size = size;
  }
}

TEST(VideoWriter, BadArgumentsAreErrorsNamingTheFile) {
  testing::TempDir dir;
  const std::string path = (dir / "x.mp4").string();
  auto writer = VideoWriter::Open(dir / "x.xyz", {kWidth, kHeight}, kFps);
  EXPECT_EQ(writer.status().message(), fmt::format("'{}': expected a video file extension (.mp4, .mkv, .avi, .mov), "
                                                   "found '.xyz'",
                                                   (dir / "x.xyz").string()));
  writer = VideoWriter::Open(dir / "x.mp4", {0, 10}, kFps);
  EXPECT_EQ(writer.status().message(), fmt::format("'{}': video size: expected 1..16384 x 1..16384, found 0x10", path));
  writer = VideoWriter::Open(dir / "x.mp4", {kWidth, kHeight}, 0);
  EXPECT_EQ(writer.status().message(), fmt::format("'{}': frame rate: expected 0 < fps <= 1000, found 0", path));
  writer = VideoWriter::Open(dir / "x.mp4", {kWidth, kHeight}, kFps, {.encoder = "vp9"});
  EXPECT_EQ(writer.status().message(),
            fmt::format("'{}': encoder: expected '', 'libx264' or 'mpeg4', found 'vp9'", path));
  VideoWriterOptions bad_crf;
  bad_crf.crf = 60;
  writer = VideoWriter::Open(dir / "x.mp4", {kWidth, kHeight}, kFps, bad_crf);
  EXPECT_EQ(writer.status().message(), fmt::format("'{}': crf: expected -1 (the default, 23) or 0..51, found 60", path));
  writer = VideoWriter::Open(dir / "no-such-folder" / "x.mp4", {kWidth, kHeight}, kFps);
  EXPECT_EQ(writer.status().code(), StatusCode::kIoError) << writer.status().message();

  writer = VideoWriter::Open(dir / "x.mp4", {kWidth, kHeight}, kFps);
  ASSERT_TRUE(writer.ok());
  const Status status = (*writer)->Write(ClipFrame(10, 10, 0).view());
  EXPECT_EQ(status.message(),
            fmt::format("'{}': frame 0: expected 160x120 (the size given to Open), found 10x10", path));
}

}  // namespace
}  // namespace occmap
