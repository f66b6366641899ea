"""Evaluation helpers for synthetic datasets: the true background seen by any camera.

Novel views are compared with the ground truth inside the subject's bounding
box, so every method is composited over the same background: the scene's
static surroundings rendered from the dataset's ``scene.toml`` (synthetic
data only).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolkit.cameras import Camera
from toolkit.errors import InputError


#: Background plates :class:`BackgroundPlates` keeps (~11 MB each at 1280x720).
PLATES_KEPT = 8


class BackgroundPlates:
    """Background plates of a synthetic scene, (H, W, 3) float32 0..255 per camera.

    Parameters
    ----------
    scene_toml : path
        The dataset's ``scene.toml``.
    """

    def __init__(self, scene_toml: str | Path):
        from toolkit.synthetic.environment import make_environment
        from toolkit.synthetic.generator import build_scene, make_renderer
        from toolkit.synthetic.spec import parse_spec

        p = Path(scene_toml)
        if not p.is_file():
            raise InputError(str(p), "the scene.toml of a synthetic dataset", "no such file")
        spec = parse_spec(p.read_text())
        scene = build_scene(spec)
        env = make_environment(spec.layout, scene.rngs["environment"])
        self._renderer = make_renderer(spec, env)
        self._kept: dict = {}

    def plate(self, camera: Camera) -> np.ndarray:
        """The surroundings seen by ``camera`` (its size must be the scene's resolution); read-only.

        The last :data:`PLATES_KEPT` cameras' plates are kept (a novel camera's
        is drawn once per run, a camera path's views once each, without
        keeping them all).
        """
        key = (camera.K.tobytes(), camera.cam_from_world.tobytes())
        plate = self._kept.pop(key, None)
        if plate is None:
            plate = self._renderer.background_plate(camera, keep=False)
            plate.flags.writeable = False
        self._kept[key] = plate  # the most recently used last
        while len(self._kept) > PLATES_KEPT:
            self._kept.pop(next(iter(self._kept)))
        return plate


#: PSNRs are capped at this in the averages, dB (identical images give inf).
PSNR_CAP_DB = 100.0


def summarise(per_frame: list[dict]) -> dict:
    """Average per-frame scores of every method over views and frames.

    Parameters
    ----------
    per_frame : list of dict
        ``{method: {camera: {"psnr", "ssim"[, "psnr_subject", "coverage"]}}}`` per frame
        (:func:`toolkit.rendering.metrics.bbox_scores` and
        :func:`~toolkit.rendering.metrics.subject_scores`).

    Returns
    -------
    dict
        ``{method: {"psnr", "ssim", "n", "psnr_subject", "coverage", "coverage_min"}}``: means over the
        views with a subject (PSNR capped at :data:`PSNR_CAP_DB`), ``n`` their count, ``coverage_min`` the
        worst view-frame; NaN where there is none (e.g. ``psnr_subject`` of frames scored before it existed).
    """
    acc: dict = {}
    keys = ("psnr", "ssim", "psnr_subject", "coverage")
    for f in per_frame:
        for method, cams in f.items():
            a = acc.setdefault(method, {k: [] for k in keys})
            for s in cams.values():
                if np.isnan(s["psnr"]):
                    continue  # no subject in this view
                for k in keys:
                    v = s.get(k, float("nan"))
                    if k.startswith("psnr"):
                        v = min(v, PSNR_CAP_DB)
                    if np.isfinite(v):
                        a[k].append(v)

    def mean(v):
        return float(np.mean(v)) if v else float("nan")

    return {m: {"psnr": mean(v["psnr"]), "ssim": mean(v["ssim"]), "n": len(v["psnr"]),
                "psnr_subject": mean(v["psnr_subject"]), "coverage": mean(v["coverage"]),
                "coverage_min": float(np.min(v["coverage"])) if v["coverage"] else float("nan")}
            for m, v in acc.items()}
