"""The scene's coarse geometry: a ground plane and a cylinder of walls around the capture volume.

Free-viewpoint video of a pitch or a room needs the background where the
people are not: a broadcast camera mostly sees grass, a studio camera the
floor and the walls behind.  :class:`SceneProxy` stands for that with two
surfaces every view can be intersected with exactly and cheaply:

* the ground, the plane ``z = ground_z`` (the project's world convention puts
  the ground at z = 0), out to ``radius_m`` from ``centre``;
* a vertical cylinder of radius ``radius_m`` around ``centre``, of unlimited
  height: walls, stands, the sky above them.

:func:`toolkit.scene.fit.fit_proxy` takes the centre from where the source cameras look and
chooses the radius from the source backgrounds themselves: each candidate
radius carries every source's background into every other source (leave one
out, at a reduced resolution), and the radius whose carried views agree best
with the sources' own where the cylinder matters wins; with no evidence the
smallest candidate is kept.

Lengths are metres, world frame, z up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolkit.errors import InputError

__all__ = ["SceneProxy", "SURFACE_NONE", "SURFACE_GROUND", "SURFACE_WALL"]

#: :meth:`SceneProxy.intersect` surface ids.
SURFACE_NONE, SURFACE_GROUND, SURFACE_WALL = 0, 1, 2
@dataclass(frozen=True)
class SceneProxy:
    """A ground plane and a vertical cylinder of walls.

    Parameters
    ----------
    centre : tuple of float
        ``(x, y)`` of the cylinder's axis, metres.
    radius_m : float
        The cylinder's radius (the ground ends there), metres; it must enclose
        every camera that looks through it.
    ground_z : float
        Height of the ground plane, metres.
    """

    centre: tuple
    radius_m: float
    ground_z: float = 0.0

    def __post_init__(self):
        c = np.asarray(self.centre, float)
        if c.shape != (2,) or not np.isfinite(c).all():
            raise InputError("SceneProxy.centre", "(x, y) in metres", repr(self.centre))
        if not (np.isfinite(self.radius_m) and self.radius_m > 0):
            raise InputError("SceneProxy.radius_m", "a positive radius in metres", repr(self.radius_m))
        if not np.isfinite(self.ground_z):
            raise InputError("SceneProxy.ground_z", "a finite height in metres", repr(self.ground_z))

    def intersect(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where rays first meet the proxy.

        Parameters
        ----------
        origins, directions : ndarray of shape (N, 3)
            Ray origins inside the cylinder and directions (any length), world.

        Returns
        -------
        points : ndarray of shape (N, 3)
            The hits, NaN where none (a ray from outside the cylinder, or NaN).
        surface : ndarray of shape (N,) uint8
            :data:`SURFACE_GROUND`, :data:`SURFACE_WALL` or :data:`SURFACE_NONE`.
        """
        o = np.asarray(origins, float)
        d = np.asarray(directions, float)
        cx, cy = (float(v) for v in self.centre)
        r2 = float(self.radius_m) ** 2
        ox, oy, oz = o[:, 0], o[:, 1], o[:, 2]
        dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
        # the ground, where the ray goes down onto it inside the cylinder (column by column: the same
        # arithmetic as on (N, 3) rows, without the reductions over rows of three)
        with np.errstate(divide="ignore", invalid="ignore"):
            tg = (self.ground_z - oz) / dz
            gx, gy = ox + tg * dx, oy + tg * dy
            ground = (dz < 0) & (tg > 0) & ((gx - cx) ** 2 + (gy - cy) ** 2 <= r2)
            # the wall: |o_xy + t d_xy - c| = r, the positive root (from inside)
            qx, qy = ox - cx, oy - cy
            a = dx ** 2 + dy ** 2
            b = 2 * (qx * dx + qy * dy)
            cc = (qx ** 2 + qy ** 2) - r2
            tw = (-b + np.sqrt(b * b - 4 * a * cc)) / (2 * a)
            wall = ~ground & (cc < 0) & np.isfinite(tw) & (tw > 0)
            wall &= oz + tw * dz >= self.ground_z - 1e-9
        t = np.where(ground, tg, np.where(wall, tw, np.nan))
        pts = o + t[:, None] * d
        surf = np.zeros(o.shape[0], np.uint8)
        surf[ground] = SURFACE_GROUND
        surf[wall] = SURFACE_WALL
        return pts, surf

    def to_json(self) -> dict:
        return {"centre_m": [float(v) for v in self.centre], "radius_m": float(self.radius_m),
                "ground_z_m": float(self.ground_z)}

    @classmethod
    def from_json(cls, d: dict, where: str = "scene.json") -> "SceneProxy":
        try:
            return cls(tuple(float(v) for v in d["centre_m"]), float(d["radius_m"]), float(d["ground_z_m"]))
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"{where}: proxy", "centre_m [x, y], radius_m and ground_z_m", f"{d!r} ({e})") from e
