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
  calibration.toml    the cameras used (refined on field lines or measured)
  run.json            the dataset and options of this run: another run's folder is refused
                      (or moved aside with --replace-stale)

Frames without an estimate are NaN and their ``state`` says why (see
docs/stage1_silhouettes.md).  A run always starts from the first frame (the
temporal term links the frames).  Ctrl-C or SIGTERM stops it with exit code
130 and writes the frames estimated so far (the others "not processed"),
but never over the complete results of an earlier run of the same options,
which stay with their recording; a run killed outright leaves the finished
frames' recording in ``OUT/recording.parts/`` (the next run merges it).  A
rerun of fewer frames (``--max-frames``) than complete results hold is
refused.  Without --db, a default silhouette database is built once (about
30 s) into ~/.cache/billboard-toolkit (or $TOOLKIT_CACHE) and reused.
Options may also come from a TOML file (--config; the keys of
toolkit.pipeline.pose_from_silhouettes.PoseFromSilhouettesConfig, the
estimator in [stage1] and [stage1.query] tables; flags given here win).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.pose_from_silhouettes import FOREGROUNDS, PoseFromSilhouettesConfig, run, summary_lines
from toolkit.pipeline.run import load_config


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="dataset folder (docs/dataset_layout.md)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--db", type=Path, default=None,
                    help="silhouette database .npz (built there if missing; default: the cached default database)")
    ap.add_argument("--k", type=int, default=None, help="candidates per view (default 3, source 000 §2.1)")
    ap.add_argument("--metric", choices=("l1", "hausdorff"), default=None,
                    help="silhouette matching error: cell differences (eq. 1, default) or contour Hausdorff distance")
    ap.add_argument("--flow-weight", type=float, default=None,
                    help="weight of the optical-flow term (needs a database built with --flow; default 0: off)")
    ap.add_argument("--edits", type=Path, default=None, help="joint corrections (.toml or .json, see docs)")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--foreground", choices=FOREGROUNDS, default=None,
                    help="background model, or chroma keying (green screen); default median")
    ap.add_argument("--plates", type=Path, default=None,
                    help="folder of clean plates <camera>.png (the empty scene) to learn the backgrounds from "
                         "(default: each camera's video)")
    ap.add_argument("--no-check-sizes", action="store_true",
                    help="accept videos whose size differs from the calibration (docs/dataset_layout.md)")
    ap.add_argument("--keep-calibration", action="store_true",
                    help="do not refine the cameras on the dataset's field lines (field_model.json)")
    ap.add_argument("--no-images", action="store_true", help="do not log the camera images (smaller recording)")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--replace-stale", action="store_true",
                    help="if OUT holds results of another dataset or other options, move it to OUT.stale-N "
                         "and start afresh (default: refuse)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    return ap


def config_from_args(args: argparse.Namespace) -> PoseFromSilhouettesConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(PoseFromSilhouettesConfig, args.config, db=args.db, edits=args.edits,
                         max_frames=args.max_frames, foreground=args.foreground, plates=args.plates)
    query = {k: v for k, v in (("k", args.k), ("metric", args.metric), ("flow_weight", args.flow_weight))
             if v is not None}
    return replace(config, stage1=replace(config.stage1, query=replace(config.stage1.query, **query)),
                   check_sizes=config.check_sizes and not args.no_check_sizes,
                   refine_calibration=config.refine_calibration and not args.keep_calibration,
                   log_images=config.log_images and not args.no_images,
                   recording=config.recording and not args.no_recording,
                   replace_stale=config.replace_stale or args.replace_stale,
                   progress=config.progress and not args.quiet)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        result = run(config_from_args(args), dataset=args.dataset, out=args.out,
                     log=lambda line: print(line, flush=True))
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print("\n".join(summary_lines(result)))
    return 130 if result.stopped else 0


if __name__ == "__main__":
    sys.exit(main())
