"""The examples in examples/ and docs/python.md's example run as written."""
import json
import os
import re
import subprocess
import sys

from conftest import SOURCE_DIR

EXAMPLES = SOURCE_DIR / "examples"


def run(args, cwd=None):
    done = subprocess.run([sys.executable, *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=600)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_masks_to_tracks(lab):
    pattern = str(lab["data"] / "gt" / "changes" / "{camera}" / "{frame:06d}.png")
    out = run([EXAMPLES / "masks_to_tracks.py", lab["site"], pattern, "--frames", lab["frames"]]).splitlines()
    assert len(out) == lab["frames"]
    last = json.loads((lab["run"] / "tracks.jsonl").read_text().splitlines()[-1])
    ids = [int(m) for m in re.findall(r" (\d+):\(", out[-1])]
    assert ids == [t["id"] for t in last["tracks"]] and ids


def test_score_run(lab):
    out = run([EXAMPLES / "score_run.py", lab["run"], lab["data"] / "ground_truth.jsonl"])
    moda = float(re.search(r"MODA (-?[\d.]+)", out).group(1))
    assert f"{lab['frames']} frames" in out and 0.5 < moda <= 1.0, out


def test_tune_fusion(tmp_path):
    out = run([EXAMPLES / "tune_fusion.py", tmp_path / "corridor", "--frames", "6"]).splitlines()
    rows = [line.split() for line in out[1:]]
    assert len(rows) == 9
    assert max(float(r[2]) for r in rows) > 0.5, out


def test_guide_python_example(tmp_path):
    guide = (SOURCE_DIR / "docs" / "python.md").read_text()
    code = re.search(r"```python\n(.*?)```", guide, re.S).group(1)
    assert len(code.strip().splitlines()) <= 10
    (tmp_path / "example.py").write_text(code)
    out = run([tmp_path / "example.py"], cwd=tmp_path)
    assert "Track(id=" in out, out


def test_bench_script_runs(datasets):
    # Figures only: the ratio is docs/python.md's, measured by hand (no timed assertion here).
    out = run([SOURCE_DIR / "scripts" / "bench_python.py", "--data-root", datasets, "--repeats", "2", "--rounds", "1"])
    assert re.search(r"Python [\d.]+ ms, C\+\+ [\d.]+ ms per call, ratio [\d.]+", out), out
