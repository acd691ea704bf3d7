"""Renders a custom scene (a 6 x 4 m room, three cameras, two people crossing) and scores the
fusion over a grid of settings: change threshold x tolerance, MODA of the detections.

    python3 tune_fusion.py OUT_DIR [--frames 20]
"""
import argparse
import json
import pathlib

import occmap

SCENE = """
name: corridor
frames: {frames}
floor: {{origin_m: [0, 0], size_m: [6, 4], cell_size_m: 0.04}}
cameras:
  - {{id: a, model: pinhole, image_size: [320, 240], position_m: [-0.3, -0.3, 2.6], look_at_m: [3, 2, 0], focal_px: 220}}
  - {{id: b, model: pinhole, image_size: [320, 240], position_m: [6.3, -0.3, 2.6], look_at_m: [3, 2, 0], focal_px: 220}}
  - {{id: c, model: pinhole, image_size: [320, 240], position_m: [3, 4.3, 2.6], look_at_m: [3, 2, 0], focal_px: 220}}
objects:
  - {{id: 1, class: person, path: [{{at_m: [0.5, 1.0], t_s: 0}}, {{at_m: [5.5, 3.0], speed_m_s: 1.2}}]}}
  - {{id: 2, class: person, path: [{{at_m: [5.5, 1.0], t_s: 0}}, {{at_m: [0.5, 3.0], speed_m_s: 1.0}}]}}
"""

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("out_dir", type=pathlib.Path)
parser.add_argument("--frames", type=int, default=20)
args = parser.parse_args()

sim = occmap.Simulator(SCENE.format(frames=args.frames))
site = occmap.load_site(sim.write_dataset(args.out_dir))
tables = occmap.Tables(site)
data = args.out_dir
truth = [json.loads(line) for line in (data / "ground_truth.jsonl").read_text().splitlines()]
backgrounds = [occmap.read_image(data / "backgrounds" / f"{c.id}.png") for c in site.cameras]
frames = [[occmap.read_image(data / "frames" / c.id / f"{f:06d}.png") for c in site.cameras]
          for f in range(sim.num_frames)]
gt = [[(o["x_m"], o["y_m"]) for o in line["objects"]] for line in truth]

print("threshold  tolerance  MODA")
for threshold in (10, 20, 40):
    for tolerance in (0, 1, 2):
        fusion, detector = occmap.Fusion(tables, tolerance_px=tolerance), occmap.ObjectDetector(tables)
        found = [[(d.x_m, d.y_m) for d in detector.detect(fusion.fuse_frames(f, backgrounds, threshold)).detections]
                 for f in frames]
        print(f"{threshold:9d}  {tolerance:9d}  {occmap.detection_metrics(gt, found)['moda']:.3f}")
