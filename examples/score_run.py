"""Scores an `occmap run` against a simulated dataset's ground truth: MODA/MODP of its
detections, MOTA/IDF1 of its tracks (0.5 m matching, as on WILDTRACK).

    python3 score_run.py RUN_DIR GROUND_TRUTH_JSONL [--classes person]
"""
import argparse
import json
import pathlib

import occmap

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("run_dir", type=pathlib.Path)
parser.add_argument("ground_truth", type=pathlib.Path)
parser.add_argument("--classes", nargs="*", default=None, help="ground-truth classes to score (default all)")
args = parser.parse_args()


def lines(path):
    return {line["frame"]: line for line in map(json.loads, path.read_text().splitlines()) if line}


truth = lines(args.ground_truth)
detections = lines(args.run_dir / "detections.jsonl")
tracks = lines(args.run_dir / "tracks.jsonl")
frames = sorted(f for f in truth if f in detections)  # the frames the run processed
keep = lambda o: args.classes is None or o["class"] in args.classes
gt_xy = [[(o["x_m"], o["y_m"]) for o in truth[f]["objects"] if keep(o)] for f in frames]
gt_ids = [[(o["id"], o["x_m"], o["y_m"]) for o in truth[f]["objects"] if keep(o)] for f in frames]
mod = occmap.detection_metrics(gt_xy, [[(b["x_m"], b["y_m"]) for b in detections[f]["blobs"]] for f in frames])
mot = occmap.tracking_metrics(gt_ids, [[(t["id"], t["x_m"], t["y_m"]) for t in tracks[f]["tracks"]] for f in frames])
print(f"{len(frames)} frames: MODA {mod['moda']:.3f}  MODP {mod['modp']:.3f}  "
      f"precision {mod['precision']:.3f}  recall {mod['recall']:.3f}")
print(f"MOTA {mot['mota']:.3f}  IDF1 {mot['idf1']:.3f}  ID switches {mot['id_switches']}")
