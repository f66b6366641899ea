"""C3D files of 3D marker trajectories, read and written with ezc3d.

`ezc3d <https://github.com/pyomeca/ezc3d>`_ is the maintained C3D library of the
pyomeca project (C++ core, Python bindings): it handles the file's parameter
sections, the integer and float storage formats, the processor types and the
``LABELS2``/``LABELS3`` continuation parameters, which a hand-written parser
would have to redo.

Only the POINT section is used.  Positions are converted to metres from
``POINT:UNITS`` (``mm`` or ``m``; anything else is refused, naming the file and
field).  A sample whose residual is negative (the C3D convention for an
occluded or invalid marker) or whose coordinates are all exactly zero (the
convention of some exporters) becomes NaN.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.atomic import atomic_path

#: Length units accepted in ``POINT:UNITS``, with their factor to metres.
C3D_UNITS = {"mm": 1e-3, "m": 1.0}


@dataclass(frozen=True)
class C3DPoints:
    """The 3D points of a C3D file.

    Attributes
    ----------
    labels : tuple of str
        One per point (M), as stored (``POINT:LABELS``); generated ``P000``...
        when the file has none (``labelled`` is then False).
    positions : ndarray of shape (T, M, 3)
        Metres, NaN where the sample is missing (negative residual or all zeros).
    fps : float
        ``POINT:RATE``, frames per second.
    units : str
        The file's ``POINT:UNITS`` (``"mm"`` or ``"m"``).
    labelled : bool
        Whether the file gave a label to every point.
    source : str
        The file's path.
    measurements : dict of str to float
        The subject's measurements in the ``PROCESSING`` group (Plug-in Gait's
        ``LKneeWidth``, ``RAnkleWidth``, ``MarkerDiameter`` ...: every positive
        single number whose name ends in ``Width`` or ``Diameter``), metres
        (the group holds millimetres whatever ``POINT:UNITS`` says); empty
        when the file has none.
    """

    labels: tuple
    positions: np.ndarray
    fps: float
    units: str
    labelled: bool
    source: str
    measurements: dict = field(default_factory=dict)


def _param(params, group: str, name: str, where: str, default=None):
    try:
        return params[group][name]["value"]
    except KeyError:
        if default is not None:
            return default
        raise InputError(f"{where}: {group}:{name}", "the parameter to be present", "no such parameter") from None


def _crashes_the_reader(path: Path) -> int | None:
    """The signal that ends ezc3d reading ``path`` in a forked child (a damaged file), or None when it does not.

    ezc3d is C++ and some damaged files make it crash (a segmentation fault ends
    the whole process, with no exception to catch); reading them first in a
    child process (``os.fork``: a few milliseconds) keeps the caller alive.
    Without ``fork`` (Windows) the file is not probed.
    """
    if not hasattr(os, "fork"):
        return None
    pid = os.fork()
    if pid == 0:  # the child: read, and leave without running anything of the parent's
        code = 0
        try:
            import faulthandler

            faulthandler.disable()  # the crash is expected here: no report of it on the shared stderr
            os.dup2(os.open(os.devnull, os.O_WRONLY), 2)
            import ezc3d

            ezc3d.c3d(str(path))
        except BaseException:
            code = 1
        os._exit(code)
    _, status = os.waitpid(pid, 0)
    return os.WTERMSIG(status) if os.WIFSIGNALED(status) else None


def open_c3d(path: str | os.PathLike):
    """Read a C3D file with ezc3d; a missing, unreadable or damaged file is an InputError naming it.

    Returns
    -------
    ezc3d.c3d
    """
    import ezc3d

    path = Path(path)
    if not path.is_file():
        raise InputError(str(path), "a C3D file", "no such file")
    sig = _crashes_the_reader(path)
    if sig is not None:
        raise InputError(str(path), "a readable C3D file", f"a damaged file (the C3D reader dies on it: signal {sig})")
    try:
        return ezc3d.c3d(str(path))
    except Exception as e:  # ezc3d raises plain RuntimeError/IOError on a bad file
        raise InputError(str(path), "a readable C3D file", f"{type(e).__name__}: {e}") from None


def read_c3d(path: str | os.PathLike, *, require_labels: bool = False) -> C3DPoints:
    """Read the 3D points of a C3D file, in metres.

    Parameters
    ----------
    path : str or PathLike
    require_labels : bool
        Refuse a file without point labels (``POINT:LABELS`` absent, empty, or
        fewer labels than points) instead of generating ``P000``... labels.

    Returns
    -------
    C3DPoints

    Raises
    ------
    InputError
        The file is missing or not a C3D; ``POINT:UNITS`` is not ``mm`` or
        ``m``; labels are missing (with ``require_labels``) or duplicated.
    """
    path = Path(path)
    where = str(path)
    c3d = open_c3d(path)
    params = c3d["parameters"]
    points = np.asarray(c3d["data"]["points"], dtype=float)  # (4, M, T)
    n_points = points.shape[1]
    units_v = _param(params, "POINT", "UNITS", where, default=[""])
    units = (units_v[0] if len(units_v) else "").strip()
    if units.lower() not in C3D_UNITS:
        raise InputError(f"{where}: POINT:UNITS", "'mm' or 'm'", repr(units))
    units = units.lower()
    rate = _param(params, "POINT", "RATE", where)
    fps = float(np.asarray(rate).ravel()[0]) if np.size(rate) else float("nan")
    if not np.isfinite(fps) or fps <= 0:
        raise InputError(f"{where}: POINT:RATE", "a positive frame rate", repr(rate))
    labels = [str(s).strip() for s in _param(params, "POINT", "LABELS", where, default=[])][:n_points]
    labelled = len(labels) == n_points and all(labels)
    if not labelled:
        if require_labels:
            raise InputError(f"{where}: POINT:LABELS", f"a label for each of the {n_points} points",
                             f"{sum(1 for s in labels if s)} labels")
        labels = [f"P{i:03d}" for i in range(n_points)]
    seen, dup = set(), []
    for s in labels:
        if s in seen:
            dup.append(s)
        seen.add(s)
    if dup:
        raise InputError(f"{where}: POINT:LABELS", "distinct labels", f"duplicated {sorted(set(dup))}")
    pos = np.transpose(points[:3], (2, 1, 0)) * C3D_UNITS[units]  # (T, M, 3)
    residuals = c3d["data"]["meta_points"].get("residuals") if "meta_points" in c3d["data"] else None
    if residuals is not None and np.size(residuals):
        res = np.asarray(residuals, dtype=float)[0].T  # (T, M)
        pos[res < 0] = np.nan
    pos[np.all(pos == 0, axis=-1)] = np.nan
    return C3DPoints(labels=tuple(labels), positions=pos, fps=fps, units=units, labelled=labelled,
                     source=str(path), measurements=_measurements(params))


def _measurements(params) -> dict:
    """Positive single-number widths and diameters of the ``PROCESSING`` group, millimetres to metres."""
    out = {}
    for name, entry in (params.get("PROCESSING") or {}).items():
        if not isinstance(entry, dict) or not (name.endswith("Width") or name.endswith("Diameter")):
            continue
        try:
            v = np.asarray(entry.get("value"), dtype=float).ravel()
        except (TypeError, ValueError):
            continue
        if v.size == 1 and np.isfinite(v[0]) and v[0] > 0:
            out[str(name)] = float(v[0]) * 1e-3
    return out


def write_c3d(path: str | os.PathLike, labels, positions: np.ndarray, fps: float, *,
              units: str = "mm", descriptions=None) -> Path:
    """Write 3D points to a C3D file (atomically).

    Parameters
    ----------
    path : str or PathLike
    labels : sequence of str
        One per point (M), distinct.
    positions : ndarray of shape (T, M, 3)
        Metres; NaN = missing (written with residual -1).
    fps : float
        Frames per second (``POINT:RATE``).
    units : {"mm", "m"}
        ``POINT:UNITS`` of the file.
    descriptions : sequence of str, optional
        ``POINT:DESCRIPTIONS``, one per point.

    Returns
    -------
    Path
    """
    import ezc3d

    labels = [str(s) for s in labels]
    pos = np.asarray(positions, dtype=float)
    if pos.ndim != 3 or pos.shape[1:] != (len(labels), 3):
        raise InputError("write_c3d: positions", f"an array of shape (T, {len(labels)}, 3)", f"{pos.shape}")
    if len(set(labels)) != len(labels):
        raise InputError("write_c3d: labels", "distinct labels", f"{labels}")
    if units not in C3D_UNITS:
        raise InputError("write_c3d: units", "'mm' or 'm'", repr(units))
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(fps)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = labels
    c3d["parameters"]["POINT"]["DESCRIPTIONS"]["value"] = (
        [str(s) for s in descriptions] if descriptions is not None else [""] * len(labels))
    c3d.add_parameter("POINT", "UNITS", [units])
    missing = ~np.all(np.isfinite(pos), axis=-1)  # (T, M)
    data = np.ones((4, len(labels), pos.shape[0]))
    data[:3] = np.transpose(np.where(missing[..., None], 0.0, pos / C3D_UNITS[units]), (2, 1, 0))
    c3d["data"]["points"] = data
    res = np.where(missing, -1.0, 0.0).T[None]  # (1, M, T)
    c3d["data"]["meta_points"]["residuals"] = res
    c3d["data"]["meta_points"]["camera_masks"] = np.zeros((7, len(labels), pos.shape[0]), dtype=bool)
    path = Path(path)
    with atomic_path(path) as tmp:
        c3d.write(str(tmp))
    return path
