#!/usr/bin/env python3
"""Whole-scene free viewpoint on synthetic scenes with several players, judged against the truth.

Usage::

    python -m benchmarks.bench_players [--scenes 12] [--zoo-seed 101] [--frames 4] [--out out/bench_players]
                                       [--pictures docs/images]

Draws ``--scenes`` multi-player scenes (:func:`toolkit.synthetic.players.players_zoo`: 2-6 players,
broadcast and studio, 2-4 cameras, crossing paths), renders them, and runs
``recipes/free_viewpoint.py`` with its default options (every participant, the scene model of the
source videos) on the first ``--frames`` frames.  Stage 1 (``--stage1``): ``silhouettes`` (default;
the people found on the ground in the cameras' foreground, each through the silhouette database)
or ``detector`` (the built-in detector's keypoints, ``recipes/detect_keypoints.py``).  Nothing of
the truth reaches the pipeline.
Per scene, on the novel cameras against the rendered truth:

* ``frame``: whole-frame PSNR of the articulated rendering, and of the nearest source camera
  carried through the scene proxy (``nearest_source``);
* ``people``: per true person, PSNR over its region (+ 2 px) of the articulated rendering and
  of the better of standard billboards / visual hull; the margin;
* ``miou``: per true person, the part mIoU of the run's labels on the source cameras inside
  that person's true pixels (grown by 3 px, the other people's left out); ``miou_touching`` and
  ``miou_alone`` the same over the views where another person's pixels come within 4 px of the
  person's and over the others (overlaps told apart from the rest);
* ``mpjpe_cm``: per true person, the mean joint error of the estimated person matched to it
  (minimum-cost assignment on the hip centres over the frames run; NaN when nobody was matched
  within 1 m), so that a poor label is told apart from a poor pose.

Prints each scene and then the median and worst decile over the scenes; writes
``players.json``.  ``--rescore`` scores the runs already in ``--out`` again without running them.  With ``--pictures`` the two worst scenes' novel views (truth | ours |
nearest source) are written as ``players_worst_<k>.jpg``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
METHODS = ("articulated", "standard", "visual_hull")
#: Targets of the whole-scene issue.
TARGET_MIOU_MEDIAN, TARGET_MIOU_WORST = 0.80, 0.72
TARGET_PEOPLE_MARGIN_DB, TARGET_PEOPLE_SHARE = 0.5, 0.9


def worst_decile(values, higher_is_better: bool = True) -> float:
    """The value at the worst 10 % (10th percentile, or 90th when lower is better)."""
    v = np.asarray([x for x in values if np.isfinite(x)], float)
    if not len(v):
        return float("nan")
    return float(np.percentile(v, 10 if higher_is_better else 90))


def make_dataset(spec, out: Path, detect: bool) -> Path:
    """The scene rendered and, with ``detect``, its people detected into ``out/keypoints`` (both kept
    between runs)."""
    from toolkit.pipeline.detect_keypoints import DetectConfig, detect_videos
    from toolkit.synthetic import generate_scene

    done = out / ".complete"
    if not done.exists():
        shutil.rmtree(out, ignore_errors=True)
        generate_scene(spec, out, progress=False).close()
        done.write_text(spec.text)
    if detect and not (out / "keypoints" / ".complete").exists():
        detect_videos(out / "videos", out / "keypoints", DetectConfig(max_frames=spec.frames, progress=False),
                      log=lambda *_: None)
        (out / "keypoints" / ".complete").write_text("")
    return out


#: A person *touches* another in a view when at least this many of the other people's pixels lie within
#: :data:`TOUCH_PX` of its own (true instances).
TOUCH_MIN_PX, TOUCH_PX = 20, 4


def people_miou(ds, run: Path, frames: int, split: bool = False):
    """Per true person, the mean over source views and frames of its part mIoU (see the module docstring).

    With ``split``, also the same mean over the views where the person touches another person
    (:data:`TOUCH_PX`, :data:`TOUCH_MIN_PX`) and over the others: ``(all, touching, alone)``, each a
    list over the true people (NaN: no such view).
    """
    import cv2

    from toolkit.io.frames import frame_filename, read_png
    from toolkit.segmentation import part_iou

    kernel = np.ones((7, 7), np.uint8)
    touch_kernel = np.ones((2 * TOUCH_PX + 1, 2 * TOUCH_PX + 1), np.uint8)
    vals: dict = {}
    for cam in ds.camera_names:
        for t in range(frames):
            p = run / "parts" / cam / frame_filename(t)
            if not p.exists():
                continue
            pred, truth, inst = read_png(p), ds.gt_parts(cam, t), ds.gt_instances(cam, t)
            for k in range(ds.people_count):
                mine = inst == k + 1
                if mine.sum() < 50:
                    continue
                near = (cv2.dilate(mine.astype(np.uint8), kernel) > 0) & ((inst == 0) | mine)
                iou = part_iou(np.where(near, pred, 0), np.where(mine, truth, 0))
                if np.isfinite(iou).any():
                    grown = cv2.dilate(mine.astype(np.uint8), touch_kernel) > 0
                    touching = np.count_nonzero(grown & (inst > 0) & ~mine) >= TOUCH_MIN_PX
                    vals.setdefault(k, []).append((float(np.nanmean(iou)), touching))

    def mean(k, which=None):
        v = [x for x, touching in vals.get(k, []) if which is None or touching == which]
        return float(np.mean(v)) if v else float("nan")

    every = [mean(k) for k in range(ds.people_count)]
    if not split:
        return every
    return every, [mean(k, True) for k in range(ds.people_count)], [mean(k, False) for k in range(ds.people_count)]


#: An estimated person is matched to a true one when their hip centres are within this (m).
MATCH_RADIUS_M = 1.0


def people_mpjpe(truth: np.ndarray, estimated: np.ndarray) -> list:
    """Per true person, the mean joint error (cm) of the estimated person matched to it.

    Parameters
    ----------
    truth : ndarray of shape (P, T, 14, 3)
        The true people's joints in metres (``groundtruth/people.npz``).
    estimated : ndarray of shape (Q, T', 14, 3)
        The run's people (``people3d.npz``, or ``poses3d.npz`` as one person), NaN where missing;
        only the first ``min(T, T')`` frames are compared.

    Returns
    -------
    list of float
        ``P`` errors in centimetres, NaN for a true person nobody was matched to (hip centres
        more than :data:`MATCH_RADIUS_M` apart on average, or no estimate).
    """
    from scipy.optimize import linear_sum_assignment

    from toolkit.skeleton import SKELETON_14

    hips = [SKELETON_14.joint_names.index("l_hip"), SKELETON_14.joint_names.index("r_hip")]
    n = min(truth.shape[1], estimated.shape[1])
    g, e = truth[:, :n], estimated[:, :n]
    gh, eh = g[:, :, hips].mean(2), e[:, :, hips].mean(2)
    with np.errstate(invalid="ignore"):
        d = np.array([[np.nanmean(np.linalg.norm(eh[i] - gh[j], axis=-1)) if np.isfinite(eh[i]).any() else np.inf
                       for j in range(len(g))] for i in range(len(e))]).reshape(len(e), len(g))
    out = [float("nan")] * len(g)
    if d.size:
        rows, cols = linear_sum_assignment(np.where(np.isfinite(d), d, 1e6))
        for i, j in zip(rows, cols):
            if d[i, j] <= MATCH_RADIUS_M:
                out[j] = 100.0 * float(np.nanmean(np.linalg.norm(e[i] - g[j], axis=-1)))
    return out


def run_pose_error(dataset: Path, run: Path) -> list:
    """:func:`people_mpjpe` of a run's people against its dataset's true people."""
    truth = np.load(dataset / "groundtruth" / "people.npz")["joints"]
    if (run / "people3d.npz").exists():
        est = np.load(run / "people3d.npz")["joints"]
    else:
        est = np.load(run / "poses3d.npz")["joints"][None]
    return people_mpjpe(truth, est)


def score_run(dataset: Path, run: Path, frames: int, name: str, seconds: float) -> dict:
    """One scene's figures (see the module docstring) from a finished run of it."""
    from toolkit.io import Dataset

    m = json.loads((run / "metrics.json").read_text())
    with Dataset.open(dataset) as ds:
        miou, touching, alone = people_miou(ds, run, frames, split=True)
        P = ds.people_count
        info = json.loads((dataset / "groundtruth" / "scene_info.json").read_text())
    art = m["methods"].get("articulated", {})
    each = art.get("psnr_people") or [np.nan] * P
    best = [max((m["methods"].get(b, {}).get("psnr_people") or [np.nan] * P)[k] for b in METHODS[1:])
            for k in range(P)]
    return {"scene": name, "layout": info.get("layout"), "people": P, "followed": len(m.get("people", {}).get(
        "names", [])) or 1, "cameras": len(info.get("calibration_error_px", {})),
        "psnr_frame": art.get("psnr_frame", np.nan),
        "psnr_frame_nearest": m["methods"].get("nearest_source", {}).get("psnr_frame", np.nan),
        "psnr_people": each, "psnr_people_best_baseline": best,
        "people_margin": [e - b for e, b in zip(each, best)], "miou": miou, "miou_touching": touching,
        "miou_alone": alone,
        "mpjpe_cm": run_pose_error(dataset, run), "seconds": seconds}


def scene_name(spec) -> str:
    """The folder name of a zoo scene."""
    return spec.source.rsplit("/", 1)[-1].removesuffix(".toml")


def run_scene(spec, cache: Path, out: Path, frames: int, stage1: str = "silhouettes") -> dict:
    """Render one zoo scene (cached), run ``free_viewpoint.py`` on it with default options and score it."""
    from recipes import free_viewpoint

    name = scene_name(spec)
    t0 = time.perf_counter()
    dataset = make_dataset(spec, cache / name, stage1 == "detector")
    run = out / name
    shutil.rmtree(run, ignore_errors=True)
    how = ["--keypoint-format", "blazepose_33"] if stage1 == "detector" else ["--no-keypoints"]
    rc = free_viewpoint.main([str(dataset), "--out", str(run), "--max-frames", str(frames), "--no-recording",
                              "--quiet", *how])
    if rc != 0:
        raise RuntimeError(f"free_viewpoint.py on {dataset} returned {rc}")
    return score_run(dataset, run, frames, name, time.perf_counter() - t0)


def picture(rows: list, out: Path, runs: Path, cache: Path, pictures: Path, k: int = 2) -> None:
    import cv2

    from toolkit.io import Dataset
    from toolkit.io.frames import frame_filename, read_png

    worst = sorted(rows, key=lambda r: r["psnr_frame"] - r["psnr_frame_nearest"])[:k]
    pictures.mkdir(parents=True, exist_ok=True)
    for i, r in enumerate(worst):
        with Dataset.open(cache / r["scene"]) as ds:
            cam = ds.novel_rig[0].name
            imgs = [ds.novel_image(cam, 0), read_png(runs / r["scene"] / "novel" / cam / frame_filename(0)),
                    read_png(runs / r["scene"] / "baselines" / "nearest_source" / cam / frame_filename(0))]
        row = np.concatenate(imgs, 1)
        f = 1500 / row.shape[1]
        cv2.imwrite(str(pictures / f"players_worst_{i}.jpg"),
                    cv2.cvtColor(cv2.resize(row, None, fx=f, fy=f, interpolation=cv2.INTER_AREA), cv2.COLOR_RGB2BGR),
                    [cv2.IMWRITE_JPEG_QUALITY, 85])


#: A pose this close to the truth (mean joint error, cm) counts as right when the labels are judged apart.
POSE_RIGHT_CM = 10.0


def summarise_poses(rows: list) -> None:
    """Print the people's pose errors and the part mIoU of the people whose pose is right."""
    pairs = [(e, v) for r in rows for e, v in zip(r["mpjpe_cm"], r["miou"])]
    errors = [e for e, _ in pairs if np.isfinite(e)]
    right = [v for e, v in pairs if np.isfinite(e) and e <= POSE_RIGHT_CM and np.isfinite(v)]
    wrong = [v for e, v in pairs if not (np.isfinite(e) and e <= POSE_RIGHT_CM) and np.isfinite(v)]
    print(f"per-person pose error: {len(errors)} of {len(pairs)} players matched, median {np.median(errors):.1f} cm, "
          f"worst decile {worst_decile(errors, higher_is_better=False):.1f}; within {POSE_RIGHT_CM:.0f} cm: "
          f"{len(right)}")
    if right:
        print(f"part mIoU of the players within {POSE_RIGHT_CM:.0f} cm: median {np.median(right):.3f}, worst decile "
              f"{worst_decile(right):.3f}; of the others: median {np.median(wrong) if wrong else float('nan'):.3f}")
    # the same players' views apart: where another person touches them and where nobody does
    apart = {w: [v for r in rows for e, v in zip(r["mpjpe_cm"], r.get(f"miou_{w}", [])) if np.isfinite(e)
                 and e <= POSE_RIGHT_CM and np.isfinite(v)] for w in ("touching", "alone")}
    if apart["touching"] and apart["alone"]:
        print(f"  their views where another person touches them: median {np.median(apart['touching']):.3f} "
              f"({len(apart['touching'])} players); where nobody does: median {np.median(apart['alone']):.3f} "
              f"({len(apart['alone'])})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=12)
    ap.add_argument("--zoo-seed", type=int, default=101, help="which scenes are drawn")
    ap.add_argument("--frames", type=int, default=4, help="frames per scene rendered and run")
    ap.add_argument("--out", type=Path, default=REPO / "out" / "bench_players")
    ap.add_argument("--pictures", type=Path, default=None)
    ap.add_argument("--stage1", choices=("silhouettes", "detector"), default="silhouettes",
                    help="people from the cameras' foreground (default) or from the built-in detector")
    ap.add_argument("--rescore", action="store_true",
                    help="score the runs already in --out again (same --scenes, --zoo-seed, --frames) without running")
    args = ap.parse_args(argv)

    from toolkit.synthetic.players import players_zoo

    specs = players_zoo(args.zoo_seed, args.scenes, frames=args.frames)
    cache, runs = args.out / "scenes", args.out / f"runs_{args.stage1}"
    rows = []
    for spec in specs:
        try:
            if args.rescore:
                name = scene_name(spec)
                r = score_run(cache / name, runs / name, args.frames, name, float("nan"))
            else:
                r = run_scene(spec, cache, runs, args.frames, args.stage1)
        except Exception as e:  # one scene's failure is reported, the others go on
            print(f"[{spec.source}] failed: {type(e).__name__}: {e}")
            continue
        rows.append(r)
        print(f"[{r['scene']}] {r['layout']}, {r['people']} players ({r['followed']} followed), {r['cameras']} cameras: "
              f"whole frame {r['psnr_frame']:.2f} dB (nearest source {r['psnr_frame_nearest']:.2f}); per person "
              + ", ".join(f"{e:.1f} ({d:+.1f})" for e, d in zip(r["psnr_people"], r["people_margin"]))
              + " dB; mIoU " + ", ".join(f"{v:.2f}" for v in r["miou"])
              + "; pose error " + ", ".join(f"{v:.0f}" for v in r["mpjpe_cm"]) + f" cm  ({r['seconds']:.0f} s)",
              flush=True)
        (args.out / "players.json").write_text(json.dumps(rows, indent=2, allow_nan=True))
    if not rows:
        return 1
    frame_gain = [r["psnr_frame"] - r["psnr_frame_nearest"] for r in rows]
    margins = [d for r in rows for d in r["people_margin"] if np.isfinite(d)]
    mious = [v for r in rows for v in r["miou"] if np.isfinite(v)]
    scene_ok = [np.mean([d >= TARGET_PEOPLE_MARGIN_DB for d in r["people_margin"] if np.isfinite(d)] or [0.0])
                for r in rows]
    print(f"\n{len(rows)} scenes, {sum(r['people'] for r in rows)} players, {args.frames} frames each "
          f"(zoo seed {args.zoo_seed})")
    print(f"whole frame: median {np.median([r['psnr_frame'] for r in rows]):.2f} dB, worst decile "
          f"{worst_decile([r['psnr_frame'] for r in rows]):.2f}; over the nearest source: median "
          f"{np.median(frame_gain):+.2f} dB, worst decile {worst_decile(frame_gain):+.2f}")
    print(f"per person over the better baseline: median {np.median(margins):+.2f} dB, worst decile "
          f"{worst_decile(margins):+.2f}; scenes where every person gains >= {TARGET_PEOPLE_MARGIN_DB} dB: "
          f"{np.mean([s == 1.0 for s in scene_ok]):.0%} (target {TARGET_PEOPLE_SHARE:.0%})")
    print(f"per-person part mIoU: median {np.median(mious):.3f} (target {TARGET_MIOU_MEDIAN}), worst decile "
          f"{worst_decile(mious):.3f} (target {TARGET_MIOU_WORST})")
    summarise_poses(rows)
    if args.pictures is not None:
        picture(rows, args.out, runs, cache, args.pictures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
