"""Field models of pitches: the painted lines the broadcast cameras are refined on.

The synthetic broadcast pitch (:mod:`toolkit.synthetic.environment`) paints
exactly the lines of :func:`soccer_pitch`, and the scene generator writes them
as ``field_model.json`` into broadcast datasets.  The :class:`FieldModel` type
and its JSON file are in :mod:`toolkit.io.field_model`.
"""

from __future__ import annotations

import numpy as np

from toolkit.errors import InputError
from toolkit.io.field_model import FieldModel

__all__ = ["soccer_pitch"]


def _circle(cx: float, cy: float, r: float, a0: float = 0.0, a1: float = 2 * np.pi, n: int = 180) -> np.ndarray:
    a = np.linspace(a0, a1, n)
    return np.stack([cx + r * np.cos(a), cy + r * np.sin(a), np.zeros_like(a)], axis=1)


def _rect(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]], float)


def soccer_pitch(length_m: float = 110.0, width_m: float = 70.0) -> FieldModel:
    """The lines of a football pitch centred on the world origin, length along x.

    Touch and goal lines, halfway line, centre circle (9.15 m) and both
    penalty areas (16.5 m deep, 40 m wide), as painted by the synthetic
    broadcast environment.

    Parameters
    ----------
    length_m, width_m : float
        Pitch size between the outer lines, metres.
    """
    if not (length_m > 33 + 1 and width_m > 40 + 1):
        raise InputError("soccer_pitch", "a pitch longer than 34 m and wider than 41 m",
                         f"{length_m} x {width_m} m")
    hx, hy = length_m / 2, width_m / 2
    lines = [
        _rect(-hx, -hy, hx, hy),
        np.array([[0, -hy, 0], [0, hy, 0]], float),
        _circle(0, 0, 9.15),
        np.array([[-hx, 20, 0], [-hx + 16.5, 20, 0], [-hx + 16.5, -20, 0], [-hx, -20, 0]], float),
        np.array([[hx, 20, 0], [hx - 16.5, 20, 0], [hx - 16.5, -20, 0], [hx, -20, 0]], float),
    ]
    return FieldModel(tuple(lines), name=f"soccer {length_m:g}x{width_m:g}")
