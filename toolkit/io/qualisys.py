"""Qualisys Track Manager calibrations (``*.qca.txt``, XML) read as a :class:`~toolkit.cameras.Rig`.

Layout (the fields used; QTM writes more)::

    <calibration ...>
      <cameras>
        <camera active="1" serial="cam01" viewrotation="0" ...>
          <fov_video left="0" top="0" right="1087" bottom="1919"/>
          <transform x=".." y=".." z=".." r11=".." ... r33=".."/>
          <intrinsic focalLengthU=".." focalLengthV=".." centerPointU=".." centerPointV=".."
                     radialDistortion1=".." radialDistortion2=".." radialDistortion3=".."
                     tangentalDistortion1=".." tangentalDistortion2=".."
                     sensorMinU=".." sensorMaxU=".." sensorMinV=".." sensorMaxV=".." skew=".."/>
        </camera>
      </cameras>
    </calibration>

Conversion (checked against Pose2Sim's own conversion of the same file, ``Calib_qualisys.toml`` of
its demo, to 1e-6 px and 1e-9 m, ``tests/io/test_io_qualisys.py``):

* ``transform``: ``x, y, z`` is the camera centre in millimetres, ``r11..r33`` the matrix whose
  rows are the camera's axes in the world, with the camera looking along its -z and y up.  The
  world-to-camera rotation in the OpenCV convention is ``diag(1, -1, -1) @ R`` and the translation
  ``-R_cv @ centre / 1000`` (metres).
* ``intrinsic``: focal lengths and principal point in sensor sub-pixels; the sub-pixel factor is the
  sensor's width over the video's (64 for the Qualisys Miqus video cameras); the principal point is
  shifted by the video window's ``left`` / ``top``.  The image size is the ``fov_video`` window.
* distortion ``(k1, k2, p1, p2, k3)``: the file's coefficients divided by the same factor, as Pose2Sim
  does.  Whether QTM's coefficients really act on sub-pixel coordinates is not documented; on the
  demo they move a corner pixel by well under a pixel either way of reading them.

Inactive cameras (``active="0"``) are skipped.  A ``viewrotation`` other than 0 (a camera whose video is
rotated in QTM) is refused: the file does not say how the video on disk was rotated.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from toolkit.cameras import Camera, Rig
from toolkit.cameras.validate import check_rig
from toolkit.errors import InputError
from toolkit.io.text import require_file

__all__ = ["QCA_SUFFIXES", "is_qca", "read_calibration_qca"]

#: File names read as Qualisys calibrations (the suffix checked case-insensitively).
QCA_SUFFIXES = (".qca.txt", ".qca")
#: Flips the camera's y and z axes: QTM's camera looks along -z with y up, OpenCV's along +z with y down.
_FLIP_YZ = np.diag([1.0, -1.0, -1.0])
_TRANSFORM = ("x", "y", "z") + tuple(f"r{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))
_INTRINSIC = ("focalLengthU", "focalLengthV", "centerPointU", "centerPointV", "radialDistortion1",
              "radialDistortion2", "tangentalDistortion1", "tangentalDistortion2", "sensorMinU", "sensorMaxU")
_FOV = ("left", "top", "right", "bottom")


def is_qca(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a Qualisys calibration by its suffix (``.qca.txt`` or ``.qca``)."""
    name = Path(path).name.lower()
    return any(name.endswith(s) for s in QCA_SUFFIXES)


def _floats(where: str, element: ET.Element, names: tuple[str, ...]) -> dict[str, float]:
    """The attributes ``names`` of ``element`` as finite floats, or an InputError naming the attribute."""
    out = {}
    for n in names:
        text = element.get(n)
        if text is None:
            raise InputError(f"{where}@{n}", f"a '{n}' attribute", f"none (attributes: {sorted(element.attrib)})")
        try:
            v = float(text)
        except ValueError:
            raise InputError(f"{where}@{n}", "a number", repr(text)) from None
        if not np.isfinite(v):
            raise InputError(f"{where}@{n}", "a finite number", repr(text))
        out[n] = v
    return out


def _child(where: str, camera: ET.Element, tag: str) -> ET.Element:
    element = camera.find(tag)
    if element is None:
        raise InputError(f"{where}/{tag}", f"a <{tag}> element in every camera",
                         f"none (children: {[c.tag for c in camera]})")
    return element


def _rotation(where: str, t: dict[str, float]) -> np.ndarray:
    """QTM's rotation matrix, checked to be a rotation and made exactly orthonormal."""
    R = np.array([[t[f"r{i}{j}"] for j in (1, 2, 3)] for i in (1, 2, 3)])
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or np.linalg.det(R) <= 0:
        raise InputError(f"{where}/transform@r11..r33", "a rotation matrix (orthonormal, determinant +1)",
                         f"{np.round(R, 6).tolist()}")
    u, _, vt = np.linalg.svd(R)
    return u @ vt


def _qca_camera(path: Path, index: int, camera: ET.Element) -> Camera:
    name = camera.get("serial") or f"cam{index + 1:02d}"
    where = f"{path}: camera {index} ({name})"
    rotation = camera.get("viewrotation", "0")
    if rotation.strip() not in ("0", "0.0", ""):
        raise InputError(f"{where}@viewrotation", "0 (videos as the sensor records them)",
                         f"{rotation!r}: a rotated view, which the file does not say how to undo")
    t = _floats(f"{where}/transform", _child(where, camera, "transform"), _TRANSFORM)
    intrinsic = _child(where, camera, "intrinsic")
    intr = _floats(f"{where}/intrinsic", intrinsic, _INTRINSIC)
    k3 = (_floats(f"{where}/intrinsic", intrinsic, ("radialDistortion3",))["radialDistortion3"]
          if intrinsic.get("radialDistortion3") is not None else 0.0)
    fov = _floats(f"{where}/fov_video", _child(where, camera, "fov_video"), _FOV)
    width, height = fov["right"] - fov["left"] + 1, fov["bottom"] - fov["top"] + 1
    if width <= 0 or height <= 0:
        raise InputError(f"{where}/fov_video", "right >= left and bottom >= top", f"{fov}")
    fov_max = camera.find("fov_video_max")
    full_width = (float(fov_max.get("right", width - 1)) - float(fov_max.get("left", 0)) + 1
                  if fov_max is not None else width)
    sensor = intr["sensorMaxU"] - intr["sensorMinU"]
    if sensor <= 0:
        raise InputError(f"{where}/intrinsic@sensorMaxU", "a sensor wider than 0", f"{sensor}")
    sub = float(np.round(sensor / full_width))   # sub-pixels per pixel: 64 on the Miqus video cameras
    K = np.array([[intr["focalLengthU"] / sub, 0.0, intr["centerPointU"] / sub - fov["left"]],
                  [0.0, intr["focalLengthV"] / sub, intr["centerPointV"] / sub - fov["top"]],
                  [0.0, 0.0, 1.0]])
    dist = np.array([intr["radialDistortion1"], intr["radialDistortion2"], intr["tangentalDistortion1"],
                     intr["tangentalDistortion2"], k3]) / sub
    R_cv = _FLIP_YZ @ _rotation(where, t)
    centre = np.array([t["x"], t["y"], t["z"]]) / 1000.0
    T = np.eye(4)
    T[:3, :3] = R_cv
    T[:3, 3] = -R_cv @ centre
    try:
        return Camera(name, K, dist, (int(width), int(height)), T)
    except InputError as e:
        raise InputError(f"{where}: {e.where}", e.expected, e.found) from e


def read_calibration_qca(path: str | os.PathLike) -> Rig:
    """Read a Qualisys ``.qca.txt`` calibration (see the module docstring for the conversion).

    Parameters
    ----------
    path : str or PathLike

    Returns
    -------
    Rig
        The active cameras in file order, named by their ``serial`` attribute; world frame and
        metres as in the file (QTM: z up).

    Raises
    ------
    InputError
        Missing file, malformed XML (with its line and column), no ``<cameras>`` or no active camera,
        a camera without ``transform`` / ``intrinsic`` / ``fov_video`` or with a missing or
        non-numeric attribute, a matrix that is not a rotation, a rotated view.
    """
    path = require_file(path, "an existing Qualisys calibration file (.qca.txt)")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        line, col = e.position
        raise InputError(f"{path}: line {line}, column {col}", "well-formed Qualisys XML",
                         f"an XML error ({e})") from None
    cameras_el = root.find("cameras") if root.tag != "cameras" else root
    if cameras_el is None:
        raise InputError(f"{path}: <{root.tag}>", "a <cameras> element holding <camera> elements",
                         f"none (children: {[c.tag for c in root]})")
    cams = [c for c in cameras_el.findall("camera") if c.get("active", "1").strip() != "0"]
    if not cams:
        raise InputError(f"{path}: <cameras>", "at least one active <camera>",
                         f"{len(cameras_el.findall('camera'))} cameras, none active")
    cameras = [_qca_camera(path, i, c) for i, c in enumerate(cams)]
    try:
        rig = Rig(tuple(cameras))
    except InputError as e:
        raise InputError(f"{path}: {e.where}", e.expected, e.found) from e
    return check_rig(rig, str(path))
