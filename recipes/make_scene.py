#!/usr/bin/env python3
"""Render a synthetic multi-camera scene with exact ground truth.

Usage::

    python recipes/make_scene.py datasets_synthetic/default.toml --out out/default

Writes the dataset layout of ``docs/dataset_layout.md`` into ``--out`` and a
rerun recording ``scene.rrd`` of the scene and its ground truth.  A spec with
a ``[markers]`` table is a marker capture: only the calibration, the 2D marker
blobs and the ground truth are written (``toolkit/io/marker_files.py``), no videos.

The dataset is written into a hidden folder beside ``--out`` and renamed to
``--out`` only once complete, so an error or Ctrl-C leaves ``--out`` as it was.
An ``--out`` that holds files is refused; ``--overwrite`` replaces it (once the
new dataset is complete).  A spec whose rendering would not fit in the memory
available is refused before the first frame, with the estimate.
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
    ap.add_argument("--out", type=Path, required=True, help="dataset folder to write (new or empty)")
    ap.add_argument("--overwrite", action="store_true",
                    help="replace an --out that holds files (once the new dataset is complete)")
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
    from toolkit.io.runs import staged_folder
    from toolkit.synthetic import generate_scene, load_spec
    from toolkit.synthetic.memory import check_render_memory

    try:
        spec = load_spec(args.spec)
        if spec.markers is None:
            check_render_memory(spec)
        t0 = time.perf_counter()
        with staged_folder(args.out, overwrite=args.overwrite) as stage:
            observer = None
            if not args.no_recording:
                from toolkit.viz import RerunObserver

                observer = RerunObserver(application_id="make_scene", path=stage / "scene.rrd",
                                         camera_names=spec.camera_names)
            try:
                if spec.markers is not None:  # a marker capture: no videos
                    from toolkit.synthetic.marker_capture import generate_marker_capture

                    info = generate_marker_capture(spec, stage, observer=observer)
                else:
                    ds = generate_scene(spec, stage, observer=observer, progress=not args.quiet)
                    ds.close()
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
