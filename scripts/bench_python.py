#!/usr/bin/env python3
"""Fusion of a WILDTRACK-size frame set (7 cameras, 1920x1080 masks, 480 x 1440 cells) through
the Python module against the same work in a C++ loop: the cost of the binding per call.

    PYTHONPATH=build/release/python python3 scripts/bench_python.py [--data-root ../shared/datasets]

Masks: 20 people (0.5 x 0.5 x 1.75 m boxes) at seeded random places, projected into each camera.
Prints milliseconds per call both ways and their ratio (docs/python.md).
"""
import argparse
import pathlib
import sys
import time

import numpy as np
import occmap

SOURCE_DIR = pathlib.Path(__file__).resolve().parents[1]

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--data-root", default=str(SOURCE_DIR.parent / "shared" / "datasets"))
parser.add_argument("--repeats", type=int, default=60)
parser.add_argument("--rounds", type=int, default=5, help="alternating rounds; the best of each side is kept")
parser.add_argument("--threads", type=int, default=2)
args = parser.parse_args()

site = occmap.load_site(SOURCE_DIR / "sites" / "wildtrack.yaml", data_root=args.data_root)
tables = occmap.Tables(site, threads=args.threads)
fusion = occmap.Fusion(tables, threads=args.threads)

rng = np.random.default_rng(7)
(x0, y0), (cx, cy), s = site.grid.origin_m, site.grid.cells, site.grid.cell_size_m
people = rng.uniform([x0 + 1, y0 + 1], [x0 + cx * s - 1, y0 + cy * s - 1], size=(20, 2))
masks = []
for cam in site.cameras:
    w, h = cam.image_size
    mask = np.zeros((h, w), np.uint8)
    for px, py in people:
        corners = [cam.project(px + dx, py + dy, z) for dx in (-0.25, 0.25) for dy in (-0.25, 0.25) for z in (0, 1.75)]
        if any(c is None for c in corners):
            continue
        us, vs = zip(*corners)
        u0, u1 = max(int(min(us)), 0), min(int(max(us)) + 1, w)
        v0, v1 = max(int(min(vs)), 0), min(int(max(vs)) + 1, h)
        if u0 < u1 and v0 < v1:
            mask[v0:v1, u0:u1] = 255
    masks.append(mask)

occupancy = fusion.fuse(masks)  # warm-up (tables' pages, the map)
python_s, cpp_s = [], []
for _ in range(args.rounds):
    t0 = time.perf_counter()
    for _ in range(args.repeats):
        occupancy = fusion.fuse(masks)
    python_s.append((time.perf_counter() - t0) / args.repeats)
    cpp_s.append(fusion._fuse_repeatedly(masks, args.repeats))
py_ms, cpp_ms = 1e3 * min(python_s), 1e3 * min(cpp_s)
print(f"WILDTRACK-size fusion ({len(masks)} x 1920x1080 masks, {site.grid.cells[0]} x {site.grid.cells[1]} cells, "
      f"{occupancy.count(occmap.OCCUPIED)} occupied, {args.threads} threads): "
      f"Python {py_ms:.2f} ms, C++ {cpp_ms:.2f} ms per call, ratio {py_ms / cpp_ms:.3f}")
sys.exit(0)
