#!/usr/bin/env python3
"""Joint centres from optical markers: a marker capture folder or a C3D file (source 004).

Usage::

    python recipes/make_scene.py datasets_synthetic/markers_rom.toml --out out/markers_rom
    python recipes/joint_centres.py out/markers_rom --out out/markers_rom_centres
    python recipes/joint_centres.py ../shared/realdata/c3d_functional/right_hip.c3d --out out/right_hip

DATASET is either

* a marker capture folder (``markers/calibration.toml`` with the capture's
  ``fps``, ``n_frames`` and ``marker_set`` in its metadata, and
  ``markers/detections/<camera>.npz``, as ``recipes/make_scene.py`` writes for a
  spec with a ``[markers]`` table): the 2D blobs are reconstructed (trinocular
  matching), identified from the marker set's template (or ``--labelling FILE``)
  and tracked; with ground truth (``groundtruth/``) the labelling and the
  joint centres are scored;
* or a C3D file of 3D markers (ezc3d; ``POINT:UNITS`` mm or m), labelled
  (Plug-in Gait names, or ISB-style names such as ``RASIS``/``RTHI1``/``RLFE``)
  or not (``M000``...: rigid subsets and the centres between them are found
  without labels).

Writes ``OUT/joint_centres.npz`` (``joints`` (T, 14, 3) metres, ``names`` (14,),
``method`` per joint: score / sara / sphere / circle (functional) or template /
anatomical (the scaled generic skeleton), ``residual_mm``, ``rom_deg``,
``fps``; without labels ``pair_centres`` (P, T, 3) and ``pair_names``),
``OUT/joint_centres.c3d`` (the markers plus the centres as points
``<JOINT>_JC`` / ``S0_S1_CR``), ``OUT/skeleton.json`` (stature, bone lengths,
per joint the method, residual and range of motion, the rigid subsets and the
messages, e.g. that a static trial gives the generic skeleton because
functional centres need movement), ``OUT/trajectories.npz`` (the labelled
markers), ``OUT/metrics.json`` and ``OUT/recording.rrd`` (cameras, 2D blobs,
reconstructed and labelled markers, tracks, the rigid subsets in colours,
fitted spheres and axes, the centres and the skeleton).

The outputs are written together at the end: Ctrl-C or SIGTERM stops a run
with exit code 130, a full disk with an error naming the file (exit code 2),
and both leave the outputs and recording of an earlier complete run in OUT as
they were.

Options may also come from a TOML file (--config; the keys of
toolkit.pipeline.joint_centres.JointCentresRunConfig, the centres' in a
[centres] table, the labelling's in [label]; flags given here win).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from toolkit.errors import InputError
from toolkit.pipeline.joint_centres import JointCentresRunConfig, run, summary_lines
from toolkit.pipeline.run import load_config


def parser() -> argparse.ArgumentParser:
    """The recipe's command line (defaults of valued options: None, so a --config file's values stand)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("dataset", type=Path, help="marker capture folder or .c3d file")
    ap.add_argument("--out", type=Path, required=True, help="output folder")
    ap.add_argument("--config", type=Path, default=None, help="options from a TOML file (flags given here win)")
    ap.add_argument("--marker-set", default=None, help="marker set of a capture folder (default: its metadata's) "
                    "or of a C3D file's labels (default: found from the labels)")
    ap.add_argument("--labelling", type=Path, default=None, help="user labelling file (JSON or CSV)")
    ap.add_argument("--min-rom", type=float, default=None, help="least range of motion for a functional centre, deg")
    ap.add_argument("--height", type=float, default=None, help="performer's stature in metres (default: fitted)")
    ap.add_argument("--no-labels", action="store_true", help="ignore the labels: find rigid subsets without them")
    ap.add_argument("--no-recording", action="store_true", help="do not write recording.rrd")
    ap.add_argument("--replace-stale", action="store_true",
                    help="if OUT holds results of another input or other options, move it to OUT.stale-N "
                         "and start afresh (default: refuse)")
    return ap


def config_from_args(args: argparse.Namespace) -> JointCentresRunConfig:
    """The run's config: the --config file (or the defaults), then the flags given."""
    config = load_config(JointCentresRunConfig, args.config, marker_set=args.marker_set, labelling=args.labelling)
    centres = config.centres
    flags = (("min_rom_deg", args.min_rom), ("height_m", args.height),
             ("marker_set", "none" if args.no_labels else None))
    centres = replace(centres, **{k: v for k, v in flags if v is not None})
    return replace(config, centres=centres, recording=config.recording and not args.no_recording,
                   replace_stale=config.replace_stale or args.replace_stale)


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
