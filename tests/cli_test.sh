#!/usr/bin/env bash
# End-to-end checks of the occmap program: exit codes, messages, outputs, the table cache.
# Usage: cli_test.sh OCCMAP_BINARY SOURCE_DIR
set -uo pipefail
occmap=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
passed=0

check() {  # check NAME EXPECTED_EXIT PATTERN -- command...
  local name=$1 want=$2 pattern=$3
  shift 4
  local out
  out=$("$@" 2>&1)
  local got=$?
  if [ "$got" != "$want" ] || ! grep -qE -- "$pattern" <<<"$out"; then
    echo "FAIL $name: exit $got (want $want), output:"
    echo "$out" | head -20
    echo "(wanted a line matching: $pattern)"
    failures=$((failures + 1))
  else
    passed=$((passed + 1))
  fi
}

check version 0 '^0\.1\.0' -- "$occmap" --version
check no_subcommand 2 'subcommand' -- "$occmap"
check mistyped_command 2 "^occmap: error: unknown command 'runn' \(did you mean 'run'\?\); \`occmap --help\` lists them" -- "$occmap" runn site.yaml
check mistyped_command_after_options 2 "unknown command 'sevre' \(did you mean 'serve'\?\)" -- "$occmap" --threads 2 sevre site.yaml
check command_prefix 2 "unknown command 'cal' \(did you mean 'calibrate'\?\)" -- "$occmap" cal
check unknown_command 2 "^occmap: error: unknown command 'xyzzy'; " -- "$occmap" xyzzy
check missing_site_argument 2 'site is required' -- "$occmap" lut
check unknown_option 2 'unknown|not expected|Extras' -- "$occmap" lut x.yaml --bogus
check missing_site 2 "^occmap: error: file not found: '$work/none.yaml'" -- "$occmap" lut "$work/none.yaml"

cat >"$work/bad.yaml" <<'YAML'
floor:
  origin_m: [0, 0]
  size_m: [4, 3]
  cell_size_m: -1
cameras: []
YAML
check bad_site 2 "bad.yaml:4: floor.cell_size_m: expected a positive number, found -1" -- "$occmap" check "$work/bad.yaml"

cat >"$work/homography.yaml" <<'YAML'
name: top-down
floor: {origin_m: [0, 0], size_m: [6.4, 4.8], cell_size_m: 0.1}
cameras:
  - id: top
    calibration:
      format: homography
      unit: cm
      image_size: [640, 480]
      floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]
YAML
check homography_site 0 '^top +640x480' -- "$occmap" lut "$work/homography.yaml" --no-cache --out "$work/h"
check homography_plane 2 'only knows the floor' -- "$occmap" lut "$work/homography.yaml" --plane-height-m 1 --no-cache --out "$work/h"
check check_command 0 "valid site 'top-down' with 1 cameras" -- "$occmap" check "$work/homography.yaml"

check demo 0 'look at .*mosaic.mp4' -- "$occmap" demo --out "$work/demo" --frames 20
for f in mosaic.mp4 mosaic.png summary.json run/detections.jsonl run/tracks.jsonl dataset/site.yaml; do
  if [ ! -s "$work/demo/$f" ]; then echo "FAIL demo output $f missing"; failures=$((failures + 1)); fi
done
check demo_summary_keys 0 '^ok$' -- python3 -c "
import json; s = json.load(open('$work/demo/summary.json'))
assert all(isinstance(s[k], (int, float)) for k in ('moda', 'modp', 'precision', 'recall', 'mota', 'idf1', 'frames_per_second')); print('ok')"

check synth_clemson 0 'run it with: occmap run' -- "$occmap" synth --scene clemson --frames 6 --scale 0.5 --out "$work/clemson"
check run_clemson 0 'wrote .*summary.json' -- "$occmap" run "$work/clemson/site.yaml" --out "$work/clemson-run" --occupancy-pngs --no-cache
# A file-size limit (ulimit -f, RLIMIT_FSIZE: writes beyond it fail with EFBIG, as on a full
# disk; occmap ignores SIGXFSZ): 100 KiB holds the backgrounds (~42 KB) and summary.json but not
# mosaic.png (~360 KB). The run fails naming that file; summary.json says the same.
check run_file_size_limit 1 "mosaic.png': write failed: File too large; summary.json written with this stop_reason" -- \
  bash -c 'ulimit -f 100; exec "$0" "$@"' "$occmap" run "$work/clemson/site.yaml" --out "$work/fsize-run" --no-video --no-cache
check run_file_size_limit_summary 0 '^ok$' -- python3 -c "
import json, os; s = json.load(open('$work/fsize-run/summary.json'))
assert 'mosaic.png' in s['stop_reason'] and 'File too large' in s['stop_reason'], s['stop_reason']
assert s['frames'] == 6, s['frames']
left = [f for f in os.listdir('$work/fsize-run') if f.startswith('.tmp-') or f == 'mosaic.png']
assert not left, left
print('ok')"
check eval_clemson 0 'MODA' -- "$occmap" eval "$work/clemson" "$work/clemson-run"
check eval_json 0 '"detection"' -- "$occmap" eval "$work/clemson" "$work/clemson-run" --json
check eval_missing_run 2 'detections.jsonl|nothing to evaluate|not found' -- "$occmap" eval "$work/clemson" "$work/nowhere"
# Ground truth from a benchmark's annotation folder (WILDTRACK layout: 8-digit file names, one
# file per image by default): what it reads, how it maps frames, and its errors.
mkdir -p "$work/bench/annotations_positions"
echo '[{"personID": 1, "positionID": 1000, "views": []}]' >"$work/bench/annotations_positions/00000000.json"
echo '[]' >"$work/bench/annotations_positions/00000005.json"
check eval_annotations 0 'ground truth: wildtrack annotations, 2 files \(0\.\.5\); file = 0 \+ 5 x run frame' -- \
  "$occmap" eval "$work/bench" "$work/clemson-run"
check eval_annotations_json 0 '"annotation_file": 5' -- "$occmap" eval "$work/bench/annotations_positions" "$work/clemson-run" --json
check eval_annotations_range 0 'evaluated: 2 files, 1 people, numbers 0\.\.5 \(the range given\)' -- \
  "$occmap" eval "$work/bench" "$work/clemson-run" --annotation-range 0:5 --frame-step 1/2 --format wildtrack
check eval_annotations_no_frames 2 'expected annotated frames among the run.s frames 0\.\.5' -- \
  "$occmap" eval "$work/bench" "$work/clemson-run" --first-frame 100
check eval_bad_format 2 'format' -- "$occmap" eval "$work/bench" "$work/clemson-run" --format pets
check eval_bad_frame_step 2 "^occmap: error: --frame-step: expected a whole number or a fraction P/Q \(5, 1/6\) of whole numbers 1\.\.1000000, found '1/0'" -- \
  "$occmap" eval "$work/bench" "$work/clemson-run" --frame-step 1/0
check eval_mapping_on_synth 2 'expected a benchmark.s annotation folder, found .*ground_truth.jsonl' -- \
  "$occmap" eval "$work/clemson" "$work/clemson-run" --frame-step 1
check eval_no_ground_truth 2 'no ground truth: expected ground_truth.jsonl, gt/ground_truth.jsonl, annotations_positions/' -- \
  "$occmap" eval "$work/clemson-run" "$work/clemson-run"
echo '[{"personID": 1, "positionID": 691200}]' >"$work/bench/annotations_positions/00000010.json"
check eval_annotations_out_of_grid 2 "00000010.json: \[0\].positionID: expected an integer 0\.\.691199 \(a cell of WILDTRACK's 480 x 1440 grid\), found 691200" -- \
  "$occmap" eval "$work/bench" "$work/clemson-run"
echo '[{"personID": 1, "positionID": 5}, {"personID": 1, "positionID": 6}]' >"$work/bench/annotations_positions/00000010.json"
check eval_annotations_duplicate 2 '00000010.json: \[1\].personID: expected ids unique within a file, found 1 again \(also \[0\]\)' -- \
  "$occmap" eval "$work/bench" "$work/clemson-run"
echo '[{"personID": 1, "positionID": 5},' >"$work/bench/annotations_positions/00000010.json"
check eval_annotations_malformed 2 '00000010.json: expected a JSON list of people, found invalid JSON' -- \
  "$occmap" eval "$work/bench" "$work/clemson-run"
rm "$work/bench/annotations_positions/00000010.json"
echo '[]' >"$work/bench/annotations_positions/frame10.json"
check eval_annotations_file_name 2 "frame10.json: file name: expected the frame number in digits \(00000005.json\), found 'frame10.json'" -- \
  "$occmap" eval "$work/bench" "$work/clemson-run"
rm "$work/bench/annotations_positions/"*.json
check eval_annotations_empty 2 'expected annotation files named by their frame number \(00000005.json\), found none' -- \
  "$occmap" eval "$work/bench" "$work/clemson-run"

check synth_bad_scene 2 'scene|expected' -- "$occmap" synth --scene atlantis --out "$work/x"
cat >"$work/scene.yaml" <<'YAML'
name: broken
floor: {origin_m: [0, 0]}
YAML
check synth_bad_yaml 2 'scene.yaml' -- "$occmap" synth --scene "$work/scene.yaml" --out "$work/x"

check cache_first 0 'built \(no cache file yet\)' -- "$occmap" lut "$work/homography.yaml" --cache-dir "$work/cache" --out "$work/h"
check cache_second 0 'tables: loaded' -- "$occmap" lut "$work/homography.yaml" --cache-dir "$work/cache" --out "$work/h"
printf 'garbage' | dd of="$work/cache/top-down.lut" bs=1 seek=100 conv=notrunc status=none
check cache_corrupt 0 'rebuilt \(cache file was corrupt\)' -- "$occmap" lut "$work/homography.yaml" --cache-dir "$work/cache" --out "$work/h"
check options_after_subcommand 0 'tables: loaded' -- \
  "$occmap" lut "$work/homography.yaml" --cache-dir "$work/cache" --out "$work/h" --plane-height-m 0 --threads 1
sed -i 's/cell_size_m: 0.1/cell_size_m: 0.2/' "$work/homography.yaml"
check cache_stale_after_edit 0 'rebuilt \(cache file was stale\)' -- "$occmap" lut "$work/homography.yaml" --cache-dir "$work/cache" --out "$work/h"
check json_output 0 '"cells_seen_by_at_least"' -- "$occmap" lut "$work/homography.yaml" --no-cache --out "$work/h" --json
check unwritable_output 1 "cannot create folder" -- "$occmap" lut "$work/homography.yaml" --no-cache --out /proc/occmap-test

check run_without_source 2 "camera top: no source \(give cameras\[0\].source in the site file\)" -- \
  "$occmap" run "$work/homography.yaml" --no-cache --out "$work/r"
cat >>"$work/homography.yaml" <<'YAML'
YAML
sed -i 's|      floor_from_image: \[\[1, 0, 0\], \[0, -1, 479\], \[0, 0, 1\]\]|      floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]\n    source: {images: frames/%06d.png}|' "$work/homography.yaml"
check run_missing_frames 2 "no frame found" -- "$occmap" run "$work/homography.yaml" --no-cache --out "$work/r"
check run_bad_option 2 "frames" -- "$occmap" run "$work/homography.yaml" --frames 0 --no-cache --out "$work/r"

# The plaza as a user runs it: no background given (learned from the busy frames), colour,
# shadows; the change masks scored against the perfect ones.
check synth_plaza 0 'wrote' -- "$occmap" synth --scene plaza --scale 0.25 --duration-s 3 --out "$work/plaza"
check plaza_site_learns 0 'adaptive: true' -- cat "$work/plaza/site.yaml"
check plaza_no_background 1 '^$' -- grep -q 'background:' "$work/plaza/site.yaml"
check run_plaza 0 'background learned: mode of 3 frames' -- "$occmap" run "$work/plaza/site.yaml" --no-cache --no-video --change-pngs --out "$work/pr"
# A cache folder that cannot be written (a file in its place: root ignores modes) is said once
# per entry and the run goes on: the tables, and the six learned (settled) backgrounds.
printf 'not a folder' >"$work/blocked-cache"
check run_cache_blocked 0 "could not write the table cache $work/blocked-cache/plaza.lut: .*; going on without it" -- \
  "$occmap" run "$work/plaza/site.yaml" --cache-dir "$work/blocked-cache" --no-video --out "$work/pb"
check run_cache_blocked_backgrounds 0 '^6$' -- bash -c "\"\$0\" run \"\$1\" --cache-dir \"\$2\" --no-video --out \"\$3\" 2>&1 |
  grep -c 'warning: could not write the background cache .*going on without it'" \
  "$occmap" "$work/plaza/site.yaml" "$work/blocked-cache" "$work/pb2"
check lut_cache_blocked 0 "occmap lut: warning: could not write the table cache $work/blocked-cache/top-down.lut: " -- \
  "$occmap" lut "$work/homography.yaml" --cache-dir "$work/blocked-cache" --out "$work/h"
check plaza_change_pngs 0 '000029.png' -- ls "$work/pr/changes/c1"
check plaza_summary 0 '"shadow_look"' -- cat "$work/pr/summary.json"
check eval_plaza_changes 0 '"shadow_changed_fraction"' -- bash -c "\"$occmap\" eval \"$work/plaza\" \"$work/pr\" >/dev/null && cat \"$work/pr/evaluation.json\""
check bad_backgrounds 2 "backgrounds.learning: expected median, mode, mog2 or knn, found 'gmm'" -- bash -c "sed 's/  adaptive: true/  adaptive: true\n  learning: gmm/' \"$work/plaza/site.yaml\" > \"$work/plaza/bad.yaml\" && \"$occmap\" check \"$work/plaza/bad.yaml\""

datasets="$src/../shared/datasets"
if [ -d "$datasets/wildtrack" ]; then
  check wildtrack_lut 0 '^C7 +1920x1080' -- "$occmap" lut "$src/sites/wildtrack.yaml" --no-cache --out "$work/w"
  check data_root_option 0 'gopro6.3' -- "$occmap" --data-root "$datasets" lut "$src/sites/gopro4.yaml" --no-cache --out "$work/g"
  check run_gopro4 0 'blobs per frame: mean 4.00, max 4' -- "$occmap" run "$src/sites/gopro4.yaml" --no-cache --out "$work/gr"
  check run_gopro4_outputs 0 '"max_per_frame": 4' -- cat "$work/gr/summary.json"
  check bad_data_root 2 "data folder not found" -- "$occmap" --data-root "$work/nowhere" lut "$src/sites/gopro4.yaml" --no-cache
  # The simulator renders WILDTRACK's real trajectories at 10 fps: a run on it scored against the
  # real annotation files (--frame-step 1: run frame k is 10 fps frame k; files 0, 5, 10, 15)
  # counts exactly what its own ground truth counts at those frames.
  check synth_wildtrack 0 'run it with' -- \
    "$occmap" --data-root "$datasets" synth --scene wildtrack --scale 0.5 --frames 16 --no-change-masks --out "$work/ws"
  check run_wildtrack 0 'wrote' -- "$occmap" run "$work/ws/site.yaml" --no-cache --no-video --out "$work/wr"
  check eval_wildtrack_own 0 '"moda"' -- bash -c "\"$occmap\" eval \"$work/ws\" \"$work/wr\" --json > \"$work/own.json\" && cat \"$work/own.json\""
  check eval_wildtrack_annotations 0 '"files_evaluated": 4' -- \
    bash -c "\"$occmap\" eval \"$datasets/wildtrack\" \"$work/wr\" --frame-step 1 --json > \"$work/ann.json\" && cat \"$work/ann.json\""
  check eval_wildtrack_same_counts 0 '^same counts in 4 frames, MODA [-0-9.]+$' -- python3 -c "
import json
own = {f['frame']: f for f in json.load(open('$work/own.json'))['detection']['per_frame']}
ann = json.load(open('$work/ann.json'))['detection']
keys = ('gt', 'detections', 'tp', 'fp', 'fn')
frames = [f['frame'] for f in ann['per_frame']]
assert frames == [0, 5, 10, 15], frames
for f in ann['per_frame']:
    assert f['annotation_file'] == f['frame'] and all(f[k] == own[f['frame']][k] for k in keys), (f, own[f['frame']])
print('same counts in %d frames, MODA %s' % (len(frames), ann['moda']))"
else
  echo "shared datasets not found beside the checkout; dataset CLI checks skipped"
fi

# occmap calibrate: malformed floor-point files are bad input (exit 2) named by file and line.
printf 'u_px,v_px,x_m,y_m\n100,400,0,0\n540,410,4\n' >"$work/pts_missing.csv"
check calibrate_missing_column 2 "pts_missing.csv:3: expected 4 or 5 comma-separated columns \(u_px,v_px,x_m,y_m\[,label\]\), found 3" -- \
  "$occmap" calibrate --points "$work/pts_missing.csv" --image-size 640x480 --out "$work/cal"
printf '100,400,0,0\n540,410,NaN,0\n500,120,4,6\n130,100,0,6\n' >"$work/pts_nan.csv"
check calibrate_nan 2 "pts_nan.csv:2: x_m \(column 3\): expected a finite number, found 'NaN'" -- \
  "$occmap" calibrate --points "$work/pts_nan.csv" --image-size 640x480 --out "$work/cal"
printf '# three\n100,400,0,0\n540,410,4,0\n500,120,4,6\n' >"$work/pts_few.csv"
check calibrate_few 2 "pts_few.csv: expected at least 4 floor points \(pixel and floor position\), found 3" -- \
  "$occmap" calibrate --points "$work/pts_few.csv" --image-size 640x480 --out "$work/cal"
printf '100,400,0,0\n200,380,1,1\n300,360,2,2\n400,340,3,3\n' >"$work/pts_line.csv"
check calibrate_collinear 2 "pts_line.csv: the floor points lie on one line" -- \
  "$occmap" calibrate --points "$work/pts_line.csv" --image-size 640x480 --out "$work/cal"
printf '100,400,0,0\n200,380,1,0\n300,360,2,0\n130,100,0,6\n' >"$work/pts_three.csv"
check calibrate_three_on_a_line 2 "pts_three.csv:1: this floor point lies on one line with .*pts_three.csv:2, .*pts_three.csv:3" -- \
  "$occmap" calibrate --points "$work/pts_three.csv" --image-size 640x480 --out "$work/cal"
check calibrate_nothing 2 "give board views" -- "$occmap" calibrate --out "$work/cal"
check calibrate_print_board 0 "the board, 1100x800 px" -- "$occmap" calibrate --print-board "$work/board.png" --square-m 0.03

# A board video read every 15th frame (here the lab, which shows no board: every view rejected).
"$occmap" synth --scene lab --frames 31 --scale 0.25 --video --no-change-masks --out "$work/labv" >/dev/null 2>&1
check calibrate_board_video 2 "board views: 0 of 3 usable, at least 3 needed" -- \
  "$occmap" calibrate --board-video "$work/labv/frames/cam1.mp4" --frame-step 15 --square-m 0.03 --out "$work/cal"
check calibrate_board_video_names 2 "cam1.mp4 frame 30: no 9x6 checkerboard found" -- \
  "$occmap" calibrate --board-video "$work/labv/frames/cam1.mp4" --frame-step 15 --square-m 0.03 --out "$work/cal"

# --loop: the 31-frame videos read again from their start; without --frames a run never ends.
check run_loop 0 "wrote .*summary.json" -- "$occmap" run "$work/labv/site.yaml" --loop --frames 70 --no-cache \
  --out "$work/labv-loop"
check run_loop_frames 0 "^70$" -- python3 -c "import json; print(json.load(open('$work/labv-loop/summary.json'))['frames'])"
check run_loop_needs_frames 2 "--loop: give --frames N too" -- "$occmap" run "$work/labv/site.yaml" --loop --no-cache \
  --out "$work/labv-loop"

# A rendered lab camera: 8 floor points projected through its calibration with 0.5 px noise;
# the camera from them (pinhole with the intrinsics, homography without), written into the
# site, which must still load.
"$occmap" synth --scene lab --frames 1 --scale 0.5 --no-change-masks --out "$work/lab" >/dev/null 2>&1
python3 "$src/tests/project_floor_points.py" "$work/lab/calib/intr_cam1.xml" "$work/lab/calib/extr_cam1.xml" \
  2,1.5 4,1.5 6,1.5 8,1.5 2,5 4,5 6,5 8,5 --noise-px 0.5 --seed 3 >"$work/lab/cam1.csv"
check calibrate_lab_pinhole 0 "^reprojection RMS 0\.[0-9]+ px .*floor RMS 0\.0[0-4][0-9] m" -- \
  "$occmap" calibrate --camera cam1 --intrinsics "$work/lab/calib/intr_cam1.xml" --points "$work/lab/cam1.csv" \
  --image "$work/lab/frames/cam1/000000.png" --out "$work/lab/newcalib" --update-site "$work/lab/site.yaml" \
  --overlay "$work/lab/cam1-overlay.png"
check calibrate_lab_site_updated 0 "intrinsic: newcalib/intr_cam1.xml, extrinsic: newcalib/extr_cam1.xml, unit: m" -- \
  grep -F "calibration:" "$work/lab/site.yaml"
check calibrate_lab_site_loads 0 "valid site 'lab' with 4 cameras" -- "$occmap" check "$work/lab/site.yaml"
check calibrate_lab_backup 0 "intrinsic: calib/intr_cam1.xml" -- grep -F "cam1" "$work/lab/site.yaml.bak"
check calibrate_lab_overlay 0 "PNG image data, 320 x 240" -- file "$work/lab/cam1-overlay.png"
check calibrate_lab_homography 0 "cam1's calibration replaced" -- \
  "$occmap" calibrate --camera cam1 --points "$work/lab/cam1.csv" --image-size 320x240 --out "$work/lab/newcalib" \
  --update-site "$work/lab/site.yaml"
check calibrate_lab_homography_loads 0 "cam1 +homography +320x240" -- "$occmap" check "$work/lab/site.yaml"
check calibrate_lab_json 0 '"rms_reprojection_px"' -- \
  "$occmap" calibrate --camera cam1 --points "$work/lab/cam1.csv" --image-size 320x240 --out "$work/lab/jsoncalib" --json
check calibrate_lab_fit_lens 0 "^lens fitted to the points: focal length [0-9.]+ px, k1 -0\.[0-9]+" -- \
  "$occmap" calibrate --camera cam1 --fit-lens --points "$work/lab/cam1.csv" --image-size 320x240 \
  --out "$work/lab/lenscalib"
check calibrate_fit_lens_with_intrinsics 2 "--fit-lens: needs --points, and neither board views nor --intrinsics" -- \
  "$occmap" calibrate --camera cam1 --fit-lens --intrinsics "$work/lab/calib/intr_cam1.xml" \
  --points "$work/lab/cam1.csv" --out "$work/lab/lenscalib"
# One point's x and y swapped (p6 at (5, 4) instead of (4, 5)): named as the outlier, exit 2, the
# site and its files left as they are; --force writes it.
sed 's/^\([^,]*,[^,]*\),4\.0,5\.0,p6$/\1,5.0,4.0,p6/' "$work/lab/cam1.csv" >"$work/lab/cam1_swapped.csv"
cp "$work/lab/site.yaml" "$work/lab/site.before"
check calibrate_outlier_named 2 "cam1_swapped.csv: not used \(.*site.yaml left as it is\): .*cam1_swapped.csv:7 \(p6\): pixel \([0-9.]+, [0-9.]+\) for floor \(5.000, 4.000\) m is [0-9.]+ px from where the other points put it" -- \
  "$occmap" calibrate --camera cam1 --points "$work/lab/cam1_swapped.csv" --image-size 320x240 \
  --out "$work/lab/outliercalib" --update-site "$work/lab/site.yaml"
check calibrate_outlier_table 2 "cam1_swapped.csv:7 p6 .*  OUTLIER$" -- \
  "$occmap" calibrate --camera cam1 --points "$work/lab/cam1_swapped.csv" --image-size 320x240 --out "$work/lab/outliercalib"
check calibrate_outlier_site_kept 0 "^same$" -- bash -c "cmp '$work/lab/site.yaml' '$work/lab/site.before' && echo same"
check calibrate_outlier_no_files 0 "^none$" -- bash -c "ls '$work/lab/outliercalib' | grep -v calibration_cam1.json || echo none"
check calibrate_outlier_forced 0 "cam1's calibration replaced" -- \
  "$occmap" calibrate --camera cam1 --points "$work/lab/cam1_swapped.csv" --image-size 320x240 \
  --out "$work/lab/outliercalib" --update-site "$work/lab/site.yaml" --force
check calibrate_unknown_camera 2 "no camera 'cam9' \(the site's cameras: cam1, cam2, cam3, cam4\)" -- \
  "$occmap" calibrate --camera cam9 --points "$work/lab/cam1.csv" --image-size 320x240 --out "$work/lab/newcalib" \
  --update-site "$work/lab/site.yaml"
# --out the site's own calib/ folder without --update-site: the files the site names (here the
# synthesised cam1's) are not replaced; --force replaces them.
cp "$work/lab/calib/intr_cam1.xml" "$work/lab/calib/extr_cam1.xml" "$work"/
check calibrate_out_existing_refused 2 "--out [^ ]*/lab/calib: '[^ ]*/lab/calib/intr_cam1\.xml' exists and a site may name it: give --force to replace it, --update-site SITE" -- \
  "$occmap" calibrate --camera cam1 --intrinsics "$work/lab/calib/intr_cam1.xml" --points "$work/lab/cam1.csv" \
  --image-size 320x240 --out "$work/lab/calib"
check calibrate_out_existing_kept 0 "^same$" -- bash -c "cmp '$work/intr_cam1.xml' '$work/lab/calib/intr_cam1.xml' \
  && cmp '$work/extr_cam1.xml' '$work/lab/calib/extr_cam1.xml' && ! ls '$work/lab/calib/calibration_cam1.json' 2>/dev/null && echo same"
check calibrate_out_existing_homography 2 "'[^ ]*/lab/newcalib/homography_cam1\.yaml' exists" -- \
  "$occmap" calibrate --camera cam1 --points "$work/lab/cam1.csv" --image-size 320x240 --out "$work/lab/newcalib"
check calibrate_out_existing_forced 0 "^wrote extrinsic: [^ ]*/lab/calib/extr_cam1\.xml" -- \
  "$occmap" calibrate --camera cam1 --intrinsics "$work/lab/calib/intr_cam1.xml" --points "$work/lab/cam1.csv" \
  --image-size 320x240 --out "$work/lab/calib" --force
# ... and the files it replaced are kept as FILE.bak, byte for byte.
check calibrate_out_existing_kept_as_bak 0 "^same$" -- bash -c "cmp '$work/intr_cam1.xml' '$work/lab/calib/intr_cam1.xml.bak' \
  && cmp '$work/extr_cam1.xml' '$work/lab/calib/extr_cam1.xml.bak' && echo same"
check calibrate_out_existing_said 0 "^kept the file replaced as [^ ]*/lab/calib/extr_cam1\.xml\.bak$" -- \
  "$occmap" calibrate --camera cam1 --intrinsics "$work/lab/calib/intr_cam1.xml" --points "$work/lab/cam1.csv" \
  --image-size 320x240 --out "$work/lab/calib" --force

echo "$passed passed, $failures failed"
[ "$failures" -eq 0 ]
