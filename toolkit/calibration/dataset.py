"""Calibration refinement of a whole dataset, and the cameras a stage's output folder used.

:func:`refine_dataset` corrects the dataset's measured cameras on its field
model before stage 1; the recipes write the cameras they used to
``OUT/calibration.toml`` (:data:`USED_CALIBRATION`), and later stages read
them back with :func:`stage_rig` so that every stage works with the same
cameras.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping

import numpy as np

from toolkit.calibration.refine import RefineConfig, Refinement, refine_rig
from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.foreground.background import BackgroundModel
from toolkit.foreground.config import BACKGROUND_SAMPLES, BackgroundConfig

#: File in a stage's output folder holding the cameras it used (refined or measured).
USED_CALIBRATION = "calibration.toml"
class _DatasetFrames:
    """One camera's frames of a dataset as a sequence (``len`` and ``read(i)``) for :class:`BackgroundModel`."""

    def __init__(self, dataset, camera: str):
        self.dataset, self.camera = dataset, camera

    def __len__(self) -> int:
        return self.dataset.n_frames

    def read(self, i: int) -> np.ndarray:
        return self.dataset.frame(self.camera, i)


def background_image(dataset, camera: str, samples: int = BACKGROUND_SAMPLES) -> np.ndarray:
    """An image of the empty scene: the clean plate, else the per-pixel median of sampled frames.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    camera : str
    samples : int
        Frames sampled evenly over the video for the median
        (:class:`toolkit.foreground.BackgroundModel`, method ``"median"``).

    Returns
    -------
    ndarray of shape (H, W, 3) uint8
    """
    plate = dataset.background(camera)
    if plate is not None:
        return plate
    config = BackgroundConfig(method="median", n_samples=samples)
    return BackgroundModel.fit(_DatasetFrames(dataset, camera), config).background


def refine_dataset(dataset, config: RefineConfig = RefineConfig(), *,
                   observer=None) -> tuple[Rig, dict[str, Refinement]]:
    """Refine a dataset's measured cameras on its field model (``field_model.json``).

    Each camera is fitted on its empty-scene image (:func:`background_image`);
    for other cameras or images call :func:`toolkit.calibration.refine_rig`.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    config : RefineConfig
    observer : Observer, optional

    Returns
    -------
    rig : Rig
        Refined cameras (measured ones where refinement was rejected).
    results : dict of str to Refinement
        Empty when the dataset has no field model.
    """
    field_model = dataset.field_model()
    if field_model is None:
        return dataset.rig, {}
    images = {c.name: background_image(dataset, c.name) for c in dataset.rig}
    return refine_rig(dataset.rig, images, field_model, config, observer=observer)


def describe(results: Mapping[str, Refinement]) -> list[str]:
    """One line per camera for the recipes' console output."""
    out = []
    for name, r in results.items():
        if r.accepted:
            out.append(f"  {name}: refined on {r.inliers_after} field-line points, rotation {r.rotation_deg:.3f} deg, "
                       f"focal x{r.focal_scale:.4f}, line residual {r.rms_after_px:.2f} px")
        else:
            out.append(f"  {name}: measured calibration kept ({r.reason})")
    return out


def refined_cameras(folder: str | os.PathLike | None) -> tuple[str, ...]:
    """Names of the cameras a stage's output ``folder`` refined on field lines (``calibration.toml``).

    Empty when the folder has no ``calibration.toml`` or kept the measured
    calibration.

    Raises
    ------
    InputError
        If ``calibration.toml`` is not valid TOML or its ``[metadata]`` table is malformed.
    """
    from toolkit.io import read_calibration_metadata

    if folder is None:
        return ()
    path = Path(folder) / USED_CALIBRATION
    if not path.is_file():
        return ()
    names = read_calibration_metadata(path).get("refined_on_field_lines", "")
    if not isinstance(names, str):
        raise InputError(f"{path}: [metadata] refined_on_field_lines", "a comma-separated string of camera names",
                         repr(names))
    return tuple(n for n in names.split(",") if n)


def stage_rig(dataset, folder: str | os.PathLike | None) -> Rig:
    """The cameras a stage's output ``folder`` used (``calibration.toml``), else the dataset's measured ones.

    Raises
    ------
    InputError
        If the folder's cameras are not the dataset's.
    """
    from toolkit.io import read_calibration

    if folder is None:
        return dataset.rig
    path = Path(folder) / USED_CALIBRATION
    if not path.is_file():
        return dataset.rig
    rig = read_calibration(path)
    if rig.names != dataset.rig.names:
        raise InputError(str(path), f"the dataset's cameras {dataset.rig.names}", f"{rig.names}")
    return rig


def cameras_for_run(dataset, out: str | os.PathLike, *, refine: bool = True, resumed: bool = False,
                    config: RefineConfig = RefineConfig(), observer=None, log=print) -> Rig:
    """The cameras a recipe run works with, written to ``out/calibration.toml``.

    A resumed run (``resumed``: the caller checked that ``out`` holds earlier
    results of this same dataset and options, :func:`toolkit.io.runs.start_run`)
    reuses ``out/calibration.toml``, so its remaining frames see the same
    cameras.  Any other run refines the dataset's measured cameras on its field
    model (when it has one and ``refine`` is true) and writes them there,
    replacing what an earlier run left.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    out : path
        The recipe's output folder (created if missing).
    refine : bool
        Refine on the field lines; False keeps the measured calibration.
    resumed : bool
        ``out`` holds results of an earlier run of the same dataset and
        options, to be continued.  Without a ``calibration.toml`` that run
        predates it and used the measured cameras, so they are kept (and
        written) for the frames still to do.
    config : RefineConfig
    observer : Observer, optional
    log : callable
        Receives one line per camera (``print`` by default; ``None`` for silence).

    Returns
    -------
    Rig
    """
    from toolkit.io import write_calibration

    out = Path(out)
    path = out / USED_CALIBRATION
    log = log or (lambda *_: None)
    if resumed and path.is_file():
        rig = stage_rig(dataset, out)
        log(f"cameras: reusing {path}")
        return rig
    if resumed and refine:
        log(f"cameras: {out} holds results made with the measured calibration; keeping it")
        refine = False
    rig, results = refine_dataset(dataset, config, observer=observer) if refine else (dataset.rig, {})
    if results:
        log("cameras refined on the field lines:")
        for line in describe(results):
            log(line)
    out.mkdir(parents=True, exist_ok=True)
    refined = ",".join(n for n, r in results.items() if r.accepted)
    write_calibration(path, rig, metadata={"source": str(dataset.layout.calibration),
                                           "refined_on_field_lines": refined})
    return rig
