#!/usr/bin/env python3
"""Joint-angle benchmark: seeded synthetic people with noisy joints, and a real walk against Plug-in Gait.

Usage::

    python -m benchmarks.bench_joint_angles                     # 10 synthetic scenes (seeds 100-109) + the real walk
    python -m benchmarks.bench_joint_angles --seed 300 --scenes 20 --noise-mm 10
    python -m benchmarks.bench_joint_angles --engine own         # without OpenSim
    python -m benchmarks.bench_joint_angles --json out/bench_joint_angles.json
    python -m benchmarks.bench_joint_angles --scenes 0 --plot-walk docs/images/joint_angles_walk.png
    python -m benchmarks.bench_joint_angles --scenes 0 --no-real --plot docs/images/joint_angles_balancing.png \
        --runs out/balancing_own/angles.csv out/balancing_opensim/angles.csv

Synthetic: per seed a person (:func:`toolkit.biomech.synthetic.posed_points`)
moving every joint through one smooth cycle of 60 frames
(:func:`toolkit.biomech.synthetic.smooth_motion`: hip, knee, ankle, shoulder
and elbow over wide ranges), any heading and up to 20 degrees of tilt, its
joint centres and toes then moved by isotropic Gaussian noise (``--noise-mm``,
default 10 mm per coordinate, like a markerless system's joints).  Printed per
angle: the median and the worst decile (90th percentile) over scenes of the
RMS error against the true angles, for the project's own angles from the
joint centres alone, and for OpenSim's inverse kinematics when installed.
The seeds (100 onwards) are not those of the tests (0-11).

Real: ``../shared/realdata/c3d_plugin_gait/Movement_trial.c3d`` (a Vicon
walk, 323 frames at 120 Hz, with Plug-in Gait's angles stored in it) with its
``Static_trial.c3d``: joint centres by the project's marker system
(:func:`toolkit.markers.functional.joint_centres`), then angles; RMS and mean
difference (bias) against Plug-in Gait's per angle, for the variants of
:func:`toolkit.biomech.validate.plugin_gait_comparison`.  Targets: knee
flexion within 5 degrees RMS, hip and ankle flexion within 8.  The same
figures on ``Static_trial.c3d`` (498 frames of standing, Plug-in Gait's
angles stored too): the only other file with stored angles, not used to
develop the engines.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from toolkit.biomech.angles import angle_rms, joint_angles
from toolkit.biomech.opensim_model import opensim_angles, opensim_available
from toolkit.biomech.synthetic import posed_points, random_rotation, smooth_motion
from toolkit.biomech.validate import plugin_gait_comparison

REALDATA = Path(os.environ.get("TOOLKIT_REALDATA", Path(__file__).resolve().parents[2] / "shared" / "realdata"))
#: Frames of each synthetic scene.
N_FRAMES = 60
#: The targets, degrees RMS over a trial (knee flexion 5, hip and ankle flexion 8), as in tests/biomech/test_realdata_angles.py.
TARGETS = {"knee_flexion": 5.0, "hip_flexion": 8.0, "ankle_dorsiflexion": 8.0}


def synthetic_scene(seed: int, noise_m: float) -> tuple[dict, dict]:
    """True angles and noisy landmarks of one seeded scene."""
    rng = np.random.default_rng(seed)
    truth = smooth_motion(N_FRAMES, rng)
    pts = posed_points(truth, N_FRAMES, body=random_rotation(rng), origin=rng.uniform(-2, 2, 3))
    noisy = {k: v + rng.normal(0.0, noise_m, v.shape) for k, v in pts.items()}
    return truth, noisy


def synthetic(seeds, noise_m: float, engines, tmp: Path) -> dict:
    """``{engine: {angle: [rms per scene]}}``."""
    out = {e: {} for e in engines}
    for seed in seeds:
        truth, pts = synthetic_scene(seed, noise_m)
        results = {}
        if "own" in engines:
            results["own"] = joint_angles(pts, 30.0)
        if "opensim" in engines:
            d = tmp / f"seed{seed}"
            d.mkdir(parents=True, exist_ok=True)
            results["opensim"] = opensim_angles(pts, 30.0, d).angles
        for e, a in results.items():
            for name, v in truth.items():
                out[e].setdefault(name, []).append(angle_rms(a[name], v)[0])
    return out


def _print_synthetic(res: dict, noise_mm: float, seeds) -> None:
    print(f"synthetic: {len(seeds)} scenes (seeds {seeds[0]}-{seeds[-1]}), {N_FRAMES} frames, "
          f"joint noise {noise_mm:g} mm; RMS error per scene, degrees: median / worst decile")
    names = sorted({n[2:] for e in res.values() for n in e}, key=lambda n: list(TARGETS).index(n)
                   if n in TARGETS else 99)
    print(f"  {'angle':22s}" + "".join(f"{e:>20s}" for e in res))
    for n in names:
        row = f"  {n:22s}"
        for e in res:
            v = np.array(res[e].get(f"l_{n}", []) + res[e].get(f"r_{n}", []))
            row += f"{np.median(v):11.2f} / {np.percentile(v, 90):5.2f}" if len(v) else f"{'-':>20s}"
        print(row)


def _print_real(res: dict) -> None:
    print("real walk (c3d_plugin_gait/Movement_trial.c3d, static offsets from Static_trial.c3d) against "
          "Plug-in Gait: RMS (bias) in degrees")
    variants = [v for v in res if not v.endswith("residual_mm")]
    names = list(dict.fromkeys(n for v in variants for n in res[v]))
    print(f"  {'angle':26s}" + "".join(f"{v:>20s}" for v in variants))
    for n in names:
        row = f"  {n:26s}"
        for v in variants:
            c = res[v].get(n)
            row += f"{c['rms_deg']:12.2f} ({c['bias_deg']:5.1f})" if c else f"{'-':>20s}"
        target = TARGETS.get(n[2:])
        print(row + (f"   target {target:g}" if target else ""))
    if "opensim/residual_mm" in res:
        print(f"  OpenSim marker residual: {res['opensim/residual_mm']['all']['rms_mm']:.1f} mm RMS")


def _print_held_out(res: dict) -> None:
    print("held-out file (c3d_plugin_gait/Static_trial.c3d, standing, its own foot offsets) against Plug-in "
          "Gait: RMS in degrees")
    variants = [v for v in res if not v.endswith("residual_mm")]
    for n in ("knee_flexion", "hip_flexion", "ankle_dorsiflexion"):
        row = f"  {n:22s}"
        for v in variants:
            c = [res[v].get(f"{side}_{n}") for side in "lr"]
            row += f"  {v}: " + " / ".join(f"{x['rms_deg']:.2f}" if x else "-" for x in c)
        print(row)


#: Columns of the plots.
PLOT_COLUMNS = ("l_hip_flexion", "r_hip_flexion", "l_knee_flexion", "r_knee_flexion", "l_ankle_dorsiflexion",
                "r_ankle_dorsiflexion", "l_shoulder_flexion", "r_shoulder_flexion", "l_elbow_flexion",
                "r_elbow_flexion")


def plot_curves(curves: dict, png: Path, title: str) -> None:
    """One panel per angle of :data:`PLOT_COLUMNS` present, a line per source.

    Parameters
    ----------
    curves : dict of str to (ndarray of shape (T,), dict of str to ndarray of shape (T,))
        Source label -> (time in seconds, {column: degrees}).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = [c for c in PLOT_COLUMNS if any(c in d for _, d in curves.values())]
    n_rows = (len(cols) + 1) // 2
    fig, axes = plt.subplots(n_rows, 2, figsize=(10, 2.1 * n_rows), sharex=True, squeeze=False)
    for ax, col in zip(axes.ravel(), cols):
        for label, (t, d) in curves.items():
            if col in d:
                ax.plot(t, d[col], label=label, lw=1.2)
        ax.set_title(col, fontsize=9)
        ax.set_ylabel("deg", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[len(cols):]:
        ax.axis("off")
    axes[0, 0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=90)
    plt.close(fig)


def plot_walk(png: Path, engines, tmp: Path) -> None:
    """Own, OpenSim and Plug-in Gait's angles over the real walk."""
    from toolkit.biomech.validate import c3d_landmarks

    move = REALDATA / "c3d_plugin_gait" / "Movement_trial.c3d"
    points, fps, reference = c3d_landmarks(move)
    static = c3d_landmarks(REALDATA / "c3d_plugin_gait" / "Static_trial.c3d")[0]
    own = joint_angles(points, fps, static=static)
    curves = {"Plug-in Gait (Vicon)": (own.time, reference),
              "own": (own.time, {n: own[n] for n in own.names})}
    if "opensim" in engines:
        a = opensim_angles(points, fps, tmp, static=static).angles
        curves["OpenSim IK"] = (a.time, {n: a[n] for n in a.names})
    plot_curves(curves, png, "Movement_trial.c3d: joint centres from the markers, then angles")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--seed", type=int, default=100, help="first seed of the synthetic scenes")
    ap.add_argument("--scenes", type=int, default=10, help="number of synthetic scenes")
    ap.add_argument("--noise-mm", type=float, default=10.0, help="joint noise (standard deviation per axis), mm")
    ap.add_argument("--engine", choices=("own", "opensim", "both"), default="both")
    ap.add_argument("--no-real", action="store_true", help="skip the real walk")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    ap.add_argument("--plot-walk", type=Path, default=None, help="PNG of the real walk's angles (own, OpenSim, PiG)")
    ap.add_argument("--plot", type=Path, default=None, help="PNG of the angles.csv files given with --runs")
    ap.add_argument("--runs", type=Path, nargs="*", default=(), help="angles.csv files for --plot")
    args = ap.parse_args(argv)
    engines = ("own", "opensim") if args.engine == "both" else (args.engine,)
    if "opensim" in engines and not opensim_available():
        print("note: opensim is not installed: own engine only")
        engines = ("own",)
    seeds = list(range(args.seed, args.seed + args.scenes))
    report = {"engines": list(engines), "seeds": seeds, "noise_mm": args.noise_mm}
    with tempfile.TemporaryDirectory() as tmp:
        if seeds:
            syn = synthetic(seeds, args.noise_mm / 1000.0, engines, Path(tmp))
            _print_synthetic(syn, args.noise_mm, seeds)
            report["synthetic"] = syn
        move = REALDATA / "c3d_plugin_gait" / "Movement_trial.c3d"
        if not args.no_real and move.is_file():
            static = REALDATA / "c3d_plugin_gait" / "Static_trial.c3d"
            real = plugin_gait_comparison(move, static if static.is_file() else None, engines=engines,
                                          out=Path(tmp))
            _print_real(real)
            report["real"] = real
            if static.is_file():
                held_out = plugin_gait_comparison(static, static, engines=engines, out=Path(tmp))
                _print_held_out(held_out)
                report["real_static"] = held_out
        elif not args.no_real:
            print(f"note: {move} not found: real walk skipped")
        if args.plot_walk is not None:
            plot_walk(args.plot_walk, engines, Path(tmp))
    if args.plot is not None:
        from toolkit.biomech.files import read_angles_csv

        runs = {}
        for f in args.runs:
            a = read_angles_csv(f)
            runs[f.parent.name] = (a.time, {n: a[n] for n in a.names})
        plot_curves(runs, args.plot, " vs ".join(runs))
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
