#include "occmap/objects/object_detector.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "occmap/objects/grouping.h"
#include "occmap/util/status.h"

namespace occmap {

ObjectDetector::ObjectDetector(const ObjectOptions& options, double plane_height_m, std::vector<CameraView> cameras)
    : settings_(options), split_options_(options), plane_height_m_(plane_height_m), cameras_(std::move(cameras)) {
  const Status valid = options.Validate();
  OCCMAP_CHECK(valid.ok(), "ObjectDetector: invalid options: " + valid.message());
  // The groups are footprints grown by r, so one person's size grows with them.
  split_options_.person_diameter_m += 2 * settings_.group_radius_m;
  ghost_options_ = {.occluder_radius_m = split_options_.person_radius_m(),
                    .occluder_height_m = settings_.occluder_height_m};
  for (const CameraView& v : cameras_) {
    const CameraModel* model = v.camera;
    // Sites allow 16384 pixels a side (site.cc): an invariant here.
    OCCMAP_CHECK(model->image_size().width <= 65536 && model->image_size().height <= 32768,
                 "ObjectDetector: camera images up to 65536 x 32768 pixels (the elevated check packs pixels)");
    const Image<uint8_t>* mask = v.mask;
    const double z = plane_height_m;
    const std::optional<Eigen::Vector3d> centre = model->CenterInWorld();
    has_centre_.push_back(centre.has_value());
    // Whether the camera sees a floor point: in front, on the image, on an unmasked pixel.
    viewers_.push_back({centre.value_or(Eigen::Vector3d::Zero()), [model, mask, z](const Eigen::Vector2d& p) {
                          const auto px = model->Project(Eigen::Vector3d(p.x(), p.y(), z));
                          if (!px || !model->InImage(*px)) return false;
                          if (mask == nullptr || mask->empty()) return true;
                          const int x = std::clamp(static_cast<int>(std::lround(px->x())), 0, mask->width() - 1);
                          const int y = std::clamp(static_cast<int>(std::lround(px->y())), 0, mask->height() - 1);
                          return (*mask)(x, y) != 0;
                        }});
  }
}

void ObjectDetector::PrepareSupport(const FloorGrid& grid) {
  if (support_grid_ && *support_grid_ == grid) return;
  support_grid_ = grid;
  // Filled on first use, in tiles of kTileCells cells: a frame needs the cells under and
  // beside its detections only.
  support_tiles_ = static_cast<size_t>((grid.num_cells() + kTileCells - 1) / kTileCells);
  support_tile_start_.assign(settings_.support_heights_m.size() * support_tiles_, -1);
  support_pixel_.clear();
  // Room for every tile up front: the vector then never moves as tiles are added (a move
  // copied all the tiles so far into fresh pages, on WILDTRACK most of the page faults of a
  // short run). Only the pages of the tiles used are ever touched.
  support_pixel_.reserve(support_tile_start_.size() * static_cast<size_t>(kTileCells) * (cameras_.size() + 1));
}

int32_t* ObjectDetector::SupportPixels(size_t h, int64_t cell) {
  int64_t& start = support_tile_start_[h * support_tiles_ + static_cast<size_t>(cell / kTileCells)];
  const size_t entries = cameras_.size() + 1;
  if (start < 0) {
    start = static_cast<int64_t>(support_pixel_.size());
    support_pixel_.resize(support_pixel_.size() + static_cast<size_t>(kTileCells) * entries, kNotProjected);
  }
  return support_pixel_.data() + static_cast<size_t>(start) + static_cast<size_t>(cell % kTileCells) * entries;
}

int32_t ObjectDetector::SupportPixel(size_t h, size_t n, int64_t cell, int32_t* pixels) {
  int32_t& pixel = pixels[n];
  if (pixel != kNotProjected) return pixel;
  pixel = -1;
  const CameraModel& model = *cameras_[n].camera;
  const Eigen::Vector2d c = support_grid_->CellCenter(cell);
  const auto px = model.Project(Eigen::Vector3d(c.x(), c.y(), plane_height_m_ + settings_.support_heights_m[h]));
  if (!px || !model.InImage(*px)) return pixel;
  const int x = static_cast<int>(std::lround(px->x()));
  const int y = static_cast<int>(std::lround(px->y()));
  const ImageSize size = model.image_size();
  if (x < 0 || y < 0 || x >= size.width || y >= size.height) return pixel;
  // A masked pixel (outside the floor, or a static object in front) tells nothing.
  const Image<uint8_t>* mask = cameras_[n].mask;
  if (mask != nullptr && !mask->empty() && (*mask)(x, y) == 0) return pixel;
  pixel = PackPixel(x, y);
  return pixel;
}

int ObjectDetector::SupportAt(size_t h, int64_t cell, const ChangeLookup& changed,
                              std::span<const ChangeBuffer> buffers) {
  int32_t* pixels = SupportPixels(h, cell);
  // The cell's state is asked again by neighbouring samples: kept for this frame.
  int32_t& memo = pixels[cameras_.size()];
  if (memo >= 0 && (memo >> 2) == support_generation_) return (memo & 3) - 1;
  const int state = SupportState(h, cell, pixels, changed, buffers);
  memo = support_generation_ * 4 + (state + 1);
  return state;
}

int ObjectDetector::SupportState(size_t h, int64_t cell, int32_t* pixels, const ChangeLookup& changed,
                                 std::span<const ChangeBuffer> buffers) {
  int seeing = 0;
  for (size_t n : active_cameras_) {
    const int32_t p = SupportPixel(h, n, cell, pixels);
    if (p < 0) continue;
    ++seeing;
    const size_t x = PixelX(p), y = PixelY(p);  // no division, no virtual call
    if (!buffers.empty() && buffers[n].unchanged_bits != nullptr) {
      const ChangeBuffer& b = buffers[n];
      if ((b.unchanged_bits[y * b.row_words + x / 64] >> (x % 64)) & 1u) return 0;
    } else if (!buffers.empty()) {
      const ChangeBuffer& b = buffers[n];
      if (b.pixels[y * b.stride + x] == 0) return 0;
    } else if (!changed(static_cast<int>(n), static_cast<int>(x), static_cast<int>(y))) {
      return 0;
    }
  }
  return seeing > 0 ? 1 : -1;
}

void ObjectDetector::RemoveUnsupported(const OccupancyMap& map, const ChangeLookup& changed,
                                       std::span<const ChangeBuffer> buffers, const std::vector<int>& kept_index,
                                       const std::vector<Blob>& kept_groups, DetectedObjects& out) {
  const FloorGrid& grid = map.grid();
  PrepareSupport(grid);
  std::vector<Detection>& blobs = out.detections;
  const std::vector<int32_t>& labels = groups_.labels();
  // Each detection's footprint cells: the occupied cells of its group (within the group's
  // box), each given to the group's nearest detection.
  std::vector<std::vector<int>> detections_of(kept_index.size());
  for (size_t d = 0; d < blobs.size(); ++d) detections_of[static_cast<size_t>(blobs[d].group)].push_back(static_cast<int>(d));
  std::vector<std::vector<std::pair<int, int>>>& footprint = footprint_;
  if (footprint.size() < blobs.size()) footprint.resize(blobs.size());
  for (size_t d = 0; d < blobs.size(); ++d) footprint[d].clear();
  for (size_t g = 0; g < kept_index.size(); ++g) {
    const Blob& box = kept_groups[g];
    const std::vector<int>& candidates = detections_of[g];
    if (candidates.empty()) continue;  // no cell would be given to anyone
    for (int j = box.min_j; j <= box.max_j; ++j) {
      // The row's occupied cells in order, free spans skipped a word at a time.
      const CellState* row = map.states().data() + int64_t{j} * grid.cells_x;
      for (int i = static_cast<int>(NextOccupied(row, box.min_i, box.max_i + 1)); i <= box.max_i;
           i = static_cast<int>(NextOccupied(row, i + 1, box.max_i + 1))) {
        const int64_t cell = int64_t{j} * grid.cells_x + i;
        if (labels[static_cast<size_t>(cell)] != kept_index[g]) continue;
        if (candidates.size() == 1) {  // the nearest of one (a finite distance beats the initial infinity)
          footprint[static_cast<size_t>(candidates[0])].push_back({i, j});
          continue;
        }
        // FloorGrid::CellCenter's expression, from (i, j) without a division.
        const double cx = grid.origin_x_m + (static_cast<double>(i) + 0.5) * grid.cell_size_m;
        const double cy = grid.origin_y_m + (static_cast<double>(j) + 0.5) * grid.cell_size_m;
        int best = -1;
        double best_d2 = std::numeric_limits<double>::infinity();
        for (int d : candidates) {
          const double dx = blobs[d].x_m - cx, dy = blobs[d].y_m - cy;
          const double d2 = dx * dx + dy * dy;
          if (d2 < best_d2) {
            best_d2 = d2;
            best = d;
          }
        }
        if (best >= 0) footprint[static_cast<size_t>(best)].push_back({i, j});
      }
    }
  }
  const int reach = std::max(0, static_cast<int>(std::lround(settings_.support_slack_m / grid.cell_size_m)));
  // The plane-h state of footprint cell (i, j): occupied when the plane shows the object over
  // it or beside it (within the slack: legs lean, a foot is ahead of the knee); free when some
  // camera sees that neighbourhood free; unknown (-1) when no camera sees it.
  auto state_near = [&](size_t h, int i, int j) {
    int state = -1;
    for (int dj = -reach; dj <= reach && state < 1; dj += std::max(1, reach)) {
      for (int di = -reach; di <= reach && state < 1; di += std::max(1, reach)) {
        const int ii = i + di, jj = j + dj;
        if (ii < 0 || jj < 0 || ii >= grid.cells_x || jj >= grid.cells_y) continue;
        state = std::max(state, SupportAt(h, int64_t{jj} * grid.cells_x + ii, changed, buffers));
      }
    }
    return state;
  };
  // A detection is dropped when some plane saw at least half of its footprint and no such
  // plane shows the object over min_support of what it saw; with no plane seeing it, nothing
  // speaks against it. Planes are tried in order and the first that supports it ends the test;
  // at most kSupportSamples footprint cells, evenly spread, are tested.
  constexpr size_t kSupportSamples = 64;
  std::vector<Detection> kept;
  for (size_t d = 0; d < blobs.size(); ++d) {
    const std::vector<std::pair<int, int>>& cells = footprint[d];
    const size_t stride = std::max<size_t>(1, (cells.size() + kSupportSamples - 1) / kSupportSamples);
    size_t samples = 0;
    for (size_t k = 0; k < cells.size(); k += stride) ++samples;
    bool evidence = false, support = false;
    for (size_t h = 0; h < settings_.support_heights_m.size() && !support; ++h) {
      int seen = 0, supported = 0;
      for (size_t k = 0; k < cells.size(); k += stride) {
        const int state = state_near(h, cells[k].first, cells[k].second);
        seen += state >= 0;
        supported += state == 1;
      }
      if (seen == 0 || 2 * static_cast<size_t>(seen) < samples) continue;
      evidence = true;
      support = supported >= settings_.min_support * seen;
    }
    if (evidence && !support) continue;
    kept.push_back(std::move(blobs[d]));
  }
  blobs = std::move(kept);
}

void ObjectDetector::Detect(const OccupancyMap& map, const std::vector<bool>& active, const ChangeLookup& changed,
                            DetectedObjects& out, std::span<const ChangeBuffer> buffers) {
  OCCMAP_CHECK(buffers.empty() || buffers.size() == cameras_.size(), "ObjectDetector: one change buffer per camera");
  out.grid = map.grid();
  out.guide_radius_m = split_options_.person_radius_m();
  GrowOccupied(map, settings_.group_radius_m, out.grown);
  const std::vector<Blob>& groups = groups_.Find(out.grown);
  FootprintBlobs(map, groups_, footprints_, &footprint_spreads_);
  const std::vector<Blob>& footprints = footprints_;
  std::vector<Blob> kept_groups, kept_footprints;
  std::vector<int> kept_index;  // the group's index in `groups` (its label)
  for (size_t k = 0; k < footprints.size(); ++k) {
    if (footprints[k].cells == 0 || footprints[k].area_m2 < settings_.min_area_m2) continue;
    kept_groups.push_back(groups[k]);
    kept_footprints.push_back(footprints[k]);
    kept_index.push_back(static_cast<int>(k));
  }
  // A detection of kept group g with the group's whole footprint.
  auto whole = [&](size_t g, int parts) {
    const Blob& f = kept_footprints[g];
    Detection d;
    d.x_m = f.x_m;
    d.y_m = f.y_m;
    d.area_m2 = f.area_m2;
    d.cells = f.cells;
    d.spread_m2 = footprint_spreads_[static_cast<size_t>(kept_index[g])];
    d.group = static_cast<int>(g);
    d.parts = parts;
    return d;
  };
  std::vector<Detection>& detections = out.detections;
  detections.clear();
  if (settings_.split) {
    // Each group split once (SplitBlob); the tracker gets the splits of the groups kept.
    splits_.clear();
    for (size_t g = 0; g < kept_groups.size(); ++g) {
      splits_.push_back(SplitBlob(kept_groups[g], out.grown, groups_.labels(), kept_index[g], split_options_,
                                  split_scratch_));
    }
    for (const Detection& d : DetectionsFromSplits(kept_groups, splits_, out.grown, split_options_)) {
      if (d.parts == 1) {  // one part: the group's footprint
        detections.push_back(whole(static_cast<size_t>(d.group), 1));
        continue;
      }
      // A part of the grown group: where the split put it, its share of the footprint's area.
      Detection part = d;
      part.area_m2 = d.area_m2 * kept_footprints[static_cast<size_t>(d.group)].area_m2 /
                     kept_groups[static_cast<size_t>(d.group)].area_m2;
      detections.push_back(part);
    }
  } else {
    for (size_t g = 0; g < kept_groups.size(); ++g) detections.push_back(whole(g, 1));
  }
  if (!settings_.support_heights_m.empty() && (changed || !buffers.empty()) && !detections.empty()) {
    // A new generation of the memos of SupportAt (all cleared before the counter overflows).
    if (++support_generation_ >= (1 << 28)) {
      support_generation_ = 1;
      for (size_t k = cameras_.size(); k < support_pixel_.size(); k += cameras_.size() + 1) {
        support_pixel_[k] = kNotProjected;
      }
    }
    active_cameras_.clear();
    for (size_t n = 0; n < cameras_.size() && n < active.size(); ++n) {
      if (active[n]) active_cameras_.push_back(n);
    }
    RemoveUnsupported(map, changed, buffers, kept_index, kept_groups, out);
  }
  if (settings_.remove_ghosts && detections.size() > 1) {
    // The active cameras' viewers, rebuilt only when the active set changes (copying the
    // std::functions would allocate every frame).
    if (active != active_viewers_for_) {
      active_viewers_for_ = active;
      active_viewers_.clear();
      for (size_t n = 0; n < viewers_.size(); ++n) {
        if (n < active.size() && active[n] && has_centre_[n]) active_viewers_.push_back(viewers_[n]);
      }
    }
    std::vector<Eigen::Vector2d> points;
    for (const Detection& d : detections) points.emplace_back(d.x_m, d.y_m);
    const std::vector<bool> ghost = FindGhosts(points, active_viewers_, ghost_options_);
    size_t kept = 0;
    for (size_t k = 0; k < detections.size(); ++k) {
      if (!ghost[k]) detections[kept++] = std::move(detections[k]);
    }
    detections.resize(kept);
  }
  // The groups that still hold a detection, numbered anew, for the tracker.
  std::vector<int> group_number(kept_groups.size(), -1);
  for (const Detection& d : detections) group_number[static_cast<size_t>(d.group)] = 0;
  out.groups.clear();
  for (size_t g = 0; g < kept_groups.size(); ++g) {
    if (group_number[g] < 0) continue;
    group_number[g] = static_cast<int>(out.groups.size());
    DetectionGroup group{kept_groups[g], kept_footprints[g], {}};
    if (settings_.split) group.split = std::move(splits_[g]);
    out.groups.push_back(std::move(group));
  }
  for (Detection& d : detections) d.group = group_number[static_cast<size_t>(d.group)];
}

}  // namespace occmap
