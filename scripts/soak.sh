#!/usr/bin/env bash
# Soak: `occmap run` for MINUTES on the lab scene served as four looping live streams (ffmpeg,
# MPEG-TS over UDP on 127.0.0.1, in real time), with every output on: the videos, MQTT to a
# mosquitto of its own, ROS maps. Every 10 s the run's resident memory, open files and threads
# go into a CSV; at the end the first sample after the warm-up is printed beside the last.
# Not part of the test suite (it takes as long as asked).
#
#   scripts/soak.sh MINUTES [OCCMAP_BINARY] [OUT_DIR]     # defaults: build/release/occmap, soak-out
#   nice -n 19 scripts/soak.sh 30 &                        # on a shared machine
#
# OUT_DIR gets soak.csv (t_s, rss_kb, open_files, threads, frame_sets), run/ (the run's
# outputs), ros/ and run.log. Exit 0 when the run stopped cleanly (SIGINT, exit 0).
set -uo pipefail
minutes=${1:?usage: soak.sh MINUTES [OCCMAP_BINARY] [OUT_DIR]}
src=$(cd "$(dirname "$0")/.." && pwd)
occmap=$(realpath "${2:-$src/build/release/occmap}")
out=$(realpath -m "${3:-soak-out}")
# Samples before this are the start-up (tables, caches, arenas): resident memory climbs for
# about 8 minutes on this machine (docs/perf-log.md, 2026-12-03), so 10 by default.
warm_up_s=${SOAK_WARM_UP_S:-600}
every_s=10

source "$src/tests/test_lib.sh"
for tool in ffmpeg /usr/sbin/mosquitto mosquitto_pub; do
  command -v "$tool" >/dev/null || { echo "soak: $tool not found (scripts/install-deps.sh installs it)"; exit 2; }
done
tl_init
rm -rf "$out"
mkdir -p "$out"

# 20 s of the lab (200 frames at 10 frames a second) looped: people keep walking in and out.
tl_synth_lab "$occmap" "$work/lab" --video --frames 200
read -r -a ports <<<"$(tl_free_ports udp 4)"
tl_stream_site "$work/lab" "$work/lab/stream.yaml" "${ports[@]}"
for n in 1 2 3 4; do tl_serve "$work/lab" "$n" "${ports[$((n - 1))]}"; done
tl_broker

"$occmap" run "$work/lab/stream.yaml" --out "$out/run" --no-cache --mqtt "mqtt://127.0.0.1:$broker_port" \
  --ros-map "$out/ros" --ros-map-every-s 60 >"$out/run.log" 2>&1 &
pid=$!
tl_track $pid

frame_sets() { summary_field "$out/run" "s['frames']"; }
echo "t_s,rss_kb,open_files,threads,frame_sets" >"$out/soak.csv"
t0=$(date +%s)
end=$((t0 + minutes * 60))
while [ "$(date +%s)" -lt "$end" ]; do
  sleep "$every_s"
  if ! kill -0 $pid 2>/dev/null; then
    echo "soak: the run ended early:"
    tail -5 "$out/run.log"
    exit 1
  fi
  rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status")
  threads=$(awk '/^Threads:/ {print $2}' "/proc/$pid/status")
  files=$(ls "/proc/$pid/fd" | wc -l)
  echo "$(($(date +%s) - t0)),$rss,$files,$threads,$(frame_sets)" >>"$out/soak.csv"
done

kill -INT $pid
wait $pid
code=$?
echo "soak: $minutes min, run exit $code"
tail -3 "$out/run.log"
"$python" - "$out/soak.csv" "$warm_up_s" <<'PY'
import csv, sys
rows = [{k: int(v) for k, v in r.items()} for r in csv.DictReader(open(sys.argv[1]))]
warm = [r for r in rows if r["t_s"] >= int(sys.argv[2])] or rows
a, b = warm[0], rows[-1]
span_min = (b["t_s"] - a["t_s"]) / 60
frames = b["frame_sets"] - a["frame_sets"]
print(f"from t = {a['t_s']} s to {b['t_s']} s ({span_min:.1f} min, {frames} frame sets):")
print(f"  resident memory {a['rss_kb'] / 1024:.1f} -> {b['rss_kb'] / 1024:.1f} MB "
      f"(max {max(r['rss_kb'] for r in warm) / 1024:.1f}; {(b['rss_kb'] - a['rss_kb']) / 1024:+.1f} MB"
      + (f", {1024 * (b['rss_kb'] - a['rss_kb']) / frames:+.1f} bytes per frame set)" if frames > 0 else ")"))
print(f"  open files {a['open_files']} -> {b['open_files']} (max {max(r['open_files'] for r in warm)})")
print(f"  threads {a['threads']} -> {b['threads']} (max {max(r['threads'] for r in warm)})")
PY
[ $code -eq 0 ]
