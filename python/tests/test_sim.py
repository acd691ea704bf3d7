"""Change detection, median backgrounds and the simulator."""
import numpy as np
import occmap
import pytest


def test_detect_changes_is_equation_4_with_the_tolerance():
    background = np.full((20, 30), 100, np.uint8)
    frame = background.copy()
    frame[5, 5] = 130   # |I - B| = 30 = T: unchanged (the comparison is strict)
    frame[10, 10] = 131
    changes = occmap.detect_changes(frame, background, threshold=30)
    assert changes.dtype == np.uint8 and changes.sum() == 1 and changes[10, 10] == 1
    dilated = occmap.detect_changes(frame, background, threshold=30, tolerance_px=2)
    assert dilated.sum() == 25 and dilated[8:13, 8:13].all()
    rgb_bg = np.zeros((4, 4, 3), np.uint8)
    rgb = rgb_bg.copy()
    rgb[1, 2, 2] = 50  # blue only
    assert occmap.detect_changes(rgb, rgb_bg, threshold=30)[1, 2] == 1
    with pytest.raises(occmap.InvalidInputError, match="background"):
        occmap.detect_changes(frame, background[:10])
    with pytest.raises(occmap.InvalidInputError, match="tolerance"):
        occmap.detect_changes(frame, background, tolerance_px=1000)


def test_median_background_is_the_lower_median():
    rng = np.random.default_rng(3)
    frames = rng.integers(0, 256, size=(4, 6, 8), dtype=np.uint8)
    median = occmap.MedianBackground()
    for f in frames:
        median.add(f)
    assert median.count == 4
    assert np.array_equal(median.median(), np.sort(frames, axis=0)[1])
    with pytest.raises(occmap.InvalidInputError, match="first frame"):
        median.add(np.zeros((3, 3), np.uint8))
    with pytest.raises(occmap.InvalidInputError, match="no frame"):
        occmap.MedianBackground().median()


def test_simulator_renders_frames_masks_and_truth(tmp_path):
    sim = occmap.Simulator("lab", frames=4, scale=0.5)
    assert sim.num_frames == 4 and sim.fps == 10 and sim.camera_ids == ["cam1", "cam2", "cam3", "cam4"]
    shot = sim.render(2)
    assert shot["time_s"] == pytest.approx(0.2)
    assert [f.shape for f in shot["frames"]] == [(240, 320, 3)] * 4
    masks = shot["change_masks"]
    assert set(np.unique(masks[0])) <= {0, 255} and any(m.any() for m in masks)
    people = [o for o in shot["ground_truth"] if o["class"] == "person"]
    assert people and all(set(o) == {"id", "class", "x_m", "y_m", "inside"} for o in people)
    # Perfect masks: where the rendered frame differs from the noiseless background, an object is seen.
    quiet = sim.render(2, noise=False)["frames"][0].astype(int)
    empty = sim.backgrounds(noise=False)[0].astype(int)
    differs = np.abs(quiet - empty).max(axis=2) > 0
    assert not (differs & (masks[0] == 0)).any()
    assert [m.shape for m in sim.floor_masks()] == [(240, 320)] * 4
    assert "cameras:" in occmap.scene_yaml("lab")


def test_simulator_bad_input():
    with pytest.raises(occmap.NotFoundError):
        occmap.Simulator("no-such-scene.yaml")
    with pytest.raises(occmap.InvalidInputError):
        occmap.Simulator("lab", scale=-1)
    sim = occmap.Simulator("lab", frames=2, scale=0.25)
    with pytest.raises(occmap.InvalidInputError, match="frame: expected 0..1"):
        sim.render(5)
    with pytest.raises(occmap.InvalidInputError):
        occmap.Simulator("name: x\nframes: 3\nfloor: {origin_m: [0, 0], size_m: [2, 2], cell_size_m: 0.1}\n")
