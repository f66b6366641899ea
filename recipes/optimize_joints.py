#!/usr/bin/env python3
"""Stage 3 of the articulated-billboard pipeline: 3D joints optimised by the billboard position score.

Usage::

    python recipes/optimize_joints.py out/default --out out/default_stage3 --poses out/default_stage1
    python recipes/optimize_joints.py DATASET --out OUT --poses STAGE1_OUT --parts STAGE2_OUT

Per frame: the source images, the body-part labels and the seams (template or
ground-truth depth) give billboard fans; each joint is moved on an adaptive
grid under anthropometric constraints until the position score converges
(source 000 §3, docs/stage3_billboards.md).  Calibration offsets of stage 1
are kept and applied.

Inputs:
  --poses STAGE1_OUT  poses3d.npz (joints (T, 14, 3)) and offsets.npz (offsets (T, n_cams, 2)) of
                      pose_from_silhouettes.py.  Without it the dataset's ground-truth joints are the
                      start (synthetic datasets only), displaced by --noise-cm.
  --parts STAGE2_OUT  parts/<camera>/NNNNNN.png part labels (1-based ids, 0 background) and, if present,
                      depth/<camera>/NNNNNN.png (uint16 mm, the fitted template's) for the seams.
                      Without it the dataset's ground-truth part labels and depth are used (said so).
Writes into OUT:
  joints3d.npz   joints (T, 14, 3) optimised, initial (T, 14, 3), scores (T, 14) final joint scores,
                 n_evaluations (T,), seconds (T,), status (T,) text, names (14,)
  metrics.json   MPJPE before/after against ground truth when the dataset has it
  recording.rrd  billboards, candidates, rejections, score curves, seams (rerun viewer); a resumed
                 run writes recording.resume-<k>.rrd beside it
  frames/NNNNNN.json  per-frame results; a frame with one is finished and skipped when the run resumes
  run.json       the dataset and options of this run (another run's folder is refused, or moved
                 aside with --replace-stale)

Options may also come from a TOML file (--config; the keys of
toolkit.pipeline.optimize_joints.OptimizeJointsConfig, the search in an
[optimize] table; flags given here win).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.optimize_joints import OptimizeJointsConfig, run, summary_lines
from toolkit.pipeline.run import load_config


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="dataset folder (docs/dataset_layout.md)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--poses", type=Path, default=None, help="stage-1 output folder (poses3d.npz, offsets.npz)")
    ap.add_argument("--parts", type=Path, default=None, help="stage-2 output folder (parts/, depth/)")
    ap.add_argument("--noise-cm", type=float, default=None,
                    help="without --poses: displace the ground-truth joints by this much (cm, RMS 3D; default 0)")
    ap.add_argument("--seed", type=int, default=None, help="seed of --noise-cm (default 0)")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--sweeps", type=int, default=None, help="most sweeps over the joints (default 4, source 000)")
    ap.add_argument("--no-seams", action="store_true", help="no seam correction")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--workers", type=int, default=None,
                    help="frames at once on a local Dask cluster of N worker processes (default 1: here; "
                         "the outputs are those of one worker, docs/parallel.md)")
    ap.add_argument("--scheduler", default=None, help="run the frames on this Dask scheduler (tcp://HOST:8786)")
    ap.add_argument("--replace-stale", action="store_true",
                    help="if OUT holds results of another dataset or other options, move it to OUT.stale-N "
                         "and start afresh (default: refuse)")
    return ap


def config_from_args(args: argparse.Namespace) -> OptimizeJointsConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(OptimizeJointsConfig, args.config, poses=args.poses, parts=args.parts,
                         noise_cm=args.noise_cm, seed=args.seed, max_frames=args.max_frames,
                         workers=args.workers, scheduler=args.scheduler)
    search = config.optimize if args.sweeps is None else replace(config.optimize, max_sweeps=args.sweeps)
    return replace(config, optimize=search, seams=config.seams and not args.no_seams,
                   recording=config.recording and not args.no_recording,
                   replace_stale=config.replace_stale or args.replace_stale)


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
