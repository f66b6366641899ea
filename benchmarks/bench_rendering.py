#!/usr/bin/env python3
"""Benchmark of stage 4: novel-view quality per method, compositor speed, Open3D frame time.

Usage::

    python benchmarks/bench_rendering.py                       # 2 seeded broadcast scenes, 3 frames each
    python benchmarks/bench_rendering.py --seeds 7 8 9 --frames 6 --end-to-end 12

For each seeded broadcast scene (``datasets_synthetic/default.toml`` with the
seed replaced; generated once into ``--cache``):

* **oracle rendering**: articulated billboards (true joints and part labels),
  standard billboards (true silhouettes) and the visual hull, each rendered
  into the dataset's novel cameras over the true background; PSNR and SSIM
  inside the subject's ground-truth bounding box;
* **speed**: the CPU compositor on one core (``cv2.setNumThreads(1)``) at
  1280x720, one subject, three cameras, frames per second; the Open3D
  renderer's frame time;
* **end to end** (``--end-to-end N``): ``recipes/free_viewpoint.py`` on the
  first N frames (stage 1 needs a few frames to learn the background), its
  metrics and seconds per frame.

Targets (issue 6): articulated >= standard + 2 dB PSNR; CPU compositor >= 30 fps.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: Issue 6 targets.
TARGET_GAIN_DB = 2.0
TARGET_FPS = 30.0


def scene(seed: int, frames: int, cache: Path) -> Path:
    from toolkit.io import Dataset
    from toolkit.synthetic import generate_scene
    from toolkit.synthetic.spec import parse_spec

    out = cache / f"broadcast_s{seed}_f{frames}"
    if not (out / "field_model.json").exists():  # missing, or cached before datasets had field models
        shutil.rmtree(out, ignore_errors=True)
        shutil.rmtree(cache / f"fvv_s{seed}", ignore_errors=True)
        text = (REPO / "datasets_synthetic" / "default.toml").read_text()
        text = re.sub(r"(?m)^seed = .*$", f"seed = {seed}", text)
        text = re.sub(r"(?m)^frames = .*$", f"frames = {frames}", text)
        print(f"generating {out} ...", flush=True)
        generate_scene(parse_spec(text), out, progress=False)
    Dataset.open(out).close()
    return out


def oracle(ds, plates, frames, pictures: Path | None = None, tag: str = "") -> tuple[dict, list]:
    from toolkit.rendering import (CpuCompositor, bbox_scores, render_billboards, render_points,
                                   standard_billboards, visual_hull)

    rig = ds.gt_rig
    comp = CpuCompositor()
    scores: dict = {m: [] for m in ("articulated", "standard", "visual_hull")}
    models = []
    for t in frames:
        imgs = {c: ds.frame(c, t) for c in rig.names}
        labels = {c: ds.gt_parts(c, t) for c in rig.names}
        J = ds.gt_joints3d()[t]
        art = render_billboards(imgs, labels, J, rig, frame=t)
        std = standard_billboards(imgs, {c: labels[c] > 0 for c in labels}, J, rig, frame=t)
        hull = visual_hull(imgs, {c: labels[c] > 0 for c in labels}, J, rig)
        models.append(art)
        for cam in ds.novel_rig:
            bg = plates.plate(cam)
            gt, gm = ds.novel_image(cam.name, t), ds.novel_mask(cam.name, t)
            views = {"articulated": comp.render(art, cam).over(bg), "standard": comp.render(std, cam).over(bg)}
            scores["articulated"].append(bbox_scores(views["articulated"], gt, gm))
            scores["standard"].append(bbox_scores(views["standard"], gt, gm))
            rgb, a = render_points(hull, cam)
            views["visual hull"] = np.clip(rgb + (1 - a[..., None]) * bg + 0.5, 0, 255).astype(np.uint8)
            scores["visual_hull"].append(bbox_scores(views["visual hull"], gt, gm))
            if pictures is not None and t == frames[0]:
                comparison_picture(gt, gm, views, pictures / f"novel_oracle_{tag}_{cam.name}.png")
    return {m: {k: float(np.mean([s[k] for s in v])) for k in ("psnr", "ssim")} for m, v in scores.items()}, models


def comparison_picture(gt, gt_mask, images: dict, path: Path, margin: int = 24, scale: int = 2) -> None:
    """Save ground truth and each method side by side, cropped to the subject's box, with captions."""
    from toolkit.io import atomic_write_png
    from toolkit.rendering import mask_bbox

    x0, y0, x1, y1 = mask_bbox(gt_mask, margin)
    tiles = []
    for name, img in [("ground truth", gt)] + list(images.items()):
        tile = cv2.resize(np.ascontiguousarray(img[y0:y1, x0:x1]), None, fx=scale, fy=scale,
                          interpolation=cv2.INTER_NEAREST)
        tile = cv2.copyMakeBorder(tile, 28, 0, 0, 4, cv2.BORDER_CONSTANT, value=(255, 255, 255))
        cv2.putText(tile, name, (4, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA)
        tiles.append(tile)
    atomic_write_png(path, np.hstack(tiles))


def compositor_fps(models, cameras, repeats: int) -> float:
    from toolkit.rendering import CpuCompositor

    cv2.setNumThreads(1)
    comp = CpuCompositor()
    n = 0
    t0 = time.perf_counter()
    for _ in range(repeats):
        for m in models:
            for cam in cameras:
                comp.render(m, cam)
                n += 1
    return n / (time.perf_counter() - t0)


def open3d_seconds(models, cameras) -> float:
    from toolkit.rendering.open3d_renderer import Open3DRenderer

    r = Open3DRenderer(cameras[0].size)
    t0 = time.perf_counter()
    n = 0
    for m in models[:1]:
        for cam in cameras:
            r.render(m, cam)
            n += 1
    return (time.perf_counter() - t0) / n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[7, 8])
    ap.add_argument("--frames", type=int, default=3, help="frames per scene for the oracle rendering")
    ap.add_argument("--end-to-end", type=int, default=0, help="also run the recipe on N frames (0 = skip)")
    ap.add_argument("--repeats", type=int, default=5, help="timing repetitions of the compositor")
    ap.add_argument("--no-open3d", action="store_true")
    ap.add_argument("--cache", type=Path, default=REPO / "outputs" / "bench_rendering")
    ap.add_argument("--json", type=Path, default=None, help="write the results here")
    ap.add_argument("--pictures", type=Path, default=None,
                    help="save ground truth | articulated | standard | visual hull pictures here")
    args = ap.parse_args(argv)

    from toolkit.io import Dataset
    from toolkit.rendering.evaluation import BackgroundPlates

    results = {"scenes": {}}
    all_models, all_cams = [], []
    n_frames = max(args.frames, args.end_to_end)
    for seed in args.seeds:
        root = scene(seed, n_frames, args.cache)
        ds = Dataset.open(root)
        plates = BackgroundPlates(ds.scene_toml)
        q, models = oracle(ds, plates, list(range(args.frames)), args.pictures, f"s{seed}")
        all_models += models
        all_cams = list(ds.novel_rig)
        r = {"oracle": q}
        if args.end_to_end:
            from recipes import free_viewpoint as fv

            out = args.cache / f"fvv_s{seed}"
            fv.main([str(root), "--out", str(out), "--max-frames", str(args.end_to_end), "--quiet", "--no-recording",
                     "--replace-stale"])
            r["end_to_end"] = json.loads((out / "metrics.json").read_text())
            if args.pictures is not None:
                from toolkit.io.frames import read_png
                cam = ds.novel_rig[0].name
                f = f"{args.end_to_end // 2:06d}.png"
                views = {"articulated": read_png(out / "novel" / cam / f),
                         "standard": read_png(out / "baselines" / "standard" / cam / f),
                         "visual hull": read_png(out / "baselines" / "visual_hull" / cam / f)}
                comparison_picture(ds.novel_image(cam, args.end_to_end // 2), ds.novel_mask(cam, args.end_to_end // 2),
                                   views, args.pictures / f"novel_end_to_end_s{seed}_{cam}.png")
        results["scenes"][seed] = r
        ds.close()
        print(f"seed {seed}: " + "  ".join(f"{m} {v['psnr']:.2f} dB / SSIM {v['ssim']:.3f}" for m, v in q.items()),
              flush=True)
    fps = compositor_fps(all_models, all_cams, args.repeats)
    results["cpu_fps_1core"] = fps
    if not args.no_open3d:
        results["open3d_seconds_per_frame"] = open3d_seconds(all_models, all_cams)
    mean = {m: {k: float(np.mean([r["oracle"][m][k] for r in results["scenes"].values()])) for k in ("psnr", "ssim")}
            for m in ("articulated", "standard", "visual_hull")}
    results["mean"] = mean
    w, h = all_cams[0].size
    print(f"\nnovel views, subject's box, {len(args.seeds)} scenes x {args.frames} frames (oracle joints and labels):")
    print(f"  {'method':14s} {'PSNR dB':>8s} {'SSIM':>6s}")
    for m, v in mean.items():
        print(f"  {m:14s} {v['psnr']:8.2f} {v['ssim']:6.3f}")
    gain = mean["articulated"]["psnr"] - mean["standard"]["psnr"]
    met = "met" if gain >= TARGET_GAIN_DB else "NOT met"
    print(f"articulated - standard: {gain:+.2f} dB (target >= +{TARGET_GAIN_DB} dB): {met}")
    print(f"CPU compositor, one core, {w}x{h}, 1 subject, {len(all_models[0].rig)} cameras: {fps:.1f} fps "
          f"(target >= {TARGET_FPS}): {'met' if fps >= TARGET_FPS else 'NOT met'}")
    if "open3d_seconds_per_frame" in results:
        print(f"Open3D renderer: {results['open3d_seconds_per_frame']:.2f} s per frame")
    for seed, r in results["scenes"].items():
        if "end_to_end" in r:
            e = r["end_to_end"]
            print(f"end to end, seed {seed}: " + "  ".join(f"{m} {v['psnr']:.2f} dB" for m, v in e["methods"].items())
                  + f"  pose {e['pose']['mpjpe_m'] * 100:.1f} cm, "
                  + f"{e['seconds_per_frame'].get('total', float('nan')):.1f} s/frame")
    if args.json:
        args.json.write_text(json.dumps(results, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
