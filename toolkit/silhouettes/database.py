"""The database of reference silhouettes with known 2D poses (source 000 §2.1, claim 1).

Every entry holds a silhouette descriptor (:mod:`toolkit.silhouettes.descriptor`,
stored as uint8 levels ``round(255 v)``), the 14 joints of ``SKELETON_14``
normalised to the silhouette's bounding box, metadata saying where the entry
came from, and optionally an optical-flow descriptor.  The database is saved
to and loaded from one ``.npz`` file (:data:`FORMAT_NAME`, version
:data:`FORMAT_VERSION`) and grows when user-corrected poses are added
(claim 7).  Querying is in :mod:`toolkit.silhouettes.query`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.errors import InputError
from toolkit.silhouettes.descriptor import (
    DESCRIPTOR_LEVELS,
    DESCRIPTOR_SIZE,
    SILHOUETTE_GRID,
    bounding_box,
    normalise_joints,
    quantise_descriptor,
    silhouette_descriptor,
)
from toolkit.skeleton import SKELETON_14

#: Value of the ``format`` field of a database file.
FORMAT_NAME = "billboard-toolkit silhouette database"
#: Version of the file layout written by :meth:`SilhouetteDatabase.save`.
FORMAT_VERSION = 1
#: Length of a flow descriptor (dx and dy grids).
FLOW_SIZE = 2 * DESCRIPTOR_SIZE
#: ``motion`` of entries added by a user correction.
USER_MOTION = "user"

_N_JOINTS = SKELETON_14.n_joints


@dataclass(frozen=True)
class DatabaseEntry:
    """One reference silhouette and its 2D pose.

    Attributes
    ----------
    descriptor : ndarray of shape (1280,)
        Cell values in [0, 1] (float) or stored levels 0..255 (uint8).
    joints : ndarray of shape (14, 2)
        Joints normalised to the silhouette's bounding box, finite.
    motion : str
        Source motion (``"walk"``, ..., a BVH file name, or ``"user"``).
    azimuth_deg, elevation_deg : float
        Viewpoint relative to the subject (azimuth 0 = seen from the front,
        90 = from the subject's left, counter-clockwise seen from above;
        elevation above the horizontal); NaN when unknown.
    frame : int
        Frame of the source motion or video (-1 when unknown).
    source : str
        Free text: generator seed, dataset and camera, etc.
    flow : ndarray of shape (2560,), optional
        Flow descriptor (:func:`toolkit.silhouettes.descriptor.flow_descriptor`).
    """

    descriptor: np.ndarray
    joints: np.ndarray
    motion: str = USER_MOTION
    azimuth_deg: float = float("nan")
    elevation_deg: float = float("nan")
    frame: int = -1
    source: str = ""
    flow: np.ndarray | None = None

    @classmethod
    def from_silhouette(cls, mask: np.ndarray, joints_px: np.ndarray, **metadata) -> "DatabaseEntry":
        """An entry from a silhouette mask and its joints in pixels.

        Parameters
        ----------
        mask : ndarray of shape (H, W), bool
        joints_px : ndarray of shape (14, 2)
            Pixels, finite.
        **metadata
            ``motion``, ``azimuth_deg``, ``elevation_deg``, ``frame``, ``source``, ``flow``.
        """
        box = bounding_box(mask)
        if box is None:
            raise InputError("mask", "a silhouette with at least one pixel", "an empty mask")
        return cls(silhouette_descriptor(mask, box), normalise_joints(joints_px, box), **metadata)


def _check_entry(entry: DatabaseEntry) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    d = np.asarray(entry.descriptor)
    if d.shape != (DESCRIPTOR_SIZE,):
        raise InputError("entry.descriptor", f"shape ({DESCRIPTOR_SIZE},)", f"shape {d.shape}")
    d = d if d.dtype == np.uint8 else quantise_descriptor(d)
    j = np.asarray(entry.joints, dtype=np.float64)
    if j.shape != (_N_JOINTS, 2) or not np.all(np.isfinite(j)):
        raise InputError("entry.joints", f"finite normalised joints of shape ({_N_JOINTS}, 2)",
                         f"shape {j.shape}" if j.shape != (_N_JOINTS, 2) else "NaN or infinite values")
    f = None
    if entry.flow is not None:
        f = np.asarray(entry.flow, dtype=np.float64)
        if f.shape != (FLOW_SIZE,) or not np.all(np.isfinite(f)):
            raise InputError("entry.flow", f"a finite array of shape ({FLOW_SIZE},)", f"shape {f.shape}")
    return d, j, f


class SilhouetteDatabase:
    """Reference silhouettes with known 2D poses.

    Parameters
    ----------
    descriptors : ndarray of shape (N, 1280), uint8
        Stored levels ``round(255 v)`` (float input in [0, 1] is quantised).
    joints : ndarray of shape (N, 14, 2)
        Joints normalised to each silhouette's bounding box.
    motion, source : sequence of str, length N, optional
    azimuth_deg, elevation_deg : ndarray of shape (N,), optional
        Degrees, NaN when unknown.
    frame : ndarray of shape (N,), int, optional
    flows : ndarray of shape (N, 2560), optional
        Flow descriptors; rows of NaN for entries without flow.

    Notes
    -----
    The arrays are exposed read-only; :meth:`add` and :meth:`extend` replace
    them with grown copies.  An empty database is allowed (queries on it
    raise :class:`~toolkit.errors.InputError`).
    """

    def __init__(self, descriptors, joints, *, motion=None, azimuth_deg=None, elevation_deg=None,
                 frame=None, source=None, flows=None):
        d = np.asarray(descriptors)
        if d.ndim != 2 or d.shape[1] != DESCRIPTOR_SIZE:
            raise InputError("descriptors", f"an array of shape (N, {DESCRIPTOR_SIZE})", f"shape {d.shape}")
        n = d.shape[0]
        d = d if d.dtype == np.uint8 else quantise_descriptor(d)
        j = np.asarray(joints, dtype=np.float32)
        if j.shape != (n, _N_JOINTS, 2) or not np.all(np.isfinite(j)):
            raise InputError("joints", f"finite normalised joints of shape ({n}, {_N_JOINTS}, 2)",
                             f"shape {j.shape}" if j.shape != (n, _N_JOINTS, 2) else "NaN or infinite values")

        def col(name, value, dtype, fill):
            if value is None:
                return np.full(n, fill, dtype=dtype)
            a = np.asarray(value, dtype=dtype)
            if a.shape != (n,):
                raise InputError(name, f"shape ({n},)", f"shape {a.shape}")
            return a

        self._d = d
        self._j = j
        self._motion = col("motion", motion, np.str_, "")
        self._az = col("azimuth_deg", azimuth_deg, np.float32, np.nan)
        self._el = col("elevation_deg", elevation_deg, np.float32, np.nan)
        self._frame = col("frame", frame, np.int32, -1)
        self._source = col("source", source, np.str_, "")
        if flows is None:
            self._flows = None
        else:
            f = np.asarray(flows, dtype=np.float16)
            if f.shape != (n, FLOW_SIZE):
                raise InputError("flows", f"shape ({n}, {FLOW_SIZE})", f"shape {f.shape}")
            self._flows = f
        self._cache: dict = {}

    # ------------------------------------------------------------ accessors
    @staticmethod
    def _ro(a):
        v = a.view()
        v.setflags(write=False)
        return v

    def __len__(self) -> int:
        return int(self._d.shape[0])

    @property
    def descriptors(self) -> np.ndarray:
        """(N, 1280) uint8 levels; ``descriptors / 255`` are the cell values."""
        return self._ro(self._d)

    @property
    def joints(self) -> np.ndarray:
        """(N, 14, 2) float32 joints normalised to each bounding box."""
        return self._ro(self._j)

    @property
    def motion(self) -> np.ndarray:
        return self._ro(self._motion)

    @property
    def azimuth_deg(self) -> np.ndarray:
        return self._ro(self._az)

    @property
    def elevation_deg(self) -> np.ndarray:
        return self._ro(self._el)

    @property
    def frame(self) -> np.ndarray:
        return self._ro(self._frame)

    @property
    def source(self) -> np.ndarray:
        return self._ro(self._source)

    @property
    def flows(self) -> np.ndarray | None:
        """(N, 2560) float16 flow descriptors (NaN rows: none), or None."""
        return None if self._flows is None else self._ro(self._flows)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return SKELETON_14.joint_names

    @property
    def cache(self) -> dict:
        """Derived data kept by queries (e.g. contour points); cleared when the database grows."""
        return self._cache

    def entry(self, i: int) -> DatabaseEntry:
        """Entry ``i`` (descriptor as uint8 levels)."""
        n = len(self)
        if not -n <= int(i) < n:
            raise InputError("entry index", f"an index in [0, {n})", str(i))
        f = None if self._flows is None or np.isnan(self._flows[i, 0]) else self._flows[i].astype(np.float64)
        return DatabaseEntry(self._d[i].copy(), self._j[i].astype(np.float64), str(self._motion[i]),
                             float(self._az[i]), float(self._el[i]), int(self._frame[i]),
                             str(self._source[i]), f)

    @classmethod
    def empty(cls) -> "SilhouetteDatabase":
        return cls(np.zeros((0, DESCRIPTOR_SIZE), np.uint8), np.zeros((0, _N_JOINTS, 2)))

    @classmethod
    def from_entries(cls, entries) -> "SilhouetteDatabase":
        db = cls.empty()
        db.extend_entries(entries)
        return db

    # --------------------------------------------------------------- growth
    def add(self, entry: DatabaseEntry) -> int:
        """Append one entry (e.g. a user-corrected pose); returns its index."""
        self.extend_entries([entry])
        return len(self) - 1

    def extend_entries(self, entries) -> None:
        """Append several :class:`DatabaseEntry` objects."""
        entries = list(entries)
        if not entries:
            return
        checked = [_check_entry(e) for e in entries]
        flows = None
        if self._flows is not None or any(f is not None for _, _, f in checked):
            flows = np.full((len(entries), FLOW_SIZE), np.nan, np.float16)
            for r, (_, _, f) in enumerate(checked):
                if f is not None:
                    flows[r] = f
        other = SilhouetteDatabase(
            np.stack([d for d, _, _ in checked]), np.stack([j for _, j, _ in checked]),
            motion=[e.motion for e in entries], azimuth_deg=[e.azimuth_deg for e in entries],
            elevation_deg=[e.elevation_deg for e in entries], frame=[e.frame for e in entries],
            source=[e.source for e in entries], flows=flows)
        self.extend(other)

    def extend(self, other: "SilhouetteDatabase") -> None:
        """Append every entry of another database."""
        if not isinstance(other, SilhouetteDatabase):
            raise InputError("other", "a SilhouetteDatabase", type(other).__name__)
        both = SilhouetteDatabase.concatenate([self, other])
        self.__dict__.update(both.__dict__)

    @classmethod
    def concatenate(cls, databases) -> "SilhouetteDatabase":
        """One database with the entries of several, in order."""
        dbs = list(databases)
        for i, db in enumerate(dbs):
            if not isinstance(db, SilhouetteDatabase):
                raise InputError(f"databases[{i}]", "a SilhouetteDatabase", type(db).__name__)
        if not dbs:
            return cls.empty()
        flows = None
        if any(db._flows is not None for db in dbs):
            flows = np.concatenate([db._flows if db._flows is not None
                                    else np.full((len(db), FLOW_SIZE), np.nan, np.float16) for db in dbs])
        cat = lambda name: np.concatenate([getattr(db, name) for db in dbs])  # noqa: E731
        return cls(cat("_d"), cat("_j"), motion=cat("_motion"), azimuth_deg=cat("_az"), elevation_deg=cat("_el"),
                   frame=cat("_frame"), source=cat("_source"), flows=flows)

    def subset(self, indices) -> "SilhouetteDatabase":
        """A new database holding the entries ``indices`` (e.g. for held-out tests)."""
        idx = np.asarray(indices)
        return SilhouetteDatabase(self._d[idx], self._j[idx], motion=self._motion[idx],
                                  azimuth_deg=self._az[idx], elevation_deg=self._el[idx],
                                  frame=self._frame[idx], source=self._source[idx],
                                  flows=None if self._flows is None else self._flows[idx])

    # ------------------------------------------------------------- file I/O
    def save(self, path: str | os.PathLike) -> Path:
        """Write the database to one ``.npz`` file atomically.

        Fields: ``format`` (:data:`FORMAT_NAME`), ``version``
        (:data:`FORMAT_VERSION`), ``grid`` (32, 40), ``levels`` (255),
        ``joint_names`` (14,), ``descriptors`` (N, 1280) uint8, ``joints``
        (N, 14, 2) float32, ``motion`` (N,) str, ``azimuth_deg``,
        ``elevation_deg`` (N,) float32, ``frame`` (N,) int32, ``source`` (N,)
        str and, when present, ``flows`` (N, 2560) float16.
        """
        from toolkit.io import atomic_save_npz

        arrays = dict(format=np.array(FORMAT_NAME), version=np.array(FORMAT_VERSION),
                      grid=np.array(SILHOUETTE_GRID), levels=np.array(DESCRIPTOR_LEVELS),
                      joint_names=np.array(SKELETON_14.joint_names), descriptors=self._d, joints=self._j,
                      motion=self._motion, azimuth_deg=self._az, elevation_deg=self._el,
                      frame=self._frame, source=self._source)
        if self._flows is not None:
            arrays["flows"] = self._flows
        return atomic_save_npz(path, **arrays)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "SilhouetteDatabase":
        """Read a database written by :meth:`save`.

        Raises
        ------
        InputError
            Naming the file and the field: a missing or unreadable file, another
            format or version, another grid or skeleton, missing fields, wrong
            shapes or non-finite joints.
        """
        from toolkit.io.layout import load_npz

        p = Path(path)
        z = load_npz(p)

        def need(key):
            if key not in z:
                raise InputError(f"{p}: {key}", "a field of a silhouette database file",
                                 f"fields {sorted(z)}")
            return z[key]

        fmt = need("format")
        if fmt.shape != () or str(fmt) != FORMAT_NAME:
            raise InputError(f"{p}: format", repr(FORMAT_NAME), repr(fmt.tolist()))
        ver = need("version")
        if ver.shape != () or int(ver) != FORMAT_VERSION:
            raise InputError(f"{p}: version", str(FORMAT_VERSION), str(ver.tolist()))
        grid = need("grid")
        if tuple(np.asarray(grid).tolist()) != SILHOUETTE_GRID:
            raise InputError(f"{p}: grid", str(SILHOUETTE_GRID), str(grid.tolist()))
        names = tuple(str(s) for s in need("joint_names"))
        if names != SKELETON_14.joint_names:
            raise InputError(f"{p}: joint_names", f"the joints of SKELETON_14 {SKELETON_14.joint_names}",
                             str(names))
        d = need("descriptors")
        if d.dtype != np.uint8:
            raise InputError(f"{p}: descriptors", "uint8 levels", f"dtype {d.dtype}")
        try:
            return cls(d, need("joints"), motion=need("motion"), azimuth_deg=need("azimuth_deg"),
                       elevation_deg=need("elevation_deg"), frame=need("frame"), source=need("source"),
                       flows=z.get("flows"))
        except InputError as e:
            raise InputError(f"{p}: {e.where}", e.expected, e.found) from None

    def __repr__(self) -> str:
        motions = sorted(set(self._motion.tolist()))
        return (f"SilhouetteDatabase({len(self)} entries, motions={motions}"
                f"{', with flow' if self._flows is not None else ''})")
