#!/usr/bin/env python3
"""Joint centres on the real C3D captures of ``../shared/realdata`` (issue 17): distances and pictures.

Usage::

    python benchmarks/markers_realdata.py                      # numbers only
    python benchmarks/markers_realdata.py --images docs/images # and docs/images/markers_*.png

Real data is never committed; this script reads it from ``$TOOLKIT_REALDATA``
or ``../shared/realdata`` and says so when it is absent.  Measured:

* ``c3d_functional/right_hip.c3d`` (a right-hip functional trial, thigh and
  shank clusters): the functional hip centre (SCoRE, Ehrig et al. 2006)
  against the pelvic regression of Harrington et al. 2007 from the ASIS/PSIS
  markers, and the knee (SARA, Ehrig et al. 2007, forced even where the
  default gates refuse it) against the midpoint of the epicondyles ``RLFE/RMFE``:
  median distance over frames (target 25 mm);
* ``c3d_plugin_gait/Movement_trial.c3d`` (walking, Plug-in Gait markers): knee
  and ankle centres against Plug-in Gait's own ``LFEO/RFEO``, ``LTIO/RTIO``
  stored in the file, hips against ``LFEP/RFEP``;
* ``c3d_plugin_gait/Static_trial.c3d``: the scaled generic skeleton (stature,
  bone lengths) and its message;
* ``c3d_functional/arm-*.c3d`` and ``fullbody_*.c3d`` (unlabelled ``M000``...):
  the rigid subsets and the centres of rotation between them, found without labels.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from toolkit.markers.functional import JointCentresConfig, joint_centres, trajectories_from_c3d
from toolkit.markers.skeleton_fit import J14, harrington_hips

SUBSET_BGR = [(75, 25, 230), (75, 180, 60), (25, 225, 255), (200, 130, 0), (48, 130, 245), (180, 30, 145),
              (240, 240, 70), (230, 50, 240), (60, 245, 210), (212, 190, 250), (128, 128, 0), (255, 190, 220),
              (40, 110, 170), (0, 0, 128), (195, 255, 170)]


def realdata_root() -> Path:
    env = os.environ.get("TOOLKIT_REALDATA")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "shared" / "realdata"


def _median_mm(a, b) -> float:
    d = np.linalg.norm(a - b, axis=-1)
    return float(1e3 * np.nanmedian(d))


def draw(traj, res, frame: int, title: str, path: Path) -> None:
    """Front (x-z) and side (y-z) views of one frame: markers by subset, centres, axes (OpenCV)."""
    import cv2

    pos = traj.positions[frame]
    subset_of = np.full(traj.n_markers, -1)
    for k, idx in enumerate(res.subsets.values()):
        for i in idx:
            if subset_of[i] < 0:
                subset_of[i] = k
    cents = [(k, f.centre[frame], None if f.axis is None else f.axis[frame]) for k, f in res.fits.items()]
    allp = np.concatenate([pos[np.isfinite(pos).all(axis=1)]] + [c[1][None] for c in cents
                                                                   if np.isfinite(c[1]).all()])
    lo, hi = allp.min(axis=0) - 0.1, allp.max(axis=0) + 0.1
    size = 420
    scale = (size - 40) / max(hi[2] - lo[2], hi[0] - lo[0], hi[1] - lo[1])
    img = np.full((size + 40, 2 * size, 3), 255, np.uint8)
    for v, (a, b) in enumerate(((0, 2), (1, 2))):
        def px(p):
            return (int(v * size + 20 + (p[a] - lo[a]) * scale), int(size + 20 - (p[b] - lo[b]) * scale))
        for i in range(traj.n_markers):
            if np.isfinite(pos[i]).all():
                col = SUBSET_BGR[subset_of[i] % len(SUBSET_BGR)] if subset_of[i] >= 0 else (150, 150, 150)
                cv2.circle(img, px(pos[i]), 5, col, -1, cv2.LINE_AA)
        for k, c, ax in cents:
            if not np.isfinite(c).all():
                continue
            if ax is not None and np.isfinite(ax).all():
                cv2.line(img, px(c - 0.1 * ax), px(c + 0.1 * ax), (0, 0, 0), 2, cv2.LINE_AA)
            cv2.circle(img, px(c), 8, (0, 0, 0), 2, cv2.LINE_AA)
            cv2.drawMarker(img, px(c), (0, 0, 0), cv2.MARKER_CROSS, 10, 1)
        if res.labelled:
            for a_, b_ in ((1, 0), (1, 2), (2, 3), (3, 4), (1, 5), (5, 6), (6, 7), (1, 8), (8, 9), (9, 10),
                           (1, 11), (11, 12), (12, 13)):
                pa, pb = res.joints[frame, a_], res.joints[frame, b_]
                if np.isfinite(pa).all() and np.isfinite(pb).all():
                    cv2.line(img, px(pa), px(pb), (90, 90, 90), 1, cv2.LINE_AA)
    cv2.putText(img, title, (10, size + 32), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, "front (x-z)", (10, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, "side (y-z)", (size + 10, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), img)


def right_hip(root: Path, images: Path | None) -> list:
    tr = trajectories_from_c3d(root / "c3d_functional" / "right_hip.c3d")
    P = {lab: tr.positions[:, i] for i, lab in enumerate(tr.labels)}
    res = joint_centres(tr)
    _, rh = harrington_hips(P["LASIS"], P["RASIS"], P["LPSIS"], P["RPSIS"])
    epi = 0.5 * (P["RLFE"] + P["RMFE"])
    forced = joint_centres(tr, config=replace(JointCentresConfig(), max_hinge_conditioning=1.0,
                                              max_residual_m=1.0, min_rom_deg=10.0))
    kf = forced.fits.get("r_knee")
    out = [f"right_hip.c3d ({tr.n_frames} frames): r_hip {res.method[J14['r_hip']]}, residual "
           f"{1e3 * res.residual_m[J14['r_hip']]:.1f} mm, range {res.rom_deg[J14['r_hip']]:.0f} deg; "
           f"median distance to Harrington's hip {_median_mm(res.joints[:, J14['r_hip']], rh):.1f} mm"]
    if kf is not None:
        d = epi - kf.centre
        perp = d - np.sum(d * kf.axis, axis=1, keepdims=True) * kf.axis
        out.append(f"  r_knee by default: {res.method[J14['r_knee']]} ({'; '.join(m for m in res.messages if 'r_knee' in m)})")
        out.append(f"  r_knee SARA forced: residual {1e3 * kf.residual_m:.1f} mm, range {kf.rom_deg[0]:.0f} deg, "
                   f"singular value ratio {kf.conditioning:.2f}; median distance to the epicondyle midpoint "
                   f"{_median_mm(kf.centre, epi):.1f} mm, of which across the axis "
                   f"{1e3 * np.nanmedian(np.linalg.norm(perp, axis=1)):.1f} mm (along it the centre is placed "
                   f"at the anatomical estimate)")
    if images is not None:
        f = int(np.argmax(np.linalg.norm(res.fits["r_hip"].centre - res.fits["r_hip"].centre.mean(0), axis=1))) \
            if "r_hip" in res.fits else 0
        draw(tr, res, 0, "right_hip.c3d: segments (colours), functional r_hip, skeleton", images / "markers_right_hip.png")
        _ = f
    return out


def plug_in_gait(root: Path, images: Path | None) -> list:
    from toolkit.markers.marker_sets import get_marker_set

    tr = trajectories_from_c3d(root / "c3d_plugin_gait" / "Movement_trial.c3d")
    P = {lab: tr.positions[:, i] for i, lab in enumerate(tr.labels)}
    ms = get_marker_set("plug-in-gait")
    sub = tr.subset([lab for lab in tr.labels if lab in ms.labels])
    res = joint_centres(sub)
    out = [f"Movement_trial.c3d ({tr.n_frames} frames, walking, Plug-in Gait), vs Plug-in Gait's outputs in the file:"]
    for j, ref in (("l_knee", "LFEO"), ("r_knee", "RFEO"), ("l_ankle", "LTIO"), ("r_ankle", "RTIO"),
                   ("l_hip", "LFEP"), ("r_hip", "RFEP")):
        i = J14[j]
        out.append(f"  {j} ({res.method[i]}): median {_median_mm(res.joints[:, i], P[ref]):.1f} mm to {ref}"
                   + ("" if res.method[i] not in ("score", "sara", "sphere", "circle") else
                      f" (generic skeleton's: {_median_mm(res.generic[:, i], P[ref]):.1f} mm)"))
    out += [f"  note: {m}" for m in res.messages]
    out += _pig_knee_axes(sub, P)
    if images is not None:
        draw(sub, res, 100, "Movement_trial.c3d frame 100: Plug-in Gait segments, centres, skeleton",
             images / "markers_movement_trial.png")
    st = trajectories_from_c3d(root / "c3d_plugin_gait" / "Static_trial.c3d")
    st = st.subset([lab for lab in st.labels if lab in ms.labels])
    rs = joint_centres(st)
    out.append(f"Static_trial.c3d: stature {rs.height_m:.3f} m (Test.vsk: 1.679 m); methods {sorted(set(rs.method))}; "
               + "; ".join(m for m in rs.messages if "no functional" in m))
    out.append("  bone lengths (m): " + ", ".join(f"{k} {v:.3f}" for k, v in rs.lengths.items()))
    return out


def _pig_knee_axes(sub, P) -> list:
    """The knees' circle fits forced through every gate: their axes against the pelvis's and Plug-in Gait's."""
    forced = joint_centres(sub, config=replace(JointCentresConfig(), max_hinge_conditioning=1.0, max_residual_m=1.0,
                                               max_axis_spread_m=1.0))

    def angle(a, b):
        a = a / np.linalg.norm(a, axis=1, keepdims=True)
        b = b / np.linalg.norm(b, axis=1, keepdims=True)
        return float(np.nanmedian(np.degrees(np.arccos(np.clip(np.abs(np.sum(a * b, axis=1)), 0, 1)))))

    out = []
    for s in "LR":
        f = forced.fits.get(f"{s.lower()}_knee")
        if f is None or f.axis is None:
            continue
        pig_axis = P[f"{s}FEL"] - P[f"{s}FEO"]
        out.append(f"  {s.lower()}_knee circle fit forced ({f.method}, axis spread {1e3 * f.axis_spread_m:.1f} mm, "
                   f"residual {1e3 * f.residual_m:.1f} mm): median {_median_mm(f.centre, P[s + 'FEO']):.1f} mm to "
                   f"{s}FEO; its axis {angle(f.axis, P['RASI'] - P['LASI']):.0f} deg from the ASIS line, Plug-in "
                   f"Gait's femur axis ({s}FEL-{s}FEO) {angle(pig_axis, P['RASI'] - P['LASI']):.0f} deg, the two "
                   f"{angle(f.axis, pig_axis):.0f} deg apart")
    return out


def unlabelled(root: Path, images: Path | None) -> list:
    out = []
    for name, tag in (("arm-4-2-3_clean_120fps.c3d", "arm"), ("fullbody_44Markers_clean_120fps.c3d", "fullbody")):
        tr = trajectories_from_c3d(root / "c3d_functional" / name)
        res = joint_centres(tr)
        out.append(f"{name} ({tr.n_frames} frames, {tr.n_markers} unlabelled markers): {len(res.subsets)} rigid "
                   f"subsets {[len(s) for s in res.subsets.values()]}, {len(res.fits)} centres: "
                   + ", ".join(f"{k} {f.method} {1e3 * f.residual_m:.1f} mm / {f.rom_deg[0]:.0f} deg"
                               for k, f in res.fits.items()))
        if images is not None:
            draw(tr, res, tr.n_frames // 2, f"{name}: rigid subsets found without labels, centres (circles)",
                 images / f"markers_{tag}.png")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--images", type=Path, default=None, help="write markers_*.png here")
    args = ap.parse_args(argv)
    root = realdata_root()
    if not (root / "c3d_functional").is_dir() or not (root / "c3d_plugin_gait").is_dir():
        print(f"real data not found at {root} (set TOOLKIT_REALDATA)")
        return 1
    for part in (right_hip, plug_in_gait, unlabelled):
        print("\n".join(part(root, args.images)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
