#!/usr/bin/env bash
# A cache that cannot be written never stops a process (a cache is a head start, never an
# output): the cache folder is a regular file (the tests may run as root, whom no mode stops).
# 1. `occmap edge` x 2 and `occmap fuse` over the small plaza's files (adaptive, learned, not
#    settled) through a mosquitto of the test's own: the edges cannot cache their learned
#    backgrounds nor the tables, the fuse not its tables; each says so once per entry
#    ("could not write the ... cache <path>: <error>; going on without it") and every frame set
#    is fused.
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

tl_finish cache_unwritable
