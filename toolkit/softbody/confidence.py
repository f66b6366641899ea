"""How far a tracked frame can be trusted: residuals, coverage and silhouettes of the fitted model.

A tracker that has lost the person still returns a pose, and the tracker's
own inlier fraction alone does not say so: the model may fit the points near
it well (a leg on the other leg's points, the trunk on the near side of the
body) while a whole limb or half the body is elsewhere.  Three measures of
the fitted pose, each a fraction in [0, 1], see different failures:

* **residuals**: the share of the points within ``residual_gate`` of the
  fitted surface that lie within ``inlier_distance`` of it (points the model
  does not explain: it lies beside the body); the tracker passes the points
  it fitted, those it took for the subject's (:mod:`toolkit.softbody.separate`:
  not another person's; a limb the tracker lost and took for another body
  shows in the coverage and the silhouettes);
* **coverage**: the share of the model's surface facing a camera that has a
  point of the cloud within ``coverage_distance`` (model parts where the
  cameras see no body: a limb swung out into empty space);
* **silhouettes**: per camera with a mask, the least of the share of the
  mask's outline rays passing within ``outline_distance`` of the model, of
  those within ``residual_gate`` of it (the person's outline explained;
  another person's outline in the same mask left out) and, per rigid part of the model (trunk, head,
  each limb segment), the share of its unburied surface samples projecting
  into the mask (the part where the camera sees the person; an occluded limb
  still projects into the mask of what hides it); the least over the cameras (one camera that sees the model off the
  person is enough to doubt the frame).  Both come from what the silhouette
  block of tracking uses (:mod:`toolkit.softbody.silhouette`), at about a
  tenth of the cost of drawing the model's own silhouette.

The frame's **confidence** is the least of the three, each divided by its
``trusted_*`` level (clipped to 1): 1 when every measure reaches its level.
A frame is **lost** when any measure falls below its ``lost_*`` level, and
**trusted** otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from toolkit.errors import InputError
from toolkit.softbody.distance import distance
from toolkit.softbody.model import SoftBodyModel, SoftBodyParams

__all__ = ["ConfidenceConfig", "FrameConfidence", "frame_confidence", "VERDICTS"]

#: What a frame's confidence says.
VERDICTS = ("trusted", "lost")


@dataclass(frozen=True)
class ConfidenceConfig:
    """Levels of :func:`frame_confidence`.

    Attributes
    ----------
    inlier_distance : float
        A point within this of the fitted surface is explained, metres.
    residual_gate : float
        Points and outline rays further than this from the fitted surface are left out of the residual and
        outline measures, metres (another body, clutter).
    coverage_distance : float
        A model surface sample with a cloud point within this is covered, metres.
    coverage_dirs : int
        Surface samples per metaball.
    outline_distance : float
        A camera ray through the mask's outline passing this close to the model's surface is explained,
        metres.
    mask_margin_px : float
        A model surface sample projecting this close to the mask (pixels) lies in it.
    lost_residual, lost_coverage, lost_silhouette : float
        A frame whose share of explained points, of covered surface or whose least silhouette IoU is below
        this is lost.
    trusted_residual, trusted_coverage, trusted_silhouette : float
        The levels that count as full confidence (1).

    Notes
    -----
    The levels were set on a 30-frame trinocular walk (seed 20500 of ``bench_softbody --motions walk
    --frames 30 --seed 20000``): its tracked frames (36-45 mm from the truth) had 0.97-0.99 of the
    points explained, 0.68-0.78 of the surface covered and silhouettes of 0.87-0.94; the same frames
    fitted from starts moved 0.25-0.4 m or with every angle off by 0.5 rad (59-308 mm from the truth)
    0.48-0.65 covered or silhouettes of 0.30-0.64 (the points stay explained: the fit sits on part of
    the body).
    """

    inlier_distance: float = 0.05
    residual_gate: float = 0.25
    coverage_distance: float = 0.05
    coverage_dirs: int = 24
    outline_distance: float = 0.03
    mask_margin_px: float = 2.0
    lost_residual: float = 0.9
    lost_coverage: float = 0.35
    lost_silhouette: float = 0.6
    trusted_residual: float = 0.97
    trusted_coverage: float = 0.7
    trusted_silhouette: float = 0.8

    def __post_init__(self):
        for name in ("inlier_distance", "residual_gate", "coverage_distance"):
            if not getattr(self, name) > 0:
                raise InputError(f"ConfidenceConfig.{name}", "a positive distance in metres", repr(getattr(self, name)))
        for kind in ("residual", "coverage", "silhouette"):
            lo, hi = getattr(self, f"lost_{kind}"), getattr(self, f"trusted_{kind}")
            if not 0.0 <= lo < hi <= 1.0:
                raise InputError(f"ConfidenceConfig.lost_{kind}/trusted_{kind}", "0 <= lost < trusted <= 1",
                                 f"{lo}, {hi}")


class FrameConfidence(NamedTuple):
    """One frame's confidence (:func:`frame_confidence`).

    Attributes
    ----------
    residual, coverage, silhouette : float
        The three fractions in [0, 1]; NaN where not measured (no points; no masks).
    confidence : float
        Least of the measured fractions, each divided by its trusted level, clipped to [0, 1]; 0 without points.
    verdict : str
        One of :data:`VERDICTS`.
    """

    residual: float
    coverage: float
    silhouette: float
    confidence: float
    verdict: str


def _coverage(model: SoftBodyModel, params: SoftBodyParams, tree: cKDTree, config: ConfidenceConfig,
              viewpoints) -> float:
    from toolkit.softbody.residuals import coverage_samples

    samples = coverage_samples(model, params, n_dirs=config.coverage_dirs, viewpoints=viewpoints)
    if len(samples) == 0:
        return float("nan")
    d, _ = tree.query(samples.points(model.state(params)))
    return float(np.mean(d < config.coverage_distance))


def _silhouette(model: SoftBodyModel, params: SoftBodyParams, views, config: ConfidenceConfig) -> float:
    from toolkit.softbody.mesh import unit_directions
    from toolkit.softbody.residuals import CoverageSamples
    from toolkit.softbody.silhouette import ray_minimum

    st = model.state(params)
    n_dirs = config.coverage_dirs
    prims = np.repeat(np.arange(model.n_prims), n_dirs)
    surface = CoverageSamples(prims, np.tile(unit_directions(n_dirs), (model.n_prims, 1))).points(st)
    unburied = distance(model, params, surface, state=st) > -0.01   # not inside another metaball
    surface, part = surface[unburied], np.asarray(model.prim_frame)[prims[unburied]]
    parts = [part == k for k in np.unique(part) if np.count_nonzero(part == k) >= 5]
    shares = []
    for v in views:
        if v.state != "ok":
            continue
        _, d = ray_minimum(model, params, v.origins, v.directions, state=st)
        near = np.abs(d) < config.residual_gate   # another person's outline in the same mask: left out
        outline = float(np.mean(np.abs(d[near]) < config.outline_distance)) if near.any() else 0.0
        uv = v.camera.project(surface)
        ok = np.isfinite(uv).all(axis=1) & v.camera.in_image(uv, margin=0.0) & (v.camera.depth_of(surface) > 0)
        q = np.round(uv[ok]).astype(int)
        inside = np.zeros(len(surface), bool)
        inside[np.flatnonzero(ok)] = v.outside[q[:, 1], q[:, 0]] <= config.mask_margin_px
        # each rigid part on its own: one limb out in the background is a loss however well the rest fits
        shares.append(min([outline] + [float(np.mean(inside[m])) for m in parts]))
    return float(min(shares)) if shares else float("nan")


def frame_confidence(model: SoftBodyModel, params: SoftBodyParams, points, *, silhouettes=None, viewpoints=None,
                     config: ConfidenceConfig = ConfidenceConfig()) -> FrameConfidence:
    """How far one fitted frame can be trusted.

    Parameters
    ----------
    model : SoftBodyModel
    params : SoftBodyParams
        The fitted pose.
    points : array_like of shape (N, 3)
        The frame's points (metres, world); may be empty.
    silhouettes : list of SilhouetteView, optional
        The frame's camera silhouettes.
    viewpoints : array_like of shape (V, 3), optional
        Camera centres (metres): coverage only of the surface facing one.
    config : ConfidenceConfig

    Returns
    -------
    FrameConfidence
    """
    pts = np.asarray(points, float).reshape(-1, 3)
    nan = float("nan")
    if len(pts) == 0:
        return FrameConfidence(0.0, 0.0, nan, 0.0, "lost")
    d = np.abs(distance(model, params, pts))
    near = d < config.residual_gate
    residual = float(np.mean(d[near] < config.inlier_distance)) if near.any() else 0.0
    coverage = _coverage(model, params, cKDTree(pts), config, viewpoints)
    sil = _silhouette(model, params, silhouettes, config) if silhouettes else nan
    measured = [(residual, config.lost_residual, config.trusted_residual),
                (coverage, config.lost_coverage, config.trusted_coverage),
                (sil, config.lost_silhouette, config.trusted_silhouette)]
    measured = [m for m in measured if np.isfinite(m[0])]
    confidence = float(np.clip(min(v / hi for v, _, hi in measured), 0.0, 1.0))
    lost = any(v < lo for v, lo, _ in measured)
    return FrameConfidence(residual, coverage, sil, confidence, "lost" if lost else "trusted")
