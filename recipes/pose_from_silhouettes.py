#!/usr/bin/env python3
"""Stage 1 of the articulated-billboard pipeline: 2D poses from silhouettes, 3D joints with offsets.

Usage::

    python recipes/pose_from_silhouettes.py out/default --out out/default_stage1
    python recipes/pose_from_silhouettes.py DATASET --out OUT --edits edits.toml   # after corrections

Per frame: foreground silhouettes per camera -> the k best database
silhouettes per view (E_S, with the temporal term after the first frame) ->
multi-view selection with per-view 2D offsets -> 2D poses, 3D joints,
offsets.  Writes into OUT:

  poses2d.npz         one (T, 14, 2) array per camera (image pixels), view_state, bbox,
                      candidates, candidate_errors, candidate_index, edited, cameras
  poses3d.npz         joints (T, 14, 3) metres, names (14,), state (T,), cost (T,)
  offsets.npz         offsets (T, n_cams, 2) pixels, cameras, state
  recording.rrd       every intermediate, for the rerun viewer
  edits_template.toml the estimated joints of every frame in the edits format

Frames without an estimate are NaN and their ``state`` says why (see
docs/stage1_silhouettes.md).  Results are written even when the run stops
early.  Without --db, a default silhouette database is built once (about
30 s) into ~/.cache/billboard-toolkit (or $TOOLKIT_CACHE) and reused.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from toolkit.errors import InputError

#: Frames between two writes of the partial results.
CHECKPOINT_FRAMES = 50


def _write(out: Path, arrays: dict) -> None:
    from toolkit.io import atomic_save_npz

    for name in ("poses2d", "poses3d", "offsets"):
        atomic_save_npz(out / f"{name}.npz", **arrays[name])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="dataset folder (docs/dataset_layout.md)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--db", type=Path, default=None,
                    help="silhouette database .npz (built there if missing; default: the cached default database)")
    ap.add_argument("--k", type=int, default=None, help="candidates per view (default 3, source 000 §2.1)")
    ap.add_argument("--metric", choices=("l1", "hausdorff"), default="l1",
                    help="silhouette matching error: cell differences (eq. 1) or contour Hausdorff distance")
    ap.add_argument("--flow-weight", type=float, default=0.0,
                    help="weight of the optical-flow term (needs a database built with --flow; default 0: off)")
    ap.add_argument("--edits", type=Path, default=None, help="joint corrections (.toml or .json, see docs)")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--foreground", choices=("median", "mog2", "knn", "chroma"), default="median",
                    help="background model, or chroma keying (green screen)")
    ap.add_argument("--plates", type=Path, default=None,
                    help="folder of clean plates <camera>.png (the empty scene) to learn the backgrounds from "
                         "(default: each camera's video)")
    ap.add_argument("--no-check-sizes", action="store_true",
                    help="accept videos whose size differs from the calibration (docs/dataset_layout.md)")
    ap.add_argument("--keep-calibration", action="store_true",
                    help="do not refine the cameras on the dataset's field lines (field_model.json)")
    ap.add_argument("--no-images", action="store_true", help="do not log the camera images (smaller recording)")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)

    from dataclasses import replace

    from tqdm import tqdm

    from toolkit.foreground import BackgroundConfig, ForegroundConfig
    import numpy as np

    from toolkit.calibration import cameras_for_run, refined_cameras
    from toolkit.io import Dataset, atomic_write_text, read_png
    from toolkit.silhouettes import (
        QueryConfig,
        SilhouetteDatabase,
        Stage1Config,
        default_database,
        default_database_path,
        edits_template,
        read_edits,
        stack_estimates,
    )
    from toolkit.silhouettes.pipeline import FRAME_OK, FRAME_STATES, estimate_dataset
    from toolkit.skeleton import SKELETON_14

    try:
        ds = Dataset.open(args.dataset, check_sizes=not args.no_check_sizes)
        names = ds.camera_names
        query = QueryConfig(metric=args.metric, flow_weight=args.flow_weight)
        if args.k is not None:
            query = replace(query, k=args.k)
        config = Stage1Config(query=query)
        edits = read_edits(args.edits, names, ds.n_frames) if args.edits is not None else None
        db_path = args.db if args.db is not None else default_database_path()
        if db_path.exists():
            db = SilhouetteDatabase.load(db_path)
            print(f"silhouette database: {db_path} ({len(db)} entries)")
        else:
            print(f"building the silhouette database into {db_path} (once, about a minute) ...", flush=True)
            t0 = time.perf_counter()
            db, db_path = default_database(db_path)
            print(f"silhouette database: {db_path} ({len(db)} entries, built in {time.perf_counter() - t0:.0f} s)")
        if len(db) == 0:
            raise InputError(str(db_path), "a silhouette database with at least one entry", "an empty database")
        fg = ForegroundConfig(method="chroma") if args.foreground == "chroma" else \
            ForegroundConfig(background=replace(BackgroundConfig(), method=args.foreground))
        plates = None
        if args.plates is not None:
            plates = {c: [read_png(args.plates / f"{c}.png", channels=3, dtype=np.uint8)] for c in names}
        n = ds.frames_to_process(args.max_frames)
        args.out.mkdir(parents=True, exist_ok=True)
        observer = None
        if not args.no_recording:
            from toolkit.viz import RerunObserver
            observer = RerunObserver(application_id="pose_from_silhouettes", path=args.out / "recording.rrd",
                                     camera_names=names)
            observer.report("skeleton", skeleton=SKELETON_14)
        rig = cameras_for_run(ds, args.out, refine=not args.keep_calibration, observer=observer)
        config = config.with_refined_cameras(refined_cameras(args.out))  # tight offset prior where refined
        if observer is not None:
            observer.report("rig", rig=rig)
        n_db = len(db)
        estimates = []
        t0 = time.perf_counter()
        stopped = ""
        try:
            run = estimate_dataset(ds, db, config, foreground=fg, frames=range(n), edits=edits, backgrounds=plates,
                                   rig=rig, observer=observer, log_images=not args.no_images)
            for est, _ in tqdm(run, total=n, desc="stage 1", unit="frame", disable=args.quiet):
                estimates.append(est)
                if len(estimates) % CHECKPOINT_FRAMES == 0:
                    _write(args.out, stack_estimates(estimates, n, names, config.query.k))
        except KeyboardInterrupt:
            stopped = "interrupted"
        finally:
            arrays = stack_estimates(estimates, n, names, config.query.k)
            _write(args.out, arrays)
            atomic_write_text(args.out / "edits_template.toml",
                              edits_template({c: arrays["poses2d"][c] for c in names}, range(len(estimates)),
                                             header=f"Edits for {args.dataset} (pose_from_silhouettes.py)"))
            if len(db) > n_db:
                db.save(db_path)
                print(f"added {len(db) - n_db} corrected pose(s) to {db_path} ({len(db)} entries)")
            if observer is not None:
                observer.close()
            ds.close()
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    dt = time.perf_counter() - t0
    states = arrays["poses3d"]["state"][:len(estimates)]
    ok = int((states == FRAME_OK).sum())
    print(f"{'stopped early (' + stopped + '): ' if stopped else ''}{len(estimates)} of {n} frames in {dt:.1f} s "
          f"({dt / max(len(estimates), 1):.2f} s/frame); 3D estimate in {ok}")
    for code in sorted(set(states.tolist()) - {FRAME_OK}):
        print(f"  {int((states == code).sum())} frame(s): {FRAME_STATES[code]}")
    print(f"  2D poses:  {args.out / 'poses2d.npz'}  (one (T, 14, 2) array per camera, pixels)")
    print(f"  3D joints: {args.out / 'poses3d.npz'}  (joints (T, 14, 3) metres, names, state)")
    print(f"  offsets:   {args.out / 'offsets.npz'}  (offsets (T, cameras, 2) pixels)")
    print(f"  cameras:   {args.out / 'calibration.toml'}  (the calibration used: refined on field lines or measured)")
    print(f"  edits:     {args.out / 'edits_template.toml'}  (copy the frames to correct into an edits file)")
    if not args.no_recording:
        print(f"  recording: {args.out / 'recording.rrd'}   (open with: rerun {args.out / 'recording.rrd'})")
    return 0 if not stopped else 130


if __name__ == "__main__":
    sys.exit(main())
