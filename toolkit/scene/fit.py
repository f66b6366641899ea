"""Choosing the scene proxy of a rig from its source backgrounds.

:func:`fit_proxy` takes the proxy's centre from where the source cameras look
(:func:`look_centre`) and its wall radius from the backgrounds themselves: each
candidate radius (:data:`RADIUS_CANDIDATES`) carries every source's background
into every other source (leave one out, :data:`FIT_DOWNSCALE` times smaller),
and the radius whose carried views agree best with the sources' own on the
wall wins.  With no evidence (all the cameras look down at the ground, or no two
of them see the same wall) the smallest candidate is kept: the ground ends just
behind the farthest camera, where a room's walls stand.
"""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.cameras import Rig, closest_point_to_rays
from toolkit.scene.backgrounds import SourceBackground
from toolkit.scene.model import SceneModel
from toolkit.scene.proxy import SURFACE_WALL, SceneProxy

__all__ = ["fit_proxy", "look_centre", "RADIUS_CANDIDATES", "FIT_DOWNSCALE", "MIN_WALL_SHARE"]

#: Candidate wall radii, as multiples of the farthest source camera's horizontal distance from the centre.
RADIUS_CANDIDATES = (1.1, 1.25, 1.45, 1.7, 2.0, 2.5, 3.2, 4.0, 5.5, 8.0)
#: The leave-one-out renders of :func:`fit_proxy` are this many times smaller than the sources.
FIT_DOWNSCALE = 8
#: A radius is chosen only when at least this share of the sources' sampled pixels fall on the wall.
MIN_WALL_SHARE = 0.02


def look_centre(rig: Rig, ground_z: float = 0.0) -> np.ndarray:
    """``(x, y)`` of the point the cameras' optical axes pass closest to (metres)."""
    if len(rig) >= 2:
        p = closest_point_to_rays(rig.centers, np.array([cam.forward for cam in rig]))[0]
        return np.asarray(p[:2], float)
    cam = rig[0]
    f = cam.forward
    t = (ground_z - cam.center[2]) / f[2] if f[2] < -1e-6 else 10.0
    return np.asarray((cam.center + t * f)[:2], float)


def fit_proxy(rig: Rig, backgrounds: dict, ground_z: float = 0.0, log=None) -> tuple[SceneProxy, dict]:
    """The proxy of a rig: its centre from the cameras' axes, its radius from the backgrounds' agreement.

    Parameters
    ----------
    rig : Rig
        The source cameras.
    backgrounds : dict of str -> SourceBackground
        Their estimated empty views.
    ground_z : float
        Height of the ground, metres.
    log : callable, optional

    Returns
    -------
    proxy : SceneProxy
    evidence : dict
        ``radii_m`` tried, ``errors`` (mean absolute colour difference of the carried
        views on the wall pixels, grey levels, per radius), ``wall_share`` (share of
        sampled pixels on the wall) and ``chosen_by`` (``"agreement"`` or ``"no evidence"``).
    """
    centre = look_centre(rig, ground_z)
    far = float(np.max(np.linalg.norm(rig.centers[:, :2] - centre, axis=1)))
    radii = [max(far, 1.0) * k for k in RADIUS_CANDIDATES]
    small = Rig(tuple(cam.scaled(1.0 / FIT_DOWNSCALE) for cam in rig))
    bgs = {}
    for cam in small:
        b = backgrounds[cam.name]
        w, h = cam.size
        bgs[cam.name] = SourceBackground(cv2.resize(b.image, (w, h), interpolation=cv2.INTER_AREA),
                                         cv2.resize(b.confidence, (w, h), interpolation=cv2.INTER_AREA), b.samples)
    errors, shares = [], []
    for r in radii:
        proxy = SceneProxy(tuple(centre), r, ground_z)
        diffs, wall_px, all_px = [], 0, 0
        for cam in small:
            others = Rig(tuple(c for c in small if c.name != cam.name))
            if not len(others):
                continue
            model = SceneModel(others, {c.name: bgs[c.name] for c in others}, proxy)
            img, cover, surf = model.render(cam, with_surface=True)
            own = bgs[cam.name]
            sel = (surf == SURFACE_WALL) & (cover > 0.2) & (own.confidence > 0.5)
            wall_px += int(sel.sum())
            all_px += sel.size
            if sel.any():
                diffs.append(np.abs(img[sel] - own.image[sel]).mean(-1))
        shares.append(wall_px / max(all_px, 1))
        errors.append(float(np.mean(np.concatenate(diffs))) if diffs else float("nan"))
    ok = [i for i, (e, s) in enumerate(zip(errors, shares)) if np.isfinite(e) and s >= MIN_WALL_SHARE]
    if ok:
        best = min(ok, key=lambda i: errors[i])
        how = "agreement"
    else:  # a room's size: the ground ends near the cameras (the walls seen behind a source stand there)
        best = 0
        how = "no evidence"
    proxy = SceneProxy(tuple(float(v) for v in centre), float(radii[best]), ground_z)
    if log is not None:
        log(f"scene proxy: ground z = {ground_z:.2f} m, walls {radii[best]:.1f} m around "
            f"({centre[0]:.1f}, {centre[1]:.1f}) ({how})")
    return proxy, {"radii_m": [float(r) for r in radii], "errors": errors, "wall_share": shares, "chosen_by": how}
