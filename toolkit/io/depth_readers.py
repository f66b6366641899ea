"""Depth input: depth-map readers and the depth camera's intrinsics file.

Depth maps come in as float32 metres, camera-frame z, with NaN where the sensor
gave no reading.  Three file kinds are read:

* 16-bit PNG in millimetres (0 = no reading), the layout's ``depth/NNNNNN.png``;
* raw little-endian uint16 millimetres without a header, as the Kinect v1
  frames of Skeltrack's test set (640 x 480, 614 400 bytes);
* any image Open3D reads (``open3d.io.read_image``): uint16 millimetres or
  float32 metres, and ``.npy`` arrays with either encoding.

The depth camera's intrinsics file (``depth_camera/intrinsics.toml``) holds one
camera in the Pose2Sim calibration vocabulary plus its pose as a 4 x 4
``cam_from_world`` matrix::

    name = "depth"
    size = [640, 480]                    # width, height in pixels
    matrix = [[585.0, 0.0, 319.5], [0.0, 585.0, 239.5], [0.0, 0.0, 1.0]]
    distortions = [0.0, 0.0, 0.0, 0.0, 0.0]
    cam_from_world = [[...], [...], [...], [0.0, 0.0, 0.0, 1.0]]   # optional
    depth_units_per_metre = 1000.0       # PNG units

Without ``cam_from_world`` the pose is unknown: the camera frame is used as the
world frame and results stay in camera coordinates.
"""

from __future__ import annotations

import os
import re
import tokenize
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.cameras import Camera
from toolkit.cameras.validate import check_camera
from toolkit.errors import InputError
from toolkit.io.layout import is_stray
from toolkit.io.text import load_toml
from toolkit.io.frames import mm_to_depth, read_png
from toolkit.io.frames import DEPTH_UNITS_PER_METRE

__all__ = [
    "DEPTH_SUFFIXES",
    "KINECT_V1_FOCAL_PX",
    "KINECT_V1_SIZE",
    "DepthCameraInfo",
    "DepthInput",
    "default_depth_camera",
    "depth_intrinsics_text",
    "list_depth_frames",
    "open_depth_input",
    "read_depth",
    "read_depth_intrinsics",
    "read_depth_npy",
    "read_depth_open3d",
    "read_depth_png",
    "read_depth_raw",
]

#: Image size of a Kinect v1 depth frame (width, height).
KINECT_V1_SIZE = (640, 480)
#: Nominal focal length of the Kinect v1 depth camera at 640 x 480, pixels
#: (about 57 degrees horizontal field of view).  The real frames of
#: ``../shared/realdata/kinect_depth`` come without intrinsics; this is their default.
KINECT_V1_FOCAL_PX = 585.0
#: Largest median depth of a float depth map taken as metres: depth cameras reach 10-20 m, so a float map
#: whose readings are mostly beyond is in other units (float millimetres read as metres would put a person
#: at 2 km).
MAX_FLOAT_MEDIAN_DEPTH_M = 50.0
#: Largest depth frame read, pixels (a 16K frame; larger is a wrong size or a damaged header).
MAX_DEPTH_PIXELS = 15360 * 8640
#: File suffixes :func:`read_depth` dispatches on (anything else is read as raw uint16).
DEPTH_SUFFIXES = (".png", ".npy", ".tif", ".tiff", ".jpg", ".jpeg")


@dataclass(frozen=True)
class DepthCameraInfo:
    """A depth camera and whether its pose in the world is known.

    Attributes
    ----------
    camera : Camera
        Intrinsics, image size and ``cam_from_world`` (identity if unknown).
    pose_known : bool
        ``True`` when ``cam_from_world`` came from the file; results can then be
        given in world coordinates (z up, metres).
    depth_units_per_metre : float
        Units of the integer depth files (1000 = millimetres).
    """

    camera: Camera
    pose_known: bool
    depth_units_per_metre: float = DEPTH_UNITS_PER_METRE


def default_depth_camera(size=KINECT_V1_SIZE, focal_px: float | None = None, name: str = "depth") -> Camera:
    """A Kinect-v1-like depth camera with the principal point at the image centre.

    Parameters
    ----------
    size : tuple of int
        ``(width, height)`` in pixels.
    focal_px : float, optional
        Focal length in pixels; default :data:`KINECT_V1_FOCAL_PX` scaled by ``width / 640``.
    name : str

    Returns
    -------
    Camera
        Identity ``cam_from_world`` (the camera frame is the world frame).
    """
    w, h = (int(v) for v in size)
    if w <= 0 or h <= 0:
        raise InputError("size", "positive (width, height)", f"{size}")
    f = KINECT_V1_FOCAL_PX * w / KINECT_V1_SIZE[0] if focal_px is None else float(focal_px)
    if not np.isfinite(f) or f <= 0:
        raise InputError("focal_px", "a positive focal length in pixels", f"{focal_px!r}")
    K = np.array([[f, 0.0, (w - 1) / 2.0], [0.0, f, (h - 1) / 2.0], [0.0, 0.0, 1.0]])
    return Camera(name, K, np.zeros(5), (w, h), np.eye(4))


# ------------------------------------------------------------------ readers
def _as_metres(arr: np.ndarray, where: str, units_per_metre: float) -> np.ndarray:
    """uint16 units or float metres to float32 metres with NaN for no reading."""
    a = np.asarray(arr)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if a.ndim != 2:
        raise InputError(where, "a single-channel depth image (H, W)", f"shape {a.shape}")
    if a.dtype == np.uint16:
        if units_per_metre == DEPTH_UNITS_PER_METRE:
            return mm_to_depth(a)
        out = a.astype(np.float32) / np.float32(units_per_metre)
        out[a == 0] = np.nan
        return out
    if np.issubdtype(a.dtype, np.floating):
        out = a.astype(np.float32)
        out[~np.isfinite(out) | (out <= 0)] = np.nan
        if np.isfinite(out).any() and (med := float(np.nanmedian(out))) > MAX_FLOAT_MEDIAN_DEPTH_M:
            raise InputError(where, f"float depth in metres (median at most {MAX_FLOAT_MEDIAN_DEPTH_M:g} m)",
                             f"a median of {med:.6g} (millimetres? store uint16 millimetres or float metres)")
        return out
    raise InputError(where, "uint16 depth units or float metres", f"dtype {a.dtype}")


def read_depth_png(path: str | os.PathLike, units_per_metre: float = DEPTH_UNITS_PER_METRE) -> np.ndarray:
    """Read a 16-bit PNG depth map (0 = no reading).

    Returns
    -------
    ndarray of shape (H, W), float32
        Metres, NaN where the file holds 0.
    """
    img = read_png(path, channels=1, dtype=np.uint16)
    return _as_metres(img, str(path), units_per_metre)


def read_depth_raw(path: str | os.PathLike, size=KINECT_V1_SIZE, dtype: str = "<u2",
                   units_per_metre: float = DEPTH_UNITS_PER_METRE) -> np.ndarray:
    """Read a headerless depth frame (default: little-endian uint16 millimetres, 640 x 480).

    Raises
    ------
    InputError
        Missing file, or a file size other than ``width * height * itemsize``.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(str(path), "an existing raw depth file", "no such file")
    w, h = (int(v) for v in size)
    dt = np.dtype(dtype)
    n = path.stat().st_size
    if n != w * h * dt.itemsize:
        raise InputError(str(path), f"{w * h * dt.itemsize} bytes ({w} x {h} x {dt.itemsize})",
                         f"{n} bytes")
    a = np.fromfile(path, dtype=dt).reshape(h, w)
    if dt.kind == "u" and dt.itemsize == 2:
        a = a.astype(np.uint16)
    return _as_metres(a, str(path), units_per_metre)


def read_depth_open3d(path: str | os.PathLike, units_per_metre: float = DEPTH_UNITS_PER_METRE) -> np.ndarray:
    """Read a depth image with ``open3d.io.read_image`` (uint16 units or float32 metres)."""
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise InputError(str(path), "an existing image file", "no such file")
    img = o3d.io.read_image(str(path))
    a = np.asarray(img)
    if a.size == 0:
        raise InputError(str(path), "an image Open3D can read", "an empty image")
    return _as_metres(a, str(path), units_per_metre)


def read_depth_npy(path: str | os.PathLike, units_per_metre: float = DEPTH_UNITS_PER_METRE) -> np.ndarray:
    """Read a ``.npy`` depth map: uint16 units or float metres."""
    path = Path(path)
    if not path.is_file():
        raise InputError(str(path), "an existing .npy file", "no such file")
    try:
        a = np.load(path, allow_pickle=False, mmap_mode="r")
        if a.size > MAX_DEPTH_PIXELS:
            raise InputError(str(path), f"a depth frame of at most {MAX_DEPTH_PIXELS} pixels", f"shape {a.shape}")
        a = np.array(a)
    except (ValueError, OSError, EOFError, SyntaxError, tokenize.TokenError) as e:
        # a damaged header reaches numpy's header parser (Python's tokenizer) as well as its own checks
        raise InputError(str(path), "a numpy array file", f"unreadable ({e})") from None
    return _as_metres(a, str(path), units_per_metre)


def read_depth(path: str | os.PathLike, *, reader: str = "auto", size=KINECT_V1_SIZE,
               units_per_metre: float = DEPTH_UNITS_PER_METRE) -> np.ndarray:
    """Read one depth frame as float32 metres (NaN = no reading).

    Parameters
    ----------
    path : str or PathLike
    reader : {"auto", "png", "raw", "open3d", "npy"}
        ``"auto"`` picks by suffix: ``.png`` PNG, ``.npy`` numpy, other image
        suffixes Open3D, anything else raw uint16 of ``size``.
    size : tuple of int
        ``(width, height)`` of raw frames.
    units_per_metre : float
        Units of integer depth values.

    Returns
    -------
    ndarray of shape (H, W), float32
    """
    suffix = Path(path).suffix.lower()
    if reader == "auto":
        reader = {".png": "png", ".npy": "npy"}.get(suffix, "open3d" if suffix in DEPTH_SUFFIXES else "raw")
    if reader == "png":
        return read_depth_png(path, units_per_metre)
    if reader == "raw":
        return read_depth_raw(path, size, units_per_metre=units_per_metre)
    if reader == "open3d":
        return read_depth_open3d(path, units_per_metre)
    if reader == "npy":
        return read_depth_npy(path, units_per_metre)
    raise InputError("reader", "'auto', 'png', 'raw', 'open3d' or 'npy'", repr(reader))


def _natural_key(p: Path):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]


def list_depth_frames(folder: str | os.PathLike) -> list[Path]:
    """Depth frame files of a folder in natural order (hidden files and ``*.toml`` left out).

    Raises
    ------
    InputError
        If ``folder`` is not a directory or holds no frame file.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(str(folder), "a folder of depth frames", "no such folder")
    files = [p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".") and not is_stray(p)
             and p.suffix.lower() not in (".toml", ".md", ".txt", ".json", ".yml", ".yaml")
             and p.name not in ("COPYING", "LICENSE", "README")]
    if not files:
        raise InputError(str(folder), "at least one depth frame file", "none")
    return sorted(files, key=_natural_key)


# --------------------------------------------------------------- intrinsics
def _num(x: float) -> str:
    return repr(float(x))


def depth_intrinsics_text(camera: Camera, *, pose_known: bool = True,
                          units_per_metre: float = DEPTH_UNITS_PER_METRE, comment: str = "") -> str:
    """The text of a depth camera's ``intrinsics.toml`` (numbers written with ``repr``).

    Parameters
    ----------
    camera : Camera
    pose_known : bool
        Write ``cam_from_world`` (otherwise the reader treats the camera frame as world).
    units_per_metre : float
    comment : str
        One line written as a TOML comment at the top.
    """
    rows = lambda M: "[" + ", ".join("[" + ", ".join(_num(v) for v in r) + "]" for r in M) + "]"
    lines = []
    if comment:
        lines.append("# " + comment.replace("\n", " "))
    name = camera.name.replace("\\", "\\\\").replace('"', '\\"')
    lines += [
        f'name = "{name}"',
        f"size = [{camera.size[0]}, {camera.size[1]}]",
        f"matrix = {rows(camera.K)}",
        "distortions = [" + ", ".join(_num(v) for v in camera.dist) + "]",
    ]
    if pose_known:
        lines.append(f"cam_from_world = {rows(camera.cam_from_world)}")
    lines.append(f"depth_units_per_metre = {_num(units_per_metre)}")
    return "\n".join(lines) + "\n"


def read_depth_intrinsics(path: str | os.PathLike) -> DepthCameraInfo:
    """Read a depth camera's ``intrinsics.toml``.

    Raises
    ------
    InputError
        Naming the file and the field: missing file, TOML syntax error,
        missing or malformed ``size`` / ``matrix``, malformed ``distortions``
        or ``cam_from_world``.
    """
    path = Path(path)
    data = load_toml(path, "an existing intrinsics.toml (valid TOML)")

    def field(key, shape, required=True):
        if key not in data:
            if required:
                raise InputError(f"{path}: {key}", f"a field of shape {shape}", "nothing")
            return None
        try:
            a = np.asarray(data[key], dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{path}: {key}", f"numbers of shape {shape}", repr(data[key])) from None
        if (shape is not None and a.shape != shape) or not np.all(np.isfinite(a)):
            raise InputError(f"{path}: {key}", f"finite numbers of shape {shape}", f"shape {a.shape}")
        return a

    size = field("size", (2,))
    if np.any(size <= 0) or np.any(size != np.round(size)):
        raise InputError(f"{path}: size", "two positive integers [width, height]", f"{size.tolist()}")
    K = field("matrix", (3, 3))
    dist = field("distortions", None, required=False)
    dist = np.zeros(5) if dist is None else dist.ravel()
    T = field("cam_from_world", (4, 4), required=False)
    units = data.get("depth_units_per_metre", DEPTH_UNITS_PER_METRE)
    if not isinstance(units, (int, float)) or isinstance(units, bool) or not units > 0:
        raise InputError(f"{path}: depth_units_per_metre", "a positive number", repr(units))
    name = str(data.get("name", "depth"))
    try:
        cam = Camera(name, K, dist, (int(size[0]), int(size[1])), np.eye(4) if T is None else T)
    except InputError as e:
        raise InputError(f"{path}: {e.where}", e.expected, e.found) from None
    return DepthCameraInfo(check_camera(cam, str(path)), T is not None, float(units))


# ------------------------------------------------------------------ inputs
@dataclass(frozen=True)
class DepthInput:
    """A sequence of depth frames with its camera, as the depth recipe reads it.

    Attributes
    ----------
    camera : Camera
    pose_known : bool
    frames : list of Path
        Frame files in order.
    background : ndarray of shape (H, W) or None
        Depth of the empty scene (float32 metres), if the input has one.
    truth : dict or None
        ``joints`` (T, 13, 3) world metres, ``names`` and ``visible`` (T, 13) from
        ``groundtruth/skeleton13.npz`` when present.
    reader : str
        Reader of :func:`read_depth` used for the frames.
    size : tuple of int
        Image size of raw frames.
    units_per_metre : float
    kind : str
        ``"dataset"`` (a folder with ``depth_camera/``) or ``"frames"`` (a folder of depth files).
    """

    camera: Camera
    pose_known: bool
    frames: list
    background: np.ndarray | None
    truth: dict | None
    reader: str = "auto"
    size: tuple = KINECT_V1_SIZE
    units_per_metre: float = DEPTH_UNITS_PER_METRE
    kind: str = "frames"

    def __len__(self) -> int:
        return len(self.frames)

    def read(self, i: int) -> np.ndarray:
        """Frame ``i`` as float32 metres (NaN = no reading)."""
        d = read_depth(self.frames[i], reader=self.reader, size=self.size, units_per_metre=self.units_per_metre)
        w, h = self.camera.size
        if d.shape != (h, w):
            raise InputError(str(self.frames[i]), f"a {w} x {h} depth frame (the camera's size)",
                             f"{d.shape[1]} x {d.shape[0]}")
        return d


def open_depth_input(path: str | os.PathLike, *, size=None, focal_px: float | None = None,
                     intrinsics: str | os.PathLike | None = None, reader: str = "auto",
                     background: str | os.PathLike | None = None) -> DepthInput:
    """Open a dataset folder with ``depth_camera/`` or a folder of depth frames.

    Parameters
    ----------
    path : str or PathLike
        A dataset folder (``depth_camera/intrinsics.toml``, ``depth_camera/depth/NNNNNN.png``,
        optionally ``depth_camera/background.png`` and ``groundtruth/skeleton13.npz``) or a
        folder of depth frames (16-bit PNG, raw uint16, Open3D images, ``.npy``).
    size : tuple of int, optional
        ``(width, height)`` of raw frames and of the default camera (default 640 x 480).
    focal_px : float, optional
        Focal length of the default camera (default :data:`KINECT_V1_FOCAL_PX` scaled to the width).
    intrinsics : str or PathLike, optional
        An ``intrinsics.toml`` for a folder of frames (overrides ``size`` and ``focal_px``).
    reader : str
        See :func:`read_depth`.
    background : str or PathLike, optional
        A depth file of the empty scene (datasets use ``depth_camera/background.png``).

    Raises
    ------
    InputError
        Missing folder, no frames, unreadable intrinsics.
    """
    root = Path(path)
    if not root.is_dir():
        raise InputError(str(root), "a dataset folder with depth_camera/ or a folder of depth frames",
                         "no such folder")
    dc = root / "depth_camera"
    if dc.is_dir():
        info = read_depth_intrinsics(intrinsics if intrinsics is not None else dc / "intrinsics.toml")
        frames = sorted((dc / "depth").glob("*.png")) if (dc / "depth").is_dir() else []
        if not frames:
            raise InputError(str(dc / "depth"), "NNNNNN.png depth frames", "none")
        bg_path = Path(background) if background is not None else dc / "background.png"
        bg = read_depth(bg_path, units_per_metre=info.depth_units_per_metre) if bg_path.is_file() else None
        truth = None
        gt = root / "groundtruth" / "skeleton13.npz"
        if gt.is_file():
            with np.load(gt, allow_pickle=False) as z:
                truth = {k: z[k] for k in z.files}
        return DepthInput(info.camera, info.pose_known, frames, bg, truth, "png", info.camera.size,
                          info.depth_units_per_metre, "dataset")
    frames = list_depth_frames(root)
    if intrinsics is not None:
        info = read_depth_intrinsics(intrinsics)
        cam, pose_known, units = info.camera, info.pose_known, info.depth_units_per_metre
    else:
        cam = default_depth_camera(size if size is not None else KINECT_V1_SIZE, focal_px)
        pose_known, units = False, DEPTH_UNITS_PER_METRE
    bg = read_depth(background, reader=reader, size=cam.size, units_per_metre=units) if background else None
    return DepthInput(cam, pose_known, frames, bg, None, reader, cam.size, units, "frames")
