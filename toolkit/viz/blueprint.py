"""The entity tree of a toolkit recording and the default rerun viewer layout.

Every path the rerun observer writes is built here, so the layout (the
blueprint) and the data always agree:

=================================  ===================================================
``world``                          world frame, metres, z up (``ViewCoordinates``)
``world/cams/<camera>``            ``Transform3D``: world from camera
``world/cams/<camera>/image``      ``Pinhole`` (K, OpenCV axes) and the camera image
``world/cams/<camera>/image/subject``  the subject's crop of the camera image, every frame
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

from collections.abc import Iterable, Mapping, Sequence

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


#: Child entity of a camera image holding the subject's crop of each frame (drawn over the last full
#: image; :class:`toolkit.viz.RerunObserver` logs the full image only now and then).
SUBJECT_CROP = "subject"
#: Stage panels of the default layout: tab name and the overlay names (first segment of a report's
#: ``name`` under a camera image) that it shows over the camera images.
STAGE_TABS = (
    ("stage 1: silhouettes, multi-view", ("calibration", "silhouettes", "multiview")),
    ("stage 2: template, parts", ("template", "segmentation")),
    ("stages 3-4: seams, rendered views", ("seams", "render", "optimize")),
)
#: Overlays of the stage tabs that the overview also shows (the result of each stage).
OVERVIEW_OVERLAYS = ("silhouettes/pose", "render/articulated")
#: Distance of the 3D view's eye from the subject, metres, and its height above the subject's centre.
EYE_DISTANCE_M = 6.0
EYE_HEIGHT_M = 1.5
#: Cameras whose mean unit direction from the subject is shorter than this surround it (a capture ring).
RING_SPREAD = 0.5


def subject_eye(target, camera_centres=None, distance_m: float = EYE_DISTANCE_M,
                height_m: float = EYE_HEIGHT_M) -> tuple[list[float], list[float]]:
    """Eye position and look target of a 3D view framed on a subject.

    Parameters
    ----------
    target : array_like of shape (3,)
        The subject's centre, metres (world, z up).
    camera_centres : array_like of shape (n_cams, 3), optional
        The eye looks from their mean horizontal direction (default: from -y);
        from cameras all around the subject (their mean unit direction shorter
        than ``RING_SPREAD``), from the middle of the widest gap between them.
    distance_m, height_m : float
        How far from the target the eye is horizontally, and how much higher.

    Returns
    -------
    position, look_target : list of 3 float
        ``distance_m`` from the target horizontally, ``height_m`` above it.
    """
    import numpy as np

    t = np.asarray(target, float).reshape(3)
    d = np.array([0.0, -1.0])
    if camera_centres is not None and len(camera_centres):
        v = np.asarray(camera_centres, float)[:, :2] - t[:2]
        u = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-9)
        if len(u) >= 3 and np.linalg.norm(u.mean(axis=0)) < RING_SPREAD:  # a ring: between two cameras
            a = np.sort(np.arctan2(u[:, 1], u[:, 0]))
            gaps = np.diff(np.append(a, a[0] + 2 * np.pi))
            k = int(np.argmax(gaps))
            mid = a[k] + gaps[k] / 2
            d = np.array([np.cos(mid), np.sin(mid)])
        elif np.linalg.norm(v.mean(axis=0)) > 1e-6:
            d = v.mean(axis=0) / np.linalg.norm(v.mean(axis=0))
    pos = [t[0] + distance_m * d[0], t[1] + distance_m * d[1], t[2] + height_m]
    return [float(x) for x in pos], [float(x) for x in t]


#: 3D entities (under ``world``) the overview's 3D view leaves to the stage tabs: rays from cameras tens of
#: metres away and the joint search's candidate clouds hide the subject.
STAGE_3D_DETAILS = ("multiview/rays", "multiview/closest_points", "multiview/retriangulated/rays",
                    "multiview/retriangulated/closest_points", "optimize/**")
#: Margin of a 2D view's initial bounds around the subject, as a fraction of its height on each side.
VIEW_BOUNDS_MARGIN = 1.0


def _overview_contents(seen: Iterable[str] | None) -> list[str]:
    """A camera's overview contents: its image, the stages' results and overlays of no stage."""
    staged = {p for _, prefixes in STAGE_TABS for p in prefixes}
    if seen is None:  # not known yet: everything but the stages' details
        return ["+ $origin/**"] + [f"- $origin/{p}/**" for p in sorted(staged)] \
            + [f"+ $origin/{p}" for p in OVERVIEW_OVERLAYS]
    return ["+ $origin", f"+ $origin/{SUBJECT_CROP}"] + [f"+ $origin/{p}" for p in OVERVIEW_OVERLAYS] \
        + [f"+ $origin/{n}/**" for n in sorted(set(seen) - staged)]


def _checked_names(camera_names: Iterable[str]) -> list[str]:
    """The camera names as a list: non-empty strings, none repeated.

    Parameters
    ----------
    camera_names : iterable of str

    Returns
    -------
    list of str

    Raises
    ------
    InputError
        A name repeated, empty or not a string.
    """
    names = list(camera_names)
    for n in names:
        if not isinstance(n, str) or not n:
            raise InputError("make_blueprint: camera_names", "non-empty str names", f"{n!r}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError("make_blueprint: camera_names", "unique names", f"duplicates {dup}")
    return names


def _stage_tabs(names: list[str], overlays: Mapping[str, Iterable[str]] | None, cams_root: str, bounds,
                controls) -> list:
    """One tab per stage of :data:`STAGE_TABS`: the camera images with that stage's overlays only.

    Parameters
    ----------
    names : list of str
        Cameras, in display order.
    overlays : mapping of str to iterable of str or None
        Per camera, the overlay names seen so far (None: every stage with every camera).
    cams_root : str
        Root of the camera entities.
    bounds : callable
        Camera name -> initial visual bounds of its 2D views (or None).
    controls : rerun.blueprint.EyeControls3D or None
        The 3D view's eye.

    Returns
    -------
    list of rerun.blueprint.Grid
        The tabs of the stages some camera has overlays of.
    """
    tabs = []
    for title, prefixes in STAGE_TABS:
        cams = [n for n in names if overlays is None or set(prefixes) & set(overlays.get(n, ()))]
        if not cams:
            continue
        contents = ["+ $origin", f"+ $origin/{SUBJECT_CROP}"] + [f"+ $origin/{p}/**" for p in prefixes]
        views = [rrb.Spatial2DView(origin=image_path(n, cams_root), name=n, contents=contents, visual_bounds=bounds(n))
                 for n in cams]
        if title == STAGE_TABS[0][0]:  # the selection's rays and closest points in 3D
            views.insert(0, rrb.Spatial3DView(origin=WORLD, name="3D: rays", eye_controls=controls,
                                              contents=["+ $origin/**", "- $origin/optimize/**"]))
        tabs.append(rrb.Grid(*views, name=title))
    return tabs


def make_blueprint(
    camera_names: Iterable[str],
    *,
    extra_2d: Sequence[str] = (),
    include_metrics: bool = True,
    include_logs: bool = True,
    cams_root: str = CAMS,
    overlays: Mapping[str, Iterable[str]] | None = None,
    eye: tuple[Sequence[float], Sequence[float]] | None = None,
    timeline: str = "frame",
    subject_boxes: Mapping[str, Sequence[float]] | None = None,
) -> rrb.Blueprint:
    """The default viewer layout for a recording of a camera rig.

    A first tab, "overview": left a 3D view of ``world`` (framed on the subject
    when ``eye`` is given, not on the far cameras) above a text log view of
    ``logs``; right a grid of 2D views, one per camera image
    (``<cams_root>/<name>/image``) with the camera image, each stage's result
    (:data:`OVERVIEW_OVERLAYS`) and overlays of no stage, then one per
    ``extra_2d`` entity, above a time-series view of ``metrics``.  Then one tab
    per stage (:data:`STAGE_TABS`): the camera images with that stage's
    overlays only, so that the panels of a stage are together and the overview
    stays readable.

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
    overlays : mapping of str to iterable of str, optional
        Per camera, the overlay names seen so far (first segment of the report
        names); a stage tab then shows only the cameras with overlays of that
        stage and is left out when none has any.  Default: every stage tab with
        every camera.
    eye : (position, look_target), optional
        Metres, world frame (:func:`subject_eye`).
    timeline : str
        Timeline the time panel shows (the observer's ``frame``).
    subject_boxes : mapping of str to (x0, y0, x1, y1), optional
        Per camera, the initial visible region of its 2D views (pixels): around the
        subject rather than the whole frame (zoom out with a double click).

    Returns
    -------
    rerun.blueprint.Blueprint

    Raises
    ------
    InputError
        If a camera name is repeated or empty.
    """
    names = _checked_names(camera_names)

    def bounds(n):
        b = (subject_boxes or {}).get(n)
        return None if b is None else rrb.VisualBounds2D(x_range=[b[0], b[2]], y_range=[b[1], b[3]])

    views_2d: list[rrb.View] = [
        rrb.Spatial2DView(origin=image_path(n, cams_root), name=n, visual_bounds=bounds(n),
                          contents=_overview_contents(None if overlays is None else overlays.get(n, ())))
        for n in names]
    views_2d += [rrb.Spatial2DView(origin=entity_path(p), name=p) for p in extra_2d]

    controls = None
    if eye is not None:
        controls = rrb.EyeControls3D(position=list(eye[0]), look_target=list(eye[1]), eye_up=[0.0, 0.0, 1.0])
    left: list = [rrb.Spatial3DView(origin=WORLD, name="3D", eye_controls=controls,
                                    contents=["+ $origin/**"] + [f"- $origin/{p}" for p in STAGE_3D_DETAILS])]
    if include_logs:
        left.append(rrb.TextLogView(origin=LOGS, name="log"))
    right: list = []
    if views_2d:
        right.append(rrb.Grid(*views_2d, name="cameras"))
    if include_metrics:
        right.append(rrb.TimeSeriesView(origin=METRICS, name="metrics"))

    left_col = rrb.Vertical(*left, row_shares=[3, 1][: len(left)]) if len(left) > 1 else left[0]
    if right:
        right_col = rrb.Vertical(*right, row_shares=[3, 1][: len(right)]) if len(right) > 1 else right[0]
        main = rrb.Horizontal(left_col, right_col, name="overview")
    else:
        main = rrb.Horizontal(left_col, name="overview")
    tabs = [main] + _stage_tabs(names, overlays, cams_root, bounds, controls)
    # the views get the room: blueprint and selection panels folded (one click opens them), the time
    # panel on the frame timeline
    panels = (rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
              rrb.TimePanel(state="expanded", timeline=timeline))
    if len(tabs) == 1 and not names:
        return rrb.Blueprint(left_col if not right else main, *panels, collapse_panels=False)
    return rrb.Blueprint(rrb.Tabs(*tabs, active_tab=0), *panels, collapse_panels=False)


#: Entities of a soft-body fit's recording (``recipes/fit_soft_body.py``), under :data:`METRICS`.
SOFTBODY_LENGTHS = "softbody/global/lengths"
SOFTBODY_COST = "softbody/global/cost"
SOFTBODY_RESIDUAL = "softbody/median_residual_mm"
SOFTBODY_TRACK = "softbody/track"
SOFTBODY_POSTURE = "softbody/posture"
SOFTBODY_OTHER = "other_points"  # under SOFTBODY_TRACK: a count, plotted apart from the fractions and metres


def softbody_blueprint(length_names: Iterable[str], *, eye: tuple[Sequence[float], Sequence[float]] | None = None,
                       timeline: str = "frame") -> rrb.Blueprint:
    """The viewer layout of a soft-body fit's recording.

    Left, the 3D view (framed on the subject when ``eye`` is given: the
    clouds, patches, the model's surface, the residual-coloured points and
    the joints, each toggled in the view's entity list) above the log; right,
    tabs: the median residual per frame, the tracking's per-frame figures
    (inlier fraction and median distance; the points of other bodies, a
    count, in a plot of their own), the trunk's
    bend and twist against the pelvis per frame (degrees), and the
    global fit's lengths over its iterations (one bar chart per length, with
    the cost).

    Parameters
    ----------
    length_names : iterable of str
        The model's fitted lengths, as reported (``softbody/global/lengths/<name>``).
    eye : (position, look_target), optional
        Metres, world frame (:func:`subject_eye`).
    timeline : str

    Returns
    -------
    rerun.blueprint.Blueprint
    """
    controls = None if eye is None else rrb.EyeControls3D(position=list(eye[0]), look_target=list(eye[1]),
                                                         eye_up=[0.0, 0.0, 1.0])
    left = rrb.Vertical(rrb.Spatial3DView(origin=WORLD, name="3D", eye_controls=controls),
                        rrb.TextLogView(origin=LOGS, name="log"), row_shares=[4, 1])
    bars = [rrb.BarChartView(origin=entity_path(METRICS, SOFTBODY_COST), name="cost")]
    bars += [rrb.BarChartView(origin=entity_path(METRICS, SOFTBODY_LENGTHS, n), name=n) for n in length_names]
    right = rrb.Tabs(
        rrb.Vertical(rrb.TimeSeriesView(origin=entity_path(METRICS, SOFTBODY_RESIDUAL), name="median residual (mm)"),
                     rrb.TimeSeriesView(origin=entity_path(METRICS, SOFTBODY_TRACK), name="tracking",
                                        contents=["+ $origin/**", f"- $origin/{SOFTBODY_OTHER}"]),
                     rrb.TimeSeriesView(origin=entity_path(METRICS, SOFTBODY_TRACK, SOFTBODY_OTHER),
                                        name="points of other bodies"),
                     rrb.TimeSeriesView(origin=entity_path(METRICS, SOFTBODY_POSTURE),
                                        name="trunk against the pelvis (deg)"),
                     name="per frame"),
        rrb.Grid(*bars, name="global fit: lengths over the iterations (m)"),
        active_tab=0)
    panels = (rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
              rrb.TimePanel(state="expanded", timeline=timeline))
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), *panels, collapse_panels=False)
