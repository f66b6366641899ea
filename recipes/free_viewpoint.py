#!/usr/bin/env python3
"""Free-viewpoint video from a few cameras with articulated billboards: every stage, end to end.

Usage::

    python recipes/make_scene.py datasets_synthetic/default.toml --out out/default
    python recipes/free_viewpoint.py out/default --out out/default_fvv
    python recipes/import_pose2sim.py TRIAL --out out/demo      # real footage with OpenPose keypoints
    python recipes/free_viewpoint.py out/demo --out out/demo_fvv --hold-out cam_01

Per frame: foreground silhouettes, 2D poses and the multi-view selection with
calibration offsets (stage 1; from a detector's 2D keypoints instead of the
silhouette database when the dataset has keypoints/ or --keypoints is given,
with silhouettes given (--masks), from clean plates, or seeded by the
keypoints) -> template fit and body-part segmentation -> seams and the 3D joint
optimisation by the position score -> articulated billboards -> view-dependent
rendering (source 000 §4) of every novel camera of the dataset, of a held-out
source camera (--hold-out) and of three camera paths.  Writes into OUT:

  poses3d.npz            joints (T, 14, 3) metres, names, joints_stage1, status (str per frame)
  parts/<camera>/NNNNNN.png      part labels per source camera
  novel/<camera>/NNNNNN.png      articulated-billboard rendering of each novel camera
  novel_alpha/<camera>/NNNNNN.png   its opacity, uint8 (255 = opaque subject, 0 = background)
  baselines/<method>/<camera>/NNNNNN.png   standard billboards and visual hull, same views
  baselines/plate/<camera>/NNNNNN.png      the background alone (what the subject is drawn over)
  paths/<path>/NNNNNN.png, paths/<path>.mp4   orbit, sweep through the sources, bird's-eye
  heldout/<CAM>/NNNNNN.png       with --hold-out CAM: CAM's view rendered from the other cameras (articulated);
                                 heldout_alpha/ its opacity, heldout_region/ the person's region it is judged in,
                                 baselines/<method>/<CAM>/ the baselines; metrics.json "heldout" their scores
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
                    help="JPEG quality of the images in the recording, 1-100 (default 90; camera images and the "
                         "rendered views, cropped to the subject, are most of its size: docs/recordings.md)")
    ap.add_argument("--replace-stale", action="store_true",
                    help="if OUT holds results of another dataset or other options, move it to OUT.stale-N "
                         "and start afresh (default: refuse)")
    ap.add_argument("--keypoints", type=Path, default=None,
                    help="2D keypoints of any detector, one sub-folder per camera (default: the dataset's "
                         "keypoints/ when it has one): stage 1 triangulates them instead of querying the "
                         "silhouette database")
    ap.add_argument("--no-keypoints", action="store_true",
                    help="ignore the dataset's keypoints/ (2D poses from the silhouette database)")
    ap.add_argument("--keypoint-format", default=None,
                    choices=("body_25", "body_25b", "coco_17", "coco_18", "halpe_26", "coco_133", "blazepose_33"),
                    help="the keypoints' format (default: the dataset's import.json pose_model, else found "
                         "from the files)")
    ap.add_argument("--masks", type=Path, default=None,
                    help="subject masks from elsewhere, <dir>/<camera>/NNNNNN.png (default: the dataset's masks/)")
    ap.add_argument("--silhouettes", choices=("auto", "masks", "background", "seeded"), default="auto",
                    help="with keypoints: masks given, background subtraction, or a segmentation seeded by the "
                         "keypoints (auto: masks if given, else clean plates, else seeded)")
    ap.add_argument("--hold-out", default=None, metavar="CAM",
                    help="leave camera CAM out: run without its images and keypoints, render its view into "
                         "OUT/heldout/CAM/ and compare with what it filmed (metrics.json 'heldout')")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    if args.jpeg_quality is not None and not 1 <= args.jpeg_quality <= 100:
        ap.error(f"--jpeg-quality: expected an integer in 1..100, found {args.jpeg_quality}")

    from dataclasses import replace

    import numpy as np
    from tqdm import tqdm

    from toolkit.foreground import BackgroundConfig, ForegroundConfig
    from toolkit.calibration import cameras_for_run, refined_cameras
    from toolkit.cameras import Rig, closest_point_to_rays
    from toolkit.io import Dataset, atomic_save_npz, atomic_write_png, atomic_write_text, write_video
    from toolkit.io.frames import frame_filename, read_png
    from toolkit.io.runs import dataset_fingerprint, run_recording, start_run
    from toolkit.rendering import CpuCompositor, birds_eye, orbit_path, source_path
    from toolkit.rendering.evaluation import BackgroundPlates, pose_errors, summarise
    from toolkit.rendering.freeviewpoint import METHODS, FrameProcessor, FreeViewpointConfig, render_methods
    from toolkit.pipeline import KeypointStage1Config, estimate_from_keypoints
    from toolkit.pipeline.keypoints import declared_format
    from toolkit.pipeline.views import (HELDOUT_REGION_DOC, EvaluationView, HeldOutRegions, render_evaluation,
                                        split_rig)
    from toolkit.silhouettes import Stage1Config, default_database, default_database_path
    from toolkit.silhouettes.pipeline import estimate_dataset
    from toolkit.skeleton import SKELETON_14

    try:
        ds = Dataset.open(args.dataset)
        all_names = ds.camera_names
        n = ds.frames_to_process(args.max_frames)
        out = args.out
        kp_dir = None if args.no_keypoints else (
            args.keypoints if args.keypoints is not None else (ds.root / "keypoints" if ds.has_keypoints else None))
        if kp_dir is not None and not Path(kp_dir).is_dir():
            raise InputError("--keypoints", "a folder with one sub-folder of keypoints per camera", f"{kp_dir}")
        masks_dir = args.masks if args.masks is not None else (ds.root / "masks" if ds.has_masks else None)
        if masks_dir is not None and not Path(masks_dir).is_dir():
            raise InputError("--masks", "a folder with one sub-folder of masks per camera", f"{masks_dir}")
        if args.hold_out is not None and args.hold_out not in all_names:
            raise InputError("--hold-out", f"one of the dataset's cameras {all_names}", repr(args.hold_out))
        # results of another dataset or other options must not be resumed (run.json)
        identity = {"recipe": "free_viewpoint", "dataset": dataset_fingerprint(ds.root),
                    # the default database's file name holds its build configuration's key
                    "db": default_database_path().name if args.db is None else str(args.db.resolve()),
                    "foreground": args.foreground, "optimize": not args.no_optimize,
                    "keep_calibration": args.keep_calibration, "baselines": not args.no_baselines,
                    "renderer": args.renderer}
        if kp_dir is not None or args.hold_out is not None or masks_dir is not None:
            identity.update(keypoints=str(Path(kp_dir).resolve()) if kp_dir is not None else None,
                            masks=str(Path(masks_dir).resolve()) if masks_dir is not None else None,
                            silhouettes=args.silhouettes, hold_out=args.hold_out,
                            keypoint_format=args.keypoint_format)
        resumed = start_run(out, identity, replace_stale=args.replace_stale)
        novel = list(ds.novel_rig) if ds.has_groundtruth and (ds.root / "groundtruth/novel/calibration.toml").exists() \
            else []
        if not novel and args.hold_out is None:
            print("note: the dataset has no novel cameras; rendering the camera paths only (no image metrics)")
        done = {t for t in range(n) if (out / "frames" / frame_filename(t, ".json")).exists()}
        observer = rec_path = None
        if not args.no_recording and len(done) < n:  # nothing left to do: no new recording part
            from toolkit.viz import RerunConfig, RerunObserver

            # a resumed run writes its own part beside the earlier one(s), same recording id
            rec_path, rec_id = run_recording(out, resumed)
            rconf = RerunConfig() if args.jpeg_quality is None else RerunConfig(jpeg_quality=args.jpeg_quality)
            observer = RerunObserver(application_id="free_viewpoint", path=rec_path, recording_id=rec_id,
                                     camera_names=all_names + [c.name for c in novel], config=rconf)
            if novel:
                observer.report("rig", rig=ds.novel_rig)
            observer.report("skeleton", skeleton=SKELETON_14)
        # frames of this same run are finished: continue with its cameras
        full_rig = cameras_for_run(ds, out, refine=not args.keep_calibration, resumed=resumed and bool(done),
                                   observer=observer)
        held = None
        rig = full_rig
        if args.hold_out is not None:  # the pipeline never sees the held-out camera's images or keypoints
            rig, held = split_rig(full_rig, args.hold_out)
        names = rig.names
        if observer is not None:
            observer.report("rig", rig=rig)
        plates = BackgroundPlates(ds.scene_toml) if ds.scene_toml is not None else None
        target = closest_point_to_rays(rig.centers, np.array([c.forward for c in rig]))[0]
        paths = {"orbit": orbit_path(target, n, radius_m=float(np.median(np.linalg.norm(rig.centers - target, axis=1))),
                                     height_m=float(np.median(rig.centers[:, 2])), size=rig[0].size,
                                     focal_px=float(rig[0].K[0, 0])),
                 # a path between cameras of different sizes (1080 and 1088 px wide) is drawn at the first one's
                 "sweep": source_path(Rig(tuple(replace(c, size=rig[0].size) for c in rig)), max(n, 2),
                                      closed=True)[:n],
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
        if todo and kp_dir is None:
            db = default_database(args.db)[0] if args.db is None or not args.db.exists() else None
            if db is None:
                from toolkit.silhouettes import SilhouetteDatabase
                db = SilhouetteDatabase.load(args.db)
        # clean plates of the source cameras (a broadcast crew records the empty pitch): segmentation uses them
        source_plates = {c: p for c in names if (p := ds.background(c)) is not None} if todo else {}
        region_of = None
        if held is not None:
            region_of = HeldOutRegions(ds, held, masks_dir=masks_dir, keypoints=kp_dir, out=out,
                                       fmt=args.keypoint_format or declared_format(ds.root))
        stopped = ""
        t_start = time.perf_counter()
        try:
            fg = ForegroundConfig(method="chroma") if args.foreground == "chroma" else \
                ForegroundConfig(background=replace(BackgroundConfig(), method=args.foreground))
            if not todo:
                run = iter(())
            elif kp_dir is not None:
                kconf = KeypointStage1Config(fmt=args.keypoint_format or declared_format(ds.root))
                run = estimate_from_keypoints(ds, kp_dir, rig, kconf, frames=todo, silhouettes=args.silhouettes,
                                              masks_dir=masks_dir, foreground=fg, observer=observer)
            else:
                s1config = Stage1Config().with_refined_cameras(refined_cameras(out))  # tight prior where refined
                run = estimate_dataset(ds, db, s1config, foreground=fg, frames=todo, rig=rig, observer=observer)
            for est, masks in tqdm(run, total=len(todo), desc="free viewpoint", unit="frame", disable=args.quiet):
                t0 = time.perf_counter()
                t = est.frame
                images = {c: ds.frame(c, t) for c in names}
                res = processor.process(t, images, masks, est, plates=source_plates)
                for c in names:
                    atomic_write_png(out / "parts" / c / frame_filename(t), res.labels[c])
                views = [EvaluationView(cam, "novel", plates.plate(cam) if plates is not None else
                                        np.zeros(cam.size[::-1] + (3,), np.float32),
                                        ds.novel_image(cam.name, t), ds.novel_mask(cam.name, t)) for cam in novel]
                if held is not None:
                    views.append(region_of.view(t, res.joints if res.ok else None))
                scores, heldout = {}, {}
                for v in views:
                    for m, sc in render_evaluation(res, v, out, t, compositor, observer=observer).items():
                        (scores if v.kind == "novel" else heldout).setdefault(m, {})[v.camera.name] = sc
                for p, cams in paths.items():
                    bg = plates.plate(cams[t]) if plates is not None else np.zeros(cams[t].size[::-1] + (3,))
                    img = render_methods(res, cams[t], bg, compositor, methods=("articulated",))["articulated"]
                    atomic_write_png(out / "paths" / p / frame_filename(t), img)
                record = {"frame": t, "status": res.status, "joints": res.joints.tolist(),
                          "joints_stage1": res.joints_stage1.tolist(), "offsets": res.offsets.tolist(),
                          "scores": scores, "timings": {**res.timings, **{k: v for k, v in est.timings.items()
                                                                          if k in ("foreground", "keypoints")},
                                                        "total": time.perf_counter() - t0},
                          "optimize": res.optimize}
                if held is not None:
                    record["heldout"] = heldout
                    record["heldout_region"] = region_of.how.get(t, "")
                    record["heldout_offset"] = region_of.offsets.get(t, np.zeros(2)).tolist()
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
        metrics = {"frames": n, "finished": len(records), "optimize": outcome,
                   "stage1": "keypoints" if kp_dir is not None else "silhouette database",
                   "seconds_per_frame": {k: float(np.mean([r["timings"].get(k, np.nan) for r in records]))
                                         for k in ("total", "foreground", "keypoints", "segmentation", "optimize",
                                                   "billboards", "standard_billboards", "visual_hull")}
                   if records else {}}
        if ds.has_groundtruth:
            gt = ds.gt_joints3d()[:n]
            metrics.update({"methods": summarise([r["scores"] for r in records]),
                            "pose": pose_errors(joints, gt), "pose_stage1": pose_errors(stage1, gt),
                            "novel_cameras": [c.name for c in novel]})
        if held is not None:
            metrics["heldout"] = {"camera": held.name, "methods": summarise([r.get("heldout", {}) for r in records]),
                                  "region": dict(Counter(r.get("heldout_region", "") for r in records)),
                                  "region_definition": HELDOUT_REGION_DOC,
                                  "offset_px_median": np.median(offs, axis=0).tolist() if (offs := [
                                      r["heldout_offset"] for r in records if "heldout_offset" in r]) else None}
        if ds.has_groundtruth or held is not None:
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
    if held is not None and records:
        print(f"  held-out camera {held.name} (its person's region: "
              + ", ".join(f"{k} {v} frames" for k, v in metrics["heldout"]["region"].items())
              + ("; its calibration corrected by a 2D offset of ({:+.1f}, {:+.1f}) px".format(
                  *metrics["heldout"]["offset_px_median"]) if metrics["heldout"]["offset_px_median"] else "")
              + "):")
        for m in METHODS:
            s = metrics["heldout"]["methods"].get(m)
            if s:
                print(f"  {m:12s} on the person {s['psnr_subject']:.2f} dB  box PSNR {s['psnr']:.2f} dB  "
                      f"SSIM {s['ssim']:.3f}  coverage {s['coverage']:.3f}  ({s['n']} frames)")
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
