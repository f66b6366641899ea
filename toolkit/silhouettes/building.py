"""Building a silhouette database by rendering the synthetic body (source 000 §2.1).

For each pose (frames of the procedural motions of :mod:`toolkit.motion`,
several seeded sequences per motion, and of any BVH file), the body of
:mod:`toolkit.body.model` is posed once and seen from many virtual
cameras around it: azimuths stratified over the full circle relative to the
subject's facing, elevations in 0-35 degrees, distances from studio to
broadcast range (log-uniform in 4-40 m) with the focal length chosen so the
subject is about :data:`SUBJECT_HEIGHT_PX` pixels tall, so the perspective of
near and far cameras is represented.  The silhouettes of all views of a pose
are ray cast in one Open3D call (pixel centres, exact), each view's image
window cropped to the projected skeleton plus a margin.  Every silhouette
gives an entry: its 32 x 40 descriptor and the projected joints normalised to
its box; optionally its left/right mirror image (free: the mirrored
silhouette with mirrored, left/right-swapped joints is the view of the
mirrored pose) and an optical-flow descriptor (exact motion of the surface
point seen in each pixel since the previous frame).

:func:`default_database` builds the default database once and keeps it in a
cache folder (``$TOOLKIT_CACHE`` or ``~/.cache/billboard-toolkit``).
"""

from __future__ import annotations

import hashlib
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import open3d as o3d

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion import CMU_UNIT_M, MOTIONS, SCENE_MOTIONS, generate_motion, motion_from_bvh, read_bvh
from toolkit.observe import as_observer
from toolkit.silhouettes.database import FLOW_SIZE, SilhouetteDatabase
from toolkit.silhouettes.descriptor import (
    SILHOUETTE_GRID,
    bounding_box,
    flow_descriptor,
    normalise_joints,
    silhouette_grid,
)
from toolkit.skeleton import SKELETON_14
from toolkit.skeleton.mappings import CMU_BVH_TO_14, SKELETON14_BVH_TO_14
from toolkit.body.model import BodyModel

#: Subject stature in pixels in the virtual views (the 40-cell grid gets about 3 pixels per cell).
SUBJECT_HEIGHT_PX = 120.0
#: Extra image margin around the projected joints, metres (body volume beyond the joint centres:
#: head top ~0.13 m above the head joint, feet ~0.2 m ahead of the ankles, hands ~0.16 m past the wrists).
VOLUME_MARGIN_M = 0.3
#: Viewing elevations of the database cameras, degrees above the horizontal.
ELEVATION_RANGE_DEG = (0.0, 35.0)
#: Camera distances, metres (log-uniform): studio to broadcast.
DISTANCE_RANGE_M = (4.0, 40.0)
#: Statures of the rendered people, metres.
HEIGHT_RANGE_M = (1.55, 1.90)
#: Coarse tessellation is enough for silhouettes of ~120 pixels.
MESH_DETAIL = 0.3
#: Units of BVH files written by :func:`toolkit.motion.write_bvh` (centimetres).
SKELETON14_BVH_UNIT_M = 0.01
#: Environment variable naming the cache folder.
CACHE_ENV = "TOOLKIT_CACHE"
#: Default cache folder.
DEFAULT_CACHE_DIR = Path("~/.cache/billboard-toolkit")

_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}
_FLIP = SKELETON_14.flip_permutation


@dataclass(frozen=True)
class BuildConfig:
    """What goes into a rendered silhouette database.

    Parameters
    ----------
    motions : tuple of str
        Procedural motions (names from :data:`toolkit.motion.MOTIONS`; default
        :data:`toolkit.motion.SCENE_MOTIONS`, without the lab's ``rom`` trial).
    sequences_per_motion : int
        Seeded sequences (person, build, motion parameters) per motion.
    frames_per_sequence : int
        Length of each sequence, frames at ``fps``.
    fps : float
    frame_stride : int
        One pose every ``frame_stride`` frames.
    views_per_pose : int
        Virtual cameras per pose (azimuths stratified over 360 degrees).
    elevation_range_deg, distance_range_m, height_range_m : tuple of float
    subject_height_px : float
    mirror : bool
        Also add the mirror image of every view.
    with_flow : bool
        Store optical-flow descriptors (costs a second mesh per pose).
    mesh_detail : float
        Body tessellation (:class:`toolkit.body.model.BodyModel`).
    bvh_frame_stride : int
        One pose every this many frames of each BVH file (at ``fps``).
    """

    motions: tuple[str, ...] = SCENE_MOTIONS
    sequences_per_motion: int = 4
    frames_per_sequence: int = 100
    fps: float = 25.0
    frame_stride: int = 5
    views_per_pose: int = 16
    elevation_range_deg: tuple[float, float] = ELEVATION_RANGE_DEG
    distance_range_m: tuple[float, float] = DISTANCE_RANGE_M
    height_range_m: tuple[float, float] = HEIGHT_RANGE_M
    subject_height_px: float = SUBJECT_HEIGHT_PX
    mirror: bool = True
    with_flow: bool = False
    mesh_detail: float = MESH_DETAIL
    bvh_frame_stride: int = 4

    def __post_init__(self):
        for m in self.motions:
            if m not in MOTIONS:
                raise InputError("BuildConfig.motions", f"names from {list(MOTIONS)}", repr(m))
        for name in ("sequences_per_motion", "frames_per_sequence", "frame_stride", "views_per_pose",
                     "bvh_frame_stride"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise InputError(f"BuildConfig.{name}", "a positive integer", repr(v))
        lo, hi = self.elevation_range_deg
        if not -89 <= lo <= hi <= 89:
            raise InputError("BuildConfig.elevation_range_deg", "a range within (-89, 89) degrees",
                             repr(self.elevation_range_deg))
        lo, hi = self.distance_range_m
        if not 0 < lo <= hi:
            raise InputError("BuildConfig.distance_range_m", "0 < near <= far metres", repr(self.distance_range_m))
        if not self.subject_height_px >= 20:
            raise InputError("BuildConfig.subject_height_px", "at least 20 pixels", repr(self.subject_height_px))
        object.__setattr__(self, "motions", tuple(self.motions))

    @property
    def n_entries(self) -> int:
        """Entries from the procedural motions (before dropping cut silhouettes)."""
        poses = len(self.motions) * self.sequences_per_motion * len(
            range(0, self.frames_per_sequence, self.frame_stride))
        return poses * self.views_per_pose * (2 if self.mirror else 1)

    def key(self) -> str:
        """A short hash identifying the configuration (cache file names)."""
        return hashlib.sha1(repr(sorted(asdict(self).items())).encode()).hexdigest()[:12]


@dataclass(frozen=True)
class ViewSpec:
    """One virtual camera around a pose.

    Attributes
    ----------
    R : ndarray of shape (3, 3)
        World to camera rotation (OpenCV axes).
    center : ndarray of shape (3,)
        Camera centre, metres.
    K : ndarray of shape (3, 3)
        Intrinsics of the cropped window.
    size : tuple of int
        Window (width, height), pixels.
    azimuth_deg, elevation_deg, distance_m : float
    """

    R: np.ndarray
    center: np.ndarray
    K: np.ndarray
    size: tuple[int, int]
    azimuth_deg: float
    elevation_deg: float
    distance_m: float

    def project(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) to window pixels (..., 2)."""
        pc = (np.asarray(points, float) - self.center) @ self.R.T
        q = pc @ self.K.T
        return q[..., :2] / q[..., 2:3]


def subject_frame(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal facing and left unit vectors of a (14, 3) pose (from the hips and shoulders)."""
    lateral = (joints[_J["r_hip"]] - joints[_J["l_hip"]]) + (joints[_J["r_shoulder"]] - joints[_J["l_shoulder"]])
    lateral[2] = 0.0
    if np.linalg.norm(lateral) < 1e-6:
        lateral = np.array([1.0, 0.0, 0.0])
    lateral /= np.linalg.norm(lateral)
    up = np.array([0.0, 0.0, 1.0])
    facing = np.cross(up, lateral)
    return facing, np.cross(up, facing)


def view_around(joints: np.ndarray, azimuth_deg: float, elevation_deg: float, distance_m: float,
                subject_height_px: float = SUBJECT_HEIGHT_PX, margin_m: float = VOLUME_MARGIN_M) -> ViewSpec:
    """A virtual camera looking at a pose from a given direction and distance.

    Parameters
    ----------
    joints : ndarray of shape (14, 3)
        World metres, z up.
    azimuth_deg : float
        0 = in front of the subject, 90 = at its left, counter-clockwise from above.
    elevation_deg : float
        Above the horizontal.
    distance_m : float
        From the centre of the joints' bounding box.
    subject_height_px : float
        A 1.75 m tall subject at ``distance_m`` is this many pixels tall.
    margin_m : float
        Window margin around the projected joints, metres at the subject.

    Returns
    -------
    ViewSpec
        The window is the projected joints' box plus the margin.
    """
    J = np.asarray(joints, float)
    target = 0.5 * (J.min(axis=0) + J.max(axis=0))
    facing, left = subject_frame(J)
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    horiz = np.cos(a) * facing + np.sin(a) * left
    direction = np.cos(e) * horiz + np.array([0.0, 0.0, np.sin(e)])
    center = target + distance_m * direction
    z = -direction
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    f = subject_height_px * distance_m / 1.75
    pc = (J - center) @ R.T
    uv = f * pc[:, :2] / pc[:, 2:3]
    m = f * margin_m / distance_m
    lo = np.floor(uv.min(axis=0) - m)
    hi = np.ceil(uv.max(axis=0) + m)
    w, h = (int(v) for v in hi - lo + 1)
    K = np.array([[f, 0.0, -lo[0]], [0.0, f, -lo[1]], [0.0, 0.0, 1.0]])
    return ViewSpec(R, center, K, (w, h), float(azimuth_deg), float(elevation_deg), float(distance_m))


def _rays(view: ViewSpec) -> np.ndarray:
    w, h = view.size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    d_cam = np.stack([(u - view.K[0, 2]) / view.K[0, 0], (v - view.K[1, 2]) / view.K[1, 1], np.ones_like(u)], -1)
    d = d_cam.reshape(-1, 3) @ view.R
    o = np.broadcast_to(view.center, d.shape)
    return np.concatenate([o, d], axis=1)


def render_silhouettes(vertices: np.ndarray, triangles: np.ndarray, views: list[ViewSpec],
                       previous_vertices: np.ndarray | None = None):
    """Ray-cast the silhouettes of one mesh seen by several views in one call.

    Parameters
    ----------
    vertices : ndarray of shape (V, 3)
    triangles : ndarray of shape (F, 3)
    views : list of ViewSpec
    previous_vertices : ndarray of shape (V, 3), optional
        The same mesh one frame earlier: then the per-pixel motion (dx, dy)
        of the surface point seen in each pixel since that frame is returned.

    Returns
    -------
    masks : list of ndarray of shape (h, w), bool
    flows : list of ndarray of shape (h, w, 2) or None
    """
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(vertices, np.float32)),
                        o3d.core.Tensor(np.asarray(triangles, np.uint32)))
    rays = np.concatenate([_rays(v) for v in views]).astype(np.float32)
    ans = scene.cast_rays(o3d.core.Tensor(rays))
    hit = np.isfinite(ans["t_hit"].numpy())
    masks, flows = [], []
    start = 0
    if previous_vertices is not None:
        prim = ans["primitive_ids"].numpy().astype(np.int64)
        bary = ans["primitive_uvs"].numpy().astype(np.float64)
    for v in views:
        w, h = v.size
        sl = slice(start, start + w * h)
        start += w * h
        masks.append(hit[sl].reshape(h, w))
        if previous_vertices is None:
            flows.append(None)
            continue
        sel = np.flatnonzero(hit[sl]) + sl.start
        tri = np.asarray(triangles)[prim[sel]]
        b = bary[sel]
        Pv = np.asarray(previous_vertices, float)
        prev = (Pv[tri[:, 0]] * (1 - b[:, :1] - b[:, 1:2]) + Pv[tri[:, 1]] * b[:, :1] + Pv[tri[:, 2]] * b[:, 1:2])
        uv_prev = v.project(prev)
        pix = np.stack(np.unravel_index(sel - sl.start, (h, w))[::-1], -1).astype(np.float64)
        fl = np.zeros((h, w, 2))
        fl.reshape(-1, 2)[sel - sl.start] = pix - uv_prev
        flows.append(fl)
    return masks, flows


def _mirror_grid(grid: np.ndarray) -> np.ndarray:
    return grid[:, ::-1]


def _mirror_joints(q: np.ndarray) -> np.ndarray:
    m = q[_FLIP].copy()
    m[:, 0] = 1.0 - m[:, 0]
    return m


def _mirror_flow(flow: np.ndarray) -> np.ndarray:
    gw, gh = SILHOUETTE_GRID
    dx = -flow[:gw * gh].reshape(gh, gw)[:, ::-1]
    dy = flow[gw * gh:].reshape(gh, gw)[:, ::-1]
    return np.concatenate([dx.ravel(), dy.ravel()])


@dataclass
class _Accumulator:
    grids: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    motion: list = field(default_factory=list)
    az: list = field(default_factory=list)
    el: list = field(default_factory=list)
    frame: list = field(default_factory=list)
    source: list = field(default_factory=list)
    flows: list = field(default_factory=list)
    dropped: int = 0

    def add(self, grid, joints, motion, az, el, frame, source, flow):
        self.grids.append(grid.reshape(-1))
        self.joints.append(joints)
        self.motion.append(motion)
        self.az.append(az)
        self.el.append(el)
        self.frame.append(frame)
        self.source.append(source)
        self.flows.append(flow)

    def database(self, with_flow: bool) -> SilhouetteDatabase:
        if not self.grids:
            return SilhouetteDatabase.empty()
        flows = None
        if with_flow:
            flows = np.stack([np.full(FLOW_SIZE, np.nan) if f is None else f for f in self.flows])
        az = (np.asarray(self.az) + 180.0) % 360.0 - 180.0
        return SilhouetteDatabase(np.stack(self.grids), np.stack(self.joints), motion=self.motion,
                                  azimuth_deg=az, elevation_deg=self.el, frame=self.frame,
                                  source=self.source, flows=flows)


def _add_pose(acc: _Accumulator, model: BodyModel, joints: np.ndarray, prev_joints: np.ndarray | None,
              config: BuildConfig, rng: np.random.Generator, motion: str, frame: int, source: str) -> None:
    mesh = model.mesh(joints)
    prev_vertices = model.mesh(prev_joints).vertices if (config.with_flow and prev_joints is not None) else None
    n_views = config.views_per_pose
    az = (np.arange(n_views) + rng.random()) * (360.0 / n_views)
    el = rng.uniform(*config.elevation_range_deg, size=n_views)
    lo, hi = np.log(config.distance_range_m)
    dist = np.exp(rng.uniform(lo, hi, size=n_views))
    views = [view_around(joints, a, e, d, config.subject_height_px) for a, e, d in zip(az, el, dist)]
    masks, flows = render_silhouettes(mesh.vertices, mesh.triangles, views, prev_vertices)
    for view, mask, flow in zip(views, masks, flows):
        box = bounding_box(mask)
        h, w = mask.shape
        if box is None or box[0] < 0 or box[1] < 0 or box[2] > w - 1 or box[3] > h - 1:
            acc.dropped += 1  # touches the window border: the margin was too small for this pose
            continue
        grid = silhouette_grid(mask, box)
        q = normalise_joints(view.project(joints), box)
        fd = flow_descriptor(flow, box) if flow is not None else None
        acc.add(grid, q, motion, view.azimuth_deg, view.elevation_deg, frame, source, fd)
        if config.mirror:
            acc.add(_mirror_grid(grid), _mirror_joints(q), motion, -view.azimuth_deg, view.elevation_deg, frame,
                    source + " mirrored", None if fd is None else _mirror_flow(fd))


def _bvh_layout(path: str) -> dict:
    """Mapping and units of a BVH file: the toolkit's own export (14 named joints, cm) or CMU."""
    names = set(read_bvh(path).joint_names)
    if set(SKELETON_14.joint_names) <= names:
        return dict(mapping=SKELETON14_BVH_TO_14, units=SKELETON14_BVH_UNIT_M)
    return dict(mapping=CMU_BVH_TO_14, units=CMU_UNIT_M)


def _run_job(job: tuple, config: BuildConfig) -> tuple[SilhouetteDatabase, int, int]:
    """Render the entries of one sequence: ``job = (kind, name, index, seed)``.

    Returns the entries, the number of poses and the number of dropped views.
    """
    kind, name, s, seed = job
    prng = np.random.default_rng(seed)
    props = BodyProportions.sample(float(prng.uniform(*config.height_range_m)), prng)
    model = BodyModel.sample(props, prng, detail=config.mesh_detail)
    if kind == "motion":
        J = generate_motion(name, props, config.frames_per_sequence, config.fps, prng)
        stride, label = config.frame_stride, name
    else:
        J = motion_from_bvh(name, props, None, config.fps, prng, **_bvh_layout(name))
        stride, label = config.bvh_frame_stride, Path(name).stem
    acc = _Accumulator()
    frames = range(0, len(J), stride)
    for f in frames:
        prev = J[f - 1] if f > 0 else None
        _add_pose(acc, model, J[f], prev, config, prng, label, f, f"{label} seq {s} seed {seed}")
    return acc.database(config.with_flow), len(frames), acc.dropped


def build_database(config: BuildConfig = BuildConfig(), rng: np.random.Generator | int | None = None, *,
                   bvh_files=(), workers: int = 1, observer=None, progress=None) -> SilhouetteDatabase:
    """Render a silhouette database.

    Parameters
    ----------
    config : BuildConfig
    rng : numpy.random.Generator or int or None
        Draws one seed per sequence; each sequence's person, build, motion
        parameters and viewpoints come from its seed, so the result does not
        depend on ``workers``.
    bvh_files : sequence of path
        BVH motions added with a random person each (every
        ``config.bvh_frame_stride``-th frame at ``config.fps``): CMU-style
        files, or files written by :func:`toolkit.motion.write_bvh`.
    workers : int
        Processes rendering sequences in parallel (1: in this process).
    observer : Observer, optional
        Receives ``scalar`` reports ``silhouette_db/entries`` and
        ``silhouette_db/entries_per_s`` and one ``text`` summary.
    progress : callable, optional
        Called as ``progress(done, total)`` (sequences) after each sequence.

    Returns
    -------
    SilhouetteDatabase
        ``source`` says ``"<motion> seq <i> seed <s>"`` (``" mirrored"`` for mirror images).
    """
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise InputError("workers", "a positive integer", repr(workers))
    rng = np.random.default_rng(rng)
    obs = as_observer(observer)
    t0 = time.perf_counter()
    jobs = []
    for motion in config.motions:
        for s in range(config.sequences_per_motion):
            jobs.append(("motion", motion, s, int(rng.integers(2**31))))
    for path in bvh_files:
        p = Path(path)
        if not p.is_file():
            raise InputError("bvh_files", "existing .bvh files", f"{str(p)!r} (no such file)")
        jobs.append(("bvh", str(p), 0, int(rng.integers(2**31))))
    results: list = [None] * len(jobs)
    if workers == 1 or len(jobs) <= 1:
        for i, job in enumerate(jobs):
            results[i] = _run_job(job, config)
            if progress is not None:
                progress(i + 1, len(jobs))
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(max_workers=int(workers), mp_context=mp.get_context("spawn")) as pool:
            futures = {pool.submit(_run_job, job, config): i for i, job in enumerate(jobs)}
            for n, fut in enumerate(as_completed(futures)):
                results[futures[fut]] = fut.result()
                if progress is not None:
                    progress(n + 1, len(jobs))
    db = SilhouetteDatabase.concatenate([part for part, _, _ in results])
    poses = sum(r[1] for r in results)
    dropped = sum(r[2] for r in results)
    dt = time.perf_counter() - t0
    obs.report("scalar", name="silhouette_db/entries", value=float(len(db)))
    obs.report("scalar", name="silhouette_db/entries_per_s", value=float(len(db) / max(dt, 1e-9)))
    obs.report("text", name="silhouette_db", text=f"built {len(db)} entries from {poses} poses in {dt:.1f} s "
                                                  f"({dropped} views cut by the window dropped)")
    return db


def cache_dir() -> Path:
    """``$TOOLKIT_CACHE`` or ``~/.cache/billboard-toolkit``."""
    env = os.environ.get(CACHE_ENV)
    return Path(env).expanduser() if env else DEFAULT_CACHE_DIR.expanduser()


#: Configuration of the database the pipeline uses when none is given (20 480 entries).
DEFAULT_BUILD = BuildConfig()
#: Seed of the default database.
DEFAULT_SEED = 20100430


def default_database_path(config: BuildConfig = DEFAULT_BUILD, seed: int = DEFAULT_SEED) -> Path:
    """Where :func:`default_database` keeps a database: ``<cache_dir()>/silhouettes-<key>-<seed>.npz``."""
    return cache_dir() / f"silhouettes-{config.key()}-{seed}.npz"


def default_database(path: str | os.PathLike | None = None, config: BuildConfig = DEFAULT_BUILD,
                     seed: int = DEFAULT_SEED, *, observer=None, progress=None) -> tuple[SilhouetteDatabase, Path]:
    """Load the default database, building and saving it the first time.

    Parameters
    ----------
    path : path, optional
        Database file; defaults to ``<cache_dir()>/silhouettes-<config key>-<seed>.npz``.
        If it exists it is loaded as is (whatever configuration made it).
    config : BuildConfig
    seed : int

    Returns
    -------
    database : SilhouetteDatabase
    path : Path
        Where it was loaded from or saved to.
    """
    p = Path(path) if path is not None else default_database_path(config, seed)
    if p.exists():
        return SilhouetteDatabase.load(p), p
    db = build_database(config, seed, observer=observer, progress=progress)
    db.save(p)
    return db, p
