"""What a later stage reads from a stage-1 output folder (``recipes/pose_from_silhouettes.py --out``).

One reader for the stage-2 and stage-3 runs (:mod:`toolkit.pipeline.segment_parts`,
:mod:`toolkit.pipeline.optimize_joints`): the cameras stage 1 used, and its
output read by :func:`toolkit.io.stage_outputs.read_stage1_output` (3D
joints, offsets, optionally the per-view 2D poses), the offsets turned into
each frame's corrected cameras by :meth:`Stage1Poses.cameras`
(:func:`toolkit.multiview.corrected_rig`).  Missing files and arrays are
:class:`InputError` naming the file and what it should hold.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.cameras import Rig
from toolkit.io.stage_outputs import Stage1Output


@dataclass(frozen=True, eq=False)
class Stage1Poses:
    """A stage-1 output folder, read: its :class:`Stage1Output` and the cameras it used.

    Attributes
    ----------
    folder : Path
    rig : Rig
        The cameras stage 1 used (``calibration.toml``: refined on field lines
        or measured), else the dataset's measured ones.
    output : Stage1Output
        Joints, offsets, states and (when asked for) 2D poses; its cameras are ``rig``'s.
    """

    folder: Path
    rig: Rig
    output: Stage1Output

    @property
    def joints(self) -> np.ndarray:
        """(T, 14, 3) world, metres, NaN = no estimate."""
        return self.output.joints

    @property
    def offsets(self) -> np.ndarray:
        """(T, n_cams, 2) stage 1's offsets as it wrote them, pixels; 0 without ``offsets.npz``.

        Consumers take :meth:`cameras`, not these.
        """
        return self.output.offsets

    @property
    def poses2d(self) -> dict:
        """camera -> (T, 14, 2) chosen 2D pose, image pixels (empty unless asked for)."""
        return self.output.poses2d

    def cameras(self, t: int) -> Rig:
        """``rig`` corrected by frame ``t``'s offsets (:func:`toolkit.multiview.corrected_rig`)."""
        from toolkit.multiview import corrected_rig

        return corrected_rig(self.rig, self.offsets[t])


def read_stage1(dataset, folder, *, poses2d: bool = False) -> Stage1Poses:
    """Read a stage-1 output folder for ``dataset``.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    folder : path
        ``poses3d.npz`` (required), ``offsets.npz``, ``poses2d.npz`` (with
        ``poses2d``), ``calibration.toml``
        (:func:`toolkit.io.stage_outputs.read_stage1_output`, :func:`toolkit.calibration.stage_rig`).
    poses2d : bool
        Also read every camera's 2D poses.

    Returns
    -------
    Stage1Poses

    Raises
    ------
    InputError
        ``poses3d.npz`` missing or without ``joints`` (T, 14, 3); ``offsets.npz``
        without ``offsets`` (T, n_cams, 2); an array of another shape; the
        folder's cameras are not the dataset's.
    """
    from toolkit.calibration import stage_rig
    from toolkit.io.stage_outputs import read_stage1_output

    folder = Path(folder)
    output = read_stage1_output(folder, cameras=dataset.rig.names, poses2d=poses2d)
    return Stage1Poses(folder, stage_rig(dataset, folder), output)
