"""Evaluation helpers for synthetic datasets: the true background seen by any camera.

Novel views are compared with the ground truth inside the subject's bounding
box, so every method is composited over the same background: the scene's
static surroundings rendered from the dataset's ``scene.toml`` (synthetic
data only).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from toolkit.cameras import Camera
from toolkit.errors import InputError
from toolkit.io.shared_store import SharedStore


#: Background plates :class:`BackgroundPlates` keeps (~11 MB each at 1280x720).
PLATES_KEPT = 8


class BackgroundPlates:
    """Background plates of a synthetic scene, (H, W, 3) float32 0..255 per camera.

    Parameters
    ----------
    scene_toml : path
        The dataset's ``scene.toml``.
    store : path, optional
        A folder shared by the processes of one run (e.g. the run folder's
        ``.plates``): the plates of :meth:`share` cameras are drawn there
        once, by whichever process claims each first, and read by the others
        (the same float32 values, ``.npy``).
    """

    def __init__(self, scene_toml: str | Path, store: str | Path | None = None):
        from toolkit.synthetic.environment import make_environment
        from toolkit.synthetic.generator import build_scene, make_renderer
        from toolkit.synthetic.spec import parse_spec

        p = Path(scene_toml)
        if not p.is_file():
            raise InputError(str(p), "the scene.toml of a synthetic dataset", "no such file")
        text = p.read_text()
        spec = parse_spec(text)
        scene = build_scene(spec)
        env = make_environment(spec.layout, scene.rngs["environment"])
        self._renderer = make_renderer(spec, env)
        self._kept: dict = {}
        self._scene_digest = hashlib.sha1(text.encode()).hexdigest()
        self._store = None if store is None else SharedStore(store)

    def plate(self, camera: Camera) -> np.ndarray:
        """The surroundings seen by ``camera`` (its size must be the scene's resolution); read-only.

        The last :data:`PLATES_KEPT` cameras' plates are kept (a novel camera's
        is drawn once per run, a camera path's views once each, without
        keeping them all); with a store, a plate found there is read, not drawn.
        """
        key = (camera.K.tobytes(), camera.cam_from_world.tobytes())
        plate = self._kept.pop(key, None)
        if plate is None:
            plate = self._stored(camera) if self._store is not None else None
            if plate is None:
                plate = self._renderer.background_plate(camera, keep=False)
            plate.flags.writeable = False
        self._kept[key] = plate  # the most recently used last
        while len(self._kept) > PLATES_KEPT:
            self._kept.pop(next(iter(self._kept)))
        return plate

    def share(self, cameras) -> int:
        """Draw into the store the plates of ``cameras`` no other process has claimed; returns how many.

        Every process of a run calls it with the run's fixed cameras (novel
        views, a bird's-eye view) before its first frame: each plate is drawn
        once in all, the work split between the processes, none waiting for
        another (:meth:`toolkit.io.shared_store.SharedStore.compute`).  Without a
        store it does nothing.
        """
        if self._store is None:
            return 0
        return sum(self._store.compute(self._key(cam), lambda cam=cam: {
            "plate": self._renderer.background_plate(cam, keep=False)}) for cam in cameras)

    def _key(self, camera: Camera) -> str:
        h = hashlib.sha1(self._scene_digest.encode())
        for a in (camera.K, camera.cam_from_world, np.asarray(camera.size)):
            h.update(np.ascontiguousarray(a, np.float64).tobytes())
        return h.hexdigest()

    def _path(self, camera: Camera) -> Path:
        return self._store.path(self._key(camera))

    def _stored(self, camera: Camera) -> np.ndarray | None:
        """The stored plate of ``camera``; while another process draws it (its claim is fresh), waited for."""
        got = self._store.get(self._key(camera))
        return None if got is None else got["plate"]


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
        ``{method: {"psnr", "ssim", "n", "psnr_subject", "coverage", "coverage_min", "psnr_frame"}}``: means over the
        views with a subject (PSNR capped at :data:`PSNR_CAP_DB`), ``n`` their count, ``coverage_min`` the
        worst view-frame; NaN where there is none (e.g. ``psnr_subject`` of frames scored before it existed);
        with several people ``psnr_people``: per person the mean of its region's PSNR.
    """
    acc: dict = {}
    keys = ("psnr", "ssim", "psnr_subject", "coverage", "psnr_frame")
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

    people: dict = {}
    for f in per_frame:
        for method, cams in f.items():
            for s in cams.values():
                for k, v in enumerate(s.get("psnr_people") or []):
                    if np.isfinite(v):
                        people.setdefault(method, {}).setdefault(k, []).append(min(v, PSNR_CAP_DB))
    return {m: {"psnr": mean(v["psnr"]), "ssim": mean(v["ssim"]), "n": len(v["psnr"]),
                **({"psnr_people": [mean(people[m].get(k, [])) for k in range(max(people[m]) + 1)]}
                   if m in people else {}),
                "psnr_subject": mean(v["psnr_subject"]), "coverage": mean(v["coverage"]),
                "psnr_frame": mean(v["psnr_frame"]),
                "coverage_min": float(np.min(v["coverage"])) if v["coverage"] else float("nan")}
            for m, v in acc.items()}
