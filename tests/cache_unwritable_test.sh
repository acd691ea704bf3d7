#!/usr/bin/env bash
# A cache that cannot be written never stops a process (a cache is a head start, never an
# output): the cache folder is a regular file (the tests may run as root, whom no mode stops).
# 1. `occmap edge` x 2 and `occmap fuse` over the small plaza's files (adaptive, learned, not
#    settled) through a mosquitto of the test's own: the edges cannot cache their learned
#    backgrounds nor the tables, the fuse not its tables; each says so once per entry
#    ("could not write the ... cache <path>: <error>; going on without it") and every frame set
#    is fused.
# 2. A live edge (the lab's cameras 1 and 2 as UDP streams, skipped without ffmpeg) whose
#    backgrounds are written back every second into a cache whose backgrounds/ is a file: every
#    refresh fails; the edge goes on publishing, says it once per camera, and its end-of-run
#    lines report the failures.
#
#   tests/cache_unwritable_test.sh OCCMAP_BINARY [FRAMES]   (skipped without mosquitto)
set -uo pipefail
occmap=$(realpath "${1:?usage: cache_unwritable_test.sh OCCMAP_BINARY [FRAMES]}")
frames=${2:-40}
source "$(dirname "$0")/test_lib.sh"
tl_need_mosquitto
tl_init
tl_synth_small_plaza "$occmap" "$work/plaza" "$frames"
# Edges do not settle their learned backgrounds (that needs the fused map while they learn).
tl_unsettle "$work/plaza/site.yaml"
site="$work/plaza/site.yaml"
printf 'not a folder' >"$work/blocked"
common=(--cache-dir "$work/blocked" --threads 1)

# said LOG WHAT: how many lines of LOG say a WHAT ("background", "table") cache was not written.
said() { grep -c "warning: could not write the $2 cache $work/blocked/.*: .*cannot create folder: .*; going on without it" "$1"; }

tl_broker
broker="mqtt://127.0.0.1:$broker_port"
"$occmap" fuse "$site" --broker "$broker" --out "$work/fuse" --no-video --latency-budget-s 2 "${common[@]}" \
  >"$work/fuse.log" 2>&1 &
fuse_pid=$!
tl_track $fuse_pid
tl_wait_for "$work/fuse.log" "subscribed to" 30 || fail "the fuse did not subscribe: $(tail -3 "$work/fuse.log")"
declare -a edges
for cams in c1,c2,c3 c4,c5,c6; do
  "$occmap" edge "$site" --cameras "$cams" --broker "$broker" "${common[@]}" >"$work/edge-$cams.log" 2>&1 &
  edges+=($!)
  tl_track $!
done
tl_edges_then_fuse $fuse_pid "$work/fuse.log" 60 "${edges[@]}"
n=$(summary_field "$work/fuse" "s['frames']")
[ "$n" = "$frames" ] && ok || fail "fuse: $frames frame sets expected, found $n"
[ "$(said "$work/fuse.log" table)" = 1 ] && ok || fail "the fuse did not say once that its tables were not cached: $(cat "$work/fuse.log")"
grep -q "could not write the table cache $work/blocked/plaza.lut: " "$work/fuse.log" && ok ||
  fail "the fuse's warning does not name the table file: $(grep warning "$work/fuse.log")"
for cams in c1,c2,c3 c4,c5,c6; do
  log="$work/edge-$cams.log"
  [ "$(said "$log" background)" = 3 ] && [ "$(said "$log" table)" = 1 ] && ok ||
    fail "edge $cams: not one warning per learned background (3) and one for the tables: $(grep warning "$log")"
  grep -q "backgrounds: .*learned" "$log" && ok || fail "edge $cams: no learned background said: $(head -3 "$log")"
done
[ -f "$work/blocked" ] && [ "$(cat "$work/blocked")" = "not a folder" ] && ok || fail "the file in the cache's place was touched"

# 2. A live edge whose refreshes all fail: the lab's cameras 1 and 2 as UDP streams, their
#    backgrounds learned (learn_s 2) and written back every second (refresh_cache_s 1) into a
#    cache whose backgrounds/ is a file. The edge goes on publishing after the first failure, says
#    it once per camera, and its end-of-run lines report the failures.
if ! command -v ffmpeg >/dev/null; then
  echo "SKIP part 2 (a live edge): no ffmpeg program"
  tl_finish cache_unwritable
  exit $?
fi
tl_synth_lab "$occmap" "$work/lab" --video --frames 100
read -r -a ports <<<"$(tl_free_ports udp 2)"
tl_stream_site "$work/lab" "$work/lab/live.yaml" "${ports[@]}"
sed -i -e '/^ *background: /d' -e '/^backgrounds:/,/^[^ ]/{/^backgrounds:/d;/^ /d}' "$work/lab/live.yaml"
echo 'backgrounds: {adaptive: true, learn_s: 2, learn_samples: 10, refresh_cache_s: 1}' >>"$work/lab/live.yaml"
"$occmap" check "$work/lab/live.yaml" >/dev/null || fail "the live lab's site is not valid: $("$occmap" check "$work/lab/live.yaml" 2>&1)"
for n in 1 2; do tl_serve "$work/lab" $n "${ports[$((n - 1))]}"; done
mkdir -p "$work/live-cache"
printf 'not a folder' >"$work/live-cache/backgrounds"
mosquitto_sub -h 127.0.0.1 -p "$broker_port" -t 'occmap/lab/edge/#' -F '%t' >"$work/published.txt" 2>/dev/null &
tl_track $!
log="$work/edge-live.log"
"$occmap" edge "$work/lab/live.yaml" --cameras cam1,cam2 --broker "$broker" --cache-dir "$work/live-cache" \
  --threads 1 >"$log" 2>&1 &
edge_pid=$!
tl_track $edge_pid
refresh_said() { grep -c "warning: camera $1: refreshing its cached background: .*live-cache/backgrounds" "$log"; }
for _ in $(seq 600); do [ "$(refresh_said cam1)" -ge 1 ] && [ "$(refresh_said cam2)" -ge 1 ] && break; sleep 0.1; done
[ "$(refresh_said cam1)" -ge 1 ] && [ "$(refresh_said cam2)" -ge 1 ] && ok ||
  fail "the live edge said no failed refresh in 60 s: $(tail -5 "$log")"
before=$(lines "$work/published.txt")
sleep 4  # four more refresh periods, all failing
after=$(lines "$work/published.txt")
echo "live edge: $before messages published by the first failed refresh, $after four seconds later"
[ "$after" -gt $((before + 20)) ] && ok || fail "the edge did not go on publishing after its refreshes failed ($before -> $after)"
kill -INT $edge_pid
wait $edge_pid
code=$?
[ $code -eq 0 ] && ok || fail "the live edge exited $code: $(tail -3 "$log")"
for cam in cam1 cam2; do
  # Said once for the whole failing spell (and once at start-up, for the learned entry).
  [ "$(refresh_said $cam)" = 1 ] && ok || fail "camera $cam: the failing refresh said $(refresh_said $cam) times, not once"
  [ "$(grep -c "warning: could not write the background cache .*$cam-.*going on without it" "$log")" = 1 ] && ok ||
    fail "camera $cam: the start-up's learned entry not said once: $(grep warning "$log")"
  line=$(grep "^cached background of $cam: " "$log")
  echo "$line"
  failed=$(sed -n 's/.*: 0 refreshes, \([0-9]*\) failed; failing: camera .*: refreshing its cached background: .*/\1/p' <<<"$line")
  [ -n "$failed" ] && [ "$failed" -ge 4 ] && ok || fail "camera $cam: the edge's last line does not report 4 or more failed refreshes: $line"
done

tl_finish cache_unwritable
