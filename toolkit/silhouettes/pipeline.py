"""Stage 1 per frame: silhouettes -> database candidates -> multi-view selection (source 000 §2.1).

:class:`SilhouettePoseEstimator` takes one silhouette per camera and frame
(from :mod:`toolkit.foreground` or any other segmentation), checks it,
queries the database for the k best entries (E_S with the temporal term
after the first frame, the previous pose being the one the multi-view step
chose), hands the candidates in pixels to
:class:`toolkit.multiview.MultiViewTracker` (every combination, rays,
closest points, per-view offsets by Levenberg-Marquardt) and applies the
user's edits (claim 7): corrected joints replace the automatic ones, the
frame is re-triangulated with the corrected poses, and each corrected pose
joins the database with its silhouette.

Bad input never raises: a view whose silhouette is empty, tiny, fills the
frame, touches the border (a person leaving the image) or is missing (a
shorter video) is left out and its state recorded; a frame with fewer than
two usable views gets NaN and a frame state.  :func:`stack_estimates` turns
the per-frame results into a :class:`toolkit.io.stage_outputs.Stage1Output`
(the recipe's ``.npz`` files).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import replace

import numpy as np

from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.io.stage_outputs import Stage1Output
from toolkit.multiview import MultiViewSelection, MultiViewTracker, select_multiview
from toolkit.observe import as_observer
from toolkit.silhouettes.database import USER_MOTION, DatabaseEntry, SilhouetteDatabase
from toolkit.silhouettes.descriptor import (
    SILHOUETTE_STATES,
    STATE_NO_FRAME,
    STATE_OK,
    check_silhouette,
    flow_descriptor,
    normalise_joints,
    silhouette_grid,
)
from toolkit.silhouettes.edits import JointEdit
from toolkit.silhouettes.estimate import (
    FRAME_NOT_PROCESSED,
    FRAME_OK,
    FRAME_SELECTION_FAILED,
    FRAME_STATES,
    FRAME_TOO_FEW_VIEWS,
    FrameEstimate,
    Stage1Config,
)
from toolkit.silhouettes.pooling import pool_pose
from toolkit.silhouettes.query import Candidates, query_database
from toolkit.skeleton import SKELETON_14

#: Prefix of the names of this stage's reports.
REPORT_PREFIX = "silhouettes"
#: Report prefix of the second triangulation of a frame (pooled or corrected 2D poses), beside the
#: selection's ``multiview/...`` reports.
RETRIANGULATED_PREFIX = "multiview/retriangulated"
#: Scale of the 32 x 40 grid image logged per camera (pixels per cell).
GRID_DISPLAY_SCALE = 4
_J = SKELETON_14.n_joints


def _first(c: Candidates, k: int) -> Candidates:
    """The ``k`` best of a candidate list."""
    if len(c) <= k:
        return c
    return replace(c, indices=c.indices[:k], errors=c.errors[:k], silhouette_errors=c.silhouette_errors[:k],
                   temporal_errors=c.temporal_errors[:k], joints=c.joints[:k])


class SilhouettePoseEstimator:
    """Frame-by-frame stage 1 over a rig, keeping the previous poses for the temporal term.

    Parameters
    ----------
    rig : Rig
        At least two cameras, in the order masks are given.
    database : SilhouetteDatabase
        Must not be empty; grows with user corrections.
    config : Stage1Config, optional
    observer : Observer, optional
        Receives, per frame and camera: the silhouette (``mask``), its 32 x 40
        grid (``image``, enlarged), its box (``boxes2d``), the k candidates
        (``joints2d``) with their E_S terms (``scalar``, ``text``), the chosen
        pose; from :mod:`toolkit.multiview`: candidates, rays, closest points,
        ray distances, offsets, 3D joints.

    Raises
    ------
    InputError
        An empty database, fewer than two cameras.
    """

    def __init__(self, rig: Rig, database: SilhouetteDatabase, config: Stage1Config | None = None,
                 observer=None):
        if not isinstance(database, SilhouetteDatabase):
            raise InputError("database", "a SilhouetteDatabase", type(database).__name__)
        if len(database) == 0:
            raise InputError("database", "a silhouette database with at least one entry", "an empty database")
        if len(rig) < 2:
            raise InputError("rig", "at least two cameras", f"{len(rig)}")
        self.rig = rig
        self.database = database
        self.config = config or Stage1Config()
        self.observer = as_observer(observer)
        self.tracker = MultiViewTracker(rig, self.config.multiview, self.observer)
        self._previous: list[np.ndarray | None] = [None] * len(rig)

    @property
    def n_views(self) -> int:
        return len(self.rig)

    def reset(self) -> None:
        """Forget the previous frame (the next query uses λ = 0)."""
        self._previous = [None] * self.n_views
        self.tracker = MultiViewTracker(self.rig, self.config.multiview, self.observer)

    # ------------------------------------------------------------ per view
    def _view(self, v: int, mask, frame: int, flow=None):
        cam = self.rig[v]
        obs = self.observer
        P = REPORT_PREFIX
        if mask is None:
            return STATE_NO_FRAME, None, None
        m = np.asarray(mask)
        if m.ndim != 2:
            raise InputError(f"masks[{v}] ({cam.name})", "a 2D (H, W) mask", f"shape {m.shape}")
        check = check_silhouette(m, min_pixels=self.config.min_pixels, max_fill=self.config.max_fill,
                                 border_px=self.config.border_px)
        obs.report("mask", camera=cam.name, mask=m.astype(bool), name=f"{P}/silhouette", frame=frame)
        if check.bbox is not None:
            b = check.bbox
            obs.report("boxes2d", camera=cam.name, mins=b[None, :2], sizes=(b[2:] - b[:2])[None],
                       name=f"{P}/bbox", labels=[check.reason], frame=frame)
        if not check.ok:
            obs.report("text", name=f"{P}/{cam.name}", text=f"frame {frame}: view left out: {check.reason}",
                       level="WARN", frame=frame)
            return check.state, check.bbox, None
        grid = silhouette_grid(m, check.bbox)
        big = np.kron(grid, np.ones((GRID_DISPLAY_SCALE, GRID_DISPLAY_SCALE), np.float32))
        obs.report("image", camera=cam.name, image=big, name=f"{P}/grid", frame=frame)
        fd = None
        if flow is not None and self.config.query.flow_weight > 0:
            fd = flow_descriptor(flow, check.bbox)
        query = self.config.query
        if self.config.pool_k > query.k:  # the selection uses the k best, pooling the pool_k best
            query = replace(query, k=self.config.pool_k)
        cands = query_database(self.database, grid.reshape(-1), self._previous[v], query, flow=fd)
        return STATE_OK, check.bbox, cands

    def _report_candidates(self, v: int, cands: Candidates, cand_px: np.ndarray, frame: int) -> None:
        cam = self.rig[v]
        P = REPORT_PREFIX
        lines = [f"frame {frame}, {cam.name}: {len(cands)} best of {len(self.database)} entries "
                 f"(lambda = {cands.lam:g}, {cands.metric})"]
        for i in range(len(cands)):
            self.observer.report("joints2d", camera=cam.name, joints=cand_px[i], name=f"{P}/candidate_{i}",
                                 skeleton=SKELETON_14, frame=frame)
            self.observer.report("scalar", name=f"{P}/E_S/{cam.name}/candidate_{i}", value=float(cands.errors[i]),
                                 frame=frame)
            r = int(cands.indices[i])
            lines.append(f"  {i}: entry {r} ({self.database.motion[r]}, az {self.database.azimuth_deg[r]:.0f}, "
                         f"el {self.database.elevation_deg[r]:.0f}) E_S {cands.errors[i]:.4f} = silhouette "
                         f"{cands.silhouette_errors[i]:.4f}, joints {cands.temporal_errors[i]:.4f}")
        self.observer.report("text", name=f"{P}/candidates/{cam.name}", text="\n".join(lines), frame=frame)

    # ----------------------------------------------------------- per frame
    def step(self, masks: Sequence[np.ndarray | None], frame: int,
             edits: dict[str, JointEdit] | None = None, flows: Sequence[np.ndarray | None] | None = None
             ) -> FrameEstimate:
        """Estimate one frame.

        Parameters
        ----------
        masks : sequence of (ndarray of shape (H, W), bool, or None)
            One silhouette per camera of the rig; None when the camera has no
            frame (a shorter video).
        frame : int
        edits : dict of str to JointEdit, optional
            This frame's corrections by camera name (:meth:`Edits.for_frame`).
        flows : sequence of (ndarray of shape (H, W, 2) or None), optional
            Per camera, the motion of each pixel since the previous frame
            (pixels); used by the flow term when ``config.query.flow_weight > 0``.

        Returns
        -------
        FrameEstimate
        """
        if len(masks) != self.n_views:
            raise InputError("masks", f"one mask per camera ({self.n_views})", f"{len(masks)}")
        if flows is not None and len(flows) != self.n_views:
            raise InputError("flows", f"one flow field (or None) per camera ({self.n_views})", f"{len(flows)}")
        t_start = time.perf_counter()
        n_views = self.n_views
        states, boxes, cands, cand_px, pool = self._query_views(masks, frame, flows)
        t_query = time.perf_counter() - t_start
        usable = states == STATE_OK
        poses = np.full((n_views, _J, 2), np.nan)
        offsets = np.full((n_views, 2), np.nan)
        joints = np.full((_J, 3), np.nan)
        cost = float("nan")
        sel = None
        chosen = poses
        if usable.sum() < 2:
            fstate = FRAME_TOO_FEW_VIEWS
        else:
            sel = self.tracker.step(cand_px, frame=frame)
            fstate = FRAME_OK if sel.success else FRAME_SELECTION_FAILED
            if sel.success:
                used = sel.views_used
                poses = np.where(used[:, None, None], sel.poses2d_raw, np.nan)
                offsets = np.where(used[:, None], sel.offsets, np.nan)
                joints, cost = sel.joints3d, float(sel.cost)
                chosen = poses
        # pooled and corrected 2D poses are triangulated once, together
        target, counts = poses, np.zeros(n_views, int)
        if sel is not None and sel.success and self.config.pool_k > 1:
            target, counts = self._pool(pool, boxes, poses)
        t_multiview = time.perf_counter() - t_start - t_query
        edited = np.zeros(n_views, bool)
        added: list[int] = []
        if edits:
            target, edited, added = self._apply_edits(edits, masks, target, frame)
            poses = target  # the corrections stand even if they cannot be triangulated
        t_edits = time.perf_counter() - t_start - t_query - t_multiview
        if (counts >= 2).any() or (edited.any() and (np.isfinite(target).all(-1).sum(-1) >= 1).sum() >= 2):
            res = self._retriangulate(target, frame)
            if res.success:
                used = res.views_used
                poses = np.where(used[:, None, None], target, np.nan)
                offsets = np.where(used[:, None], res.offsets, np.nan)
                joints, cost, fstate, sel = res.joints3d, float(res.cost), FRAME_OK, res
            if (counts >= 2).any():
                self.observer.report("text", name=f"{REPORT_PREFIX}/pooling", frame=frame,
                                     text=f"frame {frame}: pooled " + ", ".join(
                                         f"{c.name} {n}" for c, n in zip(self.rig, counts))
                                     + " database entries per view"
                                     + ("" if res.success else "; triangulation failed, the selection's pose kept"))
        t_multiview = time.perf_counter() - t_start - t_query - t_edits
        self._remember(poses, chosen, edited, boxes)
        self._report_frame(poses, joints, states, fstate, frame)
        return FrameEstimate(frame, fstate, states, boxes, tuple(cands), cand_px, poses, offsets, joints, cost,
                             edited, tuple(added), sel,
                             {"query": t_query, "multiview": t_multiview, "edits": t_edits})

    def _query_views(self, masks, frame: int, flows):
        """Query the database with every view's silhouette.

        Parameters
        ----------
        masks : sequence of (ndarray of shape (H, W), bool, or None)
        frame : int
        flows : sequence of (ndarray of shape (H, W, 2) or None) or None

        Returns
        -------
        states : ndarray of uint8, shape (n_views,)
            Silhouette state per view.
        boxes : ndarray of shape (n_views, 4)
            Silhouette boxes, pixels (NaN none).
        cands : list of (Candidates or None)
            The ``k`` best database entries per view.
        cand_px : ndarray of shape (n_views, k, 14, 2)
            Their 2D poses, pixels.
        pool : list of (tuple or None)
            Per view, the ``pool_k`` best 2D poses (pool_k, 14, 2) and their errors.
        """
        n_views, k = self.n_views, self.config.query.k
        states = np.zeros(n_views, np.uint8)
        boxes = np.full((n_views, 4), np.nan)
        cands: list[Candidates | None] = [None] * n_views
        cand_px = np.full((n_views, k, _J, 2), np.nan)
        pool: list[tuple[np.ndarray, np.ndarray] | None] = [None] * n_views
        for v in range(n_views):
            state, box, c = self._view(v, masks[v], frame, None if flows is None else flows[v])
            states[v] = state
            if box is not None:
                boxes[v] = box
            if c is not None:
                px = c.joints_px(box)
                pk = self.config.pool_k  # the query returned max(k, pool_k) entries
                pool[v] = (px[:pk], np.asarray(c.errors, float)[:pk])
                c = _first(c, k)
                cands[v] = c
                cand_px[v, :len(c)] = px[:k]
                self._report_candidates(v, c, cand_px[v], frame)
        return states, boxes, cands, cand_px, pool

    def _remember(self, poses: np.ndarray, chosen: np.ndarray, edited: np.ndarray, boxes: np.ndarray) -> None:
        """Keep each view's pose for the temporal term of the next frame.

        The chosen database pose (not pooled) in its own box; corrected views their corrected pose.

        Parameters
        ----------
        poses : ndarray of shape (n_views, 14, 2)
            The frame's 2D poses (corrections applied), pixels.
        chosen : ndarray of shape (n_views, 14, 2)
            The selection's database poses, pixels.
        edited : ndarray of shape (n_views,), bool
        boxes : ndarray of shape (n_views, 4)
        """
        for v in range(self.n_views):
            p = poses[v] if edited[v] else chosen[v]
            ok = np.isfinite(boxes[v]).all() and np.isfinite(p).all()
            self._previous[v] = normalise_joints(p, boxes[v]) if ok else None

    def _report_frame(self, poses: np.ndarray, joints: np.ndarray, states: np.ndarray, fstate: int,
                      frame: int) -> None:
        """Report the frame's 2D poses, 3D joints and states.

        Parameters
        ----------
        poses : ndarray of shape (n_views, 14, 2)
        joints : ndarray of shape (14, 3)
        states : ndarray of uint8, shape (n_views,)
        fstate : int
        frame : int
        """
        P = REPORT_PREFIX
        for v, cam in enumerate(self.rig):
            if np.isfinite(poses[v]).any():
                self.observer.report("joints2d", camera=cam.name, joints=poses[v], name=f"{P}/pose",
                                     skeleton=SKELETON_14, frame=frame)
        if np.isfinite(joints).any():
            self.observer.report("joints3d", joints=joints, name=f"{P}/pose3d", skeleton=SKELETON_14, frame=frame)
        self.observer.report("text", name=f"{P}/frame", frame=frame,
                             text=f"frame {frame}: {FRAME_STATES[fstate]}; views: "
                                  + ", ".join(f"{c.name} {SILHOUETTE_STATES[int(s)]}" for c, s in zip(self.rig, states)),
                             level="INFO" if fstate == FRAME_OK else "WARN")

    def _pool(self, pool, boxes, poses):
        """Each view's chosen pose replaced by the weighted mean of the database entries that agree with it
        (see :class:`Stage1Config`); returns the poses (n_views, 14, 2) and the entries pooled per view."""
        pooled = poses.copy()
        counts = np.zeros(self.n_views, int)
        for v in range(self.n_views):
            if pool[v] is None or not np.isfinite(poses[v]).all():
                continue
            radius = self.config.pool_radius * float(boxes[v, 3] - boxes[v, 1])
            pooled[v], counts[v] = pool_pose(poses[v], pool[v][0], pool[v][1], radius)
        return pooled, counts

    def _retriangulate(self, poses, frame) -> MultiViewSelection:
        """Triangulate fixed 2D poses (one candidate per view, no flips) from the tracker's offsets;
        on success the tracker carries the new offsets and pose forward (corrected or pooled poses)."""
        cfg = replace(self.config.multiview, flips=())
        init = self.tracker.offsets
        sel = select_multiview(poses[:, None], self.rig, cfg, initial_offsets=init,
                               previous_joints3d=self.tracker.joints3d, observer=self.observer, frame=frame,
                               report_prefix=RETRIANGULATED_PREFIX)
        if sel.success:
            used = sel.views_used
            self.tracker.offsets = np.where(used[:, None], sel.offsets, 0.0 if init is None else init)
            if np.isfinite(sel.joints3d).all():
                self.tracker.joints3d = sel.joints3d
        return sel

    def _apply_edits(self, edits, masks, poses, frame):
        """The user's corrections applied to ``poses`` (n_views, 14, 2), optionally added to the database;
        returns the poses, which views were edited and the database rows added (triangulated by the caller)."""
        n_views = self.n_views
        names = self.rig.names
        edited = np.zeros(n_views, bool)
        added: list[int] = []
        poses = poses.copy()
        for cam_name, e in edits.items():
            if cam_name not in names:
                raise InputError(f"edits: frame {frame} camera", f"one of {names}", repr(cam_name))
            v = names.index(cam_name)
            poses[v] = e.apply(poses[v])
            edited[v] = True
            mask = masks[v]
            if not (self.config.add_edits_to_database and e.add_to_database):
                continue
            if mask is None or not np.asarray(mask).any() or not np.isfinite(poses[v]).all():
                self.observer.report("text", name=f"{REPORT_PREFIX}/edits", level="WARN", frame=frame,
                                     text=f"frame {frame}, {cam_name}: corrected pose not added to the database "
                                          "(no silhouette or not all 14 joints known)")
                continue
            entry = DatabaseEntry.from_silhouette(np.asarray(mask, bool), poses[v], motion=USER_MOTION, frame=frame,
                                                  source=f"{cam_name} frame {frame}")
            added.append(self.database.add(entry))
        self.observer.report("text", name=f"{REPORT_PREFIX}/edits", frame=frame,
                             text=f"frame {frame}: corrected {[names[v] for v in np.flatnonzero(edited)]}; "
                                  f"{len(added)} pose(s) added to the database ({len(self.database)} entries)")
        return poses, edited, added


def stack_estimates(estimates: Sequence[FrameEstimate | None], n_frames: int, camera_names: Sequence[str],
                    k: int) -> Stage1Output:
    """Per-frame estimates as the run's stage-1 output (written by :func:`toolkit.io.stage_outputs.write_stage1`).

    Parameters
    ----------
    estimates : sequence of FrameEstimate or None
        Indexed by frame; missing or None frames are ``FRAME_NOT_PROCESSED``.
    n_frames : int
    camera_names : sequence of str
    k : int
        Candidates per view.

    Returns
    -------
    Stage1Output
        ``joints`` (T, 14, 3), ``offsets`` (T, n_views, 2) pixels, ``poses2d``
        (one (T, 14, 2) array per camera, image pixels, chosen pose),
        ``state`` (T,) uint8, ``cost`` (T,) metres, ``view_state`` (T,
        n_views) uint8, ``bbox`` (T, n_views, 4), ``candidates`` (T, n_views,
        k, 14, 2), ``candidate_errors`` (T, n_views, k), ``candidate_index``
        (T, n_views, k), ``edited`` (T, n_views); NaN (-1 for indices) where a
        frame or view has none.

    Raises
    ------
    InputError
        Camera names that clash with the per-view arrays' keys (``Stage1Output.cameras``).
    """
    T, C = int(n_frames), len(camera_names)
    poses = np.full((C, T, _J, 2), np.nan)
    vstate = np.full((T, C), STATE_NO_FRAME, np.uint8)
    bbox = np.full((T, C, 4), np.nan)
    cand = np.full((T, C, k, _J, 2), np.nan)
    cerr = np.full((T, C, k), np.nan)
    cidx = np.full((T, C, k), -1, np.int64)
    edited = np.zeros((T, C), bool)
    joints = np.full((T, _J, 3), np.nan)
    state = np.full(T, FRAME_NOT_PROCESSED, np.uint8)
    cost = np.full(T, np.nan)
    offsets = np.full((T, C, 2), np.nan)
    for e in estimates:
        if e is None or not 0 <= e.frame < T:
            continue
        t = e.frame
        poses[:, t] = e.poses2d
        vstate[t] = e.view_states
        bbox[t] = e.bboxes
        cand[t, :, :e.candidates_px.shape[1]] = e.candidates_px[:, :k]
        for v, c in enumerate(e.candidates):
            if c is not None:
                cerr[t, v, :len(c)] = c.errors[:k]
                cidx[t, v, :len(c)] = c.indices[:k]
        edited[t] = e.edited
        joints[t] = e.joints3d
        state[t] = e.state
        cost[t] = e.cost
        offsets[t] = e.offsets
    return Stage1Output(joints, tuple(camera_names), offsets, {name: poses[v] for v, name in enumerate(camera_names)},
                        state=state, cost=cost, joint_names=SKELETON_14.joint_names, view_state=vstate, bbox=bbox,
                        candidates=cand, candidate_errors=cerr, candidate_index=cidx, edited=edited)


def _rig_and_frames(dataset, rig: Rig | None, frames) -> tuple[Rig, list[int]]:
    """The cameras and the frames to process, checked against the dataset.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    rig : Rig or None
        Default ``dataset.rig``.
    frames : sequence of int or None
        Default all.

    Returns
    -------
    rig : Rig
    todo : list of int
        Increasing frame indices.

    Raises
    ------
    InputError
        A camera the dataset lacks, or frames not increasing within the dataset.
    """
    rig = dataset.rig if rig is None else rig
    names = rig.names
    unknown = [c for c in names if c not in dataset.camera_names]
    if unknown:
        raise InputError("rig", f"cameras of the dataset {dataset.camera_names}", f"{unknown}")
    todo = list(range(dataset.n_frames)) if frames is None else [int(t) for t in frames]
    if any(b <= a for a, b in zip(todo, todo[1:])) or (todo and not 0 <= todo[0] <= todo[-1] < dataset.n_frames):
        raise InputError("frames", f"increasing frame indices in [0, {dataset.n_frames})", f"{todo[:5]}...")
    return rig, todo


class _CameraFeed:
    """One camera's frames through its foreground extractor, with the state kept between frames.

    Parameters
    ----------
    name : str
        The camera.
    read : callable
        Frame index -> (H, W, 3) uint8 image; raises ``InputError`` or ``IndexError`` past the video's end.
    extractor : ForegroundExtractor
        Fitted to the camera's background.
    obs : Observer
    use_flow : bool
        Estimate the motion since the previous frame (dense optical flow).
    log_images : bool
        Report each image.
    """

    def __init__(self, name: str, read, extractor, obs, use_flow: bool, log_images: bool):
        self.name, self.read, self.extractor, self.obs = name, read, extractor, obs
        self.use_flow, self.log_images = use_flow, log_images
        self.ended = False
        self.previous: tuple | None = None
        self.last: tuple[int, np.ndarray] | None = None

    def step(self, t: int) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The silhouette of frame ``t`` and the motion since frame ``t - 1``.

        Parameters
        ----------
        t : int
            Frame index (increasing between calls).

        Returns
        -------
        mask : ndarray of shape (H, W), bool, or None
            None when the video has no frame ``t``.
        flow : ndarray of shape (H, W, 2) or None
            Pixels; None without flow or without the previous frame.
        """
        from toolkit.foreground import dense_flow

        c, obs = self.name, self.obs
        frame = None
        if not self.ended:
            try:
                frame = self.read(t)
            except (InputError, IndexError) as e:
                self.ended = True
                obs.report("text", name=f"{REPORT_PREFIX}/{c}", level="WARN", frame=t,
                           text=f"frame {t}: {c} has no more frames ({e}); its view is left out")
        if frame is None:
            self.previous = None
            return None, None
        if self.use_flow and self.last is not None and self.last[0] == t - 1:
            # motion since the previous frame: minus the flow from this frame back to it
            flow = -dense_flow(frame, self.last[1])
        else:
            flow = None
        self.last = (t, frame)
        if self.log_images:
            obs.report("image", camera=c, image=frame, frame=t)
        sil = self.extractor.extract(frame, self.previous)
        self.previous = (frame, sil.mask) if sil.usable else None
        return sil.mask, flow


def estimate_dataset(dataset, database: SilhouetteDatabase, config: Stage1Config | None = None, *,
                     foreground=None, frames: Sequence[int] | None = None, edits=None, rig: Rig | None = None,
                     backgrounds=None, observer=None, log_images: bool = True
                     ) -> Iterator[tuple[FrameEstimate, list]]:
    """Run stage 1 over a dataset's videos, frame by frame.

    Parameters
    ----------
    dataset : toolkit.io.Dataset
    database : SilhouetteDatabase
    config : Stage1Config, optional
    foreground : toolkit.foreground.ForegroundConfig, optional
        How silhouettes are cut from the videos (background subtraction by
        default; the background is learned per camera from its whole video).
    frames : sequence of int, optional
        Frames to process, increasing (default: all).
    edits : toolkit.silhouettes.Edits, optional
        User corrections, applied on their frames.
    rig : Rig, optional
        Cameras to use instead of ``dataset.rig``: a subset of its cameras
        (by name) or other calibrations of them (e.g. the true ones).
    backgrounds : mapping of str to sequence of ndarray of shape (H, W, 3), optional
        Per camera, frames to learn its background from instead of its video
        (e.g. one clean plate of the empty scene).
    observer : Observer, optional
        Also receives each camera image (``image``) per frame.
    log_images : bool
        Report the camera images (large recordings for long videos).

    Yields
    ------
    estimate : FrameEstimate
        With ``timings["foreground"]`` (seconds for all cameras) and ``timings["stage1"]`` (all of this
        frame's stage 1: the foreground, the query and the multi-view step, and its share of learning the
        background models).
    masks : list of (ndarray of shape (H, W), bool, or None)
        The silhouettes given to the estimator (None: no frame).

    Notes
    -----
    With ``config.query.flow_weight > 0`` the motion of every pixel since the
    previous frame is estimated by dense optical flow
    (:func:`toolkit.foreground.dense_flow`, from this frame back to the
    previous one, negated) and matched against the database's flow
    descriptors (build the database with ``BuildConfig(with_flow=True)``).

    A camera whose video ends early (fewer decodable frames than declared)
    gives ``None`` masks from then on (state "no video frame"); the other
    cameras go on.
    """
    from toolkit.foreground import ForegroundExtractor
    from toolkit.io import VideoReader

    obs = as_observer(observer)
    rig, todo = _rig_and_frames(dataset, rig, frames)
    names = rig.names
    estimator = SilhouettePoseEstimator(rig, database, config, observer)
    if backgrounds is None:  # the dataset's clean plates, where it has them
        plate = getattr(dataset, "background", None)  # readers without clean plates have none
        backgrounds = {} if plate is None else {c: [img] for c in names if (img := plate(c)) is not None}
    # a background model without a plate learns from a pass over the video, on its own decoder; the frames
    # themselves are read through the dataset, whose reader keeps the last one: the caller's
    # dataset.frame(c, t) after this generator yields frame t decodes nothing again
    shared = getattr(dataset, "frame", None)  # a Dataset; any object with video_path() works too
    t_setup = time.perf_counter()
    readers = {c: VideoReader(dataset.video_path(c)) for c in names if c not in backgrounds or shared is None}
    try:
        extractors = {c: ForegroundExtractor(foreground).fit(backgrounds[c] if c in backgrounds else readers[c])
                      for c in names}
        setup = (time.perf_counter() - t_setup) / max(len(todo), 1)  # each frame's share of the background models
        use_flow = estimator.config.query.flow_weight > 0
        feeds = [_CameraFeed(c, (lambda t, c=c: shared(c, t)) if shared is not None else readers[c].read,
                             extractors[c], obs, use_flow, log_images) for c in names]
        for t in todo:
            t0 = time.perf_counter()
            steps = [feed.step(t) for feed in feeds]
            masks = [mask for mask, _ in steps]
            flows = [flow for _, flow in steps]
            t_fg = time.perf_counter() - t0
            est = estimator.step(masks, t, None if edits is None else edits.for_frame(t), flows if use_flow else None)
            est.timings["foreground"] = t_fg
            est.timings["stage1"] = time.perf_counter() - t0 + setup
            yield est, masks
    finally:
        for r in readers.values():
            r.close()
