#!/usr/bin/env bash
# A run that learns its backgrounds and a run that reuses them from the cache give the same
# answer: the plaza (colour, adaptive, learned by mode) run twice with one cache folder, with
# the learned backgrounds settled (the default) and not; the second run must say "reused" and
# write the same detections, tracks and backgrounds.
set -uo pipefail
occmap=$(realpath "${1:?usage: learned_cache_test.sh OCCMAP_BINARY [FRAMES]}")
frames=${2:-80}
source "$(dirname "$0")/test_lib.sh"
tl_init
"$occmap" synth --scene plaza --scale 0.25 --frames "$frames" --out "$work/plaza" >"$work/synth.log" 2>&1 ||
  { echo "FAIL synth --scene plaza: $(tail -2 "$work/synth.log")"; exit 1; }
grep -q "adaptive: true" "$work/plaza/site.yaml" || { echo "FAIL the plaza's site is not adaptive"; exit 1; }
# Settled (the default for file sources) and not: each learned, then reused.
sed 's/^  adaptive: true$/  adaptive: true\n  settle: false/' "$work/plaza/site.yaml" >"$work/plaza/unsettled.yaml"
grep -q "settle: false" "$work/plaza/unsettled.yaml" || { echo "FAIL could not write the unsettled site"; exit 1; }
for site in site unsettled; do
  for run in learned reused; do
    "$occmap" run "$work/plaza/$site.yaml" --out "$work/$site-$run" --cache-dir "$work/cache" --no-video --no-wall-clock \
      --threads 1 >"$work/$site-$run.log" 2>&1 || fail "occmap run ($site, $run): $(tail -2 "$work/$site-$run.log")"
  done
  if grep -q "background learned" "$work/$site-learned.log"; then ok; else
    fail "the first run of $site did not learn: $(grep -m1 background "$work/$site-learned.log")"
  fi
  if [ "$(grep -c "background reused" "$work/$site-reused.log")" -eq 6 ]; then ok; else
    fail "the second run of $site did not reuse the six backgrounds: $(grep -m1 background "$work/$site-reused.log")"
  fi
  for f in detections.jsonl tracks.jsonl backgrounds/c1.png backgrounds/c4.png; do
    if cmp -s "$work/$site-learned/$f" "$work/$site-reused/$f"; then ok; else fail "$f differs between the learned and the reused run ($site)"; fi
  done
done
if [ "$(grep -c "settled over" "$work/site-learned.log")" -eq 6 ]; then ok; else
  fail "the learned run did not settle its six backgrounds: $(grep -m1 background "$work/site-learned.log")"
fi
if grep -q "settled over" "$work/unsettled-learned.log"; then fail "settle: false settled"; else ok; fi
# Unsettled backgrounds keep their alternatives (with chroma) in the cache; settled ones have none.
[ "$(ls "$work/cache/backgrounds/"*-alt-u.png 2>/dev/null | wc -l)" -eq 6 ] && ok || fail "not six alternatives' chroma in the cache"
tl_finish learned_cache
