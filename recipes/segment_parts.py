#!/usr/bin/env python3
"""Stage 2 of the articulated-billboard pipeline: body-part labels for every camera and frame.

Usage::

    python recipes/segment_parts.py out/default --out out/default_parts --poses out/default_stage1
    python recipes/segment_parts.py out/default --out out/default_parts --gt-joints --gt-masks

Per camera and frame: the generic template is fitted exactly to the 2D pose
(source 000 §2.2), projected thinned and thickened, and the silhouette split
into confident and uncertain pixels; one Gaussian mixture per part is learned
from the confident pixels and labels the uncertain ones (colour then nearest
part), and a closing removes outliers (§2.3).  Writes into OUT:

  parts/<camera>/NNNNNN.png   part ids 1..10 (ids of groundtruth/parts), 0 background
  recording.rrd               template labels (thin, thick), confident and uncertain
                              masks, final labels, per-part model summaries (a resumed run
                              writes recording.resume-<k>.rrd beside it)
  frames/NNNNNN.json          per frame: parts without a colour model, IoU per camera; a frame
                              with one is finished and skipped when the run resumes
  run.json                    the dataset and options of this run (another run's folder is refused,
                              or moved aside with --replace-stale)

Poses: ``--poses STAGE1_OUT`` (poses3d.npz, poses2d.npz, offsets.npz of
recipes/pose_from_silhouettes.py, measured calibration plus offsets) or
``--gt-joints`` (ground-truth joints and the true calibration).  Silhouettes:
foreground extraction (median background), or ``--gt-masks``.  Settings:
``--config FILE.toml`` with the keys of
``toolkit.pipeline.segment_parts.SegmentPartsConfig`` and a ``[segmentation]``
table of ``toolkit.segmentation.SegmentationConfig`` fields
(docs/stage2_segmentation.md); flags given here win.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.run import load_config
from toolkit.pipeline.segment_parts import SegmentPartsConfig, run, summary_lines
from toolkit.segmentation.pipeline import TEMPLATE_POSES


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="dataset folder (docs/dataset_layout.md)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--poses", type=Path, default=None, help="output folder of recipes/pose_from_silhouettes.py")
    src.add_argument("--gt-joints", action="store_true", help="use the ground-truth joints and calibration")
    ap.add_argument("--gt-masks", action="store_true", help="use the ground-truth silhouettes")
    ap.add_argument("--template-pose", choices=TEMPLATE_POSES, default=None,
                    help="fit the template to the stage-1 3D joints projected (multiview, default) or to each "
                         "view's stage-1 2D pose (per_view)")
    ap.add_argument("--config", type=Path, default=None,
                    help="TOML file with a [segmentation] table (and any SegmentPartsConfig key)")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--replace-stale", action="store_true",
                    help="if OUT holds results of another dataset or other options, move it to OUT.stale-N "
                         "and start afresh (default: refuse)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    ap.add_argument("--workers", type=int, default=None,
                    help="frames at once on a local Dask cluster of N worker processes (default 1: here; "
                         "the outputs are those of one worker, docs/parallel.md)")
    ap.add_argument("--scheduler", default=None, help="run the frames on this Dask scheduler (tcp://HOST:8786)")
    return ap


def config_from_args(args: argparse.Namespace) -> SegmentPartsConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(SegmentPartsConfig, args.config, poses=args.poses, template_pose=args.template_pose,
                         max_frames=args.max_frames, workers=args.workers, scheduler=args.scheduler)
    return replace(config, gt_joints=config.gt_joints or args.gt_joints, gt_masks=config.gt_masks or args.gt_masks,
                   recording=config.recording and not args.no_recording,
                   replace_stale=config.replace_stale or args.replace_stale,
                   progress=config.progress and not args.quiet)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        result = run(config_from_args(args), dataset=args.dataset, out=args.out)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print("\n".join(summary_lines(result)))
    return 130 if result.stopped else 0


if __name__ == "__main__":
    sys.exit(main())
