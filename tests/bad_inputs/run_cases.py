#!/usr/bin/env python3
"""The bad-input corpus: every case runs the real `occmap` binary on one bad file or option and
checks its exit code and the words of its message (the file and the field at fault).

Usage: run_cases.py OCCMAP_BINARY [--jobs N] [--keep] [--only SUBSTRING[,SUBSTRING...]] [--list]

The cases are the table CASES below. Fixtures are made once per run with occmap itself (`synth`
of the lab and clemson scenes at quarter size, one short `run`, one table cache), in a temporary
folder; a case writes its bad file into its own folder and points a copy of a valid site at it
(`data_root:` keeps the other paths valid). A new reader adds its cases here.
"""
import concurrent.futures
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

# ----------------------------------------------------------------------------------------------
# Fixtures

LAB_CALIB = "calib/intr_cam1.xml"


def rodrigues(r):
    """Rotation matrix (row-major 3x3 list) of a rotation vector."""
    theta = math.sqrt(sum(v * v for v in r))
    if theta < 1e-12:
        return [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    k = [v / theta for v in r]
    c, s = math.cos(theta), math.sin(theta)
    kx, ky, kz = k
    return [[c + kx * kx * (1 - c), kx * ky * (1 - c) - kz * s, kx * kz * (1 - c) + ky * s],
            [ky * kx * (1 - c) + kz * s, c + ky * ky * (1 - c), ky * kz * (1 - c) - kx * s],
            [kz * kx * (1 - c) - ky * s, kz * ky * (1 - c) + kx * s, c + kz * kz * (1 - c)]]


def xml_numbers(text, tag):
    start = text.index("<" + tag)
    data = text.index("<data>", start) + len("<data>")
    end = text.index("</data>", data)
    return [float(v) for v in text[data:end].split()]


def make_fixtures(occmap, work):
    """Valid inputs every case starts from."""
    jobs = [
        [occmap, "synth", "--scene", "lab", "--frames", "2", "--scale", "0.25", "--out", f"{work}/lab"],
        [occmap, "synth", "--scene", "clemson", "--frames", "2", "--scale", "0.25", "--out", f"{work}/clemson"],
        [occmap, "synth", "--scene", "lab", "--frames", "2", "--scale", "0.25", "--video", "--out", f"{work}/labvid"],
    ]
    procs = [subprocess.Popen(j, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) for j in jobs]
    for j, p in zip(jobs, procs):
        _, err = p.communicate()
        if p.returncode != 0:
            sys.exit(f"fixture failed: {' '.join(j)}\n{err.decode(errors='replace')}")
    after = [
        [occmap, "run", f"{work}/lab/site.yaml", "--frames", "2", "--no-video", "--no-cache", "--no-wall-clock",
         "--out", f"{work}/labrun"],
        [occmap, "lut", f"{work}/lab/site.yaml", "--cache-dir", f"{work}/cache", "--out", f"{work}/lutout"],
    ]
    procs = [subprocess.Popen(j, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) for j in after]
    for j, p in zip(after, procs):
        _, err = p.communicate()
        if p.returncode != 0:
            sys.exit(f"fixture failed: {' '.join(j)}\n{err.decode(errors='replace')}")
    # GoPro JSON of lab camera 1, from its OpenCV files.
    intr = open(f"{work}/lab/calib/intr_cam1.xml").read()
    extr = open(f"{work}/lab/calib/extr_cam1.xml").read()
    k = xml_numbers(intr, "camera_matrix")
    d = xml_numbers(intr, "distortion_coefficients")
    r = rodrigues(xml_numbers(extr, "rvec"))
    t = xml_numbers(extr, "tvec")
    with open(f"{work}/lab/calib/gopro_intr_cam1.json", "w") as f:
        f.write('{"K": [[%r, %r, %r], [0.0, %r, %r], [0.0, 0.0, 1.0]], "distCoeffs": [[%s]], "image_shape": [120, 160]}'
                % (k[0], k[1], k[2], k[4], k[5], ", ".join(repr(v) for v in d)))
    with open(f"{work}/lab/calib/gopro_extr_cam1.json", "w") as f:
        f.write('{"unit": "m", "R": [%s], "t": [%r, %r, %r]}'
                % (", ".join("[%r, %r, %r]" % tuple(row) for row in r), t[0], t[1], t[2]))


LAB_SITE = None  # text of lab/site.yaml, read after the fixtures
CLEMSON_SITE = None
LAB_SCENE = None

GOPRO_CAM = ("    calibration: {format: opencv, intrinsic: calib/intr_cam1.xml, extrinsic: calib/extr_cam1.xml, unit: m}",
             "    calibration: {format: gopro-json, intrinsic: calib/gopro_intr_cam1.json, "
             "extrinsic: calib/gopro_extr_cam1.json}")

HOMOGRAPHY_SITE = """version: 1
name: top
floor: {origin_m: [0, 0], size_m: [6.4, 4.8], cell_size_m: 0.1}
cameras:
  - id: top
    calibration:
      format: homography
      unit: cm
      image_size: [640, 480]
      floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]
"""

# ----------------------------------------------------------------------------------------------
# The table

CASES = []


class Case:
    def __init__(self, name, argv, words, code=2, files=None, setup=None, timeout=60, max_output=None):
        self.name, self.argv, self.words, self.code = name, argv, words, code
        self.max_output = max_output  # bytes: a long value is cut in the message, never echoed whole
        self.files = files or {}
        self.setup = setup
        self.timeout = timeout


def add(*args, **kwargs):
    CASES.append(Case(*args, **kwargs))


def with_data_root(text, base):
    return text.replace("version: 1\n", "version: 1\ndata_root: {w}/" + base + "\n", 1)


def site(name, frm, to, words, base="lab", cmd="check", args=(), code=2, count=1, max_output=None):
    """A copy of a valid site with `frm` replaced by `to`, run through `occmap CMD`."""
    def setup(case_dir, work):
        text = {"lab": LAB_SITE, "clemson": CLEMSON_SITE, "homography": HOMOGRAPHY_SITE}[base]
        if frm not in text:
            raise AssertionError(f"{name}: '{frm}' is not in the {base} site")
        text = text.replace(frm, to, count)
        if base != "homography":
            text = with_data_root(text, base)
        with open(os.path.join(case_dir, "site.yaml"), "wb") as f:
            f.write(text.replace("{w}", work).encode("utf-8", "surrogateescape"))
    extra = list(args)
    if cmd == "run":
        extra = ["--frames", "1", "--no-video", "--no-cache", "--out", "{c}/out"] + extra
    if cmd == "lut":
        extra = ["--no-cache", "--out", "{c}/out"] + extra
    add(name, ["{bin}", cmd, "{c}/site.yaml"] + extra, ["site.yaml"] + words, code=code, setup=setup,
        max_output=max_output)


def bad_file(name, target, content, words, base="lab", cmd="check", args=(), code=2, frm=None, to=None, names_file=True):
    """A valid site whose file `target` (a path in the site) is replaced by `content`."""
    file_name = "bad-" + os.path.basename(target)

    def setup(case_dir, work):
        text = {"lab": LAB_SITE, "clemson": CLEMSON_SITE}[base]
        if frm is not None:
            text = text.replace(frm, to, 1)
        assert target in text, f"{name}: {target} not in the site"
        text = with_data_root(text.replace(target, os.path.join(case_dir, file_name), 1), base)
        with open(os.path.join(case_dir, "site.yaml"), "w") as f:
            f.write(text.replace("{w}", work))
        data = content(work) if callable(content) else content
        with open(os.path.join(case_dir, file_name), "wb") as f:
            f.write(data if isinstance(data, bytes) else data.encode("utf-8", "surrogateescape"))
    extra = list(args)
    if cmd == "run":
        extra = ["--frames", "1", "--no-video", "--no-cache", "--out", "{c}/out"] + extra
    add(name, ["{bin}", cmd, "{c}/site.yaml"] + extra, ([file_name] if names_file else []) + words, code=code, setup=setup)


def read(work, rel):
    with open(os.path.join(work, rel), "rb") as f:
        return f.read()


# --- site files: structure and fields (check) -------------------------------------------------
site("site_yaml_syntax", "origin_m: [0, 0]", "origin_m: [0, 0", ["YAML syntax error"])
site("site_tab_indent", "  cells: [450, 325]", "\tcells: [450, 325]", ["YAML syntax error"])
site("site_not_a_map", "version: 1\n", "- 1\n", [], count=1)
site("site_version", "version: 1\n", "version: 2\n", ["version", "expected site format version 1, found 2"])
site("site_version_text", "version: 1\n", "version: one\n", ["version", "expected an integer, found 'one'"])
site("site_unknown_key", "floor:\n", "flor: 1\nfloor:\n", ["unknown field 'flor'", "did you mean 'floor'"])
site("site_key_not_a_name", "floor:\n", "? [a, b]\n: 1\nfloor:\n", ["expected a field name, found a list of 2"])
site("site_missing_floor", "floor:\n  origin_m: [0, 0]\n  cells: [450, 325]\n  cell_size_m: 0.02\n", "",
     ["missing required field 'floor'"])
site("site_missing_cameras", "cameras:\n", "cameraz:\n", ["unknown field 'cameraz'"])
site("site_cameras_empty", "cameras:\n  - id: cam1", "cameras: []\nx:\n  - id: cam1", ["unknown field 'x'"])
site("site_cameras_not_list", "cameras:\n", "cameras: 3\nold_cameras:\n", ["unknown field 'old_cameras'"])
site("site_duplicate_top_key", "detection:\n", "detection: {}\ndetection:\n", ["duplicate key 'detection'"])
site("site_duplicate_nested_key", "  threshold: 20\n", "  threshold: 20\n  threshold: 40\n",
     ["detection", "duplicate key 'threshold'", "first at line"])
site("site_duplicate_camera_key", "    mask: masks/cam1.png\n", "    mask: masks/cam1.png\n    mask: masks/cam2.png\n",
     ["cameras[0]", "duplicate key 'mask'"])
site("site_invalid_utf8_id", "id: cam1", "id: cam1\udcff", ["expected UTF-8 text, found the byte 0xff"])
site("site_invalid_utf8_name", 'name: "lab"', 'name: "l\udcc3(ab"', ["expected UTF-8 text, found the byte 0xc3"])
site("site_invalid_utf8_comment", "# A pixel", "# A pix\udce9l", ["expected UTF-8 text, found the byte 0xe9"])
site("site_id_slash", "id: cam1", 'id: "../../escaped"', ["cameras[0].id", "character '.' (U+002E) at position 1"])
site("site_id_inner_slash", "id: cam1", "id: a/b", ["cameras[0].id", "character '/' (U+002F) at position 2"])
site("site_id_backslash", "id: cam1", 'id: "a\\\\b"', ["cameras[0].id", "(U+005C) at position 2"])
site("site_id_newline", "id: cam1", 'id: "cam\\n1"', ["cameras[0].id", "(U+000A) at position 4"])
site("site_id_tab", "id: cam1", 'id: "cam\\t1"', ["cameras[0].id", "(U+0009) at position 4"])
site("site_id_nul", "id: cam1", 'id: "cam\\x001"', ["cameras[0].id", "(U+0000) at position 4"])
site("site_id_escape", "id: cam1", 'id: "cam\\e[31m"', ["cameras[0].id", "(U+001B) at position 4"])
site("site_id_space", "id: cam1", 'id: "cam 1"', ["cameras[0].id", "' ' (U+0020) at position 4"])
site("site_id_leading_dash", "id: cam1", "id: -cam1", ["cameras[0].id", "position 1 is not allowed first"])
site("site_id_bidi", "id: cam1", 'id: "cam\\u202e1"', ["cameras[0].id", "(U+202E) at position 4"])
site("site_id_too_long", "id: cam1", "id: " + "c" * 65, ["cameras[0].id", "expected at most 64 bytes, found 65"])
site("site_id_empty", "id: cam1", 'id: ""', ["cameras[0].id", "non-empty camera id"])
site("site_id_list", "id: cam1", "id: [cam1]", ["cameras[0].id", "expected a text value"])
site("site_id_duplicate", "id: cam2", "id: cam1", ["cameras[1].id", "duplicate camera id 'cam1'"])
site("site_id_missing", "  - id: cam1\n    calibration", "  - calibration", ["cameras[0]", "missing required field 'id'"])
site("site_name_slash", 'name: "lab"', 'name: "../lab"', ["name", "site name '../lab'", "position 1"])
site("site_name_colon", 'name: "lab"', 'name: "lab:x"', ["name", "character ':' (U+003A) at position 4"])
site("site_name_list", 'name: "lab"', "name: [lab]", ["name", "expected a text value"])
# A 10 MB name was echoed whole to the terminal: cut, with its length.
site("site_name_huge", 'name: "lab"', 'name: "' + "x" * 10_000_000 + '"', ["name", "... (10000000 bytes)"], max_output=4000)
site("site_data_root_missing", "version: 1\n", "version: 1\ndata_root: /nonexistent/occmap\n",
     ["data_root"])  # the fixture site has one already: refused as a duplicate key
site("site_floor_not_map", "floor:\n  origin_m: [0, 0]\n  cells: [450, 325]\n  cell_size_m: 0.02\n", "floor: 3\n",
     ["floor"])
site("site_floor_unknown", "  cell_size_m: 0.02\n", "  cell_size_m: 0.02\n  cel_size: 1\n", ["floor", "unknown field 'cel_size'"])
site("site_cell_size_zero", "cell_size_m: 0.02", "cell_size_m: 0", ["floor.cell_size_m", "expected a positive number, found 0"])
site("site_cell_size_nan", "cell_size_m: 0.02", "cell_size_m: .nan", ["floor.cell_size_m", "expected a finite number"])
site("site_cell_size_inf", "cell_size_m: 0.02", "cell_size_m: .inf", ["floor.cell_size_m", "expected a finite number"])
site("site_cell_size_text", "cell_size_m: 0.02", "cell_size_m: small", ["floor.cell_size_m", "found 'small'"])
site("site_cells_negative", "cells: [450, 325]", "cells: [-450, 325]", ["floor.cells"])
site("site_cells_fraction", "cells: [450, 325]", "cells: [450.5, 325]", ["floor.cells"])
site("site_cells_three", "cells: [450, 325]", "cells: [450, 325, 1]", ["floor.cells", "expected a list of 2 numbers, found 3"])
site("site_cells_huge", "cells: [450, 325]", "cells: [4500000, 3250000]", ["floor", "too large"])
site("site_cells_and_size", "cells: [450, 325]", "cells: [450, 325]\n  size_m: [9, 6.5]", ["floor", "exactly one of"])
site("site_origin_text", "origin_m: [0, 0]", "origin_m: [a, 0]", ["floor.origin_m", "found 'a'"])
site("site_origin_huge", "origin_m: [0, 0]", "origin_m: [1e300, 0]", ["floor"])
site("site_plane_height_text", "cell_size_m: 0.02", "cell_size_m: 0.02\n  plane_height_m: high",
     ["floor.plane_height_m", "found 'high'"])
site("site_camera_not_map", "  - id: cam1\n    calibration: {format: opencv, intrinsic: calib/intr_cam1.xml, extrinsic: calib/extr_cam1.xml, unit: m}\n    mask: masks/cam1.png\n    source: {images: frames/cam1/%06d.png}\n    background: backgrounds/cam1.png\n",
     "  - cam1\n", ["cameras[0]", "expected a map"])
site("site_camera_unknown_key", "    mask: masks/cam1.png", "    maks: masks/cam1.png", ["cameras[0]", "unknown field 'maks'", "did you mean 'mask'"])
site("site_calibration_missing", "    calibration: {format: opencv, intrinsic: calib/intr_cam1.xml, extrinsic: calib/extr_cam1.xml, unit: m}\n", "",
     ["cameras[0]", "missing required field 'calibration'"])
site("site_calibration_not_map", "calibration: {format: opencv, intrinsic: calib/intr_cam1.xml, extrinsic: calib/extr_cam1.xml, unit: m}",
     "calibration: opencv", ["cameras[0].calibration", "expected a map"])
site("site_calibration_format", "format: opencv, intrinsic: calib/intr_cam1", "format: matlab, intrinsic: calib/intr_cam1",
     ["cameras[0].calibration.format", "expected opencv, gopro-json, tsai-yaml or homography, found 'matlab'"])
site("site_calibration_no_format", "{format: opencv, intrinsic: calib/intr_cam1", "{intrinsic: calib/intr_cam1",
     ["cameras[0].calibration", "missing required field 'format'"])
site("site_calibration_unit", "extr_cam1.xml, unit: m}", "extr_cam1.xml, unit: inch}", ["cameras[0].calibration.unit", "found 'inch'"])
site("site_calibration_no_unit", "extr_cam1.xml, unit: m}", "extr_cam1.xml}", ["cameras[0].calibration", "missing required field 'unit'"])
site("site_calibration_wrong_unit", "extr_cam1.xml, unit: m}", "extr_cam1.xml, unit: mm}", ["cameras[0]", "sees none"])
site("site_calibration_unknown_key", "extr_cam1.xml, unit: m}", "extr_cam1.xml, unit: m, focal: 3}",
     ["cameras[0].calibration", "unknown field 'focal'"])
site("site_intrinsic_missing_file", "intrinsic: calib/intr_cam1.xml", "intrinsic: calib/intr_cam9.xml",
     ["cameras[0].calibration.intrinsic", "file not found", "intr_cam9.xml"])
site("site_extrinsic_missing_file", "extrinsic: calib/extr_cam1.xml", "extrinsic: calib/extr_cam9.xml",
     ["cameras[0].calibration.extrinsic", "file not found", "extr_cam9.xml"])
site("site_intrinsic_empty_path", "intrinsic: calib/intr_cam1.xml", 'intrinsic: ""',
     ["cameras[0].calibration.intrinsic", "expected a path"])
site("site_intrinsic_is_folder", "intrinsic: calib/intr_cam1.xml", "intrinsic: calib",
     ["cameras[0].calibration", "expected a file, found a directory"])
site("site_forward", "extr_cam1.xml, unit: m}", "extr_cam1.xml, unit: m, forward: up}",
     ["cameras[0].calibration.forward", "expected auto, +z or -z, found 'up'"])
site("site_image_size_aspect", "    mask: masks/cam1.png\n", "    image_size: [160, 160]\n    mask: masks/cam1.png\n",
     ["cameras[0].image_size", "aspect ratio"])
site("site_image_size_zero", "    mask: masks/cam1.png\n", "    image_size: [0, 120]\n    mask: masks/cam1.png\n",
     ["cameras[0].image_size", "whole pixels"])
site("site_image_size_huge", "    mask: masks/cam1.png\n", "    image_size: [100000, 75000]\n    mask: masks/cam1.png\n",
     ["cameras[0].image_size", "whole pixels 1..16384"])
site("site_mask_polygon_outside", "mask: masks/cam1.png", "mask: {polygon: [[0, 0], [500, 0], [0, 100]]}",
     ["cameras[0].mask.polygon[1]", "outside the 160x120 image"])
site("site_mask_polygon_short", "mask: masks/cam1.png", "mask: {polygon: [[0, 0], [50, 0]]}",
     ["cameras[0].mask.polygon", "at least 3"])
site("site_mask_polygon_text", "mask: masks/cam1.png", "mask: {polygon: [[0, 0], [50, a], [0, 100]]}",
     ["cameras[0].mask.polygon[1]", "found 'a'"])
site("site_mask_unknown_key", "mask: masks/cam1.png", "mask: {polygone: [[0, 0], [50, 0], [0, 100]]}",
     ["cameras[0].mask", "unknown field 'polygone'"])
site("site_mask_missing_file", "mask: masks/cam1.png", "mask: masks/cam9.png", ["cameras[0].mask", "cam9.png"])
site("site_mask_sees_nothing", "mask: masks/cam1.png", "mask: {polygon: [[0, 0], [3, 0], [0, 3]]}",
     ["cameras[0]", "sees none of the 10201 floor sample points in its image and mask"])
site("site_source_two_kinds", "source: {images: frames/cam1/%06d.png}", "source: {images: frames/cam1/%06d.png, video: x.mp4}",
     ["cameras[0].source", "exactly one of images, video, stream or masks"])
site("site_source_none", "source: {images: frames/cam1/%06d.png}", "source: {}",
     ["cameras[0].source", "exactly one of"])
site("site_source_unknown", "source: {images: frames/cam1/%06d.png}", "source: {image: frames/cam1/%06d.png}",
     ["cameras[0].source", "unknown field 'image'"])
site("site_source_video_missing", "source: {images: frames/cam1/%06d.png}", "source: {video: none.mp4}",
     ["cameras[0].source.video", "file not found", "none.mp4"])


# --- files that are not files (issue 39): a FIFO with no writer would block an open forever -----
def make_special(path, kind):
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        os.makedirs(path)
    elif kind == "loop":  # path -> path.b -> path
        os.symlink(path + ".b", path)
        os.symlink(path, path + ".b")


def special_site(name, kind, frm, to, words, cmd="check", args=(), code=2, timeout=30):
    """A copy of the lab site with `frm` replaced by `to`, where {c}/special is made a `kind`."""
    def setup(case_dir, work):
        assert frm in LAB_SITE, f"{name}: '{frm}' is not in the lab site"
        text = with_data_root(LAB_SITE.replace(frm, to, 1), "lab").replace("{w}", work).replace("{c}", case_dir)
        with open(os.path.join(case_dir, "site.yaml"), "w") as f:
            f.write(text)
        make_special(os.path.join(case_dir, "special"), kind)
    extra = list(args)
    if cmd == "run":
        extra = ["--frames", "2", "--no-video", "--no-cache", "--out", "{c}/out"] + extra
    add(name, ["{bin}", cmd, "{c}/site.yaml"] + extra, ["site.yaml"] + words, code=code, setup=setup, timeout=timeout)


for cmd in ("check", "run"):
    special_site(f"site_source_video_fifo_{cmd}", "fifo", "source: {images: frames/cam1/%06d.png}",
                 "source: {video: {c}/special}", ["cameras[0].source.video", "special': expected a regular file, found a FIFO"],
                 cmd=cmd)
special_site("site_source_video_loop", "loop", "source: {images: frames/cam1/%06d.png}", "source: {video: {c}/special}",
             ["cameras[0].source.video", "Too many levels of symbolic links (a loop of symbolic links)"])
# A stream from a FIFO nobody writes to: an error after the stream timeout (10 s), not a run
# blocked for good.
special_site("site_source_stream_fifo_no_writer", "fifo", "source: {images: frames/cam1/%06d.png}",
             "source: {stream: {c}/special}", ["camera cam1", "no data within 10000 ms (the FIFO has no writer, or it is silent)"],
             cmd="run", code=1, timeout=40)
MQTT_OUT = "outputs:\n  mqtt:\n    url: mqtt://127.0.0.1:1\n    username: u\n    password_file: {c}/special\n"
for kind, found in (("fifo", "expected a regular file, found a FIFO"), ("folder", "expected a file, found a directory"),
                    ("loop", "(a loop of symbolic links)")):
    special_site(f"site_mqtt_password_file_{kind}", kind, "cameras:", MQTT_OUT + "cameras:",
                 ["outputs.mqtt.password_file", "special': " if kind != "loop" else "special': cannot be read", found])
add("cli_calibrate_board_video_fifo",
    ["{bin}", "calibrate", "--board-video", "{c}/board.fifo", "--board-size", "9x6", "--square-m", "0.03", "--out", "{c}/o"],
    ["board.fifo", "expected a regular file, found a FIFO"], setup=lambda c, w: os.mkfifo(os.path.join(c, "board.fifo")),
    timeout=20)
site("site_source_fps_video", "source: {images: frames/cam1/%06d.png}", "source: {video: ../labvid/frames/cam1.mp4, fps: 5}",
     ["cameras[0].source.fps", "fps is for images and masks"])
site("site_source_fps_negative", "source: {images: frames/cam1/%06d.png}", "source: {images: frames/cam1/%06d.png, fps: -5}",
     ["cameras[0].source.fps", "found -5"])
site("site_source_empty", "source: {images: frames/cam1/%06d.png}", 'source: {images: ""}',
     ["cameras[0].source", "expected a location"])
site("site_background_missing", "background: backgrounds/cam1.png", "background: backgrounds/cam9.png",
     ["cameras[0].background", "file not found", "cam9.png"])
site("site_detection_threshold", "threshold: 20", "threshold: 300", ["detection.threshold", "expected 0..254 grey levels, found 300"])
site("site_detection_threshold_text", "threshold: 20", "threshold: low", ["detection.threshold", "found 'low'"])
site("site_detection_tolerance", "tolerance_px: 1", "tolerance_px: 99", ["detection.tolerance_px", "expected 0..64 pixels, found 99"])
site("site_detection_colour", "tolerance_px: 1", "tolerance_px: 1\n  colour: maybe", ["detection.colour", "expected true or false"])
site("site_detection_unknown", "tolerance_px: 1", "tolerance_px: 1\n  treshold: 3", ["detection", "unknown field 'treshold'"])
site("site_blobs_radius", "group_radius_m: 0.2", "group_radius_m: -1", ["blobs.group_radius_m"])
site("site_blobs_area", "min_area_m2: 0.015", "min_area_m2: abc", ["blobs.min_area_m2", "found 'abc'"])
site("site_blobs_support", "min_support: 0.3", "min_support: 1.5", ["blobs.min_support", "found 1.5"])
site("site_blobs_heights", "support_heights_m: [0.35, 0.7, 1.0, 1.3]", "support_heights_m: [0.35, -1]",
     ["blobs.support_heights_m", "found -1"])
site("site_blobs_clear_views", "min_support: 0.3", "min_support: 0.3\n  min_clear_views: 0",
     ["blobs.min_clear_views", "expected 1..64 cameras, found 0"])
site("site_blobs_unknown", "min_support: 0.3", "min_support: 0.3\n  split_me: true", ["blobs", "unknown field 'split_me'"])
site("site_fusion_algorithm", "min_support: 0.3", "min_support: 0.3\nfusion: {algorithm: fastest}",
     ["fusion.algorithm", "found 'fastest'"])
site("site_fusion_votes", "min_support: 0.3", "min_support: 0.3\nfusion: {max_free_views: 9}",
     ["fusion.max_free_views", "found 9"])
site("site_backgrounds_learning", "min_support: 0.3", "min_support: 0.3\nbackgrounds: {learning: gmm}",
     ["backgrounds.learning", "found 'gmm'"])
site("site_backgrounds_absorb", "min_support: 0.3", "min_support: 0.3\nbackgrounds: {absorb_s: -3}",
     ["backgrounds.absorb_s", "found -3"])
site("site_backgrounds_shadows", "min_support: 0.3", "min_support: 0.3\nbackgrounds: {shadows: {min_ratio: 0.5, max_ratio: 0.4}}",
     ["backgrounds.shadows", "min_ratio"])
site("site_tracking_speed", "min_support: 0.3", "min_support: 0.3\ntracking: {max_speed_mps: -1}",
     ["tracking.max_speed_mps", "found -1"])
site("site_tracking_algorithm", "min_support: 0.3", "min_support: 0.3\ntracking: {algorithm: psychic}",
     ["tracking.algorithm", "psychic"])
site("site_tracking_unknown", "min_support: 0.3", "min_support: 0.3\ntracking: {max_sped_mps: 2}",
     ["tracking", "unknown field 'max_sped_mps'"])
site("site_lut_unknown", "min_support: 0.3", "min_support: 0.3\nlut: {add_projections: true}",
     ["lut", "unknown field 'add_projections'"])
site("site_outputs_unknown", "min_support: 0.3", "min_support: 0.3\noutputs: {kafka: {}}", ["outputs", "unknown field 'kafka'"])
site("site_mqtt_url", "min_support: 0.3", "min_support: 0.3\noutputs: {mqtt: {url: http://x}}", ["outputs.mqtt.url"])
site("site_deep_nesting", "min_support: 0.3", "min_support: 0.3\nlut: " + "[" * 300 + "]" * 300,
     ["levels of nesting"])
site("site_alias_bomb", "min_support: 0.3",
     "min_support: 0.3\nstatics_x:\n  a: &a [x, x, x, x, x, x, x, x, x, x]\n  b: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
     "  c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b, *b]\n  d: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c, *c]\n"
     "  e: &e [*d, *d, *d, *d, *d, *d, *d, *d, *d, *d]\n  f: &f [*e, *e, *e, *e, *e, *e, *e, *e, *e, *e]\n"
     "  g: &g [*f, *f, *f, *f, *f, *f, *f, *f, *f, *f]\n",
     ["YAML nodes"])
site("site_statics_bad", "min_support: 0.3", "min_support: 0.3\nstatics: 3", ["statics"])
site("site_people_bad", "min_support: 0.3", "min_support: 0.3\npeople: {bogus: 1}", ["people", "unknown field 'bogus'"])

# --- homography calibrations -----------------------------------------------------------------
site("homography_no_size", "      image_size: [640, 480]\n", "", ["cameras[0].calibration", "missing required field 'image_size'"],
     base="homography")
site("homography_two_rows", "floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]", "floor_from_image: [[1, 0, 0], [0, -1, 479]]",
     ["cameras[0].calibration.floor_from_image", "3x3"], base="homography")
site("homography_short_row", "floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]", "floor_from_image: [[1, 0], [0, -1, 479], [0, 0, 1]]",
     ["floor_from_image[0]", "expected a list of 3 numbers, found 2"], base="homography")
site("homography_text", "floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]", "floor_from_image: [[1, 0, x], [0, -1, 479], [0, 0, 1]]",
     ["floor_from_image[0][2]", "found 'x'"], base="homography")
site("homography_singular", "floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]", "floor_from_image: [[0, 0, 0], [0, 0, 0], [0, 0, 1]]",
     ["floor_from_image"], base="homography")
site("homography_nan", "floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]", "floor_from_image: [[.nan, 0, 0], [0, -1, 479], [0, 0, 1]]",
     ["floor_from_image[0][0]", "finite"], base="homography")
site("homography_plane", "cell_size_m: 0.1}", "cell_size_m: 0.1, plane_height_m: 1}", ["cameras[0].calibration", "only knows the floor"],
     base="homography")
site("homography_sees_nothing", "floor_from_image: [[1, 0, 0], [0, -1, 479], [0, 0, 1]]",
     "floor_from_image: [[1, 0, 100000], [0, -1, 479], [0, 0, 1]]", ["cameras[0].calibration", "invertible"], base="homography")
site("homography_unknown_key", "      unit: cm\n", "      unit: cm\n      file: x\n", ["cameras[0].calibration", "unknown field 'file'"],
     base="homography")

# --- OpenCV XML calibrations -----------------------------------------------------------------
OK_K = "87.5 0. 79.5 0. 87.5 59.5 0. 0. 1."


def intr_xml(k=OK_K, rows=3, cols=3, dist="-0.16 0.035 0 0 0", extra="<image_width>160</image_width><image_height>120</image_height>"):
    return ('<?xml version="1.0"?>\n<opencv_storage>\n<camera_matrix type_id="opencv-matrix"><rows>%d</rows><cols>%d</cols>'
            '<dt>d</dt><data>%s</data></camera_matrix>\n<distortion_coefficients type_id="opencv-matrix"><rows>1</rows>'
            '<cols>%d</cols><dt>d</dt><data>%s</data></distortion_coefficients>\n%s\n</opencv_storage>\n'
            % (rows, cols, k, len(dist.split()), dist, extra))


def extr_xml(work, rvec=None, tvec=None):
    text = read(work, "lab/calib/extr_cam1.xml").decode()
    r = " ".join(repr(v) for v in xml_numbers(text, "rvec")) if rvec is None else rvec
    t = " ".join(repr(v) for v in xml_numbers(text, "tvec")) if tvec is None else tvec
    return ('<?xml version="1.0"?>\n<opencv_storage>\n<rvec>%s</rvec>\n<tvec>%s</tvec>\n</opencv_storage>\n' % (r, t))


INTR = "calib/intr_cam1.xml"
EXTR = "calib/extr_cam1.xml"
# --- frame times (io/frame_times.h) -----------------------------------------------------------
SRC = "source: {images: frames/cam1/%06d.png}"
SRC_TIMES = "source: {images: frames/cam1/%06d.png, timestamps: times.txt}"
bad_file("times_not_increasing", "times.txt", "0\n0.1\n0.1\n", [":3:", "expected times that increase"], frm=SRC, to=SRC_TIMES)
bad_file("times_mixed_forms", "times.txt", "0 0.0\n0.1\n", [":2:", "'INDEX TIME' as on the first line"], frm=SRC, to=SRC_TIMES)
bad_file("times_index_skipped", "times.txt", "0 0.0\n2 0.1\n", [":2:", "expected image index 1"], frm=SRC, to=SRC_TIMES)
bad_file("times_not_a_number", "times.txt", "0\nsoon\n", [":2:", "expected a time in seconds", "soon"], frm=SRC, to=SRC_TIMES)
bad_file("times_empty", "times.txt", "# nothing\n", ["expected a time per image, found none"], frm=SRC, to=SRC_TIMES)

bad_file("opencv_intr_empty", INTR, "", ["empty file"])
bad_file("opencv_intr_blank", INTR, "\n \n", ["empty file"])
bad_file("opencv_intr_not_xml", INTR, "hello world", ["OpenCV FileStorage"])
bad_file("opencv_intr_binary", INTR, bytes(range(256)) * 4, ["OpenCV FileStorage"])
bad_file("opencv_intr_truncated", INTR, lambda w: read(w, INTR and "lab/" + INTR)[:200], ["OpenCV FileStorage"])
bad_file("opencv_intr_no_matrix", INTR, '<?xml version="1.0"?>\n<opencv_storage>\n<x>1</x>\n</opencv_storage>\n',
         ["camera_matrix: missing"])
bad_file("opencv_intr_2x3", INTR, intr_xml("1 2 3 4 5 6", 2, 3), ["camera_matrix", "expected a 3x3 matrix, found 2x3"])
bad_file("opencv_intr_short_data", INTR, intr_xml("87.5 0 79.5 0 87.5 59.5 0 0"), ["camera_matrix", "9 numbers in data, found 8"])
bad_file("opencv_intr_long_data", INTR, intr_xml(OK_K + " 5"), ["camera_matrix", "9 numbers in data, found 10"])
bad_file("opencv_intr_nan", INTR, intr_xml("87.5 0 nan 0 87.5 59.5 0 0 1"), ["camera_matrix", "finite"])
bad_file("opencv_intr_dot_nan", INTR, intr_xml("87.5 0 .Nan 0 87.5 59.5 0 0 1"), ["camera_matrix", "finite"])
bad_file("opencv_intr_inf", INTR, intr_xml("87.5 0 inf 0 87.5 59.5 0 0 1"), ["camera_matrix", "finite"])
bad_file("opencv_intr_text", INTR, intr_xml("87.5 0 abc 0 87.5 59.5 0 0 1"), ["camera_matrix"])
bad_file("opencv_intr_not_camera", INTR, intr_xml("87.5 0 79.5 0 87.5 59.5 0 1 1"), ["camera_matrix", "expected [fx s cx; 0 fy cy; 0 0 1]"])
bad_file("opencv_intr_zero_focal", INTR, intr_xml("0 0 79.5 0 87.5 59.5 0 0 1"), ["camera_matrix", "positive focal lengths"])
bad_file("opencv_intr_negative_focal", INTR, intr_xml("87.5 0 79.5 0 -5 59.5 0 0 1"), ["camera_matrix", "fy = -5"])
bad_file("opencv_intr_rows_not_int", INTR, intr_xml().replace("<rows>3</rows>", "<rows>[3</rows>"),
         ["camera_matrix", "rows: expected an integer, found '[3'"])
bad_file("opencv_intr_no_data", INTR, intr_xml().replace("<data>87.5", "<x>87.5").replace("1.</data>", "1.</x>"),
         ["camera_matrix", "found no data"])
bad_file("opencv_intr_dist_three", INTR, intr_xml(dist="0 0 0"), ["distortion_coefficients", "found 3"])
bad_file("opencv_intr_dist_rational", INTR, intr_xml(dist="0 0 0 0 0 0.5 0 0"), ["distortion_coefficients", "coefficient 6 = 0.5"])
bad_file("opencv_intr_dist_nan", INTR, intr_xml(dist="0 nan 0 0 0"), ["distortion_coefficients", "finite"])
bad_file("opencv_intr_no_size", INTR, intr_xml(extra=""), ["image_width/image_height"])
bad_file("opencv_extr_no_rvec", EXTR, '<?xml version="1.0"?>\n<opencv_storage>\n<tvec>0 0 1</tvec>\n</opencv_storage>\n', ["rvec: missing"])
bad_file("opencv_extr_no_tvec", EXTR, '<?xml version="1.0"?>\n<opencv_storage>\n<rvec>0 0 0</rvec>\n</opencv_storage>\n', ["tvec: missing"])
bad_file("opencv_extr_short_rvec", EXTR, lambda w: extr_xml(w, rvec="0.1 0.2"), ["rvec: expected 3 numbers, found 2"])
bad_file("opencv_extr_text_tvec", EXTR, lambda w: extr_xml(w, tvec="1 abc 3"), ["tvec: expected a finite number, found 'abc'"])
bad_file("opencv_extr_nan_tvec", EXTR, lambda w: extr_xml(w, tvec="1 nan 3"), ["tvec", "found 'nan'"])
bad_file("opencv_extr_huge_rvec", EXTR, lambda w: extr_xml(w, rvec="1e300 1e300 1e300"), ["rvec", "at most 1000 rad"])
site("opencv_intr_size_mismatch", "calibration: {format: opencv, intrinsic: calib/intr_cam1.xml",
     "calibration: {format: opencv, image_size: [320, 240], intrinsic: calib/intr_cam1.xml",
     ["cameras[0].calibration.image_size", "the calibration file says 160x120, the site says 320x240"])
bad_file("opencv_extr_huge_tvec", EXTR, lambda w: extr_xml(w, tvec="1e300 1e300 1e300"), ["cameras[0]", "sees none"],
         names_file=False)
bad_file("opencv_extr_empty", EXTR, "", ["empty file"])
bad_file("opencv_extr_nul_byte", EXTR, b'<?xml version=\0\0"1.0"?>\n<opencv_storage>\n<rvec>0 0 0</rvec>\n</opencv_storage>\n',
         ["found a NUL byte at offset 14"])
bad_file("opencv_extr_truncated", EXTR, lambda w: read(w, "lab/" + EXTR)[:120], ["OpenCV FileStorage"])
# OpenCV's parsers recurse per level: 30,000 deep (XML) or 50,000 (YAML flow) overflowed the stack.
bad_file("opencv_intr_deep_xml", INTR, intr_xml(extra="<a>" * 30000 + "</a>" * 30000),
         ["nesting deeper than 64 levels"])
bad_file("opencv_intr_deep_yaml", INTR, "%YAML:1.0\n---\ncamera_matrix: " + "[" * 50000 + "]" * 50000 + "\n",
         [":3: nesting deeper than 64 levels"])
bad_file("opencv_intr_deep_yaml_block", INTR, "%YAML:1.0\n---\ncamera_matrix:\n" + "- " * 50000 + "1\n",
         [":4: nesting deeper than 64 levels"])
bad_file("opencv_intr_deep_json", INTR, '{"camera_matrix": ' + "[" * 50000 + "]" * 50000 + "}", ["nesting deeper than 64 levels"])
bad_file("opencv_extr_deep_xml", EXTR, '<?xml version="1.0"?>\n<opencv_storage>' + "<a>" * 30000 + "</a>" * 30000
         + "</opencv_storage>\n", ["nesting deeper than 64 levels"], cmd="run")
bad_file("opencv_intr_deep_xml_lut", INTR, intr_xml(extra="<a>" * 30000 + "</a>" * 30000),
         ["nesting deeper than 64 levels"], cmd="lut", args=["--no-cache", "--out", "{c}/o"])
# OpenCV keeps both values of a repeated key and reads the first.
bad_file("opencv_intr_duplicate_key", INTR, intr_xml(extra="<image_width>160</image_width><image_height>120</image_height>"
                                                     "<image_width>320</image_width>"), ["duplicate key 'image_width'"])
bad_file("opencv_extr_duplicate_key_yaml", EXTR, "%YAML:1.0\n---\nrvec: [0.1, 0.2, 0.3]\ntvec: [0, 0, 1]\nrvec: [0, 0, 0]\n",
         ["duplicate key 'rvec'"])

# --- GoPro JSON calibrations -----------------------------------------------------------------
GI = "calib/gopro_intr_cam1.json"
GE = "calib/gopro_extr_cam1.json"
GOOD_GI = '{"K": [[87.5, 0.0, 79.5], [0.0, 87.5, 59.5], [0.0, 0.0, 1.0]], "image_shape": [120, 160]}'
GOOD_R = "[[0.5821119003185249, -0.8131086861592094, 0], [-0.1968191111474196, -0.14090459093508448, -0.9702618892549351], [0.7889283700024327, 0.5648009921608325, -0.2420575680689282]]"
GOOD_T = "[0.02309967858406846, 2.653479471196575, 0.5181824975697796]"


def gopro(name, which, content, words):
    bad_file(name, GI if which == "i" else GE, content, words, frm=GOPRO_CAM[0], to=GOPRO_CAM[1])


gopro("gopro_intr_empty", "i", "", ["JSON syntax error"])
gopro("gopro_intr_syntax", "i", '{"K": [', ["JSON syntax error"])
gopro("gopro_intr_array", "i", "[1, 2]", ["expected a JSON object"])
gopro("gopro_intr_no_k", "i", '{"image_shape": [120, 160]}', ["K: missing"])
gopro("gopro_intr_k_rows", "i", '{"K": [[1,0,0],[0,1,0]], "image_shape": [120, 160]}', ["K: expected a 3x3 matrix, found 2 rows"])
gopro("gopro_intr_k_text", "i", '{"K": [[1,0,"x"],[0,1,0],[0,0,1]], "image_shape": [120, 160]}', ["K: expected numbers"])
gopro("gopro_intr_k_shape", "i", '{"K": [[87.5,0,79.5],[0,87.5,59.5],[0,1,1]], "image_shape": [120, 160]}', ["K: expected [fx s cx"])
gopro("gopro_intr_zero_focal", "i", '{"K": [[0,0,79.5],[0,87.5,59.5],[0,0,1]], "image_shape": [120, 160]}', ["positive focal lengths"])
gopro("gopro_intr_shape", "i", '{"K": [[87.5,0,79.5],[0,87.5,59.5],[0,0,1]], "image_shape": [120.5, 160]}', ["image_shape"])
gopro("gopro_intr_no_shape", "i", '{"K": [[87.5,0,79.5],[0,87.5,59.5],[0,0,1]]}', ["image_shape: missing"])
gopro("gopro_intr_dist_short", "i", GOOD_GI[:-1] + ', "distCoeffs": [[0, 0, 0]]}', ["distCoeffs"])
gopro("gopro_intr_big_number", "i", '{"K": [[1e999,0,79.5],[0,87.5,59.5],[0,0,1]], "image_shape": [120, 160]}', ["number overflow"])
gopro("gopro_intr_invalid_utf8", "i", b'{"K": "\xff"}', ["JSON syntax error"])
gopro("gopro_extr_not_rotation", "e", '{"unit": "m", "t": %s, "R": [[2,0,0],[0,1,0],[0,0,1]]}' % GOOD_T,
      ["R/t: rotation: expected an orthonormal matrix"])
gopro("gopro_extr_short_t", "e", '{"unit": "m", "t": [1, 2], "R": %s}' % GOOD_R, ["t: expected 3 numbers, found 2"])
gopro("gopro_extr_no_r", "e", '{"unit": "m", "t": %s}' % GOOD_T, ["R: missing"])
gopro("gopro_extr_unit", "e", '{"unit": "furlong", "t": %s, "R": %s}' % (GOOD_T, GOOD_R), ["unit", "furlong"])
gopro("gopro_extr_unit_number", "e", '{"unit": 3, "t": %s, "R": %s}' % (GOOD_T, GOOD_R), ["unit: expected a text"])
gopro("gopro_extr_no_unit", "e", '{"t": %s, "R": %s}' % (GOOD_T, GOOD_R), ["no `unit` field"])
gopro("gopro_intr_deep", "i", '{"K": ' + "[" * 100000 + "]" * 100000 + "}", ["nesting deeper than 64 levels"])
gopro("gopro_intr_duplicate_key", "i", GOOD_GI[:-1] + ', "K": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}', ["duplicate key 'K'"])
gopro("gopro_extr_duplicate_key", "e", '{"unit": "m", "t": %s, "R": %s, "t": [0, 0, 0]}' % (GOOD_T, GOOD_R), ["duplicate key 't'"])
gopro("gopro_extr_null_r", "e", '{"unit": "m", "t": %s, "R": null}' % GOOD_T, ["R: expected a 3x3 matrix"])

# --- Tsai YAML calibrations (clemson) ----------------------------------------------------------
TSAI = "calib/tsai_c1.yaml"


def tsai(name, frm, to, words):
    def content(work):
        text = read(work, "clemson/" + TSAI).decode()
        assert frm in text, f"{name}: {frm}"
        return text.replace(frm, to, 1)
    bad_file(name, TSAI, content, words, base="clemson")


tsai("tsai_f_zero", "\nf: 3", "\nf: 0", ["f"])
tsai("tsai_f_text", "\nf: 3", "\nf: three", ["f", "found 'three'"])
tsai("tsai_missing_f", "\nf: 3", "", ["bad-tsai_c1.yaml:1", "expected Tsai parameters"])
tsai("tsai_dx_negative", "\ndx: 0.029600000000000001", "\ndx: -1", ["dx"])
tsai("tsai_kappa_nan", "\nkappa1: 0.0040000000000000001", "\nkappa1: .nan", ["kappa1", "finite"])
tsai("tsai_rx_list", "\nRx: 2.3369660910926378", "\nRx: [1, 2]", ["Rx", "expected a number"])
tsai("tsai_width_zero", "image_width: 160", "image_width: 0", ["image size: expected 1..65535, found 0x120"])
tsai("tsai_unknown_key", "\nf: 3", "\nf: 3\nfocal: 3", ["unknown field 'focal'"])
tsai("tsai_duplicate_key", "\nf: 3", "\nf: 3\nf: 4", ["duplicate key 'f'"])
tsai("tsai_centre_inconsistent", "\nf: 3", "\nf: 3\ncamera_centre_world: [1, 2, 3]", ["camera_centre_world", "expected -R^T T"])
tsai("tsai_syntax", "\nf: 3", "\nf: [3", ["YAML syntax error"])
tsai("tsai_invalid_utf8", "\nf: 3", "\nf: 3 # \udcff", ["expected UTF-8 text"])
bad_file("tsai_empty", TSAI, "", [], base="clemson")
bad_file("tsai_list", TSAI, "- 1\n- 2\n", [], base="clemson")

# --- masks, backgrounds, frames, videos --------------------------------------------------------
PNG_HEADER = b"\x89PNG\r\n\x1a\n"


def png_bomb(side=10000):
    """A valid grey PNG of side x side black pixels: about 100 KB that decode to 100 MB."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    z = zlib.compressobj(9)
    row = b"\0" * (side + 1)
    idat = b"".join(z.compress(row) for _ in range(side)) + z.flush()
    return (PNG_HEADER + chunk(b"IHDR", struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0)) + chunk(b"IDAT", idat)
            + chunk(b"IEND", b""))


def jpeg_of(work, source="lab/frames/cam1/000000.png"):
    """A JPEG of a lab frame, made by ffmpeg (a dependency of the frame sources)."""
    out = os.path.join(work, "frame.jpg")
    if not os.path.exists(out):  # cases run in threads: each writes its own, the rename is atomic
        tmp = f"{out}.{os.getpid()}-{id(object())}.jpg"
        subprocess.run(["ffmpeg", "-loglevel", "error", "-y", "-i", os.path.join(work, source), "-frames:v", "1", tmp],
                       check=True)
        os.replace(tmp, out)
    return read(work, "frame.jpg")
bad_file("mask_not_png", "masks/cam1.png", "garbage", ["cameras[0].mask", "cannot decode image"])
bad_file("mask_empty", "masks/cam1.png", b"", ["cameras[0].mask", "empty file"])
bad_file("mask_truncated", "masks/cam1.png", lambda w: read(w, "lab/masks/cam1.png")[:60], ["cameras[0].mask"])
bad_file("mask_header_only", "masks/cam1.png", PNG_HEADER, ["cameras[0].mask"])
bad_file("mask_wrong_size", "masks/cam1.png", lambda w: read(w, "lab/../clemson/masks/c1.png") if False else read(w, "lutout/visibility.png"),
         ["cameras[0].mask", "expected the camera's image size 160x120"])
bad_file("mask_is_jpeg_garbage", "masks/cam1.png", b"\xff\xd8\xff\xe0" + b"\0" * 100, ["cameras[0].mask"])
# Decoded whole before its size was checked (1.85 GB for 30000 x 30000); a JPEG cut short was
# taken without a word, its missing rows grey.
bad_file("mask_png_bomb", "masks/cam1.png", lambda w: png_bomb(), ["cameras[0].mask", "PNG of 10000x10000 pixels",
         "refused before decoding"])
bad_file("mask_truncated_jpeg", "masks/cam1.png", lambda w: jpeg_of(w)[:len(jpeg_of(w)) // 2],
         ["cameras[0].mask", "truncated JPEG"])
site("mask_polygon_and_polygons", "mask: masks/cam1.png",
     "mask: {polygon: [[0, 0], [100, 0], [100, 100]], polygons: [[[0, 0], [50, 0], [50, 50]]]}",
     ["cameras[0].mask", "found both"])
bad_file("background_png_bomb", "backgrounds/cam1.png", lambda w: png_bomb(), ["PNG of 10000x10000 pixels"], cmd="run")
bad_file("background_truncated_jpeg", "backgrounds/cam1.png", lambda w: jpeg_of(w)[:len(jpeg_of(w)) // 2],
         ["truncated JPEG"], cmd="run")
bad_file("background_not_png", "backgrounds/cam1.png", "garbage", ["cam1"], cmd="run")
bad_file("background_empty", "backgrounds/cam1.png", b"", ["cam1"], cmd="run")
bad_file("background_wrong_size", "backgrounds/cam1.png", lambda w: read(w, "lutout/visibility.png"),
         ["cameras[0].background", "expected the image size 160x120"], cmd="run")
bad_file("background_truncated", "backgrounds/cam1.png", lambda w: read(w, "lab/backgrounds/cam1.png")[:100], ["cam1"], cmd="run")
site("frames_missing_folder", "source: {images: frames/cam1/%06d.png}", "source: {images: frames/none/%06d.png}",
     ["cameras[0].source", "none"], cmd="run")
site("frames_empty_folder", "source: {images: frames/cam1/%06d.png}", "source: {images: gt/%06d.png}",
     ["cameras[0].source", "gt"], cmd="run")
site("frames_start_past_end", "source: {images: frames/cam1/%06d.png}", "source: {images: frames/cam1/%06d.png}",
     ["cameras[0].source", "--start 50", "cannot skip to frame 50"], cmd="run", args=["--start", "50"])


def frame_case(name, content, words):
    def setup(case_dir, work):
        os.makedirs(os.path.join(case_dir, "f"))
        shutil.copy(os.path.join(work, "lab/frames/cam1/000000.png"), os.path.join(case_dir, "f/000000.png"))
        data = content(work) if callable(content) else content
        with open(os.path.join(case_dir, "f/000001.png"), "wb") as f:
            f.write(data)
        text = with_data_root(LAB_SITE.replace("frames/cam1/%06d.png", os.path.join(case_dir, "f/%06d.png"), 1), "lab")
        with open(os.path.join(case_dir, "site.yaml"), "w") as f:
            f.write(text.replace("{w}", work))
    add(name, ["{bin}", "run", "{c}/site.yaml", "--frames", "2", "--no-video", "--no-cache", "--out", "{c}/out"],
        words, setup=setup)


frame_case("frame_corrupt", b"garbage", ["000001.png"])
frame_case("frame_truncated", lambda w: read(w, "lab/frames/cam1/000001.png")[:80], ["000001.png"])
frame_case("frame_wrong_size", lambda w: read(w, "lutout/visibility.png"), ["000001.png", "160x120"])
frame_case("frame_empty", b"", ["000001.png"])
frame_case("frame_png_bomb", lambda w: png_bomb(), ["000001.png", "PNG of 10000x10000 pixels"])
frame_case("frame_truncated_jpeg", lambda w: jpeg_of(w)[:len(jpeg_of(w)) // 2], ["000001.png", "truncated JPEG"])


def video_case(name, content, words, file_name="v.mp4"):
    def setup(case_dir, work):
        data = content(work) if callable(content) else content
        with open(os.path.join(case_dir, file_name), "wb") as f:
            f.write(data)
        text = with_data_root(LAB_SITE.replace("{images: frames/cam1/%06d.png}", "{video: " + os.path.join(case_dir, file_name) + "}", 1), "lab")
        with open(os.path.join(case_dir, "site.yaml"), "w") as f:
            f.write(text.replace("{w}", work))
    add(name, ["{bin}", "run", "{c}/site.yaml", "--frames", "2", "--no-video", "--no-cache", "--out", "{c}/out"],
        [file_name] + words, setup=setup)


def tiny_bmp():
    """A 4x2 24-bit BMP."""
    import struct
    pixels = b"\x40" * 24
    return (b"BM" + struct.pack("<IHHI", 54 + len(pixels), 0, 0, 54)
            + struct.pack("<IiiHHIIiiII", 40, 4, 2, 1, 24, 0, len(pixels), 0, 0, 0, 0) + pixels)


video_case("video_empty", b"", [])
video_case("video_garbage", b"not a video at all" * 100, [])
# Still images: FFmpeg would read each as a video of one frame.
STILL = ["site.yaml:13: cameras[0].source", "expected a video file, found"]
video_case("video_is_png", lambda w: read(w, "lab/frames/cam1/000000.png"), STILL + ["a PNG image"])
video_case("video_is_png_named_png", lambda w: read(w, "lab/frames/cam1/000000.png"), STILL + ["a PNG image"],
           file_name="v.png")
video_case("video_is_mask_png", lambda w: read(w, "lab/masks/cam1.png"), STILL + ["a PNG image"])
video_case("video_is_bmp", tiny_bmp(), STILL + ["a BMP image"], file_name="v.bmp")
video_case("video_truncated_header", lambda w: read(w, "labvid/frames/cam1.mp4")[:500], [])
video_case("video_wrong_size", lambda w: read(w, "labvid/frames/cam1.mp4") if False else b"\0" * 4096, [])

# --- table caches: a corrupt cache is rebuilt (exit 0), never trusted --------------------------


def cache_case(name, mutate, words, code=0):
    def setup(case_dir, work):
        os.makedirs(os.path.join(case_dir, "cache"))
        data = bytearray(read(work, "cache/lab.lut"))
        with open(os.path.join(case_dir, "cache/lab.lut"), "wb") as f:
            f.write(bytes(mutate(data)))
    add(name, ["{bin}", "lut", "{w}/lab/site.yaml", "--cache-dir", "{c}/cache", "--out", "{c}/out"], words, code=code,
        setup=setup)


def flip(data, at):
    data[at] ^= 0xFF
    return data


cache_case("cache_empty", lambda d: b"", ["rebuilt"])
cache_case("cache_truncated_header", lambda d: d[:20], ["rebuilt"])
cache_case("cache_truncated_payload", lambda d: d[: len(d) // 2], ["rebuilt"])
cache_case("cache_bad_magic", lambda d: flip(d, 0), ["rebuilt"])
cache_case("cache_bad_version", lambda d: flip(d, 8), ["rebuilt"])
cache_case("cache_flipped_payload", lambda d: flip(d, len(d) - 10), ["rebuilt"])
cache_case("cache_huge_length", lambda d: d[:24] + b"\xff" * 8 + d[32:], ["rebuilt"])
cache_case("cache_other_file", lambda d: b"x" * 100, ["rebuilt"])

# --- scene files (synth --scene X.yaml) --------------------------------------------------------


def scene(name, frm, to, words, args=()):
    def setup(case_dir, work):
        assert frm in LAB_SCENE, f"{name}: {frm}"
        with open(os.path.join(case_dir, "scene.yaml"), "wb") as f:
            f.write(LAB_SCENE.replace(frm, to, 1).encode("utf-8", "surrogateescape"))
    add(name, ["{bin}", "synth", "--scene", "{c}/scene.yaml", "--out", "{c}/out", "--scale", "0.25"] + list(args),
        ["scene.yaml"] + words, setup=setup)


scene("scene_syntax", "fps: 10", "fps: [10", ["YAML syntax error"])
scene("scene_version", "version: 1", "version: 7", ["version"])
scene("scene_fps_zero", "fps: 10", "fps: 0", ["fps"])
scene("scene_fps_text", "fps: 10", "fps: fast", ["fps", "found 'fast'"])
scene("scene_frames_zero", "frames: 2", "frames: 0", ["frames"])
scene("scene_frames_huge", "frames: 2", "frames: 100000000", ["frames"])
scene("scene_unknown_key", "seed: 1", "seed: 1\nsed: 2", ["unknown field 'sed'"])
scene("scene_duplicate_key", "seed: 1", "seed: 1\nseed: 2", ["duplicate key 'seed'"])
scene("scene_camera_model", "model: pinhole", "model: fisheye", ["cameras[0].model", "fisheye"])
scene("scene_camera_size", "image_size: [160, 120]", "image_size: [0, 120]", ["cameras[0].image_size"])
scene("scene_rotation", "rotation: [[0.5821119003185249, -0.8131086861592094, 0]", "rotation: [[2, -0.8131086861592094, 0]",
      ["cameras[0]", "rotation"])
scene("scene_object_class", "class: person", "class: ghost", ["objects[0].class", "ghost"])
scene("scene_object_height", "height_m: 1.6286362564733015", "height_m: -1", ["objects[0].height_m"])
scene("scene_path_time", "- {at_m: [7.6, 1.3], t_s: 5.125621913485231}", "- {at_m: [7.6, 1.3], t_s: -5}", ["objects[0].path"])
scene("scene_static_shape", "shape: box", "shape: sphere", ["statics[0].shape", "sphere"])
scene("scene_material_pattern", "pattern: carpet", "pattern: plaid", ["floor.pieces[0].material.pattern", "plaid"])
scene("scene_light_type", "type: point", "type: laser", ["lighting.light.type", "laser"])
scene("scene_camera_key", "  shadows: false", "  shadows: false\n  camera: {jpg_quality: 70}",
      ["photometry.camera", "unknown field 'jpg_quality'", "did you mean 'jpeg_quality'"])
scene("scene_camera_supersample", "  shadows: false", "  shadows: false\n  camera: {supersample: 8}",
      ["photometry.camera.supersample", "found 8"])
scene("scene_camera_white_balance", "  shadows: false", "  shadows: false\n  camera: {white_balance: yes}",
      ["photometry.camera.white_balance"])
scene("scene_contact_reach", "  shadows: false", "  shadows: false\n  contact_shadows: {radius_m: 0.3, reach_m: 0.2}",
      ["photometry.contact_shadows.reach_m", "found 0.2"])
scene("scene_invalid_utf8", 'name: "lab"', 'name: "l\udcffab"', ["expected UTF-8 text"])
scene("scene_name_traversal", 'name: "lab"', 'name: "../../evil"', ["name", "scene name '../../evil'"])
add("scene_missing_file", ["{bin}", "synth", "--scene", "{c}/none.yaml", "--out", "{c}/out"], ["none.yaml", "file not found"])
add("scene_fifo", ["{bin}", "synth", "--scene", "{c}/fifo.yaml", "--out", "{c}/out"], ["fifo.yaml", "expected a regular file, found a FIFO"],
    setup=lambda c, w: os.mkfifo(os.path.join(c, "fifo.yaml")), timeout=20)

# --- eval inputs -------------------------------------------------------------------------------


def eval_case(name, gt=None, det=None, words=(), code=2, tracks=None, args=()):
    def setup(case_dir, work):
        ds = os.path.join(case_dir, "ds")
        run = os.path.join(case_dir, "run")
        shutil.copytree(os.path.join(work, "lab"), ds, ignore=shutil.ignore_patterns("frames", "backgrounds", "masks", "calib"))
        shutil.copytree(os.path.join(work, "labrun"), run)
        if gt is not None:
            with open(os.path.join(ds, "ground_truth.jsonl"), "wb") as f:
                f.write(gt if isinstance(gt, bytes) else gt.encode())
        if det is not None:
            with open(os.path.join(run, "detections.jsonl"), "wb") as f:
                f.write(det if isinstance(det, bytes) else det.encode())
        if tracks is not None:
            with open(os.path.join(run, "tracks.jsonl"), "wb") as f:
                f.write(tracks if isinstance(tracks, bytes) else tracks.encode())
    add(name, ["{bin}", "eval", "{c}/ds", "{c}/run"] + list(args), list(words), code=code, setup=setup)


eval_case("eval_gt_syntax", gt='{"frame": 0, "objects": [\n', words=["ground_truth.jsonl", ":1"])
eval_case("eval_gt_not_object", gt="[1, 2]\n", words=["ground_truth.jsonl", ":1"])
eval_case("eval_gt_no_frame", gt='{"objects": []}\n', words=["ground_truth.jsonl", ":1", "frame"])
eval_case("eval_gt_frame_text", gt='{"frame": "zero", "objects": []}\n', words=["ground_truth.jsonl", ":1", "frame"])
eval_case("eval_gt_object_no_x", gt='{"frame": 0, "time_s": 0, "objects": [{"id": 1, "y_m": 1}]}\n', words=["ground_truth.jsonl:1", "x_m"])
eval_case("eval_gt_no_time", gt='{"frame": 0, "objects": []}\n', words=["ground_truth.jsonl:1", "time_s"])
eval_case("eval_gt_nan", gt='{"frame": 0, "objects": [{"id": 1, "x_m": NaN, "y_m": 1}]}\n', words=["ground_truth.jsonl", ":1"])
eval_case("eval_gt_invalid_utf8", gt=b'{"frame": 0, "objects": [{"class": "\xff"}]}\n', words=["ground_truth.jsonl", ":1"])
eval_case("eval_gt_line_2", gt='{"frame": 0, "time_s": 0, "objects": []}\n{"frame": 1, "time_s": 0.1, "objects": 3}\n',
          words=["ground_truth.jsonl:2", "objects"])
eval_case("eval_gt_number_overflow", gt='{"frame": 0, "time_s": 1e999, "objects": []}\n', words=["ground_truth.jsonl:1"])
eval_case("eval_det_number_overflow", det='{"frame": 0, "time_s": 1e999, "blobs": []}\n', words=["detections.jsonl:1"])
eval_case("eval_det_syntax", det='{"frame": 0, "blobs": [\n', words=["detections.jsonl", ":1"])
eval_case("eval_det_no_blobs", det='{"frame": 0}\n', words=["detections.jsonl", ":1", "blobs"])
eval_case("eval_det_blob_text", det='{"frame": 0, "time_s": 0, "blobs": [{"x_m": "a", "y_m": 1}]}\n', words=["detections.jsonl:1", "x_m"])
eval_case("eval_det_frame_negative", det='{"frame": -4, "blobs": []}\n', words=["detections.jsonl", ":1", "frame"])
# dump() in the messages recursed per level: 100,000 deep crashed `occmap eval`.
eval_case("eval_gt_deep", gt='{"frame": 0, "time_s": 0, "objects": ' + "[" * 100000 + "]" * 100000 + "}\n",
          words=["ground_truth.jsonl:1", "nesting deeper than 64 levels"])
eval_case("eval_det_deep", det='{"frame": 0, "time_s": 0, "blobs": [' + "[" * 100000 + "]" * 100000 + "]}\n",
          words=["detections.jsonl:1", "nesting deeper than 64 levels"])
eval_case("eval_tracks_syntax", tracks='{"frame": 0, "tracks": [\n', words=["tracks.jsonl", ":1"])
eval_case("eval_tracks_not_list", tracks='{"frame": 0, "time_s": 0, "tracks": 5}\n', words=["tracks.jsonl", ":1", "tracks"])
add("eval_missing_run", ["{bin}", "eval", "{w}/lab", "{c}/nowhere"], ["nowhere"])
add("eval_missing_dataset", ["{bin}", "eval", "{c}/nowhere", "{w}/labrun"], ["nowhere"])
add("eval_threshold_negative", ["{bin}", "eval", "{w}/lab", "{w}/labrun", "--threshold-m", "-1"], ["threshold"])
add("eval_format", ["{bin}", "eval", "{w}/lab", "{w}/labrun", "--format", "coco"], ["--format", "coco"])
add("eval_frame_step", ["{bin}", "eval", "{w}/lab", "{w}/labrun", "--frame-step", "0/0"], ["frame-step"])
add("eval_range", ["{bin}", "eval", "{w}/lab", "{w}/labrun", "--annotation-range", "9:1"], ["annotation-range"])


def annotations_case(name, content, words):
    def setup(case_dir, work):
        os.makedirs(os.path.join(case_dir, "bench/annotations_positions"))
        with open(os.path.join(case_dir, "bench/annotations_positions/00000000.json"), "wb") as f:
            f.write(content.encode() if isinstance(content, str) else content)
    add(name, ["{bin}", "eval", "{c}/bench", "{w}/labrun"], ["00000000.json"] + words, setup=setup)


annotations_case("annotations_syntax", "[{", [])
annotations_case("annotations_not_list", '{"a": 1}', [])
annotations_case("annotations_position_text", '[{"personID": 1, "positionID": "x", "views": []}]', ["positionID"])
annotations_case("annotations_number_overflow", '[{"personID": 1e999, "positionID": 3, "views": []}]', [])
annotations_case("annotations_deep", "[" * 100000 + "]" * 100000, ["nesting deeper than 64 levels"])
annotations_case("annotations_no_id", '[{"positionID": 3, "views": []}]', ["personID"])

# --- command-line options ----------------------------------------------------------------------
add("cli_no_subcommand", ["{bin}"], ["subcommand"])
add("cli_unknown_subcommand", ["{bin}", "fly"], ["unknown command", "fly"])
add("cli_unknown_option", ["{bin}", "check", "{w}/lab/site.yaml", "--bogus"], ["--bogus"])
add("cli_threads_negative", ["{bin}", "--threads", "-1", "check", "{w}/lab/site.yaml"], ["--threads"])
add("cli_threads_huge", ["{bin}", "--threads", "100000", "check", "{w}/lab/site.yaml"], ["--threads"])
add("cli_threads_text", ["{bin}", "--threads", "many", "check", "{w}/lab/site.yaml"], ["--threads"])
add("cli_run_frames_negative", ["{bin}", "run", "{w}/lab/site.yaml", "--frames", "-1", "--out", "{c}/o"], ["--frames", "-1"])
add("cli_run_frames_zero", ["{bin}", "run", "{w}/lab/site.yaml", "--frames", "0", "--out", "{c}/o"], ["--frames", "0"])
add("cli_run_frames_text", ["{bin}", "run", "{w}/lab/site.yaml", "--frames", "ten", "--out", "{c}/o"], ["--frames"])
add("cli_run_start_negative", ["{bin}", "run", "{w}/lab/site.yaml", "--start", "-3", "--out", "{c}/o"], ["--start", "-3"])
add("cli_fuse_token_without_listen", ["{bin}", "fuse", "{w}/lab/site.yaml", "--token", "t0ken", "--out", "{c}/o"],
    ["--token", "--listen"])
add("cli_fuse_listen_beyond_loopback", ["{bin}", "fuse", "{w}/lab/site.yaml", "--listen", "0.0.0.0:0", "--out", "{c}/o"],
    ["--listen", "0.0.0.0:0", "--token"])
# A one-character token is no gate beyond loopback.
add("cli_serve_token_short", ["{bin}", "serve", "{w}/lab/site.yaml", "--listen", "0.0.0.0:0", "--token", "a", "--out", "{c}/o"],
    ["--token", "at least 16 characters, found 1"])
# '%' would be decoded out of the Authorization header before the token is compared.
add("cli_serve_token_percent", ["{bin}", "serve", "{w}/lab/site.yaml", "--listen", "127.0.0.1:0", "--token",
                                "abcdefgh%41bcdefgh", "--out", "{c}/o"],
    ["--token", "without spaces or '%'"])
add("cli_fuse_token_short", ["{bin}", "fuse", "{w}/lab/site.yaml", "--listen", "0.0.0.0:0", "--token", "short", "--out", "{c}/o"],
    ["--token", "at least 16 characters, found 5"])
add("cli_serve_allow_host", ["{bin}", "serve", "{w}/lab/site.yaml", "--allow-host", "a/b", "--out", "{c}/o"],
    ["--allow-host", "a/b"])
add("cli_fuse_allow_host", ["{bin}", "fuse", "{w}/lab/site.yaml", "--listen", "127.0.0.1:0", "--allow-host", "a b",
                            "--out", "{c}/o"], ["--allow-host", "a b"])
add("cli_fuse_allow_host_without_listen", ["{bin}", "fuse", "{w}/lab/site.yaml", "--allow-host", "occmap.test",
                                           "--out", "{c}/o"], ["--allow-host", "--listen"])
add("cli_fuse_listen_bad_port", ["{bin}", "fuse", "{w}/lab/site.yaml", "--listen", "127.0.0.1:99999", "--out", "{c}/o"],
    ["--listen", "99999"])
add("cli_run_sync", ["{bin}", "run", "{w}/lab/site.yaml", "--sync", "clock", "--out", "{c}/o"], ["--sync", "clock"])
add("cli_run_summary_every", ["{bin}", "run", "{w}/lab/site.yaml", "--summary-every-s", "-1", "--frames", "1", "--out", "{c}/o"],
    ["summary"])
add("cli_run_background_frames", ["{bin}", "run", "{w}/lab/site.yaml", "--background-frames", "0", "--frames", "1", "--out", "{c}/o"],
    ["background"])
add("cli_run_min_blob_area", ["{bin}", "run", "{w}/lab/site.yaml", "--min-blob-area-m2", "-1", "--frames", "1", "--out", "{c}/o"],
    ["area"])
add("cli_run_mqtt_url", ["{bin}", "run", "{w}/lab/site.yaml", "--mqtt", "ftp://x", "--frames", "1", "--out", "{c}/o"], ["mqtt"])
add("cli_run_mqtt_password_missing", ["{bin}", "run", "{w}/lab/site.yaml", "--mqtt", "mqtt://127.0.0.1:1", "--mqtt-password-file",
                                      "{c}/none.txt", "--frames", "1", "--out", "{c}/o"], ["none.txt"])
add("cli_run_ros_fraction", ["{bin}", "run", "{w}/lab/site.yaml", "--ros-map", "{c}/ros", "--ros-map-static-fraction", "2",
                             "--frames", "1", "--out", "{c}/o"], ["static"])
add("cli_run_out_is_file", ["{bin}", "run", "{w}/lab/site.yaml", "--frames", "1", "--no-video", "--out", "{w}/lab/site.yaml"],
    ["site.yaml"], code=1)
add("cli_run_site_missing", ["{bin}", "run", "{c}/none.yaml"], ["none.yaml", "file not found"])
add("cli_run_site_directory", ["{bin}", "run", "{w}/lab"], ["lab", "expected a file, found a directory"])
add("cli_check_dev_zero", ["{bin}", "check", "/dev/zero"], ["/dev/zero", "expected a regular file, found a character device"],
    timeout=20)
add("cli_check_fifo", ["{bin}", "check", "{c}/fifo.yaml"], ["fifo.yaml", "expected a regular file, found a FIFO"],
    setup=lambda c, w: os.mkfifo(os.path.join(c, "fifo.yaml")), timeout=20)
add("cli_check_too_big", ["{bin}", "check", "{c}/big.yaml"], ["big.yaml", "expected at most 67108864 bytes"],
    setup=lambda c, w: os.truncate(open(os.path.join(c, "big.yaml"), "w").name, (64 << 20) + 1))
add("cli_check_data_root_missing", ["{bin}", "--data-root", "{c}/none", "check", "{w}/lab/site.yaml"], ["--data-root", "none"])
add("cli_synth_frames_huge", ["{bin}", "synth", "--frames", "10000001", "--out", "{c}/o"], ["--frames", "10000001"])
add("cli_synth_frames_negative", ["{bin}", "synth", "--frames", "-1", "--out", "{c}/o"], ["--frames", "-1"])
add("cli_synth_scene", ["{bin}", "synth", "--scene", "mars", "--out", "{c}/o"], ["scene", "mars"])
add("cli_synth_scale", ["{bin}", "synth", "--scale", "0", "--out", "{c}/o"], ["scale", "found 0"])
add("cli_synth_noise", ["{bin}", "synth", "--noise", "100", "--out", "{c}/o"], ["noise", "found 100"])
add("cli_synth_people", ["{bin}", "synth", "--scene", "plaza", "--people", "99", "--out", "{c}/o"], ["people", "found 99"])
add("cli_synth_duration", ["{bin}", "synth", "--scene", "plaza", "--duration-s", "0.1", "--out", "{c}/o"], ["duration", "found 0.1"])
add("cli_synth_sun", ["{bin}", "synth", "--scene", "plaza", "--sun-elevation-deg", "1", "--out", "{c}/o"], ["sun elevation", "found 1"])
add("cli_synth_drift", ["{bin}", "synth", "--exposure-drift", "3", "--out", "{c}/o"], ["exposure drift", "found 3"])
add("cli_synth_supersample", ["{bin}", "synth", "--supersample", "9", "--out", "{c}/o"], ["supersample", "found 9"])
add("cli_synth_jpeg_quality", ["{bin}", "synth", "--jpeg-quality", "101", "--out", "{c}/o"], ["JPEG quality", "found 101"])
add("cli_synth_crf", ["{bin}", "synth", "--crf", "60", "--out", "{c}/o"], ["crf", "found 60"])
add("cli_synth_white_balance", ["{bin}", "synth", "--white-balance", "2", "--out", "{c}/o"], ["white balance", "found 2"])
add("cli_synth_shot_noise", ["{bin}", "synth", "--shot-noise", "-1", "--out", "{c}/o"], ["shot noise", "found -1"])
add("cli_synth_contact_shadows", ["{bin}", "synth", "--contact-shadows", "1.5", "--out", "{c}/o"], ["contact shadows", "found 1.5"])
add("cli_synth_two_cameras", ["{bin}", "synth", "--real-camera", "--ideal-camera", "--out", "{c}/o"], ["--real-camera", "found both"])
add("cli_synth_overcast_lab", ["{bin}", "synth", "--overcast", "--out", "{c}/o"], ["overcast", "scene 'lab'"])
add("cli_synth_overcast_sun", ["{bin}", "synth", "--scene", "plaza", "--overcast", "--sun-elevation-deg", "30", "--out", "{c}/o"],
    ["overcast", "found a sun elevation of 30"])
add("cli_demo_frames_negative", ["{bin}", "demo", "--frames", "-1", "--out", "{c}/o"], ["--frames", "-1"])
add("cli_lut_plane_nan", ["{bin}", "lut", "{w}/lab/site.yaml", "--plane-height-m", "nan", "--no-cache", "--out", "{c}/o"], ["plane"])
add("cli_bench_fraction", ["{bin}", "bench", "--changed-fraction", "2"], ["--changed-fraction"])
add("cli_calibrate_missing", ["{bin}", "calibrate"], ["calibrate"])


def site_calib_copy(case_dir, work):
    """The lab site's calib/ folder copied, as --out, and four floor points."""
    shutil.copytree(os.path.join(work, "lab", "calib"), os.path.join(case_dir, "calib"))
    with open(os.path.join(case_dir, "pts.csv"), "w") as f:
        f.write("20,20,1,1\n140,20,7,1\n140,100,7,5\n20,100,1,5\n")


# --out the site's own calib/ without --update-site or --force: its files are not replaced.
add("cli_calibrate_out_site_calib",
    ["{bin}", "calibrate", "--camera", "cam1", "--intrinsics", "{w}/lab/calib/intr_cam1.xml", "--points", "{c}/pts.csv",
     "--image-size", "160x120", "--out", "{c}/calib"],
    ["calib/intr_cam1.xml' exists", "--force", "--update-site"], setup=site_calib_copy)

# ----------------------------------------------------------------------------------------------
# Runner


def run_case(case, occmap, work, root):
    case_dir = os.path.join(root, case.name)
    os.makedirs(case_dir)
    try:
        if case.setup:
            case.setup(case_dir, work)
    except Exception as e:  # a broken table row is a failure of its own
        return case, None, f"setup failed: {e!r}"
    argv = [a.replace("{bin}", occmap).replace("{w}", work).replace("{c}", case_dir) for a in case.argv]
    t0 = time.monotonic()
    try:
        p = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=case.timeout, cwd=case_dir,
                           stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return case, None, f"timed out after {case.timeout} s: {' '.join(argv)}"
    except OSError as e:
        return case, None, f"cannot run {argv[0]}: {e}"
    out = p.stdout.decode("utf-8", errors="replace")
    problems = []
    if p.returncode != case.code:
        problems.append(f"exit {p.returncode}, expected {case.code}")
    for w in case.words:
        w = w.replace("{w}", work).replace("{c}", case_dir)
        if w not in out:
            problems.append(f"message lacks {w!r}")
    if p.returncode < 0 or p.returncode >= 128:
        problems.append("crashed")
    if case.code == 2 and not out.strip():
        problems.append("no message")
    if case.max_output is not None and len(p.stdout) > case.max_output:
        problems.append(f"{len(p.stdout)} bytes of output, expected at most {case.max_output}")
        out = out[:3000]
    detail = "; ".join(problems)
    if problems:
        detail += f"\n    command: {' '.join(argv)}\n    output: " + "\n            ".join(out.strip().splitlines()[-6:])
    return case, time.monotonic() - t0, detail


def main():
    args = sys.argv[1:]
    if not args:
        sys.exit(__doc__)
    occmap = os.path.abspath(args[0])
    jobs = int(args[args.index("--jobs") + 1]) if "--jobs" in args else max(2, os.cpu_count() or 2)
    only = args[args.index("--only") + 1] if "--only" in args else None
    names = [c.name for c in CASES]
    dupes = {n for n in names if names.count(n) > 1}
    if dupes:
        sys.exit(f"duplicate case names: {sorted(dupes)}")
    if "--list" in args:
        print("\n".join(names))
        print(f"{len(CASES)} cases")
        return 0
    root = tempfile.mkdtemp(prefix="occmap-bad-inputs-")
    work = os.path.join(root, "fixtures")
    os.makedirs(work)
    t0 = time.monotonic()
    global LAB_SITE, CLEMSON_SITE, LAB_SCENE
    make_fixtures(occmap, work)
    LAB_SITE = open(f"{work}/lab/site.yaml").read()
    CLEMSON_SITE = open(f"{work}/clemson/site.yaml").read()
    LAB_SCENE = open(f"{work}/lab/scene.yaml").read()
    t_fixtures = time.monotonic() - t0
    cases = [c for c in CASES if only is None or any(o in c.name for o in only.split(","))]
    failures = []
    cases_dir = os.path.join(root, "cases")
    with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
        for case, seconds, detail in pool.map(lambda c: run_case(c, occmap, work, cases_dir), cases):
            if detail:
                failures.append(f"FAIL {case.name}: {detail}")
    for f in failures:
        print(f)
    print(f"{len(cases) - len(failures)} of {len(cases)} bad-input cases passed "
          f"(fixtures {t_fixtures:.1f} s, total {time.monotonic() - t0:.1f} s, {jobs} jobs)")
    if "--keep" in args:
        print(f"kept {root}")
    else:
        shutil.rmtree(root, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    sys.exit(main())
