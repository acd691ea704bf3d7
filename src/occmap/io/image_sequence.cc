// Image sequences and mask sequences: a printf-style pattern, a folder of images, or one file.
#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "occmap/io/frame_source.h"
#include "occmap/io/frame_times.h"
#include "occmap/util/image_io.h"
#include "occmap/util/yuv.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

constexpr const char* kPatternExample = "'frame_%06d.png'";

// A printf-style file pattern with exactly one integer conversion: prefix, number, suffix.
// Supported conversion: %[-0][width][.precision]{d,i,u} with optional length modifiers
// (hh, h, l, ll, j, z, t), which do not matter here; "%%" is a literal '%'.
struct FilePattern {
  std::string prefix;
  std::string suffix;
  bool left_align = false;
  bool zero_pad = false;
  int width = 0;
  int precision = 0;  // minimum number of digits

  std::string Format(int64_t number) const {
    std::string digits = std::to_string(number);
    if (static_cast<int>(digits.size()) < precision) {
      digits.insert(0, static_cast<size_t>(precision) - digits.size(), '0');
    }
    if (static_cast<int>(digits.size()) < width) {
      const size_t pad = static_cast<size_t>(width) - digits.size();
      if (left_align) {
        digits.append(pad, ' ');
      } else {
        digits.insert(0, pad, zero_pad && precision == 0 ? '0' : ' ');
      }
    }
    return prefix + digits + suffix;
  }
};

Result<int> ParseSmallNumber(const std::string& text, size_t& i) {
  int value = 0;
  while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
    value = value * 10 + (text[i] - '0');
    if (value > 64) return InvalidInput("a width or precision above 64");
    ++i;
  }
  return value;
}

Result<FilePattern> ParseFilePattern(const std::string& pattern) {
  const auto bad = [&](const std::string& found) {
    return InvalidInput(
        fmt::format("'{}': expected a printf-style pattern with exactly one integer conversion such as {}, found {}",
                    pattern, kPatternExample, found));
  };
  FilePattern out;
  int conversions = 0;
  std::string* part = &out.prefix;
  for (size_t i = 0; i < pattern.size();) {
    if (pattern[i] != '%') {
      part->push_back(pattern[i++]);
      continue;
    }
    const size_t start = i++;
    if (i < pattern.size() && pattern[i] == '%') {
      part->push_back('%');
      ++i;
      continue;
    }
    FilePattern spec;
    while (i < pattern.size() && (pattern[i] == '-' || pattern[i] == '0')) {
      (pattern[i] == '-' ? spec.left_align : spec.zero_pad) = true;
      ++i;
    }
    if (i < pattern.size() && std::string_view("+ #'").find(pattern[i]) != std::string_view::npos) {
      return bad(fmt::format("the unsupported flag '{}' in '{}'", pattern[i], pattern.substr(start, i + 1 - start)));
    }
    auto width = ParseSmallNumber(pattern, i);
    if (!width.ok()) return bad(width.status().message());
    spec.width = *width;
    if (i < pattern.size() && pattern[i] == '.') {
      ++i;
      auto precision = ParseSmallNumber(pattern, i);
      if (!precision.ok()) return bad(precision.status().message());
      spec.precision = *precision;
    }
    while (i < pattern.size() && std::string_view("hljzt").find(pattern[i]) != std::string_view::npos) ++i;
    if (i >= pattern.size()) return bad(fmt::format("an unfinished conversion '{}' at the end", pattern.substr(start)));
    const char conversion = pattern[i++];
    if (conversion != 'd' && conversion != 'i' && conversion != 'u') {
      return bad(fmt::format("the non-integer conversion '{}'", pattern.substr(start, i - start)));
    }
    if (++conversions > 1) return bad("more than one conversion");
    out.left_align = spec.left_align;
    out.zero_pad = spec.zero_pad;
    out.width = spec.width;
    out.precision = spec.precision;
    part = &out.suffix;
  }
  if (conversions == 0) return bad("no conversion");
  return out;
}

bool IsImageFile(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg";
}

bool FileExists(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

class ImageSequence final : public FrameSource {
 public:
  // Files: a fixed list (folder or single file). Pattern: numbered files from `first_number`.
  using Files = std::vector<fs::path>;
  struct Numbered {
    FilePattern pattern;
    int64_t first_number = 0;
  };

  ImageSequence(std::string location, bool masks, const FrameSourceOptions& options,
                std::variant<Files, Numbered> files)
      : location_(std::move(location)),
        masks_(masks),
        colour_(options.colour && !masks),
        chroma_(options.chroma && !masks),
        image_fps_(options.image_fps),
        image_times_s_(options.image_times_s),
        files_(std::move(files)) {
    const char* what = masks_ ? "mask" : "image";
    if (std::holds_alternative<Numbered>(files_)) {
      name_ = fmt::format("{} sequence '{}'", what, location_);
    } else if (std::get<Files>(files_).size() == 1 && FileExists(location_)) {
      name_ = fmt::format("{} '{}'", what, location_);
    } else {
      name_ = fmt::format("{} folder '{}'", what, location_);
    }
  }

  // Decodes the first frame: the size of the sequence. Kept for the first Read.
  Status Init() {
    OCCMAP_RETURN_IF_ERROR(Decode(0, PathOf(0), first_));
    size_ = {first_.gray.width(), first_.gray.height()};
    have_first_ = true;
    return Status::Ok();
  }

  std::string Describe() const override {
    if (const auto* numbered = std::get_if<Numbered>(&files_)) {
      return fmt::format("{} (from {}, {}x{})", name_, numbered->first_number, size_.width, size_.height);
    }
    const size_t n = std::get<Files>(files_).size();
    if (n == 1) return fmt::format("{} ({}x{})", name_, size_.width, size_.height);
    return fmt::format("{} ({} files, {}x{})", name_, n, size_.width, size_.height);
  }
  ImageSize size() const override { return size_; }
  std::optional<double> fps() const override {
    if (image_times_s_.size() >= 2) return MeanRateHz(image_times_s_);
    if (image_fps_ > 0) return image_fps_;
    return std::nullopt;
  }
  std::optional<int64_t> frame_count() const override {
    if (const auto* files = std::get_if<Files>(&files_)) return static_cast<int64_t>(files->size());
    return std::nullopt;  // a pattern ends at its first missing file, and may still be growing
  }
  std::optional<int64_t> next_index() const override { return next_; }

  Result<bool> Read(Frame& frame) override {
    const int64_t index = next_;
    if (!Exists(index)) return false;
    if (!image_times_s_.empty() && index >= static_cast<int64_t>(image_times_s_.size())) {
      return InvalidInput(fmt::format("{}: frame {}: its timestamps give the times of {} images, none for this one",
                                      name_, index, image_times_s_.size()));
    }
    if (index == 0 && have_first_) {
      frame.gray = std::move(first_.gray);
      frame.rgb = std::move(first_.rgb);
      frame.u = std::move(first_.u);
      frame.v = std::move(first_.v);
      have_first_ = false;
    } else {
      OCCMAP_RETURN_IF_ERROR(Decode(index, PathOf(index), frame));
    }
    if (!colour_) frame.rgb = Image<Rgb8>();
    if (!chroma_) {
      frame.u = Image<uint8_t>();
      frame.v = Image<uint8_t>();
    }
    frame.index = index;
    if (!image_times_s_.empty()) {
      frame.timestamp_s = image_times_s_[static_cast<size_t>(index)];
    } else {
      frame.timestamp_s = image_fps_ > 0 ? static_cast<double>(index) / image_fps_ : std::nan("");
    }
    next_ = index + 1;
    return true;
  }

  Status SkipTo(int64_t index) override {
    if (index < 0) {
      return InvalidInput(fmt::format("{}: cannot skip to frame {}: expected an index >= 0", name_, index));
    }
    // Every frame before `index` must exist (a pattern ends at its first missing file).
    for (int64_t i = std::min(index, next_); i < index; ++i) {
      if (!Exists(i)) {
        return InvalidInput(
            fmt::format("{}: cannot skip to frame {}: the sequence ends after {} frames", name_, index, i));
      }
    }
    if (index != 0) {
      have_first_ = false;
      first_ = Frame();
    }
    next_ = index;
    return Status::Ok();
  }

 private:
  fs::path PathOf(int64_t index) const {
    if (const auto* numbered = std::get_if<Numbered>(&files_)) {
      return numbered->pattern.Format(numbered->first_number + index);
    }
    return std::get<Files>(files_)[static_cast<size_t>(index)];
  }

  bool Exists(int64_t index) const {
    if (std::holds_alternative<Numbered>(files_)) return FileExists(PathOf(index));
    return index < static_cast<int64_t>(std::get<Files>(files_).size());
  }

  Status Decode(int64_t index, const fs::path& path, Frame& frame) const {
    const std::string context = fmt::format("{}: frame {}", name_, index);
    if (colour_ || chroma_) {
      // Grey, u and v from the same RGB pixels: gray is the Y of util/yuv.h's formulas.
      auto rgb = ReadRgbImage(path);
      if (!rgb.ok()) return rgb.status().WithContext(context);
      frame.rgb = std::move(rgb).value();
      LumaFromRgb(frame.rgb.view(), frame.gray);
      if (chroma_) ChromaFromRgb(frame.rgb.view(), frame.u, frame.v);
    } else {
      auto gray = ReadGrayImage(path);
      if (!gray.ok()) return gray.status().WithContext(context);
      frame.gray = std::move(gray).value();
    }
    const ImageSize found{frame.gray.width(), frame.gray.height()};
    if (size_.width > 0 && found != size_) {  // size_ is set once the first frame is decoded
      return InvalidInput(fmt::format("{}: '{}': expected {}x{} (the size of the first frame), found {}x{}", context,
                                      path.string(), size_.width, size_.height, found.width, found.height));
    }
    return Status::Ok();
  }

  std::string location_;
  std::string name_;  // for messages: "image sequence 'frames/c1_%06d.png'"
  bool masks_;
  bool colour_;
  bool chroma_;
  double image_fps_;
  std::vector<double> image_times_s_;  // empty: none
  std::variant<Files, Numbered> files_;
  ImageSize size_;
  int64_t next_ = 0;
  Frame first_;  // decoded by Init(), handed out by the first Read
  bool have_first_ = false;
};

}  // namespace

Result<std::unique_ptr<FrameSource>> OpenImageSequence(const std::string& location, bool masks,
                                                       const FrameSourceOptions& options) {
  OCCMAP_RETURN_IF_ERROR(options.Validate());
  std::variant<ImageSequence::Files, ImageSequence::Numbered> files;
  std::error_code ec;
  const fs::path path(location);
  if (fs::is_directory(path, ec)) {
    ImageSequence::Files list;
    for (const fs::directory_entry& entry : fs::directory_iterator(path, ec)) {
      std::error_code entry_ec;
      if (entry.is_regular_file(entry_ec) && IsImageFile(entry.path())) list.push_back(entry.path());
    }
    if (ec) return NotFound(fmt::format("'{}': cannot list folder: {}", location, ec.message()));
    if (list.empty()) {
      return InvalidInput(fmt::format("'{}': expected a folder with .png/.jpg/.jpeg files, found none", location));
    }
    std::sort(list.begin(), list.end(),
              [](const fs::path& a, const fs::path& b) { return a.filename().string() < b.filename().string(); });
    files = std::move(list);
  } else if (FileExists(path)) {
    files = ImageSequence::Files{path};
  } else if (location.find('%') != std::string::npos) {
    OCCMAP_ASSIGN_OR_RETURN(FilePattern pattern, ParseFilePattern(location));
    ImageSequence::Numbered numbered{std::move(pattern), 0};
    if (!FileExists(numbered.pattern.Format(0))) {
      if (!FileExists(numbered.pattern.Format(1))) {
        return NotFound(fmt::format("no frame found for pattern '{}': expected '{}' or '{}'", location,
                                    numbered.pattern.Format(0), numbered.pattern.Format(1)));
      }
      numbered.first_number = 1;
    }
    files = std::move(numbered);
  } else {
    return NotFound(
        fmt::format("'{}': not found: expected an image file, a folder, or a printf-style pattern with one integer "
                    "conversion such as {}",
                    location, kPatternExample));
  }
  auto source = std::make_unique<ImageSequence>(location, masks, options, std::move(files));
  OCCMAP_RETURN_IF_ERROR(source->Init());
  return std::unique_ptr<FrameSource>(std::move(source));
}

}  // namespace occmap
