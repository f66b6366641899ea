"""Speed of the free-viewpoint pipeline, today's code against a baseline commit, side by side in one run (issue 20).

Both sides run ``toolkit.pipeline.free_viewpoint.run`` on the same dataset
(default: the built-in default scene, ``datasets_synthetic/default.toml``,
generated once into ``--cache``; ``--dataset`` takes any dataset folder) for
the first ``--frames`` frames, single-threaded (``OMP_NUM_THREADS=1`` and the
BLAS variables, ``threadpoolctl``, ``cv2.setNumThreads(1)``), without a
recording.  The baseline is a ``git worktree`` of ``--baseline`` made in a
temporary folder and run as a subprocess with that folder as its working
directory and ``PYTHONPATH``, so it imports its own ``toolkit``, not the
editable install's; the working tree's side runs the same way from this
checkout.  Each side is one fresh process.

Reported per side (from the run's ``metrics.json`` ``seconds_per_frame``, the
mean over the frames): the stage-3 search (``optimize``: the position scorer
and the joint search) and the whole frame (``total``: segmentation to the last
rendered and scored view; stage 1 and the run's setup are outside it; the
run's wall time per frame is printed too), and their ratios.  Then the check
that both sides produced the same results: the poses (``poses3d.npz``, every
array equal to 1e-9 m, NaN where the other side has NaN) and every PNG the
runs wrote (parts, novel views, baselines, camera paths), byte for byte; each
difference is listed (the file, and for images of equal shape the largest
pixel difference).

``--workers N`` (N > 1) runs the working tree's side on a local Dask cluster
(``FreeViewpointRunConfig.workers``, docs/parallel.md) and the baseline as it
is (sequential); the outputs must still be identical.

Writes ``OUT/speed.json`` (both sides' timings, ratios, the comparison).

``--stages`` measures the working tree alone instead: seconds per frame per
stage (``metrics.json`` ``seconds_per_frame``), the frames' wall time per frame,
the CPU time and the peak resident memory of the whole process tree (the
workers' included), on the default scene, the first zoo scene of
``--zoo-seed`` and the real balancing trial at full resolution with a camera
held out, each with ``--workers 1`` and ``--workers auto``; writes
``OUT/stages.json``.
Usage::

    python -m benchmarks.bench_speed --frames 4
    python -m benchmarks.bench_speed --stages --frames 8
    python -m benchmarks.bench_speed --dataset /path/to/default_scene --frames 4 --out out/bench_speed
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

import numpy as np

from toolkit.io import atomic_write_text

ROOT = Path(__file__).resolve().parents[1]
#: The code before issue 20 ("today's code" of the issue).
BASELINE = "373b53b1ae69e579c76b4684a3dff95abbbddccc"
#: Poses are the same when every coordinate agrees to this, metres.
POSE_TOL_M = 1e-9
#: Environment of a single-threaded side.
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "NUMEXPR_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1"}

#: What each side runs (``python -c``), with only the public API both sides have.
SIDE = r"""
import json, sys, time
import cv2
cv2.setNumThreads(1)
from threadpoolctl import threadpool_limits
threadpool_limits(1)
try:
    import open3d as o3d
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
except Exception:
    pass
import toolkit
from toolkit.pipeline.free_viewpoint import FreeViewpointRunConfig, run

dataset, out, frames, workers = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
kw = dict(max_frames=frames, recording=False, progress=False)
if workers > 1 or "workers" in FreeViewpointRunConfig.__dataclass_fields__:  # explicit: the default is "auto"
    kw["workers"] = workers
t0 = time.perf_counter()
res = run(FreeViewpointRunConfig(**kw), dataset=dataset, out=out, log=None)
wall = time.perf_counter() - t0
print("SIDE-RESULT " + json.dumps({"toolkit": toolkit.__file__, "wall_s": wall, "processed": res.processed,
                                   "seconds_per_frame": res.metrics.get("seconds_per_frame", {})}))
"""


def default_dataset(cache: Path) -> Path:
    """The built-in default scene, generated into ``cache`` the first time."""
    from toolkit.synthetic import generate_scene
    from toolkit.synthetic.spec import parse_spec

    out = cache / "default_scene"
    if not (out / "scene.toml").exists():
        print(f"generating the default scene into {out} (once)", flush=True)
        tmp = cache / "default_scene.partial"
        shutil.rmtree(tmp, ignore_errors=True)
        generate_scene(parse_spec((ROOT / "datasets_synthetic" / "default.toml").read_text()), tmp, progress=False)
        tmp.rename(out)
    return out


def run_side(name: str, code_root: Path, dataset: Path, out: Path, frames: int, workers: int) -> dict:
    """Run one side in a fresh single-threaded process; its timings and where its outputs are."""
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, **ONE_THREAD, "PYTHONPATH": str(code_root)}
    print(f"{name}: {code_root} ...", flush=True)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", SIDE, str(dataset), str(out), str(frames), str(workers)],
                          cwd=code_root, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-4000:] + proc.stderr[-4000:])
        raise SystemExit(f"{name}: the run failed (exit {proc.returncode})")
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("SIDE-RESULT ")][-1]
    res = json.loads(line[len("SIDE-RESULT "):])
    if not Path(res["toolkit"]).resolve().is_relative_to(code_root.resolve()):
        raise SystemExit(f"{name}: imported {res['toolkit']}, not the code in {code_root}")
    res.update(name=name, code=str(code_root), out=str(out), process_s=time.perf_counter() - t0)
    return res


def compare_outputs(a: Path, b: Path) -> dict:
    """Poses to :data:`POSE_TOL_M` and every PNG byte for byte; the differences found."""
    import cv2

    diffs = []
    pa, pb = np.load(a / "poses3d.npz"), np.load(b / "poses3d.npz")
    pose_max = 0.0
    for k in sorted(set(pa.files) | set(pb.files)):
        if k not in pa.files or k not in pb.files:
            diffs.append(f"poses3d.npz: {k} only on one side")
            continue
        x, y = pa[k], pb[k]
        if x.dtype.kind == "f":
            same_nan = np.array_equal(np.isnan(x), np.isnan(y))
            d = float(np.nanmax(np.abs(x - y))) if x.shape == y.shape and np.isfinite(x).any() else 0.0
            pose_max = max(pose_max, d) if k.startswith("joints") else pose_max
            if x.shape != y.shape or not same_nan or d > POSE_TOL_M:
                diffs.append(f"poses3d.npz: {k} differs (max {d:.3g} m)")
        elif not np.array_equal(x, y):
            diffs.append(f"poses3d.npz: {k} differs")
    # where the differences start: frames whose stage-1 joints differ, frames whose final joints differ
    frames = {}
    for k in ("joints_stage1", "joints"):
        if k in pa.files and k in pb.files and pa[k].shape == pb[k].shape:
            d = np.abs(np.nan_to_num(pa[k], nan=0.0) - np.nan_to_num(pb[k], nan=0.0)).reshape(len(pa[k]), -1).max(axis=1)
            frames[k] = [int(t) for t in np.flatnonzero((d > POSE_TOL_M) | np.any(np.isnan(pa[k]) != np.isnan(pb[k]),
                                                                                  axis=(1, 2)))]
    for k, ts in frames.items():
        if ts:
            diffs.append(f"poses3d.npz: {k} differ in frames {ts}")
    ia = {p.relative_to(a) for p in a.rglob("*.png")}
    ib = {p.relative_to(b) for p in b.rglob("*.png")}
    for p in sorted(ia ^ ib):
        diffs.append(f"{p}: only in {'baseline' if p in ia else 'new'}")
    n_same = 0
    for p in sorted(ia & ib):
        if (a / p).read_bytes() == (b / p).read_bytes():
            n_same += 1
            continue
        x, y = cv2.imread(str(a / p), cv2.IMREAD_UNCHANGED), cv2.imread(str(b / p), cv2.IMREAD_UNCHANGED)
        if x is not None and y is not None and x.shape == y.shape:
            d = np.abs(x.astype(np.int64) - y.astype(np.int64))
            diffs.append(f"{p}: {int(np.count_nonzero(d))} values differ, by up to {int(d.max())}")
        else:
            diffs.append(f"{p}: differs")
    return {"identical": not diffs, "pose_max_diff_m": pose_max, "frames_differing": frames, "images": len(ia | ib),
            "images_identical": n_same, "differences": diffs}


def print_table(sides: list, ratios: dict) -> None:
    keys = [k for k in ("optimize", "total") if all(k in s["seconds_per_frame"] for s in sides)]
    others = sorted({k for s in sides for k, v in s["seconds_per_frame"].items()
                     if k not in keys and v == v and v is not None})
    print()
    print(f"{'seconds per frame':<22}" + "".join(f"{s['name']:>12}" for s in sides) + f"{'speed-up':>10}")
    for k in keys + others:
        vals = [s["seconds_per_frame"].get(k, float("nan")) for s in sides]
        label = {"optimize": "stage 3 (optimize)", "total": "whole frame (total)"}.get(k, k)
        r = vals[0] / vals[1] if vals[1] and vals[1] == vals[1] and vals[0] == vals[0] else float("nan")
        print(f"{label:<22}" + "".join(f"{v:12.2f}" for v in vals) + f"{r:9.2f}x")
    walls = [s["wall_s"] / max(s["processed"], 1) for s in sides]
    print(f"{'run wall / frame':<22}" + "".join(f"{v:12.2f}" for v in walls) + f"{walls[0] / walls[1]:9.2f}x")


#: The real trial of ``--stages`` (docs/real_footage.md): the Pose2Sim demo's balancing trial, at full resolution.
REAL_TRIAL = Path("/work/shared/realdata/pose2sim_demo/S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial")
#: Stages of ``--stages``' table (``metrics.json`` ``seconds_per_frame``; ``total`` is the frame after stage 1).
STAGE_COLUMNS = ("stage1", "segmentation", "optimize", "billboards", "visual_hull", "views", "paths", "other", "total")


def stage_scenes(args) -> list:
    """``(label, dataset or trial folder, extra flags)`` of ``--stages``: the default scene, one zoo scene, the
    real trial with a camera held out (each left out when missing)."""
    from benchmarks.bench_zoo import draw_specs, scene

    scenes = [("default", args.dataset if args.dataset is not None else default_dataset(args.cache), ())]
    name, text = draw_specs(1, args.zoo_seed, args.frames)[0]
    scenes.append((f"zoo {name}", scene(args.cache / "zoo", name, text), ()))
    if args.real is not None and Path(args.real).is_dir():
        scenes.append(("real balancing", Path(args.real), ("--hold-out", args.hold_out)))
    else:
        print(f"no real trial at {args.real}: left out", flush=True)
    return scenes


def stage_table(args) -> dict:
    """Seconds per frame per stage, run wall per frame, CPU and peak memory of the process tree, for every scene
    of :func:`stage_scenes` on one worker and on ``auto`` (every core), each run a fresh process."""
    from benchmarks.bench_parallel import timed_run

    rows = []
    for label, data, extra in stage_scenes(args):
        for workers in (1, "auto"):
            out = args.out / "stages" / f"{label.split()[0]}_{workers}"
            print(f"{label}, workers {workers} ...", flush=True)
            r = timed_run(data, out, args.frames, workers, recording=False, extra=extra)
            results = out / "results" if (out / "results" / "metrics.json").exists() else out
            spf = json.loads((results / "metrics.json").read_text()).get("seconds_per_frame", {}) \
                if (results / "metrics.json").exists() else {}
            rows.append({"scene": label, "dataset": str(data), **r, "seconds_per_frame": spf})
    head = f"{'scene':<22}{'workers':>8}{'run/frame':>10}" + "".join(f"{k[:9]:>10}" for k in STAGE_COLUMNS)
    print("\nseconds per frame (stages: mean per frame inside a worker; run/frame: the frames' wall / frames)")
    print(head + f"{'CPU/frame':>10}{'peak MB':>9}")
    for r in rows:
        n = max(r["processed"], 1)
        print(f"{r['scene'][:21]:<22}{str(r['workers']):>8}{r['run_s'] / n:10.2f}"
              + "".join(f"{r['seconds_per_frame'].get(k, float('nan')):10.2f}" for k in STAGE_COLUMNS)
              + f"{r['cpu_s'] / n:10.2f}{r['peak_rss_mb']:9.0f}")
    report = {"frames": args.frames, "rows": rows}
    atomic_write_text(args.out / "stages.json", json.dumps(report, indent=2, allow_nan=True))
    print(f"\nwrote {args.out / 'stages.json'}")
    return report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dataset", type=Path, help="dataset folder (default: the default scene, generated into --cache)")
    ap.add_argument("--frames", type=int, default=4, help="frames run on each side")
    ap.add_argument("--baseline", default=BASELINE, help="commit of the baseline side")
    ap.add_argument("--workers", type=int, default=1,
                    help="Dask workers of the working tree's side (1: sequential, like the baseline)")
    ap.add_argument("--cache", type=Path, default=ROOT / "out" / "cache")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench_speed")
    ap.add_argument("--stages", action="store_true",
                    help="instead of the comparison: seconds per frame per stage and peak memory of the default "
                         "scene, a zoo scene and the real trial, on one worker and on all (--workers auto)")
    ap.add_argument("--zoo-seed", type=int, default=71, help="--stages: the zoo scene (the first of this seed)")
    ap.add_argument("--real", type=Path, default=REAL_TRIAL, help="--stages: the real trial (a Pose2Sim trial)")
    ap.add_argument("--hold-out", default="cam_01", help="--stages: the real trial's held-out camera (imported names)")
    args = ap.parse_args(argv)
    if args.frames < 1 or args.workers < 1:
        ap.error("--frames and --workers must be >= 1")
    if args.stages:
        args.out.mkdir(parents=True, exist_ok=True)
        stage_table(args)
        return 0
    dataset = args.dataset if args.dataset is not None else default_dataset(args.cache)
    if not (Path(dataset) / "scene.toml").exists() and not (Path(dataset) / "calibration.toml").exists():
        ap.error(f"--dataset {dataset}: not a dataset folder (no calibration.toml)")
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="bench_speed_") as tmp:
        base_root = Path(tmp) / "baseline"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(base_root), args.baseline],
                       check=True, capture_output=True)
        try:
            sides = [run_side("baseline", base_root, dataset, args.out / "baseline", args.frames, 1),
                     run_side("new", ROOT, dataset, args.out / "new", args.frames, args.workers)]
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_root)],
                           capture_output=True)
    ratios = {k: sides[0]["seconds_per_frame"][k] / sides[1]["seconds_per_frame"][k]
              for k in ("optimize", "total") if k in sides[0]["seconds_per_frame"] and k in sides[1]["seconds_per_frame"]}
    cmp = compare_outputs(args.out / "baseline", args.out / "new")
    print_table(sides, ratios)
    print(f"\nbaseline {args.baseline[:12]} vs working tree ({subprocess.run(['git', '-C', str(ROOT), 'rev-parse', '--short', 'HEAD'], capture_output=True, text=True).stdout.strip()}"
          f" + uncommitted changes), {args.frames} frames of {dataset}, workers {args.workers}")
    print(f"outputs: poses max difference {cmp['pose_max_diff_m']:.3g} m, {cmp['images_identical']} of {cmp['images']} "
          f"images byte-identical -> {'IDENTICAL' if cmp['identical'] else 'DIFFERENT'}")
    for d in cmp["differences"][:40]:
        print("  " + d)
    report = {"dataset": str(dataset), "frames": args.frames, "workers": args.workers, "baseline": args.baseline,
              "sides": sides, "speedup": ratios, "outputs": cmp}
    atomic_write_text(args.out / "speed.json", json.dumps(report, indent=2, allow_nan=True))
    print(f"\nwrote {args.out / 'speed.json'}")
    return 0 if cmp["identical"] else 1


if __name__ == "__main__":
    sys.exit(main())
