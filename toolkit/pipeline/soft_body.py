"""The soft-body system's run: clouds -> patches -> initial model -> tracking -> global fit (source 002).

:func:`run` is what ``recipes/fit_soft_body.py`` calls (its docstring lists the
outputs).  One run is one sequence:

1. per frame, a cloud from the dataset's depth camera or trinocular stereo
   heads (:mod:`toolkit.pipeline.soft_body_sources`), reduced to robust
   surface-patch centres (:func:`toolkit.pointcloud.patches.surface_patches`);
2. the model scaled and posed on 14 joints of one frame
   (:func:`toolkit.softbody.model_from_joints`): the depth tracker's skeleton
   for depth input, a joints file or two-view clicks for stereo;
3. frame-to-frame tracking of the pose (:func:`toolkit.softbody.track_sequence`);
4. the global fit of all postures with the bone lengths and metaball widths
   (:func:`toolkit.softbody.global_fit`), unless ``global_fit = false``.

The run folder is identified like every run (``OUT/run.json``: the dataset and
the options that change the results); a folder of another run is refused
(``replace_stale`` moves it aside).  Tracking carries its state from frame to
frame and the global fit needs every frame, so a run always starts from the
first frame and replaces earlier results once it has its own
(:func:`toolkit.pipeline.run.whole_run`): Ctrl-C or SIGTERM ends it quietly
(``RunResult.stopped``), a full disk with an error naming the file, and
either leaves the results and recording of an earlier complete run as they
were; a run killed outright leaves its recording's finished parts
(``recording.parts/``, merged by the next run).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.pipeline.run import RunResult, frame_ranges, open_run, whole_run
from toolkit.pointcloud.patches import PatchConfig
from toolkit.pointcloud.stereo import StereoConfig
from toolkit.softbody import GlobalFitConfig, TrackConfig
from toolkit.softbody.confidence import ConfidenceConfig
from toolkit.softbody.init import POSTURE_WEIGHT, RefineConfig

#: Cloud sources.
SOURCES = ("auto", "depth", "stereo")
#: Where the initial joints come from.
INITS = ("auto", "depth_tracker", "joints", "clicks", "detector")
#: A re-initialisation from the detector needs at least this many of the 14 joints triangulated.
MIN_DETECTED_JOINTS = 8


@dataclass(frozen=True)
class SoftBodyRunConfig:
    """Options of a soft-body run (the recipe's flags; a TOML file holds the same keys).

    Parameters
    ----------
    source : str
        One of :data:`SOURCES` (``auto``: depth when the dataset has ``depth_camera/``).
    foreground : str
        Stereo: how the subject is found in the images (``auto``, ``masks``, ``plate``,
        ``groundtruth``; see :mod:`toolkit.pipeline.soft_body_sources`).
    init : str
        One of :data:`INITS` (``auto``: ``init_joints`` or ``clicks``, whichever is given, else the depth
        tracker for depth input and the built-in detector for stereo: its keypoints on each head's
        reference camera triangulated across the heads, :func:`~toolkit.pipeline.soft_body_sources.detect_joints`).
    init_joints : Path, optional
        ``.npz`` with ``joints`` (T, 14, 3) or (14, 3), metres, world (stage 1's output,
        triangulated clicks, ...).
    clicks : Path, optional
        ``.npz`` with 2D joints in two images (see :func:`~toolkit.pipeline.soft_body_sources.read_clicks`).
    init_frame : int
        Frame whose joints initialise the model (the first frame's pose is found by the tracker).
    init_posture_weight : float
        Pull of the initial pose's trunk bend and twist (against the pelvis) towards 0 when it is
        fitted to the initial joints, metres per radian (:func:`toolkit.softbody.model_from_joints`).
    stereo : StereoConfig
    patches : PatchConfig
    track : TrackConfig
        Frame-to-frame tracking (``viewpoints`` default to the source's camera centres).
    fit : GlobalFitConfig
        The global fit (``[fit]`` table in TOML; ``viewpoints`` default to the source's camera centres).
    confidence : ConfidenceConfig
        Per frame, how far the tracked pose can be trusted (residuals, coverage, silhouettes:
        :mod:`toolkit.softbody.confidence`; ``[confidence]`` table); a ``lost`` frame (and an ``empty`` or
        ``crowded`` one) is not written as tracked (its joints NaN in ``joints.npz``).
    recovery : bool
        Search for the person again in a lost frame (:func:`toolkit.softbody.track_sequence`): from the
        depth tracker's skeleton (depth input) or the built-in 2D detector's keypoints on each stereo head's
        reference camera, triangulated across the heads (:mod:`toolkit.softbody.reinit`), and from the last
        trusted pose moved over the cloud.
    refine : RefineConfig
        Clicks: the clicked model's pose and lengths refined on the init frame's points, silhouettes
        and the clicks as soft observations (:func:`toolkit.softbody.init.refine_initial_model`; ``[refine]``
        table; ``enabled = true`` to use it, off by default: see :class:`~toolkit.softbody.init.RefineConfig`).
    global_fit : bool
        Run the global fit after tracking.
    independent : bool
        Unrelated still frames (depth input): each frame's model is initialised from the
        depth tracker's skeleton of that frame and fitted alone (no global fit).
    mesh_voxel_m : float
        Grid step of the surface meshes (recording, ``meshes``), metres.
    meshes : bool
        Write ``OUT/meshes/NNNNNN.ply``.
    images : Path, optional
        Write the fitted surface with the cloud over it, from the camera and the side, per frame here.
    max_frames : int, optional
        Use at most this many frames (the first ones).
    recording : bool
        Write ``recording.rrd``.
    replace_stale : bool
        Move another run's results aside instead of refusing them.
    progress : bool
        Show a progress bar.
    """

    source: str = "auto"
    foreground: str = "auto"
    init: str = "auto"
    init_joints: Path | None = None
    clicks: Path | None = None
    init_frame: int = 0
    init_posture_weight: float = POSTURE_WEIGHT
    stereo: StereoConfig = field(default_factory=StereoConfig)
    patches: PatchConfig = field(default_factory=PatchConfig)
    track: TrackConfig = field(default_factory=TrackConfig)
    fit: GlobalFitConfig = field(default_factory=GlobalFitConfig)
    refine: RefineConfig = field(default_factory=RefineConfig)
    confidence: ConfidenceConfig = field(default_factory=ConfidenceConfig)
    recovery: bool = True
    global_fit: bool = True
    independent: bool = False
    mesh_voxel_m: float = 0.015
    meshes: bool = False
    images: Path | None = None
    max_frames: int | None = None
    recording: bool = True
    replace_stale: bool = False
    progress: bool = True

    #: Fields that do not change the joints and the model (left out of the run identity).
    RUNTIME = ("meshes", "max_frames", "recording", "replace_stale", "progress", "mesh_voxel_m", "images")

    def __post_init__(self):
        if self.source not in SOURCES:
            raise InputError("SoftBodyRunConfig.source (--source)", f"one of {SOURCES}", repr(self.source))
        if self.init not in INITS:
            raise InputError("SoftBodyRunConfig.init (--init)", f"one of {INITS}", repr(self.init))
        if int(self.init_frame) < 0:
            raise InputError("SoftBodyRunConfig.init_frame (--init-frame)", "a frame >= 0", repr(self.init_frame))
        if not (np.isfinite(self.init_posture_weight) and self.init_posture_weight >= 0):
            raise InputError("SoftBodyRunConfig.init_posture_weight", "a finite weight >= 0 (metres per radian)",
                             repr(self.init_posture_weight))
        if not 0.003 <= self.mesh_voxel_m <= 0.1:
            raise InputError("SoftBodyRunConfig.mesh_voxel_m", "a grid step from 0.003 to 0.1 m",
                             repr(self.mesh_voxel_m))
        if self.max_frames is not None and int(self.max_frames) < 1:
            raise InputError("SoftBodyRunConfig.max_frames (--frames)", "a number of frames >= 1",
                             repr(self.max_frames))

    def with_posture_weight(self, weight: float) -> "SoftBodyRunConfig":
        """The same config with one posture prior (the trunk's bend and twist against the pelvis towards 0,
        metres per radian) in the initial fit, tracking and the global fit (``--posture-weight``; 0 for
        motions that really twist the trunk against the pelvis: golf, throwing)."""
        return replace(self, init_posture_weight=weight, track=replace(self.track, posture_weight=weight),
                       fit=replace(self.fit, posture_weight=weight))


def build_clouds(source, n: int, patches: PatchConfig, observer=None, progress: bool = False):
    """Raw clouds reduced to patch centres for frames ``0..n-1``.

    Returns
    -------
    centres : list of ndarray of shape (P_t, 3)
        Patch centres per frame, metres, world (empty arrays allowed).
    raw : list of ndarray of shape (<= 4000, 3)
        An even subsample of each raw cloud (for pictures).
    stats : dict
        ``raw_points`` and ``patches`` per frame (lists of int), ``seconds`` per frame (list).
    """
    from tqdm import tqdm

    from toolkit.pointcloud.patches import surface_patches

    centres, raws, stats = [], [], {"raw_points": [], "patches": [], "seconds": []}
    for t in tqdm(range(n), desc="clouds", unit="frame", disable=not progress):
        t0 = time.perf_counter()
        raw = source.cloud(t)
        p = surface_patches(raw, patches)
        centres.append(p.centres)
        raws.append(raw[::max(1, len(raw) // 4000)])
        stats["raw_points"].append(len(raw))
        stats["patches"].append(len(p))
        stats["seconds"].append(time.perf_counter() - t0)
        if observer is not None:
            observer.report("points3d", frame=t, points=raw, name="softbody/cloud", radii=0.003,
                            colors=np.array([150, 150, 150], np.uint8))
            observer.report("points3d", frame=t, points=p.centres, name="softbody/patches", radii=0.008,
                            colors=np.array([60, 160, 255], np.uint8))
    return centres, raws, stats


def tracker_joints(source, n: int, independent: bool = False) -> np.ndarray:
    """The depth tracker's skeleton as 14 joints, (n, 14, 3) metres in the run's world (NaN where lost)."""
    from toolkit.depth import DepthTracker, track_sequence
    from toolkit.depth.tracker_state import TrackerConfig
    from toolkit.pipeline.soft_body_sources import joints14_from_control13

    inp = source.input
    tracker = DepthTracker(inp.camera, inp.pose_known, TrackerConfig(), background=inp.background, rng=0)
    res = track_sequence(tracker, (inp.read(i) for i in range(n)), independent=independent)
    out = np.full((n, 14, 3), np.nan)
    for t in range(n):
        j13 = np.asarray(res.joints[t], float)
        if np.isfinite(j13).all():
            out[t] = joints14_from_control13(j13 if res.coordinates == "world" else source.to_world(j13))
    return out


def _tracker_joints(source, n: int, frame: int) -> np.ndarray:
    """14 joints of the depth tracker at ``frame`` (or the first later frame where it has all of them)."""
    j = tracker_joints(source, n)
    for t in range(frame, n):
        if np.isfinite(j[t]).all():
            return j[t]
    inp = source.input
    raise InputError(f"{inp.frames[0].parent}", f"a frame from {frame} on where the depth tracker finds the user",
                     "none")


def _detector_start(config: SoftBodyRunConfig, source, n: int, cloud=None):
    """The model on the joints the built-in detector finds in the init frame, triangulated across the stereo
    heads (:func:`toolkit.pipeline.soft_body_sources.detect_joints`)."""
    from toolkit.pipeline.soft_body_sources import detect_joints, stereo_detector
    from toolkit.skeleton import SKELETON_14
    from toolkit.softbody import model_from_joints
    from toolkit.softbody.reinit import fill_hanging_limbs

    f0 = min(config.init_frame, n - 1)
    if source.kind != "stereo" or len(source.heads) < 2:
        raise InputError("--init-joints / --clicks", "initial joints for this dataset (a joints .npz, e.g. stage "
                         "1's, or 2D joints clicked in two images); the detector's start needs two stereo heads",
                         f"{source.kind} input with {len(getattr(source, 'heads', ()))} heads")
    found = detect_joints(source, stereo_detector(), f0, cloud)
    joints = fill_hanging_limbs(found.joints)   # an arm or leg hidden behind the body: hanging, fitted later
    if not np.isfinite(joints).all():
        missing = [name for name, j in zip(SKELETON_14.joint_names, joints) if not np.isfinite(j).all()]
        raise InputError("--init-joints / --clicks", f"a person the detector finds in frame {f0} of two heads' "
                         "reference cameras with all 14 joints (else give initial joints or clicks)",
                         f"joints missing: {', '.join(missing)}")
    return (*model_from_joints(joints, posture_weight=config.init_posture_weight), joints)


def initial_model(config: SoftBodyRunConfig, source, n: int, cloud=None, silhouettes=None, observer=None):
    """The model and parameters the tracking starts from, and the joints they came from (14, 3).

    ``cloud`` (N, 3) metres and ``silhouettes`` (list of SilhouetteView): the init frame's, for
    refining a clicked start (``config.refine``, reported to ``observer``)."""
    from toolkit.pipeline.soft_body_sources import read_clicks, read_init_joints
    from toolkit.softbody import init_from_2d, model_from_joints

    init = config.init
    if init == "auto":
        init = ("joints" if config.init_joints is not None else "clicks" if config.clicks is not None
                else "depth_tracker" if source.kind == "depth" else "detector")
    if init == "detector":
        return _detector_start(config, source, n, cloud)
    if init == "depth_tracker":
        if source.kind != "depth":
            raise InputError("init (--init)", "'depth_tracker' only for depth input", source.kind)
        joints = _tracker_joints(source, n, min(config.init_frame, n - 1))
        return (*model_from_joints(joints, posture_weight=config.init_posture_weight), joints)
    if init == "joints":
        if config.init_joints is None:
            raise InputError("init_joints (--init-joints)", "a joints .npz for init = 'joints'", "none")
        joints = read_init_joints(config.init_joints, config.init_frame)
        return (*model_from_joints(joints, posture_weight=config.init_posture_weight), joints)
    if config.clicks is None:
        raise InputError("clicks (--clicks)", "a clicks .npz for init = 'clicks'", "none")
    a, b, cam_a, cam_b, _ = read_clicks(config.clicks, source.data.rig)
    model, params = init_from_2d(a, b, cam_a, cam_b, posture_weight=config.init_posture_weight)
    if config.refine.enabled and cloud is not None:
        from toolkit.softbody.init import refine_initial_model

        model, params = refine_initial_model(model, params, cloud, clicks=[(cam_a, a), (cam_b, b)],
                                             silhouettes=silhouettes, config=config.refine, observer=observer,
                                             frame=min(config.init_frame, n - 1))
    return model, params, model.joints(params)


def body_model_json(model, params) -> dict:
    """``body_model.json``: lengths, bone lengths, widths and the metaballs (in the given pose)."""
    from toolkit.skeleton import SKELETON_14
    from toolkit.softbody import LENGTH_NAMES, WIDTH_GROUPS

    st = model.state(params)
    names = SKELETON_14.joint_names
    bones = {f"{names[a]}-{names[b]}": float(v) for (a, b), v in zip(SKELETON_14.bones, model.bone_lengths(params))}
    groups = np.asarray(model.prim_group)
    return {"units": "metres", "stature_m": float(model.proportions.height), "girth": float(model.girth),
            "lengths": dict(zip(LENGTH_NAMES, map(float, params.lengths))),
            "bone_lengths": bones, "widths": dict(zip(WIDTH_GROUPS, map(float, params.widths))),
            "metaballs": [{"centre": np.round(c, 5).tolist(), "radii": np.round(r, 5).tolist(),
                           "group": WIDTH_GROUPS[g], "weight": float(params.widths[g])}
                          for c, r, g in zip(st.centres, st.radii, groups)],
            "metaball_note": "centres and radii in the first frame's pose (world); weight: the width "
                             "multiplier of the metaball's group"}


def _scores(joints: np.ndarray, truth: np.ndarray) -> dict:
    """MPJPE (mm) and the mean absolute bone-length error (mm) against ground-truth joints (T, 14, 3)."""
    from toolkit.skeleton import SKELETON_14

    ok = np.isfinite(truth).all(-1) & np.isfinite(joints).all(-1)
    err = np.linalg.norm(joints - truth, axis=-1)[ok]
    lt = np.nanmean(SKELETON_14.bone_lengths(truth), axis=0)
    lf = np.nanmean(SKELETON_14.bone_lengths(joints), axis=0)
    return {"mpjpe_mm": 1000 * float(np.mean(err)) if err.size else float("nan"),
            "bone_length_error_mm": 1000 * float(np.mean(np.abs(lf - lt)))}


def _truth(dataset, n: int):
    """Ground-truth joints (n, 14, 3) of a synthetic dataset, or None."""
    p = Path(dataset) / "groundtruth" / "joints3d.npz"
    if not p.is_file():
        return None
    with np.load(p) as z:
        j = np.asarray(z["joints"], float)
    return j[:n] if j.ndim == 3 and j.shape[1:] == (14, 3) and len(j) >= n else None


@dataclass
class Fitted:
    """What the fit gives per frame (one model per frame: the same one for a sequence).

    Attributes
    ----------
    models : list of SoftBodyModel
    params, params_tracking : ndarray of shape (T, 47)
        Final (after the global fit when there is one) and tracked parameter vectors.
    joints, joints_tracking : ndarray of shape (T, 14, 3)
    states : list of str
        The tracker's state per frame.
    global_fit : bool
        Whether ``params`` come from the global fit.
    trusted, recovered : ndarray of shape (T,) bool, optional
        Frames reported as tracked (confidence not ``lost``, state ``ok``); frames whose pose comes from a
        re-initialisation.
    confidence : ndarray of shape (T,), optional
        :func:`toolkit.softbody.confidence.frame_confidence` per frame (NaN where not fitted).
    """

    models: list
    params: np.ndarray
    params_tracking: np.ndarray
    joints: np.ndarray
    joints_tracking: np.ndarray
    states: list
    global_fit: bool
    trusted: np.ndarray | None = None
    recovered: np.ndarray | None = None
    confidence: np.ndarray | None = None


def _write(out: Path, fitted: Fitted, n: int, dataset) -> dict:
    """``joints.npz``, ``body_model.json`` and ``metrics.json`` (returned)."""
    from toolkit.io import atomic_save_npz, atomic_write_text
    from toolkit.skeleton import SKELETON_14
    from toolkit.softbody import SoftBodyParams

    f = fitted
    n_t = len(f.states)
    trusted = np.ones(n_t, bool) if f.trusted is None else np.asarray(f.trusted, bool)
    recovered = np.zeros(n_t, bool) if f.recovered is None else np.asarray(f.recovered, bool)
    # a frame the confidence calls lost is no measurement of the person: its joints are not written as tracked
    hide = lambda j: np.where(trusted[:, None, None], j, np.nan)  # noqa: E731
    atomic_save_npz(out / "joints.npz", joints=hide(f.joints), names=np.array(SKELETON_14.joint_names),
                    joints_tracking=hide(f.joints_tracking), state=np.array(f.states, dtype=str),
                    params=f.params, params_tracking=f.params_tracking, trusted=trusted, recovered=recovered,
                    confidence=np.full(n_t, np.nan) if f.confidence is None else np.asarray(f.confidence, float))
    first = next((t for t, s in enumerate(f.states) if s == "ok"), 0)
    info = body_model_json(f.models[first], SoftBodyParams(f.params[first]))
    atomic_write_text(out / "body_model.json", json.dumps(info, indent=1) + "\n")
    metrics = {"frames": n, "states": {s: int(np.sum(np.array(f.states) == s)) for s in sorted(set(f.states))},
               "trusted_frames": np.flatnonzero(trusted).tolist(), "lost_frames": np.flatnonzero(~trusted).tolist(),
               "recovered_frames": np.flatnonzero(recovered).tolist()}
    truth = _truth(dataset, n)
    if truth is not None:   # scored on the trusted frames (the others are not reported as tracked)
        metrics["tracking"] = _scores(hide(f.joints_tracking), truth)
        if f.global_fit:
            metrics["global_fit"] = _scores(hide(f.joints), truth)
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=2) + "\n")
    return metrics


def _surfaces(out: Path, fitted: Fitted, clouds, raws, config: SoftBodyRunConfig, forward, observer) -> None:
    """Per frame: the model surface, joints and residual-coloured patches to the recording;
    ``OUT/meshes/NNNNNN.ply`` (``config.meshes``); pictures (``config.images``)."""
    if observer is None and not config.meshes and config.images is None:
        return
    from toolkit.io import atomic_write_png, frame_filename
    from toolkit.pipeline.soft_body_images import draw_fit
    from toolkit.softbody import SoftBodyParams, distance
    from toolkit.softbody.mesh import surface_mesh

    for t, (model, vector) in enumerate(zip(fitted.models, fitted.params)):
        params = SoftBodyParams(vector)
        v, f = surface_mesh(model, params, voxel=config.mesh_voxel_m)
        if observer is not None:
            observer.report("mesh", frame=t, vertices=v, triangles=f, name="softbody/surface",
                            vertex_colors=np.tile(np.array([230, 170, 120], np.uint8), (len(v), 1)))
            observer.report("joints3d", frame=t, joints=model.joints(params), name="softbody/joints")
            if len(clouds[t]):
                _residuals(t, clouds[t], np.abs(distance(model, params, clouds[t])), observer)
        if config.meshes:
            _write_ply(out / "meshes" / frame_filename(t, ".ply"), v, f)
        if config.images is not None:
            raw = raws[t]
            d = np.abs(distance(model, params, raw)) if len(raw) else np.zeros(0)
            img = draw_fit(raw, d, v, f, forward, caption=f"frame {t} {fitted.states[t]}")
            atomic_write_png(Path(config.images) / f"softbody_{t:03d}.png", img)


def _write_ply(path: Path, vertices: np.ndarray, triangles: np.ndarray) -> None:
    """A triangle mesh as binary PLY (Open3D's writer, via a temporary name renamed into place)."""
    import open3d as o3d

    from toolkit.io.atomic import atomic_path

    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(triangles))
    with atomic_path(path) as tmp:
        if not o3d.io.write_triangle_mesh(str(tmp), mesh):
            raise InputError(str(path), "room to write the mesh (an earlier one is kept as it was)",
                             "Open3D's PLY writer failed (a full or read-only disk?)")


def _residuals(t: int, pts: np.ndarray, d: np.ndarray, observer) -> None:
    """The patch centres coloured by their distance ``d`` to the fitted surface (blue 0, red >= 3 cm)."""
    c = np.clip(d / 0.03, 0, 1)[:, None]
    colors = np.round(255 * ((1 - c) * [0.1, 0.3, 1.0] + c * [1.0, 0.15, 0.1])).astype(np.uint8)
    observer.report("points3d", frame=t, points=pts, name="softbody/residuals", colors=colors, radii=0.01)
    observer.report("scalar", frame=t, name="softbody/median_residual_mm", value=1000 * float(np.median(d)))


def _with_viewpoints(cfg, viewpoints):
    """A tracking or global-fit config whose ``viewpoints`` are the source's cameras unless it names some
    (the coverage blocks then expect data only on the model's side facing a camera)."""
    from dataclasses import replace

    if viewpoints is not None and cfg.viewpoints is None:
        cfg = replace(cfg, viewpoints=tuple(tuple(map(float, v)) for v in viewpoints))
    return cfg


def fit_clouds(model, params0, clouds, config: SoftBodyRunConfig, viewpoints=None, observer=None,
               silhouettes=None, reinit=None) -> Fitted:
    """Track, then (with ``config.global_fit``) fit globally (:mod:`toolkit.softbody`).

    ``viewpoints`` (V, 3): the cameras' centres, so that the tracker expects data only
    on the model's side facing them; ``silhouettes``: per frame, the cameras' silhouettes
    (:func:`silhouettes_of`), or None; ``reinit``: joints to search a lost person from
    (:func:`reinit_joints`), or None.
    """
    from toolkit.softbody import global_fit, track_sequence
    from toolkit.softbody.silhouette import report_silhouettes

    from toolkit.softbody.init import fit_pose_to_joints

    def starts(t, last):   # the last trusted pose fitted to the frame's re-initialisation joints
        return [fit_pose_to_joints(model, last, j) for j in reinit(t, model.joints(last))]

    track = track_sequence(model, params0, clouds, config=_with_viewpoints(config.track, viewpoints),
                           observer=observer, silhouettes=silhouettes, confidence=config.confidence,
                           reinit=starts if config.recovery and reinit is not None else None,
                           recover=config.recovery)
    final = track
    if config.global_fit:
        # the global fit sees the subject's points only (the tracker left other bodies' out)
        final = global_fit(model, track, track.subject_clouds(clouds), config=_with_viewpoints(config.fit, viewpoints),
                           observer=observer, silhouettes=silhouettes)
    for t, views in enumerate(silhouettes if observer is not None and silhouettes is not None else []):
        report_silhouettes(observer, model, _params(final.params[t]), views, t)
    # a crowded frame is not reported as tracked either: the tracker could not tell the person's points from
    # another body's there (alone in the scene: its own swinging limb), and the global fit leaves its points out
    trusted = None if track.trusted is None else np.asarray(track.trusted) & (np.array(track.states) != "crowded")
    return Fitted([model] * len(clouds), np.asarray(final.params), np.asarray(track.params), final.joints,
                  track.joints, list(track.states), config.global_fit, trusted, track.recovered,
                  track.confidence)


def fit_independent(source, clouds, config: SoftBodyRunConfig, observer=None) -> Fitted:
    """Unrelated depth frames: each initialised from the depth tracker's skeleton of that frame, fitted alone."""
    from toolkit.softbody import model_from_joints, track_sequence

    n = len(clouds)
    joints = tracker_joints(source, n, independent=True)
    tcfg = _with_viewpoints(config.track, source.viewpoints)
    models, params, states = [], [], []
    for t in range(n):
        if not np.isfinite(joints[t]).all():
            models.append(models[-1] if models else None)
            params.append(params[-1] if params else None)
            states.append("lost")
            continue
        model, p0 = model_from_joints(joints[t], posture_weight=config.init_posture_weight)
        tr = track_sequence(model, p0, [clouds[t]], config=tcfg)
        models.append(model)
        params.append(np.asarray(tr.params[0]))
        states.append(tr.states[0])
        if observer is not None:
            observer.report("joints3d", frame=t, joints=joints[t], name="softbody/init_joints")
    if all(m is None for m in models):
        raise InputError(f"{source.input.frames[0].parent}", "frames where the depth tracker finds the user", "none")
    k = next(t for t, m in enumerate(models) if m is not None)
    models[:k], params[:k] = [models[k]] * k, [params[k]] * k  # lost frames before the first found one
    P = np.stack(params)
    J = np.stack([m.joints(_params(v)) for m, v in zip(models, P)])
    return Fitted(models, P, P, J, J, states, False)


def reinit_joints(source, n: int, clouds, log=None):
    """``reinit(t, last_joints) -> [joints (14, 3)]`` for :func:`toolkit.softbody.track_sequence`: the depth
    tracker's skeleton of frame ``t`` (depth input), or the built-in 2D detector's keypoints on each stereo
    head's reference camera triangulated across the heads (:func:`toolkit.softbody.reinit.triangulate_views`,
    joints it cannot triangulate taken from ``last_joints`` moved with the others); None when neither can run
    (no detector installed: the run says so through ``log``, and the search over the cloud still runs)."""
    if source.kind != "depth" and len(source.heads) < 2:
        return None   # one head: nothing to triangulate across
    if source.kind == "depth":
        cache = {}

        def depth(t, last):
            if "j" not in cache:
                cache["j"] = tracker_joints(source, n)
            j = cache["j"][t]
            return [j] if np.isfinite(j).all() else []
        return depth
    detector = {}

    def stereo(t, last):
        from toolkit.pipeline.soft_body_sources import detect_joints, stereo_detector

        if "d" not in detector:
            try:
                detector["d"] = stereo_detector()
            except InputError as e:
                detector["d"] = None
                if log is not None:
                    log(f"no detector for re-initialising lost frames ({e}); searching the cloud only")
        if detector["d"] is None:
            return []
        v = detect_joints(source, detector["d"], t, clouds[t], previous=last)
        ok = np.isfinite(v.joints).all(axis=1)
        if ok.sum() < MIN_DETECTED_JOINTS:
            return []
        j = v.joints.copy()
        j[~ok] = last[~ok] + np.mean(v.joints[ok] - last[ok], axis=0)   # the others moved with the person
        return [j]
    return stereo


def wants_silhouettes(config: SoftBodyRunConfig) -> bool:
    """Whether the fit uses the cameras' silhouettes (a silhouette weight above 0 where it runs)."""
    return not config.independent and (config.track.silhouette_weight > 0
                                       or (config.global_fit and config.fit.silhouette_weight > 0))


def silhouettes_of(source, n: int) -> list:
    """Per frame ``0..n-1``, the source's cameras' silhouettes (:func:`toolkit.softbody.silhouette.silhouette_views`)
    from the masks its foreground step found (kept by ``source.cloud`` when the source keeps its masks), each
    outline moved onto its image's edge where the source measures it (``source.silhouette_edge_offsets``), the pixels
    it cannot tell from the background unknown where it knows them (``source.silhouette_unknown``)."""
    from toolkit.softbody.silhouette import silhouette_views

    out = []
    for t in range(n):
        pairs = source.silhouettes(t)
        offsets = source.silhouette_edge_offsets(t) if hasattr(source, "silhouette_edge_offsets") else None
        unknowns = source.silhouette_unknown(t) if hasattr(source, "silhouette_unknown") else None
        out.append(silhouette_views([c for c, _ in pairs], [m for _, m in pairs], edge_offsets=offsets,
                                    unknowns=unknowns))
    return out


def _params(vector):
    from toolkit.softbody import SoftBodyParams

    return SoftBodyParams(vector)


def run(config: SoftBodyRunConfig, *, dataset, out, observer=None, log=print) -> RunResult:
    """Fit the soft body to one sequence into ``out``.

    Parameters
    ----------
    config : SoftBodyRunConfig
    dataset : path
        A dataset folder with ``depth_camera/`` or trinocular cameras, or a folder of depth frames.
    out : path
        Output folder (``recipes/fit_soft_body.py`` lists what it holds).
    observer : Observer, optional
        Receives every intermediate; default: ``OUT/recording.rrd`` (``config.recording``).
    log : callable or None

    Returns
    -------
    RunResult
        ``metrics``: ``metrics.json``'s content plus ``seconds_per_frame`` (clouds, fit) and
        ``patches_median``; ``extra``: ``source``, ``joints``, ``body_model``, ``meshes``, ``images``.

    Raises
    ------
    InputError
        Bad input or options, or an output folder of another run.
    """
    from toolkit.io.runs import run_recording
    from toolkit.pipeline.soft_body_sources import open_source

    out = Path(out)
    source = open_source(dataset, config.source, stereo=config.stereo, foreground=config.foreground,
                         keep_masks=wants_silhouettes(config))
    n = len(source) if config.max_frames is None else min(len(source), int(config.max_frames))
    if n < 1:
        raise InputError(str(dataset), "at least one frame", "none")
    if not config.independent and config.init_frame >= n:
        raise InputError("init_frame (--init-frame)", f"a frame in [0, {n}) (the frames used)", str(config.init_frame))
    if config.independent and source.kind != "depth":
        raise InputError("independent (--independent)", "depth input (unrelated depth frames)", source.kind)
    folder = open_run(out, "fit_soft_body", dataset, config, n, exclude=SoftBodyRunConfig.RUNTIME,
                      extra={"source": source.kind}, replace_stale=config.replace_stale, recording=False, log=log)
    earlier = folder.resumed and (out / "metrics.json").is_file()   # written last: the results are complete
    own = observer is None and config.recording
    obs = _recording(out, run_recording(out, False)[1]) if own else observer
    t0 = time.perf_counter()
    metrics, timing = None, {}
    with whole_run(out, obs, own=own, earlier=earlier) as state:
        clouds, raws, stats = build_clouds(source, n, config.patches, obs, config.progress)
        silhouettes = silhouettes_of(source, n) if source.keep_masks else None
        state.checkpoint()
        timing["clouds"] = (time.perf_counter() - t0) / n
        fitted = _fit(config, source, n, clouds, silhouettes, obs, own, log)
        timing["fit"] = (time.perf_counter() - t0) / n - timing["clouds"]
        state.checkpoint()
        with state.writing():
            metrics = _write(out, fitted, n, dataset)
        _surfaces(out, fitted, clouds, raws, config, source.forward, obs)
    extra = {"source": source.kind, "joints": out / "joints.npz", "body_model": out / "body_model.json",
             "meshes": out / "meshes" if config.meshes else None, "images": config.images, "earlier": earlier}
    if metrics is None:   # stopped before its results were written: those of an earlier complete run stay
        return RunResult(out, n, 0, 0, 0, state.stopped, time.perf_counter() - t0, {}, state.recording, extra)
    metrics["seconds_per_frame"] = timing
    metrics["patches_median"] = float(np.median(stats["patches"]))
    return RunResult(out, n, n, n, 0, state.stopped, time.perf_counter() - t0, metrics, state.recording, extra)


def _fit(config: SoftBodyRunConfig, source, n: int, clouds, silhouettes, obs, own: bool, log) -> Fitted:
    """The initial model, tracking and the global fit (or the independent frames' fits) of a run."""
    if config.independent:
        return fit_independent(source, clouds, config, obs)
    f0 = min(config.init_frame, n - 1)
    model, params0, joints0 = initial_model(config, source, n, clouds[f0],
                                            None if silhouettes is None else silhouettes[f0], obs)
    if own:
        _send_layout(obs, joints0, source.viewpoints)
    if obs is not None:
        obs.report("joints3d", frame=f0, joints=joints0, name="softbody/init_joints")
    return fit_clouds(model, params0, clouds, config, source.viewpoints, observer=obs, silhouettes=silhouettes,
                      reinit=reinit_joints(source, n, clouds, log) if config.recovery else None)


def _recording(out: Path, recording_id: str):
    from toolkit.viz import RerunObserver

    # in parts: a run killed outright leaves its finished parts complete; a dropped one leaves the file as it was
    return RerunObserver(application_id="fit_soft_body", path=out / "recording.rrd", recording_id=recording_id,
                         parts=True)


def _send_layout(rec, joints: np.ndarray, viewpoints: np.ndarray) -> None:
    """The soft-body layout (:func:`toolkit.viz.blueprint.softbody_blueprint`), its 3D view framed on the
    subject's joints (J, 3) metres, seen from the cameras' side (viewpoints (V, 3) metres)."""
    from toolkit.softbody.model import LENGTH_NAMES
    from toolkit.viz.blueprint import softbody_blueprint, subject_eye

    ok = np.isfinite(joints).all(axis=1)
    eye = subject_eye(joints[ok].mean(axis=0), viewpoints, distance_m=3.5, height_m=0.6) if ok.any() else None
    rec.send_blueprint(softbody_blueprint(LENGTH_NAMES, eye=eye))


def summary_lines(result: RunResult) -> list:
    """What a soft-body run says when it ends (the recipe prints these)."""
    m, x = result.metrics, result.extra
    if not m:   # stopped before the results were written
        kept = "the earlier complete results (and recording) are kept" if x.get("earlier") else "no results written"
        return [f"{result.stopped}: stopped after {result.seconds:.1f} s, before the fit of the {result.frames} "
                f"frames ({x['source']}) was written; {kept}; run the same command again to fit them"]
    lines = [] if not result.stopped else [f"{result.stopped}: stopped while drawing the fitted surfaces; "
                                           "the results are written (meshes and images: the frames drawn so far)"]
    lines += [f"fitted {result.frames} frames ({x['source']}) in {result.seconds:.1f} s: "
             + ", ".join(f"{v} {k}" for k, v in m["states"].items())
             + f"; {m['patches_median']:.0f} patches per frame (median)",
             f"  trusted:     {frame_ranges(m['trusted_frames'])} ({len(m['trusted_frames'])} of {result.frames}); "
             f"lost: {frame_ranges(m['lost_frames']) or 'none'}; found again: "
             f"{frame_ranges(m['recovered_frames']) or 'none'}",
             f"  joints:      {x['joints']}", f"  body model:  {x['body_model']}"]
    if x["meshes"] is not None:
        lines.append(f"  meshes:      {x['meshes']}/")
    if x["images"] is not None:
        lines.append(f"  images:      {x['images']}/")
    if result.recording is not None:
        lines.append(f"  recording:   {result.recording}  (open with: rerun {result.recording})")
    for stage in ("tracking", "global_fit"):
        if stage in m:
            lines.append(f"  {stage:<12} MPJPE {m[stage]['mpjpe_mm']:.1f} mm, bone lengths "
                         f"{m[stage]['bone_length_error_mm']:.1f} mm off (mean)")
    return lines
