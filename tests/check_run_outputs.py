#!/usr/bin/env python3
# Every output of an `occmap run` folder valid as a live run leaves it: whole JSON lines (the
# last one ends with a newline, frames consecutive), MOT rows of 10 columns, summary.json parses,
# each MP4 starts with its header (ftyp, moov) and holds whole fragments, no '.tmp-*' file.
# Usage: check_run_outputs.py RUN_DIR [final]   (final: the run ended: summary.json is the final
# one, with latency, and each video holds a fragment). Exit 1 with the problems printed.
import json, os, struct, sys
out = sys.argv[1]
final = len(sys.argv) > 2
errors = []
for name in ("detections.jsonl", "tracks.jsonl", "events.jsonl"):
    p = os.path.join(out, name)
    if not os.path.exists(p):
        continue
    data = open(p, "rb").read()
    if data and not data.endswith(b"\n"):
        errors.append(f"{name}: last line not whole")
    frames = []
    for i, line in enumerate(data.splitlines()):
        try:
            j = json.loads(line)
        except Exception as e:
            errors.append(f"{name}:{i+1}: not JSON: {e}")
            break
        if "frame" in j and name != "events.jsonl":
            frames.append(j["frame"])
    if frames and frames != list(range(frames[0], frames[0] + len(frames))):
        errors.append(f"{name}: frames not consecutive")
p = os.path.join(out, "tracks_mot.csv")
if os.path.exists(p):
    data = open(p, "rb").read()
    if data and not data.endswith(b"\n"):
        errors.append("tracks_mot.csv: last row not whole")
    for i, row in enumerate(data.decode().splitlines()):
        if len(row.split(",")) != 10:
            errors.append(f"tracks_mot.csv:{i+1}: expected 10 columns")
            break
p = os.path.join(out, "summary.json")
if os.path.exists(p):
    try:
        s = json.load(open(p))
        if final and s.get("running") is not False:
            errors.append("summary.json: not the final summary")
        if final and not s.get("latency_ms", {}).get("p99"):
            errors.append("summary.json: no latency")
    except Exception as e:
        errors.append(f"summary.json: {e}")
elif final:
    errors.append("summary.json missing")
for name in ("occupancy.mp4", "mosaic.mp4"):
    p = os.path.join(out, name)
    if not os.path.exists(p):
        continue
    data = open(p, "rb").read()
    # Top-level boxes: ftyp, moov (empty index), then moof+mdat pairs; a cut leaves at most
    # a partial last box, which players skip.
    pos, boxes = 0, []
    while pos + 8 <= len(data):
        size, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if size < 8:
            break
        if pos + size > len(data):
            break
        boxes.append(kind.decode("latin1"))
        pos += size
    if boxes[:2] != ["ftyp", "moov"] and os.path.getsize(p) > 4096:
        errors.append(f"{name}: starts with {boxes[:2]}, expected ftyp, moov")
    if final and "moof" not in boxes:
        errors.append(f"{name}: no fragment")
for root, _, files in os.walk(out):
    for f in files:
        if f.startswith(".tmp-"):
            errors.append(f"temporary left: {os.path.join(root, f)}")
for e in errors:
    print(e)
sys.exit(1 if errors else 0)
