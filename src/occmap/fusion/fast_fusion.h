// FastFusion: the paper's image-based AND (k = 0, every camera active) with change detection
// fused in, for speed. Same result as
//   DetectChangesGray(frame_n, background_n, T, change_n) for every camera, then
//   Fusion(lut).Fuse(changes, all active, {kImageBased, k = 0}, map)
// bit for bit, tri-state included (tests), without ever writing a byte change mask.
//
// Two methods over the same views of a cell: runs of consecutive pixels of one image row that
// view it (length <= 64; WILDTRACK averages 4.3 pixels per run) and the coverage-fix pairs.
//
// Cell probes (kCellProbe, the default of Fuse / FuseChanges). Equation 5 is an AND: a cell is
// free as soon as ONE of its pixels is unchanged, so most cells need one test. Per cell a
// primary probe: the run of the camera with the most pixels on it, in the row with the most
// trailing zero bits (neighbouring cells then share image rows and cache lines), its first 56
// pixels (a longer run's tail is the cell's first secondary run). The primary table is sorted
// in image order and grouped by image row: per row, the unchanged bits of the words the probes
// span (the row kernel below); a frame starts from every seen cell free, and only the probes
// whose first pixel is changed are tested (an unchanged first pixel frees the cell; found by
// bit scans of the changed words against a bitmap of the probes' first pixels), each by one
// bit test (an
// unaligned 64-bit window of the bits at the probe's first byte, a bit-field extract), writing
// // kFree or kOccupied into the map. The row's bits stay in a bitmap of pass 1 (1 bit per
// pixel, only the probed spans written). Pass 2, once every task's pass 1 is done: cells whose
// primary run is all changed try their secondary runs (cell-major CSR, in primary order: the
// longest run of each other camera first, then the rest) until one is free; the first of them
// is, wherever one exists, a run that pass 1 turned into bits (on WILDTRACK 93 % of the cells),
// so it costs one bit test in the bitmap (in cache) instead of two image reads from memory.
// With FuseTolerant's bits (every pixel's, from pass 0) a task resolves its own failures right
// after its pass 1, without the barrier.
// Threads take contiguous ranges of the primary table: each cell is written by one thread, no
// per-thread map, no reduction. Unseen cells are never written by the probes and stay kUnseen.
// On WILDTRACK the 691 200 primary probes touch 3 627 of the 7 560 image rows.
// When more than 15 % of the probes fail (a lighting change, a covered lens: the worst case),
// the tasks stop after a sample and the frame is handed to row streaming, so the worst case
// costs about what row streaming costs.
//
// Row streaming (kRowStreaming, the previous default). Work items are the rows (of all
// cameras) that have runs or pairs, split over the pool, each thread with its own byte map.
// For a row, the thread computes a bit mask of the UNCHANGED pixels (|I - B| <= T), 64 pixels
// per 64-bit word; a run frees its cell when any of its bits is set; the per-thread maps are
// AND-reduced into the tri-state map with the per-cell view counts.
//
// Kernels: the row kernel (AVX-512BW: two loads, a saturated difference pair and one compare
// per 64 pixels) and the probe of one run (masked loads), from the process's kernel set
// (util/simd.h: AVX-512BW, AVX2 or portable, OCCMAP_KERNELS forces one); ForceKernelForTesting
// selects one. No
// allocation per frame once the buffers are sized for a thread count; the pool's task
// functors are built once.
//
//   FastFusion fast(lut);
//   fast.Fuse(frames, backgrounds, /*threshold=*/30, ctx, map);   // k = 0, all cameras
//   fast.FuseChanges(changes, ctx, map);     // over a global change buffer (non-zero = changed)
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "occmap/fusion/occupancy_map.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/util/image.h"
#include "occmap/util/thread_pool.h"

namespace occmap {

// Every pixel's change after the tolerance, as bits (FastFusion::FuseTolerant): bit x % 64 of
// words[camera_word[n] + row_words[n] * y + x / 64] is 1 when camera n's pixel (x, y) is
// UNCHANGED (no pixel of the tolerance window around it changed). Bits past a row's width are 0.
struct ChangeBits {
  std::vector<uint64_t> words;
  std::vector<size_t> row_words, camera_word;
  bool Changed(int camera, int x, int y) const {
    const uint64_t word = words[camera_word[static_cast<size_t>(camera)] +
                                row_words[static_cast<size_t>(camera)] * static_cast<size_t>(y) +
                                static_cast<size_t>(x) / 64];
    return ((word >> (static_cast<unsigned>(x) % 64)) & 1u) == 0;
  }
};

class FastFusion {
 public:
  // One run of pixels of a row mapping to the same cell.
  struct Run {
    uint32_t cell;
    uint16_t column;  // first pixel
    uint16_t length;  // 1..64
  };
  // One coverage-fix pair, within its row. (Grouping a pixel's pairs with consecutive cells
  // was tried: on WILDTRACK's 1.12 M pairs no two group, each added cell has its own pixel.)
  struct Pair {
    uint32_t cell;
    uint32_t column;
  };
  // One run of pixels of one camera's row that view the same cell, for the cell-major probes:
  // pixels (column .. column + length - 1, row) of camera `camera`; length 1..64 (0 = none).
  struct Probe {
    uint16_t column;
    uint16_t row;
    uint8_t camera;
    uint8_t length;
    uint16_t unused = 0;
  };
  // A cell's first probe, within its RowGroup; the table is sorted by (camera, row, column).
  // Stored as the probe loop uses it: with o = column - 64 word_begin (the run's first pixel
  // from the group's first word), the byte o / 8 of the group's bits where its 64-bit window
  // starts, and the bit-field extract control (o % 8) | length << 8 (length 1..56; a longer
  // run's tail is the cell's first secondary run). `cell`: the cell (row-major map index).
  struct PrimaryProbe {
    uint32_t cell;
    uint16_t byte;
    uint16_t extract;
  };
  // The primary probes of one image row: [probes_begin, next group's probes_begin), covering
  // the 64-pixel words [word_begin, word_end) of the row; word_probes_[word_probes_begin + w]
  // (w = 0 .. word_end - word_begin) is the group's first probe (from probes_begin) whose first
  // pixel lies in the span's word w or later.
  struct RowGroup {
    uint32_t probes_begin;
    uint16_t camera;
    uint16_t row;
    uint16_t word_begin;
    uint16_t word_end;
    uint32_t word_probes_begin;
  };
  // A failed primary probe: its index in the primary table and its cell.
  struct Fail {
    uint32_t probe;
    uint32_t cell;
  };
  // FailJob's first_bits entry of a cell without a first secondary run in pass 1's bits.
  static constexpr uint32_t kNoFirstBits = ~uint32_t{0};
  enum class Method {
    kCellProbe,     // cell-major, early exit (the default)
    kRowStreaming,  // row-major over every pixel, per-thread maps and a reduction
  };

  // Copies what it needs from lut (which need not outlive this object). Image widths must be
  // < 65536 (a CHECK).
  explicit FastFusion(const GroundLut& lut);
  FastFusion(const FastFusion&) = delete;
  FastFusion& operator=(const FastFusion&) = delete;

  // frames[n], backgrounds[n]: camera n's grey image and background, at the tables' image
  // size (any stride). threshold 0..255 (CHECK). `map` is reset to the grid when needed; every
  // cell is written.
  void Fuse(std::span<const ImageView<const uint8_t>> frames, std::span<const ImageView<const uint8_t>> backgrounds,
            int threshold, Context& ctx, OccupancyMap& map);
  // Tests and benchmarks: the same with a given method.
  void FuseWith(Method method, std::span<const ImageView<const uint8_t>> frames,
                std::span<const ImageView<const uint8_t>> backgrounds, int threshold, Context& ctx, OccupancyMap& map);
  void FuseChangesWith(Method method, std::span<const uint8_t> changes, Context& ctx, OccupancyMap& map);
  // The same fusion over an existing global change buffer (GroundLut pixel ids; non-zero =
  // changed), like Fusion::Fuse with image-based, k = 0, all active.
  void FuseChanges(std::span<const uint8_t> changes, Context& ctx, OccupancyMap& map);

  // Fuse with the change tolerance folded in: the same map as DetectChangesGray of every
  // camera, DilateChanges by tolerance_px (1..kMaxFusedTolerancePx), then FuseChanges, bit for
  // bit (tests), without writing a byte change mask. Every pixel's unchanged bit is computed,
  // eroded by the (2r+1)^2 square (clipped to the image, as the dilation), and left in `bits`
  // for what needs single pixels' changes after the fusion (the elevated check); then the
  // cell probes test those bits, pass 2 included (no image reads).
  void FuseTolerant(std::span<const ImageView<const uint8_t>> frames,
                    std::span<const ImageView<const uint8_t>> backgrounds, int threshold, int tolerance_px,
                    Context& ctx, OccupancyMap& map, ChangeBits& bits);
  static constexpr int kMaxFusedTolerancePx = 8;

  // What the last Fuse / FuseChanges call did.
  struct FrameStats {
    int64_t primary_probed = 0;    // primary probes decided (cell probes)
    int64_t primary_tested = 0;    // of which tested (their first pixel changed; the rest are free)
    int64_t primary_failed = 0;    // of which all changed
    int64_t secondary_probed = 0;  // secondary probes tested
    int64_t secondary_bit_tests = 0;  // of which in pass 1's bits (the cell's first secondary run)
    bool streamed = false;         // row streaming did the frame (asked for, or the hand-over)
  };
  const FrameStats& last_frame_stats() const { return stats_; }

  int num_cameras() const { return static_cast<int>(sizes_.size()); }
  int64_t num_runs() const { return static_cast<int64_t>(runs_.size()); }
  int64_t num_pairs() const { return static_cast<int64_t>(pairs_.size()); }
  int64_t mapped_pixels() const { return mapped_pixels_; }  // pixels in runs (L1 entries not the sentinel)
  int64_t num_primary_probes() const { return row_groups_.empty() ? 0 : row_groups_.back().probes_begin; }
  int64_t num_secondary_probes() const { return static_cast<int64_t>(secondary_.size()); }
  int64_t num_probe_rows() const { return static_cast<int64_t>(row_groups_.size()) - 1; }  // image rows probed
  // Bytes of all tables (both methods), not the per-thread buffers.
  int64_t MemoryBytes() const;
  // Row streaming's tables (runs, pairs, row index, view counts), all read every frame.
  int64_t StreamingTableBytes() const;
  // The cell probes' tables (primary, row groups, secondary CSR, first bits) and buffers (bitmap, the base map, word index).
  int64_t ProbeTableBytes() const;
  // Bytes read per frame by row streaming from its tables (StreamingTableBytes).
  int64_t TableBytesPerFrame() const;
  // Bytes read per frame by the cell probes' first pass: the primary table and row groups and
  // the image words (frame and background) of the probed rows' spans; failures read more.
  int64_t ProbeBytesPerFrame() const;
  // Which kernel the dispatch picked: "avx512bw", "avx2" or "portable".
  static const char* KernelName();
  // Tests: selects a kernel set ("portable", "avx2", "avx512bw", or "best" = the dispatch's
  // choice) for the process (ForceKernelsForTesting, util/simd.h); false when this CPU or
  // build lacks it. Not thread-safe: call with no fusion running.
  static bool ForceKernelForTesting(std::string_view name);
  // Tests: the fraction of failed primary probes above which the cell-probe method hands the
  // frame to row streaming (default 0.15; 0 = as soon as one probe fails, > 1 = never), and the
  // probes a task tests before it may stop early (default 4096).
  void SetStreamingFallbackForTesting(double fraction, uint32_t sample = 4096) {
    streaming_fallback_ = fraction;
    fallback_sample_ = sample;
  }

 private:
  struct WorkRow {
    uint16_t camera;
    uint16_t row;
    uint32_t runs_begin, runs_end;
    uint32_t pairs_begin, pairs_end;
  };
  enum class Input { kImages, kChanges, kBits };
  void ErodeTask(int task);

  void BuildCellTables(const GroundLut& lut);
  void ExecuteCells(Context& ctx, OccupancyMap& map);
  void CellTask(int task);
  void ResolveTask(size_t task);
  void BuildFirstBits();
  uint32_t ProbeRows(uint32_t begin, uint32_t end, Fail* fails, int64_t& num_fails, int64_t& tested, bool may_stop);
  void Prepare(Context& ctx, OccupancyMap& map);
  void Execute(Context& ctx, OccupancyMap& map);
  void RunTask(int task, int thread);
  void ReduceTask(int task);

  FloorGrid grid_;
  std::vector<ImageSize> sizes_;
  std::vector<uint32_t> pixel_offsets_;
  std::vector<Run> runs_;
  std::vector<Pair> pairs_;
  std::vector<WorkRow> rows_;
  std::vector<uint8_t> view_count_;  // per cell, cameras that see it
  // The map a frame of cell probes starts from: kFree for every seen cell, kUnseen elsewhere.
  std::vector<uint8_t> base_states_;
  std::vector<uint16_t> word_probes_;          // RowGroup::word_probes_begin
  std::vector<uint64_t> starts_;               // the same index: the probes' first pixels, a bit each
  std::vector<uint8_t> shared_starts_;         // per group: 1 = two probes start at one pixel
  std::vector<PrimaryProbe> primary_;          // per seen cell, in image order
  std::vector<RowGroup> row_groups_;           // + an end marker
  std::vector<uint32_t> secondary_offsets_;    // per primary probe + 1
  std::vector<Probe> secondary_;
  // Pass 1's unchanged bits, kept for pass 2: per camera, rows of bitmap_row_words_ words
  // (ChangeBits' layout). bits_base_: this frame's, bitmap_ or FuseTolerant's ChangeBits.
  std::vector<uint64_t> bitmap_;
  uint64_t* bits_base_ = nullptr;
  // FuseTolerant's per-frame state: the tolerance, the horizontally eroded rows, the tasks.
  int tolerance_px_ = 0;
  std::vector<std::vector<uint64_t>> erode_rows_;  // [task] a row of U, then its eroded rows
  int erode_tasks_ = 0;
  std::function<void(int, int)> erode_fn_;
  std::vector<size_t> bitmap_row_words_, bitmap_camera_word_;
  std::vector<uint32_t> first_bits_;  // per primary probe: its first secondary run in bitmap_, or kNoFirstBits
  std::vector<int> widths_;
  int max_width_ = 0;
  int64_t mapped_pixels_ = 0;

  // Per-frame state (buffers sized once per thread count).
  std::vector<std::vector<uint8_t>> partial_;   // [thread][cell] 1 = still occupied
  std::vector<std::vector<uint64_t>> bits_;     // [thread] unchanged bits of one row
  std::vector<uint8_t> thread_used_;            // [thread] wrote its partial this frame
  std::function<void(int, int)> task_fn_;       // built once: calls RunTask / ReduceTask
  std::function<void(int, int)> cell_task_fn_;  // built once: calls CellTask
  std::vector<Fail> fails_;                  // failed primary probes, task t's from its first probe
  std::vector<int64_t> task_fails_;              // [task] failed probes
  std::vector<uint8_t> task_deferred_;           // [task] 1 = stopped early, rows and fails left
  std::vector<uint32_t> task_stop_;              // [task] first row group not probed
  std::vector<int64_t> task_probed_;             // [task] primary probes passed (tested or skipped)
  std::vector<int64_t> task_tested_;             // [task] of which tested (their first pixel changed)
  std::vector<int64_t> task_secondary_;          // [task] secondary probes tested
  std::vector<int64_t> task_bit_tests_;          // [task] of which in pass 1's bits
  FrameStats stats_;
  std::vector<uint32_t> task_groups_;            // [task + 1] first row group of each task
  enum class Phase { kProbe, kFinish, kResolve };
  Phase phase_ = Phase::kProbe;
  double streaming_fallback_;
  uint32_t fallback_sample_ = 4096;
  std::vector<const uint8_t*> probe_frame_, probe_background_;
  std::vector<ptrdiff_t> probe_frame_stride_, probe_background_stride_;
  int num_tasks_ = 0;
  bool reducing_ = false;
  Input input_ = Input::kImages;
  std::span<const ImageView<const uint8_t>> frames_;
  std::span<const ImageView<const uint8_t>> backgrounds_;
  std::span<const uint8_t> changes_;
  uint8_t threshold_ = 0;
  CellState* states_ = nullptr;
};

}  // namespace occmap
