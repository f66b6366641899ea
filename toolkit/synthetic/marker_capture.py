"""Synthetic optical marker captures with exact ground truth (a scene spec with a ``[markers]`` table).

The flow of :func:`generate_marker_capture`:

1. the person and motion of :func:`toolkit.synthetic.generator.build_scene`
   (same random streams, so the joints are those of the colour scene of the
   same spec), a ring of cameras (:func:`ring_rig`) and its measured
   calibration;
2. marker positions: the spec's :class:`~toolkit.markers.MarkerSet` on the
   skin of the body, rigid with their segments plus a smooth, seeded
   soft-tissue motion (:func:`soft_tissue_offsets`);
3. per camera and frame: projections through the *true* cameras, dropped
   when outside the image or hidden by the body (:func:`body_occlusion`, a
   ray test against the body's volumes), then missed in bursts
   (:func:`burst_misses`), moved by pixel noise, shuffled, and joined by
   ghost blobs;
4. the files of :mod:`toolkit.io.marker_files`.

No colour image is rendered, so a capture of a few thousand frames takes
seconds.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.body.model import BodyModel, BodyShape
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.markers.marker_sets import MarkerSet, get_marker_set, segment_origins, segment_rotations
from toolkit.motion import inverse_kinematics, motion_from_bvh, synthesize_motion
from toolkit.observe import as_observer
from toolkit.skeleton import SKELETON_14
from toolkit.synthetic.marker_spec import MarkerSpec
from toolkit.synthetic.rigs import camera_names, perturb_rig
from toolkit.synthetic.spec import SceneSpec

__all__ = ["GHOST_NEAR_SHARE", "GHOST_NEAR_PX", "OCCLUDER_SHRINK_M", "RAY_END_CLEARANCE_M", "MarkerScene",
           "build_marker_scene", "ring_rig", "soft_tissue_offsets", "body_occlusion", "burst_misses",
           "simulate_detections", "generate_marker_capture"]

#: Share of ghost blobs drawn near the performer's markers (the rest anywhere in the image).
GHOST_NEAR_SHARE = 0.5
#: Ghosts "near the performer" fall within this distance of a marker's projection, pixels.
GHOST_NEAR_PX = 40.0
#: The body volumes of the occlusion test are this much thinner than the mesh, metres, so a marker
#: on the skin (a marker radius out) is never inside its own segment's volume.
OCCLUDER_SHRINK_M = 0.002
#: The occlusion ray stops this short of the marker, metres (it grazes the skin it sits on).
RAY_END_CLEARANCE_M = 0.01
#: Frequencies of the soft-tissue motion, Hz (skin moves with muscle contraction and impacts).
SOFT_TISSUE_HZ = (0.3, 3.0)
_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
_MARKER_STREAM = "markers"


@dataclass(frozen=True)
class MarkerScene:
    """Everything of a marker capture before the 2D detections.

    Attributes
    ----------
    spec : SceneSpec
    marker_spec : MarkerSpec
    marker_set : MarkerSet
    shape : BodyShape
    joints : ndarray of shape (T, 14, 3)
        Ground-truth joints, metres, world (z up).
    markers : ndarray of shape (T, M, 3)
        Ground-truth marker centres, metres.
    rotations : dict of str to ndarray of shape (T, 3, 3)
        Segment frames (:func:`toolkit.markers.marker_sets.segment_rotations`).
    rig : Rig
        True cameras.
    measured_rig : Rig
        The calibration written for the pipeline.
    calibration_errors_px : ndarray of shape (n_cams,)
    rngs : dict of str to numpy.random.Generator
    """

    spec: SceneSpec
    marker_spec: MarkerSpec
    marker_set: MarkerSet
    shape: BodyShape
    joints: np.ndarray
    markers: np.ndarray
    rotations: dict
    rig: Rig
    measured_rig: Rig
    calibration_errors_px: np.ndarray
    rngs: dict


def ring_rig(mspec: MarkerSpec, centre, rng: np.random.Generator) -> Rig:
    """Cameras evenly around ``centre`` (azimuth jitter +-8 degrees), looking at the body's middle.

    Parameters
    ----------
    mspec : MarkerSpec
        Count, radius (+-5 %, kept in 3-6 m), height (+-0.2 m), resolution, field of view.
    centre : array_like of shape (2,) or (3,)
        Ground point the ring is centred on, metres.
    rng : numpy.random.Generator

    Returns
    -------
    Rig
        Cameras named ``cam00``, ``cam01``, ...
    """
    c = np.r_[np.asarray(centre, float)[:2], 0.0]
    n = mspec.camera_count
    start = rng.uniform(0, 2 * np.pi)
    cams = []
    for i, name in enumerate(camera_names(n)):
        az = start + 2 * np.pi * i / n + np.radians(rng.uniform(-8.0, 8.0))
        r = float(np.clip(mspec.radius_m * rng.uniform(0.95, 1.05), 3.0, 6.0))
        eye = c + np.array([r * np.cos(az), r * np.sin(az), max(0.3, mspec.height_m + rng.uniform(-0.2, 0.2))])
        target = c + np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), 0.9])
        cams.append(Camera.look_at(name, eye, target, size=mspec.resolution, fov_x_deg=mspec.fov_deg))
    return Rig(tuple(cams))


def soft_tissue_offsets(marker_set: MarkerSet, n_frames: int, fps: float, amplitude_m: float,
                        rng: np.random.Generator) -> np.ndarray:
    """Smooth displacement of each marker relative to its segment (soft-tissue artefact).

    Each axis is a sum of three sinusoids (frequencies in :data:`SOFT_TISSUE_HZ`,
    random phases) with a standard deviation of ``amplitude_m``; the markers of
    a cluster plate share one displacement of half that size (the plate is rigid).

    Returns
    -------
    ndarray of shape (n_frames, M, 3)
        Metres, segment frame.
    """
    t = np.arange(n_frames) / fps
    groups = [(lab[:-1] if p.plate is not None else lab) for lab, p in zip(marker_set.labels, marker_set.placements)]
    keys = list(dict.fromkeys(groups))
    out = np.zeros((n_frames, len(keys), 3))
    for g, key in enumerate(keys):
        plate = key not in marker_set.labels
        a = amplitude_m * (0.5 if plate else 1.0) / np.sqrt(1.5)
        f = rng.uniform(*SOFT_TISSUE_HZ, size=(3, 3))
        ph = rng.uniform(0, 2 * np.pi, size=(3, 3))
        out[:, g] = a * np.sin(2 * np.pi * f[None] * t[:, None, None] + ph[None]).sum(axis=1)
    return out[:, [keys.index(g) for g in groups]]


def build_marker_scene(spec: SceneSpec) -> MarkerScene:
    """The person, motion, markers and cameras of a marker spec (no detections yet).

    Raises
    ------
    InputError
        If the spec has no ``[markers]`` table.
    """
    from toolkit.synthetic.generator import RNG_STREAMS

    if spec.markers is None:
        raise InputError(f"{spec.source}: [markers]", "a [markers] table", "none")
    mspec = MarkerSpec.from_table(spec.markers, spec.source)
    names = (*RNG_STREAMS, _MARKER_STREAM)
    seqs = np.random.SeedSequence(spec.seed).spawn(len(names))
    rngs = {name: np.random.default_rng(s) for name, s in zip(names, seqs)}
    props = BodyProportions.sample(spec.height_m, rngs["body"])
    shape = BodyShape.sample(props, rngs["body"])
    ankle = None
    if spec.motion_is_bvh:
        joints = motion_from_bvh(spec.motion, props, spec.frames, spec.fps, rngs["motion"])
        pose = inverse_kinematics(joints)
    else:
        motion = synthesize_motion(spec.motion, props, spec.frames, spec.fps, rngs["motion"])
        joints, pose, ankle = motion.joints, motion.pose, motion.ankle
    mset = get_marker_set(mspec.set)
    offsets = soft_tissue_offsets(mset, spec.frames, spec.fps, mspec.soft_tissue_mm / 1000.0, rngs[_MARKER_STREAM])
    markers = mset.positions(joints, shape, pose=pose, ankle=ankle, local_offsets=offsets)
    centre = np.nanmean(0.5 * (joints[:, _J["l_hip"], :2] + joints[:, _J["r_hip"], :2]), axis=0)
    rig = ring_rig(mspec, centre, rngs["cameras"])
    measured, errs = perturb_rig(rig, mspec.calibration_error_px, markers.reshape(-1, 3), rngs["calibration"])
    return MarkerScene(spec, mspec, mset, shape, joints, markers, segment_rotations(pose, ankle), rig, measured,
                       np.asarray(errs, float), rngs)


# ------------------------------------------------------------- occlusion
def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _segment_distance(p0, p1, q0, q1):
    """Closest distance between segments p0-p1 and q0-q1 (broadcast (..., 3)) and the parameter on q."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    denom = a * e - b * b
    a_safe, e_safe = np.maximum(a, 1e-12), np.maximum(e, 1e-12)
    s = np.where(denom > 1e-12, np.clip((b * f - c * e) / np.maximum(denom, 1e-12), 0, 1), 0.0)
    t = (b * s + f) / e_safe
    s = np.where(t < 0, np.clip(-c / a_safe, 0, 1), np.where(t > 1, np.clip((b - c) / a_safe, 0, 1), s))
    s = np.where(e > 1e-12, s, np.clip(-c / a_safe, 0, 1))   # q is a point
    t = np.where(e > 1e-12, np.clip(t, 0, 1), 0.0)
    d = (p0 + d1 * s[..., None]) - (q0 + d2 * t[..., None])
    return np.sqrt(_dot(d, d)), t


def _point_segment_distance(x, p0, p1):
    """Distance from points x to segments p0-p1 (broadcast (..., 3))."""
    d = p1 - p0
    s = np.clip(_dot(x - p0, d) / np.maximum(_dot(d, d), 1e-12), 0, 1)
    v = p0 + d * s[..., None] - x
    return np.sqrt(_dot(v, v))


def _hits_cylinder(p0, p1, z_end, radii):
    """Does segment p0-p1 (frame of the cylinder, (N, 3)) enter the elliptic cylinder?

    The cylinder's axis is z from 0 to ``z_end`` (N,), its section the ellipse
    of ``radii`` (rx, ry) in x and y.
    """
    q0, d = p0[:, :2] / radii, (p1 - p0)[:, :2] / radii
    A = _dot(d, d)
    B = 2 * _dot(q0, d)
    Cq = _dot(q0, q0) - 1.0
    disc = B * B - 4 * A * Cq
    ok = disc >= 0
    sq = np.sqrt(np.maximum(disc, 0.0))
    A_safe = np.where(A > 1e-12, A, 1.0)
    s1 = np.where(A > 1e-12, (-B - sq) / (2 * A_safe), np.where(Cq <= 0, 0.0, np.inf))
    s2 = np.where(A > 1e-12, (-B + sq) / (2 * A_safe), np.where(Cq <= 0, 1.0, -np.inf))
    z0, dz = p0[:, 2], p1[:, 2] - p0[:, 2]
    lo_z, hi_z = np.minimum(0.0, z_end), np.maximum(0.0, z_end)
    dz_safe = np.where(np.abs(dz) > 1e-12, dz, 1.0)
    za, zb = (lo_z - z0) / dz_safe, (hi_z - z0) / dz_safe
    inside_z = (z0 >= lo_z) & (z0 <= hi_z)
    sz1 = np.where(np.abs(dz) > 1e-12, np.minimum(za, zb), np.where(inside_z, 0.0, np.inf))
    sz2 = np.where(np.abs(dz) > 1e-12, np.maximum(za, zb), np.where(inside_z, 1.0, -np.inf))
    lo = np.maximum.reduce([s1, sz1, np.zeros_like(s1)])
    hi = np.minimum.reduce([s2, sz2, np.ones_like(s2)])
    return ok & (lo <= hi)


def _occluders(joints, rotations, shape: BodyShape):
    """Body volumes per frame: (kind, a, b, r0, r1, frame R, scale) of capsules and ellipsoids.

    The volumes are those of :class:`toolkit.body.model.BodyModel` (tapered
    capsules, the torso's elliptical section, head, hand and foot ellipsoids),
    each :data:`OCCLUDER_SHRINK_M` thinner.
    """
    R = BodyModel(shape, rng=0).radii()
    h = shape.proportions.height / 1.75
    o = segment_origins(joints)
    k = OCCLUDER_SHRINK_M
    vols = []
    Rt = rotations["thorax"]
    neck, pel = joints[:, _J["neck"]], o["pelvis"]
    down = -Rt[..., 2]
    (rx0, ry0), (rx1, ry1) = R["torso"]
    # the torso: two elliptic cylinders (top and bottom halves, each with the smaller end's section)
    # and the mesh's flattened end caps as ellipsoids
    top, bottom = neck + 0.01 * h * down, pel + 0.02 * h * down
    mid, rxm, rym = 0.5 * (top + bottom), 0.5 * (rx0 + rx1), 0.5 * (ry0 + ry1)
    vols.append(("cylinder", top, mid, np.array([min(rx0, rxm), min(ry0, rym)]) - k, None, Rt, None))
    vols.append(("cylinder", mid, bottom, np.array([min(rxm, rx1), min(rym, ry1)]) - k, None, Rt, None))
    vols.append(("ellipsoid", top, None, np.array([rx0, ry0, 0.35 * 0.5 * (rx0 + ry0)]) - k, None, Rt, None))
    vols.append(("ellipsoid", bottom, None, np.array([rx1, ry1, 0.55 * 0.5 * (rx1 + ry1)]) - k, None, Rt, None))
    vols.append(("capsule", neck, joints[:, _J["head"]], R["neck"][0][0] - k, R["neck"][1][0] - k, None, None))
    Rh = rotations["head"]
    vols.append(("ellipsoid", joints[:, _J["head"]] + 0.02 * h * Rh[..., 2], None,
                 np.array([0.075, 0.090, 0.110]) * h - k, None, Rh, None))
    for s in "lr":
        for seg, a, b, key in (("upperarm", "shoulder", "elbow", "upper_arm"), ("forearm", "elbow", "wrist", "forearm"),
                               ("thigh", "hip", "knee", "thigh"), ("shank", "knee", "ankle", "shank")):
            (r0, _), (r1, _) = R[key]
            vols.append(("capsule", joints[:, _J[f"{s}_{a}"]], joints[:, _J[f"{s}_{b}"]], r0 - k, r1 - k, None, None))
        Rf = rotations[f"{s}_forearm"]
        vols.append(("ellipsoid", joints[:, _J[f"{s}_wrist"]] - 0.075 * h * Rf[..., 2], None,
                     np.array([0.045, 0.022, 0.085]) * h - k, None, Rf, None))
        Rft = rotations[f"{s}_foot"]
        centre = joints[:, _J[f"{s}_ankle"]] + np.einsum("tij,j->ti", Rft, np.array([0.0, 0.065, -0.031]) * h)
        # foot ellipsoid axes (x, forward, up) of the foot frame, radii (0.045, 0.125, 0.038) h
        vols.append(("ellipsoid", centre, None, np.array([0.045, 0.125, 0.038]) * h - k, None, Rft, None))
    return vols


def body_occlusion(rig: Rig, markers: np.ndarray, joints: np.ndarray, rotations: dict,
                   shape: BodyShape) -> np.ndarray:
    """Which markers the body hides from each camera.

    A marker is hidden when the segment from the camera centre to it (stopped
    :data:`RAY_END_CLEARANCE_M` short) enters one of the body's volumes.

    Parameters
    ----------
    rig : Rig
    markers : ndarray of shape (T, M, 3)
    joints : ndarray of shape (T, 14, 3)
    rotations : dict of str to ndarray of shape (T, 3, 3)
        Segment frames.
    shape : BodyShape

    Returns
    -------
    ndarray of shape (C, T, M), bool
        True where hidden.
    """
    T, M, _ = markers.shape
    out = np.zeros((len(rig), T, M), bool)
    vols = _occluders(joints, rotations, shape)
    for c, cam in enumerate(rig):
        C = np.broadcast_to(cam.center, markers.shape)
        ray = markers - C
        dist = np.linalg.norm(ray, axis=-1, keepdims=True)
        end = C + ray * (1.0 - RAY_END_CLEARANCE_M / np.maximum(dist, 1e-9))
        hidden = np.zeros((T, M), bool)
        for kind, a, b, r0, r1, Rv, scale in vols:
            # candidates: rays that pass within the volume's bounding sphere
            if kind == "ellipsoid":
                centre, bound = a, np.full(T, float(np.max(r0)))
            elif kind == "cylinder":
                centre = 0.5 * (a + b)
                bound = np.hypot(0.5 * np.linalg.norm(b - a, axis=-1), float(np.max(r0)))
            else:
                centre, bound = 0.5 * (a + b), 0.5 * np.linalg.norm(b - a, axis=-1) + max(r0, r1)
            cand = (_point_segment_distance(centre[:, None], C, end) < bound[:, None]) & ~hidden
            ti, mi = np.nonzero(cand)
            if not len(ti):
                continue
            Cc, Ec = C[ti, mi], end[ti, mi]
            if kind == "ellipsoid":  # to the unit sphere: x' = diag(1/r) R^T (x - centre)
                to = lambda x: np.einsum("nji,nj->ni", Rv[ti], x - a[ti]) / r0  # noqa: E731
                d, _ = _segment_distance(to(Cc), to(Ec), np.zeros(3), np.zeros(3))
                hit = d < 1.0
            elif kind == "cylinder":  # in the frame R with the section scaled to the unit circle
                to = lambda x: np.einsum("nji,nj->ni", Rv[ti], x - a[ti])  # noqa: E731
                hit = _hits_cylinder(to(Cc), to(Ec), np.einsum("nji,nj->ni", Rv[ti], b[ti] - a[ti])[:, 2], r0)
            else:
                d, s = _segment_distance(Cc, Ec, a[ti], b[ti])
                hit = d < (1 - s) * r0 + s * r1
            hidden[ti[hit], mi[hit]] = True
        out[c] = hidden
    return out


def burst_misses(visible: np.ndarray, share: float, burst_frames: float, rng: np.random.Generator) -> np.ndarray:
    """Missed detections in bursts: a two-state Markov chain per camera and marker.

    A run of misses lasts ``burst_frames`` frames on average and misses make
    up ``share`` of the frames in the long run (the chain starts in its
    stationary state).  Only visible projections can be missed.

    Parameters
    ----------
    visible : ndarray of shape (C, T, M), bool
    share : float
        In [0, 0.9).
    burst_frames : float
        >= 1.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of shape (C, T, M), bool
        True where a visible projection is missed.
    """
    C, T, M = visible.shape
    if share <= 0:
        return np.zeros_like(visible)
    p_end = 1.0 / burst_frames
    p_start = min(1.0, share * p_end / (1.0 - share))
    state = rng.random((C, M)) < share
    out = np.zeros((C, T, M), bool)
    u = rng.random((T, C, M))
    for t in range(T):
        out[:, t] = state
        state = np.where(state, u[t] >= p_end, u[t] < p_start)
    return out & visible


def simulate_detections(scene: MarkerScene, rng: np.random.Generator) -> dict:
    """2D blobs of every camera (see the module docstring).

    Returns
    -------
    dict
        ``per_camera``: camera name -> (centres (N, 2), frame (N,), marker (N,)),
        ``visible`` (C, T, M) bool (in the image and not hidden by the body),
        ``missed`` (C, T, M) bool, ``occluded`` (C, T, M) bool, ``n_ghosts`` int.
    """
    ms, rig, X = scene.marker_spec, scene.rig, scene.markers
    T, M, _ = X.shape
    occluded = body_occlusion(rig, X, scene.joints, scene.rotations, scene.shape)
    uv = np.stack([cam.project(X) for cam in rig])                     # (C, T, M, 2)
    in_img = np.stack([cam.in_image(uv[c]) for c, cam in enumerate(rig)]) & np.isfinite(uv).all(-1)
    visible = in_img & ~occluded
    missed = burst_misses(visible, ms.occlusion, ms.occlusion_burst_frames, rng)
    seen = visible & ~missed
    per_camera, n_ghosts = {}, 0
    for c, cam in enumerate(rig):
        w, h = cam.size
        tt, mm = np.nonzero(seen[c])
        cen = uv[c, tt, mm] + rng.normal(0.0, ms.noise_px, (len(tt), 2)) if ms.noise_px > 0 else uv[c, tt, mm]
        k = rng.poisson(ms.ghosts, T)
        gt = np.repeat(np.arange(T), k)
        near = rng.random(len(gt)) < GHOST_NEAR_SHARE
        g = np.column_stack([rng.uniform(-0.5, w - 0.5, len(gt)), rng.uniform(-0.5, h - 0.5, len(gt))])
        for i in np.flatnonzero(near):
            on = np.flatnonzero(in_img[c, gt[i]])
            if len(on):
                g[i] = uv[c, gt[i], rng.choice(on)] + rng.uniform(-GHOST_NEAR_PX, GHOST_NEAR_PX, 2)
        g[:, 0] = np.clip(g[:, 0], -0.5, w - 0.5)
        g[:, 1] = np.clip(g[:, 1], -0.5, h - 0.5)
        n_ghosts += len(gt)
        frame = np.r_[tt, gt]
        centres = np.vstack([cen.reshape(-1, 2), g])
        marker = np.r_[mm, np.full(len(gt), -1)]
        order = np.lexsort((rng.random(len(frame)), frame))   # by frame, random within a frame
        keep = cam.in_image(centres[order]) & np.isfinite(centres[order]).all(1)   # noise may push a blob out
        o = order[keep]
        per_camera[cam.name] = (centres[o], frame[o].astype(np.int32), marker[o].astype(np.int32))
    return {"per_camera": per_camera, "visible": visible, "missed": missed, "occluded": occluded,
            "in_image": in_img, "n_ghosts": n_ghosts}


def generate_marker_capture(spec: SceneSpec, out: str | Path, observer=None) -> dict:
    """Write the marker capture of ``spec`` into the folder ``out``.

    Parameters
    ----------
    spec : SceneSpec
        With a ``[markers]`` table.
    out : str or Path
        Capture folder (created; existing files are overwritten).
    observer : Observer, optional
        Receives the rig, the skeleton, and per frame the joints, the true
        markers and the 2D blobs of every camera.

    Returns
    -------
    dict
        The summary also written to ``groundtruth/marker_capture.json``.
    """
    from toolkit.io import atomic_write_text, write_calibration
    from toolkit.io.marker_files import (
        CALIBRATION,
        DETECTION_TRUTH_DIR,
        DETECTIONS_DIR,
        MARKER_TRUTH,
        write_detection_truth,
        write_joints3d_file,
        write_marker_detections,
        write_marker_truth,
    )

    obs = as_observer(observer)
    scene = build_marker_scene(spec)
    det = simulate_detections(scene, scene.rngs[_MARKER_STREAM])
    out = Path(out)
    ms = scene.marker_spec
    meta = {"fps": float(spec.fps), "n_frames": int(spec.frames), "marker_set": ms.set}
    write_calibration(out / CALIBRATION, scene.measured_rig, metadata=meta)
    write_calibration(out / "groundtruth" / "calibration.toml", scene.rig, metadata=meta)
    for cam in scene.rig:
        centres, frame, marker = det["per_camera"][cam.name]
        write_marker_detections(out / DETECTIONS_DIR / f"{cam.name}.npz", centres, frame, cam.size)
        write_detection_truth(out / DETECTION_TRUTH_DIR / f"{cam.name}.npz", marker)
    write_marker_truth(out / MARKER_TRUTH, scene.marker_set.labels, scene.markers, scene.marker_set.segments,
                       spec.fps, ms.set)
    write_joints3d_file(out / "groundtruth" / "joints3d.npz", scene.joints, SKELETON_14.joint_names)
    atomic_write_text(out / "scene.toml", spec.text)
    vis = det["visible"]
    info = {
        "seed": spec.seed, "motion": spec.motion, "marker_set": ms.set, "n_markers": scene.marker_set.n_markers,
        "n_frames": spec.frames, "fps": spec.fps, "cameras": scene.rig.names,
        "stature_m": scene.shape.proportions.height,
        "noise_px": ms.noise_px, "occlusion_target": ms.occlusion,
        "occlusion_achieved": float(det["missed"].sum() / max(vis.sum(), 1)),
        "hidden_by_body_share": float(det["occluded"][det["in_image"]].mean()) if det["in_image"].any() else 0.0,
        "in_image_share": float(det["in_image"].mean()),
        "ghosts_per_camera_frame": float(det["n_ghosts"] / (len(scene.rig) * spec.frames)),
        "seen_by_3_or_more_share": float(((vis & ~det["missed"]).sum(0) >= 3).mean()),
        "calibration_error_px_target": ms.calibration_error_px,
        "calibration_error_px": dict(zip(scene.rig.names, map(float, scene.calibration_errors_px))),
    }
    atomic_write_text(out / "groundtruth" / "marker_capture.json", json.dumps(info, indent=2))
    _report(obs, scene, det)
    return info


def _report(obs, scene: MarkerScene, det: dict) -> None:
    obs = as_observer(obs)
    obs.report("rig", rig=scene.rig, path="world/cams")
    obs.report("skeleton", skeleton=SKELETON_14)
    for t in range(scene.spec.frames):
        obs.report("joints3d", frame=t, joints=scene.joints[t], name="groundtruth/joints", skeleton=SKELETON_14)
        obs.report("points3d", frame=t, points=scene.markers[t], name="groundtruth/markers", radii=0.007)
        for cam in scene.rig:
            centres, frame, _ = det["per_camera"][cam.name]
            lo, hi = np.searchsorted(frame, [t, t + 1])
            obs.report("points2d", frame=t, camera=f"world/cams/{cam.name}", points=centres[lo:hi],
                       name="markers/blobs")
