"""Field-model files: the painted lines of a pitch as 3D polylines, stored as JSON.

A broadcast camera sees the field lines of the pitch, whose layout is known
(standardised dimensions), so they pin down the camera's orientation and zoom
(:mod:`toolkit.calibration.refine`).  A :class:`FieldModel` holds those lines
as polylines in metres (world frame: z up, ground at z = 0; circles are
sampled into polylines).  It is stored as JSON (``field_model.json`` in a
dataset, :mod:`toolkit.io.layout`)::

    {"name": "soccer 110x70", "units": "m", "line_width_m": 0.12,
     "polylines": [[[x, y, z], [x, y, z], ...], ...]}

The model of a football pitch is :func:`toolkit.calibration.field.soccer_pitch`.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.text import load_json
from toolkit.io.atomic import atomic_write_text

__all__ = ["FieldModel", "read_field_model", "write_field_model"]


@dataclass(frozen=True, eq=False)
class FieldModel:
    """Painted field lines as polylines.

    Parameters
    ----------
    polylines : tuple of ndarray of shape (K_i, 3)
        Each an open polyline of K_i >= 2 vertices, metres, world frame
        (close a loop by repeating its first vertex).
    name : str
        Free text (e.g. the pitch standard).
    line_width_m : float
        Width of the painted lines (0.12 m on a football pitch); only for
        display and for choosing detector scales.
    """

    polylines: tuple
    name: str = "field"
    line_width_m: float = 0.12

    def __post_init__(self):
        lines = []
        for i, p in enumerate(self.polylines):
            a = np.asarray(p, dtype=np.float64)
            if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] < 2:
                raise InputError(f"field model polylines[{i}]", "a finite (K >= 2, 3) array of metres",
                                 f"shape {a.shape}" if a.ndim else repr(p))
            if not np.isfinite(a).all():
                raise InputError(f"field model polylines[{i}]", "a finite (K >= 2, 3) array of metres",
                                 f"{int((~np.isfinite(a)).sum())} non-finite values")
            a.setflags(write=False)
            lines.append(a)
        if not lines:
            raise InputError("field model polylines", "at least one polyline", "none")
        if not (np.isfinite(self.line_width_m) and self.line_width_m > 0):
            raise InputError("field model line_width_m", "a positive width in metres", str(self.line_width_m))
        object.__setattr__(self, "polylines", tuple(lines))

    def samples(self, step_m: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
        """Points along every line, about ``step_m`` apart.

        Returns
        -------
        points : ndarray of shape (N, 3)
            Metres, world frame.
        line_ids : ndarray of shape (N,) int
            Index of the polyline each point lies on.
        """
        if not step_m > 0:
            raise InputError("samples: step_m", "a positive step in metres", str(step_m))
        pts, ids = [], []
        for i, p in enumerate(self.polylines):
            for a, b in zip(p[:-1], p[1:]):
                n = max(1, int(np.ceil(np.linalg.norm(b - a) / step_m)))
                s = np.arange(n)[:, None] / n
                pts.append(a + s * (b - a))
                ids.append(np.full(n, i))
            pts.append(p[-1:])
            ids.append(np.array([i]))
        return np.concatenate(pts), np.concatenate(ids)


def write_field_model(path: str | os.PathLike, model: FieldModel) -> Path:
    """Write ``model`` as JSON (atomically)."""
    doc = {"name": model.name, "units": "m", "line_width_m": model.line_width_m,
           "polylines": [np.round(p, 6).tolist() for p in model.polylines]}
    path = Path(path)
    atomic_write_text(path, json.dumps(doc))
    return path


def read_field_model(path: str | os.PathLike) -> FieldModel:
    """Read a field model written by :func:`write_field_model` (or by hand).

    Raises
    ------
    InputError
        Naming the file and field when it is not valid.
    """
    path = Path(path)
    doc = load_json(path, "a field-model JSON file")
    if not isinstance(doc, dict) or "polylines" not in doc:
        raise InputError(f"{path}", "an object with a 'polylines' list", type(doc).__name__ if not isinstance(doc, dict)
                         else f"keys {sorted(doc)}")
    units = doc.get("units", "m")
    if units != "m":
        raise InputError(f"{path}: units", "'m' (metres)", repr(units))
    polys = doc["polylines"]
    if not isinstance(polys, list):
        raise InputError(f"{path}: polylines", "a list of polylines", type(polys).__name__)
    try:
        arrays = tuple(np.asarray(p, dtype=np.float64) for p in polys)
    except (TypeError, ValueError) as e:
        raise InputError(f"{path}: polylines", "lists of [x, y, z] vertices in metres", str(e)) from None
    try:
        return FieldModel(arrays, name=str(doc.get("name", path.stem)),
                          line_width_m=float(doc.get("line_width_m", 0.12)))
    except InputError as e:
        raise InputError(f"{path}: {e.where}", e.expected, e.found) from None
