#include "occmap/fusion/occluder_learning.h"

#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <cinttypes>
#include <cstdio>
#include <sstream>

#include "occmap/util/file_util.h"
#include "occmap/util/hash.h"

namespace occmap {

namespace {

constexpr const char* kMagic = "occmap-learned-occluders";
constexpr int kVersion = 1;
constexpr int kMaxCameras = 64;
constexpr uint16_t kMaxEpisodes = 65535;
// The learned blocks are applied every this many frame sets: a change rebuilds the column
// fusion's plan, and a block needs min_episodes episodes of many frames anyway.
constexpr int64_t kApplyEvery = 10;
constexpr int kBlockPx = 4;
constexpr uint8_t kHiddenEvent = 1, kSeenEvent = 2;
// A view's depth along its camera's line of sight, in the camera's own unit: the inverse of the
// foot's image scale (pixels per metre), which grows with the distance.
float Depth(const ColumnView& v) { return 1.0f / std::max(v.half_width_bottom, 1e-6f); }
// A block hides what stands this much nearer than the nearest person seen hidden there too.
constexpr float kDepthSlack = 0.95f;
// The radius of the image of a person found that explains the changes around it.
constexpr double kCoverRadiusM = 0.3;

}  // namespace

Status OccluderLearningOptions::Validate() const {
  if (!(max_changed >= 0 && max_changed < 1))
    return InvalidInput(fmt::format("max_changed: expected a fraction in [0, 1), found {}", max_changed));
  if (min_others < 1 || min_others > kMaxCameras)
    return InvalidInput(fmt::format("min_others: expected 1 to {}, found {}", kMaxCameras, min_others));
  if (episode_frames < 1 || episode_frames > 100000)
    return InvalidInput(fmt::format("episode_frames: expected 1 to 100000, found {}", episode_frames));
  if (min_episodes < 1 || min_episodes > kMaxEpisodes)
    return InvalidInput(fmt::format("min_episodes: expected 1 to {}, found {}", kMaxEpisodes, min_episodes));
  if (!(max_contrary >= 0 && max_contrary < 1))
    return InvalidInput(fmt::format("max_contrary: expected a fraction in [0, 1), found {}", max_contrary));
  return Status::Ok();
}

Status ParseOccluderLearningOptions(const YamlField& f, OccluderLearningOptions& o) {
  OCCMAP_RETURN_IF_ERROR(
      f.CheckKeys({"learn", "max_changed", "min_others", "episode_frames", "min_episodes", "max_contrary"}));
  OCCMAP_ASSIGN_OR_RETURN(o.learn, f.GetBool("learn", o.learn));
  OCCMAP_ASSIGN_OR_RETURN(o.max_changed, f.GetDouble("max_changed", o.max_changed));
  OCCMAP_ASSIGN_OR_RETURN(int64_t others, f.GetInt("min_others", o.min_others));
  o.min_others = static_cast<int>(std::clamp<int64_t>(others, -1, 1000));
  OCCMAP_ASSIGN_OR_RETURN(int64_t episode, f.GetInt("episode_frames", o.episode_frames));
  o.episode_frames = static_cast<int>(std::clamp<int64_t>(episode, -1, 1000000));
  OCCMAP_ASSIGN_OR_RETURN(int64_t episodes, f.GetInt("min_episodes", o.min_episodes));
  o.min_episodes = static_cast<int>(std::clamp<int64_t>(episodes, -1, 1000000));
  OCCMAP_ASSIGN_OR_RETURN(o.max_contrary, f.GetDouble("max_contrary", o.max_contrary));
  if (Status s = o.Validate(); !s.ok()) return f.Error(s.message());
  return Status::Ok();
}

OccluderLearner::OccluderLearner(ColumnLut& columns, const ColumnFusionOptions& column,
                                 const OccluderLearningOptions& options)
    : columns_(columns),
      column_(column),
      options_(options),
      views_(static_cast<size_t>(columns.num_cameras()) * static_cast<size_t>(columns.candidates().num_cells())) {
  OCCMAP_CHECK(columns.num_cameras() <= kMaxCameras, "OccluderLearner: at most 64 cameras");
}

bool OccluderLearner::Blocks(const View& v) const {
  const double episodes = static_cast<double>(v.hidden) + static_cast<double>(v.seen);
  return v.hidden >= options_.min_episodes && static_cast<double>(v.seen) <= options_.max_contrary * episodes;
}

// Calls fn(block) for every pixel block the band of view (c, k) reads (a block once per row read).
template <typename Fn>
void OccluderLearner::ForBandBlocks(int c, int64_t k, Fn&& fn) const {
  const double h = columns_.options().height_m;
  const ColumnSpans s = MakeColumnSpans(columns_.view(c, k), column_.radius_m, column_.band_low_m / h,
                                        column_.band_high_m / h, columns_.image_size(c));
  const int stride = std::max(1, (s.last_row - s.first_row + 1 + column_.max_rows - 1) / column_.max_rows);
  const int blocks_x = (s.width + kBlockPx - 1) / kBlockPx;
  for (int y = s.first_row; y <= s.last_row; y += stride) {
    int x0, x1;
    if (!s.Span(y, x0, x1)) continue;
    for (int bx = x0 / kBlockPx; bx <= x1 / kBlockPx; ++bx) {
      const int px = std::min(x1, bx * kBlockPx + kBlockPx - 1) - std::max(x0, bx * kBlockPx) + 1;
      fn(static_cast<size_t>((y / kBlockPx) * blocks_x + bx), px);
    }
  }
}

void OccluderLearner::Pool(int32_t frame) {
  const int cams = columns_.num_cameras();
  const int64_t n = columns_.candidates().num_cells();
  if (blocks_.size() != static_cast<size_t>(cams)) {
    blocks_.resize(static_cast<size_t>(cams));
    for (int c = 0; c < cams; ++c) {
      const ImageSize size = columns_.image_size(c);
      blocks_[c].assign(static_cast<size_t>((size.width + kBlockPx - 1) / kBlockPx) *
                            static_cast<size_t>((size.height + kBlockPx - 1) / kBlockPx),
                        Block{});
    }
  }
  for (int c = 0; c < cams; ++c) {
    for (int64_t k = 0; k < n; ++k) {
      const uint8_t event = events_[static_cast<size_t>(c) * static_cast<size_t>(n) + static_cast<size_t>(k)];
      if (event == 0) continue;
      const float depth = Depth(columns_.view(c, k));
      std::vector<Block>& blocks = blocks_[c];
      ForBandBlocks(c, k, [&](size_t b, int) {
        Block& block = blocks[b];
        if (event == kHiddenEvent) {
          block.near_hidden = std::min(block.near_hidden, depth);
          if (int64_t{frame} - block.last_hidden >= options_.episode_frames) {
            block.last_hidden = frame;
            if (block.hidden < kMaxEpisodes) ++block.hidden;
          }
        } else {
          block.far_seen = std::max(block.far_seen, depth);
          if (int64_t{frame} - block.last_seen >= options_.episode_frames) {
            block.last_seen = frame;
            if (block.seen < kMaxEpisodes) ++block.seen;
          }
        }
      });
    }
  }
}

bool OccluderLearner::BlockHides(const Block& b, float depth) const {
  if (b.hidden < options_.min_episodes || depth < kDepthSlack * b.near_hidden) return false;
  // People seen through it as far as this: contrary, unless few.
  if (b.far_seen < kDepthSlack * depth) return true;
  return static_cast<double>(b.seen) <= options_.max_contrary * (static_cast<double>(b.hidden) + b.seen);
}

bool OccluderLearner::Apply() {
  const uint64_t before = columns_.revision();
  const int64_t n = columns_.candidates().num_cells();
  for (int c = 0; c < columns_.num_cameras(); ++c) {
    for (int64_t k = 0; k < n; ++k) {
      bool block = Blocks(views_[static_cast<size_t>(c) * static_cast<size_t>(n) + k]);
      const ColumnView& v = columns_.view(c, k);
      if (!block && v.seen && !(v.blocked && !v.learned) && static_cast<size_t>(c) < blocks_.size()) {
        // Pooled: at least half of the band's pixels in blocks that hide what stands this far.
        const float depth = Depth(v);
        int64_t hidden = 0, pixels = 0;
        ForBandBlocks(c, k, [&](size_t b, int px) {
          pixels += px;
          hidden += BlockHides(blocks_[c][b], depth) ? px : 0;
        });
        block = pixels > 0 && 2 * hidden >= pixels;
      }
      columns_.SetLearnedBlocked(c, k, block);
    }
  }
  return columns_.revision() != before;
}

int64_t OccluderLearner::blocked_views() const {
  int64_t blocked = 0;
  const int64_t n = columns_.candidates().num_cells();
  for (int c = 0; c < columns_.num_cameras(); ++c)
    for (int64_t k = 0; k < n; ++k) blocked += columns_.view(c, k).learned ? 1 : 0;
  return blocked;
}

bool OccluderLearner::Observe(std::span<const ImageView<const uint8_t>> changes,
                              std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                              std::span<const ExplainedPerson> people, int64_t frame_index, Context& ctx) {
  const int cams = columns_.num_cameras();
  const int64_t n = columns_.candidates().num_cells();
  const double h = columns_.options().height_m;
  // What the people found explain: their model's image, widened (a silhouette is wider than the
  // model's core), cleared from a copy of the changes.
  unexplained_.resize(static_cast<size_t>(cams));
  unexplained_counts_.resize(static_cast<size_t>(cams));
  person_at_.assign(static_cast<size_t>(n), 0);
  // Where the explanation puts a person, the candidates next to it too: the explanation may keep a
  // person on a candidate already learned, a step from where they stand.
  events_.assign(views_.size(), 0);
  const FloorGrid& g = columns_.candidates();
  for (const ExplainedPerson& p : people) {
    if (p.candidate < 0 || p.candidate >= n) continue;
    const int64_t i = p.candidate % g.cells_x, j = p.candidate / g.cells_x;
    for (int64_t nj = std::max<int64_t>(j - 1, 0); nj <= std::min<int64_t>(j + 1, g.cells_y - 1); ++nj)
      for (int64_t ni = std::max<int64_t>(i - 1, 0); ni <= std::min<int64_t>(i + 1, g.cells_x - 1); ++ni)
        person_at_[static_cast<size_t>(nj * g.cells_x + ni)] = 1;
  }
  ParallelFor(ctx, 0, cams, [&](int64_t b, int64_t e, int) {
    for (int64_t c = b; c < e; ++c) {
      if (!active[c]) continue;
      const ImageView<const uint8_t> in = changes[c];
      Image<uint8_t>& out = unexplained_[c];
      if (out.width() != in.width() || out.height() != in.height()) out = Image<uint8_t>(in.width(), in.height());
      for (int y = 0; y < in.height(); ++y) std::copy_n(in.row(y), in.width(), out.row(y));
      for (const ExplainedPerson& p : people) {
        if (p.candidate < 0 || p.candidate >= n) continue;
        const ColumnView& v = columns_.view(static_cast<int>(c), p.candidate);
        if (!v.projected) continue;
        const ColumnSpans s = MakeColumnSpans(v, kCoverRadiusM, 0.0, 1.0, columns_.image_size(static_cast<int>(c)));
        for (int y = std::max(s.first_row, 0); y <= std::min(s.last_row, s.height - 1); ++y) {
          int x0, x1;
          if (s.Span(y, x0, x1)) std::fill(out.row(y) + x0, out.row(y) + x1 + 1, uint8_t{0});
        }
      }
      unexplained_counts_[c].Build(out.view());
    }
  });
  const double low = column_.band_low_m / h, high = column_.band_high_m / h;
  const double min_changed = column_.min_changed;
  const int32_t frame = static_cast<int32_t>(std::clamp<int64_t>(frame_index, 0, INT32_MAX));
  ParallelFor(
      ctx, 0, n,
      [&](int64_t begin, int64_t end, int) {
        ColumnSpans spans[kMaxCameras];
        int testing[kMaxCameras];
        double fraction[kMaxCameras];
        bool unexplained[kMaxCameras];
        for (int64_t k = begin; k < end; ++k) {
          // The cameras that test k, as the column fusion's (a learned block set or not), with a
          // first look at 4 rows: without min_others of them possibly changed, nothing is learned.
          int num_testing = 0, maybe_changed = 0;
          for (int c = 0; c < cams; ++c) {
            if (!active[c]) continue;
            const ColumnView& v = columns_.view(c, k);
            if (!v.seen || (v.blocked && !v.learned)) continue;
            const ColumnSpans s = MakeColumnSpans(v, column_.radius_m, low, high, columns_.image_size(c));
            if (2 * s.visible_rows < s.last_row - s.first_row + 1) continue;
            int64_t pixels = 0;
            const int64_t changed = CountBand(s, counts[c], 4, pixels);
            if (pixels == 0) continue;
            maybe_changed += 2 * static_cast<double>(changed) >= min_changed * static_cast<double>(pixels) ? 1 : 0;
            spans[num_testing] = s;
            testing[num_testing++] = c;
          }
          if (maybe_changed < options_.min_others) continue;
          // f per camera, and the share of the band's changes nobody explains.
          int changed_unblocked = 0, unchanged_unblocked = 0, unexplained_unblocked = 0;
          for (int t = 0; t < num_testing; ++t) {
            int64_t pixels = 0;
            const int c = testing[t];
            const int64_t changed = CountBand(spans[t], counts[c], column_.max_rows, pixels);
            fraction[t] = pixels > 0 ? static_cast<double>(changed) / static_cast<double>(pixels) : 0.0;
            if (columns_.view(c, k).learned) continue;
            const bool is_changed = fraction[t] >= min_changed;
            (is_changed ? changed_unblocked : unchanged_unblocked) += 1;
            if (is_changed) {
              const int64_t free = CountBand(spans[t], unexplained_counts_[c], column_.max_rows, pixels);
              unexplained[t] = static_cast<double>(free) >= min_changed * static_cast<double>(pixels);
              unexplained_unblocked += unexplained[t] ? 1 : 0;
            } else {
              unexplained[t] = false;
            }
          }
          const bool person_here = person_at_[static_cast<size_t>(k)] != 0;
          for (int t = 0; t < num_testing; ++t) {
            const bool learned = columns_.view(testing[t], k).learned;
            const bool changed = fraction[t] >= min_changed;
            // The others' agreement: every camera no learned block silences, but this one.
            const int others_changed = changed_unblocked - (!learned && changed ? 1 : 0);
            const int others_unchanged = unchanged_unblocked - (!learned && !changed ? 1 : 0);
            const int others_unexplained = unexplained_unblocked - (!learned && unexplained[t] ? 1 : 0);
            const size_t at = static_cast<size_t>(testing[t]) * static_cast<size_t>(n) + static_cast<size_t>(k);
            View& v = views_[at];
            if (changed) {
              if (others_unchanged > 0 || others_changed < options_.min_others) continue;
              events_[at] = kSeenEvent;
              if (int64_t{frame} - v.last_seen >= options_.episode_frames) {
                v.last_seen = frame;
                if (v.seen < kMaxEpisodes) ++v.seen;
              }
            } else if (fraction[t] <= options_.max_changed) {
              const bool others_see_someone =
                  others_unchanged == 0 && others_unexplained >= options_.min_others && others_unexplained == others_changed;
              if (!person_here && !others_see_someone) continue;
              events_[at] = kHiddenEvent;
              if (int64_t{frame} - v.last_hidden >= options_.episode_frames) {
                v.last_hidden = frame;
                if (v.hidden < kMaxEpisodes) ++v.hidden;
              }
            }
          }
        }
      },
      1024);
  Pool(frame);
  ++frames_;
  if (frames_ % kApplyEvery != 0) return false;
  const bool changed = Apply();
  if (changed) {
    settled_after_ = frames_;
    growth_.emplace_back(frames_, blocked_views());
  }
  return changed;
}

int64_t OccluderLearner::most_after_frames() const {
  const int64_t blocked = blocked_views();
  for (const auto& [frames, count] : growth_)
    if (10 * count >= 9 * blocked) return frames;
  return frames_;
}

uint64_t OccluderLearner::Fingerprint(const ColumnLut& columns) {
  Hasher h;
  const FloorGrid& g = columns.candidates();
  h.AddPod(g.origin_x_m);
  h.AddPod(g.origin_y_m);
  h.AddPod(g.cells_x);
  h.AddPod(g.cells_y);
  h.AddPod(g.cell_size_m);
  h.AddPod(columns.num_cameras());
  for (int c = 0; c < columns.num_cameras(); ++c) {
    h.AddPod(columns.image_size(c).width);
    h.AddPod(columns.image_size(c).height);
    for (int64_t k = 0; k < g.num_cells(); ++k) {
      const ColumnView& v = columns.view(c, k);
      const float geometry[6] = {v.top_row, v.bottom_row, v.axis_x_top, v.axis_x_bottom, v.half_width_top,
                                 v.half_width_bottom};
      h.AddPod(geometry);
      const uint8_t flags = static_cast<uint8_t>((v.seen ? 1 : 0) | (v.projected ? 2 : 0) |
                                                 (v.blocked && !v.learned ? 4 : 0));
      h.AddPod(flags);
    }
  }
  return h.Digest();
}

Status OccluderLearner::Save(const std::filesystem::path& path) const {
  const int64_t n = columns_.candidates().num_cells();
  std::string body;
  int64_t lines = 0;
  for (int c = 0; c < columns_.num_cameras(); ++c) {
    for (int64_t k = 0; k < n; ++k) {
      const View& v = views_[static_cast<size_t>(c) * static_cast<size_t>(n) + static_cast<size_t>(k)];
      if (v.hidden == 0 && v.seen == 0) continue;
      body += fmt::format("{} {} {} {}\n", c, k, v.hidden, v.seen);
      ++lines;
    }
  }
  std::string pooled;
  int64_t block_lines = 0;
  for (size_t c = 0; c < blocks_.size(); ++c) {
    for (size_t b = 0; b < blocks_[c].size(); ++b) {
      const Block& x = blocks_[c][b];
      if (x.hidden == 0 && x.seen == 0) continue;
      pooled += fmt::format("{} {} {} {} {} {}\n", c, b, x.hidden, x.seen, x.near_hidden, x.far_seen);
      ++block_lines;
    }
  }
  body += fmt::format("blocks {}\n{}", block_lines, pooled);
  const std::string text = fmt::format(
      "{} {}\nfingerprint {:016x}\ncameras {} candidates {}\nframes {} settled {} most {} blocked {}\nviews {}\n{}",
      kMagic, kVersion, Fingerprint(columns_), columns_.num_cameras(), n, frames_, settled_after_, most_after_frames(),
      blocked_views(), lines, body);
  return WriteFileAtomic(path, text);
}

namespace {

// The whitespace-separated integers of a line, each in [0, limit[i]]; false when it is not that.
bool ParseInts(std::string_view line, std::span<int64_t> out) {
  size_t at = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    while (at < line.size() && line[at] == ' ') ++at;
    const auto r = std::from_chars(line.data() + at, line.data() + line.size(), out[i]);
    if (r.ec != std::errc() || out[i] < 0) return false;
    at = static_cast<size_t>(r.ptr - line.data());
  }
  return at == line.size();
}

}  // namespace

Status OccluderLearner::Load(const std::filesystem::path& path, bool* stale) {
  if (stale) *stale = false;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return NotFound(fmt::format("{}: no such file", path.string()));
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(path));
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  const auto bad = [&](std::string_view expected) {
    return DataLoss(fmt::format("{}:{}: expected {}, found '{}'", path.string(), line_no, expected,
                                line.substr(0, 80)));
  };
  const auto next = [&] {
    ++line_no;
    return static_cast<bool>(std::getline(in, line));
  };
  if (!next() || line != fmt::format("{} {}", kMagic, kVersion)) return bad(fmt::format("'{} {}'", kMagic, kVersion));
  uint64_t fingerprint = 0;
  if (!next() || std::sscanf(line.c_str(), "fingerprint %16" SCNx64, &fingerprint) != 1)
    return bad("'fingerprint' and 16 hex digits");
  int cams = 0;
  long long candidates = 0, frames = 0, settled = 0, most = 0, blocked = 0, count = 0;
  if (!next() || std::sscanf(line.c_str(), "cameras %d candidates %lld", &cams, &candidates) != 2)
    return bad("'cameras N candidates M'");
  if (!next() ||
      std::sscanf(line.c_str(), "frames %lld settled %lld most %lld blocked %lld", &frames, &settled, &most, &blocked) !=
          4 ||
      frames < 0 || settled < 0 || settled > frames || most < 0 || most > frames)
    return bad("'frames F settled S most M blocked B' (0 <= S, M <= F)");
  if (!next() || std::sscanf(line.c_str(), "views %lld", &count) != 1 || count < 0) return bad("'views N'");
  const int64_t n = columns_.candidates().num_cells();
  if (cams != columns_.num_cameras() || candidates != n || fingerprint != Fingerprint(columns_)) {
    if (stale) *stale = true;
    return DataLoss(fmt::format("{}: stale: learned for other cameras or another grid ({} cameras, {} candidates, "
                                "fingerprint {:016x}; this site: {}, {}, {:016x})",
                                path.string(), cams, candidates, fingerprint, columns_.num_cameras(), n,
                                Fingerprint(columns_)));
  }
  std::vector<View> views(views_.size());
  std::vector<uint8_t> given(views_.size(), 0);
  for (long long i = 0; i < count; ++i) {
    if (!next()) return bad(fmt::format("{} view lines, the file ends after {}", count, i));
    int64_t v[4];
    if (!ParseInts(line, v) || v[0] >= cams || v[1] >= n || v[2] > kMaxEpisodes || v[3] > kMaxEpisodes)
      return bad(fmt::format("'camera candidate hidden seen' (camera < {}, candidate < {}, episodes <= {})", cams, n,
                             kMaxEpisodes));
    const size_t at = static_cast<size_t>(v[0]) * static_cast<size_t>(n) + static_cast<size_t>(v[1]);
    if (given[at]) return bad(fmt::format("each view once (camera {} candidate {} again)", v[0], v[1]));
    given[at] = 1;
    views[at].hidden = static_cast<uint16_t>(v[2]);
    views[at].seen = static_cast<uint16_t>(v[3]);
  }
  long long num_blocks = 0;
  if (!next() || std::sscanf(line.c_str(), "blocks %lld", &num_blocks) != 1 || num_blocks < 0) return bad("'blocks N'");
  std::vector<std::vector<Block>> blocks(static_cast<size_t>(cams));
  for (int c = 0; c < cams; ++c) {
    const ImageSize size = columns_.image_size(c);
    blocks[c].assign(static_cast<size_t>((size.width + kBlockPx - 1) / kBlockPx) *
                         static_cast<size_t>((size.height + kBlockPx - 1) / kBlockPx),
                     Block{});
  }
  std::vector<std::vector<uint8_t>> block_given(static_cast<size_t>(cams));
  for (int c = 0; c < cams; ++c) block_given[c].assign(blocks[c].size(), 0);
  for (long long i = 0; i < num_blocks; ++i) {
    if (!next()) return bad(fmt::format("{} block lines, the file ends after {}", num_blocks, i));
    int c = -1;
    long long b = -1, hidden = -1, seen = -1;
    float near = 0, far = 0;
    char extra = 0;
    if (std::sscanf(line.c_str(), "%d %lld %lld %lld %f %f %c", &c, &b, &hidden, &seen, &near, &far, &extra) != 6 ||
        c < 0 || c >= cams || b < 0 || b >= static_cast<long long>(blocks[c].size()) || hidden < 0 ||
        hidden > kMaxEpisodes || seen < 0 || seen > kMaxEpisodes || !(near > 0) || !(far >= 0))
      return bad("'camera block hidden seen near far' (a block of the camera's image, episodes <= 65535, depths > 0)");
    if (block_given[c][b]) return bad(fmt::format("each block once (camera {} block {} again)", c, b));
    block_given[c][b] = 1;
    blocks[c][b].hidden = static_cast<uint16_t>(hidden);
    blocks[c][b].seen = static_cast<uint16_t>(seen);
    blocks[c][b].near_hidden = near;
    blocks[c][b].far_seen = far;
  }
  if (next() && !line.empty()) return bad("the end of the file");
  views_ = std::move(views);
  blocks_ = std::move(blocks);
  frames_ = frames;
  settled_after_ = settled;
  Apply();
  growth_.assign(1, {std::min<int64_t>(most, frames), blocked_views()});
  return Status::Ok();
}

}  // namespace occmap
