#include "occmap/pipeline/background_maintenance.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "occmap/detect/background_model.h"
#include "occmap/util/status.h"

namespace occmap {
namespace {

constexpr int kRingPoints = 12;  // points per circle of the projected box
constexpr int kConsensusBlock = 4;  // cells per side of a consensus block
constexpr int kVoteWindowPx = 2;

bool ChangedNear(ImageView<const uint8_t> changes, int cx, int cy) {
  for (int y = std::max(0, cy - kVoteWindowPx); y <= std::min(changes.height() - 1, cy + kVoteWindowPx); ++y) {
    const uint8_t* row = changes.row(y);
    for (int x = std::max(0, cx - kVoteWindowPx); x <= std::min(changes.width() - 1, cx + kVoteWindowPx); ++x) {
      if (row[x] != 0) return true;
    }
  }
  return false;
}

bool Inside(const Eigen::Vector2d& px, ImageSize size) {
  return px.x() >= -0.5 && px.y() >= -0.5 && px.x() < size.width - 0.5 && px.y() < size.height - 0.5;
}

}  // namespace

ConsensusResult ResolveLearnedBackgrounds(const GroundLut& lut, const std::vector<const CameraModel*>& cameras,
                                          double plane_height_m, const std::vector<BackgroundModel*>& models,
                                          int threshold) {
  OCCMAP_CHECK(static_cast<int>(models.size()) == lut.num_cameras(), "consensus: one model (or null) per camera");
  OCCMAP_CHECK(cameras.empty() || cameras.size() == models.size(), "consensus: no cameras or one per model");
  const size_t cams = models.size();
  // Blocks of kConsensusBlock x kConsensusBlock cells: a far cell is hit by few pixels' rays,
  // a block by enough cameras. With the cameras, the blocks go on beyond the grid by its own size
  // on every side: a low camera sees most of a standing person against floor far behind them.
  const FloorGrid& g = lut.grid();
  const double block_m = kConsensusBlock * g.cell_size_m;
  const int gbx = (g.cells_x + kConsensusBlock - 1) / kConsensusBlock;
  const int gby = (g.cells_y + kConsensusBlock - 1) / kConsensusBlock;
  const int mx = cameras.empty() ? 0 : gbx, my = cameras.empty() ? 0 : gby;  // margin, blocks
  const int bx = gbx + 2 * mx, by = gby + 2 * my;
  const size_t cells = static_cast<size_t>(bx) * static_cast<size_t>(by);
  const uint32_t sentinel = lut.sentinel();
  // Per camera and pixel: its block, or -1.
  std::vector<std::vector<int32_t>> pixel_block(cams);
  for (size_t n = 0; n < cams; ++n) {
    const BackgroundModel* m = models[n];
    if (m == nullptr || m->empty()) continue;
    const std::span<const uint32_t> l1 = lut.l1(static_cast<int>(n));
    const int w = m->width();
    pixel_block[n].assign(l1.size(), -1);
    for (size_t p = 0; p < l1.size(); ++p) {
      int i = -1, j = -1;
      if (l1[p] != sentinel) {
        i = static_cast<int>(l1[p] % static_cast<uint32_t>(g.cells_x)) / kConsensusBlock + mx;
        j = static_cast<int>(l1[p] / static_cast<uint32_t>(g.cells_x)) / kConsensusBlock + my;
      } else if (!cameras.empty()) {
        const auto q = cameras[n]->PixelToPlane(Eigen::Vector2d(static_cast<double>(p % w), static_cast<double>(p / w)),
                                                plane_height_m);
        if (!q) continue;
        i = static_cast<int>(std::floor((q->x() - g.origin_x_m) / block_m)) + mx;
        j = static_cast<int>(std::floor((q->y() - g.origin_y_m) / block_m)) + my;
      }
      if (i < 0 || j < 0 || i >= bx || j >= by) continue;
      pixel_block[n][p] = j * bx + i;
    }
  }
  // Mean background luma per (block, camera).
  std::vector<float> sum(cells * cams, 0.0f);
  std::vector<uint16_t> count(cells * cams, 0);
  for (size_t n = 0; n < cams; ++n) {
    const BackgroundModel* m = models[n];
    if (m == nullptr || m->empty()) continue;
    const int w = m->width();
    for (size_t p = 0; p < pixel_block[n].size(); ++p) {
      if (pixel_block[n][p] < 0) continue;
      const int x = static_cast<int>(p % w), y = static_cast<int>(p / w);
      const size_t k = static_cast<size_t>(pixel_block[n][p]) * cams + n;
      if (count[k] == 65535) continue;
      sum[k] += static_cast<float>(m->BackgroundLevel(x, y));
      ++count[k];
    }
  }
  auto mean = [&](const std::vector<float>& s, size_t cell, size_t n) {
    const size_t k = cell * cams + n;
    return count[k] ? s[k] / count[k] : -1.0f;
  };
  // Each camera's exposure relative to the camera that sees the most cells.
  std::vector<int64_t> seen(cams, 0);
  for (size_t c = 0; c < cells; ++c) {
    for (size_t n = 0; n < cams; ++n) seen[n] += count[c * cams + n] > 0;
  }
  const size_t ref = static_cast<size_t>(std::max_element(seen.begin(), seen.end()) - seen.begin());
  std::vector<float> gain(cams, 1.0f);
  for (size_t n = 0; n < cams; ++n) {
    std::vector<float> ratios;
    for (size_t c = 0; c < cells; ++c) {
      const float a = mean(sum, c, n), b = mean(sum, c, ref);
      if (a > 8 && b > 8) ratios.push_back(a / b);
    }
    if (ratios.size() < 100) continue;
    std::nth_element(ratios.begin(), ratios.begin() + static_cast<ptrdiff_t>(ratios.size() / 2), ratios.end());
    gain[n] = ratios[ratios.size() / 2];
  }
  // The consensus per cell, in the reference camera's exposure (-1: fewer than three views).
  std::vector<float> consensus(cells, -1.0f);
  std::vector<float> values;
  auto median = [&](std::vector<float>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  for (size_t c = 0; c < cells; ++c) {
    values.clear();
    for (size_t n = 0; n < cams; ++n) {
      if (count[c * cams + n]) values.push_back(mean(sum, c, n) / gain[n]);
    }
    if (values.size() < 3) continue;
    consensus[c] = median(values);
  }
  // A pixel far from its cell's consensus takes its alternative when that is close. (Taking
  // the consensus itself where there is no alternative was measured worse on the plaza: the
  // cell's mean has none of the pixel's texture.)
  ConsensusResult result;
  for (size_t n = 0; n < cams; ++n) {
    BackgroundModel* m = models[n];
    if (m == nullptr || m->empty()) continue;
    const int w = m->width();
    for (size_t p = 0; p < pixel_block[n].size(); ++p) {
      const int32_t b = pixel_block[n][p];
      if (b < 0 || consensus[static_cast<size_t>(b)] < 0) continue;
      const int x = static_cast<int>(p % w), y = static_cast<int>(p / w);
      ++result.pixels_checked;
      const float expected = consensus[static_cast<size_t>(b)] * gain[n];
      const float d_bg = std::abs(static_cast<float>(m->BackgroundLevel(x, y)) - expected);
      const int alt = m->AlternativeLevel(x, y);
      if (alt < 0) continue;
      // The alternative is much closer to what the other cameras see there (the block's mean:
      // no texture, hence a comparison, not a tolerance).
      const float d_alt = std::abs(static_cast<float>(alt) - expected);
      // Decided either way, the pixel keeps no alternative: the other cluster is someone who
      // stood there, and swapping it in later (BackgroundModel::Update) would hide them when
      // they stand there again.
      if (d_alt + static_cast<float>(threshold) < d_bg) {
        m->SwapWithAlternative(x, y);
        m->DropAlternative(x, y);
        ++result.pixels_swapped;
        ++result.pixels_settled;
      } else if (d_bg + static_cast<float>(threshold) < d_alt) {
        m->DropAlternative(x, y);
        ++result.pixels_settled;
      }
    }
  }
  return result;
}

BackgroundProtection::BackgroundProtection(std::vector<const CameraModel*> cameras, double plane_height_m,
                                           ProtectionOptions options)
    : cameras_(std::move(cameras)), plane_height_m_(plane_height_m), options_(options) {
  for (const CameraModel* c : cameras_) {
    const ImageSize s = c->image_size();
    images_.emplace_back(s.width, s.height, BackgroundModel::kFree);
  }
}

void BackgroundProtection::Protect(double cx, double cy, double radius, uint8_t value) {
  // The box's projection: its bounding rectangle in each camera.
  for (size_t n = 0; n < cameras_.size(); ++n) {
    const ImageSize size = cameras_[n]->image_size();
    double u0 = 1e18, v0 = 1e18, u1 = -1e18, v1 = -1e18;
    bool all = true;
    for (int k = 0; k < kRingPoints && all; ++k) {
      const double a = 2 * std::numbers::pi * k / kRingPoints;
      for (double z : {0.0, options_.height_m}) {
        const auto px = cameras_[n]->Project({cx + radius * std::cos(a), cy + radius * std::sin(a), plane_height_m_ + z});
        if (!px) {
          all = false;  // the box reaches behind the camera: protect its whole image
          break;
        }
        u0 = std::min(u0, px->x());
        u1 = std::max(u1, px->x());
        v0 = std::min(v0, px->y());
        v1 = std::max(v1, px->y());
      }
    }
    if (!all) {
      u0 = v0 = 0;
      u1 = size.width;
      v1 = size.height;
    }
    const int c0 = std::clamp(static_cast<int>(std::floor(u0)), 0, size.width);
    const int c1 = std::clamp(static_cast<int>(std::ceil(u1)) + 1, 0, size.width);
    const int r0 = std::clamp(static_cast<int>(std::floor(v0)), 0, size.height);
    const int r1 = std::clamp(static_cast<int>(std::ceil(v1)) + 1, 0, size.height);
    Image<uint8_t>& im = images_[n];
    for (int y = r0; y < r1; ++y) {
      uint8_t* row = im.row(y);
      for (int x = c0; x < c1; ++x) row[x] = std::max(row[x], value);
    }
  }
}

void BackgroundProtection::AddPeople(const std::vector<Eigen::Vector2d>& positions_m, double radius_m) {
  for (const Eigen::Vector2d& p : positions_m) {
    ++persons_;
    Protect(p.x(), p.y(), radius_m + options_.margin_m, BackgroundModel::kPerson);
  }
}

void BackgroundProtection::Compute(const OccupancyMap& map, const std::vector<ImageView<const uint8_t>>& changes) {
  OCCMAP_CHECK(changes.size() == cameras_.size(), "protection: one change mask per camera");
  for (Image<uint8_t>& im : images_) {
    for (int y = 0; y < im.height(); ++y) std::fill(im.row(y), im.row(y) + im.width(), BackgroundModel::kFree);
  }
  objects_ = persons_ = 0;
  const FloorGrid& g = map.grid();
  const std::vector<Blob>& blobs = finder_.Find(map, {.min_area_m2 = options_.min_area_m2});
  for (const Blob& b : blobs) {
    ++objects_;
    const double x0 = g.origin_x_m + b.min_i * g.cell_size_m - options_.margin_m;
    const double x1 = g.origin_x_m + (b.max_i + 1) * g.cell_size_m + options_.margin_m;
    const double y0 = g.origin_y_m + b.min_j * g.cell_size_m - options_.margin_m;
    const double y1 = g.origin_y_m + (b.max_j + 1) * g.cell_size_m + options_.margin_m;
    const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
    const double radius = 0.5 * std::hypot(x1 - x0, y1 - y0);
    // Person: change at person height above the centroid, in most cameras that see it.
    int seen = 0, changed = 0;
    for (size_t n = 0; n < cameras_.size(); ++n) {
      if (changes[n].empty()) continue;
      const ImageSize size = cameras_[n]->image_size();
      const auto foot = cameras_[n]->Project({b.x_m, b.y_m, plane_height_m_});
      const auto top = cameras_[n]->Project({b.x_m, b.y_m, plane_height_m_ + options_.person_height_m});
      if (!foot || !top || !Inside(*foot, size) || !Inside(*top, size)) continue;
      ++seen;
      changed += ChangedNear(changes[n], static_cast<int>(std::lround(top->x())), static_cast<int>(std::lround(top->y())));
    }
    const bool person = seen > 0 && 2 * changed >= seen + (seen > 1 ? 1 : 0);
    persons_ += person;
    const uint8_t value = person ? BackgroundModel::kPerson : BackgroundModel::kObject;
    Protect(cx, cy, radius, value);
  }
}

}  // namespace occmap
