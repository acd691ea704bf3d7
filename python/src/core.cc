// Sites, tables, fusion of masks, object detection, trackers and metrics for Python.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common.h"
#include "occmap/detect/change_detection.h"
#include "occmap/eval/detection_metrics.h"
#include "occmap/eval/tracking_metrics.h"
#include "occmap/fusion/fast_fusion.h"
#include "occmap/fusion/fusion.h"
#include "occmap/objects/object_detector.h"
#include "occmap/site/site.h"
#include "occmap/site/site_lut.h"
#include "occmap/track/count_lines.h"
#include "occmap/track/multi_target_tracker.h"
#include "occmap/track/track_output.h"
#include "occmap/track/zones.h"
#include "occmap/track/window_tracker.h"
#include "occmap/util/image_io.h"

namespace occmap::python {
namespace {

namespace fs = std::filesystem;
using namespace pybind11::literals;

// ---------------------------------------------------------------------------------------------
// Site and tables

Result<Site> LoadSiteFile(const fs::path& path, std::optional<fs::path> data_root) {
  SiteLoadOptions options;
  options.data_root = std::move(data_root);
  return LoadSite(path, options);
}

// The site's tables with what they came from; they keep the site (cameras, masks) alive.
struct Tables {
  std::shared_ptr<Site> site;
  CachedLut cached;
  fs::path cache_file;  // "" without a cache
};

std::shared_ptr<Tables> MakeTables(std::shared_ptr<Site> site, std::optional<fs::path> cache_dir, int threads) {
  auto tables = std::make_shared<Tables>();
  tables->site = std::move(site);
  const fs::path dir = cache_dir.value_or(fs::path());
  {
    py::gil_scoped_release release;
    Context ctx(threads);
    Result<CachedLut> cached = LoadOrBuildSiteLut(*tables->site, dir, ctx);
    if (!cached.ok()) {
      py::gil_scoped_acquire acquire;
      throw StatusError(cached.status());
    }
    tables->cached = std::move(cached).value();
  }
  if (!dir.empty()) tables->cache_file = SiteLutPath(*tables->site, dir);
  return tables;
}

// A map of cells as a (cells_y, cells_x) array: row j, column i is cell (i, j).
py::array_t<uint8_t> CellArray(const FloorGrid& grid, const uint8_t* data, py::handle base) {
  return py::array_t<uint8_t>({static_cast<py::ssize_t>(grid.cells_y), static_cast<py::ssize_t>(grid.cells_x)},
                              {static_cast<py::ssize_t>(grid.cells_x), py::ssize_t{1}}, data, base);
}

// ---------------------------------------------------------------------------------------------
// Maps: an occupancy map with the active cameras and the change buffer it was fused from (the
// object detector's elevated check reads the changes).

struct Map {
  OccupancyMap map;
  std::vector<bool> active;
  std::vector<uint8_t> changes;  // empty for a map made from an array
  std::shared_ptr<Tables> tables;
};

std::shared_ptr<Map> MapFromArray(const FloorGrid& grid, const U8Array& states) {
  if (states.ndim() != 2 || states.shape(0) != grid.cells_y || states.shape(1) != grid.cells_x) {
    std::string shape;
    for (int d = 0; d < states.ndim(); ++d) shape += (d ? ", " : "") + std::to_string(states.shape(d));
    ThrowInvalid("states: expected a (" + std::to_string(grid.cells_y) + ", " + std::to_string(grid.cells_x) +
                 ") array (cells_y, cells_x), found shape (" + shape + ")");
  }
  auto out = std::make_shared<Map>();
  out->map = OccupancyMap(grid);
  const uint8_t* p = states.data();
  for (int64_t c = 0; c < grid.num_cells(); ++c) {
    if (p[c] > 2) {
      ThrowInvalid("states: expected cell values 0 (unseen), 1 (free) or 2 (occupied), found " + std::to_string(p[c]) +
                   " at cell (" + std::to_string(c % grid.cells_x) + ", " + std::to_string(c / grid.cells_x) + ")");
    }
    out->map.states()[static_cast<size_t>(c)] = static_cast<CellState>(p[c]);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Fusion of masks, as `occmap run` fuses a site's mask sources.

class PyFusion {
 public:
  PyFusion(std::shared_ptr<Tables> tables, std::optional<std::string> method, std::optional<int> max_free_views,
           std::optional<int> tolerance_px, int threads)
      : tables_(std::move(tables)), ctx_(threads), fusion_(tables_->cached.lut) {
    const Site& site = *tables_->site;
    options_ = site.fusion;
    tolerance_px_ = site.detection.tolerance_px;
    if (method) {
      if (*method == "image-based") {
        options_.method = FusionMethod::kImageBased;
      } else if (*method == "map-based") {
        options_.method = FusionMethod::kMapBased;
      } else {
        ThrowInvalid("method: expected image-based or map-based, found '" + *method + "'");
      }
    }
    if (max_free_views) options_.max_free_views = *max_free_views;
    ThrowIfError(options_.Validate(lut().num_cameras()));
    if (tolerance_px) {
      if (*tolerance_px < 0 || *tolerance_px > ChangeDetectionOptions::kMaxTolerancePx) {
        ThrowInvalid("tolerance_px: expected 0.." + std::to_string(ChangeDetectionOptions::kMaxTolerancePx) +
                     ", found " + std::to_string(*tolerance_px));
      }
      tolerance_px_ = *tolerance_px;
    }
    if (options_.method == FusionMethod::kImageBased && options_.max_free_views == 0) fast_.emplace(lut());
  }

  const GroundLut& lut() const { return tables_->cached.lut; }

  std::shared_ptr<Map> Fuse(const std::vector<std::optional<py::array>>& masks) {
    CheckCount(masks.size(), "masks");
    std::vector<U8Array> arrays(masks.size());
    std::vector<ImageView<const uint8_t>> views(masks.size());
    for (size_t c = 0; c < masks.size(); ++c) {
      if (!masks[c]) continue;
      const std::string what = "masks[" + std::to_string(c) + "] (camera " + CameraId(c) + ")";
      arrays[c] = MaskArray(*masks[c], what);
      views[c] = GrayView(arrays[c], what);
      CheckMaskShape(c, views[c], what);
    }
    return FuseWith(views, [&](size_t c, ImageView<uint8_t> out) { MaskToChanges(views[c], out); });
  }

  // A mask as 0 / non-zero bytes: bool and integer arrays (a non-zero value of any width is
  // foreground, never truncated to a byte); floats are refused: a segmenter's 0.7 is not 0 or
  // 1 until the caller says where the threshold is.
  static U8Array MaskArray(const py::array& mask, const std::string& what) {
    const char kind = mask.dtype().kind();
    if (kind == 'f' || kind == 'c') {
      ThrowInvalid(what + ": expected a mask of booleans or integers (non-zero = foreground), found " +
                   std::string(py::str(mask.dtype())) + " values: threshold it first, e.g. mask > 0.5");
    }
    if (kind != 'b' && kind != 'u' && kind != 'i') {
      ThrowInvalid(what + ": expected a mask of booleans or integers, found dtype " + std::string(py::str(mask.dtype())));
    }
    if (kind == 'b' || mask.dtype().itemsize() == 1) return U8Array::ensure(mask);
    return U8Array::ensure(py::module_::import("numpy").attr("not_equal")(mask, 0));
  }

  // A mask of any size is resampled to the camera's, but not one of another shape: a
  // transposed (columns, rows) array would put every change in the wrong place.
  void CheckMaskShape(size_t c, ImageView<const uint8_t> mask, const std::string& what) const {
    const ImageSize size = lut().image_size(static_cast<int>(c));
    const double camera_aspect = static_cast<double>(size.width) / size.height;
    const double mask_aspect = static_cast<double>(mask.width()) / mask.height();
    if (std::abs(mask_aspect / camera_aspect - 1) > 0.02) {
      ThrowInvalid(what + ": expected an array of the camera's shape (" + std::to_string(size.height) + ", " +
                   std::to_string(size.width) + ") or a scale of it, found (" + std::to_string(mask.height()) + ", " +
                   std::to_string(mask.width()) + ")");
    }
  }

  // The bench's C++ side (scripts/bench_python.py): what fuse() does after the arguments are
  // converted, `repeats` times in a C++ loop; the seconds per call.
  double FuseRepeatedly(const std::vector<std::optional<U8Array>>& masks, int repeats) {
    CheckCount(masks.size(), "masks");
    std::vector<ImageView<const uint8_t>> views(masks.size());
    for (size_t c = 0; c < masks.size(); ++c) {
      if (masks[c]) views[c] = GrayView(*masks[c], "masks[" + std::to_string(c) + "]");
    }
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < repeats; ++i) {
      FuseWith(views, [&](size_t c, ImageView<uint8_t> out) { MaskToChanges(views[c], out); });
    }
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / std::max(repeats, 1);
  }

  // Equation 4 against each camera's background, as `occmap run` on a site with backgrounds.
  std::shared_ptr<Map> FuseFrames(const std::vector<std::optional<U8Array>>& frames, const std::vector<U8Array>& backgrounds,
                                  std::optional<int> threshold) {
    CheckCount(frames.size(), "frames");
    CheckCount(backgrounds.size(), "backgrounds");
    ChangeDetectionOptions detection = tables_->site->detection;
    if (threshold) detection.threshold = *threshold;
    ThrowIfError(detection.Validate());
    const int channels = detection.colour ? 3 : 2;
    std::vector<ImageView<const uint8_t>> views(frames.size()), bg(frames.size());
    auto check = [&](const U8Array& a, size_t c, const std::string& what) {
      const ImageSize size = lut().image_size(static_cast<int>(c));
      const std::string name = what + "[" + std::to_string(c) + "] (camera " + CameraId(c) + ")";
      if (a.ndim() != channels || (channels == 3 && a.shape(2) != 3)) {
        ThrowInvalid(name + ": expected " + (channels == 3 ? "an RGB (rows, columns, 3) array (detection.colour)" : "a grey 2-D array (rows, columns)") +
                     ", found " + std::to_string(a.ndim()) + "-D");
      }
      if (a.shape(0) != size.height || a.shape(1) != size.width) {
        ThrowInvalid(name + ": expected " + std::to_string(size.height) + " rows x " + std::to_string(size.width) +
                     " columns (the camera's image size), found " + std::to_string(a.shape(0)) + " x " + std::to_string(a.shape(1)));
      }
      return ImageView<const uint8_t>(a.data(), size.width * (channels == 3 ? 3 : 1), size.height, size.width * (channels == 3 ? 3 : 1));
    };
    for (size_t c = 0; c < frames.size(); ++c) {
      if (!frames[c]) continue;
      views[c] = check(*frames[c], c, "frames");
      bg[c] = check(backgrounds[c], c, "backgrounds");
    }
    return FuseWith(views, [&](size_t c, ImageView<uint8_t> out) {
      if (channels == 3) {
        auto rgb = [&](ImageView<const uint8_t> v) {
          return ImageView<const Rgb8>(reinterpret_cast<const Rgb8*>(v.data()), out.width(), out.height(), out.width());
        };
        DetectChangesRgb(rgb(views[c]), rgb(bg[c]), detection.threshold, out);
      } else {
        DetectChangesGray(views[c], bg[c], detection.threshold, out);
      }
    });
  }

 private:
  // A result Python no longer holds (no allocation per call: `m = fusion.fuse(...)` in a loop
  // holds the previous one while the next is made), else a new one.
  std::shared_ptr<Map> TakeMap() {
    for (const std::shared_ptr<Map>& m : pool_) {
      if (m.use_count() == 1) return m;
    }
    auto m = std::make_shared<Map>();
    m->tables = tables_;
    if (pool_.size() < kPool) {
      pool_.push_back(m);
    } else {
      pool_[next_++ % kPool] = m;
    }
    return m;
  }

  void CheckCount(size_t found, const char* what) const {
    const int n = lut().num_cameras();
    if (static_cast<int>(found) != n) {
      ThrowInvalid(std::string(what) + ": expected " + std::to_string(n) +
                   " arrays (one per camera, in the site's order), found " + std::to_string(found));
    }
  }
  const std::string& CameraId(size_t c) const { return tables_->site->cameras[c].id; }

  // changes(c, out): camera c's change mask (1 / 0) into out, at the camera's size; a camera whose
  // view is empty is inactive. Then the tolerance and the fusion, without the GIL.
  template <typename Changes>
  std::shared_ptr<Map> FuseWith(const std::vector<ImageView<const uint8_t>>& views, const Changes& changes) {
    std::shared_ptr<Map> out;
    py::gil_scoped_release release;
    std::lock_guard lock(mutex_);
    out = TakeMap();
    const GroundLut& l = lut();
    out->active.assign(views.size(), false);
    if (out->changes.size() != l.total_pixels()) out->changes.assign(l.total_pixels(), 0);
    bool all_active = true;
    for (size_t c = 0; c < views.size(); ++c) {
      if (views[c].empty()) {
        all_active = false;
        continue;
      }
      out->active[c] = true;
      const ImageSize size = l.image_size(static_cast<int>(c));
      ImageView<uint8_t> slice(out->changes.data() + l.pixel_offset(static_cast<int>(c)), size.width, size.height,
                               size.width);
      if (tolerance_px_ == 0) {
        changes(c, slice);
      } else {
        if (raw_.width() != size.width || raw_.height() != size.height) raw_ = Image<uint8_t>(size.width, size.height);
        changes(c, raw_.view());
        DilateChanges(raw_.view(), tolerance_px_, slice, scratch_);
      }
    }
    if (fast_ && all_active) {
      fast_->FuseChanges(out->changes, ctx_, out->map);
    } else {
      fusion_.Fuse(out->changes, out->active, options_, out->map);
    }
    return out;
  }

  std::shared_ptr<Tables> tables_;
  Context ctx_;
  Fusion fusion_;
  std::optional<FastFusion> fast_;  // the paper's AND with every camera active (bit-identical)
  FusionOptions options_;
  int tolerance_px_ = 0;
  std::mutex mutex_;
  static constexpr size_t kPool = 3;
  std::vector<std::shared_ptr<Map>> pool_;
  size_t next_ = 0;
  Image<uint8_t> raw_;
  std::vector<uint8_t> scratch_;
};

// ---------------------------------------------------------------------------------------------
// Objects and trackers

struct Objects {
  DetectedObjects objects;
};

class PyDetector {
 public:
  explicit PyDetector(std::shared_ptr<Tables> tables) : tables_(std::move(tables)), detector_(MakeDetector()) {}

  std::shared_ptr<Objects> Detect(const Map& map) {
    const GroundLut& lut = tables_->cached.lut;
    if (!(map.map.grid() == lut.grid())) ThrowInvalid("map: its grid is not the site's");
    const size_t n = static_cast<size_t>(lut.num_cameras());
    auto out = std::make_shared<Objects>();
    std::vector<bool> active = map.active.empty() ? std::vector<bool>(n, true) : map.active;
    if (active.size() != n) ThrowInvalid("map: made for another number of cameras");
    py::gil_scoped_release release;
    std::lock_guard lock(mutex_);
    if (map.changes.size() == lut.total_pixels()) {
      // As the run: the elevated check reads the changes the map was fused from.
      const ObjectDetector::ChangeLookup changed = [&](int c, int x, int y) {
        const size_t width = static_cast<size_t>(lut.image_size(c).width);
        return map.changes[lut.pixel_offset(c) + static_cast<size_t>(y) * width + static_cast<size_t>(x)] != 0;
      };
      std::vector<ObjectDetector::ChangeBuffer> buffers;
      for (size_t c = 0; c < n; ++c) {
        ObjectDetector::ChangeBuffer b;
        b.pixels = map.changes.data() + lut.pixel_offset(static_cast<int>(c));
        b.stride = static_cast<size_t>(lut.image_size(static_cast<int>(c)).width);
        buffers.push_back(b);
      }
      detector_.Detect(map.map, active, changed, out->objects, buffers);
    } else {
      detector_.Detect(map.map, active, out->objects);
    }
    return out;
  }

 private:
  ObjectDetector MakeDetector() {
    const Site& site = *tables_->site;
    std::vector<ObjectDetector::CameraView> views;
    for (const SiteCamera& c : site.cameras) views.push_back({c.camera.get(), &c.mask});
    return ObjectDetector(site.objects, site.plane_height_m, std::move(views));
  }
  std::shared_ptr<Tables> tables_;
  ObjectDetector detector_;
  std::mutex mutex_;
};

// The site's tracker, whichever algorithm it names (as pipeline/run.cc's).
class PyTracker {
 public:
  explicit PyTracker(const Site& site)
      : options_(site.tracking),
        grid_(site.grid),
        zones_(Unwrap(ZoneMonitor::Create(options_.zones, options_.zone_count_every_frame))),
        lines_(Unwrap(LineCounter::Create(options_.lines))) {
    if (options_.algorithm == TrackerAlgorithm::kWindow) {
      window_ = std::make_unique<WindowTracker>(Unwrap(WindowTracker::Create(options_)));
    } else {
      multi_ = std::make_unique<MultiTargetTracker>(Unwrap(MultiTargetTracker::Create(options_)));
    }
  }

  // As the run: the tracker, then the zones and counting lines over every live track.
  std::vector<Track> Update(const Objects& objects, double time_s, bool all, std::optional<int64_t> frame) {
    std::vector<Track> tracks;
    {
      py::gil_scoped_release release;
      std::lock_guard lock(mutex_);
      Result<std::vector<Track>> r = window_ ? WindowUpdate(objects.objects, time_s) : multi_->Update(objects.objects, time_s);
      if (!r.ok()) {
        py::gil_scoped_acquire acquire;
        throw StatusError(r.status());
      }
      tracks = std::move(r).value();
      const int64_t f = frame.value_or(next_frame_);
      next_frame_ = f + 1;
      events_.clear();
      for (const ZoneEvent& e : zones_.Update(f, time_s, tracks).events) events_.push_back(ZoneEventJsonLine(e));
      for (const LineEvent& e : lines_.Update(f, time_s, tracks).events) events_.push_back(LineEventJsonLine(e));
    }
    if (!all) std::erase_if(tracks, [&](const Track& t) { return !IsReported(t, options_.report_coasting_s); });
    return tracks;
  }

  // The last update's zone events and line crossings, as events.jsonl's lines.
  py::list Events() const {
    py::object loads = py::module_::import("json").attr("loads");
    py::list out;
    for (const std::string& line : events_) out.append(loads(line));
    return out;
  }

  std::vector<Track> UpdateDetections(const std::vector<Detection>& detections, double time_s, bool all,
                                      std::optional<int64_t> frame) {
    if (window_) ThrowInvalid("detections: the window tracker reads a map's groups; give it detect()'s result");
    Objects objects;
    objects.objects.grid = grid_;
    objects.objects.detections = detections;
    for (Detection& d : objects.objects.detections) d.group = -1;  // no groups: never guided
    return Update(objects, time_s, all, frame);
  }

 private:
  Result<std::vector<Track>> WindowUpdate(const DetectedObjects& objects, double time_s) {
    groups_.clear();
    for (const DetectionGroup& g : objects.groups) groups_.push_back(g.group);
    return window_->Update(groups_, objects.grown, time_s);
  }
  TrackerOptions options_;
  FloorGrid grid_;
  std::unique_ptr<WindowTracker> window_;
  std::unique_ptr<MultiTargetTracker> multi_;
  ZoneMonitor zones_;
  LineCounter lines_;
  int64_t next_frame_ = 0;
  std::vector<std::string> events_;
  std::vector<Blob> groups_;
  std::mutex mutex_;
};

// ---------------------------------------------------------------------------------------------
// Metrics on Python sequences

std::vector<Eigen::Vector2d> Positions(const py::handle& frame, const std::string& what) {
  std::vector<Eigen::Vector2d> out;
  for (const py::handle& p : frame) {
    auto seq = py::reinterpret_borrow<py::sequence>(p);
    if (py::len(seq) < 2) ThrowInvalid(what + ": expected (x_m, y_m) pairs, found " + py::repr(p).cast<std::string>());
    out.emplace_back(seq[0].cast<double>(), seq[1].cast<double>());
  }
  return out;
}

std::vector<IdPosition> IdPositions(const py::handle& frame, const std::string& what) {
  std::vector<IdPosition> out;
  std::set<int64_t> ids;
  for (const py::handle& p : frame) {
    IdPosition ip;
    if (py::isinstance<Track>(p)) {
      const Track& t = p.cast<const Track&>();
      ip.id = t.id;
      ip.position_m = {t.x_m, t.y_m};
    } else {
      auto seq = py::reinterpret_borrow<py::sequence>(p);
      if (py::len(seq) < 3) ThrowInvalid(what + ": expected (id, x_m, y_m) triples or Tracks, found " + py::repr(p).cast<std::string>());
      ip.id = seq[0].cast<int64_t>();
      ip.position_m = {seq[1].cast<double>(), seq[2].cast<double>()};
    }
    if (!ids.insert(ip.id).second) ThrowInvalid(what + ": id " + std::to_string(ip.id) + " appears twice in one frame");
    out.push_back(ip);
  }
  return out;
}

void CheckSameLength(const py::sequence& a, const py::sequence& b, const char* b_name) {
  if (py::len(a) != py::len(b)) {
    ThrowInvalid(std::string(b_name) + ": expected one frame per ground-truth frame (" + std::to_string(py::len(a)) +
                 "), found " + std::to_string(py::len(b)));
  }
}

EvalOptions MetricOptions(double match_threshold_m) {
  EvalOptions options;
  options.match_threshold_m = match_threshold_m;
  ThrowIfError(options.Validate());
  return options;
}

py::dict DetectionMetricsDict(const py::sequence& gt, const py::sequence& detections, double match_threshold_m) {
  CheckSameLength(gt, detections, "detections");
  DetectionEvaluator evaluator(MetricOptions(match_threshold_m));
  for (size_t f = 0; f < py::len(gt); ++f) {
    const std::vector<Eigen::Vector2d> g = Positions(gt[f], "ground_truth[" + std::to_string(f) + "]");
    std::vector<Eigen::Vector2d> d;
    const py::object frame = detections[f];
    for (const py::handle& p : frame) {
      if (py::isinstance<Detection>(p)) {
        const Detection& det = p.cast<const Detection&>();
        d.emplace_back(det.x_m, det.y_m);
      } else {
        py::list one;
        one.append(p);
        d.push_back(Positions(one, "detections[" + std::to_string(f) + "]")[0]);
      }
    }
    evaluator.AddFrame(static_cast<int64_t>(f), g, d);
  }
  const DetectionMetrics m = evaluator.Metrics();
  return py::dict("frames"_a = m.frames, "gt"_a = m.gt, "detections"_a = m.detections, "tp"_a = m.tp, "fp"_a = m.fp,
                  "fn"_a = m.fn, "moda"_a = m.moda, "modp"_a = m.modp, "precision"_a = m.precision,
                  "recall"_a = m.recall, "mean_distance_m"_a = m.mean_distance_m);
}

py::dict TrackingMetricsDict(const py::sequence& gt, const py::sequence& tracks, double match_threshold_m) {
  CheckSameLength(gt, tracks, "tracks");
  TrackingEvaluator evaluator(MetricOptions(match_threshold_m));
  for (size_t f = 0; f < py::len(gt); ++f) {
    const auto g = IdPositions(gt[f], "ground_truth[" + std::to_string(f) + "]");
    const auto t = IdPositions(tracks[f], "tracks[" + std::to_string(f) + "]");
    evaluator.AddFrame(g, t);
  }
  const TrackingMetrics m = evaluator.Metrics();
  return py::dict("frames"_a = m.frames, "gt"_a = m.gt, "predictions"_a = m.predictions, "tp"_a = m.tp, "fp"_a = m.fp,
                  "fn"_a = m.fn, "id_switches"_a = m.id_switches, "fragmentations"_a = m.fragmentations,
                  "gt_trajectories"_a = m.gt_trajectories, "track_trajectories"_a = m.track_trajectories,
                  "mostly_tracked"_a = m.mostly_tracked, "partially_tracked"_a = m.partially_tracked,
                  "mostly_lost"_a = m.mostly_lost, "mota"_a = m.mota, "motp_m"_a = m.motp_m,
                  "motp_closeness"_a = m.motp_closeness, "idtp"_a = m.idtp, "idfp"_a = m.idfp, "idfn"_a = m.idfn,
                  "idf1"_a = m.idf1, "idp"_a = m.idp, "idr"_a = m.idr);
}

std::string Repr(const Detection& d) {
  return "Detection(x_m=" + py::repr(py::float_(d.x_m)).cast<std::string>() +
         ", y_m=" + py::repr(py::float_(d.y_m)).cast<std::string>() +
         ", area_m2=" + py::repr(py::float_(d.area_m2)).cast<std::string>() + ")";
}

}  // namespace

void BindCore(py::module_& m) {
  // --- grid
  py::class_<FloorGrid>(m, "Grid", "The floor grid: cell (i, j) covers [x0 + i s, x0 + (i+1) s) x [y0 + j s, ...).")
      .def(py::init([](std::pair<double, double> origin_m, std::pair<int, int> cells, double cell_size_m) {
             FloorGrid g;
             g.origin_x_m = origin_m.first;
             g.origin_y_m = origin_m.second;
             g.cells_x = cells.first;
             g.cells_y = cells.second;
             g.cell_size_m = cell_size_m;
             ThrowIfError(g.Validate());
             return g;
           }),
           "origin_m"_a, "cells"_a, "cell_size_m"_a, "A grid: origin (x, y) in metres, cells (x, y), cell size in metres.")
      .def_property_readonly("origin_m", [](const FloorGrid& g) { return std::make_pair(g.origin_x_m, g.origin_y_m); })
      .def_property_readonly("cells", [](const FloorGrid& g) { return std::make_pair(g.cells_x, g.cells_y); },
                             "(cells_x, cells_y)")
      .def_property_readonly("shape", [](const FloorGrid& g) { return std::make_pair(g.cells_y, g.cells_x); },
                             "(cells_y, cells_x): the shape of a map's array")
      .def_readonly("cell_size_m", &FloorGrid::cell_size_m)
      .def("cell_center", [](const FloorGrid& g, int i, int j) {
             if (i < 0 || j < 0 || i >= g.cells_x || j >= g.cells_y) ThrowInvalid("cell: outside the grid");
             const Eigen::Vector2d c = g.CellCenter(int64_t{j} * g.cells_x + i);
             return std::make_pair(c.x(), c.y());
           }, "i"_a, "j"_a, "The world (x, y) in metres of the centre of cell (i, j) (array [j, i]).")
      .def("__eq__", [](const FloorGrid& a, const FloorGrid& b) { return a == b; })
      .def("__repr__", [](const FloorGrid& g) {
        return "Grid(origin_m=(" + std::to_string(g.origin_x_m) + ", " + std::to_string(g.origin_y_m) + "), cells=(" +
               std::to_string(g.cells_x) + ", " + std::to_string(g.cells_y) + "), cell_size_m=" + std::to_string(g.cell_size_m) + ")";
      });

  // --- site
  py::class_<SiteCamera>(m, "Camera", "A camera of a site: id, run-time image size, floor mask.")
      .def_readonly("id", &SiteCamera::id)
      .def_property_readonly("image_size", [](const SiteCamera& c) {
        const ImageSize s = c.camera->image_size();
        return std::make_pair(s.width, s.height);
      }, "(width, height) of the frames and masks the run reads")
      .def_property_readonly("kind", [](const SiteCamera& c) { return std::string(c.camera->kind()); })
      .def_property_readonly("mask", [](const SiteCamera& c) -> py::object {
        if (c.mask.empty()) return py::none();
        return ToArray(c.mask.view());
      }, "The floor mask (non-zero = monitored floor) as a (rows, columns) array, or None (all floor).")
      .def("project", [](const SiteCamera& c, double x, double y, double z) -> py::object {
        auto p = c.camera->Project({x, y, z});
        if (!p) return py::none();
        return py::make_tuple(p->x(), p->y());
      }, "x"_a, "y"_a, "z"_a = 0.0, "The pixel (column, row) of a world point in metres, or None behind the camera.")
      .def("__repr__", [](const SiteCamera& c) { return "Camera('" + c.id + "')"; });

  py::class_<Site, std::shared_ptr<Site>>(m, "Site",
      "A loaded site (load_site): floor grid, cameras, and the settings of detection, fusion, objects, tracking.")
      .def_readonly("name", &Site::name)
      .def_property_readonly("file", [](const Site& s) { return s.file; })
      .def_readonly("grid", &Site::grid)
      .def_readonly("plane_height_m", &Site::plane_height_m)
      .def_property_readonly("cameras", [](py::object self) {
        py::list out;
        for (SiteCamera& c : self.cast<Site&>().cameras) out.append(py::cast(&c, py::return_value_policy::reference_internal, self));
        return out;
      }, "The cameras, in the site file's order (the order of fuse()'s masks).")
      .def_property("threshold", [](const Site& s) { return s.detection.threshold; },
                    [](Site& s, int v) {
                      ChangeDetectionOptions o = s.detection;
                      o.threshold = v;
                      ThrowIfError(o.Validate());
                      s.detection = o;
                    }, "detection.threshold: T of the change test |I - B| > T")
      .def_property("tolerance_px", [](const Site& s) { return s.detection.tolerance_px; },
                    [](Site& s, int v) {
                      ChangeDetectionOptions o = s.detection;
                      o.tolerance_px = v;
                      ThrowIfError(o.Validate());
                      s.detection = o;
                    }, "detection.tolerance_px: dilation of every change mask before the fusion")
      .def_property_readonly("fusion_method", [](const Site& s) { return std::string(ToString(s.fusion.method)); })
      .def_property_readonly("max_free_views", [](const Site& s) { return s.fusion.max_free_views; })
      .def_property_readonly("tracker", [](const Site& s) { return std::string(ToString(s.tracking.algorithm)); })
      .def("__repr__", [](const Site& s) {
        return "Site('" + s.name + "', cameras=" + std::to_string(s.cameras.size()) + ")";
      });

  m.def("_load_site_file", [](const fs::path& path, std::optional<fs::path> data_root) {
    return std::make_shared<Site>(Unwrap(LoadSiteFile(path, std::move(data_root))));
  }, "path"_a, "data_root"_a = py::none());
  m.def("_parse_site", [](const std::string& text, const fs::path& path, std::optional<fs::path> data_root) {
    SiteLoadOptions options;
    options.data_root = std::move(data_root);
    return std::make_shared<Site>(Unwrap(ParseSite(text, path, options)));
  }, "text"_a, "path"_a, "data_root"_a = py::none());

  // --- tables
  py::class_<Tables, std::shared_ptr<Tables>>(m, "Tables",
      "The lookup tables of a site (pixel -> cell and cell -> pixels), built or loaded from the cache.")
      .def(py::init(&MakeTables), "site"_a, "cache_dir"_a = py::none(), "threads"_a = 0,
           "Builds the tables, or loads them from cache_dir/<site>.lut when it is valid for this site\n"
           "(a stale or corrupt file is rebuilt and rewritten). cache_dir None: no file. threads 0: all cores.")
      .def_property_readonly("site", [](const Tables& t) { return t.site; })
      .def_property_readonly("grid", [](const Tables& t) { return t.cached.lut.grid(); })
      .def_property_readonly("num_cameras", [](const Tables& t) { return t.cached.lut.num_cameras(); })
      .def_property_readonly("total_pixels", [](const Tables& t) { return t.cached.lut.total_pixels(); })
      .def_property_readonly("cache", [](const Tables& t) { return std::string(ToString(t.cached.outcome)); },
                             "What the cache gave: loaded, built (no file), rebuilt (stale), ...")
      .def_property_readonly("cache_reason", [](const Tables& t) { return t.cached.reason; })
      .def_property_readonly("cache_file", [](const Tables& t) -> py::object {
        if (t.cache_file.empty()) return py::none();
        return py::cast(t.cache_file);
      })
      .def_property_readonly("build_seconds", [](const Tables& t) { return t.cached.build_seconds; })
      .def_property_readonly("view_counts", [](const Tables& t) {
        const auto counts = t.cached.lut.view_count();
        return CellArray(t.cached.lut.grid(), counts.data(), py::handle());  // no base: a copy
      }, "Per cell, how many cameras see it: a (cells_y, cells_x) array.")
      .def("coverage_table", [](const Tables& t) { return CoverageTable(*t.site, t.cached.lut); },
           "The per-camera coverage figures as `occmap lut` prints them.");

  // --- maps
  py::class_<Map, std::shared_ptr<Map>>(m, "Map",
      "A tri-state occupancy map: states[j, i] is cell (i, j), UNSEEN (0), FREE (1) or OCCUPIED (2).")
      .def_static("from_array", [](const FloorGrid& grid, const U8Array& states) { return MapFromArray(grid, states); },
                  "grid"_a, "states"_a, "A map from a (cells_y, cells_x) array of 0, 1, 2 (no changes: no elevated check).")
      .def_property_readonly("states", [](py::object self) {
        Map& map = self.cast<Map&>();
        py::array_t<uint8_t> a = CellArray(map.map.grid(), reinterpret_cast<const uint8_t*>(map.map.states().data()), self);
        py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
        return a;
      }, "The states as a read-only (cells_y, cells_x) uint8 array, without a copy (row j = cell row j, y up).")
      .def_property_readonly("grid", [](const Map& map) { return map.map.grid(); })
      .def_property_readonly("active", [](const Map& map) { return map.active; },
                             "Per camera, whether it had a mask in this fusion.")
      .def("count", [](const Map& map, int state) {
        if (state < 0 || state > 2) ThrowInvalid("state: expected 0, 1 or 2, found " + std::to_string(state));
        return map.map.Count(static_cast<CellState>(state));
      }, "state"_a, "Cells in this state.")
      .def("to_image", [](const Map& map) { return ToArray(map.map.ToGrayImage().view()); },
           "The plan-view picture `occmap run` writes (occupancy/NNNNNN.png): one pixel per cell, +y up,\n"
           "white free, black occupied, grey (128) unseen.")
      .def("__eq__", [](const Map& a, const Map& b) { return a.map == b.map; });

  // --- fusion
  py::class_<PyFusion>(m, "Fusion",
      "Fusion of per-camera foreground masks into a map, as `occmap run` fuses a site's mask sources.")
      .def(py::init([](std::shared_ptr<Tables> tables, std::optional<std::string> method, std::optional<int> k,
                       std::optional<int> tolerance_px, int threads) {
             return std::make_unique<PyFusion>(std::move(tables), std::move(method), k, tolerance_px, threads);
           }),
           "tables"_a, "method"_a = py::none(), "max_free_views"_a = py::none(), "tolerance_px"_a = py::none(),
           "threads"_a = 0,
           "method: 'image-based' or 'map-based'; max_free_views: k of the vote rule (0: the paper's AND);\n"
           "tolerance_px: dilation of each mask. Each defaults to the site's setting.")
      .def("fuse", &PyFusion::Fuse, "masks"_a,
           "Fuses one mask per camera (site order): 2-D arrays, non-zero = foreground, of the camera's\n"
           "shape (rows, columns) or a scale of it (resampled to the camera's, nearest pixel), of any\n"
           "integer or bool type (float masks raise: threshold them first, e.g. mask > 0.5); None for\n"
           "a camera without a frame (its cells seen by no other camera become UNSEEN). Returns a Map.\n"
           "Raises InvalidInputError on a wrong count, shape or dtype. Releases the GIL.")
      .def("_fuse_repeatedly", &PyFusion::FuseRepeatedly, "masks"_a, "repeats"_a,
           "Bench only: fuse()'s C++ work `repeats` times in a C++ loop; seconds per call.")
      .def("fuse_frames", &PyFusion::FuseFrames, "frames"_a, "backgrounds"_a, "threshold"_a = py::none(),
           "Fuses camera frames against their backgrounds (equation 4, |I - B| > threshold, the site's\n"
           "detection settings): grey (rows, columns) arrays at each camera's image size as read_image\n"
           "gives them (RGB (rows, columns, 3) when the site's detection.colour is set); None for a\n"
           "camera without a frame. The adaptive backgrounds of `backgrounds.adaptive` are not used.");

  // --- objects
  py::class_<Detection>(m, "Detection", "One object on the floor in one frame.")
      .def(py::init([](double x_m, double y_m, double area_m2, std::string class_hint) {
             Detection d;
             d.x_m = x_m;
             d.y_m = y_m;
             d.area_m2 = area_m2;
             d.class_hint = std::move(class_hint);
             return d;
           }),
           "x_m"_a, "y_m"_a, "area_m2"_a = 0.0, "class_hint"_a = "")
      .def_readwrite("x_m", &Detection::x_m)
      .def_readwrite("y_m", &Detection::y_m)
      .def_readwrite("area_m2", &Detection::area_m2)
      .def_readonly("cells", &Detection::cells)
      .def_readwrite("spread_m2", &Detection::spread_m2, "2x2 covariance of its cells' centres")
      .def_readwrite("class_hint", &Detection::class_hint)
      .def_readonly("group", &Detection::group)
      .def_readonly("parts", &Detection::parts)
      .def_readonly("guided", &Detection::guided)
      .def("__repr__", &Repr);

  py::class_<Objects, std::shared_ptr<Objects>>(m, "Objects", "A frame's detections (ObjectDetector.detect).")
      .def_property_readonly("detections", [](const Objects& o) { return o.objects.detections; })
      .def_property_readonly("grown", [](const Objects& o) {
        auto map = std::make_shared<Map>();
        map->map = o.objects.grown;
        return map;
      }, "The map with fragments grouped.")
      .def("__len__", [](const Objects& o) { return o.objects.detections.size(); });

  py::class_<PyDetector>(m, "ObjectDetector",
      "From a map to the objects standing on it: grouping, size filter, split at necks, elevated check, ghosts.")
      .def(py::init([](std::shared_ptr<Tables> tables) { return std::make_unique<PyDetector>(std::move(tables)); }),
           "tables"_a, "The site's `blobs:` and person settings.")
      .def("detect", &PyDetector::Detect, "map"_a, "The map's objects (Objects). Releases the GIL.");

  // --- tracking
  py::class_<Track>(m, "Track", "One tracked object in one frame.")
      .def_readonly("id", &Track::id)
      .def_readonly("x_m", &Track::x_m)
      .def_readonly("y_m", &Track::y_m)
      .def_readonly("vx_mps", &Track::vx_mps)
      .def_readonly("vy_mps", &Track::vy_mps)
      .def_readonly("object_class", &Track::object_class)
      .def_readonly("coasting", &Track::coasting)
      .def_readonly("time_since_update_s", &Track::time_since_update_s)
      .def_readonly("hits", &Track::hits)
      .def_readonly("area_m2", &Track::area_m2)
      .def("__repr__", [](const Track& t) {
        return "Track(id=" + std::to_string(t.id) + ", x_m=" + py::repr(py::float_(t.x_m)).cast<std::string>() +
               ", y_m=" + py::repr(py::float_(t.y_m)).cast<std::string>() + ")";
      });

  py::class_<PyTracker>(m, "Tracker", "The site's tracker (tracking.algorithm), stepped one frame at a time.")
      .def(py::init([](const Site& site) { return std::make_unique<PyTracker>(site); }), "site"_a)
      .def(py::init([](const Tables& t) { return std::make_unique<PyTracker>(*t.site); }), "tables"_a)
      .def("update", &PyTracker::Update, "objects"_a, "time_s"_a, "all"_a = false, "frame"_a = py::none(),
           "One frame: detect()'s Objects at time_s (strictly increasing, else InvalidInputError).\n"
           "Returns the tracks `occmap run` writes (all=True: coasting ones past report_coasting_s too).\n"
           "frame: the frame number in events (default: one more than the last). Releases the GIL.")
      .def("update", &PyTracker::UpdateDetections, "detections"_a, "time_s"_a, "all"_a = false, "frame"_a = py::none(),
           "One frame from a list of Detection (any detector's; multi-target tracker only).")
      .def_property_readonly("events", &PyTracker::Events,
           "The last update's zone events (enter, leave, dwell, count) and line crossings (in, out) of\n"
           "the site's tracking.zones and tracking.lines, as dicts like events.jsonl's lines.");

  // --- metrics
  m.def("detection_metrics", &DetectionMetricsDict, "ground_truth"_a, "detections"_a, "match_threshold_m"_a = 0.5,
        "CLEAR MOD (MODA, MODP, precision, recall) over frames: ground_truth[f] and detections[f] are\n"
        "sequences of (x_m, y_m) (or Detection). Returns a dict; undefined ratios are nan.");
  m.def("tracking_metrics", &TrackingMetricsDict, "ground_truth"_a, "tracks"_a, "match_threshold_m"_a = 0.5,
        "CLEAR MOT (MOTA, MOTP) and IDF1 over frames: ground_truth[f] and tracks[f] are sequences of\n"
        "(id, x_m, y_m) (or Track). Returns a dict; undefined ratios are nan.");

  // --- images
  m.def("read_image", [](const fs::path& path, bool colour) -> py::array_t<uint8_t> {
    if (colour) return ToArray(Unwrap(ReadRgbImage(path)).view());
    return ToArray(Unwrap(ReadGrayImage(path)).view());
  }, "path"_a, "colour"_a = false, "An image file as (rows, columns) grey or (rows, columns, 3) RGB uint8.");
}

}  // namespace occmap::python
