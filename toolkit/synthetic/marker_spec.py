"""The ``[markers]`` table of a scene spec: a synthetic optical marker capture.

A scene spec with a ``[markers]`` table is a *marker capture*: the performer
wears reflective markers of a :class:`~toolkit.markers.MarkerSet`, a ring of
calibrated cameras sees them as unlabelled 2D blobs, and no colour videos
are rendered (the spec has no ``[cameras]`` table: its cameras are
``[markers].cameras``).  Example::

    seed = 3
    frames = 300
    fps = 100

    [subject]
    height_m = 1.72
    motion = "rom"

    [markers]
    set = "plug-in-gait"       # or "cluster"
    noise_px = 0.5             # standard deviation of the blob centres, pixels
    occlusion = 0.1            # share of the visible marker projections missed, in bursts
    ghosts = 1.0               # spurious blobs per camera and frame (mean)

    [markers.cameras]
    count = 8                  # >= 3, on a ring around the performer
    radius_m = 4.5             # 3-6 m
    height_m = 2.4
    resolution = [1280, 1024]
    fov_deg = 60.0             # horizontal field of view

``cameras = 8`` is short for ``[markers.cameras] count = 8``.  The writer is
:mod:`toolkit.synthetic.marker_capture`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

__all__ = ["MarkerSpec", "RING_RADIUS_RANGE_M", "MIN_MARKER_CAMERAS", "MAX_MARKER_CAMERAS"]

#: Radius of the camera ring, metres (the issue's 3-6 m).
RING_RADIUS_RANGE_M = (3.0, 6.0)
#: Fewest cameras of a marker capture (trinocular reconstruction needs three views).
MIN_MARKER_CAMERAS = 3
#: Most cameras of a marker capture.
MAX_MARKER_CAMERAS = 32
#: Largest mean burst length of missed detections, frames.
MAX_BURST_FRAMES = 1000.0

_KEYS = {"set", "cameras", "noise_px", "occlusion", "occlusion_burst_frames", "ghosts", "calibration_error_px",
         "soft_tissue_mm"}
_CAMERA_KEYS = {"count", "radius_m", "height_m", "resolution", "fov_deg"}


@dataclass(frozen=True)
class MarkerSpec:
    """A parsed ``[markers]`` table.

    Attributes
    ----------
    set : str
        Marker set name (``"plug-in-gait"`` or ``"cluster"``).
    camera_count : int
        Number of cameras on the ring, >= 3.
    radius_m : float
        Ring radius around the performer's mean position, metres (3-6).
    height_m : float
        Camera height above the ground, metres (they look at the body's middle).
    resolution : tuple of int
        ``(width, height)`` pixels.
    fov_deg : float
        Horizontal field of view, degrees.
    noise_px : float
        Standard deviation of each blob centre's x and y, pixels.
    occlusion : float
        Share of the marker projections that reach an image (in view and not
        hidden by the body) but are missed, in [0, 0.9).
    occlusion_burst_frames : float
        Mean length of a run of misses, frames (misses come in bursts).
    ghosts : float
        Mean number of spurious blobs per camera and frame (Poisson).
    calibration_error_px : float
        Mean reprojection error of the written ("measured") calibration, pixels (0 = exact).
    soft_tissue_mm : float
        Amplitude (standard deviation per axis) of the smooth soft-tissue
        motion of skin markers relative to their segment, mm (plates move half as much).
    """

    set: str = "plug-in-gait"
    camera_count: int = 8
    radius_m: float = 4.5
    height_m: float = 2.4
    resolution: tuple[int, int] = (1280, 1024)
    fov_deg: float = 60.0
    noise_px: float = 0.5
    occlusion: float = 0.05
    occlusion_burst_frames: float = 8.0
    ghosts: float = 0.5
    calibration_error_px: float = 0.0
    soft_tissue_mm: float = 2.0

    @classmethod
    def from_table(cls, table, source: str = "<spec>") -> "MarkerSpec":
        """Parse and validate a ``[markers]`` table.

        Parameters
        ----------
        table : dict
            The table as ``tomllib`` gives it.
        source : str
            File name used in error messages.

        Raises
        ------
        InputError
            ``"<source>: markers.<field>"`` with what was expected and found,
            for an unknown field or an impossible value (fewer than 3 cameras,
            a ring outside 3-6 m, an occlusion share outside [0, 0.9), ...).
        """
        from toolkit.markers.marker_sets import MARKER_SETS

        where = f"{source}: markers"
        if not isinstance(table, dict):
            raise InputError(where, "a table", type(table).__name__)
        unknown = sorted(set(table) - _KEYS)
        if unknown:
            raise InputError(f"{where}.{unknown[0]}", f"one of the fields {sorted(_KEYS)}", "an unknown field")
        kw = {}

        def number(t, key, lo, hi, name, lo_open=False, hi_open=False):
            v = t[key]
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
            ok = ok and (lo < v if lo_open else lo <= v) and (v < hi if hi_open else v <= hi)
            if not ok:
                lb, hb = "(" if lo_open else "[", ")" if hi_open else "]"
                raise InputError(f"{where}.{name}", f"a number in {lb}{lo:g}, {hi:g}{hb}", repr(v))
            return float(v)

        if "set" in table:
            if table["set"] not in MARKER_SETS:
                raise InputError(f"{where}.set", f"one of {sorted(MARKER_SETS)}", repr(table["set"]))
            kw["set"] = table["set"]
        for key, lo, hi, lo_open, hi_open in (("noise_px", 0.0, 20.0, False, False),
                                              ("occlusion", 0.0, 0.9, False, True),
                                              ("occlusion_burst_frames", 1.0, MAX_BURST_FRAMES, False, False),
                                              ("ghosts", 0.0, 100.0, False, False),
                                              ("calibration_error_px", 0.0, 100.0, False, False),
                                              ("soft_tissue_mm", 0.0, 30.0, False, False)):
            if key in table:
                kw[key] = number(table, key, lo, hi, key, lo_open, hi_open)
        cams = table.get("cameras", {})
        if isinstance(cams, int) and not isinstance(cams, bool):
            cams = {"count": cams}
        if not isinstance(cams, dict):
            raise InputError(f"{where}.cameras", "a camera count or a [markers.cameras] table", repr(cams))
        unknown = sorted(set(cams) - _CAMERA_KEYS)
        if unknown:
            raise InputError(f"{where}.cameras.{unknown[0]}", f"one of the fields {sorted(_CAMERA_KEYS)}",
                             "an unknown field")
        if "count" in cams:
            c = cams["count"]
            if (isinstance(c, bool) or not isinstance(c, int)
                    or not MIN_MARKER_CAMERAS <= c <= MAX_MARKER_CAMERAS):
                raise InputError(f"{where}.cameras.count",
                                 f"an integer from {MIN_MARKER_CAMERAS} to {MAX_MARKER_CAMERAS}"
                                 " (trinocular reconstruction needs at least three views)", repr(c))
            kw["camera_count"] = c
        if "radius_m" in cams:
            kw["radius_m"] = number(cams, "radius_m", *RING_RADIUS_RANGE_M, "cameras.radius_m")
        if "height_m" in cams:
            kw["height_m"] = number(cams, "height_m", 0.3, 6.0, "cameras.height_m")
        if "fov_deg" in cams:
            kw["fov_deg"] = number(cams, "fov_deg", 10.0, 150.0, "cameras.fov_deg")
        if "resolution" in cams:
            r = cams["resolution"]
            if not (isinstance(r, list) and len(r) == 2
                    and all(isinstance(x, int) and not isinstance(x, bool) and 64 <= x <= 8192 and x % 2 == 0 for x in r)):
                raise InputError(f"{where}.cameras.resolution", "[width, height], even integers from 64 to 8192",
                                 repr(r))
            kw["resolution"] = (r[0], r[1])
        return cls(**kw)
