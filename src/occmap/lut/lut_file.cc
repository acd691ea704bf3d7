#include "occmap/lut/lut_file.h"

#include <fmt/core.h>

#include <chrono>
#include <cstring>

#include "occmap/util/file_util.h"
#include "occmap/util/hash.h"

namespace occmap {
namespace fs = std::filesystem;

constexpr char kMagic[8] = {'O', 'C', 'C', 'M', 'L', 'U', 'T', '\0'};
constexpr uint32_t kHeaderBytes = 48;

// Serialises GroundLut's private fields (a friend of GroundLut).
class LutFileCodec {
 public:
  static std::string EncodePayload(const GroundLut& lut) {
    std::string out;
    Pod(out, lut.grid_.origin_x_m);
    Pod(out, lut.grid_.origin_y_m);
    Pod(out, lut.grid_.cells_x);
    Pod(out, lut.grid_.cells_y);
    Pod(out, lut.grid_.cell_size_m);
    Pod(out, lut.plane_height_m_);
    Pod(out, static_cast<uint32_t>(lut.image_sizes_.size()));
    for (size_t c = 0; c < lut.image_sizes_.size(); ++c) {
      Pod(out, lut.image_sizes_[c]);
      Pod(out, lut.coverage_[c]);
      Array(out, lut.l1_[c]);
      Array(out, lut.extra_pixels_[c]);
      Array(out, lut.extra_cells_[c]);
    }
    Array(out, lut.pixel_offsets_);
    Array(out, lut.view_count_);  // L2 is not stored: DeriveL2 rebuilds it on load
    return out;
  }

  static Result<GroundLut> DecodePayload(std::string_view in) {
    Reader r{in};
    GroundLut lut;
    uint32_t cameras = 0;
    bool ok = r.Pod(lut.grid_.origin_x_m) && r.Pod(lut.grid_.origin_y_m) && r.Pod(lut.grid_.cells_x) &&
              r.Pod(lut.grid_.cells_y) && r.Pod(lut.grid_.cell_size_m) && r.Pod(lut.plane_height_m_) && r.Pod(cameras);
    if (!ok || cameras == 0 || cameras > GroundLut::kMaxCameras) return DataLoss("bad table header");
    lut.image_sizes_.resize(cameras);
    lut.coverage_.resize(cameras);
    lut.l1_.resize(cameras);
    lut.extra_pixels_.resize(cameras);
    lut.extra_cells_.resize(cameras);
    for (uint32_t c = 0; c < cameras && ok; ++c) {
      ok = r.Pod(lut.image_sizes_[c]) && r.Pod(lut.coverage_[c]) && r.Array(lut.l1_[c]) &&
           r.Array(lut.extra_pixels_[c]) && r.Array(lut.extra_cells_[c]);
    }
    ok = ok && r.Array(lut.pixel_offsets_) && r.Array(lut.view_count_);
    if (!ok) return DataLoss("payload ends early");
    if (r.pos != in.size()) return DataLoss("payload has trailing bytes");
    OCCMAP_RETURN_IF_ERROR(lut.CheckCameraTables());  // before L2 is derived from them
    lut.DeriveL2();
    OCCMAP_RETURN_IF_ERROR(lut.CheckConsistency());
    return lut;
  }

 private:
  template <typename T>
  static void Pod(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  template <typename T>
  static void Array(std::string& out, const std::vector<T>& v) {
    Pod(out, static_cast<uint64_t>(v.size()));
    out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  struct Reader {
    std::string_view in;
    size_t pos = 0;
    template <typename T>
    bool Pod(T& v) {
      if (in.size() - pos < sizeof(T)) return false;
      std::memcpy(&v, in.data() + pos, sizeof(T));
      pos += sizeof(T);
      return true;
    }
    template <typename T>
    bool Array(std::vector<T>& v) {
      uint64_t n = 0;
      if (!Pod(n) || n > (in.size() - pos) / sizeof(T)) return false;
      v.resize(n);
      if (n > 0) std::memcpy(v.data(), in.data() + pos, n * sizeof(T));  // memcpy(nullptr, ..., 0) is UB
      pos += n * sizeof(T);
      return true;
    }
  };
};

Status SaveGroundLut(const fs::path& path, const GroundLut& lut, uint64_t key) {
  const std::string payload = LutFileCodec::EncodePayload(lut);
  std::string file(kHeaderBytes, '\0');
  const uint64_t payload_bytes = payload.size();
  const uint64_t checksum = HashBytes(std::as_bytes(std::span(payload.data(), payload.size())));
  const uint64_t reserved = 0;
  char* h = file.data();
  std::memcpy(h, kMagic, 8);
  std::memcpy(h + 8, &kLutFileVersion, 4);
  std::memcpy(h + 12, &kHeaderBytes, 4);
  std::memcpy(h + 16, &key, 8);
  std::memcpy(h + 24, &payload_bytes, 8);
  std::memcpy(h + 32, &checksum, 8);
  std::memcpy(h + 40, &reserved, 8);
  file += payload;
  return WriteFileAtomic(path, std::as_bytes(std::span(file.data(), file.size())));
}

Result<GroundLut> LoadGroundLut(const fs::path& path, uint64_t expected_key, bool* stale) {
  if (stale != nullptr) *stale = false;
  OCCMAP_ASSIGN_OR_RETURN(std::string file, ReadFileToString(path));
  auto corrupt = [&](const std::string& why) {
    return DataLoss(fmt::format("'{}': lookup-table file {}", path.string(), why));
  };
  if (file.size() < kHeaderBytes) return corrupt(fmt::format("is truncated ({} bytes, header needs {})", file.size(), kHeaderBytes));
  if (std::memcmp(file.data(), kMagic, 8) != 0) return corrupt("has no OCCMLUT magic (not a table file)");
  uint32_t version = 0, header_bytes = 0;
  uint64_t key = 0, payload_bytes = 0, checksum = 0;
  std::memcpy(&version, file.data() + 8, 4);
  std::memcpy(&header_bytes, file.data() + 12, 4);
  std::memcpy(&key, file.data() + 16, 8);
  std::memcpy(&payload_bytes, file.data() + 24, 8);
  std::memcpy(&checksum, file.data() + 32, 8);
  if (version != kLutFileVersion || header_bytes != kHeaderBytes) {
    return corrupt(fmt::format("has format version {}, expected {}", version, kLutFileVersion));
  }
  if (key != expected_key) {
    if (stale != nullptr) *stale = true;
    return corrupt(fmt::format("is stale: built for inputs {:016x}, current inputs are {:016x}", key, expected_key));
  }
  if (payload_bytes != file.size() - kHeaderBytes) {
    return corrupt(fmt::format("is truncated: {} payload bytes, header says {}", file.size() - kHeaderBytes, payload_bytes));
  }
  const std::string_view payload(file.data() + kHeaderBytes, payload_bytes);
  if (HashBytes(std::as_bytes(std::span(payload.data(), payload.size()))) != checksum) {
    return corrupt("fails its checksum (corrupt)");
  }
  auto lut = LutFileCodec::DecodePayload(payload);
  if (!lut.ok()) return corrupt(fmt::format("is inconsistent: {}", lut.status().message()));
  return lut;
}

const char* ToString(LutCacheOutcome outcome) {
  switch (outcome) {
    case LutCacheOutcome::kLoaded: return "loaded";
    case LutCacheOutcome::kBuiltNoFile: return "built (no cache file yet)";
    case LutCacheOutcome::kRebuiltStale: return "rebuilt (cache file was stale)";
    case LutCacheOutcome::kRebuiltCorrupt: return "rebuilt (cache file was corrupt)";
    case LutCacheOutcome::kBuiltNoCache: return "built (cache disabled)";
  }
  return "?";
}

Result<CachedLut> LoadOrBuildGroundLut(const fs::path& cache_path, const std::vector<LutCameraInput>& cameras,
                                       const FloorGrid& grid, const LutOptions& options, Context& ctx) {
  using Clock = std::chrono::steady_clock;
  CachedLut result;
  result.key = GroundLutKey(cameras, grid, options);
  if (!cache_path.empty()) {
    const auto t0 = Clock::now();
    bool stale = false;
    auto loaded = LoadGroundLut(cache_path, result.key, &stale);
    if (loaded.ok()) {
      result.lut = std::move(loaded).value();
      result.outcome = LutCacheOutcome::kLoaded;
      result.load_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      return result;
    }
    if (loaded.status().code() == StatusCode::kNotFound) {
      result.outcome = LutCacheOutcome::kBuiltNoFile;
    } else {
      result.outcome = stale ? LutCacheOutcome::kRebuiltStale : LutCacheOutcome::kRebuiltCorrupt;
      result.reason = loaded.status().message();
    }
  }
  const auto t0 = Clock::now();
  OCCMAP_ASSIGN_OR_RETURN(result.lut, BuildGroundLut(cameras, grid, options, ctx));
  result.build_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (!cache_path.empty()) {  // a cache, never an output: the caller says why it was not written
    Status written = cache_path.has_parent_path() ? EnsureDirectory(cache_path.parent_path()) : Status::Ok();
    if (written.ok()) written = SaveGroundLut(cache_path, result.lut, result.key);
    if (!written.ok()) result.write_error = written.message();
  }
  return result;
}

}  // namespace occmap
