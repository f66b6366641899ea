"""3D joint trajectories in the biomechanics formats: TRC, C3D and CSV.

Inside the toolkit, trajectories are metres in the calibration's world frame
(Z up).  The files follow their own conventions, converted here at the edge:

TRC (OpenSim, as Pose2Sim writes it)
    Tab-separated text, metres, **Y up**: the file's ``(X, Y, Z)`` are the world's
    ``(Y, Z, X)`` (Pose2Sim's ``zup2yup``).  Five header lines (``PathFileType``, the
    rates / counts / units line with ``OrigDataStartFrame`` = the first frame number,
    the marker names, ``X1 Y1 Z1 ...``), then one row per frame: ``Frame#`` = frame
    number + 1 and ``Time`` = ``Frame#`` / rate, as in Pose2Sim's files.  A missing
    marker is an empty field.  A TRC holds no free-form metadata: the filter's cut-off
    goes into the other outputs (and the recipe's ``poses3d.json``).
C3D (through ezc3d)
    Millimetres, with the TRC's axes, as Pose2Sim's ``trc_to_c3d`` writes them
    (Visual3D reads them with the screen axes ``X = +Z``, ``Y = +Y``); a missing marker is
    NaN with residual -1; ``POINT:RATE``, ``POINT:LABELS``, the header's first frame;
    metadata as strings in the parameter group ``TOOLKIT``.
CSV
    ``#``-comment lines with the metadata (``# key: value``), then ``frame,time,
    <name>_x,<name>_y,<name>_z,...`` in metres in the world frame (Z up); missing = empty.

Frames are written as a contiguous range: frames absent in between become rows of
NaN (:meth:`Trajectories.contiguous`).
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.io.atomic import atomic_path, atomic_write_text
from toolkit.io.text import read_text

__all__ = ["Trajectories", "world_to_trc", "trc_to_world", "write_trc", "read_trc", "write_c3d", "read_c3d",
           "write_csv", "read_csv", "C3D_GROUP", "EXPORTS", "skeleton14_trajectories", "write_trajectories"]

#: C3D parameter group holding the toolkit's metadata (strings).
C3D_GROUP = "TOOLKIT"
#: Trajectory file kinds written by :func:`write_trajectories`.
EXPORTS = ("trc", "c3d", "csv")
#: TRC units understood by the reader, in metres.
TRC_UNITS = {"m": 1.0, "mm": 0.001, "cm": 0.01}


def _in_file(path: Path, make):
    """``make()``, its InputError re-raised naming ``path`` (a read file's content checked by the dataclass)."""
    try:
        return make()
    except InputError as e:
        raise InputError(f"{path}: {e.where}", e.expected, e.found) from None


def world_to_trc(xyz: np.ndarray) -> np.ndarray:
    """World (Z up) to TRC / OpenSim axes (Y up): ``(x, y, z) -> (y, z, x)``; shape (..., 3)."""
    return np.asarray(xyz, float)[..., [1, 2, 0]]


def trc_to_world(xyz: np.ndarray) -> np.ndarray:
    """TRC / OpenSim axes (Y up) to world (Z up): ``(X, Y, Z) -> (Z, X, Y)``; shape (..., 3)."""
    return np.asarray(xyz, float)[..., [2, 0, 1]]


@dataclass(frozen=True, eq=False)
class Trajectories:
    """Named 3D trajectories.

    Attributes
    ----------
    positions : ndarray of shape (T, M, 3)
        Metres, world frame (Z up); NaN = missing.
    names : tuple of str
        ``M`` marker names (no tabs, commas or newlines).
    frames : ndarray of shape (T,) of int
        Frame numbers (0-based), increasing.
    rate : float
        Frames per second.
    metadata : dict of str to str
        Free-form facts carried by the C3D and CSV outputs (filter, sources, ...).
    """

    positions: np.ndarray
    names: tuple[str, ...]
    frames: np.ndarray
    rate: float
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        pos = np.asarray(self.positions, float)
        if pos.ndim != 3 or pos.shape[2] != 3:
            raise InputError("positions", "an array of shape (T, M, 3)", f"shape {pos.shape}")
        names = tuple(str(n) for n in self.names)
        if len(names) != pos.shape[1]:
            raise InputError("names", f"{pos.shape[1]} names, one per marker", f"{len(names)}")
        bad = [n for n in names if not n or any(ch in n for ch in "\t\n\r,")]
        if bad or len(set(names)) != len(names):
            raise InputError("names", "distinct non-empty names without tabs, commas or newlines",
                             repr(bad or names))
        frames = np.asarray(self.frames)
        if frames.shape != (pos.shape[0],) or (frames.size and not np.issubdtype(frames.dtype, np.integer)):
            raise InputError("frames", f"{pos.shape[0]} integer frame numbers", f"{frames.dtype} {frames.shape}")
        if frames.size > 1 and np.any(np.diff(frames) <= 0):
            raise InputError("frames", "increasing frame numbers", f"{frames[:6].tolist()}...")
        rate = float(self.rate)
        if not (math.isfinite(rate) and rate > 0):
            raise InputError("rate", "a positive frame rate (Hz)", repr(self.rate))
        meta = {str(k): str(v) for k, v in dict(self.metadata).items()}
        if any("\n" in k + v or ":" in k for k, v in meta.items()):
            raise InputError("metadata", "keys without ':' and values on one line", repr(meta)[:80])
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "frames", frames.astype(int))
        object.__setattr__(self, "rate", rate)
        object.__setattr__(self, "metadata", meta)

    def contiguous(self) -> "Trajectories":
        """The same trajectories over every frame from the first to the last (NaN rows added)."""
        if self.frames.size == 0 or self.frames[-1] - self.frames[0] + 1 == len(self.frames):
            return self
        frames = np.arange(self.frames[0], self.frames[-1] + 1)
        pos = np.full((len(frames),) + self.positions.shape[1:], np.nan)
        pos[self.frames - frames[0]] = self.positions
        return Trajectories(pos, self.names, frames, self.rate, self.metadata)


def _num(v: float) -> str:
    return "" if not math.isfinite(v) else repr(float(v))


def _rate_text(rate: float) -> str:
    return str(int(rate)) if float(rate).is_integer() else repr(float(rate))


# --------------------------------------------------------------------------- TRC

def trc_text(traj: Trajectories, file_name: str) -> str:
    """The TRC file of ``traj`` (see the module docstring); ``file_name`` goes into the first line."""
    t = traj.contiguous()
    n_frames, n_markers = t.positions.shape[:2]
    rate = _rate_text(t.rate)
    first = int(t.frames[0]) if n_frames else 0
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{file_name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
             "\t".join([rate, rate, str(n_frames), str(n_markers), "m", rate, str(first), str(n_frames)]),
             "Frame#\tTime\t" + "\t\t\t".join(t.names) + "\t\t",
             "\t\t" + "\t".join(f"X{i + 1}\tY{i + 1}\tZ{i + 1}" for i in range(n_markers))]
    yup = world_to_trc(t.positions).reshape(n_frames, -1)
    for f, row in zip(t.frames, yup):
        number = int(f) + 1
        lines.append("\t".join([str(number), repr(number / t.rate)] + [_num(v) for v in row]))
    return "\n".join(lines) + "\n"


def write_trc(path: str | os.PathLike, traj: Trajectories) -> Path:
    """Write ``traj`` as a TRC file (Pose2Sim / OpenSim convention), atomically; returns the path."""
    p = Path(path)
    return atomic_write_text(p, trc_text(traj, p.name))


def read_trc(path: str | os.PathLike) -> Trajectories:
    """Read a TRC file into world-frame metres.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    Trajectories
        ``frames`` = ``Frame#`` - 1, ``rate`` = ``DataRate``; units converted to metres
        and axes to the world frame (:func:`trc_to_world`).

    Raises
    ------
    InputError
        A missing file, a header that is not a TRC header, unknown units, a row with a
        wrong number of fields or a non-number (named with its line).
    """
    p = Path(path)
    lines = read_text(p, "a readable TRC file").splitlines()
    if len(lines) < 5 or not lines[0].startswith("PathFileType") or not lines[1].startswith("DataRate"):
        raise InputError(str(p), "a TRC header (PathFileType, DataRate ... lines)", repr(lines[:1])[:80])
    keys = lines[1].split("\t")
    vals = lines[2].split("\t")
    head = dict(zip(keys, vals))
    try:
        rate = float(head["DataRate"])
        n_markers = int(head["NumMarkers"])
    except (KeyError, ValueError):
        raise InputError(f"{p}: line 3", "DataRate and NumMarkers numbers", repr(lines[2])[:80]) from None
    units = head.get("Units", "m").strip()
    if units not in TRC_UNITS:
        raise InputError(f"{p}: Units", f"one of {list(TRC_UNITS)}", repr(units))
    names = [n.strip() for n in lines[3].split("\t")[2:] if n.strip()]
    if len(names) != n_markers:
        raise InputError(f"{p}: line 4", f"{n_markers} marker names (NumMarkers)", f"{len(names)}")
    frames, rows = [], []
    for i, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        fields = line.split("\t")
        if len(fields) > 2 + 3 * n_markers and any(f.strip() for f in fields[2 + 3 * n_markers:]):
            raise InputError(f"{p}: line {i}", f"{2 + 3 * n_markers} fields", f"{len(fields)}")
        fields = fields[:2 + 3 * n_markers] + [""] * max(0, 2 + 3 * n_markers - len(fields))
        try:
            frames.append(int(float(fields[0])))
            float(fields[1])                                  # Time: a number (derived from Frame# here)
            rows.append([float(f) if f.strip() else np.nan for f in fields[2:]])
        except ValueError:
            raise InputError(f"{p}: line {i}", "numbers (or empty fields)", repr(line)[:80]) from None
    pos = np.array(rows, float).reshape(len(rows), n_markers, 3) * TRC_UNITS[units]
    return _in_file(p, lambda: Trajectories(trc_to_world(pos), tuple(names), np.array(frames, int) - 1, rate))


# --------------------------------------------------------------------------- C3D

def write_c3d(path: str | os.PathLike, traj: Trajectories) -> Path:
    """Write ``traj`` as a C3D file with ezc3d (millimetres, TRC axes), atomically; returns the path."""
    import ezc3d

    t = traj.contiguous()
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [t.rate]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(t.names)
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    n_frames, n_markers = t.positions.shape[:2]
    pts = np.ones((4, n_markers, n_frames))
    pts[:3] = np.transpose(world_to_trc(t.positions) * 1000.0, (2, 1, 0))
    residuals = np.where(np.isfinite(pts[:3]).all(axis=0), 0.0, -1.0)[None]
    c3d["data"]["points"] = pts
    c3d["data"]["meta_points"] = {"residuals": residuals,
                                  "camera_masks": np.zeros((7, n_markers, n_frames), bool)}
    if n_frames:
        c3d["header"]["points"]["first_frame"] = int(t.frames[0])
    c3d.add_parameter(C3D_GROUP, "AXES", ["X = world y, Y = world z (up), Z = world x"])
    for k, v in t.metadata.items():
        c3d.add_parameter(C3D_GROUP, k.upper()[:30], [v])
    p = Path(path)
    with atomic_path(p) as tmp:
        c3d.write(str(tmp))
    return p


def read_c3d(path: str | os.PathLike) -> Trajectories:
    """Read the points of a C3D file (ezc3d) into world-frame metres (TRC axes, like :func:`write_c3d`).

    Returns
    -------
    Trajectories
        ``metadata`` holds the strings of the ``TOOLKIT`` group (lower-case keys).

    Raises
    ------
    InputError
        A missing or unreadable file, or units other than mm / m.
    """
    from toolkit.io.c3d import open_c3d

    p = Path(path)
    c3d = open_c3d(p)
    par = c3d["parameters"]
    units = str(par["POINT"].get("UNITS", {}).get("value", ["mm"])[0]).strip() or "mm"
    if units not in ("mm", "m"):
        raise InputError(f"{p}: POINT:UNITS", "mm or m", repr(units))
    pts = np.array(c3d["data"]["points"][:3], float)                # (3, M, T)
    res = c3d["data"].get("meta_points", {}).get("residuals")
    if res is not None:
        pts[:, np.asarray(res)[0] < 0] = np.nan
    pos = np.transpose(pts, (2, 1, 0)) * (0.001 if units == "mm" else 1.0)
    names = tuple(str(n).strip() for n in par["POINT"]["LABELS"]["value"])
    first = int(c3d["header"]["points"]["first_frame"])
    meta = {}
    if C3D_GROUP in par:
        for k, v in par[C3D_GROUP].items():
            if isinstance(v, dict) and "value" in v and k not in ("__METADATA__", "AXES"):
                val = v["value"]
                meta[k.lower()] = str(val[0]) if len(val) else ""
    return _in_file(p, lambda: Trajectories(trc_to_world(pos), names, np.arange(first, first + pos.shape[0]),
                                            float(c3d["header"]["points"]["frame_rate"]), meta))


# --------------------------------------------------------------------------- CSV

def write_csv(path: str | os.PathLike, traj: Trajectories) -> Path:
    """Write ``traj`` as CSV (metres, world frame, metadata in ``#`` lines), atomically; returns the path."""
    t = traj.contiguous()
    buf = io.StringIO()
    meta = {"units": "m", "axes": "world frame (calibration), z up", "rate_hz": _rate_text(t.rate), **t.metadata}
    for k, v in meta.items():
        buf.write(f"# {k}: {v}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["frame", "time"] + [f"{n}_{a}" for n in t.names for a in "xyz"])
    for f, row in zip(t.frames, t.positions.reshape(len(t.frames), -1)):
        w.writerow([int(f), repr(int(f) / t.rate)] + [_num(v) for v in row])
    return atomic_write_text(path, buf.getvalue())


def read_csv(path: str | os.PathLike) -> Trajectories:
    """Read a CSV written by :func:`write_csv`.

    Raises
    ------
    InputError
        A missing file, a header without ``frame,time`` and ``<name>_x/_y/_z`` triples, or a bad row.
    """
    p = Path(path)
    text = read_text(p, "a trajectories CSV file")
    meta, body = {}, []
    for line in text.splitlines():
        if line.startswith("#"):
            k, _, v = line[1:].partition(":")
            meta[k.strip()] = v.strip()
        elif line.strip():
            body.append(line)
    rows = list(csv.reader(body))
    if not rows or rows[0][:2] != ["frame", "time"] or (len(rows[0]) - 2) % 3:
        raise InputError(f"{p}: header", "frame,time,<name>_x,<name>_y,<name>_z,...", repr(rows[:1])[:80])
    cols = rows[0][2:]
    names = [c[:-2] for c in cols[::3]]
    if [f"{n}_{a}" for n in names for a in "xyz"] != cols:
        raise InputError(f"{p}: header", "<name>_x,<name>_y,<name>_z triples", repr(cols[:6]))
    try:
        frames = [int(r[0]) for r in rows[1:]]
        vals = [[float(v) if v else np.nan for v in r[2:]] for r in rows[1:]]
        rate = float(meta.pop("rate_hz"))
    except (ValueError, KeyError, IndexError) as e:
        raise InputError(str(p), "integer frames, numbers and a '# rate_hz:' line", f"{type(e).__name__}: {e}") \
            from None
    if any(len(v) != len(cols) for v in vals):
        raise InputError(str(p), f"{len(cols) + 2} fields per row", "rows of other lengths")
    for k in ("units", "axes"):
        meta.pop(k, None)
    return _in_file(p, lambda: Trajectories(np.array(vals, float).reshape(len(frames), len(names), 3), tuple(names),
                                            np.array(frames, int), rate, meta))


# --------------------------------------------------------------------------- the 14 joints

def skeleton14_trajectories(joints: np.ndarray, joint_names, frames: np.ndarray, rate: float,
                            metadata: dict | None = None) -> Trajectories:
    """The 14-joint skeleton as trajectories under Pose2Sim's marker names, in Pose2Sim's order.

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3)
        Metres, world frame; NaN = missing.
    joint_names : sequence of str
        The 14 joint names of ``joints`` (``JOINTS_14``).
    frames : ndarray of shape (T,) of int
    rate : float
        Frames per second.
    metadata : dict, optional

    Returns
    -------
    Trajectories
        Markers named by :data:`~toolkit.skeleton.mappings.POSE2SIM_MARKERS`.
    """
    from toolkit.skeleton.mappings import POSE2SIM_MARKERS

    j = np.asarray(joints, float)
    names = [str(n) for n in joint_names]
    if j.ndim != 3 or j.shape[1:] != (len(names), 3) or sorted(names) != sorted(POSE2SIM_MARKERS):
        raise InputError("joints", f"an array of shape (T, 14, 3) with joints {sorted(POSE2SIM_MARKERS)}",
                         f"shape {j.shape}, joints {names}")
    idx = [names.index(k) for k in POSE2SIM_MARKERS]
    return Trajectories(j[:, idx], tuple(POSE2SIM_MARKERS.values()), np.asarray(frames).astype(int), rate,
                        metadata or {})


def write_trajectories(stem: str | os.PathLike, traj: Trajectories, kinds=EXPORTS) -> list[Path]:
    """Write ``traj`` as ``<stem>.trc`` / ``.c3d`` / ``.csv`` (the ``kinds`` asked for); returns the paths."""
    writers = {"trc": write_trc, "c3d": write_c3d, "csv": write_csv}
    bad = [k for k in kinds if k not in writers]
    if bad:
        raise InputError("kinds", f"some of {list(EXPORTS)}", repr(bad))
    stem = Path(stem)
    return [writers[k](stem.with_name(f"{stem.name}.{k}"), traj) for k in kinds]
