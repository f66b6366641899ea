"""The ``[depth_camera]`` table of a scene spec (:class:`DepthCameraSpec`) and its second person.

Rendering is in :mod:`toolkit.synthetic.depth_sensor`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

__all__ = ["ENVIRONMENTS", "KINECT_FOV_X_DEG", "KINECT_RANGE_M", "DepthCameraSpec", "SecondPerson"]

#: Range of valid readings, metres (closer or farther reads 0).
KINECT_RANGE_M = (0.5, 4.5)
#: Horizontal field of view of the Kinect v1 depth camera, degrees.
KINECT_FOV_X_DEG = 57.0
#: Surroundings a depth camera spec may ask for.
ENVIRONMENTS = ("studio", "floor", "none")


@dataclass(frozen=True)
class SecondPerson:
    """A second person in the depth camera's view.

    Attributes
    ----------
    offset_m : tuple of float
        Position relative to the tracked person's mean position, in the tracked
        person's frame: (to their right, forward), metres.
    motion : str
        Motion name of :func:`toolkit.motion.generate_motion`.
    height_m : float
        Stature of the second person.
    """

    offset_m: tuple[float, float] = (0.75, 0.25)
    motion: str = "idle"
    height_m: float = 1.70


@dataclass(frozen=True)
class DepthCameraSpec:
    """The ``[depth_camera]`` table of a scene spec.

    Attributes
    ----------
    resolution : tuple of int
        ``(width, height)`` in pixels.
    noise : bool
        Apply the sensor model (noise, quantisation, shadows, dropouts).
    fov_deg : float
        Horizontal field of view, degrees.
    position, target : tuple of float or None
        World eye and look-at point, metres; by default the camera stands
        ``distance_m`` from the person's mean position, in their initial facing
        direction turned by ``azimuth_deg`` (counter-clockwise seen from above,
        90 = at their left), at ``height_m``, looking at ``target_height_m``.
    distance_m, height_m, target_height_m, azimuth_deg : float
    range_m : tuple of float
        Valid reading range (near, far), metres.
    environment : str
        ``"studio"`` (floor and walls, as a room seen by the sensor), ``"floor"``
        (a bare floor, quicker to build) or ``"none"``.
    second_person : SecondPerson or None
    name : str
        Camera name.
    """

    resolution: tuple[int, int] = (640, 480)
    noise: bool = True
    fov_deg: float = KINECT_FOV_X_DEG
    position: tuple[float, float, float] | None = None
    target: tuple[float, float, float] | None = None
    distance_m: float = 3.2
    height_m: float = 1.0
    target_height_m: float = 0.9
    azimuth_deg: float = 0.0
    range_m: tuple[float, float] = KINECT_RANGE_M
    environment: str = "studio"
    second_person: SecondPerson | None = None
    name: str = "depth"

    def __post_init__(self):
        w, h = self.resolution
        if w <= 0 or h <= 0:
            raise InputError("DepthCameraSpec.resolution", "positive [width, height]", f"{self.resolution}")

    @classmethod
    def from_table(cls, table: dict, source: str = "<spec>") -> DepthCameraSpec:
        """Parse a ``[depth_camera]`` table.

        Parameters
        ----------
        table : dict
            The table as ``tomllib`` gives it.
        source : str
            File name used in error messages.

        Raises
        ------
        InputError
            ``"<source>: [depth_camera].<field>"`` with what was expected and found,
            for an unknown field or a malformed value.
        """
        where = f"{source}: [depth_camera]"
        if not isinstance(table, dict):
            raise InputError(where, "a table", type(table).__name__)
        known = {"resolution", "noise", "fov_deg", "position", "target", "distance_m", "height_m",
                 "target_height_m", "azimuth_deg", "range_m", "environment", "second_person", "name"}
        unknown = sorted(set(table) - known)
        if unknown:
            raise InputError(f"{where}.{unknown[0]}", f"one of the fields {sorted(known)}", "an unknown field")
        kw = {}

        def number(key, lo=-np.inf, hi=np.inf, t=None):
            v = t.get(key) if t is not None else table.get(key)
            w_ = f"{where}.{key}" if t is None else f"{where}.second_person.{key}"
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or not lo < v < hi:
                raise InputError(w_, f"a number in ({lo}, {hi})", repr(v))
            return float(v)

        def vector(key, n, t=None):
            v = t.get(key) if t is not None else table.get(key)
            w_ = f"{where}.{key}" if t is None else f"{where}.second_person.{key}"
            ok = isinstance(v, list) and len(v) == n and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in v)
            if not ok:
                raise InputError(w_, f"a list of {n} numbers", repr(v))
            return tuple(float(x) for x in v)

        if "resolution" in table:
            r = table["resolution"]
            if not (isinstance(r, list) and len(r) == 2 and all(isinstance(x, int) and not isinstance(x, bool)
                                                                  and x > 0 for x in r)):
                raise InputError(f"{where}.resolution", "[width, height] as two positive integers", repr(r))
            kw["resolution"] = (r[0], r[1])
        if "noise" in table:
            if not isinstance(table["noise"], bool):
                raise InputError(f"{where}.noise", "true or false", repr(table["noise"]))
            kw["noise"] = table["noise"]
        if "fov_deg" in table:
            kw["fov_deg"] = number("fov_deg", 1.0, 170.0)
        for key in ("position", "target"):
            if key in table:
                kw[key] = vector(key, 3)
        for key in ("distance_m", "height_m", "target_height_m"):
            if key in table:
                kw[key] = number(key, 0.0, 100.0)
        if "azimuth_deg" in table:
            kw["azimuth_deg"] = number("azimuth_deg", -360.0, 360.0)
        if "range_m" in table:
            rng_ = vector("range_m", 2)
            if not 0 < rng_[0] < rng_[1]:
                raise InputError(f"{where}.range_m", "[near, far] with 0 < near < far", repr(table["range_m"]))
            kw["range_m"] = rng_
        if "environment" in table:
            if table["environment"] not in ENVIRONMENTS:
                raise InputError(f"{where}.environment", f"one of {list(ENVIRONMENTS)}", repr(table["environment"]))
            kw["environment"] = table["environment"]
        if "name" in table:
            if not isinstance(table["name"], str) or not table["name"]:
                raise InputError(f"{where}.name", "a non-empty string", repr(table["name"]))
            kw["name"] = table["name"]
        if "second_person" in table:
            sp = table["second_person"]
            if isinstance(sp, bool):
                kw["second_person"] = SecondPerson() if sp else None
            elif isinstance(sp, dict):
                bad = sorted(set(sp) - {"offset_m", "motion", "height_m"})
                if bad:
                    raise InputError(f"{where}.second_person.{bad[0]}", "offset_m, motion or height_m",
                                     "an unknown field")
                skw = {}
                if "offset_m" in sp:
                    skw["offset_m"] = vector("offset_m", 2, sp)
                if "motion" in sp:
                    from toolkit.motion import MOTIONS

                    if sp["motion"] not in MOTIONS:
                        raise InputError(f"{where}.second_person.motion", f"one of {list(MOTIONS)}",
                                         repr(sp["motion"]))
                    skw["motion"] = sp["motion"]
                if "height_m" in sp:
                    skw["height_m"] = number("height_m", 1.0, 2.5, sp)
                kw["second_person"] = SecondPerson(**skw)
            else:
                raise InputError(f"{where}.second_person", "true, false or a table", repr(sp))
        return cls(**kw)

