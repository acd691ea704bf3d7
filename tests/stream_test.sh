#!/usr/bin/env bash
# `occmap run` on live streams: the rendered lab scene served on loopback by ffmpeg (one MPEG-TS
# over UDP stream per camera, in real time, looping), detections.jsonl growing while it runs;
# one camera's stream stopped for 5 s (it is left out: its frame count stalls and the cells only
# it sees are unseen in the maps (occupancy/NNNNNN.png), then it rejoins without a restart and
# they are seen again), then SIGINT: exit 0 within 2 s, every output valid, no temporary file.
# Then the streams with no background given: each estimated from its own stream. Then camera
# 2's stream stops for good: the run ends with "camera cam2 lost" (exit 1).
# Usage: stream_test.sh OCCMAP_BINARY SOURCE_DIR   (skipped, exit 0, without the ffmpeg program)
set -uo pipefail
occmap=$1
src=$2
source "$src/tests/test_lib.sh"
tl_require_ffmpeg
tl_init
tl_synth_lab "$occmap" "$work/lab" --video --frames 100
read -r -a ports <<<"$(tl_free_ports udp 4)"
tl_stream_site "$work/lab" "$work/lab/stream.yaml" "${ports[@]}"
serve() { tl_serve "$work/lab" "$1" "${ports[$(($1 - 1))]}"; }  # serve N: camera N's video, looped
for n in 1 2 3 4; do serve $n; done
sleep 1

out="$work/run"
"$occmap" run "$work/lab/stream.yaml" --out "$out" --no-cache --summary-every-s 0.5 --occupancy-pngs \
  >"$work/run.log" 2>&1 &
pid=$!
tl_track $pid
cam_frames() { summary_field "$out" "s['cameras'][0]['frames']"; }  # camera 1's, in the running summary
last_frame() { tail -1 "$out/detections.jsonl" | "$python" -c "import json, sys; print(json.load(sys.stdin)['frame'])"; }
for _ in $(seq 300); do
  [ "$(lines "$out/detections.jsonl")" -ge 30 ] && break
  sleep 0.1
done
a=$(lines "$out/detections.jsonl")
sleep 1
b=$(lines "$out/detections.jsonl")
if [ "$a" -ge 30 ] && [ "$b" -gt "$a" ]; then ok; else fail "detections.jsonl did not grow while running ($a, then $b lines)"; cat "$work/run.log"; fi

# Camera 1's stream stops for 5 s: the run goes on without it, then takes it back.
frame_before=$(last_frame)
tl_stop_serving 1
sleep 1.5
during0=$(cam_frames)
lines_during0=$(lines "$out/detections.jsonl")
frame_during0=$(last_frame)
sleep 3
during1=$(cam_frames)
lines_during1=$(lines "$out/detections.jsonl")
frame_during1=$(last_frame)
sleep 0.5
serve 1
sleep 6
after=$(cam_frames)
frame_after=$(last_frame)
echo "camera 1 frames: $during0 -> $during1 while stopped, $after after it came back"
if [ "$during1" -le $((during0 + 2)) ]; then ok; else fail "camera 1 kept getting frames while its stream was stopped"; fi
if [ "$lines_during1" -gt "$lines_during0" ]; then ok; else fail "the run stopped while camera 1 was away"; fi
if [ "$after" -gt $((during1 + 10)) ]; then ok; else fail "camera 1 did not rejoin ($during1 -> $after frames)"; fi
# The maps say so: the cells only camera 1 sees (about 280 of the lab's 146250; 628 unseen with
# every camera, 904 without camera 1) are unseen in every frame set of the outage, seen again
# after. The 20 frame sets before the stop give the unseen cells with every camera.
unseen() { "$python" "$src/tests/unseen_cells.py" "$out" "$1" "$2" | awk '{print $2}' | tr '\n' ' '; }
unseen_before=$(unseen $((frame_before - 20)) "$frame_before")
unseen_during=$(unseen "$frame_during0" "$frame_during1")
unseen_after=$(unseen $((frame_after - 10)) "$frame_after")
echo "unseen cells: before the stop $unseen_before; stopped (frames $frame_during0-$frame_during1) $unseen_during;" \
  "back $unseen_after"
"$python" - "$unseen_before" "$unseen_during" "$unseen_after" <<'PY' || fail "camera 1's cells not unseen while its stream was stopped, or not seen again after"
import statistics, sys
before, during, after = ([int(v) for v in a.split()] for a in sys.argv[1:])
everyone = min(before)
ok = (len(before) >= 10 and len(during) >= 5 and len(after) >= 5
      and all(v >= everyone + 100 for v in during) and statistics.median(after) == everyone)
sys.exit(0 if ok else 1)
PY

t0=$(date +%s.%N)
kill -INT $pid
wait $pid
code=$?
t1=$(date +%s.%N)
elapsed=$("$python" -c "print(round($t1 - $t0, 3))")
echo "stopped in $elapsed s, exit $code"
if [ $code -eq 0 ]; then ok; else fail "exit $code, want 0"; cat "$work/run.log"; fi
if "$python" -c "import sys; sys.exit(0 if $elapsed < 2.0 else 1)"; then ok; else fail "took $elapsed s to stop"; fi
if "$python" "$src/tests/check_run_outputs.py" "$out" final; then ok; else fail "outputs"; fi
"$python" - "$out/summary.json" <<'PY' || fail "summary"
import json, sys
s = json.load(open(sys.argv[1]))
c = s["cameras"][0]
print(f"summary: {s['frames']} frame sets, camera 1: {c['frames']} frames, {c['reconnects']} reconnects, "
      f"{c['dropped_frames']} dropped; latency ms p50 {s['latency_ms']['p50']} p95 {s['latency_ms']['p95']} "
      f"p99 {s['latency_ms']['p99']}")
sys.exit(0 if s["stop_reason"] == "stop requested" else 1)
PY

# Streams without a background (a new site): the median is taken from each stream's own
# connection, which a second one would not get (the UDP port is bound once).
sed '/^ *background:/d' "$work/lab/stream.yaml" >"$work/lab/stream_nobg.yaml"
timeout 120 "$occmap" run "$work/lab/stream_nobg.yaml" --out "$work/run_nobg" --no-cache --frames 20 \
  --background-frames 5 >"$work/run_nobg.log" 2>&1
code=$?
if [ $code -eq 0 ]; then ok; else fail "streams without backgrounds: exit $code"; cat "$work/run_nobg.log"; fi
"$python" - "$work/run_nobg/summary.json" <<'PY' || fail "streams without backgrounds: summary"
import json, sys
s = json.load(open(sys.argv[1]))
print("backgrounds:", [c["background"] for c in s["cameras"]])
sys.exit(0 if s["frames"] == 20 and all(c["background"].startswith("estimated") for c in s["cameras"]) else 1)
PY

# Camera 2's stream goes for good: without --continue-without-camera the run ends once it has
# been silent for --camera-lost-after-s, saying so (exit 1), its outputs valid.
out="$work/lost"
"$occmap" run "$work/lab/stream.yaml" --out "$out" --no-cache --camera-lost-after-s 2 >"$work/lost.log" 2>&1 &
pid=$!
tl_track $pid
for _ in $(seq 300); do
  [ "$(lines "$out/detections.jsonl")" -ge 20 ] && break
  sleep 0.1
done
tl_stop_serving 2
for _ in $(seq 150); do
  kill -0 $pid 2>/dev/null || break
  sleep 0.1
done
if kill -0 $pid 2>/dev/null; then fail "the run did not end 15 s after camera 2's stream went"; kill -INT $pid; fi
wait $pid
code=$?
echo "camera 2 gone: exit $code; $(tail -1 "$work/lost.log")"
if [ $code -eq 1 ]; then ok; else fail "exit $code, want 1 (camera lost)"; cat "$work/lost.log"; fi
if grep -q "camera cam2 lost" "$work/lost.log"; then ok; else fail "no 'camera cam2 lost' in the message"; fi
if "$python" "$src/tests/check_run_outputs.py" "$out" final; then ok; else fail "outputs after a lost camera"; fi
"$python" - "$out/summary.json" <<'PY' || fail "summary after a lost camera"
import json, sys
s = json.load(open(sys.argv[1]))
c = s["cameras"][1]
print(f"summary: stop_reason {s['stop_reason']!r}; camera 2 end_reason {c.get('end_reason')!r}")
sys.exit(0 if s["stop_reason"].startswith("camera cam2 lost") and c.get("end_reason", "").startswith("lost:") else 1)
PY
tl_finish stream_test
