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
``state`` (T,) 0 lost / 1 recovering / 2 tracking; ``state_names``; ``observed``
(T, 13); ``explained`` and ``supported`` (T,); ``reason`` (T,); ``frames`` (T,)
file names; ``coordinates``), ``OUT/recording.rrd`` (the depth frames, point
cloud, ORUS grid, normals, curvature centres and osculating spheres, radial
profile, energy terms per iteration and the skeleton, for the rerun viewer),
``OUT/metrics.json`` when there is ground truth, and with ``--images DIR`` one
PNG per frame with the skeleton drawn over the depth.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from toolkit.errors import InputError


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("input", type=Path, help="dataset folder with depth_camera/, or a folder of depth frames")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--size", type=int, nargs=2, metavar=("W", "H"), default=None,
                    help="image size of raw frames and of the default camera (default 640 480)")
    ap.add_argument("--focal", type=float, default=None, help="focal length in pixels of the default camera")
    ap.add_argument("--intrinsics", type=Path, default=None, help="intrinsics.toml for a folder of frames")
    ap.add_argument("--reader", default="auto", choices=["auto", "png", "raw", "open3d", "npy"],
                    help="depth file reader (default: by suffix)")
    ap.add_argument("--background", type=Path, default=None, help="depth file of the empty scene")
    ap.add_argument("--fps", type=float, default=30.0, help="frame rate (default 30)")
    ap.add_argument("--frames", type=int, default=None, help="track at most this many frames")
    ap.add_argument("--bin-size", type=float, default=None, help="ORUS bin size in metres (default 0.05)")
    ap.add_argument("--output", choices=["world", "camera"], default="world",
                    help="output coordinates (world needs a camera pose)")
    ap.add_argument("--independent", action="store_true",
                    help="track each frame on its own (unrelated still frames)")
    ap.add_argument("--images", type=Path, default=None, help="write the skeleton over each depth frame here")
    ap.add_argument("--seed", type=int, default=0, help="seed of the key-point clustering")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)

    from dataclasses import replace

    import numpy as np
    from tqdm import tqdm

    from toolkit.depth import (
        STATE_NAMES, DepthTracker, TrackerConfig, open_depth_input, track_sequence,
    )
    from toolkit.depth.evaluate import draw_skeleton, summarise
    from toolkit.io import atomic_save_npz, atomic_write_png, atomic_write_text
    from toolkit.skeleton import SKELETON_13

    try:
        inp = open_depth_input(args.input, size=args.size, focal_px=args.focal, intrinsics=args.intrinsics,
                               reader=args.reader, background=args.background)
        n = len(inp) if args.frames is None else min(len(inp), max(args.frames, 0))
        cfg = TrackerConfig(fps=args.fps, output=args.output)
        if args.bin_size is not None:
            cfg = replace(cfg, orus=replace(cfg.orus, bin_size_m=args.bin_size))
        args.out.mkdir(parents=True, exist_ok=True)
        observer = None
        if not args.no_recording:
            from toolkit.viz import RerunObserver

            observer = RerunObserver(application_id="depth_tracking", path=args.out / "recording.rrd")
        tracker = DepthTracker(inp.camera, inp.pose_known, cfg, background=inp.background, rng=args.seed,
                               observer=observer)
        bar = tqdm(total=n, unit="frame", disable=args.quiet)
        depths = {}

        def frames():
            for i in range(n):
                d = inp.read(i)
                if args.images is not None:
                    depths[i] = d
                yield d

        def step(r):
            bar.update(1)
            bar.set_postfix(state=STATE_NAMES[r.state])
            if args.images is not None:
                d = depths.pop(r.index)
                uv = tracker.frame.project(r.joints_view)
                lo, hi = np.nanpercentile(d, [1, 99]) if np.isfinite(d).any() else (0.5, 4.5)
                img = draw_skeleton(d, uv, r.observed, f"{inp.frames[r.index].name} {r.state_name}", scale=0.5,
                                    depth_range=(float(lo), float(hi) + 0.3))
                atomic_write_png(args.images / f"skeleton_{r.index:03d}.png", img)  # frame order of the input

        t0 = time.perf_counter()
        try:
            res = track_sequence(tracker, frames(), independent=args.independent, progress=step)
        finally:
            bar.close()
            if observer is not None:
                observer.close()
        wall = time.perf_counter() - t0
        out_npz = atomic_save_npz(
            args.out / "skeleton.npz", joints=res.joints, names=np.array(SKELETON_13.joint_names),
            state=res.states, state_names=np.array(STATE_NAMES), observed=res.observed, explained=res.explained,
            supported=res.supported, reason=res.reasons, frames=np.array([p.name for p in inp.frames[:n]]),
            coordinates=np.array(res.coordinates))
        metrics = None
        if inp.truth is not None and res.coordinates == "world":
            s = summarise(res.joints, inp.truth["joints"][:n], res.states, inp.truth.get("visible", None)[:n]
                          if "visible" in inp.truth else None)
            metrics = {"mpjpe_mm": 1000 * s.mpjpe_m, "mpjpe_visible_mm": 1000 * s.mpjpe_visible_m,
                       "mpjpe_unoccluded_mm": 1000 * s.mpjpe_unoccluded_m, "tracked_share": s.tracked_share,
                       "estimated_share": s.estimated_share, "frames": s.n_frames,
                       "per_point_mm": {k: 1000 * float(v) for k, v in zip(SKELETON_13.joint_names, s.per_point_m)}}
            atomic_write_text(args.out / "metrics.json", json.dumps(metrics, indent=2) + "\n")
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    counts = {name: int((res.states == k).sum()) for k, name in enumerate(STATE_NAMES)}
    cpu = np.nanmedian(res.timings("total")) * 1000 if n else float("nan")
    print(f"tracked {n} frames of {args.input} ({inp.kind}, {inp.camera.size[0]}x{inp.camera.size[1]}) in "
          f"{wall:.1f} s: " + ", ".join(f"{v} {k}" for k, v in counts.items())
          + f"; median {cpu:.1f} ms CPU per frame")
    print(f"  skeleton ({res.coordinates} coordinates): {out_npz}")
    if not args.no_recording:
        print(f"  recording:                  {args.out / 'recording.rrd'}  (open with: rerun {args.out / 'recording.rrd'})")
    if metrics is not None:
        print(f"  metrics:                    {args.out / 'metrics.json'}  (MPJPE {metrics['mpjpe_mm']:.1f} mm, "
              f"{100 * metrics['tracked_share']:.0f} % of frames tracked)")
    if args.images is not None:
        print(f"  images:                     {args.images}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
