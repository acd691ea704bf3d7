#include "occmap/objects/split.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include "occmap/objects/split_internal.h"
#include "occmap/util/status.h"

namespace occmap {
namespace {

using split_internal::LocalBox;
using split_internal::MeanCellCentre;


// Felzenszwalb and Huttenlocher's lower envelope of parabolas: out[q] = min_p (q - p)^2 + f[p]
// for finite f. f and out hold n values; v and z are reused.
void SquaredDistance1dInto(const double* f, int n, double* out, std::vector<int>& v, std::vector<double>& z) {
  const double inf = std::numeric_limits<double>::infinity();
  v.resize(static_cast<size_t>(n));
  z.resize(static_cast<size_t>(n) + 1);
  v[0] = 0;
  int k = 0;
  z[0] = -inf;
  z[1] = inf;
  auto intersection = [&](int q, int p) {
    return ((f[q] + double(q) * q) - (f[p] + double(p) * p)) / (2.0 * q - 2.0 * p);
  };
  for (int q = 1; q < n; ++q) {
    double s = intersection(q, v[k]);
    while (s <= z[k]) {
      --k;
      s = intersection(q, v[k]);
    }
    ++k;
    v[k] = q;
    z[k] = s;
    z[k + 1] = inf;
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[k + 1] < q) ++k;
    out[q] = double(q - v[k]) * (q - v[k]) + f[v[k]];
  }
}

// Squared Euclidean distance (in cells) from each inside cell to the nearest outside cell
// centre, over a box whose border is outside. Column scans, then exact row envelopes.
std::vector<double> SquaredDistanceTransform(const std::vector<uint8_t>& inside, int width, int height) {
  std::vector<double> g(inside.size(), 0);
  for (int a = 0; a < width; ++a) {
    double run = 0;  // distance to the last outside cell below
    for (int b = 0; b < height; ++b) {
      run = inside[b * width + a] ? run + 1 : 0;
      g[b * width + a] = run;
    }
    run = 0;
    for (int b = height - 1; b >= 0; --b) {
      run = inside[b * width + a] ? run + 1 : 0;
      g[b * width + a] = std::min(g[b * width + a], run);
    }
  }
  std::vector<double> out(inside.size()), f(static_cast<size_t>(width));
  std::vector<int> v;
  std::vector<double> z;
  for (int b = 0; b < height; ++b) {
    for (int a = 0; a < width; ++a) f[a] = g[b * width + a] * g[b * width + a];
    SquaredDistance1dInto(f.data(), width, out.data() + int64_t{b} * width, v, z);
  }
  return out;
}



// Nearest-centre partition of the cells; ties go to the lower centre.
std::vector<int> Partition(const std::vector<Eigen::Vector2d>& points, const std::vector<Eigen::Vector2d>& centres) {
  std::vector<int> label(points.size(), 0);
  for (size_t p = 0; p < points.size(); ++p) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t c = 0; c < centres.size(); ++c) {
      const double d2 = (points[p] - centres[c]).squaredNorm();
      if (d2 < best) {
        best = d2;
        label[p] = static_cast<int>(c);
      }
    }
  }
  return label;
}

// Lloyd's k-means of grid cells (their centres) from the given centres, until no cell changes
// cluster (at most 50 rounds); empty clusters are dropped. A cluster's centre is the centre of
// its cells' mean index, from exact integer sums: x = origin_x + (sum of i / n + 0.5) * cell
// size (the same in any order of the cells, so the fast version updates the sums by the cells
// that changed cluster).
std::vector<int> KMeansCells(const FloorGrid& grid, const std::vector<int64_t>& cells,
                             std::vector<Eigen::Vector2d> centres) {
  std::vector<Eigen::Vector2d> points;
  points.reserve(cells.size());
  for (int64_t c : cells) points.push_back(grid.CellCenter(c));
  std::vector<int> label = Partition(points, centres);
  for (int round = 0; round < 50; ++round) {
    std::vector<int64_t> sum_i(centres.size(), 0), sum_j(centres.size(), 0), counts(centres.size(), 0);
    for (size_t p = 0; p < cells.size(); ++p) {
      sum_i[static_cast<size_t>(label[p])] += cells[p] % grid.cells_x;
      sum_j[static_cast<size_t>(label[p])] += cells[p] / grid.cells_x;
      ++counts[static_cast<size_t>(label[p])];
    }
    std::vector<Eigen::Vector2d> next;
    for (size_t c = 0; c < centres.size(); ++c) {
      if (counts[c] > 0) next.push_back(MeanCellCentre(grid, sum_i[c], sum_j[c], counts[c]));
    }
    centres = std::move(next);
    std::vector<int> relabel = Partition(points, centres);
    if (relabel == label) break;
    label = std::move(relabel);
  }
  return label;
}

}  // namespace

Detection DetectionFromCells(const FloorGrid& grid, const std::vector<int64_t>& cells) {
  Detection d;
  d.cells = static_cast<int64_t>(cells.size());
  d.area_m2 = static_cast<double>(cells.size()) * grid.cell_size_m * grid.cell_size_m;
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (int64_t c : cells) sum += grid.CellCenter(c);
  const double n = static_cast<double>(cells.size());
  const Eigen::Vector2d mean = sum / n;
  Eigen::Matrix2d second = Eigen::Matrix2d::Zero();
  for (int64_t c : cells) {
    const Eigen::Vector2d r = grid.CellCenter(c) - mean;
    second += r * r.transpose();
  }
  d.x_m = mean.x();
  d.y_m = mean.y();
  d.spread_m2 = second / n;
  return d;
}

std::vector<int64_t> BlobCells(const OccupancyMap& map, const Blob& blob) {
  const FloorGrid& grid = map.grid();
  OCCMAP_CHECK(blob.min_i >= 0 && blob.min_j >= 0 && blob.max_i < grid.cells_x && blob.max_j < grid.cells_y &&
                   blob.min_i <= blob.max_i && blob.min_j <= blob.max_j,
               "BlobCells: the blob's box is not on the map's grid");
  std::vector<int64_t> occupied;
  for (int j = blob.min_j; j <= blob.max_j; ++j) {
    for (int i = blob.min_i; i <= blob.max_i; ++i) {
      const int64_t cell = int64_t{j} * grid.cells_x + i;
      if (map.state(cell) == CellState::kOccupied) occupied.push_back(cell);
    }
  }
  if (static_cast<int64_t>(occupied.size()) == blob.cells) return occupied;

  // Other blobs reach into the box: label its 8-connected components, keep the blob's.
  const int w = blob.max_i - blob.min_i + 1, h = blob.max_j - blob.min_j + 1;
  std::vector<int> label(static_cast<size_t>(w) * h, -1);
  for (int64_t cell : occupied) {
    label[(cell / grid.cells_x - blob.min_j) * w + (cell % grid.cells_x - blob.min_i)] = -2;  // unlabelled
  }
  std::vector<int64_t> best;
  double best_error = std::numeric_limits<double>::infinity();
  std::vector<int> stack;
  int next_label = 0;
  for (size_t start = 0; start < label.size(); ++start) {
    if (label[start] != -2) continue;
    std::vector<int64_t> component;
    label[start] = next_label;
    stack.push_back(static_cast<int>(start));
    while (!stack.empty()) {
      const int local = stack.back();
      stack.pop_back();
      const int a = local % w, b = local / w;
      component.push_back(int64_t{b + blob.min_j} * grid.cells_x + (a + blob.min_i));
      for (int db = -1; db <= 1; ++db) {
        for (int da = -1; da <= 1; ++da) {
          const int na = a + da, nb = b + db;
          if (na < 0 || nb < 0 || na >= w || nb >= h || label[nb * w + na] != -2) continue;
          label[nb * w + na] = next_label;
          stack.push_back(nb * w + na);
        }
      }
    }
    ++next_label;
    if (static_cast<int64_t>(component.size()) != blob.cells) continue;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    for (int64_t c : component) sum += grid.CellCenter(c);
    const double error = (sum / static_cast<double>(component.size()) - Eigen::Vector2d(blob.x_m, blob.y_m)).norm();
    if (error < best_error) {
      best_error = error;
      best = std::move(component);
    }
  }
  OCCMAP_CHECK(!best.empty() && best_error < grid.cell_size_m, "BlobCells: the blob is not a component of this map");
  std::sort(best.begin(), best.end());
  return best;
}

int MaxPeopleInArea(double area_m2, const ObjectOptions& options) {
  const double n = std::floor(area_m2 / options.person_area_m2() + 1.0 - options.split_area_margin);
  return static_cast<int>(std::clamp(n, 1.0, static_cast<double>(options.max_people_per_blob)));
}

std::vector<Eigen::Vector2d> DistancePeaks(const FloorGrid& grid, const std::vector<int64_t>& cells,
                                           const ObjectOptions& options) {
  if (cells.empty()) return {};
  int min_i = grid.cells_x, min_j = grid.cells_y, max_i = -1, max_j = -1;
  for (int64_t c : cells) {
    const int i = static_cast<int>(c % grid.cells_x), j = static_cast<int>(c / grid.cells_x);
    min_i = std::min(min_i, i);
    max_i = std::max(max_i, i);
    min_j = std::min(min_j, j);
    max_j = std::max(max_j, j);
  }
  const LocalBox box{min_i - 1, min_j - 1, max_i - min_i + 3, max_j - min_j + 3};
  std::vector<uint8_t> inside(static_cast<size_t>(box.width) * box.height, 0);
  std::vector<int> locals;
  locals.reserve(cells.size());
  for (int64_t c : cells) {
    const int local = box.Index(static_cast<int>(c % grid.cells_x) - box.i0, static_cast<int>(c / grid.cells_x) - box.j0);
    inside[local] = 1;
    locals.push_back(local);
  }
  const std::vector<double> d2 = SquaredDistanceTransform(inside, box.width, box.height);
  std::vector<double> dist_m(d2.size());
  for (size_t k = 0; k < d2.size(); ++k) dist_m[k] = std::sqrt(d2[k]) * grid.cell_size_m;

  // Cells from the highest distance down (ties: lower index first); union-find of processed
  // cells; each component remembers its peak. When components meet at cell c, all but the
  // one with the highest peak end there, with persistence peak - dist(c).
  // (A counting sort on the squared distances, whole numbers of cells^2: locals are in
  // increasing index order, and each bucket keeps that order.)
  {
    int max_key = 0;
    for (int c : locals) max_key = std::max(max_key, static_cast<int>(d2[c]));
    std::vector<int> start(static_cast<size_t>(max_key) + 2, 0);
    for (int c : locals) ++start[static_cast<size_t>(max_key - static_cast<int>(d2[c])) + 1];
    for (size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
    std::vector<int> sorted(locals.size());
    for (int c : locals) sorted[static_cast<size_t>(start[static_cast<size_t>(max_key - static_cast<int>(d2[c]))]++)] = c;
    locals = std::move(sorted);
  }
  std::vector<int> parent(inside.size(), -1), peak(inside.size(), -1), rank_of(inside.size(), 0);
  for (size_t r = 0; r < locals.size(); ++r) rank_of[locals[r]] = static_cast<int>(r);
  auto find = [&](int x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  };
  const double min_neck_m = std::max(options.split_min_neck_m, grid.cell_size_m);
  const double half_cell_m = 0.5 * grid.cell_size_m;
  std::vector<int> significant;
  for (int c : locals) {
    const int a = c % box.width, b = c / box.width;
    int roots[8];
    int num_roots = 0;
    for (int db = -1; db <= 1; ++db) {
      for (int da = -1; da <= 1; ++da) {
        if (da == 0 && db == 0) continue;
        const int n = box.Index(a + da, b + db);  // the border is never inside: in range
        if (!inside[n] || parent[n] < 0) continue;
        const int root = find(n);
        if (std::find(roots, roots + num_roots, root) == roots + num_roots) roots[num_roots++] = root;
      }
    }
    if (num_roots == 0) {
      parent[c] = c;
      peak[c] = c;
      continue;
    }
    int best = roots[0];
    for (int k = 1; k < num_roots; ++k) {
      if (rank_of[peak[roots[k]]] < rank_of[peak[best]]) best = roots[k];
    }
    for (int k = 0; k < num_roots; ++k) {
      const int r = roots[k];
      if (r == best) continue;
      const double height_m = dist_m[peak[r]];
      if (height_m - dist_m[c] >= min_neck_m && height_m - half_cell_m >= options.split_min_peak_radius_m) {
        significant.push_back(peak[r]);
      }
      parent[r] = best;
    }
    parent[c] = best;
  }
  significant.push_back(locals.front());  // the highest peak always counts
  std::sort(significant.begin(), significant.end(), [&](int a, int b) { return rank_of[a] < rank_of[b]; });
  std::vector<Eigen::Vector2d> peaks;
  for (int local : significant) {
    const int64_t cell = int64_t{local / box.width + box.j0} * grid.cells_x + (local % box.width + box.i0);
    peaks.push_back(grid.CellCenter(cell));
  }
  return peaks;
}

std::vector<Detection> DetectionsFromBlobs(const std::vector<Blob>& blobs, const OccupancyMap& map,
                                           const ObjectOptions& options,
                                           const std::vector<Eigen::Vector2d>& predicted_positions_m) {
  const FloorGrid& grid = map.grid();
  const double radius_m = options.person_radius_m();
  std::vector<Detection> detections;
  for (size_t b = 0; b < blobs.size(); ++b) {
    const Blob& blob = blobs[b];
    if (blob.area_m2 < options.min_detection_area_m2 || blob.cells <= 0) continue;
    const std::vector<int64_t> cells = BlobCells(map, blob);
    const int max_people = MaxPeopleInArea(blob.area_m2, options);
    std::vector<std::vector<int64_t>> parts;
    if (max_people >= 2) {
      std::vector<Eigen::Vector2d> points;
      points.reserve(cells.size());
      for (int64_t c : cells) points.push_back(grid.CellCenter(c));
      std::vector<Eigen::Vector2d> seeds = DistancePeaks(grid, cells, options);
      if (static_cast<int>(seeds.size()) > max_people) seeds.resize(static_cast<size_t>(max_people));

      // Predictions within a person's radius of the blob's cells.
      std::vector<Eigen::Vector2d> inside;
      const double x_lo = grid.origin_x_m + blob.min_i * grid.cell_size_m - radius_m;
      const double x_hi = grid.origin_x_m + (blob.max_i + 1) * grid.cell_size_m + radius_m;
      const double y_lo = grid.origin_y_m + blob.min_j * grid.cell_size_m - radius_m;
      const double y_hi = grid.origin_y_m + (blob.max_j + 1) * grid.cell_size_m + radius_m;
      for (const Eigen::Vector2d& p : predicted_positions_m) {
        if (static_cast<int>(inside.size()) == max_people) break;
        if (p.x() < x_lo || p.x() > x_hi || p.y() < y_lo || p.y() > y_hi) continue;
        const bool near = std::any_of(points.begin(), points.end(),
                                      [&](const Eigen::Vector2d& q) { return (q - p).squaredNorm() <= radius_m * radius_m; });
        if (near) inside.push_back(p);
      }

      if (inside.size() >= 2 && inside.size() > seeds.size()) {
        // The blob measures where the group is; the predictions, how its members stand in it.
        const Detection whole = DetectionFromCells(grid, cells);
        Eigen::Vector2d mean = Eigen::Vector2d::Zero();
        for (const Eigen::Vector2d& p : inside) mean += p;
        const Eigen::Vector2d shift = Eigen::Vector2d(whole.x_m, whole.y_m) - mean / static_cast<double>(inside.size());
        const double share = 1.0 / static_cast<double>(inside.size());
        for (const Eigen::Vector2d& p : inside) {
          Detection d;
          d.x_m = p.x() + shift.x();
          d.y_m = p.y() + shift.y();
          d.area_m2 = whole.area_m2 * share;
          d.cells = whole.cells / static_cast<int64_t>(inside.size());
          d.group = static_cast<int>(b);
          d.parts = static_cast<int>(inside.size());
          d.guided = true;
          detections.push_back(d);
        }
        continue;
      }
      std::vector<int> label;
      size_t num_parts = 0;
      if (seeds.size() >= 2) {
        label = KMeansCells(grid, cells, seeds);
        num_parts = static_cast<size_t>(*std::max_element(label.begin(), label.end())) + 1;
      }
      if (num_parts >= 2) {
        parts.resize(num_parts);
        for (size_t p = 0; p < cells.size(); ++p) parts[static_cast<size_t>(label[p])].push_back(cells[p]);
      }
    }
    if (parts.empty()) parts.push_back(cells);

    const size_t first = detections.size();
    for (const std::vector<int64_t>& part : parts) {
      if (part.empty()) continue;
      Detection d = DetectionFromCells(grid, part);
      if (d.area_m2 < options.min_detection_area_m2) continue;
      d.group = static_cast<int>(b);
      detections.push_back(d);
    }
    for (size_t k = first; k < detections.size(); ++k) detections[k].parts = static_cast<int>(detections.size() - first);
  }
  return detections;
}

BlobSplit SplitBlob(const Blob& blob, const OccupancyMap& map, const ObjectOptions& options) {
  BlobSplit split;
  if (blob.area_m2 < options.min_detection_area_m2 || blob.cells <= 0) return split;
  const FloorGrid& grid = map.grid();
  split.cells = BlobCells(map, blob);
  const std::vector<int64_t>& cells = split.cells;
  split.max_people = MaxPeopleInArea(blob.area_m2, options);
  std::vector<std::vector<int64_t>> parts;
  if (split.max_people >= 2) {
    std::vector<Eigen::Vector2d> seeds = DistancePeaks(grid, cells, options);
    if (static_cast<int>(seeds.size()) > split.max_people) seeds.resize(static_cast<size_t>(split.max_people));
    split.peaks = seeds.size();
    if (seeds.size() >= 2) {
      const std::vector<int> label = KMeansCells(grid, cells, seeds);
      const size_t num_parts = static_cast<size_t>(*std::max_element(label.begin(), label.end())) + 1;
      if (num_parts >= 2) {
        parts.resize(num_parts);
        for (size_t p = 0; p < cells.size(); ++p) parts[static_cast<size_t>(label[p])].push_back(cells[p]);
      }
    }
  }
  auto add = [&](const std::vector<int64_t>& part) {
    if (part.empty()) return;
    Detection d = DetectionFromCells(grid, part);
    if (d.area_m2 < options.min_detection_area_m2) return;
    d.group = 0;
    split.detections.push_back(d);
  };
  if (parts.empty()) {
    add(cells);
  } else {
    for (const std::vector<int64_t>& part : parts) add(part);
  }
  for (Detection& d : split.detections) d.parts = static_cast<int>(split.detections.size());
  return split;
}

std::vector<Eigen::Vector2d> PredictionsOnBlob(const FloorGrid& grid, const Blob& blob, const BlobSplit& split,
                                               double radius_m,
                                               const std::vector<Eigen::Vector2d>& predicted_positions_m) {
  // Step 5 (as DetectionsFromBlobs): predictions within a person's radius of the blob's cells.
  std::vector<Eigen::Vector2d> inside;
  if (split.cells.empty() || split.max_people < 2 || predicted_positions_m.empty()) return inside;
  const double x_lo = grid.origin_x_m + blob.min_i * grid.cell_size_m - radius_m;
  const double x_hi = grid.origin_x_m + (blob.max_i + 1) * grid.cell_size_m + radius_m;
  const double y_lo = grid.origin_y_m + blob.min_j * grid.cell_size_m - radius_m;
  const double y_hi = grid.origin_y_m + (blob.max_j + 1) * grid.cell_size_m + radius_m;
  for (const Eigen::Vector2d& p : predicted_positions_m) {
    if (static_cast<int>(inside.size()) == split.max_people) break;
    if (p.x() < x_lo || p.x() > x_hi || p.y() < y_lo || p.y() > y_hi) continue;
    const bool near = std::any_of(split.cells.begin(), split.cells.end(), [&](int64_t c) {
      return (grid.CellCenter(c) - p).squaredNorm() <= radius_m * radius_m;
    });
    if (near) inside.push_back(p);
  }
  return inside;
}

std::vector<Detection> GuidedCut(double x_m, double y_m, double area_m2, int64_t cells,
                                 const std::vector<Eigen::Vector2d>& inside) {
  std::vector<Detection> out;
  if (inside.empty()) return out;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : inside) mean += p;
  const Eigen::Vector2d shift = Eigen::Vector2d(x_m, y_m) - mean / static_cast<double>(inside.size());
  const double share = 1.0 / static_cast<double>(inside.size());
  for (const Eigen::Vector2d& p : inside) {
    Detection d;
    d.x_m = p.x() + shift.x();
    d.y_m = p.y() + shift.y();
    d.area_m2 = area_m2 * share;
    d.cells = cells / static_cast<int64_t>(inside.size());
    d.parts = static_cast<int>(inside.size());
    d.guided = true;
    out.push_back(d);
  }
  return out;
}

std::vector<Detection> DetectionsFromSplits(const std::vector<Blob>& blobs, const std::vector<BlobSplit>& splits,
                                            const OccupancyMap& map, const ObjectOptions& options,
                                            const std::vector<Eigen::Vector2d>& predicted_positions_m) {
  OCCMAP_CHECK(splits.size() == blobs.size(), "DetectionsFromSplits: one split per blob");
  const FloorGrid& grid = map.grid();
  std::vector<Detection> detections;
  for (size_t b = 0; b < blobs.size(); ++b) {
    const BlobSplit& split = splits[b];
    if (split.cells.empty()) continue;
    const std::vector<Eigen::Vector2d> inside =
        PredictionsOnBlob(grid, blobs[b], split, options.person_radius_m(), predicted_positions_m);
    if (inside.size() >= 2 && inside.size() > split.peaks) {
      // The blob measures where the group is; the predictions, how its members stand in it.
      const Detection whole = DetectionFromCells(grid, split.cells);
      for (Detection d : GuidedCut(whole.x_m, whole.y_m, whole.area_m2, whole.cells, inside)) {
        d.group = static_cast<int>(b);
        detections.push_back(d);
      }
      continue;
    }
    for (Detection d : split.detections) {
      d.group = static_cast<int>(b);
      detections.push_back(d);
    }
  }
  return detections;
}

}  // namespace occmap
