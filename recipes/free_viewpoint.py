#!/usr/bin/env python3
"""Free-viewpoint video from a few cameras with articulated billboards: every stage, end to end.

Usage::

    python recipes/make_scene.py datasets_synthetic/default.toml --out out/default
    python recipes/free_viewpoint.py out/default --out out/default_fvv
    python recipes/import_pose2sim.py TRIAL --out out/demo      # real footage with OpenPose keypoints
    python recipes/free_viewpoint.py out/demo --out out/demo_fvv --hold-out cam_01
    python recipes/free_viewpoint.py TRIAL --out out/trial_fvv [--sync]   # a Pose2Sim trial directly

The positional argument is a dataset (docs/dataset_layout.md) or a Pose2Sim
trial folder, with keypoints or with videos and a calibration only: a trial is
imported first into OUT/dataset (toolkit.pipeline.trial_input; its people
detected when it has no keypoints, on the --max-frames frames only unless
--sync, which lines the cameras up by their late starts) and the results below
go to OUT/results instead of OUT.  A rerun with the same OUT reuses that import.

Per frame: foreground silhouettes, 2D poses and the multi-view selection with
calibration offsets (stage 1; from a detector's 2D keypoints instead of the
silhouette database when the dataset has keypoints/ or --keypoints is given,
with silhouettes given (--masks), from clean plates, or seeded by the
keypoints) -> template fit and body-part segmentation -> seams and the 3D joint
optimisation by the position score -> articulated billboards -> view-dependent
rendering (source 000 §4) of every novel camera of the dataset, of a held-out
source camera (--hold-out) and of three camera paths.  With keypoints every
participant goes through the stages on its own and the views draw the people
far to near (--people; toolkit/pipeline/people.py).  The people are drawn over
the scene model built from the source videos (--background; toolkit/scene/:
each camera's empty view estimated over time, carried on a ground plane and a
cylinder of walls, blended view-dependently), so every view is a whole frame.
Writes into OUT:

  poses3d.npz            joints (T, 14, 3) metres, names, joints_stage1, status (str per frame): the main person
  people3d.npz           with several people: joints (P, T, 14, 3), people (P,) names, names (14,)
  scene/                 the scene model: scene.json (proxy, how it was chosen), background/ and confidence/
                         per source camera
  parts/<camera>/NNNNNN.png      part labels per source camera (every person's; the nearest where they overlap)
  novel/<camera>/NNNNNN.png      articulated-billboard rendering of each novel camera (a whole frame)
  novel_alpha/<camera>/NNNNNN.png   its opacity, uint8 (255 = opaque people, 0 = background)
  baselines/<method>/<camera>/NNNNNN.png   standard billboards and visual hull, same views, same background;
                                 nearest_source: the closest source camera's frame carried through the scene proxy
  baselines/plate/<camera>/NNNNNN.png      the background alone (what the people are drawn over)
  paths/<path>/NNNNNN.png, paths/<path>.mp4   orbit, sweep through the sources, bird's-eye
  heldout/<CAM>/NNNNNN.png       with --hold-out CAM: CAM's view rendered from the other cameras (articulated);
                                 heldout_alpha/ its opacity, heldout_region/ the person's region it is judged in,
                                 baselines/<method>/<CAM>/ the baselines; metrics.json "heldout" their scores
  metrics.json           per method: psnr_frame (PSNR of the whole frame), PSNR / SSIM in the subject's box,
                         psnr_subject (PSNR on the true mask + 2 px), coverage (share of the true mask rendered with opacity > 0.5; mean and
                         coverage_min, the worst view); pose error, timings (with ground truth)
  recording.rrd          every intermediate of this run, with a blueprint; a resumed run writes
                         recording.resume-<k>.rrd beside it (same recording id: rerun OUT/recording*.rrd)
  frames/NNNNNN.json     per-frame results; a frame with one is finished and skipped when the run resumes
  run.json               the dataset fingerprint and options of this run: results of another dataset or
                         other options are never resumed (refused, or moved aside with --replace-stale)

A run in which no frame has a 3D pose ends with exit code 2 and a one-line
error naming each frame status (the summary says which frames have none).
Stop it at any time (Ctrl-C or SIGTERM: exit code 130; or even a kill) and run
the same command again: finished frames are kept.  --workers N runs the frames on N processes of this
machine (default auto: every core), --scheduler tcp://HOST:PORT on a Dask cluster (docs/parallel.md);
stage 1 keeps its frame order in this process, the outputs are the same.  Options may also come from a TOML file (--config; the keys of
toolkit.pipeline.free_viewpoint.FreeViewpointRunConfig, the per-frame chain in
a [frame] table; flags given on the command line win).  See docs/stage4_rendering.md.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.free_viewpoint import (BACKGROUNDS, FOREGROUNDS, KEYPOINT_FORMATS, RENDERERS, SILHOUETTES,
                                             FreeViewpointRunConfig, run, run_failure,
                                             summary_lines)
from toolkit.pipeline.parallel import AUTO, resolve_workers
from toolkit.pipeline.people import PEOPLE_CHOICES
from toolkit.pipeline.run import load_config
from toolkit.pipeline.trial_input import prepare_run_input


def workers_arg(text: str):
    """``--workers``: ``auto`` or a number of worker processes >= 1."""
    try:
        resolve_workers(text)
    except InputError:
        raise argparse.ArgumentTypeError(f"expected a number >= 1 or {AUTO!r}, found {text!r}") from None
    return AUTO if text.strip().lower() == AUTO else int(text)


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path,
                    help="dataset folder (docs/dataset_layout.md), or a Pose2Sim trial (imported into OUT/dataset)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--db", type=Path, default=None, help="silhouette database .npz (default: the cached one)")
    ap.add_argument("--foreground", choices=FOREGROUNDS, default=None,
                    help="background model, or chroma keying (green screen); default median")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--no-optimize", action="store_true", help="keep stage 1's joints (skip the position-score search)")
    ap.add_argument("--no-baselines", action="store_true", help="do not render standard billboards / visual hull")
    ap.add_argument("--renderer", choices=RENDERERS, default=None,
                    help="CPU compositor (default, fast) or Open3D's off-screen renderer (same blend, ~1 s per view)")
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
    ap.add_argument("--keypoint-format", default=None, choices=KEYPOINT_FORMATS,
                    help="the keypoints' format (default: the dataset's import.json pose_model, else found "
                         "from the files)")
    ap.add_argument("--masks", type=Path, default=None,
                    help="subject masks from elsewhere, <dir>/<camera>/NNNNNN.png (default: the dataset's masks/)")
    ap.add_argument("--silhouettes", choices=SILHOUETTES, default=None,
                    help="with keypoints: masks given, background subtraction, or a segmentation seeded by the "
                         "keypoints (default auto: masks if given, else clean plates, else seeded)")
    ap.add_argument("--hold-out", default=None, metavar="CAM",
                    help="leave camera CAM out: run without its images and keypoints, render its view into "
                         "OUT/heldout/CAM/ and compare with what it filmed (metrics.json 'heldout')")
    ap.add_argument("--workers", type=workers_arg, default=None, metavar="N|auto",
                    help="frames in parallel on a local Dask cluster of N worker processes (default auto: one per "
                         "available core, no more than the frames to do; 1: in this process); outputs identical "
                         "to one worker (docs/parallel.md)")
    ap.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                    help="frames on a running Dask cluster (dask scheduler / dask worker; the dataset and OUT on a "
                         "file system every worker sees: docs/parallel.md)")
    ap.add_argument("--background", choices=BACKGROUNDS, default=None,
                    help="what the people are drawn over: the scene model built from the source videos (default; "
                         "OUT/scene/) or the dataset's clean plates (an evaluation aid: the synthetic scene's true "
                         "surroundings, a held-out camera's own plate or inpainted frame)")
    ap.add_argument("--people", choices=PEOPLE_CHOICES, default=None,
                    help="every person (default all: the participants of the keypoints, or the people found on the "
                         "ground in the silhouettes; OUT/people3d.npz) or the main person only")
    ap.add_argument("--sync", action="store_true",
                    help="a Pose2Sim trial without keypoints: synchronise its cameras and line them up on import")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    return ap


def config_from_args(args: argparse.Namespace) -> FreeViewpointRunConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(FreeViewpointRunConfig, args.config, db=args.db, foreground=args.foreground,
                         max_frames=args.max_frames, renderer=args.renderer, jpeg_quality=args.jpeg_quality,
                         keypoints=args.keypoints, keypoint_format=args.keypoint_format, masks=args.masks,
                         silhouettes=args.silhouettes, hold_out=args.hold_out, workers=args.workers,
                         scheduler=args.scheduler, background=args.background, people=args.people)
    frame = replace(config.frame, optimize=config.frame.optimize and not args.no_optimize,
                    baselines=config.frame.baselines and not args.no_baselines)
    return replace(config, frame=frame, refine_calibration=config.refine_calibration and not args.keep_calibration,
                   recording=config.recording and not args.no_recording,
                   replace_stale=config.replace_stale or args.replace_stale,
                   use_keypoints=config.use_keypoints and not args.no_keypoints,
                   progress=config.progress and not args.quiet)


def main(argv=None) -> int:
    ap = parser()
    args = ap.parse_args(argv)
    if args.jpeg_quality is not None and not 1 <= args.jpeg_quality <= 100:
        ap.error(f"--jpeg-quality: expected an integer in 1..100, found {args.jpeg_quality}")
    try:
        config = config_from_args(args)
        source = prepare_run_input(args.dataset, args.out, max_frames=config.max_frames, sync=args.sync)
        if source.lines:
            print("\n".join(source.lines))
        result = run(config, dataset=source.dataset, out=source.out)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print("\n".join(summary_lines(result)))
    failure = run_failure(result)  # e.g. a calibration in the wrong convention: every frame behind the cameras
    if failure:
        print(f"error: {failure}", file=sys.stderr)
        return 2
    return 130 if result.stopped else 0  # stopped by Ctrl-C or SIGTERM, like every recipe


if __name__ == "__main__":
    sys.exit(main())
