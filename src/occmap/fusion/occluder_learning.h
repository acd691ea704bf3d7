// OccluderLearner: static occluders learned on site, per camera and candidate position (the
// column table's, lut/column_lut.h), where the site gives no `statics:` for them.
//
// Evidence, per frame set and candidate k, from the column band's changed fraction f_c of every
// camera c that tests k (as ColumnFusion: seen, no given static hides it, band mostly on the image):
//   hidden (c, k): f_c <= max_changed (c's pixels there did not change) while the fused result
//                  says a person stands at k: either the views' explanation placed a person at k (or next to it),
//                  or at least min_others other cameras test k and in every one of them the
//                  band's changes that no explained person covers fill min_changed of it (the
//                  column test without c, on what the people found do not explain: a ghost, the
//                  meeting of the shadows of people found elsewhere, is explained and says nothing);
//   seen (c, k):   c and at least min_others others, every other camera that tests k, see k
//                  changed (c does see people at k).
// Pooled: the same episodes are also counted on the 4 x 4 pixel blocks the view's band covers,
// with the nearest depth seen hidden and the farthest seen changed there; a view is also blocked
// when half of its band lies in blocks that hide its depth. Per view alone a pillar's shadow
// learns slowly (a person crosses a given 10 cm position rarely; 30 views in the plaza's 60 s);
// a pillar's pixels gather episodes from every position behind it.
// A camera a learned block silences still gathers evidence (a block can be unlearned), and
// cameras learned blocked at k are left out of the others' agreement.
// Each is counted at most once per episode_frames for a view (a person standing behind a
// pillar for a minute is one episode; the evidence must come from many times, so from many
// people); a view is blocked once it has at least min_episodes hidden episodes and at most
// max_contrary of its episodes are seen ones. Why per candidate and not per pixel and depth:
// the decision learned is the column table's own (ColumnView::blocked, which the column fusion
// and the views' explanation read, as they read the given statics'), the evidence is the very
// count the fusion reads, and the state is small (cameras x candidates counters).
// A person is not learned as an occluder: a person in front of another is changed in c (seen,
// not hidden), and a ghost (other cameras' shadows meeting where c rightly sees floor) moves
// with the crowd, while c sees real people cross the same cells (seen episodes).
//
//   OccluderLearner learner(columns, site.people.column, site.people.occluders);
//   learner.Observe(counts, active, frame_index, ctx);   // per frame set; blocks as learned
//   OCCMAP_RETURN_IF_ERROR(learner.Save(path));
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "occmap/fusion/column_fusion.h"
#include "occmap/fusion/view_explainer.h"
#include "occmap/lut/column_lut.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"
#include "occmap/util/yaml_util.h"

namespace occmap {

struct OccluderLearningOptions {
  bool learn = false;
  double max_changed = 0.1;    // the hidden camera's band fraction at most this
  int min_others = 2;          // other cameras that must agree a person stands there
  int episode_frames = 20;     // evidence counted at most once per this many frames, per view
  int min_episodes = 6;        // hidden episodes a block needs
  double max_contrary = 0.2;   // the share of a view's episodes that may be seen ones
  Status Validate() const;
};

// The site's `people: {occluders: {learn: true, ...}}` (keys as the struct's); errors name the line.
Status ParseOccluderLearningOptions(const YamlField& section, OccluderLearningOptions& options);

class OccluderLearner {
 public:
  // columns: the table whose learned blocks this sets (ColumnLut::SetLearnedBlocked).
  OccluderLearner(ColumnLut& columns, const ColumnFusionOptions& column, const OccluderLearningOptions& options);

  // One frame set's row sums (those of inactive cameras are not read); frame_index increases.
  // Blocks and unblocks views as the evidence decides (on the calling thread; the column
  // fusion's plan follows ColumnLut::revision()). Returns whether any view changed.
  // changes: the masks counts were built from; people: the views' explanation of this set (empty
  // without one: then only the others' changes are asked).
  bool Observe(std::span<const ImageView<const uint8_t>> changes, std::span<const ChangeRowSums> counts,
               const std::vector<bool>& active, std::span<const ExplainedPerson> people, int64_t frame_index,
               Context& ctx);

  int64_t frames_observed() const { return frames_; }
  int64_t blocked_views() const;
  // The frames observed when the set of learned blocks last changed (0: never), and when the
  // count of blocks first reached 90 % of today's (how long learning takes).
  int64_t settled_after_frames() const { return settled_after_; }
  int64_t most_after_frames() const;

  // A text file (docs/formats.md, "learned occluders"): the table's fingerprint and every
  // view's episodes. Load: kNotFound when missing, kDataLoss naming the line when malformed,
  // kDataLoss "stale" (and *stale set) for another table; on success the blocks are applied.
  Status Save(const std::filesystem::path& path) const;
  Status Load(const std::filesystem::path& path, bool* stale = nullptr);

  // The table's geometry (not its blocks): files are for the table they were learned on.
  static uint64_t Fingerprint(const ColumnLut& columns);

 private:
  struct View {
    uint16_t hidden = 0, seen = 0;      // episodes
    int32_t last_hidden = INT32_MIN / 2;  // frame set of the last counted episode (this run's)
    int32_t last_seen = INT32_MIN / 2;
  };
  // The evidence pooled over the cameras' pixels (4 x 4 blocks): a pillar's pixels gather
  // hidden episodes from every position behind it, and hide what stands as far as the nearest
  // person hidden there (depth: the inverse of the foot's image scale).
  struct Block {
    uint16_t hidden = 0, seen = 0;
    int32_t last_hidden = INT32_MIN / 2, last_seen = INT32_MIN / 2;
    float near_hidden = 3.4e38f;  // the nearest depth seen hidden
    float far_seen = 0;           // the farthest depth seen changed
  };
  bool Blocks(const View& v) const;
  bool BlockHides(const Block& b, float depth) const;
  template <typename Fn>
  void ForBandBlocks(int camera, int64_t candidate, Fn&& fn) const;
  void Pool(int32_t frame);
  bool Apply();  // the table's learned blocks as the views decide

  ColumnLut& columns_;
  ColumnFusionOptions column_;
  OccluderLearningOptions options_;
  std::vector<View> views_;  // [camera * candidates + candidate]
  std::vector<std::vector<Block>> blocks_;  // per camera, row-major
  std::vector<uint8_t> events_;  // this frame's evidence per view
  int64_t frames_ = 0, settled_after_ = 0;
  std::vector<std::pair<int64_t, int64_t>> growth_;  // (frames observed, blocked views) at each change
  // Per frame and camera: the changes no explained person covers, and their row sums.
  std::vector<Image<uint8_t>> unexplained_;
  std::vector<ChangeRowSums> unexplained_counts_;
  std::vector<uint8_t> person_at_;  // per candidate: an explained person stands there
};

}  // namespace occmap
