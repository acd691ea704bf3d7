"""occmap: floor occupancy from several calibrated cameras, from Python.

Load a site, build its lookup tables, fuse per-camera foreground masks (NumPy arrays) into a
tri-state map, find the objects on it, track them frame by frame, and score the result:

    import occmap
    site = occmap.load_site("sites/gopro4.yaml", data_root="/data")
    tables = occmap.Tables(site, cache_dir="/tmp/occmap-cache")
    fusion, detector, tracker = occmap.Fusion(tables), occmap.ObjectDetector(tables), occmap.Tracker(tables)
    occupancy = fusion.fuse([mask0, mask1, mask2, mask3])       # one 2-D array per camera
    tracks = tracker.update(detector.detect(occupancy), time_s=0.0)

Errors raise occmap.Error subclasses with occmap's own messages (file, line, field, expected,
found): InvalidInputError (also a ValueError), NotFoundError (a FileNotFoundError),
DataLossError (ValueError), ResourceExhaustedError (ValueError), IoError (OSError),
InternalError (RuntimeError).
"""
import json as _json
import os as _os

try:  # the arrays are NumPy's: say so at import rather than at the first call
    import numpy as _numpy  # noqa: F401
except ImportError as _e:  # pragma: no cover - depends on the system
    raise ImportError("occmap needs NumPy: apt install python3-numpy (or pip install numpy)") from _e

from ._occmap import *  # noqa: F401,F403
from ._occmap import __version__, _load_site_file, _parse_site

__all__ = [
    "Error", "InvalidInputError", "NotFoundError", "DataLossError", "ResourceExhaustedError", "IoError",
    "InternalError", "UNSEEN", "FREE", "OCCUPIED", "Grid", "Camera", "Site", "Tables", "Map", "Fusion",
    "Detection", "Objects", "ObjectDetector", "Track", "Tracker", "detection_metrics", "tracking_metrics",
    "read_image", "load_site", "__version__",
]


def load_site(site, data_root=None, base_dir=None):
    """Loads a site: a path to a site file (YAML, docs/formats.md) or a dict of the same keys.

    Relative paths in the site resolve against data_root, else the file's data_root, else the
    file's folder (for a dict: base_dir, default the current folder). Raises InvalidInputError
    or NotFoundError naming the file, line and field.
    """
    if isinstance(site, dict):
        folder = _os.fspath(base_dir) if base_dir is not None else _os.getcwd()
        text = _json.dumps(site, indent=1)
        return _parse_site(text, _os.path.join(folder, "<dict>"), data_root)
    return _load_site_file(_os.fspath(site), data_root)
