#!/usr/bin/env python3
"""Render a silhouette database for recipes/pose_from_silhouettes.py.

Usage::

    python recipes/build_silhouette_db.py --out silhouettes.npz                  # the default (20 480 entries)
    python recipes/build_silhouette_db.py --out big.npz --sequences 10           # ~51 000 entries
    python recipes/build_silhouette_db.py --out mine.npz --bvh walk.bvh jump.bvh --motions walk,run

The synthetic body is posed in frames of the procedural motions (several
seeded people per motion) and of any BVH files, and seen from virtual cameras
all around it (elevations 0-35 degrees, 4-40 m away, the subject about 120 px
tall); every silhouette, resampled to 32 x 40, is stored with its 2D joints
normalised to its bounding box, plus its mirror image.  See
docs/stage1_silhouettes.md.

Options may also come from a TOML file (--config; the keys of
toolkit.pipeline.silhouette_db.SilhouetteDatabaseRunConfig, what goes into the
database in a [build] table with the fields of toolkit.silhouettes.BuildConfig,
e.g. ``views_per_pose = 24``; unknown keys are refused; flags given here win).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.run import load_config
from toolkit.pipeline.silhouette_db import SilhouetteDatabaseRunConfig, run, summary_lines
from toolkit.silhouettes.building import DEFAULT_BUILD, DEFAULT_SEED


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    d = DEFAULT_BUILD
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--out", type=Path, required=True, help="database file to write (.npz)")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--motions", default=None,
                    help=f"comma-separated procedural motions (default: {','.join(d.motions)}; '' for none)")
    ap.add_argument("--sequences", type=int, default=None,
                    help=f"seeded people per motion (default {d.sequences_per_motion})")
    ap.add_argument("--frames", type=int, default=None,
                    help=f"frames per sequence at {d.fps:g} fps (default {d.frames_per_sequence})")
    ap.add_argument("--stride", type=int, default=None, help=f"one pose every N frames (default {d.frame_stride})")
    ap.add_argument("--views", type=int, default=None, help=f"viewpoints per pose (default {d.views_per_pose})")
    ap.add_argument("--bvh", type=Path, nargs="*", default=None, help="BVH files to add (CMU or write_bvh layout)")
    ap.add_argument("--no-mirror", action="store_true", help="do not add mirror images")
    ap.add_argument("--flow", action="store_true", help="also store optical-flow descriptors")
    ap.add_argument("--seed", type=int, default=None, help=f"random seed (default {DEFAULT_SEED})")
    ap.add_argument("--workers", type=int, default=None, help="parallel processes (default: all cores)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    return ap


def config_from_args(args: argparse.Namespace) -> SilhouetteDatabaseRunConfig:
    """The build's config: the --config file (or the defaults), then the flags given."""
    config = load_config(SilhouetteDatabaseRunConfig, args.config, seed=args.seed, workers=args.workers,
                         bvh=tuple(args.bvh) if args.bvh is not None else None)
    motions = None if args.motions is None else tuple(m.strip() for m in args.motions.split(",") if m.strip())
    given = {"motions": motions, "sequences_per_motion": args.sequences, "frames_per_sequence": args.frames,
             "frame_stride": args.stride, "views_per_pose": args.views}
    build = replace(config.build, **{k: v for k, v in given.items() if v is not None})
    build = replace(build, mirror=build.mirror and not args.no_mirror, with_flow=build.with_flow or args.flow)
    return replace(config, build=build, progress=config.progress and not args.quiet)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        result = run(config_from_args(args), out=args.out, log=lambda line: print(line, flush=True))
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print("\n".join(summary_lines(result)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
