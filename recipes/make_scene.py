#!/usr/bin/env python3
"""Render a synthetic multi-camera scene with exact ground truth.

Usage::

    python recipes/make_scene.py datasets_synthetic/default.toml --out out/default

Writes the dataset layout of ``docs/dataset_layout.md`` into ``--out`` and a
rerun recording ``scene.rrd`` of the scene and its ground truth.  A spec with
a ``[markers]`` table is a marker capture: only the calibration, the 2D marker
blobs and the ground truth are written (``toolkit/io/marker_files.py``), no videos.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from toolkit.errors import InputError


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (the scene spec TOML is its config)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("spec", type=Path, help="scene spec TOML (see datasets_synthetic/README.md)")
    ap.add_argument("--out", type=Path, required=True, help="dataset folder to write")
    ap.add_argument("--no-recording", action="store_true", help="do not write scene.rrd")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    return ap


def _marker_summary(args, info: dict, dt: float) -> None:
    print(f"wrote marker capture {args.out} ({info['n_frames']} frames x {len(info['cameras'])} cameras,"
          f" {info['n_markers']} {info['marker_set']} markers) in {dt:.1f} s")
    print(f"  calibration (measured): {args.out / 'markers' / 'calibration.toml'}")
    print(f"  2D blobs:               {args.out / 'markers' / 'detections'}/<camera>.npz")
    print(f"  ground truth:           {args.out / 'groundtruth'}")


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    from toolkit.synthetic import generate_scene, load_spec

    try:
        spec = load_spec(args.spec)
        observer = None
        if not args.no_recording:
            from toolkit.viz import RerunObserver

            observer = RerunObserver(application_id="make_scene", path=args.out / "scene.rrd",
                                     camera_names=spec.camera_names)
        t0 = time.perf_counter()
        try:
            if spec.markers is not None:  # a marker capture: no videos
                from toolkit.synthetic.marker_capture import generate_marker_capture

                info = generate_marker_capture(spec, args.out, observer=observer)
            else:
                ds = generate_scene(spec, args.out, observer=observer, progress=not args.quiet)
        finally:
            if observer is not None:
                observer.close()
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    dt = time.perf_counter() - t0
    if spec.markers is not None:
        _marker_summary(args, info, dt)
        return 0
    print(f"wrote dataset {args.out} ({ds.n_frames} frames x {len(ds.camera_names)} cameras"
          f" + {spec.novel_count} novel) in {dt:.1f} s")
    print(f"  calibration (measured): {args.out / 'calibration.toml'}")
    print(f"  videos:                 {args.out / 'videos'}/<camera>.mp4")
    print(f"  ground truth:           {args.out / 'groundtruth'}")
    if not args.no_recording:
        print(f"  recording:              {args.out / 'scene.rrd'}   (open with: rerun {args.out / 'scene.rrd'})")
    ds.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
