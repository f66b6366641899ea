"""An optical marker capture: a calibrated rig and unlabelled 2D blobs per camera and frame.

:func:`load_marker_capture` reads the folder layout of
:mod:`toolkit.io.marker_files` (what ``recipes/make_scene.py`` writes for a
scene spec with a ``[markers]`` table).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError

__all__ = ["MIN_CAMERAS", "MarkerCapture", "load_marker_capture"]

#: Fewest cameras a capture must have (trinocular reconstruction).
MIN_CAMERAS = 3


@dataclass(frozen=True)
class MarkerCapture:
    """Unlabelled 2D marker blobs seen by a calibrated rig.

    Attributes
    ----------
    rig : Rig
        The calibration of the capture (as measured).
    fps : float
    n_frames : int
    centres : dict of str to ndarray of shape (N, 2)
        Every blob of a camera, pixels.
    frames : dict of str to ndarray of shape (N,)
        Frame index of each blob, ascending.
    source : str
        The capture folder.
    """

    rig: Rig
    fps: float
    n_frames: int
    centres: dict
    frames: dict
    source: str = "<capture>"
    _starts: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        if len(self.rig) < MIN_CAMERAS:
            raise InputError(f"{self.source}: cameras", f"at least {MIN_CAMERAS} cameras (trinocular matching)",
                             f"{len(self.rig)}")
        for name in self.rig.names:
            if name not in self.centres or name not in self.frames:
                raise InputError(f"{self.source}: detections of {name}", "a detections file per camera", "none")
            f = self.frames[name]
            if len(f) and f.max() >= self.n_frames:
                raise InputError(f"{self.source}: detections of {name}: frame",
                                 f"frame indices below n_frames = {self.n_frames}", str(int(f.max())))
            self._starts[name] = np.searchsorted(f, np.arange(self.n_frames + 1))

    @property
    def camera_names(self) -> list[str]:
        return self.rig.names

    def detections(self, camera: str, t: int) -> np.ndarray:
        """Blob centres of ``camera`` in frame ``t``, (n, 2) pixels."""
        if camera not in self._starts:
            raise InputError("camera", f"one of {self.rig.names}", repr(camera))
        if not 0 <= t < self.n_frames:
            raise InputError("t", f"a frame index in [0, {self.n_frames})", str(t))
        s = self._starts[camera]
        return self.centres[camera][s[t]:s[t + 1]]

    def detection_rows(self, camera: str, t: int) -> slice:
        """Rows of ``camera``'s detections file that belong to frame ``t`` (for ground-truth lookup)."""
        s = self._starts[camera]
        return slice(int(s[t]), int(s[t + 1]))

    def close(self) -> None:
        """Nothing to release (the arrays are in memory); for symmetry with datasets."""


def load_marker_capture(dataset_dir: str | Path) -> MarkerCapture:
    """Read a marker capture folder.

    Parameters
    ----------
    dataset_dir : str or Path
        Folder with ``markers/calibration.toml`` and ``markers/detections/<camera>.npz``.

    Returns
    -------
    MarkerCapture

    Raises
    ------
    InputError
        Naming the file and field: no calibration, fewer than three cameras,
        a camera without detections, image sizes that differ from the
        calibration, malformed arrays, a missing ``fps`` or ``n_frames``.
    """
    from toolkit.io import read_calibration_metadata, read_calibration_toml
    from toolkit.io.marker_files import CALIBRATION, DETECTIONS_DIR, read_marker_detections

    root = Path(dataset_dir)
    cal = root / CALIBRATION
    if not cal.is_file():
        raise InputError(str(cal), "the calibration of a marker capture", "no such file")
    rig = read_calibration_toml(cal)
    meta = read_calibration_metadata(cal)
    for key in ("fps", "n_frames"):
        if key not in meta:
            raise InputError(f"{cal}: metadata.{key}", f"the capture's {key}", "nothing (field missing)")
    fps, n = meta["fps"], meta["n_frames"]
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not np.isfinite(fps) or fps <= 0:
        raise InputError(f"{cal}: metadata.fps", "a positive frame rate", repr(fps))
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise InputError(f"{cal}: metadata.n_frames", "a positive integer", repr(n))
    if len(rig) < MIN_CAMERAS:
        raise InputError(f"{cal}: cameras", f"at least {MIN_CAMERAS} cameras (trinocular matching)", f"{len(rig)}")
    centres, frames = {}, {}
    for cam in rig:
        path = root / DETECTIONS_DIR / f"{cam.name}.npz"
        c, f, size = read_marker_detections(path)
        if tuple(size) != tuple(cam.size):
            raise InputError(f"{path}: image_size", f"the calibration's {tuple(cam.size)}", f"{size}")
        centres[cam.name], frames[cam.name] = c, f
    return MarkerCapture(rig=rig, fps=float(fps), n_frames=n, centres=centres, frames=frames, source=str(root))
