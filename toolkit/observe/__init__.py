"""The observer protocol: how algorithms report what they compute.

Algorithms never import rerun.  They take an optional ``observer`` and call
``observer.report(kind, **data)`` with plain numpy arrays; an observer decides
what to do with the report (log it to rerun, keep it for a test, ignore it).

Report kinds and their fields are listed in :data:`REPORT_KINDS`, so that the
rerun observer and tests agree on them.  Every report may carry ``frame``
(int) and ``camera`` (str) to place it on the timeline and in the camera tree,
and ``static=True`` to log it once for all times.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class Observer(Protocol):
    """Anything with a ``report(kind, **data)`` method."""

    def report(self, kind: str, **data: Any) -> None:  # pragma: no cover - protocol
        ...


class NullObserver:
    """Ignores every report."""

    def report(self, kind: str, **data: Any) -> None:
        return None


@dataclass
class RecordingObserver:
    """Keeps every report in memory (for tests and for post-hoc inspection).

    Attributes
    ----------
    reports : list of (str, dict)
    """

    reports: list = field(default_factory=list)

    def report(self, kind: str, **data: Any) -> None:
        self.reports.append((kind, data))

    def of_kind(self, kind: str) -> list[dict]:
        """All reports of one kind, in order."""
        return [d for k, d in self.reports if k == kind]

    @property
    def kinds(self) -> set[str]:
        return {k for k, _ in self.reports}


class MultiObserver:
    """Forwards each report to several observers."""

    def __init__(self, *observers: Observer):
        self.observers = [o for o in observers if o is not None]

    def report(self, kind: str, **data: Any) -> None:
        for o in self.observers:
            o.report(kind, **data)


class PrefixedObserver:
    """Forwards reports under ``prefix/`` (one person of several), joints in one colour.

    Parameters
    ----------
    observer : Observer
    prefix : str
        Put before every report's ``name`` (its kind when it has none); ``rig``, ``skeleton``
        and ``image`` reports pass unchanged.
    color : tuple of int, optional
        RGB given to ``joints2d`` / ``joints3d`` reports without one.
    """

    UNCHANGED = frozenset({"rig", "skeleton", "image"})

    def __init__(self, observer: Observer, prefix: str, color=None):
        self.observer, self.prefix, self.color = observer, prefix.strip("/"), color

    def report(self, kind: str, **data: Any) -> None:
        if kind not in self.UNCHANGED:
            data["name"] = f"{self.prefix}/{data.get('name') or kind}"
            if kind in ("joints2d", "joints3d") and self.color is not None:
                data.setdefault("color", self.color)
        self.observer.report(kind, **data)


def as_observer(observer: Observer | None) -> Observer:
    """``observer`` itself, or a :class:`NullObserver` when ``None``."""
    return NullObserver() if observer is None else observer


#: Report kinds understood by :mod:`toolkit.viz.rerun_observer`, with their fields.
#: Arrays are numpy; shapes and units as documented.
REPORT_KINDS: dict[str, str] = {
    "rig": "rig: Rig; path: str = 'world/cams' (static: cameras as Transform3D + Pinhole)",
    "skeleton": "skeleton: Skeleton; class_id: int (static AnnotationContext with keypoint connections)",
    "image": "camera: str; image: (H, W, 3) uint8 RGB; name: str = 'image'",
    "mask": "camera: str; mask: (H, W) bool or uint8; name: str",
    "labels": "camera: str; labels: (H, W) uint8 part ids (0 background); name: str; skeleton optional (default SKELETON_14)",
    "depth": "camera: str; depth: (H, W) float metres (0 = none); name: str",
    "joints2d": "camera: str; joints: (J, 2) pixels, NaN missing; name: str; skeleton: Skeleton; "
                "color: (3,) uint8 optional (bones drawn in it: one colour per person)",
    "joints3d": "joints: (J, 3) metres; name: str; skeleton: Skeleton; color: (3,) uint8 optional",
    "points3d": "points: (N, 3) metres; colors: (N, 3) uint8 optional; radii optional; name: str",
    "rays": "origins: (N, 3); ends: (N, 3) metres; name: str; colors optional",
    "scalar": "name: str; value: float",
    "text": "name: str; text: str; level optional (e.g. 'WARN')",
    "mesh": "name: str; vertices: (V, 3); triangles: (F, 3); vertex_colors: (V, 3) uint8 optional; vertex_normals optional",
    "boxes2d": "camera: str; mins: (N, 2); sizes: (N, 2) pixels; name: str; labels optional; colors optional",
    "quads": ("name: str; corners: (N, 4, 3) metres, ordered top-left, top-right, bottom-right, bottom-left of the "
              "texture; textures: list of (h, w, 4) uint8 RGBA optional; colors optional (untextured)"),
    "points2d": "camera: str; points: (N, 2) pixels, NaN missing; colors: (N, 3) uint8 optional; name: str",
    "lines2d": "camera: str; strips: list of (K, 2) pixels; colors: (S, 3) uint8 optional; name: str",
    "lines3d": "strips: list of (K, 3) metres (e.g. trajectories, seams); colors optional; name: str",
    "series": "name: str; values: (N,) float; steps: (N,) int optional (a curve over iterations, e.g. score per sweep)",
}
