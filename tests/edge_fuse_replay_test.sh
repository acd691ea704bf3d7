#!/usr/bin/env bash
# The fuse does not trust the broker (issue 39): through a mosquitto of the test's own
# (127.0.0.1, an ephemeral port), messages published on the edges' topics after the fuse
# subscribed and before the edge starts, then the lab's edge of every camera over files. The
# fuse's detections, tracks and MOT file equal those of a fuse that got the genuine messages
# alone, with every frame set once, and summary.json counts what it dropped:
#   1. a copy of camera cam2's message of frame 3 (it fused frame set 3 twice);
#   2. copies of cam2's frames 5-9;
#   3. copies of every camera's frames 5-9 (the fuse began at frame 5, frames 0-4 lost);
#   4. every camera's frames 5-9 with their header intact and a random payload (frames lost,
#      every camera counted late).
#
#   tests/edge_fuse_replay_test.sh OCCMAP_BINARY
set -uo pipefail
occmap=$(realpath "${1:?usage: edge_fuse_replay_test.sh OCCMAP_BINARY}")
source "$(dirname "$0")/test_lib.sh"
tl_need_mosquitto
tl_init
frames=20
tl_synth_lab "$occmap" "$work/lab" --video --frames $frames
tl_broker
broker="mqtt://127.0.0.1:$broker_port"
common=(--cache-dir "$work/cache" --threads 1)
outputs=(detections.jsonl tracks.jsonl tracks_mot.csv)

# fuse_with NAME [FILE...]: a fuse on prefix t/NAME; once subscribed, each FILE published (QoS 1)
# on the topic its name gives (TOPIC__N.bin, "__" for "/"); then an edge of every camera. The
# genuine run (ref) records every edge message as "topic hexpayload" lines in $work/ref.msgs.
fuse_with() {
  local name=$1 f topic fuse_pid edge_pid rec_pid=
  shift
  "$occmap" fuse "$work/lab/site.yaml" --broker "$broker" --topic-prefix "t/$name" --out "$work/$name" --no-video \
    --no-wall-clock --latency-budget-s 60 --dead-after-s 60 "${common[@]}" >"$work/$name.log" 2>&1 &
  fuse_pid=$!
  tl_track $fuse_pid
  tl_wait_for "$work/$name.log" "subscribed to" 60 || fail "$name: the fuse did not subscribe: $(tail -3 "$work/$name.log")"
  if [ "$name" = ref ]; then
    mosquitto_sub -h 127.0.0.1 -p "$broker_port" -q 1 -t "t/ref/edge/+" -F '%t %x' >"$work/ref.msgs" 2>&1 &
    rec_pid=$!
    tl_track $rec_pid
    sleep 0.3
  fi
  for f in "$@"; do
    topic=$(basename "$f" .bin)
    topic=${topic%__*}
    mosquitto_pub -h 127.0.0.1 -p "$broker_port" -q 1 -t "t/$name/edge/${topic//__//}" -f "$f" ||
      fail "$name: mosquitto_pub $f"
  done
  "$occmap" edge "$work/lab/site.yaml" --broker "$broker" --topic-prefix "t/$name" "${common[@]}" \
    >"$work/edge-$name.log" 2>&1 &
  edge_pid=$!
  tl_track $edge_pid
  tl_edges_then_fuse $fuse_pid "$work/$name.log" 60 $edge_pid
  if [ -n "$rec_pid" ]; then
    sleep 0.3
    kill "$rec_pid" 2>/dev/null
  fi
}

# same_as_ref NAME: the outputs equal ref's, and frame sets are each once.
same_as_ref() {
  local f
  for f in "${outputs[@]}"; do
    cmp -s "$work/ref/$f" "$work/$1/$f" && ok ||
      fail "$1: $f differs from the genuine run's ($(lines "$work/ref/$f") vs $(lines "$work/$1/$f") lines)"
  done
  [ "$(summary_field "$work/$1" "s['frames']")" = $frames ] && ok ||
    fail "$1: $frames frame sets expected, found $(summary_field "$work/$1" "s['frames']")"
}

# counts NAME FIELD: FIELD per camera in NAME's summary.json, as "cam1=N cam2=N ...".
counts() {
  summary_field "$work/$1" "' '.join(f\"{c['id']}={c.get('$2')}\" for c in s['cameras'])"
}

fuse_with ref
n_msgs=$(grep -c " " "$work/ref.msgs")
[ "$n_msgs" -ge $((4 * frames)) ] && ok || fail "ref: $n_msgs edge messages recorded, expected >= $((4 * frames))"
[ "$(counts ref duplicate_messages)" = "cam1=0 cam2=0 cam3=0 cam4=0" ] && ok ||
  fail "ref: duplicates counted in a genuine run: $(counts ref duplicate_messages)"

# The recorded messages as files: copy CAM FIRST LAST into $work/NAME/ (genuine bytes), and junk
# CAM FIRST LAST (the genuine header, a random payload and checksum).
"$python" - "$work" <<'PY' || fail "could not cut the recorded messages"
import os, random, struct, sys
work = sys.argv[1]
msgs = {}
for line in open(f"{work}/ref.msgs"):
    topic, hexpayload = line.split()
    b = bytes.fromhex(hexpayload)
    if struct.unpack_from("<H", b, 6)[0] != 0:
        continue  # the end of the source
    msgs[(topic.rsplit("/", 1)[1], struct.unpack_from("<q", b, 36)[0])] = b
random.seed(39)
def put(folder, cams, frames, junk=False):
    os.makedirs(f"{work}/{folder}", exist_ok=True)
    for cam in cams:
        for f in frames:
            b = msgs[(cam, f)]
            if junk:
                n = random.randint(20, 200)
                b = bytearray(b[:78])
                struct.pack_into("<I", b, 72, n)
                b = bytes(b) + random.randbytes(n + 8)
            open(f"{work}/{folder}/{cam}__{f}.bin", "wb").write(b)
cams = ["cam1", "cam2", "cam3", "cam4"]
put("one_copy", ["cam2"], [3])
put("copies", ["cam2"], range(5, 10))
put("all_copies", cams, range(5, 10))
put("junk", cams, range(5, 10), junk=True)
PY

fuse_with one_copy "$work"/one_copy/*.bin
same_as_ref one_copy
[ "$(counts one_copy duplicate_messages)" = "cam1=0 cam2=1 cam3=0 cam4=0" ] && ok ||
  fail "one_copy: duplicates $(counts one_copy duplicate_messages)"

fuse_with copies "$work"/copies/*.bin
same_as_ref copies
[ "$(counts copies duplicate_messages)" = "cam1=0 cam2=5 cam3=0 cam4=0" ] && ok ||
  fail "copies: duplicates $(counts copies duplicate_messages)"

fuse_with all_copies "$work"/all_copies/*.bin
same_as_ref all_copies
[ "$(counts all_copies duplicate_messages)" = "cam1=5 cam2=5 cam3=5 cam4=5" ] && ok ||
  fail "all_copies: duplicates $(counts all_copies duplicate_messages)"
[ "$(counts all_copies late_messages)" = "cam1=0 cam2=0 cam3=0 cam4=0" ] && ok ||
  fail "all_copies: late $(counts all_copies late_messages)"

fuse_with junk "$work"/junk/*.bin
same_as_ref junk
[ "$(counts junk refused_messages)" = "cam1=5 cam2=5 cam3=5 cam4=5" ] && ok ||
  fail "junk: refused $(counts junk refused_messages)"
[ "$(counts junk late_messages)" = "cam1=0 cam2=0 cam3=0 cam4=0" ] && ok ||
  fail "junk: late $(counts junk late_messages)"
grep -q "checksum: expected" "$work/junk.log" && ok || fail "junk: the refusal not said: $(grep refused "$work/junk.log")"

tl_finish edge_fuse_replay
