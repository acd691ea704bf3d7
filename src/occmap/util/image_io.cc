#include "occmap/util/image_io.h"

#include <fmt/core.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>
#include <array>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "occmap/util/file_util.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

uint32_t Crc32(const unsigned char* p, size_t n) {
  static const auto table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  uint32_t c = 0xFFFFFFFFu;
  for (size_t i = 0; i < n; ++i) c = table[(c ^ p[i]) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

// The chunks of a PNG (other images pass) walked before OpenCV sees it: libpng prints its own "libpng error: ..."
// line on stderr for a truncated or corrupt file, before our message. Lengths, CRCs, IHDR
// first and IEND last are checked here; only a corrupt compressed stream reaches libpng.
// Not inlined: inlined into Decode, GCC 12 warns (-Wmaybe-uninitialized) about the Result's string.
Status CheckPixels(std::string_view name, std::string_view format, int64_t width, int64_t height) {
  if (width > 0 && height > 0 && width * height <= kMaxImagePixels) return Status::Ok();
  if (width <= 0 || height <= 0) {
    return DataLoss(fmt::format("'{}': {} header says {}x{} pixels, expected a positive size", name, format, width, height));
  }
  return ResourceExhausted(fmt::format("'{}': {} of {}x{} pixels, expected at most {} pixels (8192 x 4096); refused "
                                       "before decoding",
                                       name, format, width, height, kMaxImagePixels));
}

uint32_t Be32(const unsigned char* p) { return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3]; }
uint32_t Be16(const unsigned char* p) { return (uint32_t{p[0]} << 8) | p[1]; }
int32_t Le32(const unsigned char* p) {
  return static_cast<int32_t>(uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24));
}

// A JPEG's segments walked to its end marker (EOI): the frame header's size checked, the
// entropy-coded data after each scan skipped to the next marker. APPn segments are skipped by
// their length (an EXIF thumbnail's own EOI is not taken for the file's).
Status CheckJpeg(std::string_view name, std::string_view bytes) {
  const auto* b = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t n = bytes.size();
  auto truncated = [&] {
    return DataLoss(fmt::format("'{}': truncated JPEG: {} bytes, no end marker (EOI)", name, n));
  };
  size_t i = 2;
  while (true) {
    if (i >= n) return truncated();
    if (b[i] != 0xFF) {
      return DataLoss(fmt::format("'{}': corrupt JPEG: expected a marker at byte {}, found 0x{:02x}", name, i, b[i]));
    }
    while (i < n && b[i] == 0xFF) ++i;
    if (i >= n) return truncated();
    const unsigned char m = b[i++];
    if (m == 0xD9) return Status::Ok();
    if ((m >= 0xD0 && m <= 0xD7) || m == 0x01) continue;
    if (n - i < 2) return truncated();
    const size_t length = Be16(b + i);
    if (length < 2) return DataLoss(fmt::format("'{}': corrupt JPEG: segment 0x{:02x} at byte {} of length {}", name, m, i - 2, length));
    if (length > n - i) return truncated();
    const bool frame = m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC;
    if (frame && length >= 7) {
      const int64_t height = Be16(b + i + 3), width = Be16(b + i + 5);
      // A height of 0 is given later (DNL): left to the decoder, whose own limit then holds.
      if (height > 0) OCCMAP_RETURN_IF_ERROR(CheckPixels(name, "JPEG", width, height));
    }
    i += length;
    if (m == 0xDA) {  // a scan: its coded data runs to the next marker that is not a stuffed 0xFF or a restart
      while (true) {
        if (i + 1 >= n) return truncated();
        if (b[i] == 0xFF && b[i + 1] != 0x00 && b[i + 1] != 0xFF && !(b[i + 1] >= 0xD0 && b[i + 1] <= 0xD7)) break;
        ++i;
      }
    }
  }
}

// Width and height of a PNM (P1..P6) header: magic, then numbers between whitespace and comments.
Status CheckPnm(std::string_view name, std::string_view bytes) {
  size_t i = 2;
  int64_t dims[2] = {0, 0};
  for (int64_t& d : dims) {
    while (i < bytes.size() && (std::isspace(static_cast<unsigned char>(bytes[i])) || bytes[i] == '#')) {
      if (bytes[i] == '#') {
        while (i < bytes.size() && bytes[i] != '\n') ++i;
      } else {
        ++i;
      }
    }
    if (i >= bytes.size() || !std::isdigit(static_cast<unsigned char>(bytes[i]))) return Status::Ok();  // the decoder says
    while (i < bytes.size() && std::isdigit(static_cast<unsigned char>(bytes[i])) && d <= kMaxImagePixels) {
      d = d * 10 + (bytes[i++] - '0');
    }
  }
  return CheckPixels(name, "PNM image", dims[0], dims[1]);
}

// A chunk's 4-byte type as a message shows it: the letters, or \xNN escapes when a byte is not
// printable ASCII (a raw byte made the message invalid UTF-8: the web API's reply threw).
std::string ChunkName(std::string_view type) {
  std::string out;
  for (const char c : type) {
    const auto u = static_cast<unsigned char>(c);
    out += u >= 0x20 && u < 0x7f ? std::string(1, c) : fmt::format("\\x{:02x}", u);
  }
  return out;
}

[[gnu::noinline]] Status CheckPngChunks(const fs::path& path, std::string_view bytes) {
  if (bytes.size() < 8 || std::memcmp(bytes.data(), "\x89PNG\r\n\x1a\n", 8) != 0) return Status::Ok();  // not a PNG
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  // IHDR's size before anything else: width and height at bytes 16 and 20.
  if (bytes.size() >= 24 && std::memcmp(bytes.data() + 12, "IHDR", 4) == 0) {
    OCCMAP_RETURN_IF_ERROR(CheckPixels(path.string(), "PNG", Be32(p + 16), Be32(p + 20)));
  }
  size_t at = 8;
  bool first = true;
  while (true) {
    if (bytes.size() - at < 12) {
      return DataLoss(fmt::format("'{}': truncated PNG: {} bytes, no IEND chunk", path.string(), bytes.size()));
    }
    const uint32_t length = (uint32_t{p[at]} << 24) | (uint32_t{p[at + 1]} << 16) | (uint32_t{p[at + 2]} << 8) | p[at + 3];
    const std::string type(bytes.substr(at + 4, 4));
    if (length > bytes.size() - at - 12) {
      return DataLoss(fmt::format("'{}': truncated PNG: chunk '{}' at byte {} needs {} bytes, {} left", path.string(),
                                  ChunkName(type), at, length, bytes.size() - at - 12));
    }
    if (first && type != "IHDR") {
      return DataLoss(fmt::format("'{}': expected the PNG's IHDR chunk first, found '{}'", path.string(), ChunkName(type)));
    }
    first = false;
    const uint32_t crc = (uint32_t{p[at + 8 + length]} << 24) | (uint32_t{p[at + 9 + length]} << 16) |
                         (uint32_t{p[at + 10 + length]} << 8) | p[at + 11 + length];
    if (Crc32(p + at + 4, length + 4) != crc) {
      return DataLoss(fmt::format("'{}': corrupt PNG: chunk '{}' at byte {} fails its CRC", path.string(), ChunkName(type), at));
    }
    at += 12 + length;
    if (type == "IEND") return Status::Ok();
  }
}

Result<cv::Mat> Decode(const fs::path& path, int flags) {
  OCCMAP_ASSIGN_OR_RETURN(std::string bytes, ReadFileToString(path));
  if (bytes.empty()) return DataLoss(fmt::format("'{}': empty file, expected an image", path.string()));
  OCCMAP_RETURN_IF_ERROR(CheckEncodedImage(bytes, path.string()));
  cv::Mat mat;
  try {
    mat = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, bytes.data()), flags);
  } catch (const cv::Exception& e) {
    return DataLoss(fmt::format("'{}': cannot decode image: {}", path.string(), e.what()));
  }
  if (mat.empty()) {
    return DataLoss(fmt::format("'{}': cannot decode image (not a PNG/JPEG/... or truncated)",
                                path.string()));
  }
  if (mat.depth() != CV_8U) {
    return InvalidInput(fmt::format("'{}': expected an 8-bit image, found bit depth code {}",
                                    path.string(), mat.depth()));
  }
  return mat;
}

Status Encode(const fs::path& path, const cv::Mat& mat, const char* extension = ".png", const std::vector<int>& params = {}) {
  std::vector<uchar> buffer;
  const char* format = std::string_view(extension) == ".png" ? "PNG" : "JPEG";
  try {
    if (!cv::imencode(extension, mat, buffer, params)) {
      return IoError(fmt::format("'{}': {} encoding failed", path.string(), format));
    }
  } catch (const cv::Exception& e) {
    return IoError(fmt::format("'{}': {} encoding failed: {}", path.string(), format, e.what()));
  }
  return WriteFileAtomic(path, std::as_bytes(std::span(buffer.data(), buffer.size())));
}

}  // namespace

Status CheckEncodedImage(std::string_view bytes, std::string_view name) {
  const auto* b = reinterpret_cast<const unsigned char*>(bytes.data());
  if (bytes.size() >= 8 && std::memcmp(bytes.data(), "\x89PNG\r\n\x1a\n", 8) == 0) return CheckPngChunks(fs::path(name), bytes);
  if (bytes.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) return CheckJpeg(name, bytes);
  if (bytes.size() >= 26 && bytes.substr(0, 2) == "BM") {
    const int64_t width = Le32(b + 18), height = Le32(b + 22);  // height < 0: rows top down
    return CheckPixels(name, "BMP", width, height < 0 ? -height : height);
  }
  if (bytes.size() >= 3 && bytes[0] == 'P' && bytes[1] >= '1' && bytes[1] <= '6' &&
      std::isspace(static_cast<unsigned char>(bytes[2]))) {
    return CheckPnm(name, bytes);
  }
  return Status::Ok();
}

Result<Image<uint8_t>> ReadGrayImage(const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(cv::Mat mat, Decode(path, cv::IMREAD_GRAYSCALE));
  Image<uint8_t> image(mat.cols, mat.rows);
  for (int y = 0; y < mat.rows; ++y) std::memcpy(image.row(y), mat.ptr<uint8_t>(y), mat.cols);
  return image;
}

Result<Image<Rgb8>> ReadRgbImage(const fs::path& path) {
  OCCMAP_ASSIGN_OR_RETURN(cv::Mat bgr, Decode(path, cv::IMREAD_COLOR));
  Image<Rgb8> image(bgr.cols, bgr.rows);
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* src = bgr.ptr<cv::Vec3b>(y);
    Rgb8* dst = image.row(y);
    for (int x = 0; x < bgr.cols; ++x) dst[x] = {src[x][2], src[x][1], src[x][0]};
  }
  return image;
}

Status WritePng(const fs::path& path, ImageView<const uint8_t> image) {
  const cv::Mat mat(image.height(), image.width(), CV_8UC1, const_cast<uint8_t*>(image.data()),
                    static_cast<size_t>(image.stride_elems()));
  return Encode(path, mat);
}

namespace {

cv::Mat ToBgr(ImageView<const Rgb8> image) {
  cv::Mat bgr(image.height(), image.width(), CV_8UC3);
  for (int y = 0; y < image.height(); ++y) {
    const Rgb8* src = image.row(y);
    auto* dst = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < image.width(); ++x) dst[x] = cv::Vec3b(src[x].b, src[x].g, src[x].r);
  }
  return bgr;
}

}  // namespace

Status WritePng(const fs::path& path, ImageView<const Rgb8> image) { return Encode(path, ToBgr(image)); }

Status WriteJpeg(const fs::path& path, ImageView<const Rgb8> image, int quality) {
  if (quality < 1 || quality > 100) {
    return InvalidInput(fmt::format("'{}': JPEG quality: expected 1..100, found {}", path.string(), quality));
  }
  return Encode(path, ToBgr(image), ".jpg", {cv::IMWRITE_JPEG_QUALITY, quality});
}

}  // namespace occmap
