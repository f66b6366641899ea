"""Camera calibration files: the Pose2Sim / anipose TOML layout and OpenCV YAML.

TOML layout (Pose2Sim, anipose), one table per camera, in file order::

    [cam_01]
    name = "cam_01"
    size = [1088, 1920]                  # image [width, height], pixels
    matrix = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    distortions = [k1, k2, p1, p2]       # OpenCV order; 4, 5, 8, 12 or 14 values
    rotation = [rx, ry, rz]              # Rodrigues vector, world to camera
    translation = [tx, ty, tz]           # metres, world to camera
    fisheye = false

    [metadata]                           # optional, ignored on reading
    adjusted = false
    error = 0.0

The camera name is the table's ``name`` field, or the table's own name when
there is no ``name``.  ``size`` may hold floats if they are whole numbers
(Pose2Sim writes ``1088.0``).  ``rotation`` may also be a 3x3 matrix.

OpenCV YAML layout, written and read with ``cv2.FileStorage``::

    %YAML:1.0
    ---
    cameras:
       - name: cam_01
         image_width: 1088
         image_height: 1920
         K: !!opencv-matrix {rows: 3, cols: 3, dt: d, data: [...]}
         dist: !!opencv-matrix {rows: 1, cols: 5, dt: d, data: [...]}
         R: !!opencv-matrix {rows: 3, cols: 3, dt: d, data: [...]}   # or rvec (3 values)
         t: !!opencv-matrix {rows: 3, cols: 1, dt: d, data: [...]}   # metres

Every rig read is checked against the physical range of its numbers
(:func:`toolkit.cameras.validate.check_rig`: principal points inside the
image, monotonic distortion, cameras looking forward at the scene).

Both describe the OpenCV pinhole model (camera axes x right, y down, z
forward; the centre of the top-left pixel at (0, 0)) and a world-to-camera
pose, so no axis conversion happens here.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import cv2
import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.cameras.validate import check_rig
from toolkit.errors import InputError
from toolkit.io.atomic import atomic_write_text
from toolkit.io.text import load_toml, read_text

__all__ = [
    "read_calibration",
    "write_calibration",
    "read_calibration_toml",
    "write_calibration_toml",
    "read_calibration_yaml",
    "write_calibration_yaml",
    "calibration_toml_text",
    "TOML_SUFFIXES",
    "YAML_SUFFIXES",
]

#: File suffixes read as TOML and as OpenCV YAML.
TOML_SUFFIXES = (".toml",)
YAML_SUFFIXES = (".yml", ".yaml")
#: Distortion vector lengths of OpenCV's models (0 means no distortion).
DIST_LENGTHS = (4, 5, 8, 12, 14)
#: Name of the optional, non-camera table in Pose2Sim files.
METADATA_TABLE = "metadata"


# ---------------------------------------------------------------- dispatch
def _suffix(path: Path) -> str:
    return path.suffix.lower()


def read_calibration(path: str | os.PathLike) -> Rig:
    """Read a calibration file, choosing the format from the suffix.

    Parameters
    ----------
    path : str or PathLike
        ``.toml`` (Pose2Sim / anipose), ``.yml`` / ``.yaml`` (OpenCV FileStorage) or
        ``.qca.txt`` (Qualisys, :mod:`toolkit.io.qualisys`).

    Returns
    -------
    Rig
        The cameras in file order.

    Raises
    ------
    InputError
        Missing file, unknown suffix, or any malformed field (the message names
        the file and the field).
    """
    from toolkit.io.qualisys import QCA_SUFFIXES, is_qca, read_calibration_qca

    path = Path(path)
    if _suffix(path) in TOML_SUFFIXES:
        return read_calibration_toml(path)
    if _suffix(path) in YAML_SUFFIXES:
        return read_calibration_yaml(path)
    if is_qca(path):
        return read_calibration_qca(path)
    raise InputError(
        str(path),
        f"a calibration file ending in {TOML_SUFFIXES + YAML_SUFFIXES + QCA_SUFFIXES}",
        f"suffix {path.suffix!r}",
    )


def write_calibration(path: str | os.PathLike, rig: Rig, *, metadata: dict | None = None) -> Path:
    """Write a rig to a calibration file, choosing the format from the suffix.

    Parameters
    ----------
    path : str or PathLike
        ``.toml`` or ``.yml`` / ``.yaml``.
    rig : Rig
    metadata : dict of str to (bool, int, float, str), optional
        TOML only: written as a ``[metadata]`` table.

    Returns
    -------
    Path
    """
    path = Path(path)
    if _suffix(path) in TOML_SUFFIXES:
        return write_calibration_toml(path, rig, metadata=metadata)
    if _suffix(path) in YAML_SUFFIXES:
        if metadata:
            raise InputError(
                "write_calibration: metadata", "no metadata for a YAML file", f"{sorted(metadata)}"
            )
        return write_calibration_yaml(path, rig)
    raise InputError(
        str(path),
        f"a calibration file ending in {TOML_SUFFIXES + YAML_SUFFIXES}",
        f"suffix {path.suffix!r}",
    )


# ------------------------------------------------------------ validation
def _numbers(where: str, value, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a finite float array of ``shape``, or an InputError naming ``where``."""
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(where, what, f"{value!r}") from None
    if a.shape != shape:
        raise InputError(where, what, f"shape {a.shape}: {value!r}")
    if not np.all(np.isfinite(a)):
        raise InputError(where, f"finite numbers ({what})", f"{a.tolist()}")
    return a


def _image_size(where: str, value) -> tuple[int, int]:
    wh = _numbers(where, value, (2,), "[width, height] in pixels")
    if np.any(wh != np.round(wh)) or np.any(wh <= 0):
        raise InputError(where, "positive whole numbers [width, height]", f"{wh.tolist()}")
    return int(wh[0]), int(wh[1])


def _intrinsics(where: str, value) -> np.ndarray:
    K = _numbers(where, value, (3, 3), "a 3x3 matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]")
    if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]):
        raise InputError(where, "fx, fy > 0 and a last row [0, 0, 1]", f"{K.tolist()}")
    return K


def _distortion(where: str, value) -> np.ndarray:
    try:
        d = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(where, f"a list of {DIST_LENGTHS} numbers", f"{value!r}") from None
    d = d.reshape(-1) if d.ndim == 2 and 1 in d.shape else d
    if d.ndim != 1 or d.size not in DIST_LENGTHS:
        raise InputError(
            where,
            f"a list of {' or '.join(map(str, DIST_LENGTHS))} numbers (k1, k2, p1, p2[, k3, ...])",
            f"shape {d.shape}",
        )
    if not np.all(np.isfinite(d)):
        raise InputError(where, "finite distortion coefficients", f"{d.tolist()}")
    return d


def _rotation(where: str, value) -> np.ndarray:
    """A 3x3 rotation from a Rodrigues vector or a 3x3 matrix."""
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(
            where, "a Rodrigues vector [rx, ry, rz] or a 3x3 matrix", f"{value!r}"
        ) from None
    if a.size == 3 and a.ndim in (1, 2):
        a = _numbers(where, a.reshape(3), (3,), "a Rodrigues vector [rx, ry, rz]")
        return cv2.Rodrigues(a.reshape(3, 1))[0]
    R = _numbers(where, a, (3, 3), "a Rodrigues vector [rx, ry, rz] or a 3x3 matrix")
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise InputError(where, "a rotation matrix (orthonormal, det +1)", f"{R.tolist()}")
    return R


def _translation(where: str, value) -> np.ndarray:
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(where, "a translation [tx, ty, tz] in metres", f"{value!r}") from None
    return _numbers(
        where, a.reshape(-1) if a.size == 3 else a, (3,), "a translation [tx, ty, tz] in metres"
    )


def _camera(where: str, name: str, K, dist, size, R, t) -> Camera:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    try:
        return Camera(name, K, dist, size, T)
    except InputError as e:  # re-raise naming the file and table
        raise InputError(f"{where}: {e.where}", e.expected, e.found) from e


def _rig(path: Path, cameras: list[Camera]) -> Rig:
    if not cameras:
        raise InputError(str(path), "at least one camera", "no cameras")
    try:
        rig = Rig(tuple(cameras))
    except InputError as e:
        raise InputError(f"{path}: {e.where}", e.expected, e.found) from e
    return check_rig(rig, str(path))


# ------------------------------------------------------------------ TOML
def _load_toml(path: Path) -> dict:
    """The parsed TOML document at ``path``, or an InputError naming the file."""
    return load_toml(path, "a valid TOML calibration file")


def read_calibration_metadata(path: str | os.PathLike) -> dict:
    """The ``[metadata]`` table of a TOML calibration file (empty when it has none).

    Raises
    ------
    InputError
        Missing file, TOML syntax error, or a ``metadata`` entry that is not a table.
    """
    path = Path(path)
    meta = _load_toml(path).get(METADATA_TABLE, {})
    if not isinstance(meta, dict):
        raise InputError(f"{path}: {METADATA_TABLE}", "a [metadata] table", repr(meta))
    return meta


def read_calibration_toml(path: str | os.PathLike) -> Rig:
    """Read a Pose2Sim / anipose TOML calibration (see the module docstring).

    Parameters
    ----------
    path : str or PathLike

    Returns
    -------
    Rig
        Cameras in file order; the ``[metadata]`` table is ignored.

    Raises
    ------
    InputError
        Missing file, TOML syntax error, a camera table missing a field or with
        a wrong shape or a non-finite number, ``fisheye = true`` (not supported),
        a top-level value that is not a table, or no camera at all.
    """
    path = Path(path)
    doc = _load_toml(path)
    cameras = []
    for key, table in doc.items():
        if key == METADATA_TABLE:
            continue
        where = f"{path}: [{key}]"
        if not isinstance(table, dict):
            raise InputError(
                where, "a camera table (or [metadata])", f"a top-level value {table!r}"
            )
        for field in ("size", "matrix", "distortions", "rotation", "translation"):
            if field not in table:
                raise InputError(
                    f"{where}.{field}",
                    f"a '{field}' field in every camera table",
                    f"no '{field}' (fields: {sorted(table)})",
                )
        name = table.get("name", key)
        if not isinstance(name, str) or not name:
            raise InputError(f"{where}.name", "a non-empty string", f"{name!r}")
        fisheye = table.get("fisheye", False)
        if fisheye is not False:
            raise InputError(
                f"{where}.fisheye", "false (only the pinhole model is supported)", f"{fisheye!r}"
            )
        cameras.append(
            _camera(
                where,
                name,
                _intrinsics(f"{where}.matrix", table["matrix"]),
                _distortion(f"{where}.distortions", table["distortions"]),
                _image_size(f"{where}.size", table["size"]),
                _rotation(f"{where}.rotation", table["rotation"]),
                _translation(f"{where}.translation", table["translation"]),
            )
        )
    return _rig(path, cameras)


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_str(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _toml_key(s: str) -> str:
    return s if _BARE_KEY.match(s) else _toml_str(s)


def _toml_float(x: float) -> str:
    x = float(x)
    if not math.isfinite(x):
        raise InputError("write_calibration", "finite numbers", f"{x!r}")
    return repr(x)  # shortest string that reads back to the same double


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return _toml_float(v)
    if isinstance(v, str):
        return _toml_str(v)
    raise InputError(
        "write_calibration: metadata", "bool, int, float or str values", f"{type(v).__name__}"
    )


def _toml_list(values) -> str:
    return "[" + ", ".join(_toml_float(v) for v in values) + "]"


def calibration_toml_text(rig: Rig, *, metadata: dict | None = None) -> str:
    """The TOML text :func:`write_calibration_toml` writes (deterministic, full precision).

    Parameters
    ----------
    rig : Rig
    metadata : dict of str to (bool, int, float, str), optional
        Written as a final ``[metadata]`` table.

    Returns
    -------
    str
    """
    if not isinstance(rig, Rig):
        raise InputError("write_calibration: rig", "a Rig", f"{type(rig).__name__}")
    if len(rig) == 0:
        raise InputError("write_calibration: rig", "at least one camera", "an empty rig")
    lines = []
    for cam in rig:
        if cam.name == METADATA_TABLE:
            raise InputError(
                "write_calibration: rig",
                f"no camera named {METADATA_TABLE!r} (reserved)",
                f"a camera named {cam.name!r}",
            )
        w, h = cam.size
        lines += [
            f"[{_toml_key(cam.name)}]",
            f"name = {_toml_str(cam.name)}",
            f"size = [{int(w)}, {int(h)}]",
            "matrix = [" + ", ".join(_toml_list(row) for row in cam.K) + "]",
            f"distortions = {_toml_list(cam.dist)}",
            f"rotation = {_toml_list(cam.rvec)}",
            f"translation = {_toml_list(cam.t)}",
            "fisheye = false",
            "",
        ]
    if metadata:
        lines.append(f"[{METADATA_TABLE}]")
        for k, v in metadata.items():
            lines.append(f"{_toml_key(str(k))} = {_toml_value(v)}")
        lines.append("")
    return "\n".join(lines)


def write_calibration_toml(
    path: str | os.PathLike, rig: Rig, *, metadata: dict | None = None
) -> Path:
    """Write a rig as Pose2Sim / anipose TOML, atomically.

    Numbers are written with Python's ``repr`` so they read back bit for bit;
    the rotation goes through a Rodrigues vector, which reads back to within
    about 1e-15.

    Parameters
    ----------
    path : str or PathLike
    rig : Rig
    metadata : dict, optional
        See :func:`calibration_toml_text`.

    Returns
    -------
    Path
    """
    return atomic_write_text(path, calibration_toml_text(rig, metadata=metadata))


# ------------------------------------------------------------------ YAML
_YAML_CAMERAS = "cameras"


def _open_yaml(path: Path):
    """Open an OpenCV FileStorage YAML file from its text.

    Parameters
    ----------
    path : Path
        The YAML file.

    Returns
    -------
    cv2.FileStorage
        Open for reading; the caller releases it.

    Raises
    ------
    InputError
        Missing, non-UTF-8 or unparsable file.
    """
    text = read_text(path, "a UTF-8 YAML calibration file")
    try:
        return cv2.FileStorage(
            text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY | cv2.FILE_STORAGE_FORMAT_YAML
        )
    except (cv2.error, SystemError) as e:  # the binding may wrap cv2.error in SystemError
        cause = e.__cause__ or e.__context__ if isinstance(e, SystemError) else e
        text = str(cause or e).strip()
        msg = "a parse error: " + (text.splitlines()[-1] if text else "(no detail)")
        raise InputError(str(path), "a YAML file OpenCV's FileStorage can parse", msg) from None


def _yaml_field(node, where: str, key: str, kind: str = "mat", required: bool = True):
    """One field of a YAML camera map.

    Parameters
    ----------
    node : cv2.FileNode
        The camera's map.
    where : str
        The file and the camera's place in it, for errors.
    key : str
        The field's name.
    kind : {"mat", "str", "num"}
        A matrix (``!!opencv-matrix`` or a sequence of numbers), a string or a number.
    required : bool
        Whether a missing field is an error.

    Returns
    -------
    ndarray, list of float, str, float or None
        The field's value; None when missing and not required.

    Raises
    ------
    InputError
        A required field missing, or a field of another kind.
    """
    n = node.getNode(key)
    if n.empty() or n.isNone():
        if required:
            raise InputError(
                f"{where}.{key}",
                f"a '{key}' field",
                f"no '{key}' (fields: {node.keys()})",
            )
        return None
    if kind == "str":
        if not n.isString():
            raise InputError(f"{where}.{key}", "a string", "a non-string node")
        return n.string()
    if kind == "num":
        if not (n.isInt() or n.isReal()):
            raise InputError(f"{where}.{key}", "a number", "a non-numeric node")
        return n.real()
    if n.isSeq():
        items = [n.at(j) for j in range(n.size())]
        if not all(it.isInt() or it.isReal() for it in items):
            raise InputError(
                f"{where}.{key}", "a sequence of numbers", "a sequence of other nodes"
            )
        return [it.real() for it in items]
    try:
        m = n.mat() if n.isMap() else None
    except (cv2.error, SystemError):
        m = None
    if m is None:
        raise InputError(
            f"{where}.{key}",
            "an !!opencv-matrix or a sequence of numbers",
            "another kind of node",
        )
    return m


def _yaml_camera(node, where: str) -> Camera:
    """One camera of a YAML calibration, from its map.

    Parameters
    ----------
    node : cv2.FileNode
        The camera's map (name, image_width, image_height, K, dist, R or rvec, t).
    where : str
        The file and the camera's place in it, for errors.

    Returns
    -------
    Camera

    Raises
    ------
    InputError
        A non-map node, a missing field, wrong shapes or non-finite numbers.
    """
    if not node.isMap():
        raise InputError(
            where,
            "a map with name, image_width, image_height, K, dist, R or rvec, t",
            "a non-map node",
        )
    name = _yaml_field(node, where, "name", "str")
    if not name:
        raise InputError(f"{where}.name", "a non-empty string", repr(name))
    size = _image_size(
        f"{where}.image_width/image_height",
        [_yaml_field(node, where, "image_width", "num"), _yaml_field(node, where, "image_height", "num")],
    )
    K = _intrinsics(f"{where}.K", _yaml_field(node, where, "K"))
    dist = _distortion(f"{where}.dist", _yaml_field(node, where, "dist"))
    R = _yaml_field(node, where, "R", required=False)
    if R is not None:
        R = _rotation(
            f"{where}.R",
            np.asarray(R, dtype=np.float64).reshape(3, 3) if np.size(R) == 9 else R,
        )
    else:
        rvec = _yaml_field(node, where, "rvec", required=False)
        if rvec is None:
            raise InputError(
                f"{where}.R",
                "an 'R' (3x3) or 'rvec' (3) field",
                f"neither (fields: {node.keys()})",
            )
        R = _rotation(
            f"{where}.rvec",
            np.asarray(rvec, dtype=np.float64).reshape(-1) if np.size(rvec) == 3 else rvec,
        )
    t = _translation(f"{where}.t", _yaml_field(node, where, "t"))
    return _camera(where, name, K, dist, size, R, t)


def read_calibration_yaml(path: str | os.PathLike) -> Rig:
    """Read an OpenCV FileStorage YAML calibration (see the module docstring).

    Parameters
    ----------
    path : str or PathLike

    Returns
    -------
    Rig

    Raises
    ------
    InputError
        Missing or unparsable file, no ``cameras`` sequence, a camera missing a
        field, wrong shapes or non-finite numbers.
    """
    path = Path(path)
    fs = _open_yaml(path)
    try:
        seq = fs.getNode(_YAML_CAMERAS)
        if seq.empty() or seq.isNone():
            raise InputError(
                f"{path}: {_YAML_CAMERAS}", "a sequence of camera maps", "no such node"
            )
        if not seq.isSeq():
            raise InputError(
                f"{path}: {_YAML_CAMERAS}", "a sequence of camera maps", "a non-sequence node"
            )
        cameras = []
        for i in range(seq.size()):
            node = seq.at(i)
            cameras.append(_yaml_camera(node, f"{path}: {_YAML_CAMERAS}[{i}]"))
    finally:
        fs.release()
    return _rig(path, cameras)


def write_calibration_yaml(path: str | os.PathLike, rig: Rig) -> Path:
    """Write a rig as OpenCV FileStorage YAML, atomically.

    Parameters
    ----------
    path : str or PathLike
    rig : Rig

    Returns
    -------
    Path
    """
    if not isinstance(rig, Rig) or len(rig) == 0:
        raise InputError(
            "write_calibration_yaml: rig", "a Rig with at least one camera", f"{rig!r}"
        )
    fs = cv2.FileStorage(
        ".yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY | cv2.FILE_STORAGE_FORMAT_YAML
    )
    fs.startWriteStruct(_YAML_CAMERAS, cv2.FileNode_SEQ)
    for cam in rig:
        fs.startWriteStruct("", cv2.FileNode_MAP)
        fs.write("name", cam.name)
        fs.write("image_width", int(cam.size[0]))
        fs.write("image_height", int(cam.size[1]))
        fs.write("K", np.ascontiguousarray(cam.K))
        fs.write("dist", np.ascontiguousarray(cam.dist.reshape(1, -1)))
        fs.write("R", np.ascontiguousarray(cam.R))
        fs.write("t", np.ascontiguousarray(cam.t.reshape(3, 1)))
        fs.endWriteStruct()
    fs.endWriteStruct()
    return atomic_write_text(path, fs.releaseAndGetString())
