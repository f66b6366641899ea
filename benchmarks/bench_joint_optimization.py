#!/usr/bin/env python3
"""Stage-3 joint optimisation: MPJPE before/after, score evaluations, time per frame.

Usage::

    python benchmarks/bench_joint_optimization.py [--frames 2] [--scene-frames 8]
                                                  [--out out/bench_joint_optimization]
                                                  [--seeds 0 1 2] [--starts stage1 stage1+s2 gt+5cm gt-pure]

Seeded broadcast scenes at 1280x720 (2 and 3 cameras, calibration error 0 and
8 px; one scene of each kind per seed, so the camera layouts drawn by
``toolkit.synthetic.rigs.layout_azimuths``, adjacent cameras 35-110 degrees
apart, vary) of ``--scene-frames`` frames (stage 1's background model needs a
few) are generated once into OUT (reused on later runs).  Each scene's row
names the angles between its cameras' optical axes: with planar billboards the
score depends on them (two cameras 90 degrees apart see each other's
billboards edge-on).  On ``--frames`` evenly spaced
frames the joints are optimised (source 000 §3.2) from these starts:

* stage-1 joints and offsets (``recipes/pose_from_silhouettes.py``), when stage 1
  produced a 3D estimate for the frame; stage 1's offsets are added to the 2D
  joints, the scorer takes the cameras corrected by the opposite shift
  (``toolkit.pipeline.stage_inputs.Stage1Poses.cameras``, ``toolkit.multiview.corrected_rig``);
* ground-truth joints displaced by 5 cm RMS 3D noise (seeded), with the ideal
  offsets (per camera, the mean difference between the ground-truth joints
  projected through the true and the measured calibration): a test of stage 3
  alone, independent of how well stage 1 estimated the offsets;
* "gt-pure": the ground truth itself with the ideal offsets, searched with the
  source's score alone (no prior towards the start, no noise margin): where
  the score's maxima near the truth lie (of candidates scoring within the
  resampling noise of the best, the nearest), i.e. the precision of the
  score on these scenes, which bounds what a search on it can reach.

Part labels: the scenes' ground-truth part labels and depth (for the seams),
so that these starts measure stage 3 alone; and a third start, "stage1+s2",
from the stage-1 joints with the labels of the pipeline (stage 2 fitted to the
stage-1 joints on the ground-truth silhouettes, seams from the template's
depth).  ``--starts`` picks the starts; stage 1 runs only for the two that need it.
Every start runs the pipeline's stage-3 chain
(``toolkit.pipeline.stage3.optimize_frame``: seams, position score, search).  The single-evaluation timing is one joint's position score (all its
bones, every evaluated view) on one core (OpenCV and BLAS limited to one thread).
Besides the MPJPE, "aligned" is the MPJPE after removing the mean 3D
translation between the estimate and the ground truth: with miscalibrated
cameras the body's absolute position is set by the offsets' gauge (a 3D shift
of the body and a matching shift of every view's offset explain the images
equally well), which the position score cannot observe.
Targets (issue 5): >= 30 % lower MPJPE than stage 1; one evaluation < 5 ms.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import itertools  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from toolkit.anthropometry import AnthropometricConstraints  # noqa: E402
from toolkit.billboards import PositionScorer  # noqa: E402
from toolkit.cameras import Rig, camera_with_offset  # noqa: E402
from toolkit.io import Dataset  # noqa: E402
from toolkit.optimize import OptimizeConfig  # noqa: E402
from toolkit.pipeline.stage3 import optimize_frame, seams_from_depth  # noqa: E402
from toolkit.pipeline.stage_inputs import read_stage1  # noqa: E402
from toolkit.segmentation import segment_frame  # noqa: E402
from toolkit.skeleton import mpjpe  # noqa: E402
from toolkit.template import Template  # noqa: E402
from toolkit.synthetic import generate_scene, parse_spec  # noqa: E402

#: RMS 3D displacement of the ground-truth start, metres (issue 5: "5 cm noise").
GT_NOISE_M = 0.05
#: The source's score alone (no prior towards the start, no noise margin, no check that the
#: views and camera pairs agree; of candidates within the resampling noise of the best the nearest
#: still wins), run from the ground truth: where the score's maxima near the truth lie (its
#: precision on these scenes).
PURE_SCORE = OptimizeConfig(prior_weight=0.0, min_gain=0.0, decisive=False)
#: Names of the starts, in report order.
STARTS = ("stage1", "stage1+s2", "gt+5cm", "gt-pure")
#: Targets of issue 5.
TARGET_REDUCTION = 0.30
TARGET_EVAL_MS = 5.0

SPEC = """
seed = {seed}
frames = {frames}
fps = 25
[subject]
height_m = 1.76
motion = "walk"
[cameras]
count = {cams}
layout = "broadcast"
resolution = [1280, 720]
calibration_error_px = {err}
[novel]
count = 0
"""


def scene(out: Path, cams: int, err: float, frames: int, seed: int) -> Path:
    root = out / f"broadcast_{cams}cams_{int(err)}px_{frames}f_seed{seed}"
    if not (root / "field_model.json").exists():  # missing, or cached before datasets had field models
        shutil.rmtree(root, ignore_errors=True)
        shutil.rmtree(out / (root.name + "_stage1"), ignore_errors=True)
        spec = parse_spec(SPEC.format(seed=seed + 17 * cams + int(err), frames=frames, cams=cams, err=err),
                          f"{root.name}.toml")
        generate_scene(spec, root, progress=False).close()
    return root


def stage1(root: Path, out: Path) -> Path | None:
    s1 = out / (root.name + "_stage1")
    if not (s1 / "poses3d.npz").exists() or not (s1 / "calibration.toml").exists():
        r = subprocess.run([sys.executable, str(ROOT / "recipes" / "pose_from_silhouettes.py"), str(root),
                            "--out", str(s1), "--no-recording", "--quiet"], capture_output=True, text=True)
        if r.returncode != 0:
            print(f"  stage 1 failed on {root.name}: {r.stderr.strip()[-300:]}")
            return None
    return s1


def camera_angles(rig) -> list[float]:
    """Angles between the optical axes of every camera pair, degrees (rig order of pairs)."""
    fw = np.array([c.forward for c in rig])
    return [float(np.degrees(np.arccos(np.clip(fw[i] @ fw[k], -1.0, 1.0))))
            for i, k in itertools.combinations(range(len(fw)), 2)]


def change(before: float, after: float) -> str:
    """Relative change as text ("-12 %"); "n/a" from a zero start (the ground truth itself)."""
    return f"{(after / before - 1) * 100:+.0f} %" if before > 1e-9 else "n/a"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=2, help="frames optimised per scene")
    ap.add_argument("--scene-frames", type=int, default=8, help="frames per generated scene")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench_joint_optimization")
    ap.add_argument("--starts", nargs="+", choices=STARTS, default=list(STARTS),
                    help="which starts to run (default: all)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2],
                    help="scene seeds (one scene per camera count and calibration error per seed)")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    args.out.mkdir(parents=True, exist_ok=True)
    cons = AnthropometricConstraints()
    config = OptimizeConfig()
    rng = np.random.default_rng(args.seeds[0])
    print("part labels: ground truth and seams from ground-truth depth, except the 'stage1+s2' start (stage-2 labels "
          "from stage-1 joints on ground-truth silhouettes, seams from the template's depth)")
    template = Template(1.75)
    rows, eval_ms = [], []
    angles = {}
    for seed, cams, err in itertools.product(args.seeds, (2, 3), (0.0, 8.0)):
        root = scene(args.out, cams, err, args.scene_frames, seed)
        ds = Dataset.open(root)
        angles[root.name] = camera_angles(ds.rig)
        gt = ds.gt_joints3d()
        s1 = stage1(root, args.out) if {"stage1", "stage1+s2"} & set(args.starts) else None
        s1 = read_stage1(ds, s1) if s1 is not None else None  # its cameras, joints, offsets
        picks = np.unique(np.linspace(0, ds.n_frames - 1, min(args.frames, ds.n_frames) + 2)[1:-1].round())
        for t in picks.astype(int):
            images = {c: ds.frame(c, t) for c in ds.camera_names}
            labels = {c: ds.gt_parts(c, t) for c in ds.camera_names}
            depths = {c: ds.gt_depth(c, t) for c in ds.camera_names}
            have_s1 = s1 is not None and np.all(np.isfinite(s1.joints[t]))
            ideal = np.array([np.mean(ds.gt_rig[c.name].project(gt[t]) - c.project(gt[t]), axis=0)
                              for c in ds.rig])
            ideal_rig = Rig(tuple(camera_with_offset(c, o) for c, o in zip(ds.rig, ideal)))
            scorer = PositionScorer(images, labels, ideal_rig, seams_from_depth(labels, depths))
            for j in range(14):  # one candidate's score at the ground truth, as in the search (views and
                # billboards fixed per joint): median of 5 after a warm-up
                vis = {p: scorer.visibility(gt[t], p) for p in scorer.adjacent_parts(j)}
                scorer.joint_score(gt[t], j, vis)
                reps = []
                for _ in range(5):
                    t0 = time.perf_counter()
                    scorer.joint_score(gt[t], j, vis)
                    reps.append((time.perf_counter() - t0) * 1000)
                eval_ms.append(float(np.median(reps)))
            # (name, start, labels, depths for the seams, corrected cameras, search config)
            starts = [("gt+5cm", gt[t] + rng.normal(0, GT_NOISE_M / np.sqrt(3), gt[t].shape), labels, depths,
                       ideal_rig, config),
                      ("gt-pure", gt[t], labels, depths, ideal_rig, PURE_SCORE)]
            if have_s1:
                J1, rig1 = s1.joints[t], s1.cameras(t)
                starts.insert(0, ("stage1", J1, labels, depths, rig1, config))
                if "stage1+s2" in args.starts:  # the pipeline's labels: stage 2 fitted to stage 1, seams from its template
                    l2, z2 = {}, {}
                    for c in ds.camera_names:
                        seg = segment_frame(images[c], ds.gt_mask(c, t), J1, rig1[c], template)
                        l2[c], z2[c] = seg.labels, seg.template_depth
                    starts.insert(1, ("stage1+s2", J1, l2, z2, rig1, config))
            for name, J0, lab, dep, rig, cfg in [st for st in starts if st[0] in args.starts]:
                res = optimize_frame(images, lab, rig, J0, depths=dep, constraints=cons,
                                     config=cfg).search
                rows.append((root.name, t, name, mpjpe(J0, gt[t]), mpjpe(res.joints, gt[t]),
                             res.n_evaluations, res.seconds, res.n_sweeps,
                             mpjpe(J0, gt[t], aligned=True), mpjpe(res.joints, gt[t], aligned=True)))
                r = rows[-1]
                print(f"{r[0]:<38} frame {t} {name:<7} MPJPE {r[3] * 100:5.1f} -> {r[4] * 100:5.1f} cm  "
                      f"aligned {r[8] * 100:4.1f} -> {r[9] * 100:4.1f} cm  "
                      f"{r[5]:5d} evaluations  {r[6]:5.1f} s  {r[7]} sweeps", flush=True)
        ds.close()
    print()
    print(f"{'start':<9} {'scene':<31} {'camera angles':>13} {'frames':>6} {'before cm':>9} {'after cm':>8} "
          f"{'change':>7} {'aligned before':>14} {'after':>6} {'evals/frame':>11} {'s/frame':>8}")
    per_scene = {}
    for name in STARTS:
        for sc in sorted({r[0] for r in rows}):
            rr = [r for r in rows if r[0] == sc and r[2] == name]
            if not rr:
                continue
            b, a = np.mean([r[3] for r in rr]), np.mean([r[4] for r in rr])
            per_scene[name, sc] = (b, a)
            ab, aa = np.mean([r[8] for r in rr]), np.mean([r[9] for r in rr])
            ang = "/".join(f"{x:.0f}" for x in angles[sc])
            print(f"{name:<9} {sc.replace('broadcast_', ''):<31} {ang:>13} {len(rr):>6} {b * 100:9.1f} "
                  f"{a * 100:8.1f} {change(b, a):>7} {ab * 100:14.1f} {aa * 100:6.1f} "
                  f"{np.mean([r[5] for r in rr]):11.0f} {np.mean([r[6] for r in rr]):8.1f}")
    print()
    groups = (("all scenes", lambda sc: True), ("2 cameras", lambda sc: "_2cams_" in sc),
              ("3 cameras", lambda sc: "_3cams_" in sc),
              ("2 cameras < 75 deg apart", lambda sc: "_2cams_" in sc and max(angles[sc]) < 75.0),
              ("2 cameras >= 75 deg apart", lambda sc: "_2cams_" in sc and max(angles[sc]) >= 75.0))
    for name in STARTS:
        for label, keep in groups:
            v = [ba for (n, sc), ba in per_scene.items() if n == name and keep(sc)]
            if not v:
                continue
            b, a = np.mean([x[0] for x in v]), np.mean([x[1] for x in v])
            verdict = ""
            if name.startswith("stage1") and label == "all scenes":
                verdict = (f"  (target >= {TARGET_REDUCTION:.0%} reduction: "
                           f"{'met' if a <= (1 - TARGET_REDUCTION) * b else 'NOT met'})")
            print(f"{name:<9} {label:<25} {len(v):>2} scenes: MPJPE {b * 100:.1f} -> {a * 100:.1f} cm "
                  f"({change(b, a)}){verdict}")
    e = np.array(eval_ms)
    print(f"one joint's score at 1280x720 on one core (median of 5 per joint and frame): mean {e.mean():.2f} ms, "
          f"max {e.max():.2f} ms over {e.size} joint-frames (target < {TARGET_EVAL_MS:.0f} ms: "
          f"{'met' if e.mean() < TARGET_EVAL_MS else 'NOT met'} on average, "
          f"{'met' if e.max() < TARGET_EVAL_MS else 'NOT met'} for every joint)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
