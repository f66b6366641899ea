"""CPU seconds per frame of each stage of a free-viewpoint frame, baseline commit against today's code (issue 20).

Both sides run ``toolkit.pipeline.free_viewpoint.run`` on the same dataset
(default: the built-in default scene, as :mod:`benchmarks.bench_speed` makes
it) for the first ``--frames`` frames, single-threaded, without a recording,
each in a fresh process (the baseline from a ``git worktree`` of
``--baseline``, as in :mod:`benchmarks.bench_speed`), with the *same*
silhouette database (the baseline's default one, or ``--db``: the default
database's file name depends on the procedural motions, which other issues
add to).  Each side's process wraps the functions every version has (by
name) with CPU-time counters (``time.process_time``: under a loaded machine
CPU time is the fair measure of "one core"), so the table says where a frame's
time goes before and after:

* ``stage 1``: silhouettes, the database query and the multi-view step, per frame;
* ``segmentation``, ``stage 3 chain`` (seams, the joint search, the
  articulated billboards), ``standard billboards``, ``visual hull``;
* ``background plates``: the synthetic scene's surroundings seen by the
  novel cameras (once per run) and the camera paths' views (every frame);
* ``novel views``: rendering, scoring and writing the novel views (their plates excluded);
* ``path views``: rendering the camera paths' views (plates excluded);
* ``frame``: all of a frame after stage 1 (the rows above and the rest: parts
  and path PNGs, reading the novel views' references, records); ``frame + stage 1`` the whole frame.

Then the outputs are compared (:func:`benchmarks.bench_speed.compare_outputs`:
poses to 1e-9 m, every PNG byte for byte).  Writes ``OUT/stages.json``.
Usage::

    python -m benchmarks.bench_frame_stages --dataset /path/to/default_scene --frames 3
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_speed import BASELINE, ONE_THREAD, ROOT, compare_outputs, default_dataset
from toolkit.io import atomic_write_text

#: What each side runs: counters around functions both versions have, then the run.
SIDE = r"""
import functools, importlib, json, sys, time
from pathlib import Path
import cv2
cv2.setNumThreads(1)
from threadpoolctl import threadpool_limits
threadpool_limits(1)
import toolkit
acc = {}

def timed(mod, name, key, generator=False):
    m = importlib.import_module(mod)
    owner, attr = (getattr(m, name.split(".")[0]), name.split(".")[1]) if "." in name else (m, name)
    f = getattr(owner, attr)

    def count(t):
        acc[key] = acc.get(key, 0.0) + time.process_time() - t

    def gen(*a, **k):
        it = f(*a, **k)
        while True:
            t = time.process_time()
            try:
                v = next(it)
            except StopIteration:
                count(t)
                return
            count(t)
            yield v

    def call(*a, **k):
        t = time.process_time()
        try:
            return f(*a, **k)
        finally:
            count(t)
    setattr(owner, attr, functools.wraps(f)(gen if generator else call))

timed("toolkit.silhouettes.pipeline", "estimate_dataset", "stage1", generator=True)
timed("toolkit.segmentation", "segment_frame", "segmentation")
timed("toolkit.pipeline.stage3", "optimize_frame", "stage3_chain")
timed("toolkit.rendering.baselines", "standard_billboards", "standard_billboards")
timed("toolkit.rendering.baselines", "visual_hull", "visual_hull")
timed("toolkit.rendering.evaluation", "BackgroundPlates.plate", "plates")
timed("toolkit.pipeline.views", "render_evaluation", "novel_views")
timed("toolkit.rendering.freeviewpoint", "render_methods", "path_views")
timed("toolkit.pipeline.free_viewpoint", "_Frames.__call__", "frame")
from toolkit.pipeline.free_viewpoint import FreeViewpointRunConfig, run
from toolkit.silhouettes import default_database_path

dataset, out, frames, db = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
db = Path(db) if db else default_database_path()
c0, w0 = time.process_time(), time.perf_counter()
one = {"workers": 1} if "workers" in FreeViewpointRunConfig.__dataclass_fields__ else {}  # the counters: here
res = run(FreeViewpointRunConfig(max_frames=frames, recording=False, progress=False, db=db, **one), dataset=dataset,
          out=out, log=None)
acc.update(run_cpu=time.process_time() - c0, run_wall=time.perf_counter() - w0)
print("SIDE-RESULT " + json.dumps({"toolkit": toolkit.__file__, "db": str(db), "processed": res.processed,
                                   "cpu": acc, "seconds_per_frame": res.metrics.get("seconds_per_frame", {})}))
"""

#: Rows of the table: (label, how a side's per-frame CPU seconds are read from its counters).
ROWS = (("stage 1", lambda c: c.get("stage1", 0.0)),
        ("segmentation", lambda c: c.get("segmentation", 0.0)),
        ("stage 3 chain", lambda c: c.get("stage3_chain", 0.0)),
        ("standard billboards", lambda c: c.get("standard_billboards", 0.0)),
        ("visual hull", lambda c: c.get("visual_hull", 0.0)),
        ("background plates", lambda c: c.get("plates", 0.0)),
        ("novel views", lambda c: c.get("novel_views", 0.0)),
        ("path views", lambda c: c.get("path_views", 0.0)),
        ("rest of the frame", lambda c: c.get("frame", 0.0) - sum(c.get(k, 0.0) for k in (
            "segmentation", "stage3_chain", "standard_billboards", "visual_hull", "plates", "novel_views",
            "path_views"))),
        ("frame (after stage 1)", lambda c: c.get("frame", 0.0)),
        ("frame + stage 1", lambda c: c.get("frame", 0.0) + c.get("stage1", 0.0)))


def run_side(name: str, code_root: Path, dataset: Path, out: Path, frames: int, db: str) -> dict:
    """One side in a fresh single-threaded process: its CPU counters (per frame) and outputs."""
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, **ONE_THREAD, "PYTHONPATH": str(code_root)}
    print(f"{name}: {code_root} ...", flush=True)
    proc = subprocess.run([sys.executable, "-c", SIDE, str(dataset), str(out), str(frames), db], cwd=code_root,
                          env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-4000:] + proc.stderr[-4000:])
        raise SystemExit(f"{name}: the run failed (exit {proc.returncode})")
    res = json.loads([ln for ln in proc.stdout.splitlines() if ln.startswith("SIDE-RESULT ")][-1][12:])
    if not Path(res["toolkit"]).resolve().is_relative_to(code_root.resolve()):
        raise SystemExit(f"{name}: imported {res['toolkit']}, not the code in {code_root}")
    n = max(res["processed"], 1)
    res["per_frame"] = {label: f(res["cpu"]) / n for label, f in ROWS}
    res.update(name=name, out=str(out))
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dataset", type=Path, help="dataset folder (default: the default scene, generated into --cache)")
    ap.add_argument("--frames", type=int, default=3, help="frames run on each side")
    ap.add_argument("--baseline", default=BASELINE, help="commit of the baseline side")
    ap.add_argument("--baseline-dir", type=Path, default=None,
                    help="the baseline's code as a folder (e.g. `git archive COMMIT | tar -x -C DIR`) instead of a "
                         "git worktree of --baseline")
    ap.add_argument("--db", type=Path, help="silhouette database of both sides (default: the baseline's default)")
    ap.add_argument("--cache", type=Path, default=ROOT / "out" / "cache")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench_frame_stages")
    args = ap.parse_args(argv)
    if args.frames < 1:
        ap.error("--frames must be >= 1")
    dataset = args.dataset if args.dataset is not None else default_dataset(args.cache)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.baseline_dir is not None:
        base = run_side("baseline", args.baseline_dir.resolve(), dataset, args.out / "baseline", args.frames,
                        str(args.db or ""))
        new = run_side("new", ROOT, dataset, args.out / "new", args.frames, base["db"])
    else:
        with tempfile.TemporaryDirectory(prefix="bench_frame_stages_") as tmp:
            base_root = Path(tmp) / "baseline"
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(base_root), args.baseline],
                           check=True, capture_output=True)
            try:
                base = run_side("baseline", base_root, dataset, args.out / "baseline", args.frames,
                                str(args.db or ""))
                new = run_side("new", ROOT, dataset, args.out / "new", args.frames, base["db"])
            finally:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_root)],
                               capture_output=True)
    cmp = compare_outputs(args.out / "baseline", args.out / "new")
    print(f"\n{'CPU seconds per frame':<24}{'baseline':>10}{'new':>10}{'speed-up':>10}")
    for label, _ in ROWS:
        a, b = base["per_frame"][label], new["per_frame"][label]
        print(f"{label:<24}{a:10.2f}{b:10.2f}" + (f"{a / b:9.2f}x" if b > 1e-9 else ""))
    print(f"\n{args.frames} frames of {dataset}, database {base['db']}, baseline "
          f"{args.baseline_dir or args.baseline[:12]}")
    print(f"outputs: poses max difference {cmp['pose_max_diff_m']:.3g} m, {cmp['images_identical']} of "
          f"{cmp['images']} images byte-identical -> {'IDENTICAL' if cmp['identical'] else 'DIFFERENT'}")
    for d in cmp["differences"][:40]:
        print("  " + d)
    atomic_write_text(args.out / "stages.json", json.dumps({"dataset": str(dataset), "frames": args.frames,
                                                            "baseline": base, "new": new, "outputs": cmp},
                                                           indent=2, allow_nan=True))
    print(f"\nwrote {args.out / 'stages.json'}")
    return 0 if cmp["identical"] else 1


if __name__ == "__main__":
    sys.exit(main())
