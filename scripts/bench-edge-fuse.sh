#!/usr/bin/env bash
# The bench of `occmap edge` and `occmap fuse` (issue 17, item 4), with a mosquitto of its own on
# 127.0.0.1 (an ephemeral port, stopped at exit):
#  1. Per scene (lab; WILDTRACK and plaza at --scale SCALE, 0.5), FRAMES frames of H.264 rendered by
#     `occmap synth --video`: one `occmap edge` reads every camera; `occmap edge-sim --record`
#     keeps its messages. Bytes per camera-frame against the video's own (its files' bytes per
#     camera-frame), and the edge's CPU per camera-frame after its first message (decoding
#     included; the start-up apart). plaza-learned: the plaza with the backgrounds its edge learns
#     (backgrounds.adaptive, not settled), so with a fuse sending the edge its protections: also
#     the fuse's CPU per frame set and its latency (from the edge's read of a frame set to its
#     outputs written, summary.json's latency_ms; over files the edge waits for the protection of
#     the frame before, so edge and fuse go in step).
#  2. Per count in CAMERAS (4 16 64): a site repeating the WILDTRACK scene's 7 cameras that many
#     times; `occmap fuse` on it, and edges simulated by `occmap edge-sim --replay` (4 cameras per
#     process: 1, 4, 16 processes) sending the recorded messages again at RATE frame sets/s for
#     SECONDS, in step on the wall clock. The fuse's CPU per frame set (after its start-up), the
#     frame sets fused per second, and its latency from the frames' capture (the tick they were
#     sent at) to the frame set's outputs written (summary.json's latency_ms).
#
#   scripts/bench-edge-fuse.sh build/release/occmap [WORK_DIR]
#   PEOPLE=off FRAMES=100 RATE=10 SECONDS_PER_RUN=30 CAMERAS="4 16 64" SCENES="lab wildtrack plaza plaza-learned" scripts/bench-edge-fuse.sh ...
# BLOCK_PX=2 (or "[1, 2]"): the sites' changes in blocks (detection.block_px), as the edges send
# them; BLOCK_RULE=half: a block changed when half its pixels are (detection.block_rule).
set -euo pipefail
occmap=$(realpath "${1:?usage: bench-edge-fuse.sh OCCMAP [WORK_DIR]}")
work=$(realpath -m "${2:-/tmp/occmap-bench-edge-fuse}")
frames=${FRAMES:-100}
rate=${RATE:-10}
seconds=${SECONDS_PER_RUN:-30}
counts=${CAMERAS:-4 16 64}
scenes=${SCENES:-lab wildtrack plaza plaza-learned}
per_process=${CAMERAS_PER_EDGE:-4}
# PEOPLE=off: the fuse runs the floor AND alone (the site's people: section left out); else the scene's own
# people detector (WILDTRACK: explain).
people=${PEOPLE:-site}
block_px=${BLOCK_PX:-1}
block_rule=${BLOCK_RULE:-any}
warmup=${WARMUP_S:-5}
# SCALE: the WILDTRACK and plaza scenes' resolution (1: WILDTRACK's cameras' 1920x1080).
scene_scale=${SCALE:-0.5}
mkdir -p "$work"
pids=()
broker_pid=""
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
  [ -n "$broker_pid" ] && kill "$broker_pid" 2>/dev/null && wait "$broker_pid" 2>/dev/null
  true
}
trap cleanup EXIT
for tool in /usr/sbin/mosquitto mosquitto_sub /usr/bin/time python3; do
  command -v "$tool" >/dev/null || { echo "no $tool (scripts/install-deps.sh installs it)" >&2; exit 1; }
done

# CPU seconds (user + system) of a running process so far.
cpu_of() { awk -v hz="$(getconf CLK_TCK)" '{ print ($14 + $15) / hz }' "/proc/$1/stat"; }
# The occmap under a `/usr/bin/time` PID.
child_of() { for _ in $(seq 100); do c=$(pgrep -P "$1" | head -1) && [ -n "$c" ] && { echo "$c"; return; }; sleep 0.02; done; }
wait_for() {  # FILE TEXT SECONDS
  for _ in $(seq $(($3 * 20))); do grep -q "$2" "$1" 2>/dev/null && return 0; sleep 0.05; done
  echo "timed out waiting for '$2' in $1:" >&2; tail -5 "$1" >&2; exit 1
}

source "$(dirname "$0")/lib/mosquitto.sh"
# Queued messages: 64 simulated cameras outrun the default 1000 while the fuse starts.
mosquitto_start "$work" "max_queued_messages 100000" || exit 1
port=$mosquitto_port
broker_pid=$mosquitto_pid
broker="mqtt://127.0.0.1:$port"
echo "mosquitto on $broker ($(/usr/sbin/mosquitto -h 2>/dev/null | head -1))"
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"

# --- 1. Bytes per camera-frame and the edge's CPU, per scene.
printf '\n%-13s %8s %12s %12s %8s %14s %14s %16s\n' scene cameras "video B/f" "message B/f" "ratio" "edge CPU ms/f" \
  "fuse CPU ms/set" "p50/p99 ms"
for scene in $scenes; do
  dir="$work/$scene"
  scale=()
  [ "$scene" != lab ] && scale=(--scale "$scene_scale")
  learned=false
  [ "$scene" = plaza-learned ] && learned=true
  # Given backgrounds: the edge runs here without a fuse, and adaptive ones (the plaza's default)
  # are updated from the fuse's protections (an edge alone would wait for them). plaza-learned:
  # no given backgrounds, and a fuse.
  given=(--site-backgrounds)
  $learned && given=()
  if [ ! -f "$dir/site.yaml" ]; then
    nice "$occmap" synth --scene "${scene%-learned}" "${scale[@]}" "${given[@]}" --frames "$frames" --video --no-change-masks \
      --out "$dir" >"$work/synth-$scene.log" 2>&1
  fi
  if $learned; then
    # Learned and kept up at the edge; not settled (a start-up pass: the bench measures the steady state).
    sed 's/^  adaptive: true$/  adaptive: true\n  settle: false/' "$dir/site.yaml" >"$dir/site-edge.yaml"
    grep -q 'settle: false' "$dir/site-edge.yaml" || { echo "$scene: the site is not adaptive" >&2; exit 1; }
  else
    # Not the adaptive backgrounds (the plaza's): the scene's given ones instead (see above).
    sed 's/^\(  adaptive:\) true/\1 false/' "$dir/site.yaml" >"$dir/site-edge.yaml"
  fi
  if [ "$block_px" != 1 ]; then
    if grep -q '^detection:$' "$dir/site-edge.yaml"; then
      sed -i "s/^detection:\$/detection:\n  block_px: $block_px\n  block_rule: $block_rule/" "$dir/site-edge.yaml"
    else
      printf 'detection:\n  block_px: %s\n  block_rule: %s\n' "$block_px" "$block_rule" >>"$dir/site-edge.yaml"
    fi
  fi
  rm -rf "$dir/recorded"
  "$occmap" edge-sim "$dir/site-edge.yaml" --broker "$broker" --record "$dir/recorded" >"$work/record-$scene.log" 2>&1 &
  record_pid=$!
  pids+=("$record_pid")
  wait_for "$work/record-$scene.log" "subscribed" 10
  fuse_pid=""
  if $learned; then
    rm -rf "$dir/fuse"
    /usr/bin/time -f "%U %S" -o "$work/fuse-$scene.time" "$occmap" fuse "$dir/site-edge.yaml" --broker "$broker" \
      --out "$dir/fuse" --no-video --latency-budget-s 60 --dead-after-s 60 --start-wait-s 600 --no-cache \
      >"$work/fuse-$scene.log" 2>&1 &
    fuse_time_pid=$!
    fuse_pid=$(child_of $fuse_time_pid)
    pids+=("$fuse_pid")
    wait_for "$work/fuse-$scene.log" "subscribed to" 120
  fi
  # The edge's first message marks the end of its start-up.
  mosquitto_sub -h 127.0.0.1 -p "$port" -t "occmap/+/edge/+" -C 1 >/dev/null 2>&1 &
  first_pid=$!
  /usr/bin/time -f "%U %S" -o "$work/edge-$scene.time" "$occmap" edge "$dir/site-edge.yaml" --broker "$broker" --no-cache \
    >"$work/edge-$scene.log" 2>&1 &
  time_pid=$!
  edge_pid=$(child_of $time_pid)
  # The edge's first message (or its failure) ends the wait.
  while kill -0 $first_pid 2>/dev/null && kill -0 $time_pid 2>/dev/null; do sleep 0.01; done
  cpu_start=$(cpu_of "$edge_pid" 2>/dev/null || echo 0)
  fuse_cpu_start=0
  [ -n "$fuse_pid" ] && fuse_cpu_start=$(cpu_of "$fuse_pid" 2>/dev/null || echo 0)
  wait $time_pid || { echo "occmap edge failed on $scene: $(tail -2 "$work/edge-$scene.log")" >&2; exit 1; }
  kill $first_pid 2>/dev/null || true
  wait $record_pid
  [ -n "$fuse_pid" ] && { wait $fuse_time_pid || { echo "occmap fuse failed on $scene: $(tail -2 "$work/fuse-$scene.log")" >&2; exit 1; }; }
  cams=$(grep -c '^  - id:' "$dir/site.yaml")
  video=$(cat "$dir"/frames/*.mp4 | wc -c)
  python3 - "$work" "$scene" "$cams" "$frames" "$video" "$cpu_start" "$fuse_cpu_start" "$dir" <<'PY'
import json, os, re, sys
work, scene, cams, frames, video, cpu_start = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]), float(sys.argv[6])
fuse_cpu_start, scene_dir = float(sys.argv[7]), sys.argv[8]
rec = open(f"{work}/record-{scene}.log").read()
m = re.search(r"all: (\d+) messages, ([\d.]+) bytes per message \(([\d.]+) payload\)", rec)
messages, per_message = int(m.group(1)), float(m.group(2))
user, system = map(float, open(f"{work}/edge-{scene}.time").read().split()[-2:])
video_per_frame = video / (cams * frames)
steady_frames = max(1, messages - cams)
fuse = ""
if os.path.exists(f"{work}/fuse-{scene}.time") and os.path.exists(f"{scene_dir}/fuse/summary.json"):
    s = json.load(open(f"{scene_dir}/fuse/summary.json"))
    fuse_user, fuse_system = map(float, open(f"{work}/fuse-{scene}.time").read().split()[-2:])
    lat = s["latency_ms"]
    fuse = f" {1e3 * (fuse_user + fuse_system - fuse_cpu_start) / max(1, s['frames'] - 1):>14.1f} {lat['p50']:>7.1f} /{lat['p99']:>7.1f}"
print(f"{scene:<13} {cams:>8} {video_per_frame:>12.0f} {per_message:>12.0f} {100 * per_message / video_per_frame:>7.1f}% "
      f"{1e3 * (user + system - cpu_start) / steady_frames:>14.2f}{fuse}")
PY
done

# --- 2. One fuse, simulated edges: 4, 16, 64 cameras of the WILDTRACK scene.
[ -z "${counts// /}" ] && exit 0
wt="$work/wildtrack"
[ -d "$wt/recorded" ] || { echo "the WILDTRACK scene's recording is missing (SCENES must include wildtrack)" >&2; exit 1; }
printf '\n%8s %6s %8s %8s %12s %16s %16s %9s %9s %9s %6s %8s\n' cameras edges "sets" "sets/s" "fuse CPU ms" "p50/p99 ms" "all: p50/p99" \
  "1st ms" "late to s" "left out" "late" "peak MB"
for n in $counts; do
  site="$wt/site-$n.yaml"
  python3 - "$wt/site-edge.yaml" "$site" "$n" "$people" <<'PY'
import re, sys
src, dst, n, people = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
text = open(src).read()
head, rest = text.split("cameras:\n", 1)
blocks = re.findall(r"  - id: \S+\n(?:    .*\n)*", rest)
tail = rest[sum(len(b) for b in blocks):]
out = [head, "cameras:\n"]
for k in range(n):
    b = blocks[k % len(blocks)]
    out.append(re.sub(r"  - id: \S+", f"  - id: S{k + 1:02d}", b, count=1))
text = f"name: wildtrack-{n}\n".join(("".join(out) + tail).split('name: "wildtrack"\n', 1))
if people == "off":
    text = re.sub(r"\npeople:\n(?:  .*\n)*", "\n", text, count=1)
open(dst, "w").write(text)
PY
  out="$work/fuse-$n"
  rm -rf "$out"
  /usr/bin/time -f "%M %U %S" -o "$work/fuse-$n.time" "$occmap" fuse "$site" --broker "$broker" --out "$out" --no-video \
    --sync timestamp --cache-dir "$work/cache" >"$work/fuse-$n.log" 2>&1 &
  time_pid=$!
  fuse_pid=$(child_of $time_pid)
  pids+=("$fuse_pid")
  wait_for "$work/fuse-$n.log" "subscribed to" 600
  # The first tick: 3 s, and 1 s per simulated edge process to load the site and connect (16
  # processes loading a 64-camera site on 2 busy cores sent their first ticks up to 20 s late,
  # which counted as the fuse's latency).
  start=$(python3 -c "import time; print(f'{time.time() + 3 + ($n + $per_process - 1) // $per_process:.3f}')")
  # The latency in the steady state, from outside: each frame set's line appearing in the fuse's
  # tracks.jsonl (written with one write() per frame set) against its t_unix, the tick its
  # frames were sent at; frame sets of the first WARMUP_S seconds (the fuse's stages are made
  # on its first message) left out. Polled every 2 ms. Every frame set's (tick after the first,
  # latency) also goes to latency-N-all.txt: the start-up as a user sees it.
  python3 - "$out/tracks.jsonl" "$work/latency-$n.txt" "$start" "$warmup" "$fuse_pid" <<'PY' &
import json, os, sys, time
path, dst, start, warmup, pid = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
seen, buf, lat, lines_seen, steady_cpu = 0, b"", [], 0, None
every = open(dst.replace(".txt", "-all.txt"), "w")
hz = os.sysconf("SC_CLK_TCK")
while True:
    alive = os.path.exists(f"/proc/{pid}")
    try:
        with open(path, "rb") as f:
            f.seek(seen)
            chunk = f.read()
    except FileNotFoundError:
        chunk = b""
    now = time.time()
    seen += len(chunk)
    buf += chunk
    *lines, buf = buf.split(b"\n")
    for line in lines:
        t = json.loads(line)["t_unix"]
        if t >= start + warmup:
            if steady_cpu is None:  # the fuse's CPU and frame sets before the steady state
                stat = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
                steady_cpu = ((int(stat[11]) + int(stat[12])) / hz, lines_seen)
            lat.append(now - t)
        lines_seen += 1
        every.write(f"{t - start:.3f} {now - t:.4f}\n")
    if not alive:
        break
    time.sleep(0.002)
open(dst, "w").write(f"{steady_cpu[0] if steady_cpu else 0} {steady_cpu[1] if steady_cpu else 0}\n"
                     + " ".join(f"{v:.4f}" for v in lat))
PY
  tail_pid=$!
  replays=()
  edges=0
  for ((first = 0; first < n; first += per_process)); do
    count=$((n - first < per_process ? n - first : per_process))
    "$occmap" edge-sim "$site" --broker "$broker" --replay "$wt/recorded" --first-camera $first --cameras $count \
      --rate-hz "$rate" --start-unix "$start" --seconds "$seconds" >"$work/replay-$n-$first.log" 2>&1 &
    replays+=($!)
    pids+=($!)
    edges=$((edges + 1))
  done
  for p in "${replays[@]}"; do wait "$p" || { echo "a replay failed: $(cat "$work"/replay-$n-*.log | tail -3)" >&2; exit 1; }; done
  wait $time_pid || { echo "the fuse failed: $(tail -3 "$work/fuse-$n.log")" >&2; exit 1; }
  wait $tail_pid
  python3 - "$work" "$n" "$edges" "$rate" "$seconds" <<'PY'
import json, sys, glob, re
work, n, edges, rate, seconds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5])
s = json.load(open(f"{work}/fuse-{n}/summary.json"))
rss_kb, user, system = open(f"{work}/fuse-{n}.time").read().split()[-3:]
user, system = float(user), float(system)
sets = s["frames"]
left_out = sum(c.get("left_out", 0) for c in s["cameras"])
late = sum(c.get("late_messages", 0) for c in s["cameras"])
late_ticks = sum(int(re.search(r"(\d+) ticks late", open(f).read()).group(1)) for f in glob.glob(f"{work}/replay-{n}-*.log"))
lat = s["latency_ms"]
head, body = open(f"{work}/latency-{n}.txt").read().split("\n", 1)
steady_cpu, sets_before = float(head.split()[0]), int(head.split()[1])
steady = sorted(float(v) for v in body.split())
# The start-up: the first frame set's latency, and the tick (s after the first) of the last frame set
# over 200 ms (0: none).
every = [tuple(map(float, l.split())) for l in open(f"{work}/latency-{n}-all.txt")]
first_ms = 1e3 * every[0][1] if every else float("nan")
late_to = max((t - every[0][0] for t, v in every if v > 0.2), default=0.0)
pct = lambda q: 1e3 * steady[min(len(steady) - 1, max(0, int(-(-q * len(steady) // 1)) - 1))] if steady else float("nan")
print(f"{n:>8} {edges:>6} {sets:>8} {sets / seconds:>8.2f} {1e3 * (user + system - steady_cpu) / max(sets - sets_before, 1):>12.1f} "
      f"{pct(0.5):>7.1f} /{pct(0.99):>7.1f} {lat['p50']:>7.1f} /{lat['p99']:>7.1f} {first_ms:>9.0f} {late_to:>9.1f} {left_out:>9} {late:>6} {int(rss_kb) / 1024:>8.0f}"
      + (f"  ({late_ticks} replay ticks late)" if late_ticks else ""))
PY
done
