#!/usr/bin/env python3
"""Keypoint-seeded silhouettes (toolkit.foreground.seeded) against rendered ground truth.

Usage::

    python benchmarks/bench_seeded_masks.py                       # the five held-out scenes
    python benchmarks/bench_seeded_masks.py --seeds 101 102       # the scenes the defaults were tuned on
    python benchmarks/bench_seeded_masks.py --noise 0             # exact keypoints
    python benchmarks/bench_seeded_masks.py --one-model           # one colour model for the whole body

Each scene is a studio take of a subject that barely moves (``motion = "idle"``), 6 frames,
generated once into ``--cache`` (``recipes/make_scene.py``'s generator).  The seeds give the
cameras (2 or 3), the resolution (640x360 or 960x540) and the outfit (``random`` or
``like_background``, a shirt of the backdrop's or the floor's colour) as in :data:`SCENES`.
The keypoints are the true 2D joints plus Gaussian noise of ``--noise`` pixels; no clean plate
is used.  Per scene it prints the median and worst IoU over frames and cameras of the masks
(each camera's frames in order, seeded by the previous result) and of the masks carved by the
visual hull of the other views around the true 3D joints (``refine_masks``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from toolkit.foreground import SeededConfig, SeededSegmenter, mask_iou, refine_masks
from toolkit.io import Dataset
from toolkit.synthetic import generate_scene, parse_spec

#: seed -> (cameras, resolution, outfit).  101-102 tuned the defaults; 201-205 are held out.
SCENES = {101: (3, (640, 360), "random"), 102: (3, (640, 360), "like_background"),
          201: (3, (640, 360), "random"), 202: (2, (960, 540), "random"), 203: (3, (640, 360), "like_background"),
          204: (3, (960, 540), "like_background"), 205: (2, (640, 360), "random")}
HELD_OUT = (201, 202, 203, 204, 205)


def scene_spec(seed: int) -> str:
    n, (w, h), outfit = SCENES[seed]
    return (f'seed = {seed}\nframes = 6\nfps = 25\n[subject]\nheight_m = 1.75\nmotion = "idle"\noutfit = "{outfit}"\n'
            f'[cameras]\ncount = {n}\nlayout = "studio"\nresolution = [{w}, {h}]\ncalibration_error_px = 0.0\n'
            f'[novel]\ncount = 0\n')


def evaluate(root: Path, noise_px: float, rng: np.random.Generator, config: SeededConfig | None = None) -> dict:
    with Dataset.open(root) as ds:
        j2, j3 = ds.gt_joints2d(), ds.gt_joints3d()
        seg = SeededSegmenter(config)
        prev = {c: None for c in ds.camera_names}
        raw, refined = [], []
        for t in range(ds.n_frames):
            masks = {}
            for c in ds.camera_names:
                joints = j2[c][t] + rng.normal(0, noise_px, j2[c][t].shape)
                prev[c] = seg.segment(ds.frame(c, t), joints, previous=prev[c])
                masks[c] = prev[c].mask
                raw.append(mask_iou(masks[c], ds.gt_mask(c, t)))
            carved = refine_masks(masks, ds.rig, j3[t])
            refined += [mask_iou(carved[c], ds.gt_mask(c, t)) for c in ds.camera_names]
    return {"raw": (float(np.median(raw)), float(np.min(raw))),
            "refined": (float(np.median(refined)), float(np.min(refined)))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(HELD_OUT), choices=sorted(SCENES))
    ap.add_argument("--noise", type=float, default=2.0, help="keypoint noise, pixels (default 2)")
    ap.add_argument("--one-model", action="store_true", help="one colour model for the whole body "
                    "(SeededConfig.local_models = False)")
    ap.add_argument("--cache", type=Path, default=Path("out/bench_seeded_masks"))
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    print("scene  cams  size      outfit           IoU median / worst   carved median / worst   s")
    for seed in args.seeds:
        root = args.cache / f"scene_{seed}"
        if not (root / "groundtruth").is_dir():
            generate_scene(parse_spec(scene_spec(seed), f"seed {seed}"), root, progress=False).close()
        t0 = time.perf_counter()
        r = evaluate(root, args.noise, rng, SeededConfig(local_models=not args.one_model))
        n, (w, h), outfit = SCENES[seed]
        print(f"{seed:5d}  {n:4d}  {w}x{h}  {outfit:15s}  {r['raw'][0]:.3f} / {r['raw'][1]:.3f}        "
              f"{r['refined'][0]:.3f} / {r['refined'][1]:.3f}          {time.perf_counter() - t0:.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
