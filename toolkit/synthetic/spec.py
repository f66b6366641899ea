"""Scene specifications: TOML files describing a synthetic scene.

Example (``datasets_synthetic/default.toml``)::

    seed = 7
    frames = 30
    fps = 25

    [subject]
    height_m = 1.78
    motion = "walk"          # a name of toolkit.motion.MOTIONS, or a path to a .bvh file

    [cameras]
    count = 3
    layout = "broadcast"     # or "studio", "trinocular"
    resolution = [1280, 720]
    calibration_error_px = 8.0

    [novel]
    count = 2

Optional fields that widen the scene space (the scene zoo, ``benchmarks/bench_zoo.py``):
``[subject] outfit`` (``"random"`` or ``"like_background"``: a kit close to the
pitch or the backdrop), ``shirt_rgb`` / ``trousers_rgb`` (RGB in [0, 1]) and
``pattern``; ``[subject] area_m`` (walks and runs: the largest distance of the pelvis from the path's
centre, metres; a longer path becomes a loop inside it that stays in every camera's view, see
:func:`toolkit.synthetic.generator.build_scene`); ``[cameras] heads`` and ``baseline_m`` (``layout = "trinocular"``: heads of three
cameras 0.2-0.4 m apart, 2-4 m from the subject, see :func:`toolkit.synthetic.rigs.make_rig`;
``count`` is 3 per head); ``[cameras] spacing_deg`` (azimuth between neighbouring cameras,
a number or ``[lo, hi]``) and ``subject_px`` (broadcast: subject height in
pixels, a number or ``[lo, hi]``); ``[novel] placement`` (``"between"`` the
sources, or ``"around"`` the subject: reverse angles and high views).

Optional tables: ``[render]`` (``engine``: ``"raycast"`` (default) or
``"open3d"``; ``sample_count``: anti-aliasing samples per pixel for Open3D,
``supersample``: rays per pixel side for the ray caster, default 2) and
``[depth_camera]`` (see :mod:`toolkit.synthetic.depth_sensor`) and ``[markers]`` (a marker
capture without videos, see :mod:`toolkit.synthetic.marker_spec`).

Optional ``[players]`` table: a scene with several people (:class:`PlayersSpec`,
``docs/scene_spec.md``; drawn by :mod:`toolkit.synthetic.players`)::

    [players]
    count = 4                # 1-6 people; player 0 is the [subject]
    path = "cross"           # or "spots"
    kits = "teams"           # or "random"

    [[players.player]]       # optional overrides of players 1, 2, ... in order
    motion = "walk"
    height_m = 1.70
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from toolkit.errors import InputError
from toolkit.motion import MOTIONS
from toolkit.synthetic.marker_spec import MarkerSpec

#: Limits of the spec values (an impossible value is rejected with its field named).
MAX_FRAMES = 100_000
MAX_CAMERAS = 32
HEIGHT_RANGE_M = (1.40, 2.10)
#: ``[subject] area_m`` limits (the pelvis's largest distance from a walk's or run's centre), metres.
AREA_RANGE_M = (0.2, 10.0)
LAYOUTS = ("broadcast", "studio", "trinocular")
#: ``[cameras] baseline_m`` limits of a trinocular head (distance between its cameras), metres.
BASELINE_RANGE_M = (0.2, 0.4)
#: ``[subject] outfit`` values: drawn from the palettes, or close to the surroundings' colours.
OUTFITS = ("random", "like_background")
#: Shirt print patterns (``[subject] pattern``; ``checks_all``: shirt and trousers checked).
PATTERNS = ("stripes", "checks", "plain", "checks_all")
#: ``[novel] placement`` values.
NOVEL_PLACEMENTS = ("between", "around")
#: Allowed ``[cameras] spacing_deg`` range, degrees.
SPACING_RANGE_DEG = (5.0, 180.0)
#: Allowed ``[cameras] subject_px`` range, pixels.
SUBJECT_PX_RANGE = (20.0, 4000.0)
#: ``[players] count`` limit (player 0 is the ``[subject]``).
MAX_PLAYERS = 6
#: ``[players] path`` values: ``cross``: walks and runs along straight lines through the middle of the
#: volume, the first two crossing mid-sequence; ``spots``: everyone moves on a spot of their own.
PLAYER_PATHS = ("cross", "spots")
#: ``[players] kits`` values: two team kits (players 0, 2, 4 and 1, 3, 5), or an outfit of one's own.
PLAYER_KITS = ("teams", "random")
#: Default ``[players] kits`` per camera layout.
DEFAULT_KITS = {"broadcast": "teams", "studio": "random", "trinocular": "random"}
#: Default stature range of players 1.. (``[players] height_m``), metres.
PLAYER_HEIGHT_RANGE_M = (1.62, 1.95)
#: Default ``[players] spread_m`` (radius of the crossing points or spots around the middle, metres) per
#: path and layout: a pitch has room, a studio frames about 2 m.
DEFAULT_SPREAD_M = {("cross", "broadcast"): 2.5, ("spots", "broadcast"): 3.0,
                    ("cross", "studio"): 0.8, ("spots", "studio"): 1.2,
                    ("cross", "trinocular"): 0.8, ("spots", "trinocular"): 1.2}
#: Allowed ``[players] spread_m`` range, metres.
SPREAD_RANGE_M = (0.3, 30.0)
#: Motions that move along a path (the others stay on a spot).
TRAVELLING_MOTIONS = ("walk", "run")


@dataclass(frozen=True)
class PlayerSpec:
    """Overrides of one player (``[[players.player]]``); None = drawn."""

    motion: str | None = None
    height_m: float | None = None
    shirt_rgb: tuple | None = None
    trousers_rgb: tuple | None = None


@dataclass(frozen=True)
class PlayersSpec:
    """The ``[players]`` table: several people in one scene (player 0 is the ``[subject]``).

    Attributes
    ----------
    count : int
        People in the scene, 1 .. :data:`MAX_PLAYERS`.
    path : str
        One of :data:`PLAYER_PATHS`.
    motion : str
        Motion of players 1.. (a name of :data:`toolkit.motion.MOTIONS`).
    kits : str
        One of :data:`PLAYER_KITS`.
    team_shirts : tuple of 2 (r, g, b) tuples, optional
        Shirt colours of the two teams (RGB in [0, 1]); drawn when None.
    height_m : tuple of float
        ``(lo, hi)`` stature range of players 1.., metres.
    spread_m : float
        Radius of the crossing points or spots around the middle, metres.
    players : tuple of PlayerSpec
        Overrides of players 1, 2, ... (at most ``count - 1``).
    """

    count: int
    path: str = "cross"
    motion: str = "walk"
    kits: str = "teams"
    team_shirts: tuple | None = None
    height_m: tuple = PLAYER_HEIGHT_RANGE_M
    spread_m: float = 2.5
    players: tuple = ()

    def override(self, k: int) -> PlayerSpec:
        """The overrides of player ``k`` (>= 1; an empty :class:`PlayerSpec` when none)."""
        return self.players[k - 1] if 1 <= k <= len(self.players) else PlayerSpec()


@dataclass(frozen=True)
class SceneSpec:
    """A parsed, validated scene specification (all fields as in the TOML)."""

    seed: int
    frames: int
    fps: float
    height_m: float
    motion: str
    camera_count: int
    layout: str
    resolution: tuple[int, int]
    calibration_error_px: float
    novel_count: int = 0
    outfit: str = "random"
    shirt_rgb: tuple | None = None
    trousers_rgb: tuple | None = None
    pattern: str | None = None
    spacing_deg: tuple | None = None
    subject_px: tuple | None = None
    novel_placement: str = "between"
    sample_count: int = 4
    engine: str = "raycast"
    supersample: int = 2
    depth_camera: dict | None = None
    markers: dict | None = None  # a marker capture (toolkit.synthetic.marker_spec)
    heads: int = 0
    baseline_m: tuple | None = None
    players: PlayersSpec | None = None  # several people ([players]); None: the subject alone
    area_m: float | None = None  # walks and runs kept within this of their centre and in view; None: as drawn
    source: str = "<spec>"
    text: str = field(default="", repr=False)

    @property
    def motion_is_bvh(self) -> bool:
        return self.motion.lower().endswith(".bvh")

    @property
    def camera_names(self) -> list[str]:
        """The source cameras' names in the generated dataset."""
        from toolkit.synthetic.rigs import camera_names

        return camera_names(self.camera_count)


def _get(table: dict, key: str, where: str, types, default=...):
    """``table[key]`` checked against ``types``; ``where`` prefixes the field name in errors."""
    name = f"{where}{key}"
    if key not in table:
        if default is ...:
            raise InputError(name, "a value", "nothing (field missing)")
        return default
    v = table[key]
    if not isinstance(v, types) or isinstance(v, bool) and bool not in (types if isinstance(types, tuple) else (types,)):
        names = types.__name__ if isinstance(types, type) else " or ".join(t.__name__ for t in types)
        raise InputError(name, f"a {names}", f"{v!r} ({type(v).__name__})")
    return v


def _check_keys(table: dict, allowed: set, where: str, source: str):
    extra = set(table) - allowed
    if extra:
        raise InputError(f"{source}: [{where}]" if where else source, f"only the keys {sorted(allowed)}",
                         f"unknown keys {sorted(extra)}")


def _rgb(table: dict, key: str, where: str, source: str):
    """An optional ``[r, g, b]`` in [0, 1] as a tuple, or None."""
    if key not in table:
        return None
    v = table[key]
    if (not isinstance(v, list) or len(v) != 3
            or not all(isinstance(c, (int, float)) and not isinstance(c, bool) and 0 <= c <= 1 for c in v)):
        raise InputError(f"{source}: {where}.{key}", "[r, g, b] with values in [0, 1]", repr(v))
    return tuple(float(c) for c in v)


def _range(table: dict, key: str, where: str, source: str, limits: tuple):
    """An optional number or ``[lo, hi]`` within ``limits`` as a ``(lo, hi)`` tuple, or None."""
    if key not in table:
        return None
    v = table[key]
    num = lambda x: isinstance(x, (int, float)) and not isinstance(x, bool)  # noqa: E731
    if num(v):
        v = [v, v]
    if (not isinstance(v, list) or len(v) != 2 or not all(num(x) for x in v) or v[0] > v[1]
            or not all(limits[0] <= x <= limits[1] for x in v)):
        raise InputError(f"{source}: {where}.{key}",
                         f"a number or [lo, hi] (lo <= hi) within {limits[0]:g}..{limits[1]:g}", repr(table[key]))
    return (float(v[0]), float(v[1]))


def _trinocular(cams: dict, layout: str, count: int, source: str) -> tuple[int, tuple | None]:
    """``[cameras] heads`` and ``baseline_m`` of a trinocular layout (``(0, None)`` for the others)."""
    if layout != "trinocular":
        for key in ("heads", "baseline_m"):
            if key in cams:
                raise InputError(f"{source}: cameras.{key}", "no value unless layout = 'trinocular'",
                                 repr(cams[key]))
        return 0, None
    heads = _get(cams, "heads", f"{source}: cameras.", int, max(count // 3, 1))
    if not 1 <= heads <= MAX_CAMERAS // 3:
        raise InputError(f"{source}: cameras.heads", f"an integer from 1 to {MAX_CAMERAS // 3}", str(heads))
    if count != 3 * heads:
        raise InputError(f"{source}: cameras.count", f"3 cameras per trinocular head ({3 * heads} for {heads})",
                         str(count))
    baseline = _range(cams, "baseline_m", "cameras", source, BASELINE_RANGE_M) or BASELINE_RANGE_M
    return heads, baseline


def _motion_name(table: dict, key: str, where: str, source: str, default=None):
    """An optional motion name of :data:`toolkit.motion.MOTIONS` (``where`` names the table)."""
    v = _get(table, key, f"{source}: {where}.", str, default)
    if v is not None and v not in MOTIONS:
        raise InputError(f"{source}: {where}.{key}", f"one of {list(MOTIONS)}", repr(v))
    return v


def _players(d: dict, source: str, layout: str, subject_motion: str) -> PlayersSpec | None:
    """The ``[players]`` table as a :class:`PlayersSpec` (None when absent)."""
    if "players" not in d:
        return None
    S = lambda k: f"{source}: players.{k}"  # noqa: E731
    t = _get(d, "players", f"{source}: ", dict)
    _check_keys(t, {"count", "path", "motion", "kits", "team_shirts", "height_m", "spread_m", "player"},
                "players", source)
    count = _get(t, "count", f"{source}: players.", int)
    if not 1 <= count <= MAX_PLAYERS:
        raise InputError(S("count"), f"an integer from 1 to {MAX_PLAYERS}", str(count))
    path = _get(t, "path", f"{source}: players.", str, "cross")
    if path not in PLAYER_PATHS:
        raise InputError(S("path"), f"one of {list(PLAYER_PATHS)}", repr(path))
    suits = (lambda m: m in TRAVELLING_MOTIONS) if path == "cross" else \
        (lambda m: m in MOTIONS and m not in TRAVELLING_MOTIONS)
    default_motion = subject_motion if suits(subject_motion) else ("walk" if path == "cross" else "idle")
    motion = _motion_name(t, "motion", "players", source, default_motion)
    kits = _get(t, "kits", f"{source}: players.", str, DEFAULT_KITS[layout])
    if kits not in PLAYER_KITS:
        raise InputError(S("kits"), f"one of {list(PLAYER_KITS)}", repr(kits))
    team_shirts = None
    if "team_shirts" in t:
        v = t["team_shirts"]
        if kits != "teams":
            raise InputError(S("team_shirts"), "no value unless kits = 'teams'", repr(v))
        if not isinstance(v, list) or len(v) != 2:
            raise InputError(S("team_shirts"), "two [r, g, b] shirt colours (one per team)", repr(v))
        team_shirts = tuple(_rgb({f"team_shirts[{i}]": c}, f"team_shirts[{i}]", "players", source)
                            for i, c in enumerate(v))
    heights = _range(t, "height_m", "players", source, HEIGHT_RANGE_M) or PLAYER_HEIGHT_RANGE_M
    spread = float(_get(t, "spread_m", f"{source}: players.", (int, float), DEFAULT_SPREAD_M[path, layout]))
    if not SPREAD_RANGE_M[0] <= spread <= SPREAD_RANGE_M[1]:
        raise InputError(S("spread_m"), f"a radius from {SPREAD_RANGE_M[0]:g} to {SPREAD_RANGE_M[1]:g} m",
                         str(spread))
    entries = _get(t, "player", f"{source}: players.", list, [])
    if len(entries) > count - 1:
        raise InputError(S("player"), f"at most {count - 1} entries for count = {count} (the overrides of "
                         "players 1, 2, ...; player 0 is the [subject])", f"{len(entries)} entries")
    overrides = []
    for i, e in enumerate(entries):
        where = f"players.player[{i}]"
        if not isinstance(e, dict):
            raise InputError(f"{source}: {where}", "a table ([[players.player]])", repr(e))
        _check_keys(e, {"motion", "height_m", "shirt_rgb", "trousers_rgb"}, where, source)
        h = e.get("height_m")
        if h is not None:
            h = float(_get(e, "height_m", f"{source}: {where}.", (int, float)))
            if not HEIGHT_RANGE_M[0] <= h <= HEIGHT_RANGE_M[1]:
                raise InputError(f"{source}: {where}.height_m",
                                 f"a stature between {HEIGHT_RANGE_M[0]} and {HEIGHT_RANGE_M[1]} m", str(h))
        overrides.append(PlayerSpec(motion=_motion_name(e, "motion", where, source), height_m=h,
                                    shirt_rgb=_rgb(e, "shirt_rgb", where, source),
                                    trousers_rgb=_rgb(e, "trousers_rgb", where, source)))
    return PlayersSpec(count=count, path=path, motion=motion, kits=kits, team_shirts=team_shirts,
                       height_m=heights, spread_m=spread, players=tuple(overrides))


def _subject_table(d: dict, source: str, base_dir: Path | None) -> tuple:
    """Parse the ``[subject]`` table.

    Parameters
    ----------
    d : dict
        The spec's TOML.
    source : str
        File name used in error messages.
    base_dir : Path or None
        Folder relative BVH paths are resolved against.

    Returns
    -------
    tuple
        ``(height_m, motion, outfit, shirt_rgb, trousers_rgb, pattern)``; ``motion`` a motion name or an
        absolute ``.bvh`` path.

    Raises
    ------
    InputError
        A missing, mistyped or impossible value.
    """
    S = lambda k: f"{source}: {k}"  # noqa: E731
    sub = _get(d, "subject", f"{source}: ", dict)
    _check_keys(sub, {"height_m", "motion", "outfit", "shirt_rgb", "trousers_rgb", "pattern", "area_m"}, "subject",
                source)
    h = float(_get(sub, "height_m", f"{source}: subject.", (int, float)))
    if not HEIGHT_RANGE_M[0] <= h <= HEIGHT_RANGE_M[1]:
        raise InputError(S("subject.height_m"), f"a stature between {HEIGHT_RANGE_M[0]} and {HEIGHT_RANGE_M[1]} m",
                         str(h))
    motion = _get(sub, "motion", f"{source}: subject.", str)
    if motion.lower().endswith(".bvh"):
        p = Path(motion)
        if not p.is_absolute() and base_dir is not None:
            p = (base_dir / p).resolve()
        if not p.is_file():
            raise InputError(S("subject.motion"), "an existing .bvh file", f"{motion!r} (not found at {p})")
        motion = str(p)
    elif motion not in MOTIONS:
        raise InputError(S("subject.motion"), f"one of {list(MOTIONS)} or a .bvh path", repr(motion))
    outfit = _get(sub, "outfit", f"{source}: subject.", str, "random")
    if outfit not in OUTFITS:
        raise InputError(S("subject.outfit"), f"one of {list(OUTFITS)}", repr(outfit))
    shirt_rgb = _rgb(sub, "shirt_rgb", "subject", source)
    trousers_rgb = _rgb(sub, "trousers_rgb", "subject", source)
    pattern = _get(sub, "pattern", f"{source}: subject.", str, None)
    if pattern is not None and pattern not in PATTERNS:
        raise InputError(S("subject.pattern"), f"one of {list(PATTERNS)}", repr(pattern))
    return h, motion, outfit, shirt_rgb, trousers_rgb, pattern


def _subject_area(d: dict, source: str) -> float | None:
    """``[subject] area_m``: a distance within :data:`AREA_RANGE_M` (metres), or None when absent."""
    sub = d.get("subject", {})
    if "area_m" not in sub:
        return None
    v = sub["area_m"]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not AREA_RANGE_M[0] <= v <= AREA_RANGE_M[1]:
        raise InputError(f"{source}: subject.area_m", f"a distance from {AREA_RANGE_M[0]:g} to {AREA_RANGE_M[1]:g} m",
                         repr(v))
    return float(v)


def _cameras_table(d: dict, source: str) -> tuple:
    """Parse the ``[cameras]`` table.

    Parameters
    ----------
    d : dict
        The spec's TOML (a marker capture's cameras already filled in).
    source : str

    Returns
    -------
    tuple
        ``(count, layout, resolution, calibration_error_px, spacing_deg, subject_px, heads, baseline_m)``.

    Raises
    ------
    InputError
        A missing, mistyped or impossible value.
    """
    S = lambda k: f"{source}: {k}"  # noqa: E731
    cams = _get(d, "cameras", f"{source}: ", dict)
    _check_keys(cams, {"count", "layout", "resolution", "calibration_error_px", "spacing_deg", "subject_px",
                       "heads", "baseline_m"}, "cameras", source)
    count = _get(cams, "count", f"{source}: cameras.", int)
    if not 1 <= count <= MAX_CAMERAS:
        raise InputError(S("cameras.count"), f"an integer from 1 to {MAX_CAMERAS}", str(count))
    layout = _get(cams, "layout", f"{source}: cameras.", str)
    if layout not in LAYOUTS:
        raise InputError(S("cameras.layout"), f"one of {list(LAYOUTS)}", repr(layout))
    res = _get(cams, "resolution", f"{source}: cameras.", list)
    if (len(res) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) for v in res)
            or not all(16 <= v <= 8192 for v in res) or any(v % 2 for v in res)):
        raise InputError(S("cameras.resolution"), "[width, height], even integers from 16 to 8192", repr(res))
    err = float(_get(cams, "calibration_error_px", f"{source}: cameras.", (int, float), 0.0))
    if not 0 <= err <= 100:
        raise InputError(S("cameras.calibration_error_px"), "a value from 0 to 100 pixels", str(err))
    spacing = _range(cams, "spacing_deg", "cameras", source, SPACING_RANGE_DEG)
    spaced = max(count // 3, 1) if layout == "trinocular" else count  # trinocular: the heads are spaced
    if spacing is not None and spaced > 1 and spacing[0] * (spaced - 1) > 360.0:
        raise InputError(S("cameras.spacing_deg"), f"at most {360.0 / (spaced - 1):g} degrees for {spaced} "
                         + ("heads" if layout == "trinocular" else "cameras"), repr(cams["spacing_deg"]))
    subject_px = _range(cams, "subject_px", "cameras", source, SUBJECT_PX_RANGE)
    if subject_px is not None and layout != "broadcast":
        raise InputError(S("cameras.subject_px"), "no value for a studio (its cameras frame the whole volume)",
                         repr(cams["subject_px"]))
    heads, baseline = _trinocular(cams, layout, count, source)
    return count, layout, res, err, spacing, subject_px, heads, baseline


def _novel_table(d: dict, source: str) -> tuple[str, int]:
    """Parse the ``[novel]`` table.

    Parameters
    ----------
    d : dict
        The spec's TOML.
    source : str
        File name used in error messages.

    Returns
    -------
    placement : str
    count : int
        Number of novel views.

    Raises
    ------
    InputError
        A mistyped or impossible value.
    """
    S = lambda k: f"{source}: {k}"  # noqa: E731
    novel = _get(d, "novel", f"{source}: ", dict, {})
    _check_keys(novel, {"count", "placement"}, "novel", source)
    placement = _get(novel, "placement", f"{source}: novel.", str, "between")
    if placement not in NOVEL_PLACEMENTS:
        raise InputError(S("novel.placement"), f"one of {list(NOVEL_PLACEMENTS)}", repr(placement))
    ncount = _get(novel, "count", f"{source}: novel.", int, 0)
    if not 0 <= ncount <= MAX_CAMERAS:
        raise InputError(S("novel.count"), f"an integer from 0 to {MAX_CAMERAS}", str(ncount))
    return placement, ncount


def _render_table(d: dict, source: str) -> tuple[int, str, int]:
    """Parse the ``[render]`` table.

    Parameters
    ----------
    d : dict
        The spec's TOML.
    source : str
        File name used in error messages.

    Returns
    -------
    sample_count : int
    engine : str
    supersample : int

    Raises
    ------
    InputError
        A mistyped or impossible value.
    """
    S = lambda k: f"{source}: {k}"  # noqa: E731
    render = _get(d, "render", f"{source}: ", dict, {})
    _check_keys(render, {"sample_count", "engine", "supersample"}, "render", source)
    sc = _get(render, "sample_count", f"{source}: render.", int, 1)
    if sc not in (1, 2, 4, 8):
        raise InputError(S("render.sample_count"), "1, 2, 4 or 8", str(sc))
    engine = _get(render, "engine", f"{source}: render.", str, "raycast")
    if engine not in ("raycast", "open3d"):
        raise InputError(S("render.engine"), "'raycast' or 'open3d'", repr(engine))
    ss = _get(render, "supersample", f"{source}: render.", int, 2)
    if not 1 <= ss <= 4:
        raise InputError(S("render.supersample"), "an integer from 1 to 4", str(ss))
    return sc, engine, ss


def parse_spec(text: str, source: str = "<spec>", base_dir: Path | None = None) -> SceneSpec:
    """Parse and validate a scene spec from TOML text.

    Parameters
    ----------
    text : str
        TOML content.
    source : str
        File name used in error messages.
    base_dir : Path, optional
        Folder relative BVH paths are resolved against.

    Raises
    ------
    InputError
        Naming ``source`` and the field for every missing, mistyped or impossible value.
    """
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(source, "valid TOML", f"a syntax error: {e}") from None
    _check_keys(d, {"seed", "frames", "fps", "subject", "cameras", "novel", "render", "depth_camera", "name",
                    "description", "markers", "players"}, "", source)
    S = lambda k: f"{source}: {k}"  # noqa: E731
    seed = _get(d, "seed", f"{source}: ", int)
    if seed < 0:
        raise InputError(S("seed"), "an integer >= 0", str(seed))
    frames = _get(d, "frames", f"{source}: ", int)
    if not 1 <= frames <= MAX_FRAMES:
        raise InputError(S("frames"), f"an integer from 1 to {MAX_FRAMES}", str(frames))
    fps = float(_get(d, "fps", f"{source}: ", (int, float)))
    if not 0 < fps <= 1000:
        raise InputError(S("fps"), "a frame rate in (0, 1000]", str(fps))
    h, motion, outfit, shirt_rgb, trousers_rgb, pattern = _subject_table(d, source, base_dir)
    area = _subject_area(d, source)
    markers = _get(d, "markers", f"{source}: ", dict, None)
    if markers is not None:  # a marker capture: its cameras are [markers].cameras, no videos are rendered
        if "cameras" in d:
            raise InputError(S("cameras"), "no [cameras] table in a marker capture (its cameras are "
                             "[markers].cameras)", "a [cameras] table")
        m = MarkerSpec.from_table(markers, source)
        d["cameras"] = {"count": m.camera_count, "layout": "studio", "resolution": list(m.resolution),
                        "calibration_error_px": m.calibration_error_px}
    count, layout, res, err, spacing, subject_px, heads, baseline = _cameras_table(d, source)
    placement, ncount = _novel_table(d, source)
    sc, engine, ss = _render_table(d, source)
    depth = _get(d, "depth_camera", f"{source}: ", dict, None)
    players = _players(d, source, layout, motion)
    if players is not None and markers is not None:
        raise InputError(S("players"), "no [players] table in a marker capture (one person wears the markers)",
                         "a [players] table")
    if players is not None and area is not None:
        raise InputError(S("subject.area_m"), "no area with a [players] table (the players' paths are the "
                         "table's)", repr(area))
    if players is not None and depth is not None:
        raise InputError(S("players"), "no [players] table with a [depth_camera] (the depth camera sees the "
                         "subject alone)", "a [players] table")
    return SceneSpec(seed=seed, frames=frames, fps=fps, height_m=h, motion=motion, camera_count=count,
                     layout=layout, resolution=(res[0], res[1]), calibration_error_px=err, novel_count=ncount,
                     outfit=outfit, shirt_rgb=shirt_rgb, trousers_rgb=trousers_rgb, pattern=pattern,
                     spacing_deg=spacing, subject_px=subject_px, novel_placement=placement,
                     sample_count=sc, engine=engine, supersample=ss, depth_camera=depth, heads=heads,
                     baseline_m=baseline, markers=markers, players=players, area_m=area, source=source,
                     text=text)


def load_spec(path: str | Path) -> SceneSpec:
    """Read and validate a scene spec file (see :func:`parse_spec`)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(str(p), "a scene spec TOML file", "no such file")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(str(p), "a readable UTF-8 text file", str(e)) from None
    return parse_spec(text, str(p), p.parent)
