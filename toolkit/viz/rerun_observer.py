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

import dataclasses
import os
import uuid
from collections.abc import Mapping
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
    STAGE_TABS,
    SUBJECT_CROP,
    VIEW_BOUNDS_MARGIN,
    image_path,
    make_blueprint,
    subject_eye,
)
from toolkit.viz.fields import (
    _array,
    _camera_name,
    _check_writable,
    _colors,
    _field,
    _image_uint8,
    _pack_atlas,
    _side_color,
)
from toolkit.viz.style import (
    GENERIC_TEXT_CHARS,
    MASK_COLOR,
    PART_COLORS,
    QUAD_COLOR,
    SKELETON_COLORS,
    STATIC_KINDS,
    RerunConfig,
)

#: Name of the sequence timeline that frames are logged on.
FRAME_TIMELINE = "frame"
#: Pixels added around a colour image's subject crop (beyond ``RerunConfig.crop_margin``).
CROP_PAD_PX = 8
#: A crop is stored only when it keeps at most this fraction of the image's pixels.
CROP_MAX_FRACTION = 0.5
#: Draw order of the subject crop: above the camera image (rerun's default -10), below masks (0).
SUBJECT_DRAW_ORDER = -9.0
#: Longest time the compaction of a saved recording may take, seconds.
COMPACT_TIMEOUT_S = 300
#: Frames between two full camera images at most (a moving camera's background stays current).
KEYFRAME_INTERVAL = 25


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
    parts : bool
        Write ``path`` in parts that are each a complete file: while the
        recording is open it is the folder ``<path without .rrd>.parts/``,
        ``NNNNNN.rrd`` one part per :meth:`checkpoint` (the part being written
        is ``.NNNNNN.rrd.partial``); :meth:`close` merges them into ``path``.
        A process killed outright (SIGKILL) leaves every part but the last
        one complete (``rerun rrd verify`` accepts them; :func:`finish_parts`
        merges them).

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
                 recording_id: str | uuid.UUID | None = None, parts: bool = False):
        self.config = config if config is not None else RerunConfig()
        self.path = _check_writable(path) if path is not None else None
        self._owns_stream = recording is None
        self.recording = recording if recording is not None else rr.RecordingStream(
            application_id, recording_id=recording_id if recording_id is not None else uuid.uuid4())
        self._parts = parts_folder(self.path) if parts and self.path is not None else None
        self._part = 0
        if self._parts is not None:
            self._parts.mkdir(parents=True, exist_ok=True)
            self._part = len(list(self._parts.glob("*.rrd")))
        if self.path is not None:
            try:
                self.recording.save(self.path if self._parts is None else self._part_file(self._part, True))
            except RuntimeError as e:
                raise InputError(f"RerunObserver: path {str(self.path)!r}", "a writable .rrd file",
                                 str(e)) from None
        self.frame: int | None = None
        self.closed = False
        self._saved = False  # the file at path was finalised by close
        self._blueprint_sent = False
        self._cam_roots: dict[str, str] = {}
        self._skeleton_ids: dict[str, int] = {}
        self._skeletons: dict[str, Skeleton] = {}
        self._skeleton_colors: dict[str, tuple] = {}  # classes of a skeleton drawn in a given colour
        self._contexts: set[str] = set()
        self._bp_args: dict | None = None  # arguments of the default blueprint sent (None: the caller's own)
        self._last_blueprint = None  # the layout sent last: the one the compacted file keeps
        self._overlays: dict[str, set[str]] = {}  # camera -> overlay names seen (first name segment)
        self._cameras: dict = {}  # camera name -> Camera, from rig reports
        self._subject: dict[int | None, np.ndarray] = {}  # frame -> the 3D joints reported in it (all people)
        self._keys: dict[str, tuple[int | None, tuple | None]] = {}  # camera -> last full image: frame, subject box
        self._eye = None
        self._view_bounds: dict[str, list[float]] | None = None
        self._crop_paths: set[str] = set()
        self._bp_dirty = False
        self._handlers = {
            "rig": self._rig, "skeleton": self._skeleton, "image": self._image, "mask": self._mask,
            "labels": self._labels, "depth": self._depth, "joints2d": self._joints2d,
            "joints3d": self._joints3d, "points2d": self._points2d, "points3d": self._points3d,
            "rays": self._rays, "lines2d": self._lines2d, "lines3d": self._lines3d,
            "scalar": self._scalar, "series": self._series, "text": self._text, "mesh": self._mesh, "boxes2d": self._boxes2d,
            "quads": self._quads, "depth_energy": self._depth_energy, "depth_move": self._depth_move,
            "depth_radial": self._depth_radial, "silhouette": self._silhouette,
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
        if self._bp_dirty and i != self.frame and not self.closed:
            self._refresh_blueprint(now=True)
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
            self._bp_args = dict(camera_names=names, extra_2d=tuple(extra_2d), include_metrics=include_metrics,
                                 cams_root=cams_root)
            blueprint = make_blueprint(**self._bp_args, overlays=self._overlays, eye=self._eye,
                                       subject_boxes=self._view_bounds)
        else:
            self._bp_args = None
        self.recording.send_blueprint(blueprint)
        self._last_blueprint = blueprint
        self._blueprint_sent = True

    def _refresh_blueprint(self, now: bool = False) -> None:
        """Send the default blueprint again with what was learnt (stage overlays, the subject's place):
        when the frame changes or the recording closes (a blueprint is ~20 chunks: not once per report)."""
        if self._bp_args is None or not self.config.auto_blueprint:
            return
        if not now:
            self._bp_dirty = True
            return
        self._bp_dirty = False
        names = self._bp_args["camera_names"]
        self._bp_args["camera_names"] = names + [c for c in self._cam_roots if c not in names]
        self._last_blueprint = make_blueprint(**self._bp_args, overlays=self._overlays, eye=self._eye,
                                              subject_boxes=self._view_bounds)
        self.recording.send_blueprint(self._last_blueprint)

    def flush(self) -> None:
        """Write everything logged so far to the sinks."""
        self.recording.flush()

    def _part_file(self, k: int, partial: bool = False) -> Path:
        return self._parts / (f".{k:06d}.rrd.partial" if partial else f"{k:06d}.rrd")

    def checkpoint(self) -> None:
        """End the recording's current part (a complete file from now on) and go on in a new one.

        Without ``parts`` only flushes.  Called by a run after each frame
        (:func:`toolkit.pipeline.run.run_frames`).
        """
        self._check_open()
        if self._parts is None:
            self.recording.flush()
            return
        if self._bp_dirty:
            self._refresh_blueprint(now=True)
        self.recording.flush()
        done = self._part_file(self._part, True)
        self._part += 1
        self.recording.save(self._part_file(self._part, True))  # the file before is finished (footer)
        os.replace(done, self._part_file(self._part - 1))

    @property
    def saved(self) -> Path | None:
        """The finished ``.rrd`` file once :meth:`close` wrote it, else None (still open, written in parts
        that were not merged, dropped, or no ``path``): the only file a run may offer as openable."""
        return self.path if self.closed and self._saved and self.path.is_file() else None

    def close(self, keep: bool = True) -> None:
        """Flush and finalise the recording (the ``.rrd`` file is complete afterwards).

        Closes the stream's sinks when this observer created the stream or
        opened the file; a caller's stream without ``path`` is only flushed.
        Calling ``close`` again does nothing.

        Parameters
        ----------
        keep : bool
            False: drop what was recorded instead of writing it to ``path``.
            With ``parts`` the file at ``path`` stays as it was (e.g. the
            recording of a complete earlier run, whose results an interrupted
            run did not replace); without parts ``path`` was written from the
            start and is finalised all the same.
        """
        if self.closed:
            return
        if self._bp_dirty:
            self._refresh_blueprint(now=True)
        self.recording.flush()
        if self._owns_stream or self.path is not None:
            self.recording.disconnect()
        self.closed = True
        if self._parts is not None:
            if not keep:
                import shutil

                shutil.rmtree(self._parts, ignore_errors=True)
                return
            last = self._part_file(self._part, True)
            if last.is_file():
                os.replace(last, self._part_file(self._part))
            if not finish_parts(self._parts, self.path):
                return  # the parts stay (each one complete); a warning said why
        self._saved = self.path is not None
        if self.path is not None and self.config.compact_on_close:
            self._compact()

    def _compact(self) -> None:
        """Rewrite the saved file with each entity's rows merged into few chunks (``rerun rrd optimize``)
        and only the layout sent last, atomically; on failure the file stays as written (complete and
        valid) and a warning says why.

        Every ``send_blueprint`` is a blueprint store of its own, and the viewer shows the one whose
        activation comes last in the file.  ``rerun rrd optimize`` writes the stores in an order of its
        own (not the order sent), so a file with several layouts would open on any of them: an early
        one, without the stage tabs, the subject's framing or the rendered views.  The data is written
        alone (:meth:`rerun.chunk.LazyStore.write_rrd`) and optimized together with the last layout.
        """
        import os
        import shutil
        import subprocess
        import sys
        import tempfile
        import warnings

        cli = Path(sys.executable).with_name("rerun")
        cli = str(cli) if cli.is_file() else shutil.which("rerun")
        if cli is None or not self.path.is_file():
            warnings.warn(f"{self.path}: not compacted (no rerun CLI next to {sys.executable})", stacklevel=3)
            return
        tmp = self.path.with_name(f".{self.path.name}.compact-{os.getpid()}.rrd")
        try:
            with tempfile.TemporaryDirectory(prefix=".compact-", dir=self.path.parent) as work:
                inputs = [str(self.path)]
                reader = rr.chunk.RrdReader(self.path)
                recordings = reader.recordings()
                if self._last_blueprint is not None and len(recordings) == 1:
                    rec = recordings[0]
                    data, layout = Path(work) / "data.rrd", Path(work) / "layout.rbl"
                    reader.stream(store=rec).write_rrd(data, application_id=rec.application_id,
                                                       recording_id=rec.recording_id)
                    self._last_blueprint.save(rec.application_id, layout)
                    inputs = [str(data), str(layout)]
                done = subprocess.run([cli, "rrd", "optimize", *inputs, "-o", str(tmp)],
                                      capture_output=True, text=True, timeout=COMPACT_TIMEOUT_S)
            if done.returncode == 0 and tmp.is_file() and tmp.stat().st_size > 0:
                os.replace(tmp, self.path)
            else:
                warnings.warn(f"{self.path}: not compacted (rerun rrd optimize: {done.stderr.strip()[-300:]})",
                              stacklevel=3)
        except (OSError, ValueError, RuntimeError, subprocess.TimeoutExpired) as e:
            warnings.warn(f"{self.path}: not compacted ({type(e).__name__}: {e})", stacklevel=3)
        finally:
            tmp.unlink(missing_ok=True)

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
        if name == "image":
            return base
        first = [p for p in str(name).split("/") if p][:1]
        seen = self._overlays.setdefault(cam, set())
        if first and first[0] not in seen:
            seen.add(first[0])
            if any(first[0] in prefixes for _, prefixes in STAGE_TABS):  # the camera joins a stage tab
                self._refresh_blueprint()
        return f"{base}/{entity_path(name)}"

    def _world_path(self, kind: str, data: Mapping[str, Any]) -> str:
        return entity_path(WORLD, data.get("name") or kind)

    def _context_once(self, path: str, classes: list) -> None:
        """Static annotation context at ``path`` (logged once per path)."""
        if path not in self._contexts:
            self._log(path, rr.AnnotationContext(classes), static=True)
            self._contexts.add(path)

    def _skeleton_class(self, skeleton: Skeleton, class_id: int | None = None, color=None) -> int:
        """Class id of ``skeleton``, registering it (root annotation context) on first use.

        With ``color`` (RGB uint8), a class of its own whose bones are drawn in that colour
        (one per person of a multi-person recording).
        """
        if not isinstance(skeleton, Skeleton):
            raise InputError("report: skeleton", "a toolkit.skeleton.Skeleton", f"{type(skeleton).__name__}")
        if color is not None:
            key = f"{skeleton.name} {tuple(int(c) for c in color)}"
            if key not in self._skeleton_ids:
                self._skeleton_colors[key] = tuple(int(c) for c in color)
                skeleton = dataclasses.replace(skeleton, name=key)
            else:
                skeleton = self._skeletons[key]
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
            color = self._skeleton_colors.get(name, SKELETON_COLORS[i % len(SKELETON_COLORS)])
            classes.append(rr.ClassDescription(
                info=rr.AnnotationInfo(id=cid, label=sk.name, color=color),
                keypoint_annotations=[rr.AnnotationInfo(id=j, label=jn, color=_side_color(jn))
                                      for j, jn in enumerate(sk.joint_names)],
                keypoint_connections=list(sk.edges)))
        # Root context: every joints entity under world/ (3D and 2D) inherits it.
        self._log("/", rr.AnnotationContext(classes), static=True)
        return class_id

    def _subject_box(self, camera: str, shape) -> tuple[tuple[int, int, int, int], tuple[int, int, int, int]] | None:
        """The subject's box in a camera image of ``shape``, from the 3D joints of this frame and the one
        before (every person); ``(tight, crop)`` boxes (x0, y0, x1, y1 pixels, end exclusive), the crop
        widened by ``crop_margin``; None when unknown."""
        cam = self._cameras.get(camera)
        if cam is None or not self._subject or len(shape) < 2 or tuple(shape[1::-1]) != tuple(cam.size):
            return None
        now = self.frame
        pts = [p for f, p in self._subject.items() if f == now or (f is not None and now is not None and f == now - 1)]
        if not pts:
            return None
        px = cam.project(np.concatenate(pts))
        px = px[np.isfinite(px).all(axis=1)]
        if len(px) < 2:
            return None
        lo, hi = px.min(axis=0), px.max(axis=0)
        w, h = cam.size

        def box(m):
            x0, y0 = int(np.clip(np.floor(lo[0] - m), 0, w)), int(np.clip(np.floor(lo[1] - m), 0, h))
            x1, y1 = int(np.clip(np.ceil(hi[0] + m) + 1, 0, w)), int(np.clip(np.ceil(hi[1] + m) + 1, 0, h))
            return (x0, y0, x1, y1)

        tight, crop = box(0.0), box(self.config.crop_margin * (hi[1] - lo[1]) + CROP_PAD_PX)
        return (tight, crop) if crop[2] > crop[0] and crop[3] > crop[1] else None

    def _cropped(self, path: str, img: np.ndarray, box, static: bool) -> np.ndarray:
        """``img`` cropped to ``box`` (or, for ``None``, to its non-zero pixels), with the 2D translation
        that puts it back in place logged at ``path`` (``crop_overlays``; uncropped when it saves little)."""
        if not self.config.crop_overlays:
            return img
        h, w = img.shape[:2]
        if box is None and img.ndim == 2:
            rows, cols = np.flatnonzero(img.any(axis=1)), np.flatnonzero(img.any(axis=0))
            if rows.size:
                box = (int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1)
        if box is not None and (box[2] - box[0]) * (box[3] - box[1]) > CROP_MAX_FRACTION * w * h:
            box = None
        x0, y0 = (0, 0) if box is None else box[:2]
        if box is not None or path in self._crop_paths:  # an uncropped image after a cropped one: back to 0
            self._crop_paths.add(path)
            self._log(path, rr.Transform3D(translation=[float(x0), float(y0), 0.0]), static=static)
        return img if box is None else np.ascontiguousarray(img[box[1]:box[3], box[0]:box[2]])

    def _keypoints(self, kind: str, data: Mapping[str, Any], dim: int):
        joints = _array(kind, data, "joints", (None, dim))
        ids = np.arange(len(joints))
        sk = data.get("skeleton")
        cls = None
        if sk is not None:
            if len(joints) != getattr(sk, "n_joints", len(joints)):
                raise InputError(f"report {kind!r}: joints", f"{sk.n_joints} joints of skeleton {sk.name}",
                                 f"{len(joints)}")
            color = _colors(kind, data, "color", 1)
            cls = self._skeleton_class(sk, color=None if color is None else color[0, :3])
        ok = np.all(np.isfinite(joints), axis=1)
        return joints[ok], ids[ok], cls

    # ------------------------------------------------------------ kind: setup
    def _rig(self, kind, data, static):
        rig = _field(kind, data, "rig")
        root = data.get("path") or CAMS
        cfg = self.config
        for cam in rig:
            self._cam_roots[cam.name] = root
            self._cameras[cam.name] = cam
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
        cam = _camera_name(kind, data)
        boxes = self._subject_box(cam, img.shape) if cfg.crop_overlays else None
        if path != image_path(cam, self._cam_roots.get(cam, CAMS)):
            img = self._cropped(path, img, None if boxes is None else boxes[1], static)
        elif not self._camera_image(path, cam, img, boxes, static):
            return
        self._log(path, self._encoded(path, img), static=static)

    def _camera_image(self, path: str, cam: str, img: np.ndarray, boxes, static: bool) -> bool:
        """The camera's own image: a full frame now and then, the subject's crop every frame.

        With the subject's box known, the crop (``<image>/subject``, drawn over the image) is logged
        every frame, and the full image only when the crop no longer covers the subject of the last
        full image (no ghost), every :data:`KEYFRAME_INTERVAL` frames (a moving camera) or when
        static.  Returns whether the full image is to be logged now.
        """
        sub = f"{path}/{SUBJECT_CROP}"
        if boxes is None or static:
            if sub in self._crop_paths:
                self._log(sub, rr.Clear(recursive=False), static=static)
                self._crop_paths.discard(sub)
            if static:
                self._keys.pop(cam, None)
            else:  # a full image of unknown subject box: the frame's 3D joints, when reported, give it
                self._keys[cam] = (self.frame, None)
            return True
        tight, crop = boxes
        h, w = img.shape[:2]
        if (crop[2] - crop[0]) * (crop[3] - crop[1]) > CROP_MAX_FRACTION * w * h:
            return self._camera_image(path, cam, img, None, static)
        key = self._keys.get(cam)
        full = key is None or key[1] is None or self.frame is None or key[0] is None \
            or self.frame - key[0] >= KEYFRAME_INTERVAL or not (
                crop[0] <= key[1][0] and crop[1] <= key[1][1] and crop[2] >= key[1][2] and crop[3] >= key[1][3])
        if full:
            self._keys[cam] = (self.frame, tight)
        self._crop_paths.add(sub)
        self._log(sub, rr.Transform3D(translation=[float(crop[0]), float(crop[1]), 0.0]), static=static)
        part = np.ascontiguousarray(img[crop[1]:crop[3], crop[0]:crop[2]])
        self._log(sub, self._encoded(sub, part, draw_order=SUBJECT_DRAW_ORDER), static=static)
        return full

    def _encoded(self, path: str, img: np.ndarray, draw_order: float | None = None):
        """An 8-bit image as JPEG (large RGB / grey images, ``compress_images``) or raw."""
        cfg = self.config
        channels = 1 if img.ndim == 2 else img.shape[2]
        large = img.shape[0] * img.shape[1] >= cfg.compress_min_pixels
        if cfg.compress_images and channels in (1, 3) and large:
            bgr = img if channels == 1 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
            ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(cfg.jpeg_quality)])
            if not ok:
                raise ToolkitError(f"JPEG encoding of {path} ({img.shape}) failed")
            return rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg", draw_order=draw_order)
        model = {1: "L", 3: "RGB", 4: "RGBA"}[channels]
        return rr.Image(img, color_model=model, draw_order=draw_order)

    def _mask(self, kind, data, static):
        mask = np.asarray(_field(kind, data, "mask"))
        check_shape(f"report {kind!r}: mask", mask, (None, None))
        path = self._image_path(kind, data, "mask")
        values = np.unique(mask) if mask.dtype != bool else np.array([0, 1])
        if mask.dtype == bool or np.isin(values, (0, 1, 255)).all():
            self._context_once(path, [rr.AnnotationInfo(id=0, label="background", color=(0, 0, 0, 0)),
                                      rr.AnnotationInfo(id=1, label="foreground", color=MASK_COLOR)])
            seg = self._cropped(path, (mask > 0).astype(np.uint8), None, static)
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
        labels = self._cropped(path, labels, None, static)
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
                  rr.Points2D(joints, keypoint_ids=ids, class_ids=cls, radii=self.config.keypoint_radius_px,
                              show_labels=self.config.joint_labels), static=static)

    def _points2d(self, kind, data, static):
        pts = _array(kind, data, "points", (None, 2))
        ok = np.all(np.isfinite(pts), axis=1)
        colors = _colors(kind, data, "colors", len(pts))
        self._log(self._image_path(kind, data, "points"),
                  rr.Points2D(pts[ok], colors=None if colors is None else colors[ok],
                              radii=float(data.get("radii", self.config.keypoint_radius_px))), static=static)

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
                  rr.Points3D(joints, keypoint_ids=ids, class_ids=cls, radii=self.config.joint_radius_m,
                              show_labels=self.config.joint_labels), static=static)
        if len(joints) >= 2:  # where the subject is: crops of colour images, the 3D view's eye
            first = not self._subject
            if self.frame not in self._subject:
                self._subject = {f: p for f, p in self._subject.items()
                                 if f is not None and self.frame is not None and f >= self.frame - 1}
            prev = self._subject.get(self.frame)
            self._subject[self.frame] = joints if prev is None else np.concatenate([prev, joints])
            for cam, (kf, kbox) in list(self._keys.items()):  # full images of this frame: where the subject is
                if kf == self.frame and kf is not None and cam in self._cameras:
                    px = self._cameras[cam].project(self._subject[self.frame])
                    px = px[np.isfinite(px).all(axis=1)]
                    if len(px):
                        lo, hi = np.floor(px.min(axis=0)), np.ceil(px.max(axis=0)) + 1
                        box = (int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1]))
                        if kbox is not None:  # more people in the frame: the union
                            box = (min(box[0], kbox[0]), min(box[1], kbox[1]), max(box[2], kbox[2]),
                                   max(box[3], kbox[3]))
                        self._keys[cam] = (kf, box)
            if first and self._eye is None:
                centres = [c.center for c in self._cameras.values()]
                self._eye = subject_eye(joints.mean(axis=0), np.array(centres) if centres else None)
                self._view_bounds = {}
                for name, cam in self._cameras.items():
                    px = cam.project(joints)
                    px = px[np.isfinite(px).all(axis=1)]
                    if len(px) >= 2:
                        lo, hi = px.min(axis=0), px.max(axis=0)
                        m = VIEW_BOUNDS_MARGIN * (hi[1] - lo[1]) + CROP_PAD_PX
                        self._view_bounds[name] = [float(lo[0] - m), float(lo[1] - m), float(hi[0] + m),
                                                   float(hi[1] + m)]
                self._refresh_blueprint()

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

    # ----------------------------------------------------------- kind: depth
    def _number(self, kind, data, key) -> float:
        raw = _field(kind, data, key)
        try:
            return float(raw)
        except (TypeError, ValueError):
            raise InputError(f"report {kind!r}: {key}", "a number", f"{raw!r}") from None

    def _depth_energy(self, kind, data, static):
        """Each residual block's energy and the total after one LM round, under ``metrics/depth_energy/<stage>``."""
        stage = str(_field(kind, data, "stage"))
        blocks = _field(kind, data, "blocks")
        if not isinstance(blocks, Mapping):
            raise InputError(f"report {kind!r}: blocks", "a dict of block name -> energy", type(blocks).__name__)
        values = {"total": self._number(kind, data, "total")}
        values.update({str(k): self._number(kind, blocks, k) for k in blocks})
        for name, value in values.items():
            self._log(entity_path(METRICS, kind, stage, name), rr.Scalars(value), static=static)

    def _depth_move(self, kind, data, static):
        """A global change tried: its weight, whether it won (1) or not (0), the energy after it."""
        move = str(_field(kind, data, "move"))
        for key in ("weight", "energy"):
            self._log(entity_path(METRICS, kind, move, key), rr.Scalars(self._number(kind, data, key)), static=static)
        self._log(entity_path(METRICS, kind, move, "won"), rr.Scalars(float(bool(_field(kind, data, "won")))),
                  static=static)

    def _depth_radial(self, kind, data, static):
        """The radial profile as a bar chart of distances by angle; its peaks' angles as a log line."""
        angles = _array(kind, data, "angles_deg", (None,))
        distances = _array(kind, data, "distances", (len(angles),))
        peaks = _array(kind, data, "peaks", (None,), np.int64)
        if peaks.size and (peaks.min() < 0 or peaks.max() >= len(angles)):
            raise InputError(f"report {kind!r}: peaks", f"indices in [0, {len(angles)})",
                             f"{peaks.min()}..{peaks.max()}")
        self._log(entity_path(METRICS, kind, "distances"), rr.BarChart(distances), static=static)
        self._log(entity_path(LOGS, kind), rr.TextLog("peaks at " + ", ".join(f"{angles[i]:.0f} deg" for i in peaks)
                                                       if peaks.size else "no peaks", level="DEBUG"), static=static)

    def _silhouette(self, kind, data, static):
        """Outline points over the camera's image, coloured by |residual|: blue 0 to red 3 cm and more (grey: none)."""
        pts = _array(kind, data, "points", (None, 2))
        res = _array(kind, data, "residuals", (len(pts),))
        a = np.clip(np.abs(np.nan_to_num(res, nan=0.0)) / 0.03, 0, 1)[:, None]
        colors = np.round(255 * ((1 - a) * [0.1, 0.3, 1.0] + a * [1.0, 0.15, 0.1])).astype(np.uint8)
        colors[~np.isfinite(res)] = 128
        ok = np.all(np.isfinite(pts), axis=1)
        self._log(self._image_path(kind, data, "silhouette"),
                  rr.Points2D(pts[ok], colors=colors[ok], radii=self.config.keypoint_radius_px), static=static)

    def _text(self, kind, data, static):
        text = _field(kind, data, "text")
        level = data.get("level")
        # clear_unset: a line without a level must not show the entity's previous line's level (e.g. WARN)
        log = rr.TextLog.from_fields(text=str(text), level=None if level is None else str(level), clear_unset=True)
        if not static and self.frame is not None:
            self._log(entity_path(LOGS, data.get("name") or "text"), log)
            return
        # a static line (or one before any frame) at frame 0: rerun's text log view lists no static rows, and a
        # static row replaces the entity's earlier one (several warnings under one name would show only the last)
        self.recording.set_time(FRAME_TIMELINE, sequence=0)
        self._log(entity_path(LOGS, data.get("name") or "text"), log)
        if self.frame is None:
            self.recording.disable_timeline(FRAME_TIMELINE)
        else:
            self.recording.set_time(FRAME_TIMELINE, sequence=self.frame)

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


def parts_folder(path: str | Path) -> Path:
    """The folder of a recording's parts while it is written in parts (``recording.rrd`` -> ``recording.parts``)."""
    return Path(path).with_suffix(".parts")


def finish_parts(parts: str | Path, path: str | Path | None = None) -> bool:
    """Merge a recording's complete parts into one file and remove the folder (``rerun rrd merge``).

    Parameters
    ----------
    parts : path
        The parts folder (:func:`parts_folder`); a part left unfinished by a
        killed process (``.NNNNNN.rrd.partial``) is dropped.
    path : path, optional
        The merged file, replaced if it exists (default: the folder's name with
        ``.rrd``, or where that file exists the next free ``<stem>.resume-<k>.rrd``).

    Returns
    -------
    bool
        Whether the parts were merged (False: they stay, and a warning says why).
    """
    import shutil
    import subprocess
    import sys
    import warnings

    parts = Path(parts)
    given = path is not None
    path = Path(path) if given else parts.with_suffix(".rrd")
    if path.exists() and not given:
        k = 1
        while (alt := path.with_name(f"{path.stem.split('.resume-')[0]}.resume-{k}.rrd")).exists():
            k += 1
        path = alt
    files = sorted(parts.glob("[0-9]*.rrd"))
    if not files:
        shutil.rmtree(parts, ignore_errors=True)
        return True
    cli = Path(sys.executable).with_name("rerun")
    cli = str(cli) if cli.is_file() else shutil.which("rerun")
    tmp = path.with_name(f".{path.name}.merge-{os.getpid()}.rrd")
    try:
        if cli is None:
            raise OSError(f"no rerun CLI next to {sys.executable}")
        done = subprocess.run([cli, "rrd", "merge", *map(str, files), "-o", str(tmp)], capture_output=True,
                              text=True, timeout=COMPACT_TIMEOUT_S)
        if done.returncode != 0 or not tmp.is_file():
            raise OSError(f"rerun rrd merge: {done.stderr.strip()[-300:]}")
        os.replace(tmp, path)
    except (OSError, subprocess.TimeoutExpired) as e:
        warnings.warn(f"{parts}: recording parts not merged ({e}); each part opens: rerun {parts}/*.rrd",
                      stacklevel=2)
        return False
    finally:
        tmp.unlink(missing_ok=True)
    shutil.rmtree(parts, ignore_errors=True)
    return True
