"""The module's API: sites from files and dicts, tables and their cache, fusion settings, the
exception types of bad input, metrics, and memory over many fusion calls."""
import gc
import os

import numpy as np
import occmap
import pytest

from conftest import SOURCE_DIR


def rss_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def small_site_dict():
    """Two homography cameras over a 4 x 3 m floor (each maps its 400 x 300 pixels onto the floor)."""
    cams = []
    for i, (sx, sy) in enumerate([(100, 100), (100, 100)]):
        cams.append({"id": f"c{i}", "image_size": [400, 300],
                     "calibration": {"format": "homography", "image_size": [400, 300], "unit": "m",
                                     "floor_from_image": [[1 / sx, 0, 0], [0, 1 / sy, 0], [0, 0, 1]]}})
    return {"version": 1, "name": "small", "floor": {"origin_m": [0, 0], "size_m": [4, 3], "cell_size_m": 0.1},
            "cameras": cams}


def test_site_from_file_and_its_fields(lab):
    site = occmap.load_site(lab["site"])
    assert site.name == "lab"
    assert [c.id for c in site.cameras] == ["cam1", "cam2", "cam3", "cam4"]
    assert site.cameras[0].image_size == (640, 480)
    assert site.cameras[0].mask.shape == (480, 640)
    assert site.grid.shape == (325, 450) and site.grid.cell_size_m == pytest.approx(0.02)
    assert site.tolerance_px == 1 and site.fusion_method == "image-based"


def test_tables_come_from_the_cache_the_second_time(lab, tmp_path):
    site = occmap.load_site(lab["site"])
    first = occmap.Tables(site, cache_dir=tmp_path)
    assert first.cache != "loaded" and first.cache_file.exists()
    second = occmap.Tables(site, cache_dir=tmp_path)
    assert second.cache == "loaded"
    assert np.array_equal(first.view_counts, second.view_counts)
    assert first.view_counts.shape == site.grid.shape and first.view_counts.max() == 4
    assert "cam1" in first.coverage_table()


def test_map_array_has_the_grid_geometry(lab):
    site = occmap.load_site(lab["site"])
    tables = occmap.Tables(site)
    masks = [occmap.read_image(lab["data"] / "gt" / "changes" / c.id / "000005.png") for c in site.cameras]
    occupancy = occmap.Fusion(tables).fuse(masks)
    states = occupancy.states
    assert states.shape == site.grid.shape and states.dtype == np.uint8
    assert not states.flags.writeable
    assert set(np.unique(states)) <= {occmap.UNSEEN, occmap.FREE, occmap.OCCUPIED}
    assert occupancy.count(occmap.OCCUPIED) == int((states == occmap.OCCUPIED).sum()) > 0
    # The picture is the array upside down (+y up) in grey levels.
    grey = np.choose(states, [128, 255, 0]).astype(np.uint8)
    assert np.array_equal(occupancy.to_image(), grey[::-1])
    # Unseen cells: where no camera sees the floor.
    assert np.array_equal(states == occmap.UNSEEN, tables.view_counts == 0)
    # bool masks and masks at another size (resampled) are accepted.
    assert occmap.Fusion(tables).fuse([m > 0 for m in masks]) == occupancy
    # A camera without a frame: only its cells become unseen.
    partial = occmap.Fusion(tables).fuse([None] + masks[1:])
    assert partial.active == [False, True, True, True]
    assert partial.count(occmap.UNSEEN) >= occupancy.count(occmap.UNSEEN)
    # A map from an array round-trips.
    assert occmap.Map.from_array(site.grid, states) == occupancy


def test_vote_rule_and_method_give_the_documented_maps(lab):
    site = occmap.load_site(lab["site"])
    tables = occmap.Tables(site)
    masks = [occmap.read_image(lab["data"] / "gt" / "changes" / c.id / "000005.png") for c in site.cameras]
    image_based = occmap.Fusion(tables, method="image-based", max_free_views=1).fuse(masks)
    map_based = occmap.Fusion(tables, method="map-based", max_free_views=1).fuse(masks)
    strict = occmap.Fusion(tables).fuse(masks)
    assert image_based == map_based
    assert image_based.count(occmap.OCCUPIED) >= strict.count(occmap.OCCUPIED)


def test_site_from_a_dict():
    site = occmap.load_site(small_site_dict())
    assert site.name == "small" and len(site.cameras) == 2
    tables = occmap.Tables(site)
    mask = np.zeros((300, 400), np.uint8)
    mask[100:150, 200:260] = 255  # x 2.0-2.6 m, y 1.0-1.5 m in both cameras
    occupancy = occmap.Fusion(tables).fuse([mask, mask])
    occupied = np.argwhere(occupancy.states == occmap.OCCUPIED)
    assert occupied[:, 0].min() == 10 and occupied[:, 0].max() == 14  # rows j = y cells
    assert occupied[:, 1].min() == 20 and occupied[:, 1].max() == 25
    objects = occmap.ObjectDetector(tables).detect(occupancy)
    assert len(objects) == 1
    assert objects.detections[0].x_m == pytest.approx(2.3, abs=0.06)


def test_bad_input_raises_the_documented_types(tmp_path, lab):
    with pytest.raises(occmap.NotFoundError) as e:
        occmap.load_site(tmp_path / "missing.yaml")
    assert isinstance(e.value, FileNotFoundError) and isinstance(e.value, occmap.Error)
    assert "missing.yaml" in str(e.value)

    bad = tmp_path / "bad.yaml"
    bad.write_text((SOURCE_DIR / "sites" / "gopro4.yaml").read_text().replace("cell_size_m: 0.1", "cell_size_m: -1"))
    with pytest.raises(occmap.InvalidInputError) as e:
        occmap.load_site(bad, data_root=tmp_path)
    assert isinstance(e.value, ValueError)
    assert "bad.yaml:" in str(e.value) and "cell_size_m" in str(e.value)

    d = small_site_dict()
    d["cameras"][1]["id"] = "c0"
    with pytest.raises(occmap.InvalidInputError, match="c0"):
        occmap.load_site(d)

    site = occmap.load_site(lab["site"])
    tables = occmap.Tables(site)
    fusion = occmap.Fusion(tables)
    mask = np.zeros((480, 640), np.uint8)
    with pytest.raises(occmap.InvalidInputError, match="expected 4 arrays"):
        fusion.fuse([mask] * 3)
    with pytest.raises(occmap.InvalidInputError, match=r"masks\[2\].*2-D"):
        fusion.fuse([mask, mask, np.zeros((480, 640, 3), np.uint8), mask])
    # A transposed mask (columns, rows) is refused, a scaled one resampled.
    with pytest.raises(occmap.InvalidInputError, match=r"masks\[1\].*camera's shape \(480, 640\).*found \(640, 480\)"):
        fusion.fuse([mask, mask.T.copy(), mask, mask])
    assert fusion.fuse([mask, np.zeros((240, 320), np.uint8), mask, mask]) is not None
    # A segmenter's float mask (0.7 would have become 0): refused, with the way out.
    with pytest.raises(occmap.InvalidInputError, match=r"masks\[0\].*float64.*threshold it first"):
        fusion.fuse([np.full((480, 640), 0.7), mask, mask, mask])
    with pytest.raises(occmap.InvalidInputError, match="image-based or map-based"):
        occmap.Fusion(tables, method="magic")
    with pytest.raises(occmap.InvalidInputError, match="max_free_views"):
        occmap.Fusion(tables, max_free_views=9)
    with pytest.raises(occmap.InvalidInputError, match="tolerance_px"):
        occmap.Fusion(tables, tolerance_px=-1)
    with pytest.raises(occmap.InvalidInputError, match="0 \\(unseen\\)"):
        occmap.Map.from_array(site.grid, np.full(site.grid.shape, 7, np.uint8))

    tracker = occmap.Tracker(site)
    objects = occmap.ObjectDetector(tables).detect(fusion.fuse([mask] * 4))
    tracker.update(objects, 1.0)
    with pytest.raises(occmap.InvalidInputError):
        tracker.update(objects, 1.0)  # times must increase

    with pytest.raises(occmap.InvalidInputError, match="appears twice"):
        occmap.tracking_metrics([[(1, 0.0, 0.0)]], [[(5, 0.0, 0.0), (5, 1.0, 1.0)]])
    with pytest.raises(occmap.InvalidInputError, match="one frame per ground-truth frame"):
        occmap.detection_metrics([[(0.0, 0.0)]], [])
    with pytest.raises(occmap.NotFoundError):
        occmap.read_image(tmp_path / "none.png")
    png = (SOURCE_DIR / "docs" / "images" / "lab-mosaic.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(png[:300])
    with pytest.raises(occmap.DataLossError, match="cut.png.*truncated") as e:
        occmap.read_image(tmp_path / "cut.png")
    assert isinstance(e.value, ValueError) and isinstance(e.value, occmap.Error)
    (tmp_path / "a_file").write_text("not a folder")
    with pytest.raises(occmap.IoError, match="a_file/data") as e:
        occmap.Simulator("lab", frames=1).write_dataset(tmp_path / "a_file" / "data")
    assert isinstance(e.value, OSError) and isinstance(e.value, occmap.Error)


def test_integer_masks_of_any_width_are_foreground_where_non_zero(lab):
    site = occmap.load_site(lab["site"])
    tables = occmap.Tables(site)
    masks = [occmap.read_image(lab["data"] / "gt" / "changes" / c.id / "000005.png") for c in site.cameras]
    expected = occmap.Fusion(tables).fuse(masks)
    # 256 as uint16 is foreground (a cast to bytes would make it 0).
    wide = [(m > 0).astype(np.uint16) * 256 for m in masks]
    assert occmap.Fusion(tables).fuse(wide) == expected
    assert occmap.Fusion(tables).fuse([(m > 0).astype(np.int64) * -3 for m in masks]) == expected


def test_version():
    assert occmap.__version__ == "0.1.0"
    assert "__version__" in occmap.__all__


def test_metrics_on_lists():
    gt = [[(0.0, 0.0), (2.0, 0.0)], [(0.1, 0.0), (2.1, 0.0)]]
    det = [[(0.0, 0.1)], [(0.1, 0.0), (2.1, 0.2), (5.0, 5.0)]]
    m = occmap.detection_metrics(gt, det)
    assert (m["tp"], m["fp"], m["fn"], m["gt"]) == (3, 1, 1, 4)
    assert m["moda"] == pytest.approx(0.5)
    t = occmap.tracking_metrics([[(1, 0.0, 0.0)], [(1, 0.1, 0.0)], [(1, 0.2, 0.0)]],
                                [[(7, 0.0, 0.0)], [(8, 0.1, 0.0)], [(8, 0.2, 0.0)]])
    assert t["id_switches"] == 1 and t["mota"] == pytest.approx(2 / 3)
    assert t["idf1"] == pytest.approx(2 / 3)


def test_tracker_takes_plain_detections():
    site = occmap.load_site(small_site_dict())
    tracker = occmap.Tracker(site)
    confirmed = []
    for f in range(10):
        confirmed = tracker.update([occmap.Detection(1.0 + 0.1 * f, 1.5, area_m2=0.2)], f * 0.1)
    assert len(confirmed) == 1 and confirmed[0].id == 1
    assert confirmed[0].vx_mps == pytest.approx(1.0, abs=0.2)


def test_no_leak_over_1000_fusion_calls(lab):
    site = occmap.load_site(lab["site"])
    tables = occmap.Tables(site)
    fusion, detector = occmap.Fusion(tables), occmap.ObjectDetector(tables)
    masks = [occmap.read_image(lab["data"] / "gt" / "changes" / c.id / "000010.png") for c in site.cameras]
    for _ in range(50):
        detector.detect(fusion.fuse(masks))
    gc.collect()
    before = rss_bytes()
    for i in range(1000):
        occupancy = fusion.fuse(masks)
        if i % 10 == 0:
            detector.detect(occupancy).detections
    gc.collect()
    grown = rss_bytes() - before
    assert grown < 4 << 20, f"resident memory grew by {grown / 2**20:.1f} MiB over 1000 calls"


def test_help_shows_docstrings():
    assert "masks" in occmap.Fusion.fuse.__doc__
    assert "InvalidInputError" in occmap.__doc__
