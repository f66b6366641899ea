#!/usr/bin/env python3
"""Correct 2D joints in the browser: drag them, re-triangulate, grow the silhouette database.

Usage::

    python recipes/pose_from_silhouettes.py out/default --out out/default_stage1
    python recipes/correct_poses.py out/default_stage1 --port 8050      # then open http://127.0.0.1:8050/
    python recipes/pose_from_silhouettes.py out/default --out out/default_stage1b \\
        --edits out/default_stage1/edits.toml                            # the corrections applied

Serves a local page for the output folder RUN of ``pose_from_silhouettes.py``
or ``free_viewpoint.py``: per frame every camera's image with its 2D joints
and bones, the 3D joints' reprojection, a frame slider, the multi-view cost,
the 3D skeleton and the joints that break an anthropometric rule.  Dragging a
joint re-triangulates the frame and writes the correction to RUN/edits.toml
(the ``--edits`` format); "undo" takes it back; "add to database" adds the
frame's poses with their silhouettes to the silhouette database (the default
one that the recipes use, or --db).  Nothing else is written.  The JSON API
the page uses is in docs/correction.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from toolkit.errors import InputError


def parser() -> argparse.ArgumentParser:
    """The recipe's command line."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("run", type=Path, help="output folder of pose_from_silhouettes.py or free_viewpoint.py")
    ap.add_argument("--port", type=int, default=8050, help="port of the page (default 8050)")
    ap.add_argument("--host", default="127.0.0.1",
                    help="address to listen on (default 127.0.0.1: this machine only)")
    ap.add_argument("--dataset", type=Path, default=None,
                    help="the run's dataset folder (default: the one named in RUN/calibration.toml)")
    ap.add_argument("--db", type=Path, default=None,
                    help="silhouette database that 'add to database' grows (default: the cached default one)")
    ap.add_argument("--foreground", choices=("median", "mog2", "knn", "chroma"), default="median",
                    help="how the silhouettes added to the database are cut (as the run's --foreground)")
    ap.add_argument("--screenshot", type=Path, default=None,
                    help="save a picture of the page (first frame) with headless Chromium to this PNG and exit")
    return ap


def main(argv=None) -> int:
    ap = parser()
    args = ap.parse_args(argv)
    if not 0 < args.port < 65536:
        ap.error(f"--port: expected 1..65535, found {args.port}")
    from toolkit.correction import CorrectionSession
    from toolkit.correction.serve import screenshot_page, serve

    try:
        session = CorrectionSession(args.run, args.dataset, args.db, args.foreground)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"{len(session.frames)} frames of {args.run} ({session.kind}), cameras {', '.join(session.camera_names)}")
    print(f"corrections: {args.run / 'edits.toml'}; database: {session.database_path}")
    try:
        if args.screenshot is not None:
            print(f"page: {screenshot_page(session, args.host, args.port, args.screenshot)}")
            return 0
        print(f"open http://{args.host}:{args.port}/  (Ctrl-C to stop)", flush=True)
        serve(session, args.host, args.port)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    finally:
        session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
