#!/usr/bin/env python3
"""Fit and track the 13-point skeleton in depth frames (source 001).

Usage::

    python recipes/depth_tracking.py out/depth_wave --out out/depth_wave_track
    python recipes/depth_tracking.py ../shared/realdata/kinect_depth --out out/kinect --independent \\
        --images docs/images/depth

INPUT is either

* a dataset folder with ``depth_camera/`` (``intrinsics.toml`` with K, size and
  ``cam_from_world``; ``depth/NNNNNN.png``; optional ``background.png``), as
  ``recipes/make_scene.py`` writes it for a spec with a ``[depth_camera]`` table;
  ground truth in ``groundtruth/skeleton13.npz`` is scored when present;
* or a folder of depth frames (16-bit PNG, raw little-endian uint16 millimetres,
  Open3D images, ``.npy``), in natural file-name order.  The camera is
  ``--intrinsics FILE`` if given, else a Kinect-v1-like camera of ``--size``
  (default 640 x 480) with focal length ``--focal`` (default 585 px scaled to the
  width) looking level; without a camera pose the output is in camera
  coordinates (x right, y down, z forward, metres).

Writes ``OUT/skeleton.npz`` (``joints`` (T, 13, 3) metres in world coordinates
when the camera pose is known, else camera coordinates; ``names`` (13,);
``state`` (T,) 0 lost (NaN joints: no depth, no person, a flat surface such as a wall; the summary counts
them) / 1 recovering / 2 tracking; ``state_names``; ``observed``
(T, 13); ``explained`` and ``supported`` (T,); ``reason`` (T,); ``frames`` (T,)
file names; ``coordinates``; ``status``; ``unreadable``), ``OUT/recording.rrd`` (the depth frames, point
cloud, ORUS grid, normals, curvature centres and osculating spheres, radial
profile, energy terms per iteration and the skeleton, for the rerun viewer),
``OUT/metrics.json`` when there is ground truth, and with ``--images DIR`` one
PNG per frame with the skeleton drawn over the depth.

Several inputs are several sequences, each tracked into ``OUT/<its folder's
name>/`` (``--workers N``: N at a time on this machine; ``--scheduler
tcp://HOST:PORT``: on a Dask cluster, docs/parallel.md).  One run is one sequence.  ``OUT/run.json`` identifies it (the input's frames,
camera and background by content, and the options that change the results): a
folder of another input or other options is refused (``--replace-stale`` moves
it aside); the same run again tracks from the first frame and replaces the
results.  Ctrl-C writes the frames tracked so far (``status`` "interrupted" in
``skeleton.npz``; never over a complete run's), an unreadable frame file is
tracked as a frame without depth and named (``unreadable`` (T,) in
``skeleton.npz``), and float ``.npy`` depth must be metres.  Options may also come from a TOML file (--config; the keys of
toolkit.pipeline.depth_tracking.DepthTrackingRunConfig, the tracker's in a
[tracker] table, e.g. ``[tracker.orus] bin_size_m = 0.06``; flags given on the
command line win).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.depth_tracking import READERS, DepthTrackingRunConfig, run, run_sequences, summary_lines
from toolkit.pipeline.run import load_config


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("input", type=Path, nargs="+",
                    help="dataset folder with depth_camera/, or a folder of depth frames; several: each sequence "
                         "into OUT/<its name>/")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--size", type=int, nargs=2, metavar=("W", "H"), default=None,
                    help="image size of raw frames and of the default camera (default 640 480)")
    ap.add_argument("--focal", type=float, default=None, help="focal length in pixels of the default camera")
    ap.add_argument("--intrinsics", type=Path, default=None, help="intrinsics.toml for a folder of frames")
    ap.add_argument("--reader", default=None, choices=READERS, help="depth file reader (default: by suffix)")
    ap.add_argument("--background", type=Path, default=None, help="depth file of the empty scene")
    ap.add_argument("--fps", type=float, default=None, help="frame rate (default 30)")
    ap.add_argument("--frames", type=int, default=None, help="track at most this many frames")
    ap.add_argument("--bin-size", type=float, default=None, help="ORUS bin size in metres (default 0.05)")
    ap.add_argument("--output", choices=["world", "camera"], default=None,
                    help="output coordinates (world needs a camera pose; default world)")
    ap.add_argument("--independent", action="store_true",
                    help="track each frame on its own (unrelated still frames)")
    ap.add_argument("--images", type=Path, default=None, help="write the skeleton over each depth frame here")
    ap.add_argument("--seed", type=int, default=None, help="seed of the key-point clustering (default 0)")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--replace-stale", action="store_true",
                    help="if OUT holds results of another input or other options, move it to OUT.stale-N "
                         "and start afresh (default: refuse)")
    ap.add_argument("--workers", type=int, default=None,
                    help="several sequences in parallel on N local worker processes (default 1)")
    ap.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                    help="several sequences on a running Dask cluster (docs/parallel.md)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    return ap


def config_from_args(args: argparse.Namespace) -> DepthTrackingRunConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(DepthTrackingRunConfig, args.config, size=tuple(args.size) if args.size else None,
                         focal=args.focal, intrinsics=args.intrinsics, reader=args.reader,
                         background=args.background, max_frames=args.frames, images=args.images, seed=args.seed,
                         workers=args.workers, scheduler=args.scheduler)
    tracker = config.tracker
    if args.bin_size is not None:
        tracker = replace(tracker, orus=replace(tracker.orus, bin_size_m=args.bin_size))
    tracker = replace(tracker, **{k: v for k, v in (("fps", args.fps), ("output", args.output)) if v is not None})
    return replace(config, tracker=tracker, independent=config.independent or args.independent,
                   recording=config.recording and not args.no_recording,
                   replace_stale=config.replace_stale or args.replace_stale, progress=config.progress and not args.quiet)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        config = config_from_args(args)
        results = [run(config, dataset=args.input[0], out=args.out)] if len(args.input) == 1 else \
            run_sequences(config, datasets=args.input, out=args.out)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for result in results:
        print("\n".join(summary_lines(result)))
    return 130 if any(r.stopped for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
