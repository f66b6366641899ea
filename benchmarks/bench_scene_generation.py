#!/usr/bin/env python3
"""Scene-generation throughput: frames per second per camera at 1280x720.

Usage::

    python benchmarks/bench_scene_generation.py [--frames 10] [--engine raycast open3d]

Renders a broadcast scene with 3 cameras for each engine and reports the
time per camera-frame of each step (mesh, colour render, label/depth ray
cast, writing PNG/MP4 files) and the overall camera-frames per second.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from toolkit.synthetic import generate_scene, parse_spec

SPEC = """
seed = 5
frames = {frames}
fps = 25
[subject]
height_m = 1.78
motion = "walk"
[cameras]
count = 3
layout = "{layout}"
resolution = [1280, 720]
calibration_error_px = 8.0
[novel]
count = 0
[render]
engine = "{engine}"
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--engine", nargs="+", default=["raycast", "open3d"])
    ap.add_argument("--layout", default="broadcast", choices=["broadcast", "studio"])
    args = ap.parse_args(argv)
    print(f"{'engine':8s} {'layout':9s} {'frames':>6s} {'cams':>4s} {'total s':>8s} {'cam-frames/s':>12s}")
    for engine in args.engine:
        spec = parse_spec(SPEC.format(frames=args.frames, engine=engine, layout=args.layout), "bench.toml")
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            generate_scene(spec, Path(tmp) / "scene", progress=False).close()
            dt = time.perf_counter() - t0
        n = args.frames * spec.camera_count
        print(f"{engine:8s} {args.layout:9s} {args.frames:6d} {spec.camera_count:4d} {dt:8.2f} {n / dt:12.2f}",
              flush=True)


if __name__ == "__main__":
    main()
