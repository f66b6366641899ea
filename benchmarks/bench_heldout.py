#!/usr/bin/env python3
"""Leave one real camera out: free-viewpoint video of the Pose2Sim demo judged against what the camera filmed.

Usage::

    python benchmarks/bench_heldout.py [--realdata DIR] [--trial balancing|static|multiperson] [--frames N] [--scale S]
                                       [--cameras cam_01 ...] [--out OUT] [--pictures docs/images] [--orbit]
                                       [--workers N]

Imports the demo's trial (``recipes/import_pose2sim.py``: videos, OpenPose keypoints,
the lab's calibration), then for each camera runs ``recipes/free_viewpoint.py DATASET
--hold-out CAM`` with default options on the first ``--frames`` frames: stage 1
triangulates the other three cameras' keypoints, silhouettes are seeded by them (no
clean plate exists), and the held-out view is rendered from the other three with
articulated billboards, standard billboards and the visual hull.  Prints per camera and
method the PSNR over the person's region (its keypoint-seeded mask + 2 px; docs:
``toolkit/pipeline/views.py``), SSIM in its box and coverage, the articulated margin
over the better baseline, the wall seconds per frame of each stage, and writes
``heldout.json``.  With ``--pictures`` it saves, per held-out camera, real frame |
articulated | standard | visual hull cropped to the person, the whole frames (real |
ours | the nearest source camera carried through the scene proxy), and (``--orbit``) a
camera path around the scene from a run with every camera.  ``multiperson``
(``pose2sim_multiperson``: videos and a Qualisys calibration only) is detected by the
built-in detector on import; every participant is drawn and judged in its own region.

The demo lives in ``../shared/realdata/pose2sim_demo`` (or ``$TOOLKIT_REALDATA``);
without it the benchmark prints a message and exits 0.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

TRIALS = {"balancing": Path("pose2sim_demo/S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial"),
          "static": Path("pose2sim_demo/S00_P00_SingleParticipant/S00_P00_T00_StaticTrial"),
          "multiperson": Path("pose2sim_multiperson")}  # videos and a Qualisys calibration only: detected
#: Frames of the resampled copy the scene model learns the backgrounds from (the runs use --frames of them).
SCENE_FRAMES = 30
METHODS = ("articulated", "standard", "visual_hull")
#: Frames of the run with every camera whose orbit path is pictured (one orbit position per frame).
ORBIT_FRAMES = 8


def load_recipe(name: str):
    """The module ``recipes.<name>``."""
    return importlib.import_module(f"recipes.{name}")


def crop_row(images: list, region: np.ndarray, margin: float = 0.15, height: int = 480) -> np.ndarray:
    """Images side by side, cropped to the region's box (grown by ``margin``), scaled to ``height`` px."""
    import cv2

    ys, xs = np.nonzero(region)
    H, W = region.shape
    if ys.size == 0:
        y0, y1, x0, x1 = 0, H, 0, W
    else:
        h = ys.max() - ys.min() + 1  # the margin scales with the person's height on both axes
        y0, y1 = max(0, int(ys.min() - margin * h)), min(H, int(ys.max() + margin * h) + 1)
        x0, x1 = max(0, int(xs.min() - margin * h)), min(W, int(xs.max() + margin * h) + 1)
    tiles = []
    for img in images:
        c = np.asarray(img)[y0:y1, x0:x1]
        s = height / c.shape[0]
        tiles.append(cv2.resize(c, (max(1, int(round(c.shape[1] * s))), height), interpolation=cv2.INTER_AREA))
        tiles.append(np.full((height, 6, 3), 255, np.uint8))
    return np.concatenate(tiles[:-1], 1)


#: Stages of ``metrics.json`` ``seconds_per_frame`` printed per held-out run (wall seconds per frame).
SPEED_STAGES = ("stage1", "segmentation", "optimize", "billboards", "standard_billboards", "visual_hull", "views",
                "paths", "other", "total")


def print_speed(table: dict) -> None:
    """Per held-out run the wall seconds per frame of each stage (``metrics.json`` ``seconds_per_frame``;
    ``total`` is everything after stage 1, ``stage1`` the keypoints and seeded silhouettes)."""
    print("\nseconds per frame (wall) per stage: " + " ".join(f"{k:>9s}" for k in SPEED_STAGES) + "  total+stage1")
    for cam, r in table.items():
        sp = r.get("seconds_per_frame", {})
        whole = sp.get("total", np.nan) + sp.get("stage1", np.nan)
        print(f"{cam:36s}" + " ".join(f"{sp.get(k, np.nan):9.2f}" for k in SPEED_STAGES) + f"  {whole:11.2f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--realdata", type=Path, default=Path(os.environ.get("TOOLKIT_REALDATA",
                                                                         REPO.parent / "shared" / "realdata")))
    ap.add_argument("--trial", choices=tuple(TRIALS), default="balancing")
    ap.add_argument("--frames", type=int, default=4, help="frames per held-out run (default 4)")
    ap.add_argument("--scale", type=float, default=0.5,
                    help="image scale of the runs (default 0.5: 540x960; the person is ~600 px tall there); 1 = the "
                         "videos as they are (stages 2-3 still work with the person at most 300 px tall: "
                         "toolkit/pipeline/working_scale.py)")
    ap.add_argument("--cameras", nargs="*", default=None, help="cameras to hold out (default: each in turn)")
    ap.add_argument("--out", type=Path, default=REPO / "out" / "bench_heldout")
    ap.add_argument("--pictures", type=Path, default=None, help="write the pictures into this folder")
    ap.add_argument("--orbit", action="store_true", help="also run every camera and picture the orbit path")
    ap.add_argument("--reuse-runs", action="store_true", help="keep finished runs (resume)")
    ap.add_argument("--workers", default=None,
                    help="free_viewpoint.py --workers of each run (default: the recipe's); 1 for seconds per frame "
                         "on one worker")
    args = ap.parse_args(argv)

    trial = args.realdata / TRIALS[args.trial]
    if not trial.is_dir():
        print(f"no Pose2Sim demo at {trial}: nothing to measure (give --realdata)")
        return 0
    from toolkit.io import Dataset
    from toolkit.io.frames import frame_filename, read_png

    dataset = args.out / f"dataset_{args.trial}"
    if not (dataset / "import.json").exists():
        rc = load_recipe("import_pose2sim").main([str(trial), "--out", str(dataset)])
        if rc != 0:
            return rc
    ds = Dataset.open(dataset)
    if args.scale != 1:
        from toolkit.io.resample import resample_dataset

        kept = max(args.frames, SCENE_FRAMES)
        scaled = args.out / f"dataset_{args.trial}_x{args.scale:g}_{kept}f"
        if not (scaled / "calibration.toml").exists():
            resample_dataset(ds, scaled, args.scale, max_frames=kept).close()
        ds.close()
        dataset = scaled
        ds = Dataset.open(dataset)
    cams = args.cameras or ds.camera_names
    fvv = load_recipe("free_viewpoint")
    table: dict = {}
    for cam in cams:
        out = args.out / f"{args.trial}_holdout_{cam}"
        t0 = time.perf_counter()
        argv_run = [str(dataset), "--out", str(out), "--hold-out", cam, "--max-frames", str(args.frames),
                    "--no-recording", "--quiet"] + ([] if args.workers is None else ["--workers", str(args.workers)])
        if not args.reuse_runs:
            argv_run.append("--replace-stale")
            if out.exists():
                import shutil

                shutil.rmtree(out)
        rc = fvv.main(argv_run)
        if rc != 0:
            print(f"{cam}: free_viewpoint.py failed (exit {rc})")
            continue
        m = json.loads((out / "metrics.json").read_text())
        table[cam] = {"methods": m["heldout"]["methods"], "region": m["heldout"]["region"],
                      "seconds": time.perf_counter() - t0, "optimize": m.get("optimize", {}),
                      "seconds_per_frame": m.get("seconds_per_frame", {})}
        if args.pictures is not None:
            import cv2

            t = 0
            region = read_png(out / "heldout_region" / cam / frame_filename(t)) > 0
            imgs = [ds.frame(cam, t), read_png(out / "heldout" / cam / frame_filename(t)),
                    read_png(out / "baselines" / "standard" / cam / frame_filename(t)),
                    read_png(out / "baselines" / "visual_hull" / cam / frame_filename(t))]
            args.pictures.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(args.pictures / f"heldout_{args.trial}_{cam}.jpg"),
                        cv2.cvtColor(crop_row(imgs, region), cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85])
            whole = [imgs[0], imgs[1], read_png(out / "baselines" / "nearest_source" / cam / frame_filename(t))]
            row = np.concatenate(whole, 1)
            f = 1500 / row.shape[1]
            cv2.imwrite(str(args.pictures / f"heldout_{args.trial}_{cam}_frame.jpg"),
                        cv2.cvtColor(cv2.resize(row, None, fx=f, fy=f, interpolation=cv2.INTER_AREA),
                                     cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85])
    if args.orbit and args.pictures is not None:
        out = args.out / f"{args.trial}_all"
        n = ORBIT_FRAMES
        orbit_ds = dataset  # the copy of SCENE_FRAMES frames or more: the people tracked and the scene learnt on all
        argv_run = [str(orbit_ds), "--out", str(out), "--max-frames", str(n), "--no-recording", "--quiet"]
        rc = fvv.main(argv_run + ([] if args.reuse_runs else ["--replace-stale"]))
        if rc == 0:
            import cv2

            tiles = [read_png(out / "paths" / "orbit" / frame_filename(t)) for t in range(n)]
            sheet = np.concatenate([np.concatenate(tiles[i:i + 4], 1) for i in range(0, 4 * (n // 4), 4)], 0)
            s = 1400 / sheet.shape[1]
            sheet = cv2.resize(sheet, (1400, int(sheet.shape[0] * s)), interpolation=cv2.INTER_AREA)
            cv2.imwrite(str(args.pictures / f"heldout_{args.trial}_orbit.jpg"),
                        cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85])

    print(f"\nleave one camera out, Pose2Sim demo {args.trial} trial, {args.frames} frames per run at "
          f"{ds.rig[0].size[0]}x{ds.rig[0].size[1]} "
          "(PSNR over the person's region + 2 px / SSIM in its box / coverage)")
    print(f"{'camera':8s} " + "  ".join(f"{m:>24s}" for m in METHODS) + "   margin   region")
    margins = []
    for cam, r in table.items():
        row = []
        for m in METHODS:
            s = r["methods"].get(m, {})
            row.append(f"{s.get('psnr_subject', float('nan')):6.2f} dB {s.get('ssim', float('nan')):.3f} "
                       f"{s.get('coverage', float('nan')):.2f}")
        best = max(r["methods"].get(m, {}).get("psnr_subject", -np.inf) for m in METHODS[1:])
        margin = r["methods"].get("articulated", {}).get("psnr_subject", np.nan) - best
        margins.append(margin)
        print(f"{cam:8s} " + "  ".join(f"{x:>24s}" for x in row) + f"   {margin:+.2f} dB  {r['region']}")
    if margins:
        print(f"articulated over the better baseline: median {np.nanmedian(margins):+.2f} dB, "
              f"worst {np.nanmin(margins):+.2f} dB (target >= +1 dB on every camera)")
    print("\nwhole frames (the people over the scene model of the other cameras' videos) against the nearest "
          "source camera carried through the scene proxy; each person's region where several are followed")
    frame_margins, person_margins = [], []
    for cam, r in table.items():
        a, n = r["methods"].get("articulated", {}), r["methods"].get("nearest_source", {})
        fm = a.get("psnr_frame", np.nan) - n.get("psnr_frame", np.nan)
        frame_margins.append(fm)
        line = (f"{cam:8s} whole frame {a.get('psnr_frame', np.nan):6.2f} dB, nearest source "
                f"{n.get('psnr_frame', np.nan):6.2f} dB ({fm:+.2f})")
        each = a.get("psnr_people")
        if each:
            best = [max(r["methods"].get(m, {}).get("psnr_people", [np.nan] * len(each))[k] for m in METHODS[1:])
                    for k in range(len(each))]
            person_margins += [e - b for e, b in zip(each, best)]
            line += "; per person " + ", ".join(f"{e:.2f} dB ({e - b:+.2f} over the better baseline)"
                                                for e, b in zip(each, best))
        print(line)
    if frame_margins:
        print(f"whole frame over the nearest source: median {np.nanmedian(frame_margins):+.2f} dB, worst "
              f"{np.nanmin(frame_margins):+.2f} dB (target >= +1 dB on every camera)")
    if person_margins:
        print(f"each person over the better baseline: median {np.nanmedian(person_margins):+.2f} dB, worst "
              f"{np.nanmin(person_margins):+.2f} dB (target >= +0.5 dB)")
    print_speed(table)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"heldout_{args.trial}.json").write_text(json.dumps(table, indent=2, allow_nan=True))
    ds.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
