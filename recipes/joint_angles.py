#!/usr/bin/env python3
"""Joint angles, and BVH / glTF animations, from any system's 3D output.

Usage::

    python recipes/joint_centres.py ../shared/realdata/c3d_plugin_gait/Movement_trial.c3d --out out/walk_centres
    python recipes/joint_angles.py out/walk_centres --out out/walk_angles --bvh --gltf
    python recipes/joint_angles.py out/balancing --out out/balancing_angles --engine opensim

RUN is a run folder of any system (``poses3d.npz`` of keypoints or free
viewpoint, ``joint_centres.npz`` of markers, with their labelled markers in
``trajectories.npz``, ``skeleton.npz`` of depth, ``joints.npz`` of soft body)
or one of those files.  A free-viewpoint run with several people also has
``people3d.npz``: ``--person NAME`` takes one of them, ``--person all`` each
into ``OUT/<person>/``; an unknown name is refused with the list of people.

Writes ``OUT/angles.csv`` (``time`` in seconds, then one column per angle in
degrees, ``<side>_<joint>_<motion>``: ``l_hip_flexion``, ``r_knee_flexion``,
``l_ankle_dorsiflexion`` ...; flexion, dorsiflexion, adduction, abduction and
internal rotation positive as Plug-in Gait reports them), ``OUT/summary.json``,
``OUT/recording.rrd`` (a plot per joint over time, the joints in 3D); with
``--bvh`` ``OUT/motion.bvh`` and with ``--gltf`` ``OUT/motion.glb`` (an animated
skeleton, rest pose from the estimate's median bone lengths); with ``--engine
opensim`` (``pip install .[opensim]``) also the scaled model ``OUT/model_scaled.osim``,
the inverse kinematics ``OUT/ik.mot`` and ``OUT/marker_residuals.json``.
See docs/joint_angles.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from toolkit.biomech.run import ENGINES, JointAnglesConfig, run, run_every_person, summary_lines
from toolkit.errors import InputError


def parser() -> argparse.ArgumentParser:
    """The recipe's command line."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("run", type=Path, help="a run folder (or its poses3d/joint_centres/skeleton/joints .npz)")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--engine", choices=ENGINES, default="own", help="own segment-frame angles or OpenSim IK")
    ap.add_argument("--fps", type=float, default=None, help="frame rate when the run's files do not say")
    ap.add_argument("--static", type=Path, default=None,
                    help="a static trial's run of the same person (the feet's pitch offsets)")
    ap.add_argument("--bvh", action="store_true", help="also write OUT/motion.bvh")
    ap.add_argument("--gltf", action="store_true", help="also write OUT/motion.glb (animated skeleton)")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--person", default=None,
                    help="one person of a free-viewpoint run's people3d.npz, or 'all' (each into OUT/<person>/); "
                         "default: the run's poses3d.npz (the main person)")
    return ap


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    every = args.person == "all"
    config = JointAnglesConfig(engine=args.engine, fps=args.fps, static=args.static, bvh=args.bvh,
                               gltf=args.gltf, recording=not args.no_recording, person=None if every else args.person)
    try:
        if every:
            results = list(run_every_person(config, source=args.run, out=args.out).values())
        else:
            results = [run(config, source=args.run, out=args.out)]
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for result in results:
        print("\n".join(summary_lines(result)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
