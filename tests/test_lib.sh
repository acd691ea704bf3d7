# Shared helpers of the shell tests (sourced, not run): pass/fail counters, a work folder removed
# at exit with every process registered in it, a rendered lab scene, free loopback ports, the
# lab's cameras served as looping UDP streams by ffmpeg, and a mosquitto broker of the test's own.
#
#   source "$(dirname "$0")/test_lib.sh"
#   tl_init                       # $work, counters, clean-up at exit
#   tl_synth_lab "$occmap" "$work/lab" --video --frames 100
#   if cond; then ok; else fail "what went wrong"; fi
#   tl_finish "my_test"           # prints the counts; the test's exit status
#
# Processes started with tl_track PID are killed (SIGKILL) at exit, brokers stopped by PID.

python=${PYTHON:-python3}
failures=0
passed=0
tl_pids=()

fail() {
  echo "FAIL $*"
  failures=$((failures + 1))
}
ok() { passed=$((passed + 1)); }

tl_track() { tl_pids+=("$1"); }

tl_cleanup() {
  local p
  for p in "${tl_pids[@]}"; do
    if [ -n "$p" ]; then kill -KILL "$p" 2>/dev/null; wait "$p" 2>/dev/null; fi
  done
  [ -n "${work:-}" ] && rm -rf "$work"
}

# A fresh work folder in $work, removed at exit with the tracked processes.
tl_init() {
  work=$(mktemp -d)
  trap tl_cleanup EXIT
}

# tl_require_ffmpeg: the test is skipped (exit 0, with a message) without the ffmpeg program.
tl_require_ffmpeg() {
  if ! command -v ffmpeg >/dev/null; then
    echo "SKIP: no ffmpeg program (scripts/install-deps.sh installs it)"
    exit 0
  fi
}

# tl_finish NAME: the counts, and the status of the test (0 when nothing failed).
tl_finish() {
  echo "${1:+$1: }$passed passed, $failures failed"
  [ "$failures" -eq 0 ]
}

# tl_synth_lab OCCMAP DIR [synth options...]: the lab scene rendered into DIR (exits on failure).
# Exits 0 with SKIP when the MQTT broker or its client is missing.
tl_need_mosquitto() {
  local tool
  for tool in /usr/sbin/mosquitto mosquitto_pub; do
    command -v "$tool" >/dev/null || { echo "SKIP: no $tool (scripts/install-deps.sh installs it)"; exit 0; }
  done
}

# The plaza at a quarter of its size, FRAMES frames, into DIR (backgrounds learned).
tl_synth_small_plaza() {
  local occmap=$1 dir=$2 frames=$3
  "$occmap" synth --scene plaza --scale 0.25 --frames "$frames" --out "$dir" >"$dir.synth.log" 2>&1 ||
    { echo "FAIL synth --scene plaza: $(tail -2 "$dir.synth.log")"; exit 1; }
}

# tl_unsettle SITE: the site's learned backgrounds not settled (settle: false after adaptive:
# true), as edges do (settling needs the fused map while they learn); exits when it cannot.
tl_unsettle() {
  sed -i 's/^  adaptive: true$/  adaptive: true\n  settle: false/' "$1"
  grep -q "settle: false" "$1" || { echo "FAIL could not turn settling off in $1 (not adaptive?)"; exit 1; }
}

tl_synth_lab() {
  local occmap=$1 dir=$2
  shift 2
  "$occmap" synth --scene lab --out "$dir" "$@" >/dev/null 2>&1 || {
    echo "FAIL synth --scene lab $*"
    exit 1
  }
}

# lines FILE: its number of lines (0 when absent).
lines() { [ -f "$1" ] && wc -l <"$1" || echo 0; }

# tl_free_ports KIND N: N free ports on 127.0.0.1 (KIND tcp or udp), space-separated.
tl_free_ports() {
  "$python" -c "
import socket, sys
kind = socket.SOCK_DGRAM if sys.argv[1] == 'udp' else socket.SOCK_STREAM
socks = [socket.socket(socket.AF_INET, kind) for _ in range(int(sys.argv[2]))]
for s in socks: s.bind(('127.0.0.1', 0))
print(' '.join(str(s.getsockname()[1]) for s in socks))" "$1" "$2"
}

# --- Live streams: the lab's cameras served by ffmpeg as MPEG-TS over UDP, looping, in real time.
# tl_stream_site LAB_DIR OUT_SITE PORT...: LAB_DIR/site.yaml with camera n read from udp port n.
tl_stream_site() {
  local lab=$1 site=$2
  shift 2
  local args=() n=1 port
  for port in "$@"; do
    args+=(-e "s#{video: frames/cam$n.mp4}#{stream: 'udp://127.0.0.1:$port?overrun_nonfatal=1\&fifo_size=100000'}#")
    n=$((n + 1))
  done
  sed "${args[@]}" "$lab/site.yaml" >"$site"
  grep -q 'stream:' "$site" || {
    echo "FAIL: no stream sources in $site"
    exit 1
  }
}

# tl_serve LAB_DIR N PORT: camera N's video sent to PORT, looped, in real time; its PID in
# tl_sender[N] (tracked).
declare -a tl_sender
tl_serve() {
  ffmpeg -loglevel error -re -stream_loop -1 -i "$1/frames/cam$2.mp4" -c copy -f mpegts \
    "udp://127.0.0.1:$3?pkt_size=1316" >/dev/null 2>&1 &
  tl_sender[$2]=$!
  tl_track $!
}
# tl_stop_serving N: camera N's sender stopped.
tl_stop_serving() {
  kill "${tl_sender[$1]}" 2>/dev/null
  wait "${tl_sender[$1]}" 2>/dev/null
}

# --- MQTT (scripts/lib/mosquitto.sh): tl_broker starts mosquitto on 127.0.0.1 at a free port
# ($broker_port, $broker_pid), with a generated config in $work; tl_restart_broker [PAUSE_S]
# stops it and starts it again on that port. Both track it (stopped at exit); both exit when it
# does not start.
source "$(dirname "${BASH_SOURCE[0]}")/../scripts/lib/mosquitto.sh"
tl_broker() {
  mosquitto_start "$work" || exit 1
  broker_port=$mosquitto_port
  broker_pid=$mosquitto_pid
  tl_track "$broker_pid"
}
tl_restart_broker() {
  mosquitto_restart "$work" "$@" || exit 1
  broker_pid=$mosquitto_pid
  tl_track "$broker_pid"
}

# summary_field DIR EXPR: a Python expression over summary.json's object `s` (-1 when unreadable).
summary_field() {
  "$python" -c "import json, sys; s = json.load(open(sys.argv[1] + '/summary.json')); print($2)" "$1" 2>/dev/null ||
    echo -1
}

# tl_wait_for LOG TEXT SECONDS: waits until LOG holds TEXT (a fuse or serve "subscribed to"), at
# most SECONDS; the test goes on either way and finds out from what follows.
tl_wait_for() {
  local k
  for k in $(seq $(($3 * 20))); do grep -q "$2" "$1" 2>/dev/null && return 0; sleep 0.05; done
  return 1
}

# tl_edges_then_fuse FUSE_PID FUSE_LOG SECONDS EDGE_PID...: every edge must exit 0, then the fuse
# must finish within SECONDS and exit 0 (counted as one ok, or failed with the logs' tails).
tl_edges_then_fuse() {
  local fuse_pid=$1 fuse_log=$2 seconds=$3 p k code
  shift 3
  for p in "$@"; do wait "$p" || fail "an edge exited $? ($(cat "$(dirname "$fuse_log")"/edge-*.log | tail -3))"; done
  for k in $(seq $((seconds * 20))); do kill -0 "$fuse_pid" 2>/dev/null || break; sleep 0.05; done
  if kill -0 "$fuse_pid" 2>/dev/null; then
    fail "the fuse did not finish after every edge ended: $(tail -3 "$fuse_log")"
  else
    wait "$fuse_pid"
    code=$?
    [ $code -eq 0 ] && ok || fail "occmap fuse exited $code: $(tail -3 "$fuse_log")"
  fi
}
