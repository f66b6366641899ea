"""What a later stage reads from a stage-1 output folder (``recipes/pose_from_silhouettes.py --out``).

One reader for the stage-2 and stage-3 runs (:mod:`toolkit.pipeline.segment_parts`,
:mod:`toolkit.pipeline.optimize_joints`): the cameras stage 1 used, its 3D
joints, its offsets (turned into each frame's corrected cameras by
:meth:`Stage1Poses.cameras`, :func:`toolkit.multiview.corrected_rig`), and
optionally its per-view 2D poses.  Missing files and arrays are :class:`InputError` naming
the file and what it should hold.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError


@dataclass(frozen=True, eq=False)
class Stage1Poses:
    """A stage-1 output folder, read.

    Attributes
    ----------
    folder : Path
    rig : Rig
        The cameras stage 1 used (``calibration.toml``: refined on field lines
        or measured), else the dataset's measured ones.
    joints : ndarray of shape (T, 14, 3)
        World, metres, NaN = no estimate.
    offsets : ndarray of shape (T, n_cams, 2)
        Stage 1's offsets as it wrote them (added to the detected 2D joints),
        pixels; NaN for unused views, 0 everywhere without an ``offsets.npz``.
        Consumers take :meth:`cameras`, not these.
    poses2d : dict of str -> ndarray of shape (T, 14, 2)
        Each view's chosen 2D pose, image pixels (empty unless asked for).
    """

    folder: Path
    rig: Rig
    joints: np.ndarray
    offsets: np.ndarray
    poses2d: dict = field(default_factory=dict)

    def cameras(self, t: int) -> Rig:
        """``rig`` corrected by frame ``t``'s offsets (:func:`toolkit.multiview.corrected_rig`)."""
        from toolkit.multiview import corrected_rig

        return corrected_rig(self.rig, self.offsets[t])


def _array(path: Path, key: str, what: str) -> np.ndarray:
    from toolkit.io.layout import load_npz

    data = load_npz(path)
    if key not in data:
        raise InputError(str(path), f"an array '{key}' ({what})", f"arrays {sorted(data)}")
    return data[key]


def read_stage1(dataset, folder, *, poses2d: bool = False) -> Stage1Poses:
    """Read a stage-1 output folder for ``dataset``.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    folder : path
        ``poses3d.npz`` (required), ``offsets.npz``, ``poses2d.npz`` (with
        ``poses2d``), ``calibration.toml``.
    poses2d : bool
        Also read every camera's 2D poses.

    Returns
    -------
    Stage1Poses

    Raises
    ------
    InputError
        ``poses3d.npz`` missing or without ``joints`` (T, 14, 3); ``offsets.npz``
        without ``offsets``; the folder's cameras are not the dataset's.
    """
    from toolkit.calibration import stage_rig

    folder = Path(folder)
    joints = np.asarray(_array(folder / "poses3d.npz", "joints", "the 3D joints (T, 14, 3)"), float)
    if joints.ndim != 3 or joints.shape[1:] != (14, 3):
        raise InputError(str(folder / "poses3d.npz"), "joints of shape (T, 14, 3)", f"shape {joints.shape}")
    rig = stage_rig(dataset, folder)
    off_file = folder / "offsets.npz"
    off = np.asarray(_array(off_file, "offsets", "pixels (T, n_cams, 2)"), float) if off_file.exists() else \
        np.zeros((joints.shape[0], len(rig), 2))
    views = {}
    if poses2d:
        from toolkit.io.layout import load_npz

        p2 = load_npz(folder / "poses2d.npz")
        views = {c: p2[c] for c in rig.names if c in p2}
    return Stage1Poses(folder, rig, joints, off, views)
