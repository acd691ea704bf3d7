#include "occmap/eval/change_metrics.h"

#include <fmt/core.h>

#include <algorithm>
#include <atomic>
#include <optional>
#include <set>
#include <system_error>
#include <utility>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <opencv2/imgcodecs.hpp>

#include "occmap/eval/run_outputs.h"
#include "occmap/util/image_io.h"

namespace occmap {
namespace fs = std::filesystem;
namespace {

double Ratio(int64_t num, int64_t den) {
  return den > 0 ? static_cast<double>(num) / static_cast<double>(den) : std::numeric_limits<double>::quiet_NaN();
}

// The subfolder names of dir, sorted (none when dir is not a folder).
std::vector<std::string> Subfolders(const fs::path& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code entry_ec;
    if (it->is_directory(entry_ec)) names.push_back(it->path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// One (camera, frame) to count.
struct MaskPair {
  size_t camera = 0;
  int64_t frame = 0;
  fs::path run, gt, shadow;  // shadow empty: no shadow mask of this frame
};

Status SizeError(const fs::path& path, ImageView<const uint8_t> image, const fs::path& like,
                 ImageView<const uint8_t> like_image) {
  return InvalidInput(fmt::format("{}: expected {}x{} pixels like {}, found {}x{}", path.string(), like_image.width(),
                                  like_image.height(), like.string(), image.width(), image.height()));
}

// Reads one worker's masks (8-bit grey, colour converted to luma, as util's ReadGrayImage),
// keeping its file buffer, and each slot's picture until the slot's next one is decoded. A
// worker reads thousands of 1 MB masks; a picture freed before the next is allocated leaves the
// top of a pool thread's glibc arena free, which glibc gives back to the system and then faults
// in again, 4 KB at a time: 6 cameras x 600 frames x 3 masks of 1280x720 on 2 threads with
// ReadGrayImage per file took 1.17 M minor faults and 46 s of CPU; this way 10 K and 22 s, as
// on 1 thread (2-core x86-64 development machine; zlib's inflate is 79 % of the time).
class MaskReader {
 public:
  // The picture stays valid until the next Read into the same slot (0..2).
  Result<ImageView<const uint8_t>> Read(const fs::path& path, int slot) {
    OCCMAP_RETURN_IF_ERROR(ReadFile(path));
    OCCMAP_RETURN_IF_ERROR(CheckEncodedImage(
        std::string_view(reinterpret_cast<const char*>(bytes_.data()), bytes_.size()), path.string()));
    cv::Mat mat;
    try {
      mat = cv::imdecode(cv::Mat(1, static_cast<int>(bytes_.size()), CV_8UC1, bytes_.data()), cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception& e) {
      return DataLoss(fmt::format("'{}': cannot decode image: {}", path.string(), e.what()));
    }
    if (mat.empty()) {
      return DataLoss(fmt::format("'{}': cannot decode image (not a PNG/JPEG/... or truncated)", path.string()));
    }
    if (mat.type() != CV_8UC1) {
      return InvalidInput(fmt::format("'{}': expected an 8-bit mask, found OpenCV type {}", path.string(), mat.type()));
    }
    decoded_[slot] = mat;
    return ImageView<const uint8_t>(mat.ptr<uint8_t>(0), mat.cols, mat.rows, static_cast<ptrdiff_t>(mat.step[0]));
  }

 private:
  Status ReadFile(const fs::path& path) {
    struct Closer {
      void operator()(std::FILE* f) const { std::fclose(f); }
    };
    std::unique_ptr<std::FILE, Closer> file(std::fopen(path.c_str(), "rb"));
    if (file == nullptr) return NotFound(fmt::format("'{}': cannot open: {}", path.string(), std::strerror(errno)));
    bytes_.clear();
    constexpr size_t kBlock = 1 << 16;
    while (true) {
      const size_t old_size = bytes_.size();
      bytes_.resize(old_size + kBlock);
      const size_t got = std::fread(bytes_.data() + old_size, 1, kBlock, file.get());
      bytes_.resize(old_size + got);
      if (got < kBlock) break;
    }
    if (std::ferror(file.get()) != 0) return DataLoss(fmt::format("'{}': read error", path.string()));
    if (bytes_.empty()) return DataLoss(fmt::format("'{}': empty file, expected an image", path.string()));
    return Status::Ok();
  }

  std::vector<uint8_t> bytes_;
  cv::Mat decoded_[3];
};

Result<ChangeCounts> CountPair(const MaskPair& pair, MaskReader& reader) {
  OCCMAP_ASSIGN_OR_RETURN(const ImageView<const uint8_t> run, reader.Read(pair.run, 0));
  OCCMAP_ASSIGN_OR_RETURN(const ImageView<const uint8_t> gt, reader.Read(pair.gt, 1));
  if (gt.width() != run.width() || gt.height() != run.height()) return SizeError(pair.gt, gt, pair.run, run);
  ImageView<const uint8_t> shadow;
  if (!pair.shadow.empty()) {
    OCCMAP_ASSIGN_OR_RETURN(shadow, reader.Read(pair.shadow, 2));
    if (shadow.width() != run.width() || shadow.height() != run.height()) {
      return SizeError(pair.shadow, shadow, pair.run, run);
    }
  }
  return CountChanges(run, gt, shadow);
}

}  // namespace

ChangeCounts& ChangeCounts::operator+=(const ChangeCounts& other) {
  tp += other.tp;
  fp += other.fp;
  fn += other.fn;
  tn += other.tn;
  shadow_pixels += other.shadow_pixels;
  shadow_changed += other.shadow_changed;
  return *this;
}

ChangeCounts CountChanges(ImageView<const uint8_t> run, ImageView<const uint8_t> gt, ImageView<const uint8_t> shadow) {
  OCCMAP_CHECK(run.width() == gt.width() && run.height() == gt.height(), "CountChanges: run and gt sizes differ");
  OCCMAP_CHECK(shadow.empty() || (shadow.width() == run.width() && shadow.height() == run.height()),
               "CountChanges: shadow size differs");
  ChangeCounts c;
  const int width = run.width();
  for (int y = 0; y < run.height(); ++y) {
    const uint8_t* r = run.row(y);
    const uint8_t* g = gt.row(y);
    // Per-row sums in 32 bits (a row is far below 2^31 pixels): the loop vectorises.
    uint32_t run_set = 0, gt_set = 0, both = 0;
    for (int x = 0; x < width; ++x) {
      const uint32_t rs = r[x] != 0;
      const uint32_t gs = g[x] != 0;
      run_set += rs;
      gt_set += gs;
      both += rs & gs;
    }
    c.tp += both;
    c.fp += run_set - both;
    c.fn += gt_set - both;
    c.tn += width - (run_set + gt_set - both);
    if (shadow.empty()) continue;
    const uint8_t* s = shadow.row(y);
    uint32_t shadow_set = 0, shadow_changed = 0;
    for (int x = 0; x < width; ++x) {
      const uint32_t ss = s[x] != 0;
      shadow_set += ss;
      shadow_changed += ss & static_cast<uint32_t>(r[x] != 0);
    }
    c.shadow_pixels += shadow_set;
    c.shadow_changed += shadow_changed;
  }
  return c;
}

ChangeMetrics MakeChangeMetrics(int64_t frames, int64_t shadow_frames, const ChangeCounts& counts) {
  ChangeMetrics m;
  m.frames = frames;
  m.shadow_frames = shadow_frames;
  m.counts = counts;
  m.precision = Ratio(counts.tp, counts.tp + counts.fp);
  m.recall = Ratio(counts.tp, counts.tp + counts.fn);
  m.f1 = Ratio(2 * counts.tp, 2 * counts.tp + counts.fp + counts.fn);
  if (shadow_frames > 0) m.shadow_changed_fraction = Ratio(counts.shadow_changed, counts.shadow_pixels);
  return m;
}

Result<ChangeEvaluation> EvaluateChangeMasks(const fs::path& run_changes_dir, const fs::path& gt_dir, Context& ctx,
                                             std::vector<std::string>& notes) {
  const fs::path gt_changes_dir = gt_dir / "changes";
  const fs::path gt_shadows_dir = gt_dir / "shadows";
  const std::vector<std::string> run_cameras = Subfolders(run_changes_dir);
  const std::vector<std::string> gt_cameras = Subfolders(gt_changes_dir);
  const std::set<std::string> gt_set(gt_cameras.begin(), gt_cameras.end());
  const std::set<std::string> run_set(run_cameras.begin(), run_cameras.end());
  for (const std::string& id : run_cameras) {
    if (!gt_set.contains(id)) {
      notes.push_back(fmt::format("changes: camera {} is in the run's changes/ but not in the dataset's gt/changes/; skipped", id));
    }
  }
  for (const std::string& id : gt_cameras) {
    if (!run_set.contains(id)) {
      notes.push_back(fmt::format("changes: camera {} is in the dataset's gt/changes/ but not in the run's changes/; skipped", id));
    }
  }

  ChangeEvaluation evaluation;
  std::vector<MaskPair> pairs;
  std::vector<int64_t> camera_frames, camera_shadow_frames;
  std::set<int64_t> frames;
  for (const std::string& id : run_cameras) {
    if (!gt_set.contains(id)) continue;
    const size_t camera = evaluation.cameras.size();
    evaluation.cameras.push_back({id, {}});
    OCCMAP_ASSIGN_OR_RETURN(const auto run_files, ListFramePngs(run_changes_dir / id, "mask"));
    OCCMAP_ASSIGN_OR_RETURN(const auto gt_files, ListFramePngs(gt_changes_dir / id, "mask"));
    std::vector<std::pair<int64_t, fs::path>> shadow_files;
    std::error_code ec;
    if (fs::is_directory(gt_shadows_dir / id, ec)) {
      OCCMAP_ASSIGN_OR_RETURN(shadow_files, ListFramePngs(gt_shadows_dir / id, "mask"));
    }
    int64_t without_gt = 0, with_shadow = 0;
    size_t g = 0, s = 0;
    for (const auto& [frame, run_path] : run_files) {
      while (g < gt_files.size() && gt_files[g].first < frame) ++g;
      if (g == gt_files.size() || gt_files[g].first != frame) {
        ++without_gt;
        continue;
      }
      MaskPair pair{camera, frame, run_path, gt_files[g].second, {}};
      while (s < shadow_files.size() && shadow_files[s].first < frame) ++s;
      if (s < shadow_files.size() && shadow_files[s].first == frame) {
        pair.shadow = shadow_files[s].second;
        ++with_shadow;
      }
      frames.insert(frame);
      pairs.push_back(std::move(pair));
    }
    camera_frames.push_back(static_cast<int64_t>(run_files.size()) - without_gt);
    camera_shadow_frames.push_back(with_shadow);
    if (without_gt > 0) {
      notes.push_back(fmt::format("changes: camera {}: {} masks of the run have no gt/changes mask of their frame; "
                                  "not evaluated",
                                  id, without_gt));
    }
  }

  // Read and count in parallel; each worker sums into its own row of per-camera counts. After
  // an error, pairs past it are skipped, pairs before it still run: the error reported is that
  // of the first failing pair, as a serial loop would report.
  const size_t num_cameras = evaluation.cameras.size();
  std::vector<std::vector<ChangeCounts>> worker_counts(static_cast<size_t>(ctx.num_threads()),
                                                       std::vector<ChangeCounts>(num_cameras));
  std::vector<MaskReader> readers(static_cast<size_t>(ctx.num_threads()));
  std::vector<Status> errors(pairs.size());
  std::atomic<int64_t> first_error{static_cast<int64_t>(pairs.size())};
  ParallelFor(ctx, 0, static_cast<int64_t>(pairs.size()), [&](int64_t begin, int64_t end, int worker) {
    for (int64_t k = begin; k < end && k < first_error.load(std::memory_order_relaxed); ++k) {
      const MaskPair& pair = pairs[static_cast<size_t>(k)];
      Result<ChangeCounts> counts = CountPair(pair, readers[static_cast<size_t>(worker)]);
      if (!counts.ok()) {
        errors[static_cast<size_t>(k)] = counts.status();
        int64_t seen = first_error.load();
        while (k < seen && !first_error.compare_exchange_weak(seen, k)) {
        }
        return;
      }
      worker_counts[static_cast<size_t>(worker)][pair.camera] += *counts;
    }
  });
  if (first_error.load() < static_cast<int64_t>(pairs.size())) return errors[static_cast<size_t>(first_error.load())];

  ChangeCounts total;
  int64_t shadow_frames = 0;
  for (size_t c = 0; c < num_cameras; ++c) {
    ChangeCounts counts;
    for (const std::vector<ChangeCounts>& w : worker_counts) counts += w[c];
    evaluation.cameras[c].metrics = MakeChangeMetrics(camera_frames[c], camera_shadow_frames[c], counts);
    total += counts;
    shadow_frames += camera_shadow_frames[c];
  }
  evaluation.overall = MakeChangeMetrics(static_cast<int64_t>(frames.size()), shadow_frames, total);
  return evaluation;
}

}  // namespace occmap
