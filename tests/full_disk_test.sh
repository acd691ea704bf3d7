#!/usr/bin/env bash
# A full disk (issue 39): the output folder on a 2 MB tmpfs, nearly filled first. A live run
# stops with exit 1 and says the disk is full; detections.jsonl, tracks.jsonl and tracks_mot.csv
# hold whole lines only (each JSON line parses, each CSV row has its 10 columns) and end at the
# same frame set. With --atomic-outputs a run either writes every output or none (whatever the
# moment the disk fills: mid-run or at the end, finishing the video). Mounting needs root (CI
# runs as root); skipped with a message when the mount fails.
#
#   tests/full_disk_test.sh OCCMAP_BINARY
set -uo pipefail
occmap=$(realpath "${1:?usage: full_disk_test.sh OCCMAP_BINARY}")
source "$(dirname "$0")/test_lib.sh"
tl_init
disk="$work/disk"
mkdir -p "$disk"
if ! mount -t tmpfs -o size=2M tmpfs "$disk" 2>/dev/null; then
  echo "SKIP: cannot mount a 2 MB tmpfs on $disk (needs root)"
  exit 0
fi
trap 'umount "$disk" 2>/dev/null; tl_cleanup' EXIT
tl_synth_lab "$occmap" "$work/lab" --video --frames 150 --scale 0.5
common=(--no-cache --threads 1 --no-wall-clock)

# fill_leaving KB: the disk filled but KB kilobytes.
fill_leaving() {
  rm -rf "${disk:?}"/*
  cat /dev/zero >"$disk/filler" 2>/dev/null
  truncate -s "-$1K" "$disk/filler"
}
# kb DIR [NAME...]: the kilobytes the files take on the disk (all of DIR without names).
kb() {
  local dir=$1
  shift
  if [ $# -eq 0 ]; then du -sk "$dir" | cut -f1; else (cd "$dir" && du -ck "$@" | tail -1 | cut -f1); fi
}

# The room each run takes (measured off the small disk: the atomic run's does not fit in it).
"$occmap" run "$work/lab/site.yaml" --out "$work/m-live" --no-video "${common[@]}" >"$work/measure.log" 2>&1 ||
  fail "the run failed: $(tail -2 "$work/measure.log")"
live_kb=$(kb "$work/m-live")
lines_kb=$(kb "$work/m-live" detections.jsonl tracks.jsonl tracks_mot.csv)
mosaic_kb=$(kb "$work/m-live" mosaic.png)  # written at the end
"$occmap" run "$work/lab/site.yaml" --out "$work/m-atomic" --atomic-outputs "${common[@]}" >"$work/measure.log" 2>&1 ||
  fail "the atomic run failed: $(tail -2 "$work/measure.log")"
atomic_kb=$(kb "$work/m-atomic")
echo "room: live $live_kb kB ($lines_kb kB of lines, $mosaic_kb kB mosaic.png), atomic with the video $atomic_kb kB"

# 1. Live: the disk fills half way through the lines: whole lines, the same frame sets in every
# line file, the error said.
fill_leaving $((live_kb - mosaic_kb - lines_kb / 2))
"$occmap" run "$work/lab/site.yaml" --out "$disk/live" --no-video "${common[@]}" >"$work/live.log" 2>&1
code=$?
[ $code -eq 1 ] && ok || fail "live on a full disk: exit 1 expected, found $code: $(tail -3 "$work/live.log")"
grep -q "No space left on device" "$work/live.log" && ok || fail "live: the full disk not said: $(tail -3 "$work/live.log")"
grep -q "not written; the line files end at the frame set before it, whole" "$work/live.log" && ok ||
  fail "live: what was kept not said: $(tail -3 "$work/live.log")"
"$python" - "$disk/live" <<'PY' && ok || fail "live: torn or disagreeing outputs"
import json, sys
out = sys.argv[1]
def lines(name):
    text = open(f"{out}/{name}").read()
    assert text == "" or text.endswith("\n"), f"{name}: a partial last line: {text[-80:]!r}"
    return text.splitlines()
det = [json.loads(l)["frame"] for l in lines("detections.jsonl")]
trk = [json.loads(l)["frame"] for l in lines("tracks.jsonl")]
assert det == trk, f"detections.jsonl has {len(det)} frame sets, tracks.jsonl {len(trk)}"
assert det == list(range(len(det))), "frame sets missing"
assert len(det) > 10, f"only {len(det)} frame sets before the disk was full"
mot = [r.split(",") for r in lines("tracks_mot.csv")]
assert all(len(r) == 10 for r in mot), [r for r in mot if len(r) != 10][:1]
assert not mot or int(mot[-1][0]) <= len(det), f"tracks_mot.csv goes on to frame {mot[-1][0]}, the others end at {len(det)}"
print(f"live on a full disk: {len(det)} whole frame sets in every line file, {len(mot)} MOT rows")
PY

# 2. Atomic: every output or none, wherever the disk fills (early, half way, at the very end).
for free_kb in 24 $((atomic_kb / 2)) $((atomic_kb - mosaic_kb - 8)) $((atomic_kb - 8)); do
  fill_leaving $free_kb
  "$occmap" run "$work/lab/site.yaml" --out "$disk/atomic" --atomic-outputs "${common[@]}" >"$work/atomic.log" 2>&1
  code=$?
  present=$(cd "$disk/atomic" 2>/dev/null && ls detections.jsonl tracks.jsonl tracks_mot.csv occupancy.mp4 2>/dev/null | wc -l)
  temps=$(find "$disk/atomic" -name '.tmp-*' 2>/dev/null | wc -l)
  if [ "$present" -eq 4 ] && { [ $code -eq 0 ] || grep -q "summary.json" "$work/atomic.log"; }; then
    ok  # every output written (the small summary.json last, which may be what found the disk full)
    echo "atomic, $free_kb kB free: every output written (exit $code)"
  elif [ $code -eq 1 ] && [ "$present" -eq 0 ] && [ "$temps" -eq 0 ]; then
    ok
    echo "atomic, $free_kb kB free: none written ($(grep -o "atomic outputs: none written" "$work/atomic.log" | head -1 ||
      true)$(grep -c "No space left" "$work/atomic.log") mentions of the full disk)"
  else
    fail "atomic, $free_kb kB free: exit $code with $present of 4 outputs and $temps temporaries: $(tail -3 "$work/atomic.log")"
  fi
done

tl_finish full_disk
