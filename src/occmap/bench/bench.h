// `occmap bench`: the speed of the on-line step (change detection + fusion, the paper's AND)
// measured four ways on one workload, in one run:
//   (a) paper:     PaperLoop, the paper's image-based pseudo-code with the change test inside
//                  (per pixel: if |I - B| <= T then O[L1[p]] = 0; sentinel cell; coverage pairs);
//   (b) opencv:    what a user would write with OpenCV: cv::absdiff + cv::threshold per camera,
//                  cv::remap of the change mask onto the floor grid (maps = each cell centre
//                  projected into the camera, INTER_NEAREST), cv::bitwise_and over cameras;
//   (c) fast_1:    FastFusion::Fuse on one thread (the cell-probe method: what `occmap run`
//                  calls);
//   (d) fast_all:  the same on all the context's threads;
//   (e) streaming: FastFusion's row-streaming method (every pixel, the previous default) on one
//                  and all threads, at the same frames;
//   (f) worst:     FastFusion::Fuse on one and all threads with EVERY pixel changed (frame =
//                  background XOR 0x80): the cell probes fail and hand over to row streaming;
//   (g)-(i)        the change test alone on one thread: plain, the adaptive model's (shadows),
//                  and the adaptive model's update.
//   (j)-(l)        the people path (fusion/people_options.h: the site's `people:` section with the
//                  defaults `occmap synth --scene wildtrack` writes: detector explain, the scene's
//                  statics as occluders) on the rendered frames, on one and all threads: (j) the
//                  column fusion (ChangeRowSums::Build per camera + ColumnFusion::Fuse), (k) the
//                  views' explanation (ViewExplainer::Explain on (j)'s map), both from the change
//                  masks |I - B| > T of the same frames and backgrounds the floor rows fuse; (l) the
//                  whole path as `occmap run` does it: those change masks (DetectChangesGray per
//                  camera), (j) and (k). PeopleRates, RenderedResult::people.
// Figures: camera pixels per second (all cameras' pixels / median time per frame over the
// repetitions) and ratios; table build time and table bytes.
//
// Workloads. "paper": 6 synthetic pinhole cameras 640x480 on the walls of a 12.8 x 9.6 m room
// onto a 640 x 480 grid of 2 cm (the paper's sizes). "wildtrack": the 7 real WILDTRACK cameras
// (1920x1080, sites/wildtrack.yaml with the data root) onto the dataset's 480 x 1440 grid;
// skipped with a note when the data is absent. "tiny" (tests): 4 cameras 96x72.
// Frames: background uniform random bytes; the frame equals the background but for
// `changed_fraction` (default 10 %) of its pixels, chosen at random, which differ by more than
// T (T = 30); `frames` such frames are cycled through. The wildtrack workload also measures
// (a)-(e) on `rendered_frames` frames rendered by the simulator (RenderWildtrackFrames: real
// trajectories, changes clustered on people), rendered once per run (render time reported apart);
// WorkloadResult::rendered, skipped with a note when the dataset is absent.
//
//   BenchOptions o; o.workload = "all";
//   OCCMAP_ASSIGN_OR_RETURN(std::vector<WorkloadResult> r, RunBench(o, ctx));
//   fmt::print("{}", BenchTable(r));
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "occmap/bench/adaptive_bench.h"
#include "occmap/fusion/people_options.h"
#include "occmap/geometry/camera_model.h"
#include "occmap/lut/column_lut.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/util/image.h"
#include "occmap/util/status.h"
#include "occmap/util/thread_pool.h"

namespace occmap::bench {

struct BenchOptions {
  std::string workload = "all";  // paper, wildtrack, adaptive, all, tiny
  int frames = 4;                // distinct frames cycled through per repetition
  int repetitions = 5;           // the median over these is reported
  double changed_fraction = 0.10;
  int threshold = 30;
  std::filesystem::path wildtrack_site = "sites/wildtrack.yaml";
  std::filesystem::path data_root;  // empty: the site file's data_root
  // End to end over H.264: the lab scene rendered to this many frames of video per camera
  // (in a temporary folder), RunSite (no video outputs) frames/s against a pure decode pass
  // over the same files with the same decoder threads. 0 = not measured (null in the JSON).
  int end_to_end_frames = 0;
  // Frames rendered by the simulator for the wildtrack workload (0 = none).
  int rendered_frames = 4;
  // End to end on the wildtrack workload's own scene: the WILDTRACK scene (real calibrations
  // and trajectories) rendered to this many frames of 1920x1080 H.264 per camera, measured as
  // the lab above (0 = not measured; at least 2 * 10 + 2 for a steady state after the warm-up).
  int wildtrack_end_to_end_frames = 0;
  // The adaptive workload (adaptive_bench.h): its datasets and frames; run by "adaptive", and by
  // "all" when datasets are given.
  AdaptiveBenchOptions adaptive;
  Status Validate() const;
};

// The people path (j)-(l) on one set of frames: camera pixels per second (all cameras' pixels /
// median time per frame set) on one thread and on the context's threads.
struct PeopleRates {
  bool measured = false;
  std::string note;                  // the detector and its settings, or why not measured
  int64_t candidates = 0;            // the column table's candidate grid
  int occluders = 0;                 // the statics the table was built with
  double column_lut_build_seconds = 0;
  int64_t column_lut_bytes = 0;      // ColumnLut::MemoryBytes
  double change_test_1_pps = 0;      // DetectChangesGray into the change masks, 1 thread (the input of (j), (k))
  double column_1_pps = 0, column_all_pps = 0;    // (j) ChangeRowSums::Build + ColumnFusion::Fuse
  double explain_1_pps = 0, explain_all_pps = 0;  // (k) ViewExplainer::Explain
  double path_1_pps = 0, path_all_pps = 0;        // (l) change masks + (j) + (k)
  double occupied_candidates_per_frame = 0;       // (j)'s map
  double people_per_frame = 0;                    // (k)'s people
};

// The same measurements on frames rendered by the simulator (the wildtrack workload: the
// dataset's calibrations and annotated trajectories, people clustered where they walk): a few
// frames spread over the sequence, rendered once per bench run at full size and kept in memory,
// turned grey; the backgrounds are the empty scene's render.
struct RenderedResult {
  bool measured = false;
  std::string note;             // why not measured, or which frames
  int frames = 0;
  double render_seconds = 0;    // scene set-up + static casts + the frames, all cameras
  double changed_fraction = 0;  // pixels with |I - B| > T, over all cameras and frames
  double paper_pps = 0;
  double opencv_pps = 0;
  double fast_1_pps = 0;
  double fast_all_pps = 0;
  double streaming_1_pps = 0;
  double streaming_all_pps = 0;
  double primary_failure_fraction = 0;  // failed primary probes / primary probes
  double primary_tested_fraction = 0;   // primary probes tested (their first pixel changed) / primary probes
  double secondary_probes_per_frame = 0;  // secondary probes tested per frame (1 thread)
  double streamed_frame_fraction = 0;   // frames handed to row streaming (1 thread)
  PeopleRates people;                   // (j)-(l) on the same frames
};

struct WorkloadResult {
  std::string name;
  bool skipped = false;
  std::string note;
  int cameras = 0;
  int64_t camera_pixels = 0;  // all cameras, per frame
  int64_t cells = 0;
  double lut_build_seconds = 0;
  double fast_build_seconds = 0;
  int64_t lut_bytes = 0;   // GroundLut::MemoryBytes
  int64_t fast_bytes = 0;  // FastFusion::MemoryBytes
  int64_t fast_runs = 0;
  int64_t fast_pairs = 0;        // coverage-fix pairs
  int64_t mapped_pixels = 0;   // pixels whose L1 entry is a cell
  std::string kernel;
  int threads = 1;         // FastFusion (d): the context's threads
  int opencv_threads = 1;  // OpenCV's own pool, set to the same count for (b)
  // Camera pixels per second.
  double paper_pps = 0;
  double opencv_pps = 0;
  double fast_1_pps = 0;
  double fast_all_pps = 0;
  double streaming_1_pps = 0;    // (e)
  double streaming_all_pps = 0;
  double worst_1_pps = 0;        // (f) every pixel changed
  double worst_all_pps = 0;
  int64_t fast_probe_table_bytes = 0;      // FastFusion::ProbeTableBytes
  int64_t fast_streaming_table_bytes = 0;  // FastFusion::StreamingTableBytes
  int64_t primary_probes = 0, secondary_probes = 0, probe_rows = 0;
  int64_t probe_bytes_read_per_frame = 0;  // FastFusion::ProbeBytesPerFrame (first pass)
  // Bytes read per frame by row streaming: images + backgrounds + its tables.
  int64_t fast_bytes_read_per_frame = 0;
  double primary_failure_fraction = 0;  // failed primary probes / primary probes, (c)'s frames
  double primary_tested_fraction = 0;   // of the primary probes, those tested, (c)'s frames
  // (g)-(i) the change test alone on one thread, without the fusion: the paper's plain test
  // (DetectChangesGray), the adaptive model's (BackgroundModel::DetectChanges: transfer, chroma
  // and shadow test) and its update (every pixel free), on the same frames (random chroma).
  double plain_change_1_pps = 0, adaptive_change_1_pps = 0, adaptive_update_1_pps = 0;
  RenderedResult rendered;              // wildtrack only
};

struct EndToEndResult {
  bool measured = false;
  std::string scene = "lab";  // lab or wildtrack
  std::string note;
  int64_t frames = 0;
  int cameras = 0;
  int repeats = 0;        // decode and run passes, alternated; the rates are medians
  double run_fps = 0;     // RunSite's steady-state frame sets per second (RunSummary::steady_fps)
  double decode_fps = 0;  // steady-state frame sets per second of the faster pure decoding pass
  double decode_parallel_fps = 0;     // one thread per camera, as RunSite's reader decodes
  double decode_interleaved_fps = 0;  // one thread reading the cameras in turn, frame-threaded decoders
  double run_startup_s = 0;           // RunSite's start-up (sources, backgrounds, tables, first frames)
  double run_overall_fps = 0;         // frames / the whole RunSite call, start-up included
  double run_cpu_ms_per_frame = 0, decode_cpu_ms_per_frame = 0;  // process CPU time per frame set
  // The same over the steady state only (after the warm-up frame sets, as the rates): what
  // occmap's own work costs per frame set is run_steady - decode_steady.
  double run_steady_cpu_ms_per_frame = 0, decode_steady_cpu_ms_per_frame = 0;
  double fuse_s = 0, detect_s = 0, decode_s = 0;  // RunSite's own split
  double blobs_s = 0, track_s = 0, output_s = 0;
  double people_s = 0;                 // RunSite's people stage (column fusion and explanation)
  // RunSummary::latency of the site's own passes (a frame set's arrival, its frames decoded, to
  // its outputs written), medians over the passes, in ms. Over files the reader runs ahead of
  // the stages, so this includes the waits in the run's queues.
  double latency_p50_ms = 0, latency_p95_ms = 0, latency_p99_ms = 0;
  std::string people_detector = "floor";  // the site's: floor (no people: section), column or explain
  // A site with a people detector (the WILDTRACK scene, as `occmap synth` writes it) is also run
  // without it (people.enabled = false: the floor AND and its blobs, the fully fused path),
  // alternated with the passes above on the same files: the figures above are the site's own,
  // these the floor AND's, so that both stand against the same decoding.
  struct FloorPass {
    bool measured = false;
    std::string fusion_path;
    double run_fps = 0, run_overall_fps = 0, run_startup_s = 0;
    double run_cpu_ms_per_frame = 0, run_steady_cpu_ms_per_frame = 0;
    double fuse_s = 0, detect_s = 0, blobs_s = 0, track_s = 0;
  };
  FloorPass floor;
  // occmap's own CPU per frame set (the steady state's, beside the decoders) over the decoding's.
  double OwnCpuVsDecode() const;
  double FloorOwnCpuVsDecode() const;
};

struct BenchResults {
  std::vector<WorkloadResult> workloads;
  EndToEndResult end_to_end;            // the lab scene (4 x 640x480): the paper workload's
  EndToEndResult wildtrack_end_to_end;  // the WILDTRACK scene (7 x 1920x1080): the wildtrack workload's
  std::vector<AdaptiveResult> adaptive;  // the adaptive workload, one per dataset
};

// Runs the workloads named by options.workload (all = paper and wildtrack, and adaptive when it
// has datasets), then the end-to-end
// measurement when asked.
Result<BenchResults> RunBench(const BenchOptions& options, Context& ctx);
// The lab scene, or with wildtrack_dir (the dataset folder) the WILDTRACK scene.
Result<EndToEndResult> MeasureEndToEnd(int frames, Context& ctx, const std::filesystem::path& wildtrack_dir = {});

std::string BenchTable(const BenchResults& results);
// {"machine": ..., "nproc": ..., "workloads": [{name, speedup_vs_opencv, speedup_vs_paper_loop,
// *_pixels_per_second, threads, ...}], "end_to_end_vs_decode": null, "notes": [...]}.
nlohmann::json BenchJson(const BenchResults& results);
std::string MachineName();  // /proc/cpuinfo's model name

// (j)-(l) on frames[f][camera] against backgrounds[camera]: the column table built from
// `cameras` (their masks: the floor AND's notion of seeing), `grid` and `statics` with
// `people`'s settings (its detector must be explain), the change masks |I - B| > threshold.
// repetitions: the median over these is reported (each a pass over every frame).
Result<PeopleRates> MeasurePeople(const std::vector<LutCameraInput>& cameras, const FloorGrid& grid,
                                  double plane_height_m, std::span<const Occluder> statics,
                                  const PeopleOptions& people,
                                  const std::vector<std::vector<ImageView<const uint8_t>>>& frames,
                                  std::span<const ImageView<const uint8_t>> backgrounds, int threshold,
                                  int repetitions, Context& ctx);

// Frames rendered by the simulator's wildtrack scene (sim::MakeWildtrackSceneSpec on
// dataset_dir: the real calibrations and annotated trajectories): `count` frames spread over the
// sequence, every camera at full size, grey (BT.601 luma, rounded), and the empty scene's render
// as the background. sizes: the tables' image sizes (checked). frames[f][n], backgrounds[n].
struct RenderedFrames {
  std::vector<Image<uint8_t>> backgrounds;
  std::vector<std::vector<Image<uint8_t>>> frames;
  std::vector<int64_t> scene_frames;
  std::vector<Occluder> statics;  // the scene's static structures, as `occmap synth` writes them
};
Result<RenderedFrames> RenderWildtrackFrames(const std::filesystem::path& dataset_dir, int count,
                                             const std::vector<ImageSize>& sizes, Context& ctx);

// (a) The paper's image-based loop with the change test inside, all cameras, AND. `occupancy`
// is resized to num_cells + 1 (the sentinel) and gets 1 = occupied (also for unseen cells),
// 0 = free. Unchanged means |I - B| <= T (equation 4; the printed pseudo-code's "< T" differs
// only at |I - B| == T).
void PaperLoop(const GroundLut& lut, std::span<const ImageView<const uint8_t>> frames,
               std::span<const ImageView<const uint8_t>> backgrounds, int threshold,
               std::vector<uint8_t>& occupancy);

// (b) The OpenCV version. Cells a camera does not see (centre behind it or outside its image)
// map to a pixel outside the image, read as 255 (changed): neutral for the AND. Samples one
// pixel per cell and camera, so it may differ from the exact fusion.
class OpenCvFusion {
 public:
  OpenCvFusion(const std::vector<const CameraModel*>& cameras, const FloorGrid& grid, double plane_height_m);
  // out: grid-sized CV_8U (rows = cells_y, cols = cells_x, cell j * cells_x + i), 255 = occupied.
  void Fuse(std::span<const ImageView<const uint8_t>> frames, std::span<const ImageView<const uint8_t>> backgrounds,
            int threshold, cv::Mat& out);

 private:
  std::vector<cv::Mat> map_x_, map_y_;
  cv::Mat diff_, mask_, remapped_;
};

}  // namespace occmap::bench
