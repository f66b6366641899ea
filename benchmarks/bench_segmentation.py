#!/usr/bin/env python3
"""Benchmark of stage 2 (template fit and GMM body-part segmentation) on seeded synthetic scenes.

Usage::

    python benchmarks/bench_segmentation.py                   # all scenes, every 4th frame
    python benchmarks/bench_segmentation.py --quick           # one broadcast, one studio scene
    python benchmarks/bench_segmentation.py --sweep           # colour spaces, components, radii
    python benchmarks/bench_segmentation.py --zoo 16          # randomised scenes: median, worst decile
    python benchmarks/bench_segmentation.py --zoo 16 --masks stage1   # with stage 1's silhouettes

Scenes (1280x720, 24 frames) are generated once into ``--cache`` and stage 1
(``recipes/pose_from_silhouettes.py``) is run once on each.  Silhouettes are
the ground-truth masks, so the numbers measure this stage alone.  Pose
sources:

``gt``      ground-truth joints, true calibration;
``stage1``  stage 1's 3D joints projected through stage 1's cameras (refined on the field
            lines where the scene has them) with its offsets, as the pipeline does;
``stage1_2d`` the same, but the template fitted to each view's own stage-1 2D pose;
``noisy``   ground-truth joints seen through the measured cameras plus exact offsets,
            2D joints perturbed by Gaussian noise of ``--noise`` x the subject's
            image height (a stand-in for a good stage 1).

Per source it prints the per-part and mean IoU against ``groundtruth/parts``
of: the template projection alone, the confident pixels only, the full GMM
labelling, and the labels after the closing; plus the median time per view.

``--zoo N`` draws N short scenes (4 frames) from ``--zoo-seed``: 2-4 cameras,
broadcast (subject 80-300 px) and studio, 960x540 to 1920x1080, 0-10 px
calibration error, 30-150 degrees between cameras, every motion, 40 % of the
kits like the pitch or the backdrop; stage 1 runs once on each.  Per labelling
variant (the default, the source's distance to confident pixels, the
background plate, the posterior rule) it prints each scene's mean part IoU
(mean over the views of the mean over the parts present, as
``benchmarks/bench_zoo.py``) and the median and worst decile over the scenes,
from stage-1 joints with ground-truth (``--masks gt``) or stage-1
(``--masks stage1``) silhouettes, and writes them to ``--json``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from toolkit.io import Dataset  # noqa: E402
from toolkit.pipeline.stage_inputs import read_stage1  # noqa: E402
from toolkit.segmentation import SegmentationConfig, part_iou, segment_frame  # noqa: E402
from toolkit.skeleton import SKELETON_14  # noqa: E402
from toolkit.synthetic import generate_scene, parse_spec  # noqa: E402
from toolkit.template import Template, camera_with_offset, subject_height_px  # noqa: E402

#: Seeded scenes: (name, seed, layout, motion, cameras, calibration error px, stature m).
SCENES = [("broadcast_11", 11, "broadcast", "walk", 3, 4.0, 1.75),
          ("broadcast_12", 12, "broadcast", "run", 3, 4.0, 1.75),
          ("broadcast_13", 13, "broadcast", "kick", 3, 4.0, 1.75),
          ("studio_21", 21, "studio", "wave", 4, 0.0, 1.70),
          ("studio_22", 22, "studio", "turn", 4, 0.0, 1.70)]
FRAMES = 24
STAGES = ("template", "confident", "gmm", "closed")


def _spec(name, seed, layout, motion, n_cams, err, height):
    return (f'name = "{name}"\nseed = {seed}\nframes = {FRAMES}\nfps = 25\n[subject]\nheight_m = {height}\n'
            f'motion = "{motion}"\n[cameras]\ncount = {n_cams}\nlayout = "{layout}"\nresolution = [1280, 720]\n'
            f'calibration_error_px = {err}\n[novel]\ncount = 0\n')


def prepare(cache: Path, scene) -> tuple[Path, Path]:
    """Generate the scene and run stage 1 once; returns (dataset, stage-1 output)."""
    ds, s1 = cache / "scenes" / scene[0], cache / "stage1" / scene[0]
    stale = scene[2] == "broadcast" and not (ds / "field_model.json").is_file()  # cached before field models
    if stale or not (ds / "groundtruth").is_dir():
        print(f"generating {scene[0]} ...", flush=True)
        shutil.rmtree(ds, ignore_errors=True)
        shutil.rmtree(s1, ignore_errors=True)
        generate_scene(parse_spec(_spec(*scene)), ds, progress=False)
    if not (s1 / "poses3d.npz").is_file() or not (s1 / "calibration.toml").is_file():
        print(f"stage 1 on {scene[0]} ...", flush=True)
        subprocess.run([sys.executable, str(ROOT / "recipes" / "pose_from_silhouettes.py"), str(ds), "--out",
                        str(s1), "--quiet", "--no-recording"], check=True, stdout=subprocess.DEVNULL)
    return ds, s1


ZOO_MOTIONS = ("walk", "run", "jump", "kick", "turn", "wave", "crouch", "idle")
ZOO_RESOLUTIONS = ((960, 540), (1280, 720), (1920, 1080))
#: Labelling variants compared on the zoo: (name, config fields, use the background plate).
ZOO_VARIANTS = (("default", {}, False),
                ("source_anchor", {"spatial_anchor": "confident"}, False),
                ("plate", {}, True),
                ("posterior", {"rule": "posterior"}, False))


def zoo_specs(n: int, seed: int, frames: int = 4) -> list[tuple[str, str]]:
    """``n`` scene specs ``(name, toml)`` drawn from ``seed`` (see the module docstring)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        studio = rng.random() < 0.3
        cams = int(rng.integers(2, 5))
        w, h = ZOO_RESOLUTIONS[int(rng.integers(3))]
        motion = ZOO_MOTIONS[i % 8] if i < 8 else ZOO_MOTIONS[int(rng.integers(8))]
        err = 0.0 if studio else float(np.round(rng.uniform(0, 10), 1))
        like = rng.random() < 0.4
        lo = float(np.round(rng.uniform(30, 110)))
        px = None if studio else float(np.round(rng.uniform(80, 300)))
        name = f"z{i:02d}_{'studio' if studio else 'bc'}{cams}_{motion}" + ("_lb" if like else "")
        text = (f'name = "{name}"\nseed = {1000 + i}\nframes = {frames}\nfps = 25\n[subject]\nheight_m = 1.75\n'
                f'motion = "{motion}"\noutfit = "{"like_background" if like else "random"}"\n[cameras]\n'
                f'count = {cams}\nlayout = "{"studio" if studio else "broadcast"}"\nresolution = [{w}, {h}]\n'
                f'calibration_error_px = {err}\nspacing_deg = [{lo}, {min(lo + 40, 150)}]\n'
                + (f'subject_px = {px}\n' if px else '') + '[novel]\ncount = 0\n')
        out.append((name, text))
    return out


def prepare_spec(cache: Path, name: str, text: str) -> tuple[Path, Path]:
    """Generate a zoo scene and run stage 1 once; returns (dataset, stage-1 output)."""
    ds, s1 = cache / "zoo" / name, cache / "zoo_stage1" / name
    if not (ds / "groundtruth").is_dir():
        print(f"generating {name} ...", flush=True)
        shutil.rmtree(s1, ignore_errors=True)
        generate_scene(parse_spec(text, f"{name}.toml"), ds, progress=False).close()
    if not (s1 / "poses3d.npz").is_file():
        print(f"stage 1 on {name} ...", flush=True)
        subprocess.run([sys.executable, str(ROOT / "recipes" / "pose_from_silhouettes.py"), str(ds), "--out",
                        str(s1), "--quiet", "--no-recording"], check=True, stdout=subprocess.DEVNULL)
    return ds, s1


def stage1_masks(ds: Dataset, camera: str) -> list:
    """Stage 1's silhouettes of one camera, every frame (median background fitted on the clean plate)."""
    from toolkit.foreground import BackgroundConfig, ForegroundConfig, ForegroundExtractor

    ex = ForegroundExtractor(ForegroundConfig(background=BackgroundConfig(method="median"))).fit([ds.background(camera)])
    prev, out = None, []
    for t in range(ds.n_frames):
        img = ds.frame(camera, t)
        sil = ex.extract(img, prev)
        prev = (img, sil.mask) if sil.usable else None
        out.append(sil.mask)
    return out


def run_zoo(args, template: Template) -> int:
    """The ``--zoo`` mode: every variant on every scene; prints the table and writes ``--json``."""
    import json

    rows = {}
    for name, text in zoo_specs(args.zoo, args.zoo_seed):
        dsp, s1 = prepare_spec(args.cache, name, text)
        ds = Dataset.open(dsp)
        masks = {c: stage1_masks(ds, c) for c in ds.camera_names} if args.masks == "stage1" else None
        per = {v[0]: [] for v in ZOO_VARIANTS}
        times = {v[0]: [] for v in ZOO_VARIANTS}
        for t, c, cam, J, x in views(ds, s1, "stage1", args.every, 0.0, None):
            if not np.isfinite(J).all():
                continue
            img, gt = ds.frame(c, t), ds.gt_parts(c, t)
            sil = gt > 0 if masks is None else masks[c][t]
            for vname, fields_, use_plate in ZOO_VARIANTS:
                t0 = time.perf_counter()
                r = segment_frame(img, sil, J, cam, template, replace(SegmentationConfig(), **fields_),
                                  plate=ds.background(c) if use_plate else None)
                times[vname].append(time.perf_counter() - t0)
                per[vname].append(float(np.nanmean(part_iou(r.labels, gt))))
        rows[name] = {v: float(np.mean(per[v])) for v in per}
        rows[name]["seconds_per_view"] = {v: float(np.median(times[v])) for v in times}
        print(f"{name:22s} " + " ".join(f"{v} {rows[name][v]:.3f}" for v in per), flush=True)
    summary = {}
    for vname, _, _ in ZOO_VARIANTS:
        v = np.array([r[vname] for r in rows.values()])
        summary[vname] = {"median": float(np.median(v)), "worst_decile": float(np.percentile(v, 10)),
                          "mean": float(v.mean())}
        print(f"{vname:14s} median {summary[vname]['median']:.3f}  worst decile "
              f"{summary[vname]['worst_decile']:.3f}  mean {summary[vname]['mean']:.3f}")
    if args.json is not None:
        args.json.write_text(json.dumps({"masks": args.masks, "zoo_seed": args.zoo_seed, "scenes": rows,
                                         "summary": summary}, indent=1))
    return 0


def views(ds: Dataset, s1: Path, source: str, every: int, noise: float, rng):
    """Yield (t, camera name, Camera, joints3d, joints2d) per evaluated view."""
    J = ds.gt_joints3d()
    if source in ("stage1", "stage1_2d"):
        # the cameras stage 1 used (refined on the field lines where it could), its joints, offsets, 2D poses
        stage1 = read_stage1(ds, s1, poses2d=True)
        p3, p2 = stage1.joints, stage1.poses2d
    for t in range(0, ds.n_frames, every):
        for i, c in enumerate(ds.camera_names):
            if source == "gt":
                yield t, c, ds.gt_rig[c], J[t], None
            elif source == "noisy":
                g, m = ds.gt_rig[c], ds.rig[c]
                cam = camera_with_offset(m, np.mean(g.project(J[t]) - m.project(J[t]), 0))
                x = g.project(J[t]) + rng.normal(0, noise * subject_height_px(J[t], g), (14, 2))
                yield t, c, cam, J[t], x
            else:
                # stage 1's offsets correct the detected joints; its cameras take the opposite shift
                cam = stage1.cameras(t)[c]
                # "stage1": the multi-view 3D joints projected (the pipeline's default); "stage1_2d": each
                # view's own stage-1 2D pose (the source's per-view fit)
                x = p2[c][t] if source == "stage1_2d" and c in p2 and np.isfinite(p2[c][t]).any() else None
                yield t, c, cam, p3[t], x


def evaluate(scenes, cache: Path, source: str, config: SegmentationConfig, every: int, noise: float,
             template: Template, seed: int = 0):
    """Per-part IoU lists per stage and kind of scene, and the view times."""
    rng = np.random.default_rng(seed)
    res = {}
    times = []
    coverage = []
    for scene in scenes:
        dsp, s1 = prepare(cache, scene)
        ds = Dataset.open(dsp)
        kind = scene[2]
        for t, c, cam, J, x in views(ds, s1, source, every, noise, rng):
            img, gt = ds.frame(c, t), ds.gt_parts(c, t)
            sil = gt > 0
            t0 = time.perf_counter()
            r = segment_frame(img, sil, J, cam, template, config, joints2d=x)
            times.append(time.perf_counter() - t0)
            coverage.append(r.pose.source if r.pose is not None else "none")
            for stage, lab in zip(STAGES, (np.where(sil, r.template_labels, 0), r.confident_labels,
                                           r.colour_labels, r.labels)):
                res.setdefault((kind, stage), []).append(part_iou(lab, gt))
    return res, times, coverage


def report(title: str, res, times, coverage) -> None:
    names = [n.replace("upper_arm", "uarm").replace("forearm", "farm") for n in SKELETON_14.part_names]
    print(f"\n== {title}")
    srcs = {s: coverage.count(s) for s in sorted(set(coverage))}
    print(f"views: {len(times)} (template pose from: {srcs}); time per view: median {np.median(times):.2f} s, "
          f"mean {np.mean(times):.2f} s")
    print(f"{'scenes':10s} {'stage':10s} {'mean':>5s} " + " ".join(f"{n:>7s}" for n in names))
    for kind in ("broadcast", "studio"):
        for stage in STAGES:
            if (kind, stage) not in res:
                continue
            per = np.nanmean(np.array(res[(kind, stage)]), 0)
            print(f"{kind:10s} {stage:10s} {np.nanmean(per):5.3f} " + " ".join(f"{v:7.2f}" for v in per))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", type=Path, default=ROOT / "out" / "bench_segmentation")
    ap.add_argument("--every", type=int, default=4, help="evaluate every N-th frame")
    ap.add_argument("--noise", type=float, default=0.01, help="2D noise of the 'noisy' source, x image height")
    ap.add_argument("--sources", default="gt,stage1,stage1_2d,noisy")
    ap.add_argument("--quick", action="store_true", help="one broadcast and one studio scene")
    ap.add_argument("--scenes", default=None, help="comma-separated scene names (default: all)")
    ap.add_argument("--sweep", action="store_true", help="colour space, components, radii, rules (noisy source)")
    ap.add_argument("--zoo", type=int, default=0, help="randomised scenes (see the module docstring)")
    ap.add_argument("--zoo-seed", type=int, default=2026)
    ap.add_argument("--masks", choices=("gt", "stage1"), default="gt", help="--zoo: silhouettes used")
    ap.add_argument("--json", type=Path, default=None, help="--zoo: write the figures here")
    args = ap.parse_args(argv)
    if args.zoo:
        return run_zoo(args, Template(1.75))
    scenes = [SCENES[0], SCENES[3]] if args.quick else SCENES
    if args.scenes:
        scenes = [s for s in SCENES if s[0] in args.scenes.split(",")]
    template = Template(1.75)
    base = SegmentationConfig()
    print(f"config: {base}")
    if args.sweep:
        variants = [("default", base)]
        variants += [(f"colour_space={s}", replace(base, colour_space=s)) for s in ("lab", "hsv", "chroma")]
        variants += [(f"n_components={k}", replace(base, n_components=k)) for k in (1, 2, 5)]
        variants += [(f"thin_thick_fraction={f}", replace(base, thin_thick_fraction=f)) for f in (0.005, 0.02, 0.04)]
        variants += [(f"colour_margin={m}", replace(base, colour_margin=m)) for m in (5.0, 100.0, 1e9)]
        variants += [("rule=colour", replace(base, rule="colour")), ("closing_fraction=0.02",
                                                                     replace(base, closing_fraction=0.02))]
        for name, cfg in variants:
            res, times, cov = evaluate(scenes, args.cache, "noisy", cfg, args.every, args.noise, template)
            line = "  ".join(f"{k}/{s} {np.nanmean(np.nanmean(np.array(res[(k, s)]), 0)):.3f}"
                             for k in ("broadcast", "studio") for s in ("gmm", "closed") if (k, s) in res)
            print(f"{name:28s} {line}  {np.median(times):.2f} s/view", flush=True)
        return 0
    for source in args.sources.split(","):
        res, times, cov = evaluate(scenes, args.cache, source, base, args.every, args.noise, template)
        title = source if source != "noisy" else f"noisy (2D noise {args.noise} x image height)"
        report(title, res, times, cov)
    return 0


if __name__ == "__main__":
    sys.exit(main())
