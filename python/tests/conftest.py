"""Shared fixtures: the occmap program, a rendered lab dataset with its perfect change masks, and
`occmap run` on that dataset's masks (the reference the module must equal)."""
import os
import pathlib
import re
import subprocess

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("OCCMAP_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
LAB_FRAMES = 24


@pytest.fixture(scope="session")
def occmap_bin():
    path = os.environ.get("OCCMAP_BIN")
    if not path:
        path = str(SOURCE_DIR / "build" / "release" / "occmap")
    assert os.path.exists(path), f"occmap program not found: {path} (set OCCMAP_BIN)"
    return path


@pytest.fixture(scope="session")
def datasets():
    root = pathlib.Path(os.environ.get("OCCMAP_DATASETS", SOURCE_DIR.parent / "shared" / "datasets"))
    if not (root / "gopro4").is_dir():
        pytest.skip(f"shared datasets not found in {root}")
    return root


def mask_site(dataset: pathlib.Path) -> pathlib.Path:
    """The dataset's site.yaml with each camera reading its perfect change masks instead of frames."""
    text = (dataset / "site.yaml").read_text()
    text = re.sub(r"source: \{images: frames/(\w+)/%06d\.png\}", r"source: {masks: gt/changes/\1/%06d.png}", text)
    text = re.sub(r"\n\s*background: [^\n]*", "", text)
    # A zone and a counting line across the room, for the events.
    text += ("tracking:\n  zones: [{name: middle, polygon: [[2, 1], [7, 1], [7, 5.5], [2, 5.5]]}]\n"
             "  lines: [{name: gate, from: [4.0, 0], to: [4.0, 6.5], hysteresis_m: 0}]\n")
    path = dataset / "mask_site.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="session")
def lab(occmap_bin, tmp_path_factory):
    """A rendered lab dataset, its mask site, and `occmap run` on it."""
    root = tmp_path_factory.mktemp("lab")
    data = root / "data"
    subprocess.run([occmap_bin, "--threads", "2", "synth", "--scene", "lab", "--frames", str(LAB_FRAMES),
                    "--out", str(data)], check=True, stdout=subprocess.DEVNULL)
    site = mask_site(data)
    run = root / "run"
    subprocess.run([occmap_bin, "--threads", "2", "run", str(site), "--out", str(run), "--no-video",
                    "--occupancy-pngs", "--no-wall-clock", "--no-cache"], check=True, stdout=subprocess.DEVNULL)
    return {"data": data, "site": site, "run": run, "frames": LAB_FRAMES}
