"""The observer protocol: how algorithms report what they compute.

Algorithms never import rerun.  They take an optional ``observer`` and call
``observer.report(kind, **data)`` with plain numpy arrays; an observer decides
what to do with the report (log it to rerun, keep it for a test, ignore it).

Report kinds and their fields are declared in :data:`REPORT_KINDS` (one
:class:`ReportKind` each), so that the algorithms, the rerun observer
(:mod:`toolkit.viz.rerun_observer`, which maps every declared kind) and the
tests agree on them.  Every report may also carry the :data:`COMMON_FIELDS`:
``frame`` (int) and ``camera`` (str) to place it on the timeline and in the
camera tree, and ``static=True`` to log it once for all times.
:func:`check_report` checks one report against its declaration;
:class:`RecordingObserver`, the fake observer of the tests, checks every
report it receives, so a misspelt kind or field fails the test that sends it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Protocol, runtime_checkable

from toolkit.errors import InputError


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
    """Keeps every report in memory after checking it (the fake observer of the tests).

    Every report is checked by :func:`check_report` before it is kept: an
    undeclared kind, a field its kind does not declare (e.g. a misspelling) or
    a missing required field raises, so a test that drives an algorithm with
    this observer fails on a report the rerun observer would drop or reject.

    Attributes
    ----------
    reports : list of (str, dict)

    Raises
    ------
    InputError
        From :meth:`report`, naming the kind and field (see :func:`check_report`).
    """

    reports: list = field(default_factory=list)

    def report(self, kind: str, **data: Any) -> None:
        check_report(kind, data)
        self.reports.append((kind, data))

    def of_kind(self, kind: str) -> list[dict]:
        """All reports of one kind, in order."""
        return [d for k, d in self.reports if k == kind]

    @property
    def kinds(self) -> set[str]:
        """The kinds received so far."""
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


@dataclass(frozen=True)
class ReportKind:
    """The declaration of one report kind: its required and optional fields.

    Parameters
    ----------
    name : str
        The kind, as passed to ``observer.report(kind, ...)``.
    doc : str
        What the report shows.
    required : Mapping of str to str
        Field name -> type, shape and units; the report must carry each.
    optional : Mapping of str to str
        Field name -> type, shape, units and the default when absent.

    Every kind also accepts the :data:`COMMON_FIELDS` (a kind may make
    ``camera`` required).
    """

    name: str
    doc: str
    required: Mapping[str, str]
    optional: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self):
        both = set(self.required) & set(self.optional)
        if both:
            raise InputError(f"ReportKind {self.name!r}", "each field either required or optional",
                             f"both: {sorted(both)}")
        object.__setattr__(self, "required", MappingProxyType(dict(self.required)))
        object.__setattr__(self, "optional", MappingProxyType(
            {**{k: v for k, v in COMMON_FIELDS.items() if k not in self.required}, **self.optional}))

    @property
    def fields(self) -> frozenset[str]:
        """Every field a report of this kind may carry (required, optional and common)."""
        return frozenset(self.required) | frozenset(self.optional)


#: Fields every report may carry.
COMMON_FIELDS: Mapping[str, str] = MappingProxyType({
    "frame": "int: the frame on the timeline (default: the observer's current frame)",
    "camera": "str: the camera the report belongs to (its image tree)",
    "static": "bool: logged once for all times (default: True for 'rig' and 'skeleton')",
})

_NAME = "str: entity path under the camera's image or the world (default: the kind)"
_COLORS = "(N, 3) or (3,) uint8 RGB (default: the viewer's)"


def _kind(name: str, doc: str, required: dict, optional: dict | None = None) -> tuple[str, ReportKind]:
    return name, ReportKind(name, doc, required, optional or {})


#: Every report kind, with its fields.  Arrays are numpy, shapes and units as
#: documented; pixels are in the camera's image, metres in the world frame.
REPORT_KINDS: Mapping[str, ReportKind] = MappingProxyType(dict([
    _kind("rig", "the cameras as Transform3D + Pinhole (static)",
          {"rig": "Rig"}, {"path": "str: entity path of the camera tree (default 'world/cams')"}),
    _kind("skeleton", "a skeleton's joints and bones as a static AnnotationContext",
          {"skeleton": "Skeleton"}, {"class_id": "int (default: the next free id)"}),
    _kind("image", "a camera's image",
          {"camera": "str", "image": "(H, W, 3) uint8 RGB, (H, W) grey, or float in [0, 1]"},
          {"name": "str (default 'image': the camera's own picture)"}),
    _kind("mask", "a binary mask (or a soft matte) over a camera's image",
          {"camera": "str", "mask": "(H, W) bool, uint8 {0, 1, 255}, or grey levels"}, {"name": _NAME}),
    _kind("labels", "body-part ids over a camera's image",
          {"camera": "str", "labels": "(H, W) integer part ids, 0 = background"},
          {"name": _NAME, "skeleton": "Skeleton naming the parts (default SKELETON_14)"}),
    _kind("depth", "a depth image",
          {"camera": "str", "depth": "(H, W) float metres, 0 or NaN = no reading"}, {"name": _NAME}),
    _kind("joints2d", "2D joints over a camera's image, bones drawn",
          {"camera": "str", "joints": "(J, 2) pixels, NaN = missing"},
          {"name": _NAME, "skeleton": "Skeleton with J joints",
           "color": "(3,) uint8: the bones' colour (one per person)"}),
    _kind("joints3d", "3D joints, bones drawn",
          {"joints": "(J, 3) metres, NaN = missing"},
          {"name": _NAME, "skeleton": "Skeleton with J joints",
           "color": "(3,) uint8: the bones' colour (one per person)"}),
    _kind("points3d", "3D points",
          {"points": "(N, 3) metres"}, {"name": _NAME, "colors": _COLORS, "radii": "(N,) or float, metres"}),
    _kind("points2d", "2D points over a camera's image",
          {"camera": "str", "points": "(N, 2) pixels, NaN = missing"},
          {"name": _NAME, "colors": _COLORS, "radii": "float: pixels, or negative: points of the screen (any zoom)"}),
    _kind("rays", "3D segments from origins to ends (camera rays)",
          {"origins": "(N, 3) metres", "ends": "(N, 3) metres"}, {"name": _NAME, "colors": _COLORS}),
    _kind("lines2d", "polylines over a camera's image",
          {"camera": "str", "strips": "list of (K, 2) pixels"}, {"name": _NAME, "colors": "(S, 3) uint8"}),
    _kind("lines3d", "3D polylines (trajectories, seams)",
          {"strips": "list of (K, 3) metres"}, {"name": _NAME, "colors": "(S, 3) uint8"}),
    _kind("boxes2d", "boxes over a camera's image",
          {"camera": "str", "mins": "(N, 2) pixels", "sizes": "(N, 2) pixels"},
          {"name": _NAME, "labels": "list of N str", "colors": _COLORS}),
    _kind("mesh", "a triangle mesh",
          {"vertices": "(V, 3) metres", "triangles": "(F, 3) int"},
          {"name": _NAME, "vertex_colors": "(V, 3) uint8", "vertex_normals": "(V, 3)"}),
    _kind("quads", "textured quadrilaterals (billboards)",
          {"corners": "(N, 4, 3) metres: top-left, top-right, bottom-right, bottom-left of the texture"},
          {"name": _NAME, "textures": "list of N (h, w, 4) uint8 RGBA", "colors": "(N, 3) uint8 (untextured)"}),
    _kind("scalar", "one number on the timeline", {"name": "str: metric path", "value": "float"}),
    _kind("series", "a curve over iterations (e.g. a score per sweep)",
          {"name": "str: metric path", "values": "(N,) float"}, {"steps": "(N,) int"}),
    _kind("text", "a line of the log",
          {"text": "str"}, {"name": "str: log path (default 'text')", "level": "str, e.g. 'WARN'"}),
    _kind("silhouette", "a mask's outline points over a camera's image with their residuals (soft-body silhouettes)",
          {"camera": "str", "points": "(K, 2) pixels",
           "residuals": "(K,) metres: the model's least distance along each point's ray (0: grazing), NaN = none"},
          {"name": _NAME}),
    _kind("depth_energy", "the depth tracker's energy blocks after one Levenberg-Marquardt round",
          {"stage": "str: which fit (e.g. 'track')", "iteration": "int: the round",
           "total": "float: sum of the blocks", "blocks": "dict of str to float: each residual block's energy"}),
    _kind("depth_move", "one global change tried by the depth tracker",
          {"move": "str: the move's name", "won": "bool: it lowered the energy",
           "weight": "float: the move's current weight", "energy": "float: the best energy after it"}),
    _kind("depth_radial", "the radial profile of the user's silhouette",
          {"angles_deg": "(n,) degrees from up, towards the image's right",
           "distances": "(n,) metres from the centroid to the contour", "peaks": "(p,) int indices of the peaks"}),
]))


def check_report(kind: str, data: Mapping[str, Any]) -> None:
    """Check one report's kind and field names against :data:`REPORT_KINDS`.

    Parameters
    ----------
    kind : str
    data : Mapping of str to Any
        The report's fields.

    Raises
    ------
    InputError
        If ``kind`` is not declared, a field is not declared for it (a
        misspelling) or a required field is missing or None.
    """
    decl = REPORT_KINDS.get(kind)
    if decl is None:
        raise InputError("report: kind", f"one of {sorted(REPORT_KINDS)}", repr(kind))
    unknown = sorted(set(data) - decl.fields)
    if unknown:
        raise InputError(f"report {kind!r}: fields", f"only {sorted(decl.fields)}", f"unknown {unknown}")
    missing = sorted(k for k in decl.required if data.get(k) is None)
    if missing:
        raise InputError(f"report {kind!r}: fields", f"all of {sorted(decl.required)}", f"missing {missing}")
