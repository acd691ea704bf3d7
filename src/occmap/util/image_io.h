// Image files (PNG, JPEG, ...) to and from Image<T>, with OpenCV's codecs at the boundary.
//
// Readers check that the file exists and decodes, and name the file in every error. Writers
// encode in memory and write atomically (file_util.h).
//
//   OCCMAP_ASSIGN_OR_RETURN(Image<uint8_t> mask, ReadGrayImage("mask.png"));
//   OCCMAP_RETURN_IF_ERROR(WritePng("map.png", rgb.view()));
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>

#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap {

// The most pixels an image read may have: more is refused from its header, before it is decoded
// (a 1 MB PNG of 30000 x 30000 pixels decoded to 1.85 GB in 8 s). 8192 x 4096 holds 8K UHD.
inline constexpr int64_t kMaxImagePixels = int64_t{1} << 25;

// Checks encoded image bytes before a decoder sees them: the size in a PNG, JPEG, BMP or
// PNM header within kMaxImagePixels; a PNG's chunks (lengths, CRCs, IHDR first, IEND last); a
// JPEG's segments up to its end marker (OpenCV decodes a truncated JPEG without a word, the
// missing rows grey). Other formats pass to the decoder. `name` names the input in messages.
Status CheckEncodedImage(std::string_view bytes, std::string_view name);

// Reads any image OpenCV decodes as 8-bit grey (colour images are converted to luma).
Result<Image<uint8_t>> ReadGrayImage(const std::filesystem::path& path);
// Reads an image as 8-bit RGB.
Result<Image<Rgb8>> ReadRgbImage(const std::filesystem::path& path);

Status WritePng(const std::filesystem::path& path, ImageView<const uint8_t> image);
Status WritePng(const std::filesystem::path& path, ImageView<const Rgb8> image);
// Baseline JPEG (4:2:0 chroma, OpenCV's libjpeg) at a quality of 1..100.
Status WriteJpeg(const std::filesystem::path& path, ImageView<const Rgb8> image, int quality);

}  // namespace occmap
