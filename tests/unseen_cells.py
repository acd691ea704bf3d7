#!/usr/bin/env python3
# The unseen cells of an `occmap run --occupancy-pngs` folder, frame by frame: the number of
# grey (128) pixels of occupancy/NNNNNN.png (docs/formats.md, "Occupancy pictures"). Plain
# Python (zlib), no imaging library: 8-bit grey PNGs only, as the run writes them.
# Usage: unseen_cells.py RUN_DIR FIRST LAST   prints "frame unseen" for each frame in
# [FIRST, LAST] that has a picture.
import os, struct, sys, zlib

UNSEEN = 128


def unseen_cells(path):
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    at, idat, width, height = 8, b"", 0, 0
    while at + 8 <= len(data):
        n, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + n]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, colour, interlace) != (8, 0, 0):
                raise ValueError(f"{path}: not 8-bit grey, non-interlaced")
        elif kind == b"IDAT":
            idat += body
        at += 12 + n
    raw = zlib.decompress(idat)
    count, prev = 0, bytearray(width)
    for y in range(height):
        start = y * (width + 1)
        kind, row = raw[start], bytearray(raw[start + 1:start + 1 + width])
        if kind == 1:
            for x in range(1, width):
                row[x] = (row[x] + row[x - 1]) & 255
        elif kind == 2:
            row = bytearray((r + p) & 255 for r, p in zip(row, prev))
        elif kind == 3:
            for x in range(width):
                row[x] = (row[x] + ((row[x - 1] if x else 0) + prev[x]) // 2) & 255
        elif kind == 4:
            for x in range(width):
                a, b, c = (row[x - 1] if x else 0), prev[x], (prev[x - 1] if x else 0)
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                row[x] = (row[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        count += row.count(UNSEEN)
        prev = row
    return count


if __name__ == "__main__":
    out, first, last = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    for frame in range(first, last + 1):
        p = os.path.join(out, "occupancy", f"{frame:06d}.png")
        if os.path.exists(p):
            print(frame, unseen_cells(p))
