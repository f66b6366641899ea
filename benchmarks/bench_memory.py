#!/usr/bin/env python3
"""Memory over long runs: resident memory early and at the end of a depth track and a free-viewpoint run.

Usage::

    python -m benchmarks.bench_memory [--parts depth,free_viewpoint] [--depth-frames 10000]
                                      [--fv-frames 200] [--out out/bench_memory]

``depth``: a synthetic depth sequence (``datasets_synthetic/depth_walk.toml``, 60 frames, made once
into ``OUT/depth_walk``) read over and over, ``--depth-frames`` frames in all, through one
:class:`toolkit.depth.DepthTracker` in this process (:func:`toolkit.depth.track_sequence`, as
``recipes/depth_tracking.py`` runs it): the resident memory (``VmRSS``) after frame 10 and after the
last frame, and the growth between them.

``free_viewpoint``: ``recipes/free_viewpoint.py`` with its default options on a synthetic scene of
``--fv-frames`` frames (the default scene's spec at 640 x 360, made once into
``OUT/fv_scene``) in a child process, whose ``VmRSS`` is sampled every 0.2 s together with the frames
finished (``OUT/fv_run/frames/``): the memory once 10 frames, half of them and all of them are
finished (the growth is the last against the first), and the largest sample (the final aggregates
included).  The bound: growth under 50 MB.  Then the same scene's first ``--fv-short`` frames: the
peak of each whole run (every process of it, ``--workers``), the long one within 10 % of the short.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: Growth allowed between frame 10 and the end, MB.
GROWTH_LIMIT_MB = 50.0
#: A long free-viewpoint run's peak memory may exceed a short one's of the same scene by this share.
PEAK_RATIO_LIMIT = 0.10


def rss_mb(pid: str | int = "self") -> float:
    """Resident memory of a process (``VmRSS``), MB; NaN once it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def make(spec: Path, out: Path, replace: dict | None = None) -> Path:
    """The scene of ``spec`` (the first ``key = ...`` line of each key of ``replace`` changed) rendered into
    ``out`` once."""
    if (out / ".complete").exists():
        return out
    text = spec.read_text()
    if replace:
        import re

        for key, value in replace.items():
            text, n = re.subn(rf"(?m)^{key}\s*=.*$", f"{key} = {value}", text, count=1)
            if not n:
                raise SystemExit(f"{spec}: no '{key} = ...' line to change")
    tmp_spec = out.parent / f"{out.name}.toml"
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp_spec.write_text(text)
    shutil.rmtree(out, ignore_errors=True)
    subprocess.run([sys.executable, str(REPO / "recipes" / "make_scene.py"), str(tmp_spec), "--out", str(out)],
                   check=True, stdout=subprocess.DEVNULL)
    (out / ".complete").write_text("")
    return out


def depth(out: Path, n_frames: int) -> dict:
    """Track ``n_frames`` frames of the depth walk, read round and round; memory at frame 10 and the end."""
    from toolkit.depth import DepthTracker, track_sequence
    from toolkit.io.depth_readers import open_depth_input

    data = make(REPO / "datasets_synthetic" / "depth_walk.toml", out / "depth_walk")
    inp = open_depth_input(data)
    frames = [inp.read(i) for i in range(len(inp.frames))]
    tracker = DepthTracker(inp.camera, inp.pose_known, background=inp.background)
    marks = {}
    t0 = time.perf_counter()

    def every():
        for i in range(n_frames):
            yield frames[i % len(frames)]

    def progress(r):
        if r.index + 1 in (10, n_frames):
            marks[r.index + 1] = rss_mb()

    track_sequence(tracker, every(), progress=progress)
    return {"frames": n_frames, "rss_at_10_mb": marks[10], "rss_end_mb": marks[n_frames],
            "growth_mb": marks[n_frames] - marks[10], "seconds": time.perf_counter() - t0}


def tree_rss_mb(pid: int) -> float:
    """Resident memory of a process and every process under it (a run's Dask workers), summed, MB."""
    import psutil

    try:
        root = psutil.Process(pid)
        return sum(q.memory_info().rss for q in [root] + root.children(recursive=True)) / 2**20
    except psutil.Error:
        return float("nan")


def free_viewpoint(out: Path, n_frames: int, workers: str = "1", scene_frames: int | None = None) -> dict:
    """``recipes/free_viewpoint.py`` on ``n_frames`` frames (of a scene of ``scene_frames``, default as many) in a
    child process with ``--workers workers``, the memory of its process tree sampled."""
    total = scene_frames or n_frames
    data = make(REPO / "datasets_synthetic" / "default.toml", out / f"fv_scene_{total}",
                {"frames": total, "resolution": "[640, 360]"})
    run = out / "fv_run"
    shutil.rmtree(run, ignore_errors=True)
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, str(REPO / "recipes" / "free_viewpoint.py"), str(data), "--out", str(run),
                          "--max-frames", str(n_frames), "--no-recording", "--quiet", "--workers", str(workers)],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    at: dict = {}
    peak = whole = 0.0
    while p.poll() is None:
        mb = tree_rss_mb(p.pid)
        whole = max(whole, mb) if mb == mb else whole
        done = len(list((run / "frames").glob("*.json"))) if (run / "frames").is_dir() else 0
        for mark in (10, n_frames // 2, n_frames):
            if done >= mark and mark not in at and mb == mb:
                at[mark] = mb
        if done >= 10 and mb == mb:
            peak = max(peak, mb)
        time.sleep(0.2)
    if p.returncode != 0:
        raise SystemExit(f"free_viewpoint.py failed ({p.returncode}): {p.stderr.read()[-2000:]}")
    return {"frames": n_frames, "rss_at_10_mb": at.get(10), "rss_middle_mb": at.get(n_frames // 2),
            "rss_last_frame_mb": at.get(n_frames), "rss_end_mb": peak, "peak_mb": whole,
            "growth_mb": at.get(n_frames, peak) - (at.get(10) or 0.0), "seconds": time.perf_counter() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--parts", default="depth,free_viewpoint")
    ap.add_argument("--depth-frames", type=int, default=10_000)
    ap.add_argument("--fv-frames", type=int, default=200)
    ap.add_argument("--fv-short", type=int, default=20,
                    help="the same scene's first N frames too: the peak of the whole run against the long one's "
                         "(target: within 10 %%; 0: not run)")
    ap.add_argument("--workers", default="1", help="free_viewpoint.py --workers (default 1; memory of all processes)")
    ap.add_argument("--out", type=Path, default=REPO / "out" / "bench_memory")
    args = ap.parse_args(argv)
    parts = {p.strip() for p in args.parts.split(",")}
    ok = True
    for name, fn, n in (("depth", depth, args.depth_frames), ("free_viewpoint", free_viewpoint, args.fv_frames)):
        if name not in parts:
            continue
        r = fn(args.out, n) if name == "depth" else fn(args.out, n, args.workers)
        ok &= r["growth_mb"] < GROWTH_LIMIT_MB
        more = (f", half way {r['rss_middle_mb']:.0f} MB, once the last frame is finished "
                f"{r['rss_last_frame_mb']:.0f} MB, largest (the final aggregates included)"
                if "rss_middle_mb" in r else ", at the end")
        print(f"{name}: {r['frames']} frames in {r['seconds']:.0f} s; resident memory after frame 10 "
              f"{r['rss_at_10_mb']:.0f} MB{more} {r['rss_end_mb']:.0f} MB: growth over the frames "
              f"{r['growth_mb']:+.1f} MB (limit {GROWTH_LIMIT_MB:.0f})", flush=True)
        if name == "free_viewpoint" and args.fv_short:
            short = fn(args.out, args.fv_short, args.workers, scene_frames=n)
            ratio = r["peak_mb"] / short["peak_mb"]
            ok &= ratio <= 1.0 + PEAK_RATIO_LIMIT
            print(f"free_viewpoint peak of the whole run (all processes, --workers {args.workers}): "
                  f"{n} frames {r['peak_mb']:.0f} MB, {args.fv_short} frames {short['peak_mb']:.0f} MB: "
                  f"{100 * (ratio - 1):+.1f} % (limit {100 * PEAK_RATIO_LIMIT:.0f} %)", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
