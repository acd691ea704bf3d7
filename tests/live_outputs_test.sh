#!/usr/bin/env bash
# End-to-end checks of `occmap run`'s live outputs for other software: MQTT against a real
# mosquitto broker (127.0.0.1, an ephemeral port, a generated config, stopped by its PID),
# read with mosquitto_sub: Home Assistant discovery per zone, retained zone and line state,
# tracks, events with line crossings, stats, availability and the last will when the run is
# killed (kill -9); a broker that is not there; bad URLs; and the ROS map_server maps
# (orientation checked against the ground truth's people); occmap serve with both.
# Usage: live_outputs_test.sh OCCMAP_BINARY
set -uo pipefail
occmap=$1
work=$(mktemp -d)
broker_pid=""
sub_pid=""
run_pid=""
cleanup() {
  for pid in "$sub_pid" "$run_pid"; do
    if [ -n "$pid" ]; then kill -KILL "$pid" 2>/dev/null; wait "$pid" 2>/dev/null; fi
  done
  if [ -n "$broker_pid" ]; then kill -TERM "$broker_pid" 2>/dev/null; wait "$broker_pid" 2>/dev/null; fi
  rm -rf "$work"
}
trap cleanup EXIT
failures=0
passed=0
fail() { echo "FAIL $*"; failures=$((failures + 1)); }
ok() { passed=$((passed + 1)); }

for tool in /usr/sbin/mosquitto mosquitto_sub mosquitto_pub; do
  command -v "$tool" >/dev/null || { echo "FAIL $tool not found: install mosquitto and mosquitto-clients (scripts/install-deps.sh)"; exit 1; }
done

# --- A broker of our own.
source "$(dirname "$0")/../scripts/lib/mosquitto.sh"
mosquitto_start "$work" || exit 1
port=$mosquitto_port
broker_pid=$mosquitto_pid

# --- A rendered lab with a zone over the whole floor and a line across the middle.
"$occmap" synth --scene lab --frames 60 --scale 0.5 --out "$work/lab" >/dev/null || { echo "FAIL synth"; exit 1; }
cat >>"$work/lab/site.yaml" <<'YAML'
tracking:
  zones:
    - {name: Whole Room, polygon: [[0, 0], [9, 0], [9, 6.5], [0, 6.5]]}
  lines:
    - {name: middle, from: [4.5, 0], to: [4.5, 6.5]}
YAML
url="mqtt://127.0.0.1:$port"

# --- A whole run, watched by a subscriber.
# The map is a binary PNG: the text log leaves it out, the retained check below reads it.
mosquitto_sub -h 127.0.0.1 -p "$port" -t 'occmap/#' -t 'homeassistant/#' -T 'occmap/lab/map' -F '%r %t %p' \
  >"$work/sub.log" 2>&1 &
sub_pid=$!
sleep 0.3
if "$occmap" run "$work/lab/site.yaml" --out "$work/run" --no-cache --no-video --mqtt "$url" >"$work/run.log" 2>&1; then ok; else
  fail "run with --mqtt: exit $?"; tail -5 "$work/run.log"; fi
# The run's last message is its "offline": wait for it (a loaded machine delivers late), then stop.
for _ in $(seq 100); do grep -q ' occmap/lab/available offline' "$work/sub.log" && break; sleep 0.1; done
sleep 0.2
kill "$sub_pid"; wait "$sub_pid" 2>/dev/null; sub_pid=""
python3 - "$work" <<'PY' && ok || fail "messages of the run"
import json, sys
work = sys.argv[1]
msgs = []
for line in open(f"{work}/sub.log"):
    retain, topic, payload = (line.rstrip("\n").split(" ", 2) + ["", ""])[:3]
    msgs.append((topic, payload))
def on(topic): return [p for t, p in msgs if t == topic]
frames = sum(1 for _ in open(f"{work}/run/detections.jsonl"))
tracks = [json.loads(p) for p in on("occmap/lab/tracks")]
assert len(tracks) == frames, (len(tracks), frames)
assert tracks == [json.loads(l) for l in open(f"{work}/run/tracks.jsonl")], "tracks: the tracks.jsonl lines"
events = [json.loads(p) for p in on("occmap/lab/events")]
assert events == [json.loads(l) for l in open(f"{work}/run/events.jsonl")], "events: the events.jsonl lines"
crossings = [e for e in events if e.get("event") == "cross"]
assert crossings and all(e["line"] == "middle" and e["direction"] in ("in", "out") for e in crossings), crossings
avail = on("occmap/lab/available")
assert avail[0] == "online" and avail[-1] == "offline", avail
counts = on("occmap/lab/zones/whole_room/count")
assert counts and int(counts[-1]) >= 0, counts
assert on("occmap/lab/zones/whole_room/occupied")[-1] in ("ON", "OFF")
stats = [json.loads(p) for p in on("occmap/lab/stats")]
assert stats and stats[-1]["frames"] == frames and stats[-1]["mqtt"]["dropped"] == 0, stats[-1:]
occ = json.loads(on("homeassistant/binary_sensor/occmap_lab/zone_whole_room_occupied/config")[-1])
assert occ["device_class"] == "occupancy" and occ["state_topic"] == "occmap/lab/zones/whole_room/occupied", occ
cnt = json.loads(on("homeassistant/sensor/occmap_lab/zone_whole_room_count/config")[-1])
assert cnt["state_class"] == "measurement" and cnt["availability_topic"] == "occmap/lab/available", cnt
line_in = json.loads(on("homeassistant/sensor/occmap_lab/line_middle_in/config")[-1])
assert line_in["state_topic"] == "occmap/lab/lines/middle/in", line_in
summary = json.load(open(f"{work}/run/summary.json"))
lines = summary["tracking"]["lines"]
assert lines == [{"name": "middle", "in": sum(e["direction"] == "in" for e in crossings),
                  "out": sum(e["direction"] == "out" for e in crossings)}], lines
print(f"mqtt: {frames} frames, {len(events)} events ({len(crossings)} crossings), {len(stats)} stats messages")
PY

# --- What stays on the broker: the retained state and the discovery configs.
mosquitto_sub -h 127.0.0.1 -p "$port" -t 'occmap/lab/#' -t 'homeassistant/#' -T 'occmap/lab/map' --retained-only -W 2 \
  -F '%r %t %p' >"$work/retained.log" 2>/dev/null
mosquitto_sub -h 127.0.0.1 -p "$port" -t 'occmap/lab/map' --retained-only -C 1 -W 2 -N >"$work/map.png" 2>/dev/null
python3 - "$work" <<'PY' && ok || fail "retained state"
import json, sys
work = sys.argv[1]
retained = {}
for line in open(f"{work}/retained.log"):
    r, topic, payload = (line.rstrip("\n").split(" ", 2) + ["", ""])[:3]
    assert r == "1", line
    retained[topic] = payload
last_counts = [l for l in open(f"{work}/run/events.jsonl") if '"line"' in l]
assert retained["occmap/lab/available"] == "offline", retained.get("occmap/lab/available")
for t in ["occmap/lab/zones/whole_room/count", "occmap/lab/zones/whole_room/occupied", "occmap/lab/lines/middle/in",
          "occmap/lab/lines/middle/out", "homeassistant/binary_sensor/occmap_lab/zone_whole_room_occupied/config",
          "homeassistant/sensor/occmap_lab/zone_whole_room_count/config"]:
    assert t in retained, t
last = json.loads(last_counts[-1])
assert int(retained["occmap/lab/lines/middle/in"]) == last["in"] and int(retained["occmap/lab/lines/middle/out"]) == last["out"]
assert "occmap/lab/tracks" not in retained
png = open(f"{work}/map.png", "rb").read()
assert png[:8] == b"\x89PNG\r\n\x1a\n", png[:16]
cam = json.loads(retained["homeassistant/image/occmap_lab/map/config"])
assert cam["image_topic"] == "occmap/lab/map" and cam["content_type"] == "image/png", cam
PY

# --- The zone and the line removed from the site (issue 38's bar): the next run, with no zones
# at all, clears their retained configs and states, and Home Assistant still gets the floor's
# person count, the run's state, the map and each camera.
sed '/^tracking:/,$d' "$work/lab/site.yaml" >"$work/lab/nozones.yaml"
if "$occmap" run "$work/lab/nozones.yaml" --out "$work/nozones" --no-cache --no-video --frames 10 --mqtt "$url" \
    >"$work/nozones.log" 2>&1; then ok; else fail "run without zones: exit $?"; tail -5 "$work/nozones.log"; fi
mosquitto_sub -h 127.0.0.1 -p "$port" -t 'occmap/lab/#' -t 'homeassistant/#' -T 'occmap/lab/map' --retained-only -W 2 \
  -F '%r %t %p' >"$work/retained2.log" 2>/dev/null
python3 - "$work" <<'PY' && ok || fail "no zones: discovery of the floor and the cameras, the removed zone cleared"
import json, sys
work = sys.argv[1]
retained = {}
for line in open(f"{work}/retained2.log"):
    r, topic, payload = (line.rstrip("\n").split(" ", 2) + ["", ""])[:3]
    retained[topic] = payload
gone = [t for t in retained if "whole_room" in t or "/middle" in t or "line_middle" in t]
assert not gone, f"still retained: {gone}"
people = json.loads(retained["homeassistant/sensor/occmap_lab/people/config"])
assert people["state_topic"] == "occmap/lab/people" and people["default_entity_id"] == "sensor.occmap_lab_people", people
assert people["origin"]["name"] == "occmap" and "object_id" not in people, people
assert int(retained["occmap/lab/people"]) >= 0
run = json.loads(retained["homeassistant/sensor/occmap_lab/run_state/config"])
assert run["state_topic"] == "occmap/lab/run" and retained["occmap/lab/run"] == "ended", (run, retained.get("occmap/lab/run"))
assert json.loads(retained["homeassistant/image/occmap_lab/map/config"])["image_topic"] == "occmap/lab/map"
for cam in ["cam1", "cam2", "cam3", "cam4"]:
    fps = json.loads(retained[f"homeassistant/sensor/occmap_lab/camera_{cam}_fps/config"])
    assert fps["state_topic"] == f"occmap/lab/cameras/{cam}/fps" and fps["unit_of_measurement"] == "fps", fps
    assert f"homeassistant/sensor/occmap_lab/camera_{cam}_state/config" in retained
    assert f"occmap/lab/cameras/{cam}/state" in retained
print(f"no zones: {sum(t.startswith('homeassistant/') for t in retained)} discovery configs retained, the zone and the line cleared")
PY

# --- kill -9 during a run: the broker publishes the last will, "offline".
mosquitto_sub -h 127.0.0.1 -p "$port" -t 'occmap/lab/available' -F '%r %p' >"$work/will.log" 2>&1 &
sub_pid=$!
sleep 0.3
"$occmap" run "$work/lab/site.yaml" --out "$work/killed" --no-cache --mqtt "$url" >/dev/null 2>&1 &
run_pid=$!
# The retained "offline" of the previous run comes first; wait for this run's "online", then
# freeze the run (it cannot finish and say "offline" itself) and kill it.
for _ in $(seq 400); do grep -q '^0 online' "$work/will.log" && break; sleep 0.01; done
if kill -STOP "$run_pid" 2>/dev/null; then
  before=$(grep -c 'offline' "$work/will.log")
  kill -KILL "$run_pid"; wait "$run_pid" 2>/dev/null; run_pid=""
  for _ in $(seq 100); do [ "$(grep -c 'offline' "$work/will.log")" -gt "$before" ] && break; sleep 0.05; done
  if [ "$(grep -c '^0 offline' "$work/will.log")" -ge 1 ] && [ "$(grep -c 'offline' "$work/will.log")" -gt "$before" ]; then ok; else
    fail "no last will after kill -9:"; cat "$work/will.log"; fi
else
  fail "the run ended before it could be killed"; cat "$work/will.log"
fi
kill "$sub_pid"; wait "$sub_pid" 2>/dev/null; sub_pid=""

# --- No broker there: the run goes on, counts what it dropped, exits 0.
closed=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
if "$occmap" run "$work/lab/site.yaml" --out "$work/nobroker" --no-cache --no-video --frames 10 \
    --mqtt "mqtt://127.0.0.1:$closed" >"$work/nobroker.log" 2>&1 && grep -q 'mqtt: .*dropped' "$work/nobroker.log" \
    && [ -s "$work/nobroker/tracks.jsonl" ]; then ok; else fail "run without a broker"; tail -5 "$work/nobroker.log"; fi

# --- Bad URLs and site blocks: exit 2 with the field named.
expect2() {  # expect2 NAME PATTERN -- command...
  local name=$1 pattern=$2; shift 3
  local out; out=$("$@" 2>&1); local got=$?
  if [ "$got" = 2 ] && grep -qE -- "$pattern" <<<"$out"; then ok; else fail "$name: exit $got: $out"; fi
}
expect2 bad_url "--mqtt: expected mqtt://HOST\[:PORT\], found 'http://x'" -- "$occmap" run "$work/lab/site.yaml" --out "$work/x" --mqtt http://x
expect2 bad_port "a port in 1..65535" -- "$occmap" run "$work/lab/site.yaml" --out "$work/x" --mqtt mqtt://h:70000
cp "$work/lab/site.yaml" "$work/lab/bad.yaml"
printf 'outputs:\n  mqtt:\n    url: mqtts://broker\n' >>"$work/lab/bad.yaml"
line=$(grep -n 'url: mqtts' "$work/lab/bad.yaml" | cut -d: -f1)
expect2 bad_site_url "bad.yaml:$line: outputs.mqtt.url: expected mqtt://HOST\[:PORT\] \(TLS is not supported\)" -- \
  "$occmap" run "$work/lab/bad.yaml" --out "$work/x"
expect2 ros_frame_without_dir "need --ros-map DIR" -- "$occmap" run "$work/lab/site.yaml" --out "$work/x" --ros-map-frame 3

# --- ROS maps: a frame's and the static map; the frame's occupied cells under the people.
if "$occmap" run "$work/lab/site.yaml" --out "$work/ros" --no-cache --no-video --ros-map "$work/ros/map" --ros-map-frame 30 --ros-map-static-fraction 0.1 \
    >"$work/ros.log" 2>&1; then ok; else fail "run with --ros-map"; tail -5 "$work/ros.log"; fi
python3 - "$work" <<'PY' && ok || fail "ROS maps"
import json, sys
work = sys.argv[1]
def read_map(path):
    meta = {}
    for line in open(path):
        k, v = line.split(":", 1)
        meta[k.strip()] = v.strip()
    data = open(f"{work}/ros/map/{meta['image']}", "rb").read()
    head = data.split(b"\n", 4)
    assert head[0] == b"P5", head[0]
    w, h = map(int, head[2].split())
    assert head[3] == b"255"
    pixels = head[4]
    assert len(pixels) == w * h
    return meta, w, h, pixels
meta, w, h, px = read_map(f"{work}/ros/map/frame_000030.yaml")
assert meta["mode"] == "trinary" and meta["resolution"] == "0.02" and meta["origin"] == "[0, 0, 0]", meta
assert (w, h) == (450, 325), (w, h)
assert set(px) <= {0, 205, 254}, set(px)
gt = [json.loads(l) for l in open(f"{work}/lab/ground_truth.jsonl")]
people = [o for o in gt[30]["objects"] if o["class"] == "person"]
def occupied_near(x, y, flip=False):
    i, j = int(x / 0.02), int(y / 0.02)
    row = (h - 1 - j) if not flip else j
    return any(px[r * w + c] == 0 for r in range(max(0, row - 8), min(h, row + 9)) for c in range(max(0, i - 8), min(w, i + 9)))
hits = sum(occupied_near(o["x_m"], o["y_m"]) for o in people)
flipped = sum(occupied_near(o["x_m"], o["y_m"], flip=True) for o in people)
assert people and hits == len(people), (hits, len(people))
assert flipped < hits, ("the map is upside down?", flipped, hits)
smeta, sw, sh, spx = read_map(f"{work}/ros/map/static.yaml")
assert (sw, sh) == (w, h) and 0 in spx and 254 in spx, "static map: occupied and free cells"
print(f"ros: frame 30 has occupied cells under all {len(people)} people ({flipped} when flipped)")
PY

# --- occmap serve: the same MQTT and ROS map outputs, the same checks of --frames and --start.
expect2 serve_bad_url "--mqtt: expected mqtt://HOST" -- "$occmap" serve "$work/lab/site.yaml" --out "$work/x" --mqtt http://x
expect2 serve_frames_0 "--frames" -- "$occmap" serve "$work/lab/site.yaml" --out "$work/x" --frames 0
expect2 serve_start_negative "--start" -- "$occmap" serve "$work/lab/site.yaml" --out "$work/x" --start -1
mosquitto_sub -h 127.0.0.1 -p "$port" -t 'occmap/lab/tracks' -F '%t %p' >"$work/serve_sub.log" 2>&1 &
sub_pid=$!
"$occmap" serve "$work/lab/site.yaml" --listen 127.0.0.1:0 --out "$work/serve" --no-cache --no-video --no-pace \
  --frames 40 --mqtt "$url" --ros-map "$work/serve/map" >"$work/serve.log" 2>&1 &
run_pid=$!
for _ in $(seq 300); do  # the run ends with the file inputs; the server stays up until a signal
  grep -q '"running": false' "$work/serve/summary.json" 2>/dev/null && break
  sleep 0.1
done
sleep 0.5
kill -TERM $run_pid
wait $run_pid
code=$?
run_pid=""
kill -TERM $sub_pid 2>/dev/null
wait $sub_pid 2>/dev/null
sub_pid=""
n=$(grep -c '^occmap/lab/tracks ' "$work/serve_sub.log")
echo "serve: exit $code, $n tracks messages, $(ls "$work/serve/map" 2>/dev/null | tr '\n' ' ')"
if [ "$code" = 0 ] && [ "$n" -ge 30 ]; then ok; else fail "serve --mqtt: exit $code, $n tracks messages"; tail -5 "$work/serve.log"; fi
if [ -f "$work/serve/map/static.yaml" ] && grep -q "^mqtt: " "$work/serve.log"; then ok; else fail "serve --ros-map: no static.yaml or no mqtt line"; cat "$work/serve.log"; fi

echo "live_outputs_test: $passed passed, $failures failed"
[ "$failures" = 0 ]
