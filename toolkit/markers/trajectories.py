"""Labelled 3D marker trajectories with a per-marker, per-frame state.

:class:`MarkerTrajectories` is what reconstruction and labelling produce and
what the joint-centre stage reads (from a synthetic capture or a C3D file).
A missing marker-frame is NaN in :attr:`~MarkerTrajectories.positions` and
:data:`MISSING` in :attr:`~MarkerTrajectories.state`; the other states say
how a position was obtained.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.errors import InputError

__all__ = ["MISSING", "TRINOCULAR", "TWO_VIEW", "BRIDGED", "FROM_FILE", "STATE_NAMES", "MarkerTrajectories"]

#: The marker was not found in this frame (position NaN).
MISSING = 0
#: Reconstructed from at least three consistent views.
TRINOCULAR = 1
#: Reconstructed from two views only (less certain).
TWO_VIEW = 2
#: Filled across a gap (from the skeleton / neighbouring markers), not observed.
BRIDGED = 3
#: Read from a file of labelled 3D markers (e.g. C3D).
FROM_FILE = 4
#: Name of each state value.
STATE_NAMES = {MISSING: "missing", TRINOCULAR: "trinocular", TWO_VIEW: "two_view", BRIDGED: "bridged",
               FROM_FILE: "from_file"}


@dataclass
class MarkerTrajectories:
    """Labelled 3D marker trajectories.

    Attributes
    ----------
    labels : tuple of str
        Marker labels (M), unique.
    positions : ndarray of shape (T, M, 3)
        Metres, world; NaN where missing.
    state : ndarray of shape (T, M), int8
        :data:`MISSING`, :data:`TRINOCULAR`, :data:`TWO_VIEW`, :data:`BRIDGED`
        or :data:`FROM_FILE`; MISSING exactly where ``positions`` is NaN.
    fps : float
        Frames per second.
    segments : tuple of str or None
        Body segment of each marker (names of
        :data:`toolkit.markers.marker_sets.SEGMENTS`) when known.
    source : str
        Where the trajectories come from (file, capture folder), for messages.
    measurements : dict of str to float
        The subject's measured widths, metres (a C3D's ``PROCESSING`` group:
        :attr:`toolkit.io.c3d.C3DPoints.measurements`); not kept by
        :meth:`save_npz`.
    """

    labels: tuple[str, ...]
    positions: np.ndarray
    state: np.ndarray
    fps: float
    segments: tuple[str, ...] | None = None
    source: str = field(default="<trajectories>")
    measurements: dict = field(default_factory=dict)

    def __post_init__(self):
        self.labels = tuple(str(x) for x in self.labels)
        if self.segments is not None:
            self.segments = tuple(str(x) for x in self.segments)
        self.positions = np.asarray(self.positions, float)
        self.state = np.asarray(self.state).astype(np.int8, copy=False)
        self.fps = float(self.fps)
        self.validate()

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_markers(self) -> int:
        return len(self.labels)

    def validate(self) -> "MarkerTrajectories":
        """Check shapes, labels, states and the frame rate.

        Raises
        ------
        InputError
            Naming ``source`` and the field: wrong shapes, duplicated labels,
            unknown states, a state that disagrees with NaN positions, a
            non-positive frame rate.
        """
        w = f"{self.source}: "
        M = len(self.labels)
        if len(set(self.labels)) != M:
            dup = sorted({x for x in self.labels if self.labels.count(x) > 1})
            raise InputError(w + "labels", "unique marker labels", f"duplicated labels {dup}")
        if self.positions.ndim != 3 or self.positions.shape[1:] != (M, 3):
            raise InputError(w + "positions", f"an array of shape (T, {M}, 3)", f"shape {self.positions.shape}")
        if self.state.shape != self.positions.shape[:2]:
            raise InputError(w + "state", f"an array of shape {self.positions.shape[:2]}",
                             f"shape {self.state.shape}")
        if self.segments is not None and len(self.segments) != M:
            raise InputError(w + "segments", f"{M} segment names (one per label)", f"{len(self.segments)}")
        bad = ~np.isin(self.state, list(STATE_NAMES))
        if bad.any():
            raise InputError(w + "state", f"values in {sorted(STATE_NAMES)}",
                             f"{sorted(set(self.state[bad].tolist()))}")
        finite = np.isfinite(self.positions).all(axis=-1)
        partial = np.isfinite(self.positions).any(axis=-1) & ~finite
        if partial.any():
            raise InputError(w + "positions", "x, y, z all finite or all NaN", "partly NaN points")
        if np.any(finite != (self.state != MISSING)):
            raise InputError(w + "state", "MISSING exactly where positions are NaN", "a disagreement")
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise InputError(w + "fps", "a positive frame rate", repr(self.fps))
        return self

    def index(self, label: str) -> int:
        """Index of a marker by label."""
        try:
            return self.labels.index(label)
        except ValueError:
            raise InputError(f"{self.source}: label", f"one of {self.labels}", repr(label)) from None

    def subset(self, labels) -> "MarkerTrajectories":
        """The trajectories of ``labels`` only (in that order)."""
        labels = tuple(labels)
        idx = [self.index(x) for x in labels]
        segs = None if self.segments is None else tuple(self.segments[i] for i in idx)
        return MarkerTrajectories(labels, self.positions[:, idx].copy(), self.state[:, idx].copy(), self.fps,
                                  segs, self.source, dict(self.measurements))

    def save_npz(self, path: str | Path) -> Path:
        """Write ``labels``, ``positions``, ``state``, ``fps``, ``segments`` (may be empty), ``source`` atomically."""
        from toolkit.io import atomic_save_npz

        return atomic_save_npz(path, labels=np.array(self.labels, dtype=str), positions=self.positions,
                               state=self.state, fps=np.float64(self.fps),
                               segments=np.array(self.segments if self.segments is not None else [], dtype=str),
                               source=np.array(self.source))

    @classmethod
    def load_npz(cls, path: str | Path) -> "MarkerTrajectories":
        """Read a file written by :meth:`save_npz`.

        Raises
        ------
        InputError
            Naming the file and the missing or malformed field.
        """
        p = Path(path)
        if not p.is_file():
            raise InputError(str(p), "a marker trajectories .npz file", "no such file")
        try:
            with np.load(p, allow_pickle=False) as z:
                d = {k: z[k] for k in z.files}
        except (OSError, ValueError, zipfile.BadZipFile) as e:
            raise InputError(str(p), "a readable .npz archive", str(e)) from None
        for key in ("labels", "positions", "state", "fps"):
            if key not in d:
                raise InputError(f"{p}: {key}", "a field of the archive", "nothing (field missing)")
        segs = d.get("segments")
        segs = tuple(segs.tolist()) if segs is not None and segs.size else None
        return cls(tuple(d["labels"].tolist()), d["positions"], d["state"], float(d["fps"]), segs, str(p))
