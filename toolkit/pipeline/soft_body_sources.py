"""Where the soft-body run's data come from: per-frame clouds and the initial joints.

Two sources of 3D points (issue 18 item 2):

* :class:`DepthClouds` -- a depth camera (a dataset folder with ``depth_camera/``
  or a folder of depth frames, :func:`toolkit.io.depth_readers.open_depth_input`):
  the foreground pixels (:func:`toolkit.pointcloud.foreground_mask`, against the
  empty scene when there is one) back-projected to the world.  Every person in
  view stays in: the tracker tells the subject from the others with its model
  (:mod:`toolkit.softbody.separate`), which a mask of one person chosen by size
  cannot (a second person standing apart, larger in the image, was taken for the
  user: every frame "empty");
* :class:`StereoClouds` -- the trinocular heads of a dataset
  (:mod:`toolkit.pointcloud.stereo`), limited to the subject by a foreground
  mask: the dataset's own masks (``masks/``), else background subtraction
  against the clean plates (``background/``, :mod:`toolkit.foreground`), or the
  ground-truth masks when asked for (``foreground = "groundtruth"``, for
  benchmarks that isolate the stereo from the segmentation).

and the initial 14 joints of one frame (item 3): the depth tracker's 13
control points turned into the 14-joint skeleton (:func:`joints14_from_control13`),
a joints file (stage 1's ``joints3d.npz``-like ``joints`` array), or 2D joints
clicked in two calibrated images (a ``clicks.npz``, triangulated by
:func:`toolkit.softbody.init_from_2d`).

A depth camera without a known pose (real Kinect frames) gives camera
coordinates; they are turned into a level world frame (x right, y forward,
z up: :data:`LEVEL_FROM_CAMERA`) so that the body model's "up" is up.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolkit.errors import InputError

#: World-from-camera rotation of a level camera (camera x right, y down, z forward -> x, y forward, z up).
LEVEL_FROM_CAMERA = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: Foreground choices of stereo sources.
FOREGROUNDS = ("auto", "masks", "plate", "groundtruth")


class DepthClouds:
    """The foreground points (every person in view) of each depth frame, world (or level camera)
    coordinates, metres.

    Parameters
    ----------
    dataset : path
        A dataset folder with ``depth_camera/`` or a folder of depth frames.
    mask_config : toolkit.pointcloud.MaskConfig, optional
    keep_masks : bool
        :meth:`cloud` keeps each frame's foreground mask until :meth:`silhouettes` takes it (the
        silhouettes are then the very masks the clouds used, found once).
    """

    kind = "depth"

    def __init__(self, dataset, *, mask_config=None, keep_masks: bool = False):
        from toolkit.io.depth_readers import open_depth_input
        from toolkit.pointcloud import BackgroundModel, MaskConfig

        self.input = open_depth_input(dataset)
        self.background = None if self.input.background is None else BackgroundModel(self.input.background)
        self.mask_config = mask_config or MaskConfig()
        self.keep_masks, self._masks, self._unknown = bool(keep_masks), {}, {}

    def __len__(self) -> int:
        return len(self.input)

    def silhouette_unknown(self, t: int) -> list:
        """Frame ``t``'s pixels in front of the background by too little to call them foreground (the soles
        of feet on the floor; :func:`toolkit.pointcloud.ambiguous_mask`), ``[(H, W) bool]`` in the order of
        :meth:`silhouettes`: the silhouettes treat them as unknown."""
        from toolkit.pointcloud import ambiguous_mask

        u = self._unknown.pop(t, None)
        if u is None:
            u = ambiguous_mask(self.input.read(t), self.input.camera, background=self.background,
                               config=self.mask_config)
        return [u]

    def silhouettes(self, t: int) -> list:
        """The camera in the run's world frame and frame ``t``'s foreground mask, ``[(Camera, (H, W) bool)]``."""
        from toolkit.pointcloud import foreground_mask

        cam = self.input.camera
        if not self.input.pose_known:  # the level frame: world = LEVEL_FROM_CAMERA @ camera
            T = np.eye(4)
            T[:3, :3] = LEVEL_FROM_CAMERA.T
            cam = cam.replace(cam_from_world=T)
        m = self._masks.pop(t, None)
        if m is None:
            m = foreground_mask(self.input.read(t), self.input.camera, background=self.background,
                                config=self.mask_config)
        return [(cam, m)]

    @property
    def forward(self) -> np.ndarray:
        """The depth camera's viewing direction in the run's world frame, (3,)."""
        return self.to_world(np.array([[0.0, 0.0, 1.0]]))[0] - self.to_world(np.zeros((1, 3)))[0]

    @property
    def viewpoints(self) -> np.ndarray:
        """The depth camera's centre in the run's world frame, (1, 3)."""
        return self.input.camera.center[None] if self.input.pose_known else np.zeros((1, 3))

    def to_world(self, points_cam: np.ndarray) -> np.ndarray:
        """Camera-frame points (N, 3) to the run's world frame."""
        cam = self.input.camera
        if self.input.pose_known:
            return (points_cam - cam.t) @ cam.R
        return points_cam @ LEVEL_FROM_CAMERA.T

    def cloud(self, t: int) -> np.ndarray:
        """The foreground points of frame ``t``, (N, 3) metres (empty when there are none)."""
        from toolkit.pointcloud import depth_to_points, foreground_mask

        d = self.input.read(t)
        m = foreground_mask(d, self.input.camera, background=self.background, config=self.mask_config)
        if self.keep_masks:
            from toolkit.pointcloud import ambiguous_mask

            self._masks[t] = m
            self._unknown[t] = ambiguous_mask(d, self.input.camera, background=self.background,
                                              config=self.mask_config)
        if not m.any():
            return np.zeros((0, 3))
        pts, _, _ = depth_to_points(d, self.input.camera, m)
        return self.to_world(pts)


class StereoClouds:
    """The points of every trinocular head of a dataset in each frame, world, metres.

    Parameters
    ----------
    dataset : path
        A dataset folder with trinocular heads (:func:`toolkit.pointcloud.stereo.trinocular_heads`).
    stereo : toolkit.pointcloud.stereo.StereoConfig, optional
    foreground : {"auto", "masks", "plate", "groundtruth"}
        How the subject is found in the images (:data:`FOREGROUNDS`).
    keep_masks : bool
        :meth:`cloud` keeps each head's reference mask until :meth:`silhouettes` takes it.
    """

    kind = "stereo"

    def __init__(self, dataset, *, stereo=None, foreground: str = "auto", keep_masks: bool = False):
        from toolkit.io import Dataset
        from toolkit.pointcloud.stereo import StereoConfig, head_pairs, trinocular_heads

        if foreground not in FOREGROUNDS:
            raise InputError("foreground (--foreground)", f"one of {FOREGROUNDS}", repr(foreground))
        self.data = Dataset.open(dataset)
        self.heads = trinocular_heads(self.data.rig)
        self.pairs = [head_pairs(h) for h in self.heads]
        self.config = stereo or StereoConfig()
        self.foreground = self._choose(foreground)
        self._plates = {}
        self.keep_masks, self._masks, self._edge_offsets = bool(keep_masks), {}, {}

    def _choose(self, foreground: str) -> str:
        d, first = self.data, self.data.camera_names[0]
        if foreground == "auto":
            if d.has_masks:
                return "masks"
            if d.background(first) is not None:
                return "plate"
            raise InputError(f"{d.root}", "subject masks (masks/) or clean plates (background/) to find the "
                             "subject in the stereo images", "neither")
        if foreground == "plate" and d.background(first) is None:
            raise InputError(f"{d.root}/background", "clean plates (foreground = 'plate')", "none")
        if foreground == "masks" and not d.has_masks:
            raise InputError(f"{d.root}/masks", "subject masks (foreground = 'masks')", "none")
        if foreground == "groundtruth" and not d.has_groundtruth:
            raise InputError(f"{d.root}/groundtruth", "ground-truth masks (foreground = 'groundtruth')", "none")
        return foreground

    def __len__(self) -> int:
        return self.data.n_frames

    @property
    def forward(self) -> np.ndarray:
        """The first head's viewing direction, (3,)."""
        return self.heads[0][0].forward

    @property
    def viewpoints(self) -> np.ndarray:
        """The heads' reference camera centres, (H, 3) metres."""
        return np.array([h[0].center for h in self.heads])

    def mask(self, camera: str, t: int, image: np.ndarray) -> np.ndarray | None:
        """The subject in ``camera``'s frame ``t`` as the config's foreground sees it."""
        if self.foreground == "groundtruth":
            return self.data.gt_mask(camera, t)
        if self.foreground == "masks":
            return self.data.mask(camera, t)
        from toolkit.foreground import BackgroundConfig, BackgroundModel, clean_mask

        if camera not in self._plates:
            cfg = BackgroundConfig()
            plate = self.data.background(camera)
            self._plates[camera] = BackgroundModel(cfg, plate, np.full(plate.shape[:2], cfg.min_threshold,
                                                                       np.float32))
        return clean_mask(self._plates[camera].foreground(image))

    def silhouettes(self, t: int) -> list:
        """Each head's reference camera with the subject's mask in frame ``t`` (the masks the clouds were
        limited by: kept by :meth:`cloud` when ``keep_masks``), ``[(Camera, (H, W) bool)]``."""
        kept = self._masks.pop(t, None)
        if kept is not None:
            return kept
        return [(h[0], self.mask(h[0].name, t, self.data.frame(h[0].name, t))) for h in self.heads]

    def silhouette_edge_offsets(self, t: int) -> list:
        """How far each head's reference image's edge lies from its mask's outline in frame ``t`` (pixels,
        :func:`toolkit.softbody.silhouette.mask_edge_offset`), in the order of :meth:`silhouettes`: the
        silhouettes' outlines are moved by it (measured by :meth:`cloud` when it keeps the masks, so that the
        images are not kept)."""
        from toolkit.softbody.silhouette import mask_edge_offset

        kept = self._edge_offsets.pop(t, None)
        if kept is not None:
            return kept
        masks = self._masks.get(t)
        out = []
        for k, h in enumerate(self.heads):
            image = self.data.frame(h[0].name, t)
            m = masks[k][1] if masks is not None else self.mask(h[0].name, t, image)
            out.append(mask_edge_offset(image, m))
        return out

    def cloud(self, t: int) -> np.ndarray:
        """The heads' points of frame ``t``, (N, 3) metres (empty when nothing matched)."""
        from toolkit.pointcloud.stereo import head_cloud

        out = []
        for head, pairs in zip(self.heads, self.pairs):
            images = [self.data.frame(c.name, t) for c in head]
            masks = [self.mask(c.name, t, im) if k == 0 else None for k, (c, im) in enumerate(zip(head, images))]
            if self.keep_masks:
                from toolkit.softbody.silhouette import mask_edge_offset

                self._masks.setdefault(t, []).append((head[0], masks[0]))
                self._edge_offsets.setdefault(t, []).append(mask_edge_offset(images[0], masks[0]))
            out.append(head_cloud(images, head, masks, self.config, pairs).points)
        return np.concatenate(out) if out else np.zeros((0, 3))


def open_source(dataset, kind: str = "auto", *, stereo=None, foreground: str = "auto", keep_masks: bool = False):
    """The cloud source of ``dataset``: ``"depth"`` (a ``depth_camera/`` or a folder of depth frames),
    ``"stereo"`` (a dataset of trinocular heads), or ``"auto"`` (depth when there is a ``depth_camera/``
    folder or no ``calibration.toml``); ``keep_masks``: the clouds' masks are kept for the silhouettes."""
    root = Path(dataset)
    if kind == "auto":
        kind = "depth" if (root / "depth_camera").is_dir() or not (root / "calibration.toml").is_file() else "stereo"
    if kind == "depth":
        return DepthClouds(root, keep_masks=keep_masks)
    if kind == "stereo":
        return StereoClouds(root, stereo=stereo, foreground=foreground, keep_masks=keep_masks)
    raise InputError("source (--source)", "'auto', 'depth' or 'stereo'", repr(kind))


def joints14_from_control13(points13: np.ndarray, stature: float = 1.75) -> np.ndarray:
    """The 14-joint skeleton under the depth tracker's 13 control points (the inverse of
    :func:`toolkit.body.control_points.control_points`, with its offsets undone along the
    limbs' directions; the neck a median shoulder drop above the shoulders' midpoint).

    Parameters
    ----------
    points13 : ndarray of shape (13, 3)
        ``JOINTS_13`` order, metres, z up.
    stature : float
        Metres (scales the hand and foot offsets).

    Returns
    -------
    ndarray of shape (14, 3)
        ``SKELETON_14`` order (NaN where the control point was missing).
    """
    from toolkit.body.control_points import (FOOT_CENTRE_DOWN, FOOT_CENTRE_FORWARD, HAND_CENTRE_BEYOND_WRIST,
                                             HEAD_CENTRE_UP)
    from toolkit.anthropometry import BodyProportions
    from toolkit.skeleton import JOINTS_13, SKELETON_14

    p = np.asarray(points13, float)
    if p.shape != (13, 3):
        raise InputError("points13", "an array of shape (13, 3)", f"shape {p.shape}")
    g = {n: p[i] for i, n in enumerate(JOINTS_13)}
    s = stature / 1.75
    unit = lambda v: v / max(np.linalg.norm(v), 1e-9)  # noqa: E731
    mid = 0.5 * (g["l_shoulder"] + g["r_shoulder"])
    neck = mid + BodyProportions.from_height(stature).shoulder_drop * unit(g["head"] - mid)
    out = {"head": g["head"] - HEAD_CENTRE_UP * s * unit(g["head"] - neck), "neck": neck}
    lateral = unit(g["r_shoulder"] - g["l_shoulder"] + g["r_hip"] - g["l_hip"])
    for side in ("l", "r"):
        for n in ("shoulder", "elbow", "hip", "knee"):
            out[f"{side}_{n}"] = g[f"{side}_{n}"]
        hand, elbow = g[f"{side}_hand"], g[f"{side}_elbow"]
        out[f"{side}_wrist"] = hand - HAND_CENTRE_BEYOND_WRIST * s * unit(hand - elbow)
        foot, knee = g[f"{side}_foot"], g[f"{side}_knee"]
        d = unit(foot - knee)
        w = unit(np.cross(-d, lateral))
        out[f"{side}_ankle"] = foot - FOOT_CENTRE_FORWARD * s * w - FOOT_CENTRE_DOWN * s * d
    return np.stack([out[n] for n in SKELETON_14.joint_names])


def read_init_joints(path, frame: int) -> np.ndarray:
    """Joints (14, 3) of ``frame`` from an ``.npz`` with ``joints`` (T, 14, 3) or (14, 3), metres, world."""
    p = Path(path)
    try:
        with np.load(p) as z:
            j = np.asarray(z["joints"], float)
    except (OSError, ValueError, KeyError) as e:
        raise InputError(str(p), "an .npz file with 'joints' (T, 14, 3) or (14, 3), metres", str(e)) from None
    if j.shape != (14, 3) and (j.ndim != 3 or j.shape[1:] != (14, 3) or not 0 <= frame < len(j)):
        raise InputError(f"{p}: joints", f"shape (T, 14, 3) with frame {frame} in it, or (14, 3)", f"{j.shape}")
    where, j = (f"{p}: joints", j) if j.shape == (14, 3) else (f"{p}: joints[{frame}]", j[frame])
    if not np.isfinite(j).all():
        raise InputError(where, "14 finite joints", f"NaN/inf in {int((~np.isfinite(j)).any(axis=1).sum())}")
    return j


def read_clicks(path, rig):
    """2D joints clicked in two images: ``.npz`` with ``camera_a``, ``camera_b`` (names in ``rig``),
    ``points2d_a``, ``points2d_b`` ((14, 2) pixels) and ``frame``; returns ``(a, b, cam_a, cam_b, frame)``."""
    p = Path(path)
    try:
        with np.load(p) as z:
            a, b = np.asarray(z["points2d_a"], float), np.asarray(z["points2d_b"], float)
            names, frame = (str(z["camera_a"]), str(z["camera_b"])), int(z["frame"])
    except (OSError, ValueError, KeyError) as e:
        raise InputError(str(p), "an .npz with camera_a, camera_b, points2d_a, points2d_b (14, 2) and frame",
                         str(e)) from None
    for n in names:
        if n not in rig.names:
            raise InputError(f"{p}: camera", f"one of {rig.names}", repr(n))
    return a, b, rig[names[0]], rig[names[1]], frame


def stereo_detector():
    """The built-in 2D keypoint detector (:func:`toolkit.detection.make_detector`, BlazePose through MediaPipe)
    for finding the person in the stereo heads' images; raises :class:`InputError` (naming what to install)
    where it cannot run."""
    from toolkit.detection import make_detector

    return make_detector("mediapipe")


def detect_joints(source: "StereoClouds", detector, t: int, cloud=None, previous=None):
    """14 joints of frame ``t`` from the detector's keypoints on each head's reference camera, triangulated
    across the heads (:func:`toolkit.softbody.reinit.triangulate_views`).

    Parameters
    ----------
    source : StereoClouds
    detector : toolkit.detection.PoseDetector
        With the ``blazepose_33`` layout or any of :data:`toolkit.skeleton.mappings.DETECTOR_FORMATS`.
    t : int
        Frame.
    cloud : ndarray of shape (N, 3), optional
        The frame's points, metres: labellings whose joints lie off the body cost more.
    previous : ndarray of shape (14, 3), optional
        Joints of a nearby frame, metres: in each view the person nearest to them is taken (else the most
        confident), and the left and right labels are told apart by them.

    Returns
    -------
    toolkit.softbody.reinit.ViewJoints
    """
    from toolkit.skeleton.mappings import to_skeleton14
    from toolkit.softbody.reinit import triangulate_views

    cams = [h[0] for h in source.heads]
    pts, conf = np.full((len(cams), 14, 2), np.nan), np.zeros((len(cams), 14))
    for c, cam in enumerate(cams):
        people = [to_skeleton14(p.keypoints, detector.layout, confidence=True)
                  for p in detector.detect(source.data.frame(cam.name, t))]
        if not people:
            continue
        k = people[0]
        if previous is not None:
            near = cam.project(np.asarray(previous, float))
            k = min(people, key=lambda q: float(np.nanmedian(np.linalg.norm(q[:, :2] - near, axis=1))))
        pts[c], conf[c] = k[:, :2], np.nan_to_num(k[:, 2])
    return triangulate_views(pts, conf, cams, previous=previous, cloud=cloud)
