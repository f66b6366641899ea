#!/usr/bin/env python3
"""Fit an articulated soft-object (metaball) body model to the point clouds of a sequence (source 002).

Usage::

    python recipes/make_scene.py datasets_synthetic/softbody_depth.toml --out out/softbody_depth
    python recipes/fit_soft_body.py out/softbody_depth --out out/softbody_depth_fit --meshes
    python recipes/fit_soft_body.py out/softbody_trinocular --out out/softbody_tri_fit --init-joints joints.npz
    python recipes/fit_soft_body.py ../shared/realdata/kinect_depth --out out/kinect_softbody --independent \
        --images docs/images

DATASET is a dataset folder with a depth camera (``depth_camera/``, the depth
tracker's skeleton initialises the model), a folder of depth frames (the same),
or a dataset of trinocular stereo heads (``layout = "trinocular"``: cameras
3k, 3k+1, 3k+2 are a head's reference, right and up cameras; the subject is
found by the dataset's masks or its clean plates; the model is initialised from
``--init-joints FILE.npz`` (``joints`` (T, 14, 3) or (14, 3), metres, e.g. stage
1's output), from 2D joints clicked in two images, ``--clicks FILE.npz``, or,
with neither, from the built-in 2D detector's keypoints on each head's reference
camera triangulated across the heads).

Every tracked frame gets a confidence from its residuals, coverage and
silhouettes; a frame it calls lost is searched for again (the depth tracker's
skeleton, the detector's joints, poses near the last trusted one;
``--no-recovery``: only said) and, if not found, is not written as tracked:
its joints are NaN and the summary lists the trusted frames.

Per frame the cloud is reduced to robust surface patches, the pose is tracked
from frame to frame, then all postures, the bone lengths and the metaball
widths are fitted together (``--no-global-fit`` skips that).  ``--independent``
fits unrelated depth frames (e.g. the real Kinect stills) each on its own, from
the depth tracker's skeleton of that frame.

Writes ``OUT/joints.npz`` (``joints`` (T, 14, 3) metres, world; ``names``;
``joints_tracking`` before the global fit; both NaN in frames not trusted; ``state``,
``trusted``, ``recovered`` (found again after a loss) and ``confidence`` per frame;
``params`` and ``params_tracking`` (T, 47) the model's parameter vectors, held
poses in lost frames),
``OUT/body_model.json`` (stature and girth of the reference model, segment and
bone lengths, widths, metaball centres, radii and weights), ``OUT/meshes/NNNNNN.ply`` with ``--meshes``,
``OUT/metrics.json`` (frame states; ``trusted_frames``, ``lost_frames``,
``recovered_frames``; with ground truth, MPJPE and bone-length error of the
trusted frames after tracking and after the global fit) and ``OUT/recording.rrd`` (the
clouds, patches, the model surface per frame, residuals coloured on the
patches, joints, the fitted lengths over the iterations); with ``--images DIR``
one PNG per frame, ``DIR/softbody_NNN.png``: the fitted surface with the points
over it (coloured by their distance to it), from the camera and from the side.

Tracking carries its state from frame to frame, so a run always fits the
whole sequence and writes its results together at the end: Ctrl-C or SIGTERM
stops it with exit code 130, a full disk with an error naming the file (exit
code 2), and both leave the results and recording of an earlier complete run
in OUT as they were; the same command then fits them again.  A run killed
outright leaves its recording's finished parts (``OUT/recording.parts/``).

Options may also come from a TOML file (--config; the keys of
toolkit.pipeline.soft_body.SoftBodyRunConfig, nested [stereo], [patches],
[track] and [fit] tables; flags given on the command line win).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.run import load_config
from toolkit.pipeline.soft_body import INITS, SOURCES, SoftBodyRunConfig, run, summary_lines
from toolkit.pipeline.soft_body_sources import FOREGROUNDS


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="dataset folder (depth camera or trinocular heads) or depth frames")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--source", choices=SOURCES, default=None, help="cloud source (default: auto)")
    ap.add_argument("--foreground", choices=FOREGROUNDS, default=None,
                    help="stereo: how the subject is found (default: masks/, else clean plates)")
    ap.add_argument("--init", choices=INITS, default=None, help="initial joints (default: auto)")
    ap.add_argument("--init-joints", type=Path, default=None, help=".npz with joints (T, 14, 3) or (14, 3)")
    ap.add_argument("--clicks", type=Path, default=None, help=".npz with 2D joints clicked in two images")
    ap.add_argument("--init-frame", type=int, default=None, help="frame of the initial joints (default 0)")
    ap.add_argument("--frames", type=int, default=None, help="use at most this many frames")
    ap.add_argument("--meshes", action="store_true", help="write OUT/meshes/NNNNNN.ply")
    ap.add_argument("--images", type=Path, default=None,
                    help="write the fitted surface with the points over it (camera and side views) here")
    ap.add_argument("--independent", action="store_true",
                    help="unrelated depth frames: each initialised from its own depth-tracker skeleton")
    ap.add_argument("--no-global-fit", action="store_true", help="track only (no lengths/widths fit)")
    ap.add_argument("--no-recovery", action="store_true",
                    help="say lost frames but do not search for the person again")
    ap.add_argument("--posture-weight", type=float, default=None,
                    help="pull of the trunk's bend and twist against the pelvis towards 0 in the initial fit, "
                         "tracking and the global fit, m/rad (default 0.2; 0 for motions that twist the trunk)")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--replace-stale", action="store_true",
                    help="if OUT holds results of another dataset or other options, move it to OUT.stale-N")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    return ap


def config_from_args(args: argparse.Namespace) -> SoftBodyRunConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(SoftBodyRunConfig, args.config, source=args.source, foreground=args.foreground,
                         init=args.init, init_joints=args.init_joints, clicks=args.clicks,
                         init_frame=args.init_frame, max_frames=args.frames, images=args.images)
    if args.posture_weight is not None:
        config = config.with_posture_weight(args.posture_weight)
    return replace(config, meshes=config.meshes or args.meshes, independent=config.independent or args.independent,
                   global_fit=config.global_fit and not args.no_global_fit,
                   recovery=config.recovery and not args.no_recovery,
                   recording=config.recording and not args.no_recording,
                   replace_stale=config.replace_stale or args.replace_stale, progress=config.progress and not args.quiet)


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    try:
        result = run(config_from_args(args), dataset=args.dataset, out=args.out)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print("\n".join(summary_lines(result)))
    return 130 if result.stopped else 0


if __name__ == "__main__":
    sys.exit(main())
