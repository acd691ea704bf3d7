#!/usr/bin/env bash
# `occmap run` as a live process: outputs grow while it runs, SIGINT stops it cleanly (exit 0
# within 2 s, every output valid, no temporary file), a second signal exits at once with the
# outputs still valid, and kill -9 at random moments leaves every file valid up to its last
# whole line (KILL_TRIALS trials, default 20).
# Usage: live_test.sh OCCMAP_BINARY SOURCE_DIR [KILL_TRIALS]
set -uo pipefail
occmap=$1
src=$2
trials=${3:-20}
source "$src/tests/test_lib.sh"
tl_init

# The lab scene rendered to H.264 (200 frames at 10 fps), run slowed down to real time by
# --threads 1 and the mosaic video, so that there is a run to interrupt.
tl_synth_lab "$occmap" "$work/lab" --video --frames 200
site="$work/lab/site.yaml"

# check_outputs DIR [final]: tests/check_run_outputs.py.
check_outputs() { "$python" "$src/tests/check_run_outputs.py" "$@"; }

# 1. SIGINT while it runs: lines appear during the run, then exit 0 within 2 s, outputs final.
out="$work/sigint"
"$occmap" --threads 1 run "$site" --out "$out" --no-cache >"$work/sigint.log" 2>&1 &
pid=$!
for _ in $(seq 600); do
  [ "$(lines "$out/detections.jsonl")" -ge 40 ] && break
  sleep 0.05
done
before=$(lines "$out/detections.jsonl")
sleep 0.5
growing=$(lines "$out/detections.jsonl")
if [ "$before" -lt 40 ] || [ "$growing" -le "$before" ]; then
  fail "sigint: detections.jsonl did not grow while the run went on ($before, then $growing lines)"
else
  ok
fi
t0=$(date +%s.%N)
kill -INT $pid
wait $pid
code=$?
t1=$(date +%s.%N)
elapsed=$("$python" -c "print(round($t1 - $t0, 3))")
if [ $code -ne 0 ]; then
  fail "sigint: exit $code, want 0"; cat "$work/sigint.log"
elif ! "$python" -c "import sys; sys.exit(0 if $elapsed < 2.0 else 1)"; then
  fail "sigint: took $elapsed s to stop, want < 2"
else
  ok
fi
if check_outputs "$out" final; then ok; else fail "sigint: outputs"; fi
if grep -q '"stop_reason": "stop requested"' "$out/summary.json" 2>/dev/null; then ok; else fail "sigint: stop_reason"; fi
n=$(lines "$out/detections.jsonl")
if [ "$n" -gt 0 ] && [ "$n" -lt 200 ]; then ok; else fail "sigint: $n frame sets (expected a part of 200)"; fi
echo "sigint: stopped in $elapsed s after $n frame sets"

# 2. Two signals: the second exits at once (128 + 15), the outputs valid to their last line.
out="$work/twice"
"$occmap" --threads 1 run "$site" --out "$out" --no-cache >/dev/null 2>&1 &
pid=$!
for _ in $(seq 600); do
  [ "$(lines "$out/detections.jsonl")" -ge 20 ] && break
  sleep 0.05
done
kill -TERM $pid
kill -TERM $pid
wait $pid
code=$?
if [ $code -eq 143 ] || [ $code -eq 0 ]; then ok; else fail "twice: exit $code, want 143 (or 0 when the first stop won)"; fi
if check_outputs "$out"; then ok; else fail "twice: outputs"; fi

# 3. kill -9 at random moments: every file present valid up to its last whole line; the next
# run in the same folder removes the temporaries the killed one left.
bad=0
for k in $(seq "$trials"); do
  out="$work/kill$k"
  "$occmap" --threads 1 run "$site" --out "$out" --no-cache --summary-every-s 0.2 >/dev/null 2>&1 &
  pid=$!
  sleep "$("$python" -c "import random; print(round(random.uniform(0.3, 6.0), 2))")"
  kill -KILL $pid 2>/dev/null
  wait $pid 2>/dev/null
  # A temporary of summary.json may survive a kill -9 (it is being renamed): not an output.
  find "$out" -name '.tmp-*' -delete 2>/dev/null
  if ! msg=$(check_outputs "$out"); then
    bad=$((bad + 1))
    echo "kill -9 trial $k: $msg"
  fi
done
if [ $bad -eq 0 ]; then ok; else fail "kill -9: $bad of $trials trials left an invalid output"; fi
echo "kill -9: $trials trials, $bad with an invalid output"

tl_finish live_test
