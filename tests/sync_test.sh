#!/usr/bin/env bash
# `occmap run --sync timestamp --sync-tolerance-s S` on streams whose timestamps are offset: the
# lab's cameras as MPEG-TS files, camera 2's starting 3 frames late (its first frame carries
# the time of frame 3) and 30 ms off the others. Within the tolerance (50 ms) every frame set
# from frame 3 on pairs camera 2's frame with the others' of the same instant: the detections
# equal those of a run on the aligned files; by index they pair the wrong frames; under a
# 10 ms tolerance camera 2 never joins.
# Usage: sync_test.sh OCCMAP_BINARY SOURCE_DIR   (skipped, exit 0, without the ffmpeg program)
set -uo pipefail
occmap=$1
src=$2
source "$src/tests/test_lib.sh"
tl_require_ffmpeg
tl_init
lab="$work/lab"
tl_synth_lab "$occmap" "$lab" --video --frames 30 --scale 0.5
# Every file encoded alike (lossless, no B-frames: frame k at the same time in each), and
# camera 2 again from its frame 3, its timestamps kept and shifted by 30 ms.
encode() { ffmpeg -loglevel error -i "$lab/frames/cam$1.mp4" "${@:3}" -c:v libx264 -qp 0 -bf 0 "$lab/frames/$2.ts"; }
for n in 1 2 3 4; do encode $n cam$n || { fail "ffmpeg"; exit 1; }; done
encode 2 late2 -vf trim=start_frame=3 -output_ts_offset 0.03 || { fail "ffmpeg trim"; exit 1; }
sed 's#frames/cam\([0-9]\).mp4#frames/cam\1.ts#' "$lab/site.yaml" >"$lab/aligned.yaml"
sed 's#frames/cam2.ts#frames/late2.ts#' "$lab/aligned.yaml" >"$lab/late.yaml"

run() {  # run NAME SITE OPTIONS...: a run into $work/NAME
  local name=$1 site=$2
  shift 2
  "$occmap" run "$lab/$site" --out "$work/$name" --no-cache --no-video --no-wall-clock "$@" >"$work/$name.log" 2>&1 ||
    { fail "run $name: $(tail -1 "$work/$name.log")"; }
}
run aligned aligned.yaml --sync timestamp
run within late.yaml --sync timestamp --sync-tolerance-s 0.05
run outside late.yaml --sync timestamp --sync-tolerance-s 0.01
run index late.yaml

"$python" - "$work" <<'PY' || fail "timestamp synchronisation"
import json, sys
work = sys.argv[1]
def detections(name):
    return [json.loads(l) for l in open(f"{work}/{name}/detections.jsonl")]
def camera_frames(name):
    return [c["frames"] for c in json.load(open(f"{work}/{name}/summary.json"))["cameras"]]
aligned, within, index = detections("aligned"), detections("within"), detections("index")
blobs = lambda lines: [l["blobs"] for l in lines[3:]]
problems = []
print(f"camera frames: aligned {camera_frames('aligned')}, within 50 ms {camera_frames('within')}, "
      f"outside 10 ms {camera_frames('outside')}")
if len(within) != len(aligned) or blobs(within) != blobs(aligned):
    problems.append("within the tolerance: detections from frame 3 differ from the aligned run's")
if blobs(index)[: len(blobs(aligned))] == blobs(aligned):
    problems.append("by index the late camera gave the aligned run's detections (the test shows nothing)")
if camera_frames("within")[1] != len(aligned) - 3:
    problems.append(f"within the tolerance camera 2 took part in {camera_frames('within')[1]} frame sets, want {len(aligned) - 3}")
if camera_frames("outside")[1] != 0:
    problems.append(f"outside the tolerance camera 2 took part in {camera_frames('outside')[1]} frame sets, want 0")
settings = json.load(open(f"{work}/within/summary.json"))["settings"]
if settings["sync"] != "timestamp" or settings["sync_tolerance_s"] != 0.05:
    problems.append(f"summary settings: {settings['sync']}, {settings['sync_tolerance_s']}")
for p in problems:
    print("FAIL", p)
sys.exit(1 if problems else 0)
PY
[ $? -eq 0 ] && ok
"$occmap" run "$lab/late.yaml" --out "$work/bad" --sync timestamp --sync-tolerance-s 0 >"$work/bad.log" 2>&1
code=$?
if [ $code -eq 2 ] && grep -q "sync-tolerance-s" "$work/bad.log"; then ok; else fail "--sync-tolerance-s 0: exit $code"; cat "$work/bad.log"; fi
tl_finish sync_test
