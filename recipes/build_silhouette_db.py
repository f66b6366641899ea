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
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from toolkit.errors import InputError


def main(argv=None) -> int:
    from toolkit.silhouettes import DEFAULT_BUILD, DEFAULT_SEED

    d = DEFAULT_BUILD
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--out", type=Path, required=True, help="database file to write (.npz)")
    ap.add_argument("--motions", default=",".join(d.motions),
                    help=f"comma-separated procedural motions (default: {','.join(d.motions)}; '' for none)")
    ap.add_argument("--sequences", type=int, default=d.sequences_per_motion,
                    help=f"seeded people per motion (default {d.sequences_per_motion})")
    ap.add_argument("--frames", type=int, default=d.frames_per_sequence,
                    help=f"frames per sequence at {d.fps:g} fps (default {d.frames_per_sequence})")
    ap.add_argument("--stride", type=int, default=d.frame_stride,
                    help=f"one pose every N frames (default {d.frame_stride})")
    ap.add_argument("--views", type=int, default=d.views_per_pose,
                    help=f"viewpoints per pose (default {d.views_per_pose})")
    ap.add_argument("--bvh", type=Path, nargs="*", default=(), help="BVH files to add (CMU or write_bvh layout)")
    ap.add_argument("--no-mirror", action="store_true", help="do not add mirror images")
    ap.add_argument("--flow", action="store_true", help="also store optical-flow descriptors")
    ap.add_argument("--seed", type=int, default=DEFAULT_SEED, help=f"random seed (default {DEFAULT_SEED})")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="parallel processes (default: all cores)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)

    from dataclasses import replace

    from tqdm import tqdm

    from toolkit.silhouettes import build_database

    try:
        motions = tuple(m for m in args.motions.split(",") if m.strip())
        config = replace(d, motions=tuple(m.strip() for m in motions), sequences_per_motion=args.sequences,
                         frames_per_sequence=args.frames, frame_stride=args.stride, views_per_pose=args.views,
                         mirror=not args.no_mirror, with_flow=args.flow)
        total = len(config.motions) * config.sequences_per_motion + len(args.bvh)
        if total == 0:
            raise InputError("--motions / --bvh", "at least one motion or BVH file", "none")
        print(f"rendering about {config.n_entries} entries from {total} sequences"
              f"{' + BVH' if args.bvh else ''} with {args.workers} worker(s) ...", flush=True)
        bar = tqdm(total=total, desc="sequences", unit="seq", disable=args.quiet)

        def progress(done, _total):
            bar.update(done - bar.n)

        t0 = time.perf_counter()
        db = build_database(config, args.seed, bvh_files=args.bvh, workers=args.workers, progress=progress)
        bar.close()
        dt = time.perf_counter() - t0
        path = db.save(args.out)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path}: {len(db)} entries in {dt:.1f} s ({len(db) / dt:.0f} entries/s), "
          f"{path.stat().st_size / 1e6:.1f} MB")
    print(f"use it with: python recipes/pose_from_silhouettes.py DATASET --out OUT --db {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
