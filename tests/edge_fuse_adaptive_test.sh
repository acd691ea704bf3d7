#!/usr/bin/env bash
# Adaptive backgrounds through edges (issue 17): the plaza (busy, sunny, backgrounds learned from
# the video and kept up from the fused map) run by `occmap run`, then by 2 edges of 3 cameras
# and 1 fuse through a mosquitto of the test's own (127.0.0.1, an ephemeral port), the fuse
# sending the edges its protections. Both are scored against the ground truth: the fuse's MODA
# within 0.03 of the run's (the edges update with a protection one frame late, and check the
# backgrounds and shadows through the floor over their own 3 cameras, not 6; they do not settle
# their learned backgrounds, nor does that run). Then one edge of all 6 cameras with
# --protection-lag 0 (each frame updated with its own frame set's protection, as the run does),
# its learned backgrounds settled over the window as the run settles them: the fuse's detections
# and tracks equal the run's byte for byte. Then over live streams (the lab, with ffmpeg): the
# edges apply the fuse's latest protections.
#
#   tests/edge_fuse_adaptive_test.sh OCCMAP_BINARY [FRAMES]
set -uo pipefail
occmap=$(realpath "${1:?usage: edge_fuse_adaptive_test.sh OCCMAP_BINARY [FRAMES]}")
frames=${2:-150}
source "$(dirname "$0")/test_lib.sh"
tl_need_mosquitto
tl_init
tl_synth_small_plaza "$occmap" "$work/plaza" "$frames"
grep -q "adaptive: true" "$work/plaza/site.yaml" || { echo "FAIL the plaza's site is not adaptive"; exit 1; }
grep -q "settle:" "$work/plaza/site.yaml" && { echo "FAIL the plaza's site states settle: (the default expected)"; exit 1; }
cp "$work/plaza/site.yaml" "$work/plaza/settled.yaml"
# Edges of part of the cameras do not settle their learned backgrounds (that needs every
# camera's view of the window): the run they are compared with does not either.
tl_unsettle "$work/plaza/site.yaml"
tl_broker
broker="mqtt://127.0.0.1:$broker_port"
common=(--no-cache --threads 1)

"$occmap" run "$work/plaza/site.yaml" --out "$work/run" --no-video --no-wall-clock "${common[@]}" >"$work/run.log" 2>&1 ||
  fail "occmap run: $(tail -2 "$work/run.log")"

"$occmap" fuse "$work/plaza/site.yaml" --broker "$broker" --out "$work/fuse" --no-video --no-wall-clock \
  --latency-budget-s 60 --dead-after-s 60 --start-wait-s 120 "${common[@]}" >"$work/fuse.log" 2>&1 &
fuse_pid=$!
tl_track $fuse_pid
tl_wait_for "$work/fuse.log" "subscribed to" 30
edge_pids=()
for cams in c1,c2,c3 c4,c5,c6; do
  "$occmap" edge "$work/plaza/site.yaml" --cameras $cams --broker "$broker" "${common[@]}" >"$work/edge-$cams.log" 2>&1 &
  edge_pids+=($!)
  tl_track $!
done
tl_edges_then_fuse $fuse_pid "$work/fuse.log" 60 "${edge_pids[@]}"
grep "protections sent" "$work/fuse.log"
n=$(summary_field "$work/fuse" "s['frames']")
[ "$n" = "$frames" ] && ok || fail "fuse: $frames frame sets expected, found $n"
# Every edge heard the fuse: all but the first frame updated with its protection.
for cams in c1,c2,c3 c4,c5,c6; do
  line=$(grep "adaptive backgrounds:" "$work/edge-$cams.log")
  echo "edge $cams: $line"
  received=$(sed -n 's/^adaptive backgrounds: \([0-9]*\) protections.*/\1/p' <<<"$line")
  without=$(sed -n 's/.*protections from the fuse, \([0-9]*\) frame sets updated without.*/\1/p' <<<"$line")
  if [ -n "$received" ] && [ "$received" -ge $((frames - 1)) ] && [ -n "$without" ] && [ "$without" -le 1 ]; then
    ok
  else
    fail "edge $cams: expected $((frames - 1))+ protections and 1 update without, found: $line"
  fi
done

moda() {
  "$occmap" eval "$work/plaza" "$1" --json 2>/dev/null | "$python" -c "import json, sys; print(json.load(sys.stdin)['detection']['moda'])"
}
run_moda=$(moda "$work/run")
fuse_moda=$(moda "$work/fuse")
echo "MODA over $frames frames of the plaza: occmap run $run_moda, 2 edges + fuse $fuse_moda"
if "$python" -c "import sys; a, b = float(sys.argv[1]), float(sys.argv[2]); sys.exit(0 if abs(a - b) <= 0.03 else 1)" \
  "$run_moda" "$fuse_moda" 2>/dev/null; then
  ok
else
  fail "MODA: edges + fuse $fuse_moda, run $run_moda: more than 0.03 apart"
fi

# 2. One edge of every camera, its learned backgrounds settled over the window, each frame
# updated with its own frame set's protection: the settled run's outputs exactly.
"$occmap" run "$work/plaza/settled.yaml" --out "$work/settled" --no-video --no-wall-clock "${common[@]}" \
  >"$work/settled.log" 2>&1 || fail "occmap run, settled: $(tail -2 "$work/settled.log")"
settled_sets=$(summary_field "$work/settled" "s['backgrounds']['settle']['frame_sets']")
[ -n "$settled_sets" ] && [ "$settled_sets" -gt 0 ] && ok || fail "the run settled over no frame set: '$settled_sets'"
"$occmap" fuse "$work/plaza/settled.yaml" --broker "$broker" --out "$work/one" --no-video --no-wall-clock \
  --latency-budget-s 60 --dead-after-s 60 --start-wait-s 120 --topic-prefix occmap-test/one "${common[@]}" \
  >"$work/one.log" 2>&1 &
one_pid=$!
tl_track $one_pid
tl_wait_for "$work/one.log" "subscribed to" 30
"$occmap" edge "$work/plaza/settled.yaml" --protection-lag 0 --topic-prefix occmap-test/one --broker "$broker" \
  "${common[@]}" >"$work/edge-one.log" 2>&1 || fail "the edge of every camera failed: $(tail -3 "$work/edge-one.log")"
for _ in $(seq 1200); do kill -0 $one_pid 2>/dev/null || break; sleep 0.05; done
if kill -0 $one_pid 2>/dev/null; then
  fail "the fuse of one edge did not finish: $(tail -3 "$work/one.log")"
else
  grep -q "adaptive backgrounds: $frames protections from the fuse, 0 frame sets updated without" "$work/edge-one.log" &&
    ok || fail "edge of every camera, lag 0: $(grep adaptive "$work/edge-one.log")"
  grep -q "settled over $settled_sets frame sets" "$work/edge-one.log" &&
    ok || fail "edge of every camera: settled over $settled_sets frame sets expected: $(grep adaptive "$work/edge-one.log")"
  for f in detections.jsonl tracks.jsonl; do
    cmp -s "$work/settled/$f" "$work/one/$f" && ok || fail "one edge, lag 0, settled: the fuse's $f differs from the run's"
  done
  # Settling changed what was found: the test compares settled backgrounds, not unsettled ones twice.
  cmp -s "$work/run/detections.jsonl" "$work/settled/detections.jsonl" &&
    echo "note: the settled and unsettled runs found the same detections over $frames frames"
fi

# 3. Live streams (the lab's 4 cameras over UDP, its backgrounds given and kept adaptive): the
# edges never wait for the fuse and apply its latest protection, a frame or a few late; only the
# first frame sets, before the fuse's first protection, are updated without one.
if command -v ffmpeg >/dev/null; then
  tl_synth_lab "$occmap" "$work/lab" --video --frames 100 --shadows
  read -r -a ports <<<"$(tl_free_ports udp 4)"
  tl_stream_site "$work/lab" "$work/lab/live.yaml" "${ports[@]}"
  printf 'backgrounds:\n  adaptive: true\n' >>"$work/lab/live.yaml"
  for n in 1 2 3 4; do tl_serve "$work/lab" $n "${ports[$((n - 1))]}"; done
  "$occmap" fuse "$work/lab/live.yaml" --broker "$broker" --out "$work/live" --no-video --summary-every-s 0.3 \
    --latency-budget-s 0.5 --dead-after-s 1.5 --topic-prefix occmap-test/live "${common[@]}" >"$work/live.log" 2>&1 &
  live_pid=$!
  tl_track $live_pid
  tl_wait_for "$work/live.log" "subscribed to" 30
  live_edges=()
  for cams in cam1,cam2 cam3,cam4; do
    "$occmap" edge "$work/lab/live.yaml" --cameras $cams --topic-prefix occmap-test/live --broker "$broker" \
      "${common[@]}" >"$work/live-$cams.log" 2>&1 &
    live_edges+=($!)
    tl_track $!
  done
  for _ in $(seq 600); do [ "$(summary_field "$work/live" "s['frames']")" -ge 80 ] && break; sleep 0.1; done
  kill -INT "${live_edges[@]}" 2>/dev/null
  for p in "${live_edges[@]}"; do wait "$p"; done
  kill -INT $live_pid 2>/dev/null
  wait $live_pid
  for cams in cam1,cam2 cam3,cam4; do
    sets=$(sed -n 's/^\([0-9]*\) frame sets, .*/\1/p' "$work/live-$cams.log")
    line=$(grep "adaptive backgrounds:" "$work/live-$cams.log")
    received=$(sed -n 's/^adaptive backgrounds: \([0-9]*\) protections.*/\1/p' <<<"$line")
    without=$(sed -n 's/.*protections from the fuse, \([0-9]*\) frame sets updated without.*/\1/p' <<<"$line")
    echo "live edge $cams: $sets frame sets; $line"
    if [ -n "$sets" ] && [ "$sets" -ge 60 ] && [ -n "$received" ] && [ "$received" -ge $((sets * 8 / 10)) ] &&
      [ -n "$without" ] && [ "$without" -le $((sets / 5)) ]; then  # start-up under load: 9 of 73 seen
      ok
    else
      fail "live edge $cams: most frame sets updated with a protection expected: $sets frame sets; $line"
    fi
  done
else
  echo "SKIP live streams: no ffmpeg program"
fi

tl_finish edge_fuse_adaptive
