"""Reading a run's 3D output and writing joint angles (``angles.csv``, ``summary.json``).

The 3D outputs of the toolkit's systems (:mod:`toolkit.biomech.mapping`):
``poses3d.npz`` (keypoints, free viewpoint), ``people3d.npz`` (free
viewpoint with several people: one person at a time), ``joint_centres.npz``
with ``trajectories.npz`` (markers), ``skeleton.npz`` (depth), ``joints.npz``
(soft body).  Every write is atomic (:mod:`toolkit.io.atomic`).
"""

from __future__ import annotations

import io
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.biomech.angles import JointAngles
from toolkit.biomech.mapping import joints_to_points, marker_points
from toolkit.errors import InputError
from toolkit.io.atomic import atomic_write_text

#: Result files of the systems, in the order they are looked for in a run folder, with the system's name.
RUN_FILES = (("poses3d.npz", "keypoints / free viewpoint"), ("joint_centres.npz", "markers"),
             ("skeleton.npz", "depth"), ("joints.npz", "soft body"))
#: The free-viewpoint recipe's file of several people: ``joints`` (P, T, 14, 3), ``people`` (P,), ``names``.
PEOPLE_FILE = "people3d.npz"


@dataclass(frozen=True)
class RunPoints:
    """A run's 3D output as landmarks.

    Attributes
    ----------
    points : dict of str to ndarray of shape (T, 3)
        Landmarks (metres, world, NaN = missing), joints and markers.
    joint_names : tuple of str
        The system's own joints among ``points`` (after renaming).
    fps : float or None
        Frames per second when the file says.
    system : str
    source : str
        The file read.
    person : str or None
        The person taken from a ``people3d.npz``; None for a single-person file.
    people : tuple of str
        Every person of the run's ``people3d.npz`` (empty without one).
    """

    points: dict
    joint_names: tuple
    fps: float | None
    system: str
    source: str
    person: str | None = None
    people: tuple = ()

    @property
    def n_frames(self) -> int:
        return len(next(iter(self.points.values())))


def _fps(data, folder: Path) -> float | None:
    for key in ("frame_rate", "fps"):
        if key in data.files:
            v = float(np.asarray(data[key]))
            if np.isfinite(v) and v > 0:
                return v
    meta = folder / "poses3d.json"
    if meta.exists():
        v = json.loads(meta.read_text()).get("frame_rate_hz")
        if v:
            return float(v)
    return None


def run_people(path: str | os.PathLike) -> tuple:
    """The people of a run's ``people3d.npz`` (a run folder or the file); empty without one.

    Raises
    ------
    InputError
        A ``people3d.npz`` without ``people``.
    """
    path = Path(path)
    file = path / PEOPLE_FILE if path.is_dir() else path
    if file.name != PEOPLE_FILE or not file.is_file():
        return ()
    with np.load(file, allow_pickle=False) as data:
        if "people" not in data.files:
            raise InputError(f"{file}: people", "the people's names (P,)", f"keys {data.files}")
        return tuple(str(n) for n in data["people"])


def _load_person(file: Path, person: str | None) -> RunPoints:
    """One person of a ``people3d.npz`` as landmarks."""
    people = run_people(file)
    if person is None or person not in people:
        raise InputError(f"{file}: people", f"a person among {list(people)} (--person NAME, or --person all)",
                         "no --person" if person is None else repr(person))
    with np.load(file, allow_pickle=False) as data:
        for key in ("joints", "names"):
            if key not in data.files:
                raise InputError(f"{file}: {key}", "the people's 3D joints (P, T, J, 3) and their names",
                                 f"keys {data.files}")
        joints = np.asarray(data["joints"], float)
        if joints.ndim != 4 or len(joints) != len(people):
            raise InputError(f"{file}: joints", f"an array of shape ({len(people)}, T, J, 3)", f"shape {joints.shape}")
        names = [str(n) for n in data["names"]]
        fps = _fps(data, file.parent)
    points = joints_to_points(joints[people.index(person)], names)
    return RunPoints(points=points, joint_names=tuple(points), fps=fps, system="free viewpoint (several people)",
                     source=str(file), person=person, people=people)


def load_run(path: str | os.PathLike, person: str | None = None) -> RunPoints:
    """The 3D output of a run folder (or one of its ``.npz`` files).

    Parameters
    ----------
    path : path
        A run folder holding one of :data:`RUN_FILES` (or :data:`PEOPLE_FILE`), or such a file.
    person : str, optional
        One person of the run's :data:`PEOPLE_FILE` (the free-viewpoint recipe with several people).
        Without it a folder gives its single-person file (``poses3d.npz``: the main person) and
        :attr:`RunPoints.people` lists the others.

    Returns
    -------
    RunPoints

    Raises
    ------
    InputError
        No result file; a file without ``joints`` and ``names``; a ``people3d.npz`` without ``person``,
        or a person it does not hold (the message lists the people).
    """
    path = Path(path)
    if person is not None or path.name == PEOPLE_FILE:
        file = path / PEOPLE_FILE if path.is_dir() else path
        if not file.is_file():
            raise InputError(str(file), f"a run with several people ({PEOPLE_FILE}) for --person {person}",
                             "no such file")
        return _load_person(file, person)
    if path.is_dir():
        found = [(path / f, s) for f, s in RUN_FILES if (path / f).exists()]
        if not found and (path / PEOPLE_FILE).is_file():
            return _load_person(path / PEOPLE_FILE, None)       # refused with the list of people
        if not found:
            raise InputError(str(path), f"a run folder with one of {[f for f, _ in RUN_FILES]}", "none of them")
        file, system = found[0]
    elif path.is_file():
        file, system = path, dict(RUN_FILES).get(path.name, "unknown")
    else:
        raise InputError(str(path), "a run folder or a joints .npz file", "no such file or folder")
    with np.load(file, allow_pickle=False) as data:
        for key in ("joints", "names"):
            if key not in data.files:
                raise InputError(f"{file}: {key}", "an array of the 3D joints and their names",
                                 f"keys {data.files}")
        joints, names = np.asarray(data["joints"], float), [str(n) for n in data["names"]]
        fps = _fps(data, file.parent)
    points = joints_to_points(joints, names)
    joint_names = tuple(points)
    trajectories = file.parent / "trajectories.npz"
    if file.name == "joint_centres.npz" and trajectories.exists():
        with np.load(trajectories, allow_pickle=False) as t:
            if "labels" in t.files and "positions" in t.files:
                for k, v in marker_points(t["labels"], t["positions"]).items():
                    if len(v) == len(joints):
                        points.setdefault(k, v)
    return RunPoints(points=points, joint_names=joint_names, fps=fps, system=system, source=str(file),
                     people=run_people(file.parent))


def angles_csv_text(angles: JointAngles) -> str:
    """``angles`` as CSV text: a ``time`` column (s) and one column per angle (degrees), NaN empty."""
    buf = io.StringIO()
    buf.write(",".join(("time",) + tuple(angles.names)) + "\n")
    for t, row in zip(angles.time, angles.degrees):
        buf.write(f"{t:.6f}," + ",".join("" if not np.isfinite(v) else f"{v:.4f}" for v in row) + "\n")
    return buf.getvalue()


def write_angles_csv(path: str | os.PathLike, angles: JointAngles) -> Path:
    """Write :func:`angles_csv_text` atomically to ``path``."""
    return atomic_write_text(path, angles_csv_text(angles))


def read_angles_csv(path: str | os.PathLike) -> JointAngles:
    """Read an ``angles.csv`` back (empty cells are NaN).

    Raises
    ------
    InputError
        A file whose first column is not ``time``.
    """
    path = Path(path)
    lines = path.read_text().splitlines()
    header = lines[0].split(",") if lines else []
    if not header or header[0] != "time":
        raise InputError(f"{path}: header", "a first column 'time'", repr(header[:1]))
    rows = [[float(x) if x else np.nan for x in line.split(",")] for line in lines[1:] if line]
    a = np.array(rows, float).reshape(-1, len(header))
    return JointAngles(time=a[:, 0], names=tuple(header[1:]), degrees=a[:, 1:])


def write_json(path: str | os.PathLike, data: dict) -> Path:
    """Write ``data`` as indented JSON, atomically."""
    return atomic_write_text(path, json.dumps(data, indent=2) + "\n")
