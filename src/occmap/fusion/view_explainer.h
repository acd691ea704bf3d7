// ViewExplainer: the set of people that best explains every camera's change mask.
//
// Model. A person standing at a candidate position appears in camera c as the image of an
// upright cylinder (ColumnLut: radius radius_m, the column's height). A set S of people
// predicts, in every camera, "changed" on the union of their images and "unchanged" elsewhere;
// its cost is the number of pixels where the prediction is wrong, unchanged pixels predicted
// changed counting unchanged_weight (a silhouette does not fill its cylinder). Adding person k
// to S lowers the cost, in camera c, by
//     gain_c(k | S) = (changed - unchanged_weight * unchanged) over k's pixels no member of S covers
//                     - ground_weight * (changed pixels no member covers in the band of floor
//                       just below k's feet, which a person standing at k would leave visible),
// and each camera's gain is divided by the area of k's image there, so that every camera that
// sees k counts alike, near or far: gain(k | S) = sum_c gain_c / area_c, in "views' worth".
//
// Search (after Alahi et al. 2011's greedy sparsity and Fleuret et al. 2008's occlusion
// reasoning, on our tables):
//  1. candidates: the occupied positions of the column map (column_fusion.h), nothing else;
//  2. forward: repeatedly add the candidate of largest gain (lazily: gains are first bounded
//     from the row sums, recomputed against the coverage when they reach the top), while it is
//     at least min_gain and no member stands within min_separation_m;
//  3. backward: repeatedly drop the member whose exclusive gain (over the pixels no other member
//     covers) is lowest, while it is below min_gain. A ghost (the intersection of the shadows of
//     people the other cameras see elsewhere) lies, in every view, inside people already chosen:
//     its exclusive gain is near zero and it goes, wherever the forward pass ranked it;
//  4. moves: each member in turn is taken out and put back at the candidate within
//     move_radius_m that gains most (moves sweeps, or until none moves): the forward pass
//     tends to place a person of a dense group where the model fits inside the group's
//     silhouettes, a little away from where the person stands.
// A camera takes part for a candidate wherever the model's image meets its image (the foot
// may be out of frame: a person close to a camera leaves a large changed region that only
// the right candidate should explain).
// Inactive cameras, cameras that do not see a candidate (ColumnView::seen) and those an
// occluder hides (blocked) say nothing about it. Equal results with 1 or 2 threads (the
// search is sequential; only the bounds are computed in parallel).
//
// Fast path (Explain): each candidate's per-camera gain with nobody chosen is computed once, with
// the bounds (row counts); a later gain reuses it for every camera where no chosen person's image
// meets the candidate's. The rows those gains read (the model's spans, the ground band's, the
// image box) depend on the geometry alone: they are worked out the first frame a candidate
// appears and kept across frames (for the same options and column table), so that a frame
// only counts. Where one does, each row the gain reads is cut by the chosen people's
// spans on it (their rows, worked out at their first Cover) into runs, and the runs that at most
// max_cover of them cover are counted from the row sums: no pixel is read, and no coverage image
// is kept (a pixel covered by 256 or more people would differ: the reference's counts are bytes).
// ExplainReference keeps the coverage of the chosen people as an image per camera and reads every
// gain pixel by pixel (equal results, tested).
//
//   ViewExplainer explainer(columns);
//   explainer.Explain(changes, counts, active, column_map, options, ctx, people);
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "occmap/fusion/column_fusion.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/lut/column_lut.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

struct ExplainOptions {
  double radius_m = 0.15;           // the person model's radius (a silhouette's core, not its arms)
  double unchanged_weight = 0.9;    // cost of an unchanged pixel predicted changed
  double min_gain = 0.7;            // views' worth a person must explain to be kept
  double min_separation_m = 0.35;   // two people are never closer
  int moves = 2;                    // sweeps of step 4
  double move_radius_m = 0.5;       // how far step 4 looks
  int max_people = 1000;
  int max_rows = 48;                // rows of a model's image read per camera (evenly spaced)
  // The floor in front of the feet: a band of ground_band times the model's rows below its foot
  // row, whose changed pixels nobody explains cost ground_weight each (0: off).
  // The depth cue: a model placed behind a person sees that person's legs in its band.
  double ground_band = 0.2;
  double ground_weight = 2.0;
  Status Validate() const;
};

struct ExplainedPerson {
  int64_t candidate = -1;  // on the column table's candidate grid
  double x_m = 0, y_m = 0;
  double gain = 0;         // its exclusive gain at the end, in views' worth
  int views = 0;           // cameras that see it
};

class ViewExplainer {
 public:
  explicit ViewExplainer(const ColumnLut& columns) : columns_(columns) {}

  // changes[c] (non-zero = changed) and counts[c] (its ChangeRowSums) per camera; those of
  // inactive cameras are not read. column_map: the column fusion's map on the candidate grid.
  // people: the chosen set, in the order chosen. Not thread-safe (keeps its buffers).
  void Explain(std::span<const ImageView<const uint8_t>> changes, std::span<const ChangeRowSums> counts,
               const std::vector<bool>& active, const OccupancyMap& column_map, const ExplainOptions& options,
               Context& ctx, std::vector<ExplainedPerson>& people);
  // The same people, every gain read pixel by pixel.
  void ExplainReference(std::span<const ImageView<const uint8_t>> changes, std::span<const ChangeRowSums> counts,
                        const std::vector<bool>& active, const OccupancyMap& column_map, const ExplainOptions& options,
                        Context& ctx, std::vector<ExplainedPerson>& people);

  // The gain of candidate k over the pixels that `coverage` (per camera, the number of chosen
  // people covering each pixel) shows at most `max_cover` on, pixel by pixel: for tests.
  double Gain(int64_t k, std::span<const ImageView<const uint8_t>> changes, const std::vector<bool>& active,
              const ExplainOptions& options, int max_cover) const;

 private:
  struct Box {
    int x0 = 1 << 30, x1 = -1, y0 = 1 << 30, y1 = -1;  // empty by default
    bool Meets(const Box& b) const { return x0 <= b.x1 && b.x0 <= x1 && y0 <= b.y1 && b.y0 <= y1; }
    bool MeetsRow(int y, int a, int b) const { return y0 <= y && y <= y1 && x0 <= b && a <= x1; }
    void Add(int y, int a, int b) {
      x0 = std::min(x0, a);
      x1 = std::max(x1, b);
      y0 = std::min(y0, y);
      y1 = std::max(y1, y);
    }
  };
  // One candidate's gain in one camera with nobody chosen, and where it reads.
  struct Term {
    double gain = 0;
    bool counts = false;  // the camera says something about it
    Box body, ground;     // the pixels the gain reads: the model's rows, the ground band's
    // Fast path: the rows the gain reads (those whose span meets the image), body rows then
    // ground rows, in model_spans_ from first_span.
    uint32_t first_span = 0;
    uint32_t body_rows = 0, ground_rows = 0;
  };
  // Fast path: where a candidate's Term reads in one camera, whatever the changes (geometry
  // alone, kept across frames: see model_of_).
  struct ModelRows {
    bool counts = false;  // the model's image has rows in the camera (not blocked, projected)
    Box body, ground;     // as Term's
    Box image;            // the model's whole image (Run's boxes_)
    uint32_t first_span = 0;  // into the worker's arena while worked out, then into model_spans_
    uint32_t body_rows = 0, ground_rows = 0;
    int64_t pixels = 0;   // of the body rows
  };

  void Run(std::span<const ImageView<const uint8_t>> changes, std::span<const ChangeRowSums> counts,
           const std::vector<bool>& active, const OccupancyMap& column_map, const ExplainOptions& options,
           Context& ctx, std::vector<ExplainedPerson>& people, bool fast);
  // Adds delta to the coverage of candidate k's pixels (k: this frame's candidate `index`).
  void Cover(int64_t k, int32_t index, const std::vector<bool>& active, const ExplainOptions& options, int delta);
  double UpperBound(int64_t k, std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                    const ExplainOptions& options) const;
  // Candidate k's Term in camera c (gain 0, counts false when c says nothing about it).
  void CameraTerm(int64_t k, int c, const ChangeRowSums& counts, const ExplainOptions& options, Term& term) const;
  // Candidate k's ModelRows in camera c, its rows appended to spans (first_span: their index there).
  void WorkOutModelRows(int64_t k, int c, const ExplainOptions& options, ModelRows& rows,
                        std::vector<RowSpan>& spans) const;
  // The image box of candidate k's model in camera c (empty when c says nothing about it).
  Box ImageBox(int64_t k, int c, const ExplainOptions& options) const;
  // Keeps the ModelRows of every candidate of this frame (works out those not yet kept).
  void KeepModelRows(const std::vector<int64_t>& candidates, const ExplainOptions& options, Context& ctx);
  // UpperBound from the kept ModelRows of candidate k, keeping each camera's Term (terms: one per camera).
  double Terms(int64_t k, std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
               const ExplainOptions& options, Term* terms) const;
  // Gain(k, ..., max_cover) for this frame's candidate `index`, from its Terms (their gains and
  // rows), the chosen people's rows and the row sums.
  double FastGain(int32_t index, std::span<const ChangeRowSums> counts, const std::vector<bool>& active,
                  const ExplainOptions& options, int max_cover);
  // Of row y's pixels x0 to x1 in FastGain's camera, those that at most max_cover of the people
  // in met_ cover: adds their number to free and the changed ones among them to changed.
  void CountUncovered(int y, int x0, int x1, int max_cover, const ChangeRowSums& counts, int64_t& changed,
                      int64_t& free);

  const ColumnLut& columns_;
  std::vector<Image<uint8_t>> coverage_;  // the reference's: per camera, the chosen people covering each pixel
  std::vector<Box> boxes_;  // per candidate and camera, this frame
  std::vector<Term> terms_;  // per candidate and camera, this frame (fast path)
  static constexpr size_t kMaxModelSpans = size_t{1} << 21;  // 12 MB of kept rows
  std::vector<Box> cover_boxes_;  // per candidate and camera: the pixels its Cover writes
  std::vector<int32_t> covered_;  // the candidates (indices) covered now, once per Cover(+1)
  std::vector<int32_t> index_of_;  // per candidate cell: its index among this frame's candidates, else -1
  // Fast path, across frames: each candidate's ModelRows (cameras in order) from
  // model_of_[candidate cell] (-1: not kept yet), their rows in model_spans_. They depend on the
  // options below and the column table's revision alone; kept until one of those changes or
  // model_spans_ outgrows kMaxModelSpans (then all are dropped at the start of a frame).
  std::vector<int32_t> model_of_;
  std::vector<ModelRows> model_rows_;
  std::vector<RowSpan> model_spans_;
  struct ModelKey {
    double radius_m = -1, ground_band = -1;
    bool ground = false;
    int max_rows = -1;
    uint64_t revision = 0;
    bool operator==(const ModelKey&) const = default;
  } model_key_;
  std::vector<std::vector<RowSpan>> arenas_;  // one per worker: rows being worked out
  std::vector<int64_t> missing_;              // this frame's candidates whose ModelRows are not kept
  std::vector<ModelRows> missing_rows_;       // theirs, per camera
  std::vector<uint8_t> missing_arena_;        // the arena holding their rows
  struct CoverRows {
    uint32_t first = 0, rows = 0;
    bool known = false;
    Box box;  // of those rows
  };
  std::vector<CoverRows> cover_rows_;  // per candidate (index) and camera
  std::vector<RowSpan> cover_spans_;
  // FastGain, in one camera: the covered candidates whose boxes meet the term's, each with its
  // Cover's box and rows there (rows in order, one per image row but where a span missed the image).
  struct Met {
    Box box;
    const RowSpan* first;
    const RowSpan* end;
  };
  std::vector<Met> met_;
  std::vector<std::pair<int, int>> edges_;  // CountUncovered: (x, +1 or -1) where a span starts or ends
  bool fast_cover_ = false;  // Cover keeps its rows (the fast path); the reference works them out each time
};

}  // namespace occmap
