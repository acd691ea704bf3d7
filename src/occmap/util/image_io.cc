#include "occmap/util/image_io.h"

#include <fmt/core.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "occmap/util/file_util.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

Result<cv::Mat> Decode(const fs::path& path, int flags) {
  OCCMAP_ASSIGN_OR_RETURN(std::string bytes, ReadFileToString(path));
  if (bytes.empty()) return DataLoss(fmt::format("'{}': empty file, expected an image", path.string()));
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

Status Encode(const fs::path& path, const cv::Mat& mat) {
  std::vector<uchar> buffer;
  try {
    if (!cv::imencode(".png", mat, buffer)) {
      return IoError(fmt::format("'{}': PNG encoding failed", path.string()));
    }
  } catch (const cv::Exception& e) {
    return IoError(fmt::format("'{}': PNG encoding failed: {}", path.string(), e.what()));
  }
  return WriteFileAtomic(path, std::as_bytes(std::span(buffer.data(), buffer.size())));
}

}  // namespace

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

Status WritePng(const fs::path& path, ImageView<const Rgb8> image) {
  cv::Mat bgr(image.height(), image.width(), CV_8UC3);
  for (int y = 0; y < image.height(); ++y) {
    const Rgb8* src = image.row(y);
    auto* dst = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < image.width(); ++x) dst[x] = cv::Vec3b(src[x].b, src[x].g, src[x].r);
  }
  return Encode(path, bgr);
}

}  // namespace occmap
