#!/usr/bin/env python3
"""Writes a floor-point file (docs/formats.md) for `occmap calibrate` tests: floor points projected
through an OpenCV FileStorage calibration (intrinsic + extrinsic XML, metres, k1 k2 p1 p2 k3),
optionally perturbed by Gaussian pixel noise with a fixed seed.

Usage: project_floor_points.py INTR.xml EXTR.xml X,Y [X,Y ...] [--noise-px S] [--seed N]
Prints the CSV on stdout. Needs only python3.
"""
import math
import random
import sys
import xml.etree.ElementTree as ET


def numbers(root, name):
    node = root.find(name)
    data = node.find("data") if node.find("data") is not None else node
    return [float(v) for v in data.text.split()]


def rodrigues(r):
    theta = math.sqrt(sum(v * v for v in r))
    if theta < 1e-15:
        return [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    k = [v / theta for v in r]
    c, s, C = math.cos(theta), math.sin(theta), 1 - math.cos(theta)
    x, y, z = k
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C]]


def main(argv):
    noise, seed, pts, args = 0.0, 1, [], argv[3:]
    i = 0
    while i < len(args):
        if args[i] == "--noise-px":
            noise = float(args[i + 1]); i += 2
        elif args[i] == "--seed":
            seed = int(args[i + 1]); i += 2
        else:
            x, y = args[i].split(","); pts.append((float(x), float(y))); i += 1
    intr, extr = ET.parse(argv[1]).getroot(), ET.parse(argv[2]).getroot()
    k = numbers(intr, "camera_matrix")
    d = (numbers(intr, "distortion_coefficients") + [0] * 5)[:5]
    r = rodrigues(numbers(extr, "rvec"))
    t = numbers(extr, "tvec")
    rng = random.Random(seed)
    print("u_px,v_px,x_m,y_m,label")
    for n, (x, y) in enumerate(pts):
        pc = [r[j][0] * x + r[j][1] * y + t[j] for j in range(3)]
        a, b = pc[0] / pc[2], pc[1] / pc[2]
        r2 = a * a + b * b
        radial = 1 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 ** 3
        ad = a * radial + 2 * d[2] * a * b + d[3] * (r2 + 2 * a * a)
        bd = b * radial + d[2] * (r2 + 2 * b * b) + 2 * d[3] * a * b
        u = k[0] * ad + k[1] * bd + k[2] + rng.gauss(0, noise)
        v = k[4] * bd + k[5] + rng.gauss(0, noise)
        print(f"{u:.3f},{v:.3f},{x},{y},p{n + 1}")


if __name__ == "__main__":
    main(sys.argv)
