"""The entity tree of a toolkit recording and the default rerun viewer layout.

Every path the rerun observer writes is built here, so the layout (the
blueprint) and the data always agree:

=================================  ===================================================
``world``                          world frame, metres, z up (``ViewCoordinates``)
``world/cams/<camera>``            ``Transform3D``: world from camera
``world/cams/<camera>/image``      ``Pinhole`` (K, OpenCV axes) and the camera image
``world/cams/<camera>/image/<n>``  2D overlays: keypoints, masks, labels, depth, boxes
``world/<n>``                      3D data: joints, points, rays, meshes, billboards
``metrics/<n>``                    scalar time series
``logs/<n>``                       text log lines
``reports/<kind>/<field>``         arrays of report kinds the observer does not know
=================================  ===================================================

Names may contain ``/`` to nest entities (``fit/residual``); every path
segment is escaped with :func:`rerun.escape_entity_path_part`, so camera names
with spaces or dots are safe.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import rerun as rr
import rerun.blueprint as rrb

from toolkit.errors import InputError

#: Root of the 3D scene (metres, z up).
WORLD = "world"
#: Default root of the camera rig.
CAMS = "world/cams"
#: Root of scalar time series.
METRICS = "metrics"
#: Root of text log lines.
LOGS = "logs"
#: Root of arrays from report kinds the observer has no dedicated mapping for.
REPORTS = "reports"
#: Name of the image entity under a camera (holds the ``Pinhole``).
IMAGE = "image"


def entity_path(*parts: str) -> str:
    """Join path parts into an escaped rerun entity path.

    Parameters
    ----------
    *parts : str
        Path parts; each may itself contain ``/`` to nest entities.  Leading,
        trailing and repeated slashes are ignored.

    Returns
    -------
    str
        The path, e.g. ``entity_path("world/cams", "cam 0")`` is ``"world/cams/cam\\ 0"``.

    Raises
    ------
    InputError
        If no non-empty segment is given.
    """
    segments: list[str] = []
    for part in parts:
        if not isinstance(part, str):
            raise InputError("entity path part", "a str", f"{type(part).__name__} {part!r}")
        segments.extend(s for s in part.split("/") if s)
    if not segments:
        raise InputError("entity path", "at least one non-empty name", f"parts {parts!r}")
    return "/".join(rr.escape_entity_path_part(s) for s in segments)


def camera_path(camera: str, root: str = CAMS) -> str:
    """Entity holding the camera's ``Transform3D``: ``<root>/<camera>``."""
    return f"{entity_path(root)}/{rr.escape_entity_path_part(camera)}"


def image_path(camera: str, root: str = CAMS) -> str:
    """Entity holding the camera's ``Pinhole`` and image: ``<root>/<camera>/image``."""
    return f"{camera_path(camera, root)}/{IMAGE}"


def make_blueprint(
    camera_names: Iterable[str],
    *,
    extra_2d: Sequence[str] = (),
    include_metrics: bool = True,
    include_logs: bool = True,
    cams_root: str = CAMS,
) -> rrb.Blueprint:
    """The default viewer layout for a recording of a camera rig.

    Left column: a 3D view of ``world`` above a text log view of ``logs``.
    Right column: a grid of 2D views, one per camera image
    (``<cams_root>/<name>/image``) then one per ``extra_2d`` entity, above a
    time-series view of ``metrics``.

    Parameters
    ----------
    camera_names : iterable of str
        Cameras, in display order.
    extra_2d : sequence of str
        Further entity paths (unescaped, ``/``-separated) to show in 2D views,
        e.g. a billboard texture atlas.
    include_metrics : bool
        Add the time-series view of ``metrics``.
    include_logs : bool
        Add the text log view of ``logs``.
    cams_root : str
        Root of the camera entities (the ``path`` of the ``rig`` report).

    Returns
    -------
    rerun.blueprint.Blueprint

    Raises
    ------
    InputError
        If a camera name is repeated or empty.
    """
    names = list(camera_names)
    for n in names:
        if not isinstance(n, str) or not n:
            raise InputError("make_blueprint: camera_names", "non-empty str names", f"{n!r}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError("make_blueprint: camera_names", "unique names", f"duplicates {dup}")

    views_2d: list[rrb.View] = [rrb.Spatial2DView(origin=image_path(n, cams_root), name=n) for n in names]
    views_2d += [rrb.Spatial2DView(origin=entity_path(p), name=p) for p in extra_2d]

    left: list = [rrb.Spatial3DView(origin=WORLD, name="3D")]
    if include_logs:
        left.append(rrb.TextLogView(origin=LOGS, name="log"))
    right: list = []
    if views_2d:
        right.append(rrb.Grid(*views_2d, name="cameras"))
    if include_metrics:
        right.append(rrb.TimeSeriesView(origin=METRICS, name="metrics"))

    left_col = rrb.Vertical(*left, row_shares=[3, 1][: len(left)]) if len(left) > 1 else left[0]
    if not right:
        return rrb.Blueprint(left_col, collapse_panels=False)
    right_col = rrb.Vertical(*right, row_shares=[3, 1][: len(right)]) if len(right) > 1 else right[0]
    return rrb.Blueprint(rrb.Horizontal(left_col, right_col), collapse_panels=False)
