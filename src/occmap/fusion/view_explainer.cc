#include "occmap/fusion/view_explainer.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <queue>

namespace occmap {

Status ExplainOptions::Validate() const {
  if (!(radius_m > 0 && radius_m <= 1))
    return InvalidInput(fmt::format("radius_m: expected a radius in (0, 1] m, found {}", radius_m));
  if (!(unchanged_weight >= 0 && unchanged_weight <= 10))
    return InvalidInput(fmt::format("unchanged_weight: expected 0 to 10, found {}", unchanged_weight));
  if (!(min_gain > 0 && std::isfinite(min_gain)))
    return InvalidInput(fmt::format("min_gain: expected a positive number, found {}", min_gain));
  if (!(min_separation_m >= 0 && min_separation_m <= 2))
    return InvalidInput(fmt::format("min_separation_m: expected 0 to 2 m, found {}", min_separation_m));
  if (moves < 0 || moves > 10) return InvalidInput(fmt::format("moves: expected 0 to 10, found {}", moves));
  if (!(move_radius_m >= 0 && move_radius_m <= 2))
    return InvalidInput(fmt::format("move_radius_m: expected 0 to 2 m, found {}", move_radius_m));
  if (max_people < 1) return InvalidInput(fmt::format("max_people: expected at least 1, found {}", max_people));
  if (!(ground_band >= 0 && ground_band <= 1))
    return InvalidInput(fmt::format("ground_band: expected 0 to 1, found {}", ground_band));
  if (!(ground_weight >= 0 && ground_weight <= 10))
    return InvalidInput(fmt::format("ground_weight: expected 0 to 10, found {}", ground_weight));
  if (max_rows < 1) return InvalidInput(fmt::format("max_rows: expected at least 1, found {}", max_rows));
  return Status::Ok();
}

namespace {
// A camera's gain over the model's pixels there, as a fraction of them.
double PerCamera(double value, int64_t pixels) { return value / static_cast<double>(pixels); }

// The spans of candidate k's person model in camera c, or visible_rows 0 when c says nothing.
ColumnSpans PersonSpans(const ColumnLut& columns, int c, int64_t k, const ExplainOptions& o) {
  const ColumnView& v = columns.view(c, k);
  if (!v.projected || v.blocked) return {};
  return MakeColumnSpans(v, o.radius_m, 0.0, 1.0, columns.image_size(c));
}

// Rows of a model's image read by the gains: evenly spaced, at most max_rows (coverage is kept
// on every row).
int RowStep(const ColumnSpans& s, int max_rows) { return std::max(1, (s.visible_rows + max_rows - 1) / max_rows); }

// The last image row of the ground band below a model's foot row (last_row when there is none).
int GroundBandEnd(const ColumnSpans& s, const ExplainOptions& o) {
  if (o.ground_band <= 0 || o.ground_weight <= 0) return s.last_row;
  const int rows = std::max(1, static_cast<int>(std::lround(o.ground_band * (s.last_row - s.first_row + 1))));
  return std::min(s.last_row + rows, s.height - 1);
}

}  // namespace

double ViewExplainer::UpperBound(int64_t k, std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                                 const ExplainOptions& o) const {
  double gain = 0;
  for (int c = 0; c < columns_.num_cameras(); ++c) {
    if (!active[c]) continue;
    Term t;
    CameraTerm(k, c, counts[c], o, t);
    gain += t.gain;
  }
  return gain;
}

// The spans read from the row sums and the ground band below them (the reference's bound).
void ViewExplainer::CameraTerm(int64_t k, int c, const ChangeRowSums& counts, const ExplainOptions& o,
                               Term& t) const {
  t = Term{};
  const ColumnSpans s = PersonSpans(columns_, c, k, o);
  if (s.visible_rows == 0) return;
  int64_t changed = 0, pixels = 0;
  const int step = RowStep(s, o.max_rows);
  s.ForEachRow(std::max(s.first_row, 0), std::min(s.last_row, s.height - 1), step, [&](int y, int x0, int x1) {
    changed += counts.Count(y, x0, x1);
    pixels += x1 - x0 + 1;
    t.body.Add(y, x0, x1);
  });
  if (pixels == 0) return;
  int64_t ground = 0;
  s.ForEachRow(s.last_row + 1, GroundBandEnd(s, o), step, [&](int y, int x0, int x1) {
    ground += counts.Count(y, x0, x1);
    t.ground.Add(y, x0, x1);
  });
  t.counts = true;
  t.gain = PerCamera(static_cast<double>(changed) - o.unchanged_weight * static_cast<double>(pixels - changed) -
                         o.ground_weight * static_cast<double>(ground),
                     pixels);
}

// The rows CameraTerm reads, without the counts.
void ViewExplainer::WorkOutModelRows(int64_t k, int c, const ExplainOptions& o, ModelRows& m,
                                     std::vector<RowSpan>& spans) const {
  m = ModelRows{};
  m.image = ImageBox(k, c, o);
  const ColumnSpans s = PersonSpans(columns_, c, k, o);
  if (s.visible_rows == 0) return;
  const size_t first = spans.size();
  int64_t pixels = 0;
  const int step = RowStep(s, o.max_rows);
  s.ForEachRow(std::max(s.first_row, 0), std::min(s.last_row, s.height - 1), step, [&](int y, int x0, int x1) {
    pixels += x1 - x0 + 1;
    m.body.Add(y, x0, x1);
    spans.push_back({static_cast<uint16_t>(y), static_cast<uint16_t>(x0), static_cast<uint16_t>(x1)});
  });
  if (pixels == 0) {
    spans.resize(first);
    m.body = Box{};
    return;
  }
  const size_t body_end = spans.size();
  s.ForEachRow(s.last_row + 1, GroundBandEnd(s, o), step, [&](int y, int x0, int x1) {
    m.ground.Add(y, x0, x1);
    spans.push_back({static_cast<uint16_t>(y), static_cast<uint16_t>(x0), static_cast<uint16_t>(x1)});
  });
  m.counts = true;
  m.pixels = pixels;
  m.first_span = static_cast<uint32_t>(first);
  m.body_rows = static_cast<uint32_t>(body_end - first);
  m.ground_rows = static_cast<uint32_t>(spans.size() - body_end);
}

ViewExplainer::Box ViewExplainer::ImageBox(int64_t k, int c, const ExplainOptions& o) const {
  Box box;
  const ColumnSpans sp = PersonSpans(columns_, c, k, o);
  if (sp.visible_rows == 0) return box;
  for (int y : {std::max(sp.first_row, 0), std::min(sp.last_row, sp.height - 1)}) {
    int x0, x1;
    if (!sp.Span(y, x0, x1)) continue;
    box.x0 = std::min(box.x0, x0);
    box.x1 = std::max(box.x1, x1);
  }
  box.y0 = std::max(sp.first_row, 0);
  box.y1 = std::min(sp.last_row, sp.height - 1);
  return box;
}

void ViewExplainer::KeepModelRows(const std::vector<int64_t>& candidates, const ExplainOptions& o, Context& ctx) {
  const int cams = columns_.num_cameras();
  ModelKey key;
  key.radius_m = o.radius_m;
  key.ground_band = o.ground_band;
  key.ground = o.ground_band > 0 && o.ground_weight > 0;  // GroundBandEnd
  key.max_rows = o.max_rows;
  key.revision = columns_.revision();
  const size_t cells = static_cast<size_t>(columns_.candidates().num_cells());
  if (!(key == model_key_) || model_of_.size() != cells || model_spans_.size() > kMaxModelSpans) {
    model_key_ = key;
    model_of_.assign(cells, -1);
    model_rows_.clear();
    model_spans_.clear();
  }
  missing_.clear();
  for (int64_t k : candidates)
    if (model_of_[static_cast<size_t>(k)] < 0) missing_.push_back(k);
  if (missing_.empty()) return;
  OCCMAP_CHECK(model_rows_.size() + missing_.size() * static_cast<size_t>(cams) < (size_t{1} << 31),
               "ViewExplainer: too many kept model rows");
  arenas_.resize(static_cast<size_t>(std::max(1, ctx.num_threads())));
  OCCMAP_CHECK(arenas_.size() <= 256, "ViewExplainer: at most 256 threads");
  for (auto& arena : arenas_) arena.clear();
  missing_rows_.resize(missing_.size() * static_cast<size_t>(cams));
  missing_arena_.resize(missing_.size());
  ParallelFor(
      ctx, 0, static_cast<int64_t>(missing_.size()),
      [&](int64_t b, int64_t e, int worker) {
        std::vector<RowSpan>& arena = arenas_[static_cast<size_t>(worker)];
        for (int64_t i = b; i < e; ++i) {
          missing_arena_[static_cast<size_t>(i)] = static_cast<uint8_t>(worker);
          for (int c = 0; c < cams; ++c)
            WorkOutModelRows(missing_[static_cast<size_t>(i)], c, o,
                             missing_rows_[static_cast<size_t>(i) * static_cast<size_t>(cams) + static_cast<size_t>(c)],
                             arena);
        }
      },
      64);
  // Into the kept rows, in the order of the candidates.
  for (size_t i = 0; i < missing_.size(); ++i) {
    model_of_[static_cast<size_t>(missing_[i])] = static_cast<int32_t>(model_rows_.size());
    const std::vector<RowSpan>& arena = arenas_[missing_arena_[i]];
    for (int c = 0; c < cams; ++c) {
      ModelRows m = missing_rows_[i * static_cast<size_t>(cams) + static_cast<size_t>(c)];
      const uint32_t n = m.body_rows + m.ground_rows;
      const size_t at = model_spans_.size();
      model_spans_.insert(model_spans_.end(), arena.begin() + m.first_span, arena.begin() + m.first_span + n);
      OCCMAP_CHECK(model_spans_.size() < (size_t{1} << 32), "ViewExplainer: too many kept model rows");
      m.first_span = static_cast<uint32_t>(at);
      model_rows_.push_back(m);
    }
  }
}

double ViewExplainer::Gain(int64_t k, std::span<const ImageView<const uint8_t>> changes,
                           const std::vector<bool>& active, const ExplainOptions& o, int max_cover) const {
  double gain = 0;
  for (int c = 0; c < columns_.num_cameras(); ++c) {
    if (!active[c]) continue;
    const ColumnSpans s = PersonSpans(columns_, c, k, o);
    if (s.visible_rows == 0) continue;
    const bool have_coverage = coverage_.size() > static_cast<size_t>(c) && !coverage_[c].empty();
    int64_t changed = 0, unchanged = 0, pixels = 0;
    const int step = RowStep(s, o.max_rows);
    for (int y = std::max(s.first_row, 0); y <= std::min(s.last_row, s.height - 1); y += step) {
      int x0, x1;
      if (!s.Span(y, x0, x1)) continue;
      pixels += x1 - x0 + 1;
      const uint8_t* ch = changes[c].row(y);
      const uint8_t* cov = have_coverage ? coverage_[c].row(y) : nullptr;
      int row_changed = 0, row_free = 0;
      if (cov == nullptr) {
        row_free = x1 - x0 + 1;
        for (int x = x0; x <= x1; ++x) row_changed += ch[x] != 0 ? 1 : 0;
      } else {
        // Branch-free, so that it vectorises: byte masks summed.
        const uint8_t limit = static_cast<uint8_t>(max_cover);
        for (int x = x0; x <= x1; ++x) {
          const int free = cov[x] <= limit ? 1 : 0;
          row_free += free;
          row_changed += free & (ch[x] != 0 ? 1 : 0);
        }
      }
      changed += row_changed;
      unchanged += row_free - row_changed;
    }
    if (pixels == 0) continue;
    // The floor just in front of the feet: changed there and explained by nobody, a person
    // standing here would hide it.
    int64_t ground = 0;
    const int band_end = GroundBandEnd(s, o);
    for (int y = s.last_row + 1; y <= band_end; y += step) {
      int x0, x1;
      if (!s.Span(y, x0, x1)) continue;
      const uint8_t* ch = changes[c].row(y);
      const uint8_t* cov = have_coverage ? coverage_[c].row(y) : nullptr;
      for (int x = x0; x <= x1; ++x) ground += (ch[x] != 0 && (cov == nullptr || cov[x] == 0)) ? 1 : 0;
    }
    gain += PerCamera(static_cast<double>(changed) - o.unchanged_weight * static_cast<double>(unchanged) -
                          o.ground_weight * static_cast<double>(ground),
                      pixels);
  }
  return gain;
}

double ViewExplainer::Terms(int64_t k, std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                            const ExplainOptions& o, Term* terms) const {
  const int cams = columns_.num_cameras();
  const ModelRows* model = model_rows_.data() + model_of_[static_cast<size_t>(k)];
  double gain = 0;
  for (int c = 0; c < cams; ++c) {
    Term& t = terms[c];
    t = Term{};
    const ModelRows& m = model[c];
    if (!active[c] || !m.counts) continue;
    const ChangeRowSums& count = counts[c];
    const RowSpan* rows = model_spans_.data() + m.first_span;
    int64_t changed = 0, ground = 0;
    for (const RowSpan* r = rows; r != rows + m.body_rows; ++r) changed += count.Count(r->y, r->x0, r->x1);
    for (const RowSpan* r = rows + m.body_rows; r != rows + m.body_rows + m.ground_rows; ++r)
      ground += count.Count(r->y, r->x0, r->x1);
    t.counts = true;
    t.body = m.body;
    t.ground = m.ground;
    t.first_span = m.first_span;
    t.body_rows = m.body_rows;
    t.ground_rows = m.ground_rows;
    t.gain = PerCamera(static_cast<double>(changed) - o.unchanged_weight * static_cast<double>(m.pixels - changed) -
                           o.ground_weight * static_cast<double>(ground),
                       m.pixels);
    gain += t.gain;
  }
  return gain;
}

void ViewExplainer::CountUncovered(int y, int x0, int x1, int max_cover, const ChangeRowSums& counts,
                                   int64_t& changed, int64_t& free) {
  // The met people's spans on this row, clipped to x0..x1, as edges: +1 where one starts, -1
  // just past where it ends.
  edges_.clear();
  for (const Met& m : met_) {
    if (!m.box.MeetsRow(y, x0, x1)) continue;
    // Row y's span: a direct index, or a search where a row whose span missed the image was dropped.
    const int i = y - m.first->y;  // the box holds y: a span was kept on its first row
    if (i < 0) continue;
    const RowSpan* span = m.first + i;
    if (!(i < m.end - m.first && span->y == y)) {
      span = std::lower_bound(m.first, m.end, y, [](const RowSpan& r, int row) { return r.y < row; });
      if (span == m.end || span->y != y) continue;
    }
    const int a = std::max<int>(span->x0, x0), b = std::min<int>(span->x1, x1);
    if (a > b) continue;
    edges_.push_back({a, +1});
    edges_.push_back({b + 1, -1});
  }
  if (static_cast<int>(edges_.size() / 2) <= max_cover) {  // nowhere covered more than max_cover
    changed += counts.Count(y, x0, x1);
    free += x1 - x0 + 1;
    return;
  }
  // A few people at most: insertion sort by position (the order within a position does not
  // matter: every edge there is applied before the run from it is counted).
  for (size_t i = 1; i < edges_.size(); ++i)
    for (size_t k = i; k > 0 && edges_[k].first < edges_[k - 1].first; --k) std::swap(edges_[k], edges_[k - 1]);
  int depth = 0;
  size_t e = 0;
  for (int at = x0; at <= x1;) {
    while (e < edges_.size() && edges_[e].first <= at) depth += edges_[e++].second;
    const int next = e < edges_.size() ? std::min(edges_[e].first, x1 + 1) : x1 + 1;
    if (depth <= max_cover) {
      changed += counts.Count(y, at, next - 1);
      free += next - at;
    }
    at = next;
  }
}

double ViewExplainer::FastGain(int32_t index, std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                               const ExplainOptions& o, int max_cover) {
  const int cams = columns_.num_cameras();
  const Term* terms = terms_.data() + static_cast<size_t>(index) * static_cast<size_t>(cams);
  double gain = 0;
  for (int c = 0; c < cams; ++c) {
    const Term& t = terms[c];
    if (!active[c] || !t.counts) continue;
    // The chosen people whose coverage meets what the gain reads here.
    met_.clear();
    int body_met = 0;
    bool ground_met = false;
    for (int32_t j : covered_) {
      const size_t at = static_cast<size_t>(j) * static_cast<size_t>(cams) + static_cast<size_t>(c);
      const Box& b = cover_boxes_[at];
      const bool in_body = b.Meets(t.body), in_ground = b.Meets(t.ground);
      if (!in_body && !in_ground) continue;
      body_met += in_body ? 1 : 0;
      ground_met |= in_ground;
      const CoverRows& rows = cover_rows_[at];
      OCCMAP_DCHECK(rows.known && rows.rows > 0, "ViewExplainer::FastGain: a covered candidate without rows");
      met_.push_back({b, cover_spans_.data() + rows.first, cover_spans_.data() + rows.first + rows.rows});
    }
    // Nobody's coverage above max_cover on the body, none on the ground band: the term as it was.
    if (body_met <= max_cover && !ground_met) {
      gain += t.gain;
      continue;
    }
    // Row by row, from the row sums: the runs of each row that at most max_cover of the met
    // people's spans cover (on the ground band, none).
    const RowSpan* rows = model_spans_.data() + t.first_span;
    int64_t changed = 0, free = 0, pixels = 0;
    for (const RowSpan* r = rows; r != rows + t.body_rows; ++r) {
      pixels += r->x1 - r->x0 + 1;
      CountUncovered(r->y, r->x0, r->x1, max_cover, counts[c], changed, free);
    }
    int64_t ground = 0, ground_free = 0;
    for (const RowSpan* r = rows + t.body_rows; r != rows + t.body_rows + t.ground_rows; ++r)
      CountUncovered(r->y, r->x0, r->x1, 0, counts[c], ground, ground_free);
    gain += PerCamera(static_cast<double>(changed) - o.unchanged_weight * static_cast<double>(free - changed) -
                          o.ground_weight * static_cast<double>(ground),
                      pixels);
  }
  return gain;
}

void ViewExplainer::Cover(int64_t k, int32_t index, const std::vector<bool>& active, const ExplainOptions& o,
                          int delta) {
  const int cams = columns_.num_cameras();
  for (int c = 0; c < cams; ++c) {
    Box& box = cover_boxes_[static_cast<size_t>(index) * static_cast<size_t>(cams) + static_cast<size_t>(c)];
    box = Box{};
    if (!active[c]) continue;
    if (fast_cover_) {  // the rows worked out at the candidate's first Cover this frame
      CoverRows& rows = cover_rows_[static_cast<size_t>(index) * static_cast<size_t>(cams) + static_cast<size_t>(c)];
      if (!rows.known) {
        rows.known = true;
        rows.first = static_cast<uint32_t>(cover_spans_.size());
        const ColumnSpans s = PersonSpans(columns_, c, k, o);
        if (s.visible_rows > 0) {
          const int y0 = std::max(s.first_row, 0), y1 = std::min(s.last_row, s.height - 1);
          cover_spans_.resize(rows.first + static_cast<size_t>(y1 - y0 + 1));
          cover_spans_.resize(rows.first + static_cast<size_t>(s.Rows(y0, y1, 1, cover_spans_.data() + rows.first)));
        }
        rows.rows = static_cast<uint32_t>(cover_spans_.size()) - rows.first;
        for (const RowSpan* r = cover_spans_.data() + rows.first; r != cover_spans_.data() + rows.first + rows.rows; ++r)
          rows.box.Add(r->y, r->x0, r->x1);
      }
      // No coverage written: FastGain counts from the chosen people's rows.
      box = rows.box;
      continue;
    }
    const ColumnSpans s = PersonSpans(columns_, c, k, o);
    if (s.visible_rows == 0) continue;
    for (int y = std::max(s.first_row, 0); y <= std::min(s.last_row, s.height - 1); ++y) {
      int x0, x1;
      if (!s.Span(y, x0, x1)) continue;
      uint8_t* cov = coverage_[c].row(y);
      for (int x = x0; x <= x1; ++x) cov[x] = static_cast<uint8_t>(cov[x] + delta);
      box.Add(y, x0, x1);
    }
  }
  if (delta > 0) {
    covered_.push_back(index);
  } else {
    const auto at = std::find(covered_.begin(), covered_.end(), index);
    if (at != covered_.end()) covered_.erase(at);
  }
}

void ViewExplainer::Explain(std::span<const ImageView<const uint8_t>> changes, std::span<const ChangeRowSums> counts,
                            const std::vector<bool>& active, const OccupancyMap& column_map,
                            const ExplainOptions& o, Context& ctx, std::vector<ExplainedPerson>& people) {
  Run(changes, counts, active, column_map, o, ctx, people, true);
}

void ViewExplainer::ExplainReference(std::span<const ImageView<const uint8_t>> changes,
                                     std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                                     const OccupancyMap& column_map, const ExplainOptions& o, Context& ctx,
                                     std::vector<ExplainedPerson>& people) {
  Run(changes, counts, active, column_map, o, ctx, people, false);
}

void ViewExplainer::Run(std::span<const ImageView<const uint8_t>> changes, std::span<const ChangeRowSums> counts,
                        const std::vector<bool>& active, const OccupancyMap& column_map, const ExplainOptions& o,
                        Context& ctx, std::vector<ExplainedPerson>& people, bool fast) {
  people.clear();
  const FloorGrid& grid = columns_.candidates();
  // The coverage images: the reference's alone (the fast path counts from the chosen people's rows).
  if (!fast && coverage_.size() != static_cast<size_t>(columns_.num_cameras())) {
    coverage_.clear();
    for (int c = 0; c < columns_.num_cameras(); ++c) {
      const ImageSize size = columns_.image_size(c);
      coverage_.emplace_back(size.width, size.height);
      for (int y = 0; y < size.height; ++y) std::fill_n(coverage_.back().row(y), size.width, uint8_t{0});
    }
  }
  // 1. Candidates and their bounds.
  std::vector<int64_t> candidates;
  for (int64_t k = 0; k < grid.num_cells(); ++k)
    if (column_map.state(k) == CellState::kOccupied) candidates.push_back(k);
  const int cams = columns_.num_cameras();
  std::vector<double> bound(candidates.size());
  if (fast) {
    // Rows are kept as 16-bit coordinates.
    for (int c = 0; c < cams; ++c)
      OCCMAP_CHECK(columns_.image_size(c).width <= 65536 && columns_.image_size(c).height <= 65536,
                   "ViewExplainer: images up to 65536 pixels a side");
    terms_.resize(candidates.size() * static_cast<size_t>(cams));
    KeepModelRows(candidates, o, ctx);
    cover_rows_.assign(candidates.size() * static_cast<size_t>(cams), CoverRows{});
    cover_spans_.clear();
  }
  fast_cover_ = fast;
  cover_boxes_.resize(candidates.size() * static_cast<size_t>(cams));
  covered_.clear();
  ParallelFor(
      ctx, 0, static_cast<int64_t>(candidates.size()),
      [&](int64_t b, int64_t e, int) {
        for (int64_t i = b; i < e; ++i) {
          bound[i] = fast ? Terms(candidates[i], counts, active, o, terms_.data() + static_cast<size_t>(i) * cams)
                          : UpperBound(candidates[i], counts, active, o);
        }
      },
      64);
  // A gain against the coverage of the people chosen so far (k: the candidate of `index`).
  const auto gain_of = [&](int64_t k, int max_cover) {
    const int32_t index = index_of_[k];
    return fast ? FastGain(index, counts, active, o, max_cover) : Gain(k, changes, active, o, max_cover);
  };
  // 2. Forward, lazily: (gain, candidate index); ties go to the lower index.
  using Entry = std::pair<double, int64_t>;
  const auto less = [](const Entry& a, const Entry& b) {
    return a.first < b.first || (a.first == b.first && a.second > b.second);
  };
  std::priority_queue<Entry, std::vector<Entry>, decltype(less)> queue(less);
  // The forward pass starts from the bounds' local maxima (3 x 3 on the candidate grid): the
  // moves (step 4) reach every candidate.
  // index_of_ is kept at -1 between calls: only this frame's candidates are set, then reset.
  std::vector<int32_t>& index_of = index_of_;
  if (index_of.size() != static_cast<size_t>(grid.num_cells())) index_of.assign(static_cast<size_t>(grid.num_cells()), -1);
  for (size_t i = 0; i < candidates.size(); ++i) index_of[candidates[i]] = static_cast<int32_t>(i);
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (bound[i] < o.min_gain) continue;
    const int64_t ci = candidates[i] % grid.cells_x, cj = candidates[i] / grid.cells_x;
    bool peak = true;
    for (int64_t dj = -1; dj <= 1 && peak; ++dj) {
      for (int64_t di = -1; di <= 1; ++di) {
        const int64_t ni = ci + di, nj = cj + dj;
        if ((di == 0 && dj == 0) || ni < 0 || nj < 0 || ni >= grid.cells_x || nj >= grid.cells_y) continue;
        const int32_t n = index_of[nj * grid.cells_x + ni];
        if (n >= 0 && (bound[n] > bound[i] || (bound[n] == bound[i] && n < static_cast<int32_t>(i)))) {
          peak = false;
          break;
        }
      }
    }
    if (peak) queue.push({bound[i], static_cast<int64_t>(i)});
  }
  // Each candidate's image box per camera: adding a person changes only the gains of the
  // candidates whose image meets its image in some camera.
  boxes_.assign(candidates.size() * static_cast<size_t>(cams), Box{});
  if (fast) {  // kept with the model's rows
    for (size_t i = 0; i < candidates.size(); ++i) {
      const ModelRows* model = model_rows_.data() + model_of_[static_cast<size_t>(candidates[i])];
      for (int c = 0; c < cams; ++c)
        if (active[c]) boxes_[i * static_cast<size_t>(cams) + static_cast<size_t>(c)] = model[c].image;
    }
  } else {
    ParallelFor(
        ctx, 0, static_cast<int64_t>(candidates.size()),
        [&](int64_t b, int64_t e, int) {
          for (int64_t i = b; i < e; ++i)
            for (int c = 0; c < cams; ++c)
              if (active[c]) boxes_[static_cast<size_t>(i) * cams + c] = ImageBox(candidates[i], c, o);
        },
        64);
  }
  const auto overlaps = [&](size_t i, size_t j) {
    for (int c = 0; c < cams; ++c) {
      const Box& a = boxes_[i * cams + c];
      const Box& b = boxes_[j * cams + c];
      if (a.x0 <= b.x1 && b.x0 <= a.x1 && a.y0 <= b.y1 && b.y0 <= a.y1) return true;
    }
    return false;
  };
  std::vector<uint8_t> fresh(candidates.size(), 0);  // gain in the queue is exact for the current set
  const double min_sep2 = o.min_separation_m * o.min_separation_m;
  while (!queue.empty() && static_cast<int>(people.size()) < o.max_people) {
    const auto [value, i] = queue.top();
    queue.pop();
    if (value < o.min_gain) break;
    const int64_t k = candidates[i];
    const Eigen::Vector2d xy = grid.CellCenter(k);
    bool too_close = false;
    for (const ExplainedPerson& p : people)
      if ((Eigen::Vector2d(p.x_m, p.y_m) - xy).squaredNorm() < min_sep2) too_close = true;
    if (too_close) continue;
    if (!fresh[i]) {
      const double g = gain_of(k, 0);
      fresh[i] = 1;
      if (g >= o.min_gain) queue.push({g, i});
      continue;
    }
    ExplainedPerson p;
    p.candidate = k;
    p.x_m = xy.x();
    p.y_m = xy.y();
    p.gain = value;
    for (int c = 0; c < columns_.num_cameras(); ++c)
      if (active[c] && columns_.view(c, k).projected && !columns_.view(c, k).blocked) ++p.views;
    people.push_back(p);
    Cover(k, static_cast<int32_t>(i), active, o, +1);
    for (size_t j = 0; j < candidates.size(); ++j)
      if (fresh[j] && overlaps(static_cast<size_t>(i), j)) fresh[j] = 0;
  }
  // 3. Backward: drop the weakest member while its exclusive gain is below min_gain.
  while (!people.empty()) {
    size_t worst = 0;
    double worst_gain = 0;
    for (size_t m = 0; m < people.size(); ++m) {
      const double g = gain_of(people[m].candidate, 1);
      people[m].gain = g;
      if (m == 0 || g < worst_gain) {
        worst = m;
        worst_gain = g;
      }
    }
    if (worst_gain >= o.min_gain) break;
    Cover(people[worst].candidate, index_of[people[worst].candidate], active, o, -1);
    people.erase(people.begin() + static_cast<ptrdiff_t>(worst));
  }
  // 4. Moves: each member in turn is taken out and put back at the candidate near it that gains most.
  const double move_r = o.move_radius_m;
  for (int sweep = 0; sweep < o.moves; ++sweep) {
    int moved = 0;
    for (size_t m = 0; m < people.size(); ++m) {
      Cover(people[m].candidate, index_of[people[m].candidate], active, o, -1);
      const Eigen::Vector2d at(people[m].x_m, people[m].y_m);
      int64_t best = people[m].candidate;
      double best_gain = gain_of(best, 0);
      for (size_t i = 0; i < candidates.size(); ++i) {
        if (bound[i] < o.min_gain) continue;
        const int64_t k = candidates[i];
        const Eigen::Vector2d xy = grid.CellCenter(k);
        if ((xy - at).squaredNorm() > move_r * move_r || k == people[m].candidate) continue;
        bool close = false;
        for (size_t q = 0; q < people.size(); ++q)
          if (q != m && (Eigen::Vector2d(people[q].x_m, people[q].y_m) - xy).squaredNorm() < min_sep2) close = true;
        if (close) continue;
        const double g = gain_of(k, 0);
        if (g > best_gain + 1e-9) { best_gain = g; best = k; }
      }
      if (best != people[m].candidate) ++moved;
      people[m].candidate = best;
      const Eigen::Vector2d xy = grid.CellCenter(best);
      people[m].x_m = xy.x();
      people[m].y_m = xy.y();
      Cover(best, index_of[best], active, o, +1);
    }
    if (moved == 0) break;
  }
  for (const ExplainedPerson& p : people) Cover(p.candidate, index_of[p.candidate], active, o, -1);  // coverage back to zero
  for (int64_t k : candidates) index_of[k] = -1;
}

}  // namespace occmap
