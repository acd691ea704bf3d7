"""Foreground masks from any segmenter -> occupancy map -> objects -> tracks.

    python3 masks_to_tracks.py SITE MASKS --frames N [--fps 10] [--data-root DIR]

MASKS is a pattern with {camera} and {frame}, e.g. 'masks/{camera}/{frame:06d}.png': one 8-bit
mask per camera and frame, non-zero where the segmenter saw a person (any size: masks are
resampled to the site's image size). Prints each frame's tracks.
"""
import argparse

import occmap

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("site")
parser.add_argument("masks")
parser.add_argument("--frames", type=int, required=True)
parser.add_argument("--fps", type=float, default=10.0)
parser.add_argument("--data-root")
args = parser.parse_args()

site = occmap.load_site(args.site, data_root=args.data_root)
tables = occmap.Tables(site)
fusion, detector, tracker = occmap.Fusion(tables), occmap.ObjectDetector(tables), occmap.Tracker(tables)
for frame in range(args.frames):
    masks = [occmap.read_image(args.masks.format(camera=c.id, frame=frame)) for c in site.cameras]
    occupancy = fusion.fuse(masks)
    objects = detector.detect(occupancy)
    tracks = tracker.update(objects, frame / args.fps)
    print(f"frame {frame}: {len(objects)} objects; tracks "
          + " ".join(f"{t.id}:({t.x_m:.2f}, {t.y_m:.2f})" for t in tracks))
