#include "occmap/pipeline/background_maintenance.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <opencv2/imgproc.hpp>

#include "occmap/detect/background_model.h"
#include "occmap/util/status.h"

namespace occmap {
namespace {

constexpr int kRingPoints = 12;  // points per circle of the projected box
constexpr int kConsensusBlock = 4;  // cells per side of a consensus block
constexpr int kVoteWindowPx = 2;
constexpr double kStoodOnShare = 0.25;  // of a block's pixels in a camera with two looks

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
                                          int threshold, int chroma_threshold, bool drop_kept,
                                          const std::vector<bool>& keep) {
  OCCMAP_CHECK(static_cast<int>(models.size()) == lut.num_cameras(), "consensus: one model (or null) per camera");
  OCCMAP_CHECK(keep.empty() || keep.size() == models.size(), "consensus: no keep flags or one per model");
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
  // Chroma, where every model has it: a look whose Cb or Cr is a change (chroma_threshold) away
  // from what the other cameras see is not the floor, however close its luma.
  const bool use_chroma = chroma_threshold > 0 && std::all_of(models.begin(), models.end(), [](const BackgroundModel* m) {
                            return m == nullptr || m->empty() || m->has_chroma();
                          });
  // Mean background luma (and chroma) per (block, camera), and the pixels with two looks far apart.
  std::vector<float> sum(cells * cams, 0.0f);
  std::vector<float> sum_u(use_chroma ? cells * cams : 0, 0.0f), sum_v(sum_u.size(), 0.0f);
  std::vector<uint16_t> count(cells * cams, 0), two_looks(cells * cams, 0);
  for (size_t n = 0; n < cams; ++n) {
    const BackgroundModel* m = models[n];
    if (m == nullptr || m->empty()) continue;
    const int w = m->width();
    for (size_t p = 0; p < pixel_block[n].size(); ++p) {
      if (pixel_block[n][p] < 0) continue;
      const int x = static_cast<int>(p % w), y = static_cast<int>(p / w);
      const size_t k = static_cast<size_t>(pixel_block[n][p]) * cams + n;
      if (count[k] == 65535) continue;
      const int level = m->BackgroundLevel(x, y), alt = m->AlternativeLevel(x, y);
      sum[k] += static_cast<float>(level);
      if (use_chroma) {
        const std::array<int, 2> uv = m->BackgroundChroma(x, y);
        sum_u[k] += static_cast<float>(uv[0]);
        sum_v[k] += static_cast<float>(uv[1]);
      }
      ++count[k];
      if (alt >= 0 && std::abs(alt - level) > threshold) ++two_looks[k];
    }
  }
  auto mean = [&](const std::vector<float>& s, size_t cell, size_t n) {
    const size_t k = cell * cams + n;
    return count[k] ? s[k] / count[k] : -1.0f;
  };
  // Before settling: the blocks something stood on for part of the window, where most of the
  // cameras that see the block have two looks over at least kStoodOnShare of its pixels. Every
  // camera saw the same thing there, so the consensus cannot tell which look is the floor.
  std::vector<uint8_t> stood_on(cells, 0);
  if (!drop_kept) {
    for (size_t c = 0; c < cells; ++c) {
      int seeing = 0, both = 0;
      for (size_t n = 0; n < cams; ++n) {
        const size_t k = c * cams + n;
        if (count[k] == 0) continue;
        ++seeing;
        both += two_looks[k] >= kStoodOnShare * count[k];
      }
      stood_on[c] = seeing >= 2 && 2 * both > seeing;
    }
  }
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
  auto median = [&](std::vector<float>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  // Each camera's white balance: its chroma's offset from the reference camera's.
  std::vector<float> offset_u(cams, 0.0f), offset_v(cams, 0.0f);
  std::vector<float> values, values_v;
  for (size_t n = 0; use_chroma && n < cams; ++n) {
    values.clear();
    values_v.clear();
    for (size_t c = 0; c < cells; ++c) {
      if (count[c * cams + n] == 0 || count[c * cams + ref] == 0) continue;
      values.push_back(mean(sum_u, c, n) - mean(sum_u, c, ref));
      values_v.push_back(mean(sum_v, c, n) - mean(sum_v, c, ref));
    }
    if (values.size() < 100) continue;
    offset_u[n] = median(values);
    offset_v[n] = median(values_v);
  }
  // The consensus per cell, in the reference camera's exposure (-1: fewer than three views).
  std::vector<float> consensus(cells, -1.0f), consensus_u(use_chroma ? cells : 0), consensus_v(consensus_u.size());
  for (size_t c = 0; c < cells; ++c) {
    values.clear();
    values_v.clear();
    for (size_t n = 0; n < cams; ++n) {
      if (count[c * cams + n]) values.push_back(mean(sum, c, n) / gain[n]);
    }
    if (values.size() < 3) continue;
    consensus[c] = median(values);
    if (!use_chroma) continue;
    values.clear();
    for (size_t n = 0; n < cams; ++n) {
      if (count[c * cams + n] == 0) continue;
      values.push_back(mean(sum_u, c, n) - offset_u[n]);
      values_v.push_back(mean(sum_v, c, n) - offset_v[n]);
    }
    consensus_u[c] = median(values);
    consensus_v[c] = median(values_v);
  }
  // A pixel far from its cell's consensus takes its alternative when that is close. (Taking
  // the consensus itself where there is no alternative was measured worse on the plaza: the
  // cell's mean has none of the pixel's texture.)
  ConsensusResult result;
  for (size_t n = 0; n < cams; ++n) {
    BackgroundModel* m = models[n];
    if (m == nullptr || m->empty() || (!keep.empty() && keep[n])) continue;
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
      // The background is kept for good only when its chroma agrees too: a person whose luma
      // matches the floor's by chance (or a pixel of a kiosk whose ray meets the floor behind
      // it) keeps the alternative, which the settling pass swaps in when they leave. Swaps stay
      // decided on luma: guarded too, they lost a person who stood through half the window.
      auto chroma_far = [&](std::array<int, 2> uv) {
        if (!use_chroma) return false;
        const size_t bb = static_cast<size_t>(b);
        return std::abs(static_cast<float>(uv[0]) - consensus_u[bb] - offset_u[n]) > static_cast<float>(chroma_threshold) ||
               std::abs(static_cast<float>(uv[1]) - consensus_v[bb] - offset_v[n]) > static_cast<float>(chroma_threshold);
      };
      // Decided either way, the pixel keeps no alternative: the other cluster is someone who
      // stood there, and swapping it in later (BackgroundModel::Update) would hide them when
      // they stand there again.
      if (d_alt + static_cast<float>(threshold) < d_bg) {
        m->SwapWithAlternative(x, y);
        m->DropAlternative(x, y);
        ++result.pixels_swapped;
        ++result.pixels_settled;
      } else if ((drop_kept || !stood_on[static_cast<size_t>(b)]) && d_bg + static_cast<float>(threshold) < d_alt &&
                 !chroma_far(m->BackgroundChroma(x, y))) {
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

void BackgroundProtection::Clear() {
  for (Image<uint8_t>& im : images_) {
    for (int y = 0; y < im.height(); ++y) std::fill(im.row(y), im.row(y) + im.width(), BackgroundModel::kFree);
  }
  objects_ = persons_ = 0;
  person_positions_.clear();
  boxes_.clear();
}

void BackgroundProtection::Draw(const std::vector<ProtectedBox>& boxes, const std::vector<Eigen::Vector2d>& persons_m) {
  Clear();
  for (const ProtectedBox& b : boxes) Protect(b.x_m, b.y_m, b.radius_m, b.value);
  objects_ = static_cast<int>(boxes.size());  // the map's objects and the people added alike
  persons_ = static_cast<int>(persons_m.size());
  person_positions_ = persons_m;
}

void BackgroundProtection::ProtectChanges(const std::vector<ImageView<const uint8_t>>& changes) {
  OCCMAP_CHECK(changes.size() == cameras_.size(), "protection: one change mask per camera");
  Clear();
  for (size_t n = 0; n < cameras_.size(); ++n) {
    if (changes[n].empty()) continue;
    Image<uint8_t>& im = images_[n];
    OCCMAP_CHECK(changes[n].width() == im.width() && changes[n].height() == im.height(), "protection: change mask size");
    for (int y = 0; y < im.height(); ++y) {
      const uint8_t* c = changes[n].row(y);
      uint8_t* o = im.row(y);
      for (int x = 0; x < im.width(); ++x) o[x] = c[x] != 0 ? BackgroundModel::kPerson : BackgroundModel::kFree;
    }
  }
}

void BackgroundProtection::Protect(double cx, double cy, double radius, uint8_t value) {
  boxes_.push_back({cx, cy, radius, value});
  // The box's projection in each camera: the outline of its two rings' points (the whole image
  // when it reaches behind the camera). Not their bounding rectangle: in a low camera the box of
  // someone standing near covers far more than them that way, and holds what lies behind.
  for (size_t n = 0; n < cameras_.size(); ++n) {
    const ImageSize size = cameras_[n]->image_size();
    double u0 = 1e18, v0 = 1e18, u1 = -1e18, v1 = -1e18;
    bool all = true;
    points_.clear();
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
        points_.emplace_back(static_cast<float>(px->x()), static_cast<float>(px->y()));
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
    if (c0 >= c1 || r0 >= r1) continue;
    Image<uint8_t>& im = images_[n];
    if (!all) {
      for (int y = r0; y < r1; ++y) {
        uint8_t* row = im.row(y);
        for (int x = c0; x < c1; ++x) row[x] = std::max(row[x], value);
      }
      continue;
    }
    cv::convexHull(points_, hull_f_);
    hull_.clear();
    for (const cv::Point2f& q : hull_f_) {
      hull_.emplace_back(static_cast<int>(std::lround(q.x)) - c0, static_cast<int>(std::lround(q.y)) - r0);
    }
    outline_.create(size.height, size.width, CV_8UC1);  // reallocated only for another image size
    cv::Mat roi = outline_(cv::Rect(c0, r0, c1 - c0, r1 - r0));
    roi.setTo(cv::Scalar(0));
    cv::fillConvexPoly(roi, hull_, cv::Scalar(1));
    for (int y = r0; y < r1; ++y) {
      uint8_t* row = im.row(y);
      const uint8_t* inside = roi.ptr<uint8_t>(y - r0);
      for (int x = c0; x < c1; ++x) {
        if (inside[x - c0]) row[x] = std::max(row[x], value);
      }
    }
  }
}

void BackgroundProtection::AddPeople(const std::vector<Eigen::Vector2d>& positions_m, double radius_m,
                                     const std::vector<bool>& walked) {
  OCCMAP_CHECK(walked.empty() || walked.size() == positions_m.size(), "protection: one walked flag per person");
  for (size_t k = 0; k < positions_m.size(); ++k) {
    const Eigen::Vector2d& p = positions_m[k];
    ++persons_;
    person_positions_.push_back(p);
    const bool has_walked = !walked.empty() && walked[k];
    Protect(p.x(), p.y(), radius_m + options_.margin_m, has_walked ? BackgroundModel::kWalkedPerson : BackgroundModel::kPerson);
  }
}

void BackgroundProtection::AddMissedPeople(const std::vector<Eigen::Vector2d>& positions_m, double radius_m) {
  for (const Eigen::Vector2d& p : positions_m) Protect(p.x(), p.y(), radius_m + options_.margin_m, BackgroundModel::kObject);
}

const std::vector<bool>& WalkedPeople::Update(const std::vector<Eigen::Vector2d>& positions_m) {
  pairs_.clear();
  for (size_t a = 0; a < people_.size(); ++a) {
    if (people_[a].missed >= options_.forget_frames) continue;  // only remembered where last seen
    for (size_t b = 0; b < positions_m.size(); ++b) {
      const double d = (people_[a].last_m - positions_m[b]).norm();
      if (d <= options_.gate_m) pairs_.push_back({d, {static_cast<int>(a), static_cast<int>(b)}});
    }
  }
  std::sort(pairs_.begin(), pairs_.end());
  person_of_.assign(positions_m.size(), -1);
  matched_.assign(people_.size(), 0);
  for (const auto& [d, ab] : pairs_) {
    const auto [a, b] = ab;
    if (matched_[static_cast<size_t>(a)] || person_of_[static_cast<size_t>(b)] >= 0) continue;
    matched_[static_cast<size_t>(a)] = 1;
    person_of_[static_cast<size_t>(b)] = a;
  }
  // Missed people age; the forgotten leave (matched ones keep their index until then).
  for (size_t a = 0; a < people_.size(); ++a) people_[a].missed = matched_[a] ? 0 : people_[a].missed + 1;
  for (size_t b = 0; b < positions_m.size(); ++b) {
    const int a = person_of_[b];
    if (a < 0) continue;
    Person& p = people_[static_cast<size_t>(a)];
    p.last_m = positions_m[b];
    if ((p.last_m - p.still_at_m).norm() > options_.still_m) {
      p.still_at_m = p.last_m;
      p.still_for = 0;
    } else {
      ++p.still_for;
    }
    p.walked = p.walked || (p.last_m - p.first_m).norm() > options_.walked_m;
  }
  walked_.assign(positions_m.size(), false);
  for (size_t b = 0; b < positions_m.size(); ++b) {
    if (person_of_[b] >= 0) walked_[b] = people_[static_cast<size_t>(person_of_[b])].walked;
  }
  std::erase_if(people_, [&](const Person& p) {
    return p.missed >= std::max(options_.forget_frames, options_.hold_frames);
  });
  missed_m_.clear();
  for (const Person& p : people_) {
    // Only walkers (a ghost never walked) who stood when last seen (one who walked on is not
    // where they were).
    if (p.walked && p.missed > 0 && p.missed < options_.hold_frames && p.still_for >= options_.still_frames) {
      missed_m_.push_back(p.last_m);
    }
  }
  for (size_t b = 0; b < positions_m.size(); ++b) {
    if (person_of_[b] >= 0) continue;
    Person& p = people_.emplace_back();
    p.first_m = p.last_m = p.still_at_m = positions_m[b];
  }
  return walked_;
}

int WalkedPeople::followed() const {
  return static_cast<int>(std::count_if(people_.begin(), people_.end(),
                                        [&](const Person& p) { return p.missed < options_.forget_frames; }));
}

void BackgroundProtection::Compute(const OccupancyMap& map, const std::vector<ImageView<const uint8_t>>& changes) {
  OCCMAP_CHECK(changes.size() == cameras_.size(), "protection: one change mask per camera");
  Clear();
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
    if (person) person_positions_.emplace_back(b.x_m, b.y_m);
    const uint8_t value = person ? BackgroundModel::kPerson : BackgroundModel::kObject;
    Protect(cx, cy, radius, value);
  }
}

namespace {
constexpr uint8_t kAbstain = 255;
constexpr uint8_t kCellUnknown = 0, kCellDark = 1, kCellNotDark = 2, kCellLit = 3;
constexpr int kMaxRatioSpread = 38;  // 0.15: of the ratios x 255 over a cell's pixels
// Shadow check: the cells around a cell (this many on each side) must be lit too. Radius 2 keeps
// fewer shadows as changes (plaza: 9.1 % against 9.4 %) but recovers less (change F1 0.837 / 0.842).
constexpr int kShadowCheckRadiusCells = 1;
}  // namespace

ShadowTeachers::ShadowTeachers(const GroundLut& lut) : lut_(lut) {
  pixels_.assign(lut.total_pixels(), kAbstain);
  ratios_.assign(lut.total_pixels(), 0);
  cell_state_.assign(static_cast<size_t>(lut.grid().num_cells()), kCellUnknown);
  near_person_.assign(static_cast<size_t>(lut.grid().num_cells()), 0);
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const ImageSize s = lut.image_size(n);
    images_.emplace_back(s.width, s.height, uint8_t{0});
  }
}

void ShadowTeachers::Compute(const std::vector<ImageView<const uint8_t>>& classes,
                             const std::vector<ImageView<const uint8_t>>& ratios,
                             const OccupancyMap& map, const std::vector<Eigen::Vector2d>& people_m, double radius_m) {
  const int cameras = lut_.num_cameras();
  OCCMAP_CHECK(static_cast<int>(classes.size()) == cameras && ratios.size() == classes.size(),
               "shadow teachers: one class and ratio image per camera");
  // The cells of people's feet: dark in every view, but not a shadow.
  const FloorGrid& g = lut_.grid();
  for (uint32_t c : near_person_cells_) near_person_[c] = 0;
  near_person_cells_.clear();
  OCCMAP_CHECK(map.grid().num_cells() == g.num_cells(), "shadow teachers: map of another grid");
  auto exclude_disc = [&](int ci, int cj, int r) {
    for (int j = std::max(0, cj - r); j <= std::min(g.cells_y - 1, cj + r); ++j) {
      for (int i = std::max(0, ci - r); i <= std::min(g.cells_x - 1, ci + r); ++i) {
        if ((i - ci) * (i - ci) + (j - cj) * (j - cj) > r * r) continue;
        const uint32_t cell = static_cast<uint32_t>(static_cast<int64_t>(j) * g.cells_x + i);
        if (!near_person_[cell]) {
          near_person_[cell] = 1;
          near_person_cells_.push_back(cell);
        }
      }
    }
  };
  const int r = static_cast<int>(std::ceil(radius_m / g.cell_size_m));
  for (const Eigen::Vector2d& p : people_m) {
    exclude_disc(static_cast<int>(std::floor((p.x() - g.origin_x_m) / g.cell_size_m)),
                 static_cast<int>(std::floor((p.y() - g.origin_y_m) / g.cell_size_m)), r);
  }
  const int object_r = static_cast<int>(std::ceil(kObjectMarginM / g.cell_size_m));
  const std::vector<CellState>& states = map.states();
  for (int j = 0; j < g.cells_y; ++j) {
    for (int i = 0; i < g.cells_x; ++i) {
      if (states[static_cast<size_t>(j) * g.cells_x + i] == CellState::kOccupied) exclude_disc(i, j, object_r);
    }
  }
  for (uint32_t c : touched_) cell_state_[c] = kCellUnknown;
  touched_.clear();
  for (int n = 0; n < cameras; ++n) {
    const ImageSize size = lut_.image_size(n);
    uint8_t* dst = pixels_.data() + lut_.pixel_offset(n);
    if (classes[static_cast<size_t>(n)].empty()) {
      std::fill(dst, dst + static_cast<size_t>(size.width) * size.height, kAbstain);
      continue;
    }
    OCCMAP_CHECK(classes[static_cast<size_t>(n)].width() == size.width && classes[static_cast<size_t>(n)].height() == size.height,
                 "shadow teachers: class image size");
    for (int y = 0; y < size.height; ++y) {
      std::copy_n(classes[static_cast<size_t>(n)].row(y), size.width, dst + static_cast<size_t>(y) * size.width);
      std::copy_n(ratios[static_cast<size_t>(n)].row(y), size.width,
                  ratios_.data() + lut_.pixel_offset(n) + static_cast<size_t>(y) * size.width);
    }
  }
  // A cell is dark when every pixel of the active cameras that views it is changed or shadow;
  // only the cells of dark pixels are asked.
  const uint32_t sentinel = lut_.sentinel();
  auto dark_cell = [&](uint32_t cell) {
    if (cell_state_[cell] == kCellUnknown) {
      bool dark = false, lit = false;
      int lo = 255, hi = 0;
      for (uint32_t q : lut_.l2_pixels_of(cell)) {
        const uint8_t v = pixels_[q];
        if (v == kAbstain) continue;
        if (v == BackgroundModel::kBackground || ratios_[q] == 0) {
          lit = true;
          break;
        }
        dark = true;
        lo = std::min<int>(lo, ratios_[q]);
        hi = std::max<int>(hi, ratios_[q]);
      }
      // A floor darkened by a shadow keeps one ratio from every side (a matte floor); an
      // object's sides, each lit its own way, do not.
      cell_state_[cell] = dark && !lit && hi - lo <= kMaxRatioSpread ? kCellDark : kCellNotDark;
      touched_.push_back(cell);
    }
    return cell_state_[cell] == kCellDark;
  };
  teachers_ = 0;
  for (int n = 0; n < cameras; ++n) {
    Image<uint8_t>& out = images_[static_cast<size_t>(n)];
    const ImageSize size = lut_.image_size(n);
    const ImageView<const uint8_t> cls = classes[static_cast<size_t>(n)];
    if (cls.empty()) {
      for (int y = 0; y < size.height; ++y) std::fill(out.row(y), out.row(y) + size.width, uint8_t{0});
      continue;
    }
    const std::span<const uint32_t> l1 = lut_.l1(n);
    for (int y = 0; y < size.height; ++y) {
      const uint8_t* c = cls.row(y);
      uint8_t* o = out.row(y);
      for (int x = 0; x < size.width; ++x) {
        const uint32_t cell = l1[static_cast<size_t>(y) * size.width + x];
        const bool teach = c[x] != BackgroundModel::kBackground && cell != sentinel && dark_cell(cell) && !near_person_[cell];
        o[x] = teach ? 1 : 0;
        teachers_ += teach;
      }
    }
  }
}

ShadowCheck::ShadowCheck(const GroundLut& lut) : lut_(lut) {
  OCCMAP_CHECK(lut.num_cameras() <= 255, "shadow check: at most 255 cameras");
  pixels_.assign(lut.total_pixels(), kAbstain);
  camera_of_.resize(lut.total_pixels());
  for (int n = 0; n < lut.num_cameras(); ++n) {
    const ImageSize s = lut.image_size(n);
    std::fill_n(camera_of_.begin() + lut.pixel_offset(n), static_cast<size_t>(s.width) * s.height, static_cast<uint8_t>(n));
  }
  cell_state_.assign(static_cast<size_t>(lut.grid().num_cells()), kCellUnknown);
  lit_.assign(static_cast<size_t>(lut.num_cameras()), 0);
  dark_.assign(static_cast<size_t>(lut.num_cameras()), 0);
  shaded_.assign(static_cast<size_t>(lut.num_cameras()), 0);
}

int64_t ShadowCheck::Apply(const std::vector<ImageView<const uint8_t>>& classes,
                           const std::vector<ImageView<uint8_t>>& changes) {
  const int cameras = lut_.num_cameras();
  OCCMAP_CHECK(static_cast<int>(classes.size()) == cameras && changes.size() == classes.size(),
               "shadow check: one class image and change mask per camera");
  for (uint32_t c : touched_) cell_state_[c] = kCellUnknown;
  touched_.clear();
  bool any = false;
  for (int n = 0; n < cameras; ++n) {
    const ImageSize size = lut_.image_size(n);
    const ImageView<const uint8_t> cls = classes[static_cast<size_t>(n)];
    uint8_t* dst = pixels_.data() + lut_.pixel_offset(n);
    if (cls.empty()) {
      std::fill(dst, dst + static_cast<size_t>(size.width) * size.height, kAbstain);
      continue;
    }
    OCCMAP_CHECK(cls.width() == size.width && cls.height() == size.height, "shadow check: class image size");
    OCCMAP_CHECK(changes[static_cast<size_t>(n)].width() == size.width && changes[static_cast<size_t>(n)].height() == size.height,
                 "shadow check: change mask size");
    for (int y = 0; y < size.height; ++y) std::copy_n(cls.row(y), size.width, dst + static_cast<size_t>(y) * size.width);
    any = true;
  }
  if (!any) return 0;
  // A cell is lit when at least half of the other cameras that view it, and two at least, see
  // it unchanged (most of their pixels there kBackground). The asking camera is one of the
  // cameras that see it dark, so "others" is the viewing cameras less one. One camera alone
  // (cells at the edge of the views) turned the lab's shadows by the walls into ghosts.
  auto lit_cell = [&](uint32_t cell) {
    if (cell_state_[cell] == kCellUnknown) {
      for (uint32_t q : lut_.l2_pixels_of(cell)) {
        const uint8_t v = pixels_[q];
        if (v == kAbstain) continue;
        const size_t k = camera_of_[q];
        if (v == BackgroundModel::kBackground) {
          lit_[k] += 1;
        } else {
          dark_[k] += 1;
          shaded_[k] += v == BackgroundModel::kShadow || v == BackgroundModel::kSoftShadow;
        }
      }
      int viewing = 0, lit = 0, shaded = 0;
      for (int n = 0; n < cameras; ++n) {
        const size_t k = static_cast<size_t>(n);
        if (lit_[k] + dark_[k] == 0) continue;
        ++viewing;
        lit += lit_[k] > dark_[k];
        shaded += 2 * shaded_[k] > lit_[k] + dark_[k];
        lit_[k] = dark_[k] = shaded_[k] = 0;
      }
      // Dark (a soft shadow's confirmation): cameras that see it mostly shadowed, other than
      // the one asking (which does), one at least and no fewer than those that see it lit.
      // Changed does not confirm: the floor behind a person is hidden by their legs from the
      // cameras beside the asking one.
      const int others_shaded = shaded - 1;
      cell_state_[cell] = lit >= 2 && 2 * lit >= viewing - 1 ? kCellLit
                          : others_shaded >= 1 && others_shaded >= lit ? kCellDark
                                                                       : kCellNotDark;
      touched_.push_back(cell);
    }
    return cell_state_[cell] == kCellLit;
  };
  auto dark_cell = [&](uint32_t cell) {
    lit_cell(cell);
    return cell_state_[cell] == kCellDark;
  };
  // A far camera's pixel spans several cells and sees a thin shadow (a leg's) unchanged: the
  // cells around must be lit too.
  const FloorGrid& g = lut_.grid();
  const int radius = kShadowCheckRadiusCells;
  auto lit_around = [&](uint32_t cell) {
    const int ci = static_cast<int>(cell % static_cast<uint32_t>(g.cells_x)), cj = static_cast<int>(cell / static_cast<uint32_t>(g.cells_x));
    for (int j = std::max(0, cj - radius); j <= std::min(g.cells_y - 1, cj + radius); ++j) {
      for (int i = std::max(0, ci - radius); i <= std::min(g.cells_x - 1, ci + radius); ++i) {
        if (!lit_cell(static_cast<uint32_t>(j * g.cells_x + i))) return false;
      }
    }
    return true;
  };
  const uint32_t sentinel = lut_.sentinel();
  int64_t turned = 0;
  for (int n = 0; n < cameras; ++n) {
    const ImageView<const uint8_t> cls = classes[static_cast<size_t>(n)];
    if (cls.empty()) continue;
    const ImageSize size = lut_.image_size(n);
    const std::span<const uint32_t> l1 = lut_.l1(n);
    const ImageView<uint8_t> out = changes[static_cast<size_t>(n)];
    for (int y = 0; y < size.height; ++y) {
      const uint8_t* c = cls.row(y);
      uint8_t* o = out.row(y);
      for (int x = 0; x < size.width; ++x) {
        if (c[x] != BackgroundModel::kShadow && c[x] != BackgroundModel::kSoftShadow) continue;
        const uint32_t cell = l1[static_cast<size_t>(y) * size.width + x];
        if (c[x] == BackgroundModel::kSoftShadow) {
          if (cell != sentinel && dark_cell(cell)) continue;  // soft: kept only where confirmed
        } else if (cell == sentinel || !lit_around(cell)) {
          continue;
        }
        o[x] = 1;
        ++turned;
      }
    }
  }
  return turned;
}

}  // namespace occmap
