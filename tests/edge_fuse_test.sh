#!/usr/bin/env bash
# `occmap edge` x 3 + `occmap fuse` through a mosquitto of the test's own (127.0.0.1, an
# ephemeral port) on a rendered lab scene: the fuse's detections, tracks and events equal
# `occmap run`'s byte for byte, and its tracks go out on MQTT as the run's do (--mqtt); a fuse given a site with other detection settings refuses the
# edges' messages, naming what differs; a fuse survives a restart of the broker; with the
# changes in 2x2 blocks (detection.block_px 2) the fuse still equals the run.
#
#   tests/edge_fuse_test.sh OCCMAP_BINARY
set -uo pipefail
occmap=$(realpath "${1:?usage: edge_fuse_test.sh OCCMAP_BINARY}")
source "$(dirname "$0")/test_lib.sh"
tl_need_mosquitto
tl_init
tl_synth_lab "$occmap" "$work/lab" --video --frames 60
tl_broker
broker="mqtt://127.0.0.1:$broker_port"
common=(--no-cache --threads 1)

"$occmap" run "$work/lab/site.yaml" --out "$work/run" --no-video --no-wall-clock "${common[@]}" >"$work/run.log" 2>&1 ||
  fail "occmap run: $(tail -2 "$work/run.log")"

# 1. Three edges (two cameras, one, one) and the fuse: the same outputs as the run.
# Over files the edges race ahead of each other: a budget longer than their lag keeps every
# frame set whole, as the run's.
mosquitto_sub -h 127.0.0.1 -p "$broker_port" -t 'occmap/lab/tracks' -t 'occmap/lab/stats' -t 'occmap/lab/available' \
  -F '%t %p' >"$work/outputs.log" 2>&1 &
tl_track $!
sub_pid=$!
"$occmap" fuse "$work/lab/site.yaml" --broker "$broker" --out "$work/fuse" --no-video --no-wall-clock \
  --latency-budget-s 60 --dead-after-s 60 --mqtt "$broker" "${common[@]}" >"$work/fuse.log" 2>&1 &
fuse_pid=$!
tl_track $fuse_pid
tl_wait_for "$work/fuse.log" "subscribed to" 10
edge_pids=()
for cams in cam1,cam2 cam3 cam4; do
  "$occmap" edge "$work/lab/site.yaml" --cameras $cams --broker "$broker" "${common[@]}" >"$work/edge-$cams.log" 2>&1 &
  edge_pids+=($!)
  tl_track $!
done
tl_edges_then_fuse $fuse_pid "$work/fuse.log" 30 "${edge_pids[@]}"
for f in detections.jsonl tracks.jsonl tracks_mot.csv $([ -f "$work/run/events.jsonl" ] && echo events.jsonl); do
  if [ -f "$work/run/$f" ] && cmp -s "$work/run/$f" "$work/fuse/$f"; then
    ok
  else
    fail "fuse's $f differs from run's ($(wc -l <"$work/run/$f" 2>/dev/null) vs $(wc -l <"$work/fuse/$f" 2>/dev/null) lines)"
  fi
done
frames=$(summary_field "$work/fuse" "s['frames']")
[ "$frames" = 60 ] && ok || fail "fuse: 60 frame sets expected, found $frames"
# The fuse's outputs for other software: every frame set's tracks on MQTT, the tracks.jsonl lines.
sleep 0.3
kill $sub_pid 2>/dev/null
"$python" - "$work" <<'PY' && ok || fail "the fuse's MQTT outputs: $(tail -3 "$work/outputs.log")"
import json, sys
work = sys.argv[1]
msgs = [l.rstrip("\n").split(" ", 1) for l in open(f"{work}/outputs.log") if " " in l]
tracks = [json.loads(p) for t, p in msgs if t == "occmap/lab/tracks"]
assert tracks == [json.loads(l) for l in open(f"{work}/fuse/tracks.jsonl")], (len(tracks), "tracks differ")
stats = [json.loads(p) for t, p in msgs if t == "occmap/lab/stats"]
assert stats and stats[-1]["frames"] == 60, stats[-1:]
avail = [p for t, p in msgs if t == "occmap/lab/available"]
assert avail[0] == "online" and avail[-1] == "offline", avail
print(f"fuse on MQTT: {len(tracks)} tracks messages, {len(stats)} stats, availability {avail}")
PY
grep -q "^mqtt: .* published, 0 dropped" "$work/fuse.log" && ok || fail "fuse: no MQTT figures: $(tail -3 "$work/fuse.log")"
grep -q "edge messages\|bytes per message" "$work"/edge-cam3.log && ok || fail "edge: no figures printed: $(cat "$work/edge-cam3.log")"

# 2. A fuse whose site has another threshold refuses the edges' messages, and says why.
sed 's/^\(  threshold:\).*/\1 41/' "$work/lab/site.yaml" >"$work/lab/other.yaml"
"$occmap" fuse "$work/lab/other.yaml" --broker "$broker" --out "$work/other" --no-video --frames 1 \
  --topic-prefix occmap-test/other "${common[@]}" >"$work/other.log" 2>&1 &
other_pid=$!
tl_track $other_pid
tl_wait_for "$work/other.log" "subscribed to" 10
"$occmap" edge "$work/lab/site.yaml" --cameras cam1 --frames 3 --topic-prefix occmap-test/other --broker "$broker" \
  "${common[@]}" >/dev/null 2>&1
for _ in $(seq 40); do grep -q "refused" "$work/other.log" && break; sleep 0.05; done
grep -q "other detection settings" "$work/other.log" && ok ||
  fail "a fuse with another threshold did not refuse: $(cat "$work/other.log")"
kill -INT $other_pid 2>/dev/null

# 3. The broker restarted under a waiting fuse: it reconnects and subscribes again, and the
# edges started after the restart give the run's outputs again.
"$occmap" fuse "$work/lab/site.yaml" --broker "$broker" --out "$work/again" --no-video --no-wall-clock \
  --latency-budget-s 60 --dead-after-s 60 --topic-prefix occmap-test/again "${common[@]}" >"$work/again.log" 2>&1 &
again_pid=$!
tl_track $again_pid
tl_wait_for "$work/again.log" "subscribed to" 10
tl_restart_broker
sleep 7  # the fuse's reconnect back-off (1 s, then 2, 4) and its subscription
for cams in cam1,cam2,cam3 cam4; do
  "$occmap" edge "$work/lab/site.yaml" --cameras $cams --topic-prefix occmap-test/again --broker "$broker" \
    "${common[@]}" >/dev/null 2>&1 || fail "an edge after the broker's restart failed"
done
for _ in $(seq 600); do kill -0 $again_pid 2>/dev/null || break; sleep 0.05; done
if kill -0 $again_pid 2>/dev/null; then
  fail "after the broker's restart the fuse did not finish: $(tail -3 "$work/again.log")"
elif cmp -s "$work/run/tracks.jsonl" "$work/again/tracks.jsonl"; then
  ok
else
  fail "after the broker's restart the fuse's tracks differ from the run's"
fi

# A run of SITE's first 30 frames into $work/NAME-run, then a fuse into $work/NAME-fuse fed by
# one edge of all the cameras; fails unless the fuse finishes (returns 1 then).
run_then_fuse() {  # NAME SITE
  local name=$1 site=$2 pid
  "$occmap" run "$site" --out "$work/$name-run" --frames 30 --no-video --no-wall-clock "${common[@]}" \
    >"$work/$name-run.log" 2>&1 || fail "occmap run ($name): $(tail -2 "$work/$name-run.log")"
  "$occmap" fuse "$site" --broker "$broker" --out "$work/$name-fuse" --no-video --no-wall-clock \
    --latency-budget-s 60 --dead-after-s 60 --topic-prefix "occmap-test/$name" "${common[@]}" >"$work/$name-fuse.log" 2>&1 &
  pid=$!
  tl_track $pid
  tl_wait_for "$work/$name-fuse.log" "subscribed to" 10
  "$occmap" edge "$site" --frames 30 --topic-prefix "occmap-test/$name" --broker "$broker" \
    "${common[@]}" >"$work/$name-edge.log" 2>&1 || fail "the $name site's edge failed"
  for _ in $(seq 600); do kill -0 $pid 2>/dev/null || break; sleep 0.05; done
  if kill -0 $pid 2>/dev/null; then
    fail "the $name site's fuse did not finish: $(tail -3 "$work/$name-fuse.log")"
    return 1
  fi
}

# 4. With `people: {occluders: {learn: true}}` the fuse saves what it learned, as the run does:
# the same occluders.txt (learning set to count every frame, so that 30 frame sets learn some).
cp "$work/lab/site.yaml" "$work/lab/people.yaml"
printf 'people:\n  occluders: {learn: true, episode_frames: 1, min_episodes: 1}\n' >>"$work/lab/people.yaml"
if run_then_fuse people "$work/lab/people.yaml"; then
  if [ ! -s "$work/people-run/occluders.txt" ]; then
    fail "occmap run with learning wrote no occluders.txt"
  elif cmp -s "$work/people-run/occluders.txt" "$work/people-fuse/occluders.txt"; then
    ok
  else
    fail "fuse's occluders.txt differs from run's or is missing: $(ls "$work/people-fuse")"
  fi
fi

# 5. Changes in 2x2 blocks (detection.block_px 2, the people detector on): the edge sends one
# pixel per block, and the fuse's outputs are still the run's byte for byte.
if grep -q '^detection:$' "$work/lab/people.yaml"; then
  sed 's/^detection:$/detection:\n  block_px: 2/' "$work/lab/people.yaml" >"$work/lab/blocks.yaml"
else
  { cat "$work/lab/people.yaml"; printf 'detection:\n  block_px: 2\n'; } >"$work/lab/blocks.yaml"
fi
if run_then_fuse blocks "$work/lab/blocks.yaml"; then
  for f in detections.jsonl tracks.jsonl; do
    if [ -s "$work/blocks-run/$f" ] && cmp -s "$work/blocks-run/$f" "$work/blocks-fuse/$f"; then
      ok
    else
      fail "with block_px 2 the fuse's $f differs from the run's"
    fi
  done
  if cmp -s "$work/people-run/detections.jsonl" "$work/blocks-run/detections.jsonl"; then
    fail "block_px 2 changed nothing in the run's detections (not applied?)"
  else
    ok
  fi
fi

tl_finish edge_fuse
