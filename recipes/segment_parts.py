#!/usr/bin/env python3
"""Stage 2 of the articulated-billboard pipeline: body-part labels for every camera and frame.

Usage::

    python recipes/segment_parts.py out/default --out out/default_parts --poses out/default_stage1
    python recipes/segment_parts.py out/default --out out/default_parts --gt-joints --gt-masks

Per camera and frame: the generic template is fitted exactly to the 2D pose
(source 000 §2.2), projected thinned and thickened, and the silhouette split
into confident and uncertain pixels; one Gaussian mixture per part is learned
from the confident pixels and labels the uncertain ones (colour then nearest
part), and a closing removes outliers (§2.3).  Writes into OUT:

  parts/<camera>/NNNNNN.png   part ids 1..10 (ids of groundtruth/parts), 0 background
  recording.rrd               template labels (thin, thick), confident and uncertain
                              masks, final labels, per-part model summaries

Poses: ``--poses STAGE1_OUT`` (poses3d.npz, poses2d.npz, offsets.npz of
recipes/pose_from_silhouettes.py, measured calibration plus offsets) or
``--gt-joints`` (ground-truth joints and the true calibration).  Silhouettes:
foreground extraction (median background), or ``--gt-masks``.  Settings:
``--config FILE.toml`` with a ``[segmentation]`` table of
``toolkit.segmentation.SegmentationConfig`` fields (docs/stage2_segmentation.md).
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

from toolkit.errors import InputError


def _config(path: Path | None):
    from dataclasses import fields

    from toolkit.segmentation import SegmentationConfig

    if path is None:
        return SegmentationConfig()
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise InputError(str(path), "a readable TOML file", f"{type(e).__name__}: {e}") from None
    table = data.get("segmentation", {})
    known = {f.name for f in fields(SegmentationConfig)}
    for k in table:
        if k not in known:
            raise InputError(f"{path}: segmentation.{k}", f"one of {sorted(known)}", repr(k))
    return SegmentationConfig(**table)


def main(argv=None) -> int:
    from toolkit.segmentation import TEMPLATE_POSES

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="dataset folder (docs/dataset_layout.md)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--poses", type=Path, default=None, help="output folder of recipes/pose_from_silhouettes.py")
    src.add_argument("--gt-joints", action="store_true", help="use the ground-truth joints and calibration")
    ap.add_argument("--gt-masks", action="store_true", help="use the ground-truth silhouettes")
    ap.add_argument("--template-pose", choices=TEMPLATE_POSES, default="multiview",
                    help="fit the template to the stage-1 3D joints projected (multiview, default) or to each "
                         "view's stage-1 2D pose (per_view)")
    ap.add_argument("--config", type=Path, default=None, help="TOML file with a [segmentation] table")
    ap.add_argument("--max-frames", type=int, default=None, help="process only the first N frames")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)

    import numpy as np
    from tqdm import tqdm

    from toolkit.foreground import extract_silhouettes
    from toolkit.io import Dataset, atomic_write_png, frame_filename
    from toolkit.io.layout import load_npz
    from toolkit.segmentation import PoseSource, part_iou, segment_views
    from toolkit.skeleton import SKELETON_14
    from toolkit.template import Template

    try:
        config = _config(args.config)
        ds = Dataset.open(args.dataset)
        names = ds.camera_names
        n = ds.frames_to_process(args.max_frames)
        if args.gt_joints:
            poses = PoseSource(ds.gt_rig, ds.gt_joints3d(), ds.gt_joints2d(), name="groundtruth")
        elif args.poses is not None:
            p3 = load_npz(args.poses / "poses3d.npz")
            p2 = load_npz(args.poses / "poses2d.npz")
            off = load_npz(args.poses / "offsets.npz")
            for f, d, k in (("poses3d.npz", p3, "joints"), ("offsets.npz", off, "offsets")):
                if k not in d:
                    raise InputError(str(args.poses / f), f"an array '{k}'", f"arrays {sorted(d)}")
            from toolkit.multiview import image_offsets
            from toolkit.calibration import stage_rig
            per_view = {c: p2[c] for c in names if c in p2} if args.template_pose == "per_view" else None
            poses = PoseSource(stage_rig(ds, args.poses), p3["joints"], per_view, image_offsets(off["offsets"]),
                               name=str(args.poses))
        else:
            print("no --poses or --gt-joints: the template is a standing pose fitted to each silhouette's box")
            poses = PoseSource(ds.rig, name="none")
        if args.gt_masks:
            def silhouette(c, t):
                return ds.gt_mask(c, t)
        else:
            fg = {c: extract_silhouettes([ds.frame(c, t) for t in range(n)], camera=c) for c in names}

            def silhouette(c, t):
                return fg[c][t].mask
        template = Template(1.75)
        args.out.mkdir(parents=True, exist_ok=True)
        observer = None
        if not args.no_recording:
            from toolkit.viz import RerunObserver
            observer = RerunObserver(application_id="segment_parts", path=args.out / "recording.rrd",
                                     camera_names=names)
            observer.report("rig", rig=poses.rig)
            observer.report("skeleton", skeleton=SKELETON_14)
        t0 = time.perf_counter()
        ious, missing, count = [], {}, 0
        try:
            run = segment_views(lambda c, t: ds.frame(c, t), silhouette, poses, n, template, config, observer)
            for t, c, r in tqdm(run, total=n * len(names), desc="segmentation", unit="view", disable=args.quiet):
                if observer is not None:
                    observer.report("image", camera=c, image=ds.frame(c, t), frame=t)
                atomic_write_png(args.out / "parts" / c / frame_filename(t), r.labels)
                count += 1
                for p in r.parts_without_model:
                    missing[p] = missing.get(p, 0) + 1
                if ds.has_groundtruth:
                    ious.append(part_iou(r.labels, ds.gt_parts(c, t)))
        finally:
            if observer is not None:
                observer.close()
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    dt = time.perf_counter() - t0
    print(f"segmented {count} views ({n} frames x {len(names)} cameras) in {dt:.1f} s "
          f"({dt / max(count, 1):.2f} s/view); poses: {poses.name}")
    if missing:
        print("parts without a colour model: " + ", ".join(
            f"{SKELETON_14.part_names[p - 1]} ({k} views)" for p, k in sorted(missing.items())))
    if ious:
        m = np.nanmean(np.array(ious), 0)
        print("IoU against groundtruth/parts: mean {:.3f}; ".format(np.nanmean(m)) + ", ".join(
            f"{nm} {v:.2f}" for nm, v in zip(SKELETON_14.part_names, m)))
    print(f"  part labels: {args.out / 'parts'}/<camera>/NNNNNN.png")
    if not args.no_recording:
        print(f"  recording:   {args.out / 'recording.rrd'}   (open with: rerun {args.out / 'recording.rrd'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
