#!/usr/bin/env python3
"""Free-viewpoint video from a few cameras with articulated billboards: every stage, end to end.

Usage::

    python recipes/make_scene.py datasets_synthetic/default.toml --out out/default
    python recipes/free_viewpoint.py out/default --out out/default_fvv

Per frame: foreground silhouettes, 2D poses and the multi-view selection with
calibration offsets (stage 1) -> template fit and body-part segmentation ->
seams and the 3D joint optimisation by the position score -> articulated
billboards -> view-dependent rendering (source 000 §4) of every novel camera
of the dataset and of three camera paths.  Writes into OUT:

  poses3d.npz            joints (T, 14, 3) metres, names, joints_stage1, status (str per frame)
  parts/<camera>/NNNNNN.png      part labels per source camera
  novel/<camera>/NNNNNN.png      articulated-billboard rendering of each novel camera
  novel_alpha/<camera>/NNNNNN.png   its opacity, uint8 (255 = opaque subject, 0 = background)
  baselines/<method>/<camera>/NNNNNN.png   standard billboards and visual hull, same views
  baselines/plate/<camera>/NNNNNN.png      the background alone (what the subject is drawn over)
  paths/<path>/NNNNNN.png, paths/<path>.mp4   orbit, sweep through the sources, bird's-eye
  metrics.json           per method: PSNR / SSIM in the subject's box, psnr_subject (PSNR on the true mask
                         + 2 px), coverage (share of the true mask rendered with opacity > 0.5; mean and
                         coverage_min, the worst view); pose error, timings (with ground truth)
  recording.rrd          every intermediate of this run, with a blueprint; a resumed run writes
                         recording.resume-<k>.rrd beside it (same recording id: rerun OUT/recording*.rrd)
  frames/NNNNNN.json     per-frame results; a frame with one is finished and skipped when the run resumes
  run.json               the dataset fingerprint and options of this run: results of another dataset or
                         other options are never resumed (refused, or moved aside with --replace-stale)

Stop it at any time (Ctrl-C) and run the same command again: finished frames
are kept.  See docs/stage4_rendering.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from toolkit.errors import InputError  # noqa: E402

PATHS = ("orbit", "sweep", "birds_eye")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="dataset folder (docs/dataset_layout.md)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--db", type=Path, default=None, help="silhouette database .npz (default: the cached one)")
    ap.add_argument("--foreground", choices=("median", "mog2", "knn", "chroma"), default="median",
                    help="background model, or chroma keying (green screen)")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--no-optimize", action="store_true", help="keep stage 1's joints (skip the position-score search)")
    ap.add_argument("--no-baselines", action="store_true", help="do not render standard billboards / visual hull")
    ap.add_argument("--renderer", choices=("cpu", "open3d"), default="cpu",
                    help="CPU compositor (fast) or Open3D's off-screen renderer (same blend, ~1 s per view)")
    ap.add_argument("--keep-calibration", action="store_true",
                    help="do not refine the cameras on the dataset's field lines (field_model.json)")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--jpeg-quality", type=int, default=None,
                    help="JPEG quality of the images in the recording, 1-100 (default 90; camera frames and the "
                         "rendered views are most of its size: about 2.5 of 3.3 MB per frame at 90)")
    ap.add_argument("--replace-stale", action="store_true",
                    help="if OUT holds results of another dataset or other options, move it to OUT.stale-N "
                         "and start afresh (default: refuse)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    if args.jpeg_quality is not None and not 1 <= args.jpeg_quality <= 100:
        ap.error(f"--jpeg-quality: expected an integer in 1..100, found {args.jpeg_quality}")

    from dataclasses import replace

    import numpy as np
    from tqdm import tqdm

    from toolkit.foreground import BackgroundConfig, ForegroundConfig
    from toolkit.calibration import cameras_for_run, refined_cameras
    from toolkit.cameras import closest_point_to_rays
    from toolkit.io import Dataset, atomic_save_npz, atomic_write_png, atomic_write_text, write_video
    from toolkit.io.frames import frame_filename, read_png
    from toolkit.io.runs import dataset_fingerprint, run_recording, start_run
    from toolkit.rendering import CpuCompositor, bbox_scores, birds_eye, orbit_path, source_path, subject_scores
    from toolkit.rendering.evaluation import BackgroundPlates, pose_errors, summarise
    from toolkit.rendering.freeviewpoint import (METHODS, FrameProcessor, FreeViewpointConfig, render_methods,
                                                   render_views)
    from toolkit.silhouettes import Stage1Config, default_database, default_database_path
    from toolkit.silhouettes.pipeline import estimate_dataset
    from toolkit.skeleton import SKELETON_14

    try:
        ds = Dataset.open(args.dataset)
        names = ds.camera_names
        n = ds.frames_to_process(args.max_frames)
        out = args.out
        # results of another dataset or other options must not be resumed (run.json)
        identity = {"recipe": "free_viewpoint", "dataset": dataset_fingerprint(ds.root),
                    # the default database's file name holds its build configuration's key
                    "db": default_database_path().name if args.db is None else str(args.db.resolve()),
                    "foreground": args.foreground, "optimize": not args.no_optimize,
                    "keep_calibration": args.keep_calibration, "baselines": not args.no_baselines,
                    "renderer": args.renderer}
        resumed = start_run(out, identity, replace_stale=args.replace_stale)
        novel = list(ds.novel_rig) if ds.has_groundtruth and (ds.root / "groundtruth/novel/calibration.toml").exists() \
            else []
        if not novel:
            print("note: the dataset has no novel cameras; rendering the camera paths only (no image metrics)")
        done = {t for t in range(n) if (out / "frames" / frame_filename(t, ".json")).exists()}
        observer = rec_path = None
        if not args.no_recording and len(done) < n:  # nothing left to do: no new recording part
            from toolkit.viz import RerunConfig, RerunObserver

            # a resumed run writes its own part beside the earlier one(s), same recording id
            rec_path, rec_id = run_recording(out, resumed)
            rconf = RerunConfig() if args.jpeg_quality is None else RerunConfig(jpeg_quality=args.jpeg_quality)
            observer = RerunObserver(application_id="free_viewpoint", path=rec_path, recording_id=rec_id,
                                     camera_names=names + [c.name for c in novel], config=rconf)
            if novel:
                observer.report("rig", rig=ds.novel_rig)
            observer.report("skeleton", skeleton=SKELETON_14)
        # frames of this same run are finished: continue with its cameras
        rig = cameras_for_run(ds, out, refine=not args.keep_calibration, resumed=resumed and bool(done),
                              observer=observer)
        if observer is not None:
            observer.report("rig", rig=rig)
        plates = BackgroundPlates(ds.scene_toml) if ds.scene_toml is not None else None
        target = closest_point_to_rays(rig.centers, np.array([c.forward for c in rig]))[0]
        paths = {"orbit": orbit_path(target, n, radius_m=float(np.median(np.linalg.norm(rig.centers - target, axis=1))),
                                     height_m=float(np.median(rig.centers[:, 2])), size=rig[0].size,
                                     focal_px=float(rig[0].K[0, 0])),
                 "sweep": source_path(rig, max(n, 2), closed=True)[:n],
                 "birds_eye": [birds_eye(rig, target)] * n}
        todo = [t for t in range(n) if t not in done]
        if done:
            print(f"resuming: {len(done)} of {n} frames already finished")
        config = FreeViewpointConfig(optimize=not args.no_optimize, baselines=not args.no_baselines)
        processor = FrameProcessor(rig, config, observer)
        if args.renderer == "open3d":
            from toolkit.rendering import Open3DRenderer
            compositor = Open3DRenderer(rig[0].size)
        else:
            compositor = CpuCompositor()
        db = None
        if todo:
            db = default_database(args.db)[0] if args.db is None or not args.db.exists() else None
            if db is None:
                from toolkit.silhouettes import SilhouetteDatabase
                db = SilhouetteDatabase.load(args.db)
        # clean plates of the source cameras (a broadcast crew records the empty pitch): segmentation uses them
        source_plates = {c: p for c in names if (p := ds.background(c)) is not None} if todo else {}
        stopped = ""
        t_start = time.perf_counter()
        try:
            fg = ForegroundConfig(method="chroma") if args.foreground == "chroma" else \
                ForegroundConfig(background=replace(BackgroundConfig(), method=args.foreground))
            s1config = Stage1Config().with_refined_cameras(refined_cameras(out))  # tight offset prior where refined
            run = estimate_dataset(ds, db, s1config, foreground=fg, frames=todo, rig=rig,
                                   observer=observer) if todo else iter(())
            for est, masks in tqdm(run, total=len(todo), desc="free viewpoint", unit="frame", disable=args.quiet):
                t0 = time.perf_counter()
                t = est.frame
                images = {c: ds.frame(c, t) for c in names}
                res = processor.process(t, images, masks, est, plates=source_plates)
                for c in names:
                    atomic_write_png(out / "parts" / c / frame_filename(t), res.labels[c])
                scores = {}
                for cam in novel:
                    bg = plates.plate(cam) if plates is not None else np.zeros(cam.size[::-1] + (3,), np.float32)
                    views = render_views(res, cam, bg, compositor, observer=observer)
                    gt, gt_mask = ds.novel_image(cam.name, t), ds.novel_mask(cam.name, t)
                    atomic_write_png(out / "baselines" / "plate" / cam.name / frame_filename(t),
                                     np.clip(np.asarray(bg, np.float32) + 0.5, 0, 255).astype(np.uint8))
                    for m, v in views.items():
                        folder = out / "novel" if m == "articulated" else out / "baselines" / m
                        atomic_write_png(folder / cam.name / frame_filename(t), v.image)
                        if m == "articulated":
                            atomic_write_png(out / "novel_alpha" / cam.name / frame_filename(t),
                                             np.clip(np.rint(v.alpha * 255.0), 0, 255).astype(np.uint8))
                        scores.setdefault(m, {})[cam.name] = {**bbox_scores(v.image, gt, gt_mask),
                                                              **subject_scores(v.image, gt, gt_mask, v.alpha)}
                        if observer is not None:
                            observer.report("image", camera=cam.name, image=v.image, name=f"render/{m}", frame=t)
                for p, cams in paths.items():
                    bg = plates.plate(cams[t]) if plates is not None else np.zeros(cams[t].size[::-1] + (3,))
                    img = render_methods(res, cams[t], bg, compositor, methods=("articulated",))["articulated"]
                    atomic_write_png(out / "paths" / p / frame_filename(t), img)
                record = {"frame": t, "status": res.status, "joints": res.joints.tolist(),
                          "joints_stage1": res.joints_stage1.tolist(), "offsets": res.offsets.tolist(),
                          "scores": scores, "timings": {**res.timings, "total": time.perf_counter() - t0},
                          "optimize": res.optimize}
                atomic_write_text(out / "frames" / frame_filename(t, ".json"), json.dumps(record, allow_nan=True))
        except KeyboardInterrupt:
            stopped = "interrupted"
        finally:
            if observer is not None:
                observer.close()
        records = [json.loads((out / "frames" / frame_filename(t, ".json")).read_text()) for t in range(n)
                   if (out / "frames" / frame_filename(t, ".json")).exists()]
        joints = np.full((n, 14, 3), np.nan)
        stage1 = np.full((n, 14, 3), np.nan)
        status = np.array(["not processed"] * n)
        for r in records:
            joints[r["frame"]], stage1[r["frame"]], status[r["frame"]] = r["joints"], r["joints_stage1"], r["status"]
        atomic_save_npz(out / "poses3d.npz", joints=joints, names=np.array(SKELETON_14.joint_names),
                        joints_stage1=stage1, status=status)
        outcome = dict(sum((Counter(r.get("optimize", {})) for r in records), Counter()))  # stage 3, all frames
        finished = len(records) == n
        if finished:
            for p in PATHS:
                frames = (read_png(out / "paths" / p / frame_filename(t)) for t in range(n))
                write_video(out / "paths" / f"{p}.mp4", frames, ds.fps)
        if ds.has_groundtruth:
            gt = ds.gt_joints3d()[:n]
            metrics = {"frames": n, "finished": len(records), "methods": summarise([r["scores"] for r in records]),
                       "pose": pose_errors(joints, gt), "pose_stage1": pose_errors(stage1, gt),
                       "seconds_per_frame": {k: float(np.mean([r["timings"].get(k, np.nan) for r in records]))
                                             for k in ("total", "segmentation", "optimize", "billboards",
                                                       "standard_billboards", "visual_hull")} if records else {},
                       "novel_cameras": [c.name for c in novel], "optimize": outcome}
            atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=2, allow_nan=True))
        ds.close()
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    dt = time.perf_counter() - t_start
    print(f"{'stopped early (' + stopped + '): ' if stopped else ''}{len(records)} of {n} frames finished "
          f"({len(todo)} this run, {dt:.1f} s)")
    if ds.has_groundtruth and records:
        for m in METHODS:
            s = metrics["methods"].get(m)
            if s:
                print(f"  {m:12s} PSNR {s['psnr']:.2f} dB  SSIM {s['ssim']:.3f}  on the subject {s['psnr_subject']:.2f} dB"
                      f"  coverage {s['coverage']:.3f} (worst view {s['coverage_min']:.3f})  ({s['n']} views)")
        e, e1 = metrics["pose"]["mpjpe_m"], metrics["pose_stage1"]["mpjpe_m"]
        print(f"  pose error {e * 100:.1f} cm (stage 1: {e1 * 100:.1f} cm)")
    if outcome:  # e.g. two cameras far apart: every joint "few_views", stage 3 changed nothing
        total = sum(outcome.values())
        print("  stage 3 joints: " + ", ".join(f"{k} {100 * v / total:.0f} %" for k, v in
                                                sorted(outcome.items(), key=lambda kv: -kv[1]))
              + " (docs/stage3_billboards.md: what each means)")
    if rec_path is None:
        earlier = not args.no_recording and any(out.glob("recording*.rrd"))
        print(f"outputs in {out}" + (f"; every frame was already finished; earlier recordings: "
                                     f"rerun {out}/recording*.rrd" if earlier else ""))
    elif rec_path.name == "recording.rrd":
        print(f"outputs in {out}; recording: rerun {rec_path}"
              + (f" (frames of this run only: {len(done)} earlier ones were made without one)" if done else ""))
    else:  # the parts of a resumed run share one recording id: the viewer merges them
        print(f"outputs in {out}; this run's recording: {rec_path.name}; all of it: rerun {out}/recording*.rrd")
    return 1 if stopped else 0


if __name__ == "__main__":
    sys.exit(main())
