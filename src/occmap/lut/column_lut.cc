#include "occmap/lut/column_lut.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace occmap {

namespace {

constexpr double kPi = 3.14159265358979323846;
// Heights (fractions of the column) whose lines of sight decide whether an occluder hides it.
constexpr double kOcclusionSamples[] = {0.1, 0.3, 0.5, 0.7, 0.9};

// Where the segment a + t (b - a), t in [0, 1], is inside [lo, hi] along one axis: narrows
// [t0, t1]; false when it leaves nothing.
bool ClipSlab(double a, double b, double lo, double hi, double& t0, double& t1) {
  const double d = b - a;
  if (std::abs(d) < 1e-12) return a >= lo && a <= hi;
  double u0 = (lo - a) / d, u1 = (hi - a) / d;
  if (u0 > u1) std::swap(u0, u1);
  t0 = std::max(t0, u0);
  t1 = std::min(t1, u1);
  return t0 <= t1;
}

}  // namespace

Status Occluder::Validate() const {
  if (!(size_m.x() > 0 && size_m.y() > 0 && std::isfinite(size_m.x()) && std::isfinite(size_m.y())))
    return InvalidInput(fmt::format("size_m: expected positive sizes, found [{}, {}]", size_m.x(), size_m.y()));
  if (!(height_m > 0 && std::isfinite(height_m)))
    return InvalidInput(fmt::format("height_m: expected a positive height, found {}", height_m));
  if (!std::isfinite(base_m) || !std::isfinite(yaw_deg) || !centre_m.allFinite())
    return InvalidInput("centre_m, base_m, yaw_deg: expected finite numbers");
  return Status::Ok();
}

bool Occluder::Blocks(const Eigen::Vector3d& a, const Eigen::Vector3d& b) const {
  double t0 = 0, t1 = 1;
  if (!ClipSlab(a.z(), b.z(), base_m, base_m + height_m, t0, t1)) return false;
  // In the occluder's own horizontal frame (centre at 0, box axes along x and y).
  const double yaw = yaw_deg * kPi / 180.0;
  const double c = std::cos(yaw), s = std::sin(yaw);
  auto local = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector2d d = p.head<2>() - centre_m;
    return Eigen::Vector2d(c * d.x() + s * d.y(), -s * d.x() + c * d.y());
  };
  const Eigen::Vector2d la = local(a), lb = local(b);
  if (shape == Shape::kBox) {
    return ClipSlab(la.x(), lb.x(), -size_m.x() / 2, size_m.x() / 2, t0, t1) &&
           ClipSlab(la.y(), lb.y(), -size_m.y() / 2, size_m.y() / 2, t0, t1);
  }
  // Cylinder: the part of [t0, t1] within radius r of the axis.
  const double r = size_m.x() / 2;
  const Eigen::Vector2d d = lb - la;
  const double qa = d.squaredNorm(), qb = 2 * la.dot(d), qc = la.squaredNorm() - r * r;
  if (qa < 1e-18) return qc <= 0;
  const double disc = qb * qb - 4 * qa * qc;
  if (disc < 0) return false;
  const double root = std::sqrt(disc);
  const double u0 = (-qb - root) / (2 * qa), u1 = (-qb + root) / (2 * qa);
  return std::max(t0, u0) <= std::min(t1, u1);
}

void Occluder::AppendToHash(Hasher& hasher) const {
  hasher.AddPod(static_cast<int>(shape));
  hasher.AddPod(centre_m.x());
  hasher.AddPod(centre_m.y());
  hasher.AddPod(size_m.x());
  hasher.AddPod(size_m.y());
  hasher.AddPod(base_m);
  hasher.AddPod(height_m);
  hasher.AddPod(yaw_deg);
}

Result<std::vector<Occluder>> ParseOccluders(const YamlField& list) {
  if (!list.IsSequence()) return list.Error("expected a list of boxes and cylinders");
  std::vector<Occluder> out;
  for (size_t k = 0; k < list.size(); ++k) {
    OCCMAP_ASSIGN_OR_RETURN(YamlField f, list.At(k));
    if (!f.IsMap()) return f.Error("expected {shape: box or cylinder, centre_m: [x, y], ...}");
    OCCMAP_RETURN_IF_ERROR(f.CheckKeys({"shape", "centre_m", "size_m", "diameter_m", "height_m", "base_m", "yaw_deg", "name"}));
    Occluder o;
    OCCMAP_ASSIGN_OR_RETURN(std::string shape, f.GetString("shape"));
    if (shape == "box") {
      o.shape = Occluder::Shape::kBox;
      OCCMAP_ASSIGN_OR_RETURN(std::vector<double> size, f.GetDoubles("size_m", 2));
      o.size_m = {size[0], size[1]};
      if (f.Has("diameter_m")) return f.Find("diameter_m")->Error("a box has size_m, not diameter_m");
    } else if (shape == "cylinder") {
      o.shape = Occluder::Shape::kCylinder;
      OCCMAP_ASSIGN_OR_RETURN(double d, f.GetDouble("diameter_m"));
      o.size_m = {d, d};
      if (f.Has("size_m")) return f.Find("size_m")->Error("a cylinder has diameter_m, not size_m");
    } else {
      return f.Find("shape")->Error(fmt::format("expected box or cylinder, found '{}'", shape));
    }
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> centre, f.GetDoubles("centre_m", 2));
    o.centre_m = {centre[0], centre[1]};
    OCCMAP_ASSIGN_OR_RETURN(o.height_m, f.GetDouble("height_m"));
    OCCMAP_ASSIGN_OR_RETURN(o.base_m, f.GetDouble("base_m", 0.0));
    OCCMAP_ASSIGN_OR_RETURN(o.yaw_deg, f.GetDouble("yaw_deg", 0.0));
    if (Status s = o.Validate(); !s.ok()) return f.Error(s.message());
    out.push_back(o);
  }
  return out;
}

Status ColumnLutOptions::Validate(const FloorGrid& grid) const {
  if (!(step_m > 0 && std::isfinite(step_m)))
    return InvalidInput(fmt::format("step_m: expected a positive distance, found {}", step_m));
  if (step_m > 1.0) return InvalidInput(fmt::format("step_m: expected at most 1 m, found {}", step_m));
  if (!(height_m > 0 && height_m <= 5 && std::isfinite(height_m)))
    return InvalidInput(fmt::format("height_m: expected a height in (0, 5] m, found {}", height_m));
  if (grid.cell_size_m > 0 && step_m < grid.cell_size_m * 0.5)
    return InvalidInput(fmt::format("step_m: expected at least the floor cell size {} m, found {}", grid.cell_size_m,
                                    step_m));
  return Status::Ok();
}

void ColumnLutOptions::AppendToHash(Hasher& hasher) const {
  hasher.AddPod(step_m);
  hasher.AddPod(height_m);
}

int64_t ColumnLut::MemoryBytes() const {
  return static_cast<int64_t>(views_.size() * sizeof(ColumnView) + view_count_.size());
}

FloorGrid CandidateGrid(const FloorGrid& grid, double step_m, int* cells_per_step) {
  const int k = std::max(1, static_cast<int>(std::lround(step_m / grid.cell_size_m)));
  if (cells_per_step != nullptr) *cells_per_step = k;
  FloorGrid out = grid;
  out.cell_size_m = grid.cell_size_m * k;
  out.cells_x = std::max(1, grid.cells_x / k);
  out.cells_y = std::max(1, grid.cells_y / k);
  return out;
}

Result<ColumnLut> BuildColumnLut(const std::vector<LutCameraInput>& cameras, const FloorGrid& grid,
                                 double plane_height_m, const ColumnLutOptions& options,
                                 std::span<const Occluder> occluders, Context& ctx) {
  OCCMAP_RETURN_IF_ERROR(grid.Validate());
  OCCMAP_RETURN_IF_ERROR(options.Validate(grid));
  if (cameras.empty() || cameras.size() > static_cast<size_t>(GroundLut::kMaxCameras))
    return InvalidInput(fmt::format("cameras: expected 1 to {}, found {}", GroundLut::kMaxCameras, cameras.size()));
  for (size_t k = 0; k < occluders.size(); ++k)
    OCCMAP_RETURN_IF_ERROR(occluders[k].Validate().WithContext(fmt::format("occluder {}", k)));
  ColumnLut lut;
  lut.options_ = options;
  lut.candidates_ = CandidateGrid(grid, options.step_m, &lut.cells_per_step_);
  const int64_t n = lut.candidates_.num_cells();
  lut.views_.assign(cameras.size() * static_cast<size_t>(n), ColumnView{});
  lut.view_count_.assign(static_cast<size_t>(n), 0);
  for (const LutCameraInput& cam : cameras) {
    if (cam.camera == nullptr) return InvalidInput("cameras: a camera model is missing");
    const ImageSize size = cam.camera->image_size();
    if (!cam.mask.empty() && (cam.mask.width() != size.width || cam.mask.height() != size.height))
      return InvalidInput(fmt::format("mask: expected {}x{} (the camera's image), found {}x{}", size.width,
                                      size.height, cam.mask.width(), cam.mask.height()));
    lut.image_sizes_.push_back(size);
  }
  const double z0 = plane_height_m, z1 = plane_height_m + options.height_m;
  for (size_t c = 0; c < cameras.size(); ++c) {
    const CameraModel& camera = *cameras[c].camera;
    const ImageView<const uint8_t> mask = cameras[c].mask;
    const std::optional<Eigen::Vector3d> centre = camera.CenterInWorld();
    const ImageSize size = lut.image_sizes_[c];
    ColumnView* views = lut.views_.data() + c * static_cast<size_t>(n);
    // Occluders a camera is mounted on (its pole, the wall it hangs on: its centre within 0.3 m
    // of their footprint) hide nothing from it.
    std::vector<Occluder> hiding;
    for (const Occluder& o : occluders) {
      if (centre) {
        Occluder grown = o;
        grown.size_m += Eigen::Vector2d(0.6, 0.6);
        grown.base_m = -1e9;
        grown.height_m = 2e9;
        if (grown.Blocks(*centre, *centre)) continue;
      }
      hiding.push_back(o);
    }
    ParallelFor(
        ctx, 0, n,
        [&](int64_t begin, int64_t end, int) {
          for (int64_t k = begin; k < end; ++k) {
            const Eigen::Vector2d xy = lut.candidates_.CellCenter(k);
            const std::optional<Eigen::Vector2d> foot = camera.Project({xy.x(), xy.y(), z0});
            if (!foot) continue;
            bool seen = camera.InImage(*foot);
            const int fx = static_cast<int>(std::lround(foot->x())), fy = static_cast<int>(std::lround(foot->y()));
            if (fx < 0 || fy < 0 || fx >= size.width || fy >= size.height) seen = false;
            if (seen && !mask.empty() && mask(fx, fy) == 0) seen = false;
            const std::optional<Eigen::Vector2d> top = camera.Project({xy.x(), xy.y(), z1});
            if (!top) continue;
            // Across the line of sight: perpendicular to the horizontal direction from the camera
            // (any horizontal direction for a camera without a centre).
            Eigen::Vector2d across(1, 0);
            if (centre) {
              const Eigen::Vector2d d = xy - centre->head<2>();
              if (d.norm() > 1e-9) across = Eigen::Vector2d(-d.y(), d.x()).normalized();
            }
            constexpr double kProbe_m = 0.1;
            const Eigen::Vector2d side = xy + kProbe_m * across;
            const std::optional<Eigen::Vector2d> foot_side = camera.Project({side.x(), side.y(), z0});
            const std::optional<Eigen::Vector2d> top_side = camera.Project({side.x(), side.y(), z1});
            if (!foot_side || !top_side) continue;
            ColumnView v;
            v.top_row = static_cast<float>(top->y());
            v.bottom_row = static_cast<float>(foot->y());
            v.axis_x_top = static_cast<float>(top->x());
            v.axis_x_bottom = static_cast<float>(foot->x());
            v.half_width_top = static_cast<float>((*top_side - *top).norm() / kProbe_m);
            v.half_width_bottom = static_cast<float>((*foot_side - *foot).norm() / kProbe_m);
            if (v.top_row > v.bottom_row) {  // an upside-down view: rows increase upwards
              std::swap(v.top_row, v.bottom_row);
              std::swap(v.axis_x_top, v.axis_x_bottom);
              std::swap(v.half_width_top, v.half_width_bottom);
            }
            v.seen = seen;
            v.feet_cut = !seen && fy >= size.height && fx >= 0 && fx < size.width && top->y() >= 0 &&
                         top->y() < size.height && camera.InImage(*top);
            v.projected = true;
            if (centre && !hiding.empty()) {
              int hidden = 0;
              for (double f : kOcclusionSamples) {
                const Eigen::Vector3d p(xy.x(), xy.y(), z0 + f * options.height_m);
                for (const Occluder& o : hiding) {
                  if (o.Blocks(*centre, p)) {
                    ++hidden;
                    break;
                  }
                }
              }
              v.blocked = 2 * hidden >= static_cast<int>(std::size(kOcclusionSamples));
            }
            views[k] = v;
          }
        },
        256);
  }
  for (size_t c = 0; c < cameras.size(); ++c)
    for (int64_t k = 0; k < n; ++k)
      if (lut.views_[c * static_cast<size_t>(n) + static_cast<size_t>(k)].seen) ++lut.view_count_[k];
  return lut;
}

}  // namespace occmap
