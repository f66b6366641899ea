"""The rerun observer: turns observer reports into rerun entities.

This is the only module of the toolkit that logs to rerun.  Algorithms call
``observer.report(kind, **data)`` (see :data:`toolkit.observe.REPORT_KINDS`);
:class:`RerunObserver` maps each kind to rerun archetypes on an explicit
:class:`rerun.RecordingStream` (never the global one), optionally saved to an
``.rrd`` file.  The entity tree is defined in :mod:`toolkit.viz.blueprint` and
described in ``docs/recordings.md``.

Conventions at this edge:

* cameras use OpenCV axes (x right, y down, z forward); the ``Pinhole`` is
  logged with ``camera_xyz = RDF`` so rerun knows it.  Lens distortion is not
  modelled by rerun: 2D overlays match the (distorted) images, 3D data projects
  through the undistorted pinhole.
* rerun's ``Transform3D`` maps child (camera) to parent (world), so the camera
  entity holds ``world_from_cam`` (translation = camera centre, matrix = R^T).
* every report may carry ``frame`` (sets the ``frame`` sequence timeline, which
  stays set for later reports) and ``static`` (log without time).
"""

from __future__ import annotations

import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import rerun as rr

from toolkit.errors import InputError, ToolkitError, check_shape
from toolkit.skeleton import SKELETON_14, Skeleton
from toolkit.viz.blueprint import (
    CAMS,
    LOGS,
    METRICS,
    REPORTS,
    WORLD,
    camera_path,
    entity_path,
    image_path,
    make_blueprint,
)

#: Name of the sequence timeline that frames are logged on.
FRAME_TIMELINE = "frame"

#: Keypoint colours (RGB) by body side, so left/right swaps are visible at a glance.
LEFT_COLOR = (60, 180, 75)
RIGHT_COLOR = (230, 25, 75)
CENTRE_COLOR = (255, 225, 25)
#: Bone colours of successive registered skeletons.
SKELETON_COLORS = ((0, 130, 200), (245, 130, 48), (145, 30, 180), (70, 240, 240))
#: Part-label colours; label id ``1 + i`` gets ``PART_COLORS[i % len]``
#: (for SKELETON_14: head, torso, l_upper_arm, l_forearm, r_upper_arm,
#: r_forearm, l_thigh, l_shank, r_thigh, r_shank).
PART_COLORS = ((255, 225, 25), (0, 130, 200), (60, 180, 75), (170, 255, 195), (230, 25, 75),
               (250, 190, 212), (128, 128, 0), (210, 245, 60), (128, 0, 0), (255, 215, 180))
#: Foreground colour of binary masks.
MASK_COLOR = (255, 0, 255)
#: Colour of untextured quads without ``colors``.
QUAD_COLOR = (180, 180, 180)
#: Report kinds logged static unless the report says ``static=False``.
STATIC_KINDS = frozenset({"rig", "skeleton"})
#: Longest field text of a generic (unknown-kind) report line.
GENERIC_TEXT_CHARS = 200


@dataclass(frozen=True)
class RerunConfig:
    """How reports are drawn and stored.

    Parameters
    ----------
    compress_images : bool
        JPEG-encode 8-bit RGB / grey images of at least ``compress_min_pixels``.
    jpeg_quality : int
        JPEG quality, 1..100.
    compress_min_pixels : int
        Images smaller than this (``H * W``) are stored raw.
    depth_png : bool
        Store depth maps of at least ``compress_min_pixels`` as 16-bit PNG
        (lossless at ``1 / depth_png_units_per_metre``; beyond 65535 units
        becomes "no depth").
    depth_png_units_per_metre : float
        Depth units per metre of the PNG (1000 = millimetres).
    joint_radius_m : float
        Radius of 3D joints, metres.
    keypoint_radius_px : float
        Radius of 2D keypoints and points, pixels.
    point_radius_m : float
        Default radius of 3D points, metres.
    ray_radius_m : float
        Radius of rays and 3D lines, metres.
    overlay_opacity : float
        Opacity of masks and part-label images over the camera image.
    image_plane_distance_m : float or None
        Depth at which the viewer draws camera frusta and images (None: rerun's choice).
    auto_blueprint : bool
        Send the default blueprint on the first ``rig`` report if none was sent.
    """

    compress_images: bool = True
    jpeg_quality: int = 90
    compress_min_pixels: int = 64 * 64
    depth_png: bool = True
    depth_png_units_per_metre: float = 1000.0
    joint_radius_m: float = 0.02
    keypoint_radius_px: float = 3.0
    point_radius_m: float = 0.005
    ray_radius_m: float = 0.002
    overlay_opacity: float = 0.5
    image_plane_distance_m: float | None = 0.5
    auto_blueprint: bool = True

    def __post_init__(self):
        if not 1 <= int(self.jpeg_quality) <= 100:
            raise InputError("RerunConfig.jpeg_quality", "an int in 1..100", f"{self.jpeg_quality}")
        if self.depth_png_units_per_metre <= 0:
            raise InputError("RerunConfig.depth_png_units_per_metre", "> 0",
                             f"{self.depth_png_units_per_metre}")
        if not 0.0 <= self.overlay_opacity <= 1.0:
            raise InputError("RerunConfig.overlay_opacity", "a value in [0, 1]", f"{self.overlay_opacity}")


def _check_writable(path: str | Path) -> Path:
    """Make sure ``path`` can be written, creating missing parent directories.

    Raises :class:`InputError` naming the path otherwise.
    """
    p = Path(path).expanduser()
    where = f"RerunObserver: path {str(p)!r}"
    if p.is_dir():
        raise InputError(where, "a file path for the .rrd recording", "an existing directory")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(where, f"a creatable directory {str(p.parent)!r}",
                         f"{type(e).__name__}: {e}") from None
    existed = p.exists()
    try:
        with open(p, "ab"):
            pass
    except OSError as e:
        raise InputError(where, "a writable file", f"{type(e).__name__}: {e}") from None
    if not existed:
        p.unlink()
    return p


def _side_color(joint_name: str) -> tuple[int, int, int]:
    if joint_name.startswith("l_"):
        return LEFT_COLOR
    if joint_name.startswith("r_"):
        return RIGHT_COLOR
    return CENTRE_COLOR


def _camera_name(kind: str, data: Mapping[str, Any]) -> str:
    cam = data.get("camera")
    if cam is None:
        raise InputError(f"report {kind!r}: camera", "a camera name", "nothing")
    name = getattr(cam, "name", cam)
    if not isinstance(name, str) or not name:
        raise InputError(f"report {kind!r}: camera", "a non-empty camera name", f"{cam!r}")
    return name


def _field(kind: str, data: Mapping[str, Any], key: str) -> Any:
    if key not in data or data[key] is None:
        raise InputError(f"report {kind!r}: {key}", "a value", "nothing")
    return data[key]


def _array(kind: str, data: Mapping[str, Any], key: str, shape: tuple, dtype=np.float64) -> np.ndarray:
    arr = np.asarray(_field(kind, data, key))
    check_shape(f"report {kind!r}: {key}", arr, shape)
    try:
        return arr.astype(dtype, copy=False)
    except (TypeError, ValueError):
        raise InputError(f"report {kind!r}: {key}", f"values convertible to {np.dtype(dtype)}",
                         f"dtype {arr.dtype}") from None


def _colors(kind: str, data: Mapping[str, Any], key: str, n: int) -> np.ndarray | None:
    """Optional uint8 colours, (3,) / (4,) for all or (n, 3|4) per item."""
    if data.get(key) is None:
        return None
    c = np.asarray(data[key])
    if c.ndim == 1 and c.shape[0] in (3, 4):
        c = np.broadcast_to(c, (n, c.shape[0]))
    if c.ndim != 2 or c.shape[0] != n or c.shape[1] not in (3, 4):
        raise InputError(f"report {kind!r}: {key}", f"(3,) or ({n}, 3) colours", f"shape {c.shape}")
    if np.issubdtype(c.dtype, np.floating):
        c = np.clip(np.round(c * 255.0), 0, 255)
    return c.astype(np.uint8)


def _image_uint8(kind: str, key: str, img: np.ndarray) -> np.ndarray:
    """uint8 image from uint8 or float in [0, 1] (scaled by 255)."""
    if img.dtype == np.uint8:
        return img
    if img.dtype == bool:
        return img.astype(np.uint8) * 255
    if np.issubdtype(img.dtype, np.floating):
        return np.clip(np.round(np.nan_to_num(img) * 255.0), 0, 255).astype(np.uint8)
    raise InputError(f"report {kind!r}: {key}", "uint8 or float in [0, 1]", f"dtype {img.dtype}")


def _pack_atlas(textures: list[np.ndarray], max_width: int = 4096) -> tuple[np.ndarray, list[tuple]]:
    """Shelf-pack RGB textures into one atlas.

    Returns the atlas (H, W, 3) and per texture its (x0, y0, w, h) pixel rectangle.
    """
    rects, x, y, row_h, width = [], 0, 0, 0, 0
    for t in textures:
        h, w = t.shape[:2]
        if x > 0 and x + w > max_width:
            x, y, row_h = 0, y + row_h, 0
        rects.append((x, y, w, h))
        x += w
        row_h = max(row_h, h)
        width = max(width, x)
    atlas = np.zeros((y + row_h, width, 3), np.uint8)
    for t, (x0, y0, w, h) in zip(textures, rects):
        atlas[y0:y0 + h, x0:x0 + w] = t[..., :3]
    return atlas, rects


class RerunObserver:
    """An observer that logs every report to a rerun recording.

    Parameters
    ----------
    recording : rerun.RecordingStream, optional
        Stream to log to.  When None a new, non-global stream is created; with
        neither ``recording`` nor ``path`` the data stays in the stream's buffer
        until you attach a sink (``observer.recording.spawn()``, ``serve_grpc()``).
    application_id : str
        Application id of a newly created stream (recordings are grouped by it).
    path : str or Path, optional
        Save the recording to this ``.rrd`` file.  Checked for writability
        before anything is logged; missing parent directories are created.
    camera_names : sequence of str, optional
        Send :func:`toolkit.viz.blueprint.make_blueprint` for these cameras now.
    config : RerunConfig, optional
    recording_id : str or uuid.UUID, optional
        Recording id of a newly created stream (default: a random one).  Files
        written with the same application and recording id open as one
        recording in the viewer (e.g. the parts of a resumed run).

    Raises
    ------
    InputError
        If ``path`` is a directory or cannot be written.

    Examples
    --------
    >>> with RerunObserver(path="out/run.rrd", camera_names=rig.names) as obs:  # doctest: +SKIP
    ...     obs.report("rig", rig=rig)
    ...     fit_pose(..., observer=obs)
    """

    def __init__(self, recording: rr.RecordingStream | None = None, *, application_id: str = "toolkit",
                 path: str | Path | None = None, camera_names=None, config: RerunConfig | None = None,
                 recording_id: str | uuid.UUID | None = None):
        self.config = config if config is not None else RerunConfig()
        self.path = _check_writable(path) if path is not None else None
        self._owns_stream = recording is None
        self.recording = recording if recording is not None else rr.RecordingStream(
            application_id, recording_id=recording_id if recording_id is not None else uuid.uuid4())
        if self.path is not None:
            try:
                self.recording.save(self.path)
            except RuntimeError as e:
                raise InputError(f"RerunObserver: path {str(self.path)!r}", "a writable .rrd file",
                                 str(e)) from None
        self.frame: int | None = None
        self.closed = False
        self._blueprint_sent = False
        self._cam_roots: dict[str, str] = {}
        self._skeleton_ids: dict[str, int] = {}
        self._skeletons: dict[str, Skeleton] = {}
        self._contexts: set[str] = set()
        self._handlers = {
            "rig": self._rig, "skeleton": self._skeleton, "image": self._image, "mask": self._mask,
            "labels": self._labels, "depth": self._depth, "joints2d": self._joints2d,
            "joints3d": self._joints3d, "points2d": self._points2d, "points3d": self._points3d,
            "rays": self._rays, "lines2d": self._lines2d, "lines3d": self._lines3d,
            "scalar": self._scalar, "series": self._series, "text": self._text, "mesh": self._mesh, "boxes2d": self._boxes2d,
            "quads": self._quads,
        }
        self._log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        if camera_names is not None:
            self.send_blueprint(camera_names=camera_names)

    # ---------------------------------------------------------------- control
    @property
    def kinds(self) -> frozenset[str]:
        """Report kinds with a dedicated mapping (others are logged generically)."""
        return frozenset(self._handlers)

    @property
    def skeleton_class_ids(self) -> dict[str, int]:
        """Class id of every registered skeleton, by skeleton name."""
        return dict(self._skeleton_ids)

    def set_frame(self, frame: int) -> None:
        """Set the ``frame`` sequence timeline for the following reports."""
        try:
            i = int(frame)
        except (TypeError, ValueError):
            raise InputError("frame", "an integer frame index", f"{frame!r}") from None
        if i != frame:
            raise InputError("frame", "an integer frame index", f"{frame!r}")
        self.frame = i
        self.recording.set_time(FRAME_TIMELINE, sequence=i)

    def send_blueprint(self, blueprint=None, *, camera_names=None, extra_2d=(), include_metrics: bool = True,
                       cams_root: str = CAMS) -> None:
        """Send a viewer layout with the recording.

        Parameters
        ----------
        blueprint : rerun.blueprint.Blueprint, optional
            Layout to send; by default :func:`make_blueprint` of ``camera_names``
            (or of the cameras of the ``rig`` reports seen so far).
        camera_names, extra_2d, include_metrics, cams_root
            Passed to :func:`make_blueprint`.
        """
        self._check_open()
        if blueprint is None:
            names = list(camera_names) if camera_names is not None else list(self._cam_roots)
            blueprint = make_blueprint(names, extra_2d=extra_2d, include_metrics=include_metrics,
                                       cams_root=cams_root)
        self.recording.send_blueprint(blueprint)
        self._blueprint_sent = True

    def flush(self) -> None:
        """Write everything logged so far to the sinks."""
        self.recording.flush()

    def close(self) -> None:
        """Flush and finalise the recording (the ``.rrd`` file is complete afterwards).

        Closes the stream's sinks when this observer created the stream or
        opened the file; a caller's stream without ``path`` is only flushed.
        Calling ``close`` again does nothing.
        """
        if self.closed:
            return
        self.recording.flush()
        if self._owns_stream or self.path is not None:
            self.recording.disconnect()
        self.closed = True

    def __enter__(self) -> "RerunObserver":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _check_open(self) -> None:
        if self.closed:
            where = f" ({self.path})" if self.path is not None else ""
            raise ToolkitError(f"RerunObserver{where} is closed; create a new one to log more")

    def _log(self, path: str, *archetypes, static: bool = False) -> None:
        self.recording.log(path, *archetypes, static=static, strict=True)

    # ----------------------------------------------------------------- report
    def report(self, kind: str, **data: Any) -> None:
        """Log one report (see :data:`toolkit.observe.REPORT_KINDS` for kinds and fields).

        Unknown kinds are logged generically: numbers as scalars under
        ``metrics/<kind>/<field>``, arrays as tensors under
        ``reports/<kind>/<field>``, and one text line under ``logs/reports/<kind>``.

        Raises
        ------
        InputError
            If a field of a known kind is missing or has the wrong shape.
        """
        self._check_open()
        if data.get("frame") is not None:
            self.set_frame(data["frame"])
        static = bool(data.get("static", kind in STATIC_KINDS))
        handler = self._handlers.get(kind)
        if handler is None:
            self._generic(kind, data, static)
        else:
            handler(kind, data, static)

    # --------------------------------------------------------------- helpers
    def _image_path(self, kind: str, data: Mapping[str, Any], default_name: str) -> str:
        cam = _camera_name(kind, data)
        base = image_path(cam, self._cam_roots.get(cam, CAMS))
        name = data.get("name") or default_name
        return base if name == "image" else f"{base}/{entity_path(name)}"

    def _world_path(self, kind: str, data: Mapping[str, Any]) -> str:
        return entity_path(WORLD, data.get("name") or kind)

    def _context_once(self, path: str, classes: list) -> None:
        """Static annotation context at ``path`` (logged once per path)."""
        if path not in self._contexts:
            self._log(path, rr.AnnotationContext(classes), static=True)
            self._contexts.add(path)

    def _skeleton_class(self, skeleton: Skeleton, class_id: int | None = None) -> int:
        """Class id of ``skeleton``, registering it (root annotation context) on first use."""
        if not isinstance(skeleton, Skeleton):
            raise InputError("report: skeleton", "a toolkit.skeleton.Skeleton", f"{type(skeleton).__name__}")
        known = self._skeleton_ids.get(skeleton.name)
        if known is not None and (class_id is None or class_id == known):
            return known
        if class_id is None:
            class_id = max(self._skeleton_ids.values(), default=0) + 1
        class_id = int(class_id)
        if class_id < 0 or class_id > 65535:
            raise InputError("report 'skeleton': class_id", "an int in 0..65535", f"{class_id}")
        other = [n for n, c in self._skeleton_ids.items() if c == class_id and n != skeleton.name]
        if other:
            raise InputError("report 'skeleton': class_id", f"an id not used by skeleton {other[0]!r}",
                             f"{class_id}")
        self._skeleton_ids[skeleton.name] = class_id
        self._skeletons[skeleton.name] = skeleton
        classes = []
        for i, (name, cid) in enumerate(self._skeleton_ids.items()):
            sk = self._skeletons[name]
            color = SKELETON_COLORS[i % len(SKELETON_COLORS)]
            classes.append(rr.ClassDescription(
                info=rr.AnnotationInfo(id=cid, label=sk.name, color=color),
                keypoint_annotations=[rr.AnnotationInfo(id=j, label=jn, color=_side_color(jn))
                                      for j, jn in enumerate(sk.joint_names)],
                keypoint_connections=list(sk.edges)))
        # Root context: every joints entity under world/ (3D and 2D) inherits it.
        self._log("/", rr.AnnotationContext(classes), static=True)
        return class_id

    def _keypoints(self, kind: str, data: Mapping[str, Any], dim: int):
        joints = _array(kind, data, "joints", (None, dim))
        ids = np.arange(len(joints))
        sk = data.get("skeleton")
        cls = None
        if sk is not None:
            if len(joints) != getattr(sk, "n_joints", len(joints)):
                raise InputError(f"report {kind!r}: joints", f"{sk.n_joints} joints of skeleton {sk.name}",
                                 f"{len(joints)}")
            cls = self._skeleton_class(sk)
        ok = np.all(np.isfinite(joints), axis=1)
        return joints[ok], ids[ok], cls

    # ------------------------------------------------------------ kind: setup
    def _rig(self, kind, data, static):
        rig = _field(kind, data, "rig")
        root = data.get("path") or CAMS
        cfg = self.config
        for cam in rig:
            self._cam_roots[cam.name] = root
            # rerun's Transform3D maps child (camera) to parent (world): log world_from_cam.
            self._log(camera_path(cam.name, root),
                      rr.Transform3D(translation=cam.center, mat3x3=cam.R.T), static=static)
            self._log(image_path(cam.name, root),
                      rr.Pinhole(image_from_camera=cam.K, resolution=list(cam.size),
                                 camera_xyz=rr.ViewCoordinates.RDF,  # OpenCV axes
                                 image_plane_distance=cfg.image_plane_distance_m), static=static)
        if cfg.auto_blueprint and not self._blueprint_sent:
            self.send_blueprint(cams_root=root)

    def _skeleton(self, kind, data, static):
        self._skeleton_class(_field(kind, data, "skeleton"), data.get("class_id"))

    # ----------------------------------------------------------- kind: images
    def _image(self, kind, data, static):
        img = np.asarray(_field(kind, data, "image"))
        if not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] in (1, 3, 4))):
            raise InputError(f"report {kind!r}: image", "(H, W), (H, W, 3) or (H, W, 4)",
                             f"shape {img.shape}")
        img = _image_uint8(kind, "image", img)
        if img.ndim == 3 and img.shape[2] == 1:
            img = img[..., 0]
        cfg = self.config
        path = self._image_path(kind, data, "image")
        channels = 1 if img.ndim == 2 else img.shape[2]
        large = img.shape[0] * img.shape[1] >= cfg.compress_min_pixels
        if cfg.compress_images and channels in (1, 3) and large:
            bgr = img if channels == 1 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
            ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(cfg.jpeg_quality)])
            if not ok:
                raise ToolkitError(f"JPEG encoding of {path} ({img.shape}) failed")
            self._log(path, rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg"), static=static)
        else:
            model = {1: "L", 3: "RGB", 4: "RGBA"}[channels]
            self._log(path, rr.Image(img, color_model=model), static=static)

    def _mask(self, kind, data, static):
        mask = np.asarray(_field(kind, data, "mask"))
        check_shape(f"report {kind!r}: mask", mask, (None, None))
        path = self._image_path(kind, data, "mask")
        values = np.unique(mask) if mask.dtype != bool else np.array([0, 1])
        if mask.dtype == bool or np.isin(values, (0, 1, 255)).all():
            self._context_once(path, [rr.AnnotationInfo(id=0, label="background", color=(0, 0, 0, 0)),
                                      rr.AnnotationInfo(id=1, label="foreground", color=MASK_COLOR)])
            seg = (mask > 0).astype(np.uint8)
            self._log(path, rr.SegmentationImage(seg, opacity=self.config.overlay_opacity), static=static)
        else:  # a soft matte: grey levels
            grey = _image_uint8(kind, "mask", mask)
            self._log(path, rr.Image(grey, color_model="L", opacity=self.config.overlay_opacity),
                      static=static)

    def _labels(self, kind, data, static):
        labels = np.asarray(_field(kind, data, "labels"))
        check_shape(f"report {kind!r}: labels", labels, (None, None))
        if not np.issubdtype(labels.dtype, np.integer):
            raise InputError(f"report {kind!r}: labels", "integer part ids", f"dtype {labels.dtype}")
        sk = data.get("skeleton") or SKELETON_14
        path = self._image_path(kind, data, "labels")
        classes = [rr.AnnotationInfo(id=0, label="background", color=(0, 0, 0, 0))]
        classes += [rr.AnnotationInfo(id=1 + i, label=p, color=PART_COLORS[i % len(PART_COLORS)])
                    for i, p in enumerate(sk.part_names)]
        self._context_once(path, classes)
        dtype = np.uint8 if labels.max(initial=0) < 256 and labels.min(initial=0) >= 0 else np.uint16
        self._log(path, rr.SegmentationImage(labels.astype(dtype), opacity=self.config.overlay_opacity),
                  static=static)

    def _depth(self, kind, data, static):
        depth = np.asarray(_field(kind, data, "depth"))
        check_shape(f"report {kind!r}: depth", depth, (None, None))
        if not np.issubdtype(depth.dtype, np.floating):
            raise InputError(f"report {kind!r}: depth", "float metres", f"dtype {depth.dtype}")
        d = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0)
        cfg = self.config
        path = self._image_path(kind, data, "depth")
        if cfg.depth_png and d.size >= cfg.compress_min_pixels:
            units = np.round(d * cfg.depth_png_units_per_metre)
            units[units > np.iinfo(np.uint16).max] = 0
            ok, buf = cv2.imencode(".png", units.astype(np.uint16))
            if not ok:
                raise ToolkitError(f"PNG encoding of {path} ({d.shape}) failed")
            self._log(path, rr.EncodedDepthImage(blob=buf.tobytes(), media_type="image/png",
                                                 meter=cfg.depth_png_units_per_metre), static=static)
        else:
            self._log(path, rr.DepthImage(d.astype(np.float32), meter=1.0), static=static)

    # ------------------------------------------------------- kind: 2D overlay
    def _joints2d(self, kind, data, static):
        joints, ids, cls = self._keypoints(kind, data, 2)
        self._log(self._image_path(kind, data, "joints"),
                  rr.Points2D(joints, keypoint_ids=ids, class_ids=cls, radii=self.config.keypoint_radius_px),
                  static=static)

    def _points2d(self, kind, data, static):
        pts = _array(kind, data, "points", (None, 2))
        ok = np.all(np.isfinite(pts), axis=1)
        colors = _colors(kind, data, "colors", len(pts))
        self._log(self._image_path(kind, data, "points"),
                  rr.Points2D(pts[ok], colors=None if colors is None else colors[ok],
                              radii=self.config.keypoint_radius_px), static=static)

    def _lines2d(self, kind, data, static):
        strips = [np.asarray(s, float) for s in _field(kind, data, "strips")]
        for i, s in enumerate(strips):
            check_shape(f"report {kind!r}: strips[{i}]", s, (None, 2))
        colors = _colors(kind, data, "colors", len(strips))
        self._log(self._image_path(kind, data, "lines"), rr.LineStrips2D(strips, colors=colors),
                  static=static)

    def _boxes2d(self, kind, data, static):
        mins = _array(kind, data, "mins", (None, 2))
        sizes = _array(kind, data, "sizes", (len(mins), 2))
        labels = data.get("labels")
        if labels is not None:
            labels = [str(s) for s in labels]
            if len(labels) != len(mins):
                raise InputError(f"report {kind!r}: labels", f"{len(mins)} labels", f"{len(labels)}")
        self._log(self._image_path(kind, data, "boxes"),
                  rr.Boxes2D(mins=mins, sizes=sizes, labels=labels,
                             colors=_colors(kind, data, "colors", len(mins))),
                  static=static)

    # ------------------------------------------------------------- kind: 3D
    def _joints3d(self, kind, data, static):
        joints, ids, cls = self._keypoints(kind, data, 3)
        self._log(self._world_path(kind, data),
                  rr.Points3D(joints, keypoint_ids=ids, class_ids=cls, radii=self.config.joint_radius_m),
                  static=static)

    def _points3d(self, kind, data, static):
        pts = _array(kind, data, "points", (None, 3))
        ok = np.all(np.isfinite(pts), axis=1)
        colors = _colors(kind, data, "colors", len(pts))
        radii = data.get("radii")
        radii = self.config.point_radius_m if radii is None else np.broadcast_to(
            np.asarray(radii, float), (len(pts),))[ok]
        self._log(self._world_path(kind, data),
                  rr.Points3D(pts[ok], colors=None if colors is None else colors[ok], radii=radii),
                  static=static)

    def _rays(self, kind, data, static):
        origins = _array(kind, data, "origins", (None, 3))
        ends = _array(kind, data, "ends", (len(origins), 3))
        ok = np.all(np.isfinite(origins), axis=1) & np.all(np.isfinite(ends), axis=1)
        colors = _colors(kind, data, "colors", len(origins))
        self._log(self._world_path(kind, data),
                  rr.LineStrips3D(np.stack([origins[ok], ends[ok]], axis=1), radii=self.config.ray_radius_m,
                                  colors=None if colors is None else colors[ok]), static=static)

    def _lines3d(self, kind, data, static):
        strips = [np.asarray(s, float) for s in _field(kind, data, "strips")]
        for i, s in enumerate(strips):
            check_shape(f"report {kind!r}: strips[{i}]", s, (None, 3))
        self._log(self._world_path(kind, data),
                  rr.LineStrips3D(strips, radii=self.config.ray_radius_m,
                                  colors=_colors(kind, data, "colors", len(strips))), static=static)

    def _mesh(self, kind, data, static):
        vertices = _array(kind, data, "vertices", (None, 3), np.float32)
        triangles = _array(kind, data, "triangles", (None, 3), np.int64)
        if triangles.size and (triangles.min() < 0 or triangles.max() >= len(vertices)):
            raise InputError(f"report {kind!r}: triangles", f"vertex indices in 0..{len(vertices) - 1}",
                             f"range {triangles.min()}..{triangles.max()}")
        path = self._world_path(kind, data)
        if len(triangles) == 0:
            self._log(path, rr.Clear(recursive=False), static=static)
            return
        normals = data.get("vertex_normals")
        if normals is not None:
            normals = _array(kind, data, "vertex_normals", (len(vertices), 3), np.float32)
        self._log(path, rr.Mesh3D(vertex_positions=vertices, triangle_indices=triangles.astype(np.uint32),
                                  vertex_normals=normals,
                                  vertex_colors=_colors(kind, data, "vertex_colors", len(vertices))),
                  static=static)

    def _quads(self, kind, data, static):
        corners = _array(kind, data, "corners", (None, 4, 3), np.float32)
        n = len(corners)
        path = self._world_path(kind, data)
        if n == 0:
            self._log(path, rr.Clear(recursive=False), static=static)
            return
        # corners: top-left, top-right, bottom-right, bottom-left of each texture
        vertices = corners.reshape(-1, 3)
        base = 4 * np.arange(n, dtype=np.uint32)[:, None, None]
        triangles = (base + np.array([[0, 1, 2], [0, 2, 3]], np.uint32)).reshape(-1, 3)
        textures = data.get("textures")
        if textures is None:
            colors = _colors(kind, data, "colors", n)
            colors = np.broadcast_to(np.array(QUAD_COLOR, np.uint8), (n, 3)) if colors is None else colors
            self._log(path, rr.Mesh3D(vertex_positions=vertices, triangle_indices=triangles,
                                      vertex_colors=np.repeat(colors, 4, axis=0)), static=static)
            return
        textures = [np.asarray(t) for t in textures]
        if len(textures) != n:
            raise InputError(f"report {kind!r}: textures", f"{n} textures (one per quad)", f"{len(textures)}")
        for i, t in enumerate(textures):
            if t.ndim != 3 or t.shape[2] not in (3, 4) or t.shape[0] == 0 or t.shape[1] == 0:
                raise InputError(f"report {kind!r}: textures[{i}]", "(h, w, 3) or (h, w, 4)",
                                 f"shape {t.shape}")
        textures = [_image_uint8(kind, "textures", t) for t in textures]
        atlas, rects = _pack_atlas(textures)
        H, W = atlas.shape[:2]
        uv = []
        for x0, y0, w, h in rects:  # inset half a texel so neighbours do not bleed in
            u0, u1 = (x0 + 0.5) / W, (x0 + w - 0.5) / W
            v0, v1 = (y0 + 0.5) / H, (y0 + h - 0.5) / H
            uv += [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]
        self._log(path, rr.Mesh3D(vertex_positions=vertices, triangle_indices=triangles,
                                  vertex_texcoords=np.array(uv, np.float32), albedo_texture=atlas),
                  static=static)

    # ------------------------------------------------------------ kind: misc
    def _scalar(self, kind, data, static):
        name = _field(kind, data, "name")
        raw = _field(kind, data, "value")
        try:
            value = float(raw)
        except (TypeError, ValueError):
            raise InputError(f"report {kind!r}: value", "a number", f"{raw!r}") from None
        self._log(entity_path(METRICS, name), rr.Scalars(value), static=static)

    def _series(self, kind, data, static):
        """A curve over iterations (e.g. a joint's score per sweep) as a bar chart at the current frame."""
        name = _field(kind, data, "name")
        values = np.asarray(_field(kind, data, "values"), dtype=np.float64).ravel()
        if values.size == 0:
            raise InputError(f"report {kind!r}: values", "a non-empty 1-D array of numbers", "an empty array")
        self._log(entity_path(METRICS, name), rr.BarChart(values), static=static)

    def _text(self, kind, data, static):
        text = _field(kind, data, "text")
        level = data.get("level")
        self._log(entity_path(LOGS, data.get("name") or "text"),
                  rr.TextLog(str(text), level=None if level is None else str(level)), static=static)

    def _generic(self, kind, data, static):
        """Unknown kind: scalars to metrics, numeric arrays as tensors, a text line with everything."""
        if not isinstance(kind, str) or not kind.strip("/"):
            raise InputError("report: kind", "a non-empty str", f"{kind!r}")
        cam = data.get("camera")
        sub = [kind] if cam is None else [kind, str(getattr(cam, "name", cam))]
        parts = []
        for key in sorted(data):
            if key in ("frame", "static", "camera"):
                continue
            value = data[key]
            arr = None
            if isinstance(value, (np.ndarray, np.generic, int, float, list, tuple)):
                try:
                    arr = np.asarray(value)
                except ValueError:  # ragged nested lists
                    arr = None
            numeric = arr is not None and (np.issubdtype(arr.dtype, np.integer)
                                           or np.issubdtype(arr.dtype, np.floating) or arr.dtype == bool)
            if numeric and arr.ndim == 0:
                self._log(entity_path(METRICS, *sub, key), rr.Scalars(float(arr)), static=static)
                parts.append(f"{key}={float(arr):g}")
            elif numeric and arr.size > 0:
                t = arr.astype(np.uint8) if arr.dtype == bool else arr
                self._log(entity_path(REPORTS, *sub, key), rr.Tensor(t), static=static)
                parts.append(f"{key}=array{arr.shape} {arr.dtype}")
            else:
                text = repr(value)
                if len(text) > GENERIC_TEXT_CHARS:
                    text = text[:GENERIC_TEXT_CHARS] + "..."
                parts.append(f"{key}={text}")
        self._log(entity_path(LOGS, REPORTS, *sub), rr.TextLog(f"{kind}: " + ", ".join(parts), level="DEBUG"),
                  static=static)
