#!/usr/bin/env python3
"""Stage-1 benchmark: silhouettes -> database candidates -> multi-view selection with offsets.

Usage::

    python benchmarks/bench_stage1.py            # 4 seeded broadcast scenes x 16 frames
    python benchmarks/bench_stage1.py --quick    # 1 scene x 6 frames

Scenes are made by the scene generator (``toolkit.synthetic``): broadcast
layout, three cameras at 1280x720, 8 px of calibration error, a different
motion per seed; they are rendered once into ``--scenes`` and reused.  Each
scene is evaluated in six configurations: its first two cameras or all
three, each with the true calibration (0 px), the measured one (8 px
error), and the measured one refined on the pitch's field lines
(``toolkit.calibration``, from the clean plates and the dataset's field
model) before stage 1.  Per configuration, against ground truth:

* silhouette IoU of the foreground extraction (background subtraction, the
  background learned from a clean plate: the empty scene rendered per camera);
* 2D PCK@0.1 (a joint within 0.1 of the true silhouette's box height) of the
  best database candidate (rank 1), of the best of the k candidates, and of
  the pose chosen by the multi-view selection;
* 3D MPJPE (mm) after multi-view selection, absolute and with the pelvis
  aligned (root-relative, the Human3.6M protocol-1 convention);
* offsets: the injected per-view image shift of the subject (GT joints
  projected through the measured minus the true camera) against the
  recovered offsets, raw and with the gauge removed (a 3D translation of the
  body shifts every view alike, so offsets are only defined up to it; see
  ``toolkit.multiview.offsets_modulo_gauge``);
* left/right swap rate: chosen 2D poses (per view, among the views where
  swapping left and right moves the joints by more than the PCK threshold)
  and 3D poses closer to the left/right-flipped ground truth than to the
  ground truth;
* time per frame of each stage.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.calibration import calibration_error_px, refine_dataset
from toolkit.cameras import Rig
from toolkit.foreground import mask_iou
from toolkit.io import Dataset
from toolkit.multiview import offsets_modulo_gauge
from toolkit.silhouettes import SilhouetteDatabase, Stage1Config, default_database
from toolkit.silhouettes.pipeline import FRAME_OK, estimate_dataset
from toolkit.skeleton import SKELETON_14
from toolkit.synthetic import generate_scene, parse_spec

#: Seeds and motions of the benchmark scenes.
SCENES = ((1, "walk"), (2, "run"), (3, "kick"), (4, "wave"))
FRAMES = 16
QUICK_FRAMES = 6
CALIBRATION_ERROR_PX = 8.0
#: PCK threshold: fraction of the ground-truth silhouette's bounding-box height.
PCK_FRACTION = 0.1
#: Joints whose left/right labels can swap (all but head and neck).
LATERAL = np.array([i for i, n in enumerate(SKELETON_14.joint_names) if n[:2] in ("l_", "r_")])
FLIP = SKELETON_14.flip_permutation
PELVIS = [SKELETON_14.index("l_hip"), SKELETON_14.index("r_hip")]

SPEC = """# scene format 2: field lines painted from the field model
name = "stage1_seed{seed}"
seed = {seed}
frames = {frames}
fps = 25
[subject]
height_m = {height}
motion = "{motion}"
[cameras]
count = 3
layout = "broadcast"
resolution = [1280, 720]
calibration_error_px = {error}
[novel]
count = 0
"""


def scene(root: Path, seed: int, motion: str, frames: int) -> tuple[Dataset, dict]:
    """The benchmark scene of a seed, generated on first use, and its clean plates per camera."""
    text = SPEC.format(seed=seed, frames=frames, height=1.70 + 0.03 * seed, motion=motion, error=CALIBRATION_ERROR_PX)
    out = root / f"seed{seed}_{motion}_{frames}f"
    spec_copy = out / "scene.toml"
    spec = parse_spec(text, str(out))
    if not (spec_copy.is_file() and spec_copy.read_text() == text):
        print(f"generating {out} ...", flush=True)
        generate_scene(spec, out, progress=False).close()
    ds = Dataset.open(out)
    plates = {cam.name: [ds.background(cam.name)] for cam in ds.gt_rig}  # the generator's clean plates
    return ds, plates


@dataclass
class Tally:
    """Per-configuration accumulators."""

    iou: list = field(default_factory=list)
    pck_top1: list = field(default_factory=list)
    pck_bestk: list = field(default_factory=list)
    pck_chosen: list = field(default_factory=list)
    mpjpe: list = field(default_factory=list)
    mpjpe_root: list = field(default_factory=list)
    offset_raw: list = field(default_factory=list)
    offset_gauge: list = field(default_factory=list)
    injected: list = field(default_factory=list)
    swap2d: list = field(default_factory=list)
    swap3d: list = field(default_factory=list)
    frames: int = 0
    estimated: int = 0
    t_foreground: list = field(default_factory=list)
    t_query: list = field(default_factory=list)
    t_multiview: list = field(default_factory=list)


def pck(pred: np.ndarray, truth: np.ndarray, height: float) -> float:
    return float(np.mean(np.linalg.norm(pred - truth, axis=-1) < PCK_FRACTION * height))


def closer_to_flipped(pred: np.ndarray, truth: np.ndarray) -> bool:
    d = np.linalg.norm(pred[LATERAL] - truth[LATERAL], axis=-1).mean()
    f = np.linalg.norm(pred[LATERAL] - truth[FLIP][LATERAL], axis=-1).mean()
    return bool(f < d)


def flip_is_visible(truth2d: np.ndarray, height: float) -> bool:
    """Whether swapping left and right moves the 2D joints by more than the PCK threshold on average
    (in side views the two sides overlap and a "swap" is not defined)."""
    return bool(np.linalg.norm(truth2d[LATERAL] - truth2d[FLIP][LATERAL], axis=-1).mean() > PCK_FRACTION * height)


def evaluate(ds: Dataset, db: SilhouetteDatabase, rig: Rig, true_rig: Rig, plates: dict, tally: Tally,
             config: Stage1Config | None = None) -> None:
    J = ds.gt_joints3d()
    for est, masks in estimate_dataset(ds, db, config, rig=rig, backgrounds=plates, log_images=False):
        t = est.frame
        tally.frames += 1
        tally.t_foreground.append(est.timings["foreground"])
        tally.t_query.append(est.timings["query"])
        tally.t_multiview.append(est.timings["multiview"])
        truth3 = J[t]
        for v, (cam, true_cam) in enumerate(zip(rig, true_rig)):
            gt_mask = ds.gt_mask(cam.name, t)
            if masks[v] is not None:
                tally.iou.append(mask_iou(masks[v], gt_mask))
            rows = np.flatnonzero(gt_mask.any(axis=1))
            if rows.size == 0:
                continue
            height = rows[-1] - rows[0] + 1
            truth2 = true_cam.project(truth3)
            cand = est.candidates_px[v]
            if np.isfinite(cand[0]).all():
                tally.pck_top1.append(pck(cand[0], truth2, height))
                tally.pck_bestk.append(max(pck(c, truth2, height) for c in cand if np.isfinite(c).all()))
            if np.isfinite(est.poses2d[v]).all():
                tally.pck_chosen.append(pck(est.poses2d[v], truth2, height))
                if flip_is_visible(truth2, height):
                    tally.swap2d.append(closer_to_flipped(est.poses2d[v], truth2))
        if est.state != FRAME_OK or not np.isfinite(est.joints3d).all():
            continue
        tally.estimated += 1
        err = np.linalg.norm(est.joints3d - truth3, axis=-1)
        tally.mpjpe.append(err.mean())
        shift = est.joints3d[PELVIS].mean(0) - truth3[PELVIS].mean(0)
        tally.mpjpe_root.append(np.linalg.norm(est.joints3d - shift - truth3, axis=-1).mean())
        tally.swap3d.append(closer_to_flipped(est.joints3d, truth3))
        injected = np.stack([(m.project(truth3) - tc.project(truth3)).mean(0) for m, tc in zip(rig, true_rig)])
        used = np.isfinite(est.offsets).all(-1)
        tally.injected.extend(np.linalg.norm(injected[used], axis=-1))
        tally.offset_raw.extend(np.linalg.norm(est.offsets[used] - injected[used], axis=-1))
        g = offsets_modulo_gauge(np.where(used[:, None], est.offsets, 0.0), injected, rig, truth3.mean(0), used)
        tally.offset_gauge.extend(np.linalg.norm(g[used], axis=-1))


def fmt(values, scale=1.0, digits=1, stat=np.mean) -> str:
    v = np.asarray(values, float)
    return "-" if v.size == 0 else f"{stat(v) * scale:.{digits}f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--quick", action="store_true", help=f"one scene of {QUICK_FRAMES} frames")
    ap.add_argument("--scenes", type=Path, default=Path("out/bench_stage1/scenes"),
                    help="folder the generated scenes are kept in (reused)")
    ap.add_argument("--db", type=Path, default=None, help="silhouette database (default: the cached default)")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures as JSON")
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    if args.db is not None:
        db = SilhouetteDatabase.load(args.db)
        db_path = args.db
    else:
        db, db_path = default_database()
    print(f"database: {db_path} ({len(db)} entries, loaded/built in {time.perf_counter() - t0:.1f} s)")
    scenes = SCENES[:1] if args.quick else SCENES
    frames = QUICK_FRAMES if args.quick else FRAMES
    # (cameras, calibration error, refined on the field lines before stage 1)
    configs = [(2, 0.0, False), (2, CALIBRATION_ERROR_PX, False), (2, CALIBRATION_ERROR_PX, True),
               (3, 0.0, False), (3, CALIBRATION_ERROR_PX, False), (3, CALIBRATION_ERROR_PX, True)]
    tallies = {c: Tally() for c in configs}
    calib_px: dict = defaultdict(list)
    t_refine: list = []
    for seed, motion in scenes:
        ds, plates = scene(args.scenes, seed, motion, frames)
        measured, truth = ds.rig, ds.gt_rig
        t1 = time.perf_counter()
        refined, results = refine_dataset(ds)  # on the clean plates and the field model, as the recipes do
        t_refine.append((time.perf_counter() - t1) / len(measured))
        J = ds.gt_joints3d()
        for c in measured:
            calib_px[c.name, False].append(calibration_error_px(c, truth[c.name], J))
            calib_px[c.name, True].append(calibration_error_px(refined[c.name], truth[c.name], J))
        for n_cams, error, lines in configs:
            names = measured.names[:n_cams]
            true_rig = Rig(tuple(truth[n] for n in names))
            rig = true_rig if error == 0 else Rig(tuple((refined if lines else measured)[n] for n in names))
            # as the recipes do: cameras whose field-line refinement was accepted on this scene get
            # the tight offset prior (for the 0 px rows, standing in for refining exact cameras)
            config = Stage1Config()
            if error == 0 or lines:
                config = config.with_refined_cameras(n for n in names if results[n].accepted)
            evaluate(ds, db, rig, true_rig, plates, tallies[(n_cams, error, lines)], config)
        ds.close()

    header = ("cams", "calibration", "frames", "3D ok", "IoU", "PCK top1", "PCK best-k", "PCK chosen", "MPJPE mm",
              "MPJPE med", "root-rel mm", "inj. px", "offset err px", "mod gauge px", "swap 2D %", "swap 3D %",
              "fg ms", "query ms", "mview ms")
    rows = []
    figures = {}
    for (n_cams, error, lines), t in tallies.items():
        label = f"{error:g} px" + (" + lines" if lines else "")
        row = (str(n_cams), label, str(t.frames), str(t.estimated), fmt(t.iou, digits=3),
               fmt(t.pck_top1, 100, 0), fmt(t.pck_bestk, 100, 0), fmt(t.pck_chosen, 100, 0), fmt(t.mpjpe, 1000, 0),
               fmt(t.mpjpe, 1000, 0, np.median), fmt(t.mpjpe_root, 1000, 0), fmt(t.injected), fmt(t.offset_raw),
               fmt(t.offset_gauge), fmt(t.swap2d, 100, 0), fmt(t.swap3d, 100, 0),
               fmt(np.asarray(t.t_foreground) / n_cams, 1000, 0), fmt(np.asarray(t.t_query) / n_cams, 1000, 1),
               fmt(t.t_multiview, 1000, 0))
        rows.append(row)
        figures[f"{n_cams}cams_{error:g}px{'_lines' if lines else ''}"] = dict(zip(header, row))
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    line = "  ".join(h.rjust(w) for h, w in zip(header, widths))
    print(f"\nstage 1 over {len(scenes)} broadcast scene(s) x {frames} frames "
          f"(motions: {', '.join(m for _, m in scenes)}), k = 3, database of {len(db)} entries")
    print(line)
    print("-" * len(line))
    for r in rows:
        print("  ".join(v.rjust(w) for v, w in zip(r, widths)))
    before = [v for (c, r), vals in calib_px.items() if not r for v in vals]
    after = [v for (c, r), vals in calib_px.items() if r for v in vals]
    print(f"\nfield-line refinement: calibration error at the joints {fmt(before, digits=2)} px -> "
          f"{fmt(after, digits=2)} px (mean over cameras; worst {fmt(after, digits=2, stat=np.max)} px), "
          f"{fmt(t_refine, 1000, 0)} ms per camera")
    figures["field_line_refinement"] = {"calibration_px_before": fmt(before, digits=2),
                                        "calibration_px_after": fmt(after, digits=2),
                                        "calibration_px_after_worst": fmt(after, digits=2, stat=np.max),
                                        "ms_per_camera": fmt(t_refine, 1000, 0)}
    print("\nIoU and PCK per view and frame; MPJPE per estimated frame (mean, median); offsets per view and frame")
    print("(injected = |true image shift|); swap 2D per view, swap 3D per frame; times per frame and camera")
    print("(foreground, query) or per frame (multi-view selection).")
    print(f"total {time.perf_counter() - t0:.0f} s")
    if args.json is not None:
        args.json.write_text(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
