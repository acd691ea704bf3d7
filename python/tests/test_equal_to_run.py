"""The module's maps, detections and tracks equal `occmap run`'s on the same masks."""
import json

import numpy as np
import occmap


def read_lines(path):
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def assert_detections_equal(mine, theirs, where):
    assert len(mine) == len(theirs), f"{where}: {len(mine)} detections, run has {len(theirs)}"
    for d, b in zip(mine, theirs):
        # The run's files round positions to 0.1 mm and areas to 1e-5 m^2.
        assert abs(d.x_m - b["x_m"]) <= 0.5e-4 + 1e-9, where
        assert abs(d.y_m - b["y_m"]) <= 0.5e-4 + 1e-9, where
        assert abs(d.area_m2 - b["area_m2"]) <= 0.5e-5 + 1e-9, where
        assert d.cells == b["cells"], where


def run_through_module(site_path, mask_paths_of_frame, frames, data_root=None):
    site = occmap.load_site(site_path, data_root=data_root)
    tables = occmap.Tables(site)
    fusion, detector, tracker = occmap.Fusion(tables), occmap.ObjectDetector(tables), occmap.Tracker(tables)
    for f, time_s in frames:
        masks = [occmap.read_image(p) for p in mask_paths_of_frame(site, f)]
        occupancy = fusion.fuse(masks)
        objects = detector.detect(occupancy)
        yield f, occupancy, objects, tracker.update(objects, time_s, frame=f), tracker


def test_lab_maps_detections_and_tracks_equal_the_run(lab):
    data, run = lab["data"], lab["run"]
    detections = read_lines(run / "detections.jsonl")
    tracks = read_lines(run / "tracks.jsonl")
    assert len(detections) == lab["frames"] and len(tracks) == lab["frames"]
    frames = [(line["frame"], line["time_s"]) for line in detections]
    paths = lambda site, f: [data / "gt" / "changes" / c.id / f"{f:06d}.png" for c in site.cameras]
    events = read_lines(run / "events.jsonl")
    my_events = []
    total_tracks = 0
    for f, occupancy, objects, my_tracks, tracker in run_through_module(lab["site"], paths, frames):
        my_events += tracker.events
        picture = occmap.read_image(run / "occupancy" / f"{f:06d}.png")
        assert np.array_equal(occupancy.to_image(), picture), f"frame {f}: map differs from the run's"
        assert_detections_equal(objects.detections, detections[f]["blobs"], f"frame {f}")
        theirs = tracks[f]["tracks"]
        assert [t.id for t in my_tracks] == [t["id"] for t in theirs], f"frame {f}"
        for t, r in zip(my_tracks, theirs):
            for key in ("x_m", "y_m", "vx_mps", "vy_mps"):
                assert abs(getattr(t, key) - r[key]) <= 0.5e-4 + 1e-9, f"frame {f} track {t.id} {key}"
            assert t.object_class == r["class"]
        total_tracks += len(my_tracks)
    assert total_tracks > 0, "the lab run should confirm tracks"
    assert my_events == events and any(e.get("line") for e in events) and any(e.get("zone") for e in events)


def test_gopro4_map_detections_and_tracks_equal_the_run(occmap_bin, datasets, tmp_path):
    import subprocess
    from conftest import SOURCE_DIR
    site_path = SOURCE_DIR / "sites" / "gopro4.yaml"
    run = tmp_path / "run"
    subprocess.run([occmap_bin, "--threads", "2", "--data-root", str(datasets), "run", str(site_path), "--out",
                    str(run), "--no-video", "--occupancy-pngs", "--no-wall-clock", "--no-cache"], check=True,
                   stdout=subprocess.DEVNULL)
    detections = read_lines(run / "detections.jsonl")
    assert len(detections) == 1
    paths = lambda site, f: [datasets / "gopro4" / f"bgsub_{c.id}.png" for c in site.cameras]
    results = list(run_through_module(site_path, paths, [(0, detections[0]["time_s"])], data_root=datasets))
    _, occupancy, objects, my_tracks, _ = results[0]
    picture = occmap.read_image(run / "occupancy" / "000000.png")
    assert np.array_equal(occupancy.to_image(), picture)
    assert len(objects) == 4  # the four people the reference POM finds
    assert_detections_equal(objects.detections, detections[0]["blobs"], "gopro4")
    # One frame set: no track is confirmed yet, in the run as in the module.
    tracks = read_lines(run / "tracks.jsonl")
    assert len(tracks) == 1 and [t.id for t in my_tracks] == [t["id"] for t in tracks[0]["tracks"]]


def test_lab_fusion_of_frames_equals_the_run(lab, occmap_bin, tmp_path):
    import subprocess
    data = lab["data"]
    run = tmp_path / "run"
    subprocess.run([occmap_bin, "--threads", "2", "run", str(data / "site.yaml"), "--out", str(run), "--no-video",
                    "--occupancy-pngs", "--no-wall-clock", "--no-cache", "--frames", "8"], check=True,
                   stdout=subprocess.DEVNULL)
    site = occmap.load_site(data / "site.yaml")
    tables = occmap.Tables(site)
    fusion, detector = occmap.Fusion(tables), occmap.ObjectDetector(tables)
    backgrounds = [occmap.read_image(data / "backgrounds" / f"{c.id}.png") for c in site.cameras]
    detections = read_lines(run / "detections.jsonl")
    for f in range(8):
        frames = [occmap.read_image(data / "frames" / c.id / f"{f:06d}.png") for c in site.cameras]
        occupancy = fusion.fuse_frames(frames, backgrounds)
        picture = occmap.read_image(run / "occupancy" / f"{f:06d}.png")
        assert np.array_equal(occupancy.to_image(), picture), f"frame {f}"
        assert_detections_equal(detector.detect(occupancy).detections, detections[f]["blobs"], f"frame {f}")
