#!/usr/bin/env bash
# An edge of an adaptive site (issue 17) killed and started again: the plaza (backgrounds learned
# from the busy video, kept up from the fuse's protections) rendered small, 2 edges of 3 cameras
# and 1 fuse over files through a mosquitto of the test's own (127.0.0.1, an ephemeral port), the
# edges' learned backgrounds cached in the test's folder. The broker is restarted under them: the
# edges and the fuse reconnect and go on. Then the second edge is killed (kill -9) mid-run: its
# cameras' cells are unseen while the fuse goes on; started again, it takes its backgrounds from
# the cache (no learning), starts at the frame after the fuse's last frame set (the fuse's
# retained progress: not from frame 0), catches up with the fuse and its cells are seen again. Every edge
# reports the end of its files and the fuse exits 0 with every frame set.
#
#   tests/edge_fuse_restart_test.sh OCCMAP_BINARY [FRAMES]
set -uo pipefail
occmap=$(realpath "${1:?usage: edge_fuse_restart_test.sh OCCMAP_BINARY [FRAMES]}")
frames=${2:-300}
source "$(dirname "$0")/test_lib.sh"
tl_need_mosquitto
tl_init
tl_synth_small_plaza "$occmap" "$work/plaza" "$frames"
# Edges do not settle their learned backgrounds (that needs the fused map while they learn).
tl_unsettle "$work/plaza/site.yaml"
tl_broker
broker="mqtt://127.0.0.1:$broker_port"
site="$work/plaza/site.yaml"
common=(--cache-dir "$work/cache" --threads 1)
out="$work/fuse"

"$occmap" fuse "$site" --broker "$broker" --out "$out" --no-video --occupancy-pngs --latency-budget-s 2 \
  --dead-after-s 1.5 --summary-every-s 0.3 "${common[@]}" >"$work/fuse.log" 2>&1 &
fuse_pid=$!
tl_track $fuse_pid
tl_wait_for "$work/fuse.log" "subscribed to" 30 || fail "the fuse did not subscribe: $(tail -3 "$work/fuse.log")"
declare -A edge_pid
start_edge() {  # start_edge CAMERAS
  "$occmap" edge "$site" --cameras "$1" --broker "$broker" "${common[@]}" \
    >>"$work/edge-$1.log" 2>&1 &
  edge_pid[$1]=$!
  tl_track $!
}
for cams in c1,c2,c3 c4,c5,c6; do start_edge $cams; done
frames_fused() { summary_field "$out" "s['frames']"; }
wait_frames() {  # wait_frames N: until the fuse has fused N frame sets (60 s at most)
  for _ in $(seq 600); do [ "$(frames_fused)" -ge "$1" ] && return 0; sleep 0.1; done
  return 1
}
grep_count() { grep -c "$2" "$1" 2>/dev/null || true; }
wait_log() {  # wait_log FILE TEXT SECONDS [COUNT]: until FILE holds TEXT COUNT times (default 1)
  for _ in $(seq $(($3 * 10))); do [ "$(grep_count "$1" "$2")" -ge "${4:-1}" ] && return 0; sleep 0.1; done
  return 1
}
# at_frame_set TEXT: the frame set of the fuse's last "camera c4 TEXT ... at frame set N"
at_frame_set() { sed -n "s/.*camera c4 $1.* at frame set \([0-9]*\).*/\1/p" "$work/fuse.log" | tail -1; }
# Both edges heard (while they learn, the fuse may say one silent and back before the first set).
wait_log "$work/edge-c4,c5,c6.log" "cameras ready" 60
wait_frames 30 && ok || fail "the fuse fused $(frames_fused) frame sets in 60 s: $(tail -3 "$work/fuse.log")"
for cams in c1,c2,c3 c4,c5,c6; do
  grep -q "backgrounds: .*learned" "$work/edge-$cams.log" && ok ||
    fail "edge $cams: no learned background said: $(head -3 "$work/edge-$cams.log")"
done

# 1. The broker restarted under them: the edges (files: they wait for it) and the fuse go on.
# The fuse is held (SIGSTOP) until the edges are back, as a loaded machine's fuse may reconnect
# last: a broker without persistence drops what the edges send before the fuse subscribes again
# (once 298 of 300 frame sets), so the edges wait for the fuse's word and send that again.
before=$(frames_fused)
kill -STOP $fuse_pid
tl_restart_broker 1
wait_log "$work/edge-c1,c2,c3.log" "the broker is back" 15
wait_log "$work/edge-c4,c5,c6.log" "the broker is back" 15
sleep 1  # the edges' first messages on the new connection, before the fuse's
kill -CONT $fuse_pid
wait_frames $((before + 10)) && ok || fail "the fuse did not go on after the broker's restart ($before -> $(frames_fused))"

# 2. The second edge killed: the fuse leaves its cameras out and goes on.
kill_at=$(frames_fused)
silent=$(grep_count "$work/fuse.log" "camera c4 silent")
back=$(grep_count "$work/fuse.log" "camera c4 is back")
kill -KILL "${edge_pid[c4,c5,c6]}"
wait "${edge_pid[c4,c5,c6]}" 2>/dev/null
wait_log "$work/fuse.log" "camera c4 silent" 20 $((silent + 1)) && ok || fail "the fuse did not give up on camera c4: $(tail -3 "$work/fuse.log")"
dead_at=$(at_frame_set silent)
wait_frames $((${dead_at:-0} + 13)) && ok || fail "the run stopped without the second edge ($(frames_fused) frame sets)"

# 3. Started again: its backgrounds from the cache, its cells back, no restart of the fuse.
restart_at=$(frames_fused)
start_edge c4,c5,c6
wait_log "$work/fuse.log" "camera c4 is back" 60 $((back + 1)) && ok || fail "camera c4 did not rejoin: $(tail -3 "$work/fuse.log")"
back_at=$(at_frame_set "is back")
[ "$(grep_count "$work/edge-c4,c5,c6.log" "backgrounds: .*reused")" -ge 1 ] && ok ||
  fail "the restarted edge did not reuse its cached backgrounds: $(grep -i background "$work/edge-c4,c5,c6.log")"
grep "cameras ready" "$work/edge-c4,c5,c6.log" | tail -1
# It began where the fuse was (its progress), not at frame 0: nothing it sends is dropped as
# late but what the fuse fused while it started.
skip_to=$(sed -n 's/.*the fuse has fused frame set [0-9]*: starting at frame \([0-9]*\).*/\1/p' "$work/edge-c4,c5,c6.log" | tail -1)
echo "the restarted edge started at frame ${skip_to:-0} (the fuse had fused $restart_at frame sets)"
[ -n "$skip_to" ] && [ "$skip_to" -ge $((restart_at - 5)) ] && [ "$skip_to" -le "${back_at:-0}" ] && ok ||
  fail "the restarted edge started at frame ${skip_to:-0}, not near the fuse's $restart_at: $(head -3 "$work/edge-c4,c5,c6.log")"
wait_frames $((${back_at:-0} + 20)) || fail "the fuse stalled after camera c4 came back"

# 4. Every edge reports the end of its files; the fuse finishes with every frame set.
tl_edges_then_fuse $fuse_pid "$work/fuse.log" 60 "${edge_pid[c4,c5,c6]}" "${edge_pid[c1,c2,c3]}"
n=$(summary_field "$out" "s['frames']")
[ "$n" = "$frames" ] && ok || fail "fuse: $frames frame sets expected, found $n"
grep "adaptive backgrounds:" "$work"/edge-*.log
grep -h "broker\|sent again" "$work"/edge-*.log
# The first edge reconnected once (the second one's figures are those of its run after the kill).
grep -q " 1 reconnects" "$work/edge-c1,c2,c3.log" && ok ||
  fail "edge c1,c2,c3: no reconnection counted: $(tail -2 "$work/edge-c1,c2,c3.log")"

# The maps: the second edge's cells unseen while it is away, seen again when it is back (the
# median over ten frame sets: under load a frame set may miss the other edge too).
grey() {  # grey FIRST LAST: the median count of unseen cells in those frame sets' occupancy maps
  "$python" "$(dirname "$0")/unseen_cells.py" "$out" "$1" "$2" | awk '{ print $2 }' | sort -n | sed -n 5p
}
g_before=$(grey $((kill_at - 10)) $((kill_at - 1)))
g_dead=$(grey $((dead_at + 3)) $((dead_at + 12)))
g_back=$(grey $((back_at + 5)) $((back_at + 14)))
echo "unseen cells: $g_before before, $g_dead with the second edge dead, $g_back after it came back" \
  "(killed at frame set $kill_at, left out at $dead_at, started again at $restart_at, back at $back_at)"
[ "${g_dead:-0}" -gt "${g_before:-0}" ] && [ -n "$g_back" ] && [ "$g_back" -lt "${g_dead:-0}" ] && ok ||
  fail "unseen cells: $g_before before, $g_dead with the second edge dead, $g_back after"
# Left out while away; late messages: only what the fuse fused while the restarted edge started
# (from frame 0 it sent every frame set before $restart_at late).
"$python" - "$out/summary.json" "$restart_at" <<'PY' || fail "summary: cameras c4-c6 not counted as left out, or late from frame 0"
import json, sys
s = json.load(open(sys.argv[1]))
restart_at = int(sys.argv[2])
left = [c.get("left_out", -1) for c in s["cameras"]]
late = [c.get("late_messages", -1) for c in s["cameras"]]
print(f"summary: {s['frames']} frame sets, left out per camera {left}, late messages {late}, "
      f"latency ms p50 {s['latency_ms']['p50']} p99 {s['latency_ms']['p99']}")
sys.exit(0 if min(left[3:]) >= 10 and max(left[:3]) < min(left[3:]) and max(late[3:]) < restart_at // 2 else 1)
PY

tl_finish edge_fuse_restart
