"""Scene-point files: 3D coordinates of landmarks and their pixel positions per camera.

TOML::

    [points]                      # metres, world frame (z up, floor z = 0)
    A = [0.0, 0.0, 0.0]
    B = [2.0, 0.0, 0.0]
    [cam_01]                      # one table per camera: pixel [u, v] of the points it sees
    A = [512.3, 1200.8]
    B = [801.0, 1180.2]

CSV (one row per observation, a header line)::

    camera,point,x,y,z,u,v
    cam_01,A,0.0,0.0,0.0,512.3,1200.8

Cameras are matched to the intrinsics' camera names by
:func:`toolkit.io.keypoint_files.match_cameras` (by name, number or order).
"""

from __future__ import annotations

import csv
import os
import tomllib
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.keypoint_files import match_cameras

__all__ = ["read_scene_points"]


def read_scene_points(path: str | os.PathLike, camera_names: list[str]) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Read a scene-point file (module docstring).

    Parameters
    ----------
    path : path-like
        ``.toml`` or ``.csv``.
    camera_names : list of str
        The cameras, in the order wanted.

    Returns
    -------
    names : list of str
    points : ndarray of shape (N, 3)
        Metres.
    pixels : ndarray of shape (n_cams, N, 2)
        NaN where a camera does not see a point.

    Raises
    ------
    InputError
        Missing file, unknown suffix, malformed entries, a point without coordinates, or
        cameras that do not match ``camera_names``.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(str(p), "a scene-point file (.toml or .csv)", "no such file")
    coords: dict[str, np.ndarray] = {}
    seen: dict[str, dict[str, np.ndarray]] = {}
    if p.suffix.lower() == ".toml":
        try:
            doc = tomllib.loads(p.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as e:
            raise InputError(str(p), "a valid TOML file", f"a syntax error: {e}") from None
        if not isinstance(doc.get("points"), dict):
            raise InputError(f"{p}: [points]", "a [points] table of name = [x, y, z] (metres)", "none")
        for k, v in doc["points"].items():
            a = np.asarray(v, float) if isinstance(v, list) else np.zeros(0)
            if a.shape != (3,):
                raise InputError(f"{p}: points.{k}", "[x, y, z] in metres", repr(v))
            coords[k] = a
        for cam, table in doc.items():
            if cam == "points":
                continue
            if not isinstance(table, dict):
                raise InputError(f"{p}: {cam}", "a camera table of point = [u, v]", repr(table))
            for k, v in table.items():
                a = np.asarray(v, float) if isinstance(v, list) else np.zeros(0)
                if a.shape != (2,):
                    raise InputError(f"{p}: {cam}.{k}", "[u, v] in pixels", repr(v))
                seen.setdefault(cam, {})[k] = a
    elif p.suffix.lower() == ".csv":
        with open(p, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
        need = {"camera", "point", "x", "y", "z", "u", "v"}
        if not rows or not need <= set(rows[0]):
            raise InputError(str(p), f"a CSV with columns {sorted(need)}", f"columns {sorted(rows[0]) if rows else []}")
        for i, r in enumerate(rows, start=2):
            try:
                xyz = np.array([float(r["x"]), float(r["y"]), float(r["z"])])
                uv = np.array([float(r["u"]), float(r["v"])])
            except ValueError:
                raise InputError(f"{p}: line {i}", "numbers in x, y, z, u, v", repr(r)) from None
            if r["point"] in coords and not np.allclose(coords[r["point"]], xyz):
                raise InputError(f"{p}: line {i}", f"the same coordinates for point {r['point']}",
                                 f"{xyz.tolist()} and {coords[r['point']].tolist()}")
            coords[r["point"]] = xyz
            seen.setdefault(r["camera"], {})[r["point"]] = uv
    else:
        raise InputError(str(p), "a .toml or .csv scene-point file", f"suffix {p.suffix!r}")
    unknown = sorted({k for t in seen.values() for k in t} - set(coords))
    if unknown:
        raise InputError(str(p), "coordinates for every point clicked", f"points without coordinates {unknown}")
    cams = sorted(seen)
    order, _ = match_cameras(list(camera_names), [Path(c) for c in cams], f"{p}: cameras")
    names = list(coords)
    pixels = np.full((len(camera_names), len(names), 2), np.nan)
    for ci, si in enumerate(order):
        for k, uv in seen[cams[si]].items():
            pixels[ci, names.index(k)] = uv
    return names, np.array([coords[n] for n in names]), pixels
