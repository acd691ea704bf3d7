#!/usr/bin/env bash
# A run that learns its backgrounds and a run that reuses them from the cache give the same
# answer: the plaza (colour, adaptive, learned by mode) run twice with one cache folder; the
# second must say "reused" and write the same detections, tracks and backgrounds.
set -uo pipefail
occmap=$(realpath "${1:?usage: learned_cache_test.sh OCCMAP_BINARY [FRAMES]}")
frames=${2:-80}
source "$(dirname "$0")/test_lib.sh"
tl_init
"$occmap" synth --scene plaza --scale 0.25 --frames "$frames" --out "$work/plaza" >"$work/synth.log" 2>&1 ||
  { echo "FAIL synth --scene plaza: $(tail -2 "$work/synth.log")"; exit 1; }
grep -q "adaptive: true" "$work/plaza/site.yaml" || { echo "FAIL the plaza's site is not adaptive"; exit 1; }
for run in learned reused; do
  "$occmap" run "$work/plaza/site.yaml" --out "$work/$run" --cache-dir "$work/cache" --no-video --no-wall-clock \
    --threads 1 >"$work/$run.log" 2>&1 || fail "occmap run ($run): $(tail -2 "$work/$run.log")"
done
if grep -q "background learned" "$work/learned.log"; then ok; else fail "the first run did not learn: $(grep -m1 background "$work/learned.log")"; fi
if [ "$(grep -c "background reused" "$work/reused.log")" -eq 6 ]; then ok; else
  fail "the second run did not reuse the six backgrounds: $(grep -m1 background "$work/reused.log")"
fi
ls "$work/cache/backgrounds/"*-alt-u.png >/dev/null 2>&1 && ok || fail "no alternative chroma in the cache"
for f in detections.jsonl tracks.jsonl backgrounds/c1.png backgrounds/c4.png; do
  if cmp -s "$work/learned/$f" "$work/reused/$f"; then ok; else fail "$f differs between the learned and the reused run"; fi
done
tl_finish learned_cache
