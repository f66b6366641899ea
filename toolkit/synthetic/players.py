"""Scenes with several players: their bodies, kits and paths, and a zoo of such scenes.

A spec's ``[players]`` table (:class:`~toolkit.synthetic.spec.PlayersSpec`,
``docs/scene_spec.md``) asks for ``count`` people; player 0 is the spec's
``[subject]``, drawn from the scene's own random streams exactly as in a scene
without the table, the others from a stream of their own
(:func:`player_streams`), so the one-person scenes of a seed never change.

Every player has its own proportions, body, outfit and motion
(:func:`draw_players`).  Kits: ``"teams"`` dresses players 0, 2, 4 and 1, 3, 5
in two kits (the subject's team close to the pitch when the subject's
``outfit = "like_background"``), ``"random"`` gives everyone an outfit of their
own.  Paths (:func:`place_players`): with ``path = "cross"`` walks and runs go
along straight lines through the middle of the volume at random headings;
the first two crossing there mid-sequence, one about a metre behind the other,
so that once the cameras are drawn the group is turned about the vertical
(:func:`turn_to_camera`) until the first camera looks along the pair at the
crossing frame and sees one partly in front of the other.  Motions that stay
in place (and walks the motion library can only lay on a circle, in
sequences too long for a line) move on spots of their own; with
``path = "spots"`` everyone does.  People keep :data:`MIN_CLEARANCE_M` apart
(hips, every frame), the crossing pair :data:`MIN_CROSSING_CLEARANCE_M`.

:func:`players_zoo` draws varied multi-player specs from a seed for benchmarks.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.body.model import SHIRT_COLOURS, TROUSER_COLOURS, BodyModel, BodyShape, dress
from toolkit.cameras import Camera, Rig
from toolkit.errors import InputError
from toolkit.motion import motion_from_bvh, synthesize_motion
from toolkit.skeleton import SKELETON_14
from toolkit.synthetic.environment import SURROUNDING_COLOURS
from toolkit.synthetic.spec import MAX_PLAYERS, TRAVELLING_MOTIONS, SceneSpec, parse_spec

__all__ = ["Player", "Crossing", "Kit", "player_streams", "draw_players", "place_players", "team_kits",
           "group_extent", "turn_to_camera", "frame_group", "players_zoo", "PLAYERS_SPAWN_KEY",
           "MIN_CLEARANCE_M", "MIN_CROSSING_CLEARANCE_M"]

#: Spawn key of the players' random stream: a child of the spec's seed that the scene's streams
#: (``generator.RNG_STREAMS``, spawned as children 0, 1, ...) and the marker capture's never reach,
#: so adding players leaves every other draw of a seed unchanged.
PLAYERS_SPAWN_KEY = 1000
#: Horizontal distance (metres) two players' hip centres keep in every frame.
MIN_CLEARANCE_M = 0.8
#: The same for the crossing pair (one passes close behind the other).
MIN_CROSSING_CLEARANCE_M = 0.6
#: Where the crossing pair's lines meet: within this share of ``spread_m`` of the middle.
CROSSING_NEAR_MIDDLE = 0.25
#: Angle between the crossing pair's lines, degrees.
CROSSING_ANGLE_DEG = (60.0, 120.0)
#: When the first of the pair is on the crossing point, as shares of the sequence.
CROSSING_TIME = (0.4, 0.6)
#: How far (metres) the second of the pair is behind the crossing point then.
CROSSING_GAP_M = (0.9, 1.2)
#: The pair is turned this far (degrees, either side) off the first camera's line of sight, so that the
#: one behind stays partly visible.
CROSSING_SIGHT_OFFSET_DEG = (8.0, 16.0)
#: Other players pass their own point of the volume within this share of the sequence.
PASS_TIME = (0.15, 0.85)
#: Tries to draw a walk or run on a line (the library lays a walk on a line with probability 0.6 when
#: it fits within its line length, else on a circle).
LINE_TRIES = 40
#: Tries to place a player clear of the others; every :data:`SPREAD_GROWTH_EVERY` failed tries the
#: radius grows by :data:`SPREAD_GROWTH`.
PLACE_TRIES = 300
SPREAD_GROWTH_EVERY, SPREAD_GROWTH = 25, 1.25
#: A kit's shirt differs from the other team's and from its own trousers by at least this much (sum of
#: the RGB differences, as :meth:`BodyShape.sample` keeps shirt and trousers apart).
KIT_CONTRAST = 0.6
#: A drawn (not ``like_background``) shirt differs from the surroundings' colours by at least this much.
KIT_BACKGROUND_CONTRAST = 0.45
#: Cameras stand at least this far (metres, horizontally) outside the radius the group moves in
#: (:func:`group_extent`); a rig that does not is moved back (studios, long walks).
CAMERA_CLEARANCE_M = 1.0
#: Cameras are widened (focal length reduced) until every player projects this share of the image
#: size inside its border.
FRAME_MARGIN = 0.04
#: The top of the head above the ``head`` joint (metres), for framing.
HEAD_TOP_M = 0.15

_J = {n: i for i, n in enumerate(SKELETON_14.joint_names)}


@dataclass(frozen=True)
class Kit:
    """A team's kit: shirt, print and trouser colours (RGB in [0, 1]), print kind, sleeve and leg lengths."""

    shirt: tuple
    print_colour: tuple
    trousers: tuple
    pattern: str
    long_sleeves: bool
    long_trousers: bool

    def apply(self, shape: BodyShape) -> BodyShape:
        """``shape`` (its skin, hair, shoes and build kept) wearing this kit."""
        colours = shape.colours.copy()
        colours[2], colours[3] = self.shirt, self.trousers
        trousers = np.asarray(self.trousers, float)
        return replace(shape, colours=colours, pattern=np.array([self.print_colour, trousers * 0.6]),
                       pattern_kind=self.pattern, long_sleeves=self.long_sleeves,
                       long_trousers=self.long_trousers)


@dataclass(frozen=True, eq=False)
class Player:
    """One person of a scene with several players.

    Attributes
    ----------
    index : int
        Player ``k`` is instance id ``k + 1``; player 0 is the spec's ``[subject]``.
    proportions : BodyProportions
    body : BodyModel
    joints : ndarray of shape (T, 14, 3)
        Metres, world (z up); NaN where absent.
    motion : str
        Motion name (or the BVH path of the subject).
    path : str
        ``"line"`` (a straight walk or run) or ``"spot"`` (moves about one place).
    team : int or None
        0 or 1 with team kits.
    """

    index: int
    proportions: BodyProportions
    body: BodyModel
    joints: np.ndarray
    motion: str
    path: str
    team: int | None = None

    def outfit(self, kind: str) -> dict:
        """What the player wears, for ``scene_info.json`` (``kind``: the kit's origin)."""
        s = self.body.shape
        return {"kind": kind, "team": self.team, "pattern": s.pattern_kind, "long_sleeves": s.long_sleeves,
                "long_trousers": s.long_trousers,
                "shirt_rgb": [round(float(v), 3) for v in s.colours[2]],
                "trousers_rgb": [round(float(v), 3) for v in s.colours[3]]}


@dataclass(frozen=True)
class Crossing:
    """Two players crossing mid-sequence.

    Attributes
    ----------
    frame : int
        The frame at which ``first`` is on the crossing point and ``second`` about ``gap_m`` before it.
    first, second : int
        Player indices.
    gap_m : float
        Distance of ``second`` from the crossing point at ``frame``, metres.
    sight_offset_deg : float
        Angle between the pair and the first camera's line of sight once turned (:func:`turn_to_camera`).
    """

    frame: int
    first: int
    second: int
    gap_m: float
    sight_offset_deg: float


def player_streams(seed: int) -> dict[str, np.random.Generator | list]:
    """The players' random streams of a spec's ``seed``.

    Returns
    -------
    dict
        ``"group"`` (statures and kits), ``"place"`` (paths and timing) and ``"players"``: one generator
        per player slot ``1 .. MAX_PLAYERS - 1`` (index 0 unused: player 0 is drawn from the scene's
        streams), each for that player's body, outfit and motion, so overriding one player leaves the
        others unchanged.
    """
    kids = np.random.SeedSequence(seed, spawn_key=(PLAYERS_SPAWN_KEY,)).spawn(2 + MAX_PLAYERS)
    gens = [np.random.default_rng(k) for k in kids]
    return {"group": gens[0], "place": gens[1], "players": gens[2:]}


def _far(colour, others, d) -> bool:
    return all(np.abs(np.asarray(colour) - np.asarray(o)).sum() >= d for o in others)


def team_kits(layout: str, like_background: bool, shirts=None,
              rng: np.random.Generator | int | None = None) -> tuple[Kit, Kit]:
    """Two team kits that differ clearly from each other.

    Parameters
    ----------
    layout : str
        Camera layout (what the kits are seen against, :data:`SURROUNDING_COLOURS`).
    like_background : bool
        Team 0's shirt and print drawn close to the surroundings (a kit like the pitch).
    shirts : sequence of 2 (r, g, b), optional
        Explicit shirt colours (RGB in [0, 1]) of the two teams; the draws are made all the same.
    rng : numpy.random.Generator or int or None

    Returns
    -------
    tuple of Kit
    """
    rng = np.random.default_rng(rng)
    near = np.asarray(SURROUNDING_COLOURS[layout], float).reshape(-1, 3)
    palette = [c for c in SHIRT_COLOURS if _far(c, near, KIT_BACKGROUND_CONTRAST)]
    base = near[rng.integers(len(near))]
    close = np.clip(base * rng.uniform(0.9, 1.2) + rng.uniform(-0.06, 0.06, 3), 0, 1)
    first = palette[rng.integers(len(palette))]
    shirt0 = close if like_background else first
    if shirts is not None:
        shirt0 = np.asarray(shirts[0], float)
    others = [c for c in palette if _far(c, [shirt0], KIT_CONTRAST)] or palette
    shirt1 = others[rng.integers(len(others))] if shirts is None else np.asarray(shirts[1], float)
    long_trousers_p = 0.2 if layout == "broadcast" else 0.8  # shorts on a pitch
    kits = []
    for shirt in (shirt0, shirt1):
        trousers = [c for c in TROUSER_COLOURS if _far(c, [shirt], KIT_CONTRAST)] or list(TROUSER_COLOURS)
        prints = [c for c in SHIRT_COLOURS if _far(c, [shirt], 0.5)]
        tr = trousers[rng.integers(len(trousers))]
        pr = prints[rng.integers(len(prints))]
        pattern = str(rng.choice(["stripes", "checks", "plain"], p=[0.4, 0.2, 0.4]))
        sleeves, legs = bool(rng.random() < 0.3), bool(rng.random() < long_trousers_p)
        kits.append(Kit(tuple(float(v) for v in shirt), tuple(float(v) for v in pr), tuple(float(v) for v in tr),
                        pattern, sleeves, legs))
    if like_background and shirts is None:  # the print close to the shirt too, as dress(near=...) draws it
        s0 = np.asarray(kits[0].shirt)
        pr = np.clip(s0 * rng.choice([0.7, 1.3]) + rng.uniform(-0.04, 0.04, 3), 0, 1)
        kits[0] = replace(kits[0], print_colour=tuple(float(v) for v in pr))
    return kits[0], kits[1]


# ------------------------------------------------------------------ people
def _motion(name: str, props: BodyProportions, spec: SceneSpec, rng: np.random.Generator, line: bool):
    """``(joints (T, 14, 3), line model or None)``: a library motion (a walk or run on a line when ``line``)
    or the subject's BVH."""
    if name.lower().endswith(".bvh"):
        return motion_from_bvh(name, props, spec.frames, spec.fps, rng), None
    m = synthesize_motion(name, props, spec.frames, spec.fps, rng)
    if not (line and name in TRAVELLING_MOTIONS):
        return m.joints, None
    for _ in range(LINE_TRIES - 1):
        if m.params.get("path") == "line":
            break
        m = synthesize_motion(name, props, spec.frames, spec.fps, rng)
    if m.params.get("path") != "line":  # too long a sequence for a line: it circles about its spot
        return m.joints, None
    h, v = m.params["heading"], m.params["speed_m_s"]
    u = np.array([-np.sin(h), np.cos(h)])  # the library's direction of travel for heading h
    t = np.arange(spec.frames) / spec.fps
    q0 = np.nanmean(_hips(m.joints) - v * t[:, None] * u, axis=0)
    return m.joints, (q0, u, v)


def draw_players(spec: SceneSpec, rngs: dict) -> tuple[list[Player], list, list[str]]:
    """The people of a spec with a ``[players]`` table, before they are placed.

    Parameters
    ----------
    spec : SceneSpec
    rngs : dict of str to numpy.random.Generator
        The scene's streams (``generator.RNG_STREAMS``): player 0 (the ``[subject]``) is drawn from
        ``body``, ``outfit`` and ``motion`` in the order of a one-person scene.

    Returns
    -------
    players : list of Player
        Joints as the motion library put them (see :func:`place_players`).
    lines : list
        Per player the line of a straight walk or run, ``(q0, u, speed)``: hips at time ``tau`` at
        ``q0 + speed * tau * u`` (metres), or None for a player on a spot.
    kit_kinds : list of str
        Where each outfit comes from (``"team 0"``, ``"random"``, ``"like_background"``, ``"explicit"``).
    """
    ps = spec.players
    if ps is None:
        raise InputError(f"{spec.source}: [players]", "a [players] table", "none")
    streams = player_streams(spec.seed)
    group = streams["group"]
    heights = group.uniform(*ps.height_m, MAX_PLAYERS)
    kits = team_kits(spec.layout, spec.outfit == "like_background", ps.team_shirts, group) \
        if ps.kits == "teams" else None
    cross = ps.path == "cross"
    players, lines, kinds = [], [], []
    for k in range(ps.count):
        team = k % 2 if kits is not None else None
        if k == 0:  # the subject: the one-person scene's draws
            props = BodyProportions.sample(spec.height_m, rngs["body"])
            shape = BodyShape.sample(props, rngs["body"])
            if kits is None:
                kind = spec.outfit
                if spec.outfit != "random" or spec.shirt_rgb or spec.trousers_rgb or spec.pattern:
                    near = SURROUNDING_COLOURS[spec.layout] if spec.outfit == "like_background" else None
                    shape = dress(shape, near=near, shirt_rgb=spec.shirt_rgb, trousers_rgb=spec.trousers_rgb,
                                  pattern=spec.pattern, rng=rngs["outfit"])
            else:
                kind = f"team {team}" + (" like_background" if spec.outfit == "like_background" else "")
                shape = kits[team].apply(shape)
                if spec.shirt_rgb or spec.trousers_rgb or spec.pattern:
                    kind = "explicit"
                    shape = dress(shape, shirt_rgb=spec.shirt_rgb, trousers_rgb=spec.trousers_rgb,
                                  pattern=spec.pattern)
            body = BodyModel(shape, rngs["body"])
            motion_name, motion_rng = spec.motion, rngs["motion"]
        else:
            o = ps.override(k)
            rng = streams["players"][k]
            props = BodyProportions.sample(o.height_m or float(heights[k]), rng)
            shape = BodyShape.sample(props, rng)
            kind = "random" if kits is None else f"team {team}"
            if kits is not None:
                shape = kits[team].apply(shape)
            if o.shirt_rgb or o.trousers_rgb:
                kind = "explicit"
                shape = dress(shape, shirt_rgb=o.shirt_rgb, trousers_rgb=o.trousers_rgb)
            body = BodyModel(shape, rng)
            motion_name, motion_rng = o.motion or ps.motion, rng
        joints, line = _motion(motion_name, props, spec, motion_rng, cross)
        players.append(Player(k, props, body, joints, motion_name, "line" if line else "spot", team))
        lines.append(line)
        kinds.append(kind)
    return players, lines, kinds


# ------------------------------------------------------------------ paths
def _hips(joints: np.ndarray) -> np.ndarray:
    """Hip centres (T, 2), metres."""
    return 0.5 * (joints[:, _J["l_hip"], :2] + joints[:, _J["r_hip"], :2])


def _moved(joints: np.ndarray, angle: float, src, dst) -> np.ndarray:
    """``joints`` turned by ``angle`` (radians, about z) around the point ``src`` (xy), which goes to ``dst``."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])
    out = joints.copy()
    out[..., :2] = (joints[..., :2] - np.asarray(src)) @ R.T + np.asarray(dst)
    return out


def _on_line(joints, line, point, direction: float, tau: float) -> np.ndarray:
    """A straight walk moved so that its hips pass ``point`` at time ``tau`` (s) heading ``direction`` (rad)."""
    q0, u, v = line
    return _moved(joints, direction - np.arctan2(u[1], u[0]), q0 + v * tau * u, point)


def _clearance(a: np.ndarray, b: np.ndarray) -> float:
    """Smallest horizontal distance between two players' hips over the frames both are present, metres."""
    d = np.linalg.norm(_hips(a) - _hips(b), axis=-1)
    return float(np.nanmin(d)) if np.isfinite(d).any() else np.inf


def _disc(rng: np.random.Generator, radius: float) -> np.ndarray:
    r = radius * np.sqrt(rng.uniform(0.0, 1.0))
    a = rng.uniform(0.0, 2 * np.pi)
    return np.array([r * np.cos(a), r * np.sin(a)])


def place_players(players: list[Player], lines: list, path: str, spread_m: float, fps: float,
                  rng: np.random.Generator | int | None = None) -> tuple[list[Player], Crossing | None]:
    """Lay the players' motions out around the origin.

    Parameters
    ----------
    players : list of Player
        As drawn (:func:`draw_players`).
    lines : list
        Their lines (None for a player on a spot).
    path : {"cross", "spots"}
    spread_m : float
        Radius (metres) of the points the lines pass and of the spots.
    fps : float
    rng : numpy.random.Generator or int or None

    Returns
    -------
    players : list of Player
        With their joints moved.
    crossing : Crossing or None
        The crossing pair (the first two players on lines with ``path = "cross"``).

    Raises
    ------
    InputError
        If a player finds no place :data:`MIN_CLEARANCE_M` clear of the others (not met in practice: the
        radius grows while trying).
    """
    rng = np.random.default_rng(rng)
    n_frames = players[0].joints.shape[0]
    duration = (n_frames - 1) / fps
    placed: dict[int, np.ndarray] = {}
    crossing = None
    on_lines = [k for k, ln in enumerate(lines) if ln is not None] if path == "cross" else []
    if len(on_lines) >= 2:
        a, b = on_lines[:2]
        X = _disc(rng, CROSSING_NEAR_MIDDLE * spread_m)
        th_a = rng.uniform(0.0, 2 * np.pi)
        th_b = th_a + rng.choice([-1.0, 1.0]) * np.radians(rng.uniform(*CROSSING_ANGLE_DEG))
        tau = rng.uniform(*CROSSING_TIME) * duration
        gap = rng.uniform(*CROSSING_GAP_M)
        offset = rng.choice([-1.0, 1.0]) * rng.uniform(*CROSSING_SIGHT_OFFSET_DEG)
        for _ in range(PLACE_TRIES):  # widen the gap until they pass clear of each other
            ja = _on_line(players[a].joints, lines[a], X, th_a, tau)
            jb = _on_line(players[b].joints, lines[b], X, th_b, tau + gap / lines[b][2])
            if _clearance(ja, jb) >= MIN_CROSSING_CLEARANCE_M:
                break
            gap += 0.15
        else:
            raise InputError("[players]", f"a crossing {MIN_CROSSING_CLEARANCE_M} m clear",
                             f"none up to a gap of {gap:.1f} m")
        placed[a], placed[b] = ja, jb
        crossing = Crossing(int(np.clip(round(tau * fps), 0, n_frames - 1)), a, b, float(gap), float(offset))
    for k, p in enumerate(players):
        if k in placed:
            continue
        radius, line = spread_m, (lines[k] if path == "cross" else None)
        for attempt in range(PLACE_TRIES):
            if attempt and attempt % SPREAD_GROWTH_EVERY == 0:
                radius *= SPREAD_GROWTH
            c = _disc(rng, radius)
            if line is not None:
                j = _on_line(p.joints, line, c, rng.uniform(0.0, 2 * np.pi), rng.uniform(*PASS_TIME) * duration)
            else:
                j = _moved(p.joints, 0.0, np.nanmean(_hips(p.joints), axis=0), c)
            if all(_clearance(j, o) >= MIN_CLEARANCE_M for o in placed.values()):
                break
        else:
            raise InputError("[players]", f"room for player {k} {MIN_CLEARANCE_M} m clear of the others",
                             f"none after {PLACE_TRIES} tries (spread_m up to {radius:.1f})")
        placed[k] = j
    return [replace(p, joints=placed[k]) for k, p in enumerate(players)], crossing


def group_extent(players: list[Player]) -> tuple[np.ndarray, float]:
    """The middle of the group on the ground and the radius the cameras must keep in view.

    Returns
    -------
    centre : ndarray of shape (3,)
        Mean neck position over players and frames (z = 0), metres.
    radius : float
        Largest horizontal distance of a joint from ``centre`` plus 0.5 m (as a one-person scene with
        ``subject_px``), metres.
    """
    joints = np.concatenate([p.joints for p in players])
    c = np.nanmean(joints[:, _J["neck"], :2], axis=0)
    r = float(np.nanmax(np.linalg.norm(joints[..., :2] - c, axis=-1))) + 0.5
    return np.r_[c, 0.0], r


def turn_to_camera(players: list[Player], crossing: Crossing, camera: Camera, centre) -> list[Player]:
    """Turn the whole group about the vertical through ``centre`` so that ``camera`` looks along the
    crossing pair at the crossing frame (``crossing.sight_offset_deg`` off its line of sight).

    Distances from ``centre`` are kept, so cameras drawn for the group's extent still frame it.
    """
    f = crossing.frame
    a = _hips(players[crossing.first].joints)[f]
    b = _hips(players[crossing.second].joints)[f]
    c = np.asarray(centre, float)[:2]
    eye = camera.center[:2]
    angle = 0.0
    for _ in range(6):  # the line of sight moves with the pair: a few fixed-point steps
        R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        ra, rb = (a - c) @ R.T + c, (b - c) @ R.T + c
        sight = 0.5 * (ra + rb) - eye
        w = rb - ra
        want = np.arctan2(sight[1], sight[0]) + np.radians(crossing.sight_offset_deg)
        delta = (want - np.arctan2(w[1], w[0]) + np.pi / 2) % np.pi - np.pi / 2  # either player in front
        angle += delta
        if abs(delta) < 1e-9:
            break
    return [replace(p, joints=_moved(p.joints, angle, c, c)) for p in players]


def frame_group(rig: Rig, players: list[Player]) -> Rig:
    """``rig`` made to see the whole group.

    First, when a camera stands less than :data:`CAMERA_CLEARANCE_M` outside the group's radius
    (:func:`group_extent`), every camera of the rig moves back by the same distance along its own
    horizontal viewing direction (orientations kept, so trinocular heads stay rigid).  Then every
    camera some player would leave is widened (focal length reduced about the principal point) until
    every joint of every frame, and the top of the head, projects :data:`FRAME_MARGIN` of the image
    size inside its border; the others are unchanged.
    """
    centre, radius = group_extent(players)
    need = max(radius + CAMERA_CLEARANCE_M - float(np.linalg.norm(cam.center[:2] - centre[:2])) for cam in rig)
    if need > 0:
        moved = []
        for cam in rig:
            back = -cam.forward * np.array([1.0, 1.0, 0.0])
            if np.linalg.norm(back) < 1e-6:  # looking straight down: away from the middle
                back = np.r_[cam.center[:2] - centre[:2], 0.0]
            back /= max(float(np.linalg.norm(back)), 1e-9)
            T = cam.cam_from_world.copy()
            T[:3, 3] = -cam.R @ (cam.center + need * back)
            moved.append(cam.replace(cam_from_world=T))
        rig = Rig(tuple(moved))
    joints = np.concatenate([p.joints for p in players])
    top = joints[:, _J["head"]] + np.array([0.0, 0.0, HEAD_TOP_M])
    pts = np.concatenate([joints.reshape(-1, 3), top])
    pts = pts[np.isfinite(pts).all(1)]
    scales = [_widening(cam, pts) for cam in rig]
    out = []
    for cam in rig:  # cameras of one orientation (a trinocular head) keep equal intrinsics
        s = max(sc for c, sc in zip(rig, scales) if np.allclose(c.R, cam.R, atol=1e-9))
        if s > 1.0:
            K = cam.K.copy()
            K[0, :2] /= s
            K[1, 1] /= s
            cam = cam.replace(K=K)
        out.append(cam)
    return Rig(tuple(out))


def _widening(cam: Camera, pts: np.ndarray) -> float:
    """By how much ``cam``'s focal length must shrink for ``pts`` (N, 3) to project
    :data:`FRAME_MARGIN` inside the image (<= 1: they do already)."""
    pc = cam.to_cam(pts)
    pc = pc[pc[:, 2] > 1e-6]
    w, h = cam.size
    m = FRAME_MARGIN * min(w, h)
    K = cam.K
    x = (pc[:, 0] / pc[:, 2]) * K[0, 0] + (pc[:, 1] / pc[:, 2]) * K[0, 1]  # offsets from the principal point
    y = (pc[:, 1] / pc[:, 2]) * K[1, 1]
    half_x = min(K[0, 2] + 0.5, w - 0.5 - K[0, 2]) - m
    half_y = min(K[1, 2] + 0.5, h - 0.5 - K[1, 2]) - m
    return max(float(np.max(np.abs(x), initial=0.0)) / half_x, float(np.max(np.abs(y), initial=0.0)) / half_y)


# ------------------------------------------------------------------ the zoo
#: Resolutions of the zoo and their probabilities.
ZOO_RESOLUTIONS = ((960, 540), (1280, 720), (1920, 1080))
ZOO_RESOLUTION_P = (0.35, 0.40, 0.25)
#: Broadcast subject sizes the zoo asks for, pixels (the cameras keep the whole group in view, which
#: may make them smaller: ``scene_info.json`` has what each camera got).
ZOO_SUBJECT_PX = (100.0, 300.0)
#: Share of the broadcast scenes whose subject's team wears a kit close to the pitch.
ZOO_LOW_CONTRAST_P = 0.25
#: In-place motions the ``spots`` scenes draw from.
ZOO_SPOT_MOTIONS = ("idle", "wave", "turn", "kick", "crouch", "jump")


def players_zoo(seed: int, count: int, frames: int = 24) -> list[SceneSpec]:
    """``count`` varied multi-player scene specs drawn from ``seed``.

    The first ten cover 2-6 players with each layout (broadcast with two team
    kits, studio with own outfits); after them the layout is broadcast with
    probability 2/3 and the player count uniform in 2-6.  Every scene has 2-4
    cameras, 30-150 degrees apart; broadcast asks for a subject of 100-300 px
    (:data:`ZOO_SUBJECT_PX`) and a quarter of the broadcast scenes dress the
    subject's team close to the pitch (``outfit = "like_background"``).  Three
    scenes in four cross (walks and runs along lines), the others stay on spots.

    Parameters
    ----------
    seed : int
        Zoo seed (>= 0); scene ``i`` gets the spec seed ``seed * 1000 + i``.
    count : int
        Number of specs (>= 0).
    frames : int
        Frames per scene.

    Returns
    -------
    list of SceneSpec
        Each with its TOML in ``text`` and ``source = "<name>.toml"``; the name tells the layout, camera
        and player counts, path kind and image height.

    Raises
    ------
    InputError
        A negative ``seed`` or ``count``, or ``frames`` below 1.

    Examples
    --------
    >>> specs = players_zoo(3, 4)
    >>> [s.players.count >= 2 for s in specs]
    [True, True, True, True]
    """
    for name, v, lo in (("seed", seed, 0), ("count", count, 0), ("frames", frames, 1)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise InputError(f"players_zoo: {name}", f"an integer >= {lo}", repr(v))
    rng = np.random.default_rng(seed)
    combos = [(n, lay) for lay in ("broadcast", "studio") for n in range(2, MAX_PLAYERS + 1)]
    combos = [combos[i] for i in rng.permutation(len(combos))]
    out = []
    for i in range(count):
        if i < len(combos):
            n_players, layout = combos[i]
        else:
            n_players = int(rng.integers(2, MAX_PLAYERS + 1))
            layout = "broadcast" if rng.random() < 2 / 3 else "studio"
        n_cams = int(rng.integers(2, 5))
        w, h = ZOO_RESOLUTIONS[rng.choice(len(ZOO_RESOLUTIONS), p=ZOO_RESOLUTION_P)]
        path = "cross" if rng.random() < 0.75 else "spots"
        motion = str(rng.choice(TRAVELLING_MOTIONS)) if path == "cross" else str(rng.choice(ZOO_SPOT_MOTIONS))
        low_contrast = layout == "broadcast" and rng.random() < ZOO_LOW_CONTRAST_P
        hi = min(150.0, 330.0 / (n_cams - 1))  # the cameras' arc must not close on itself
        spacing = float(rng.uniform(30.0, hi))
        lines = [f"# players zoo scene {i} (zoo seed {seed})", f"seed = {seed * 1000 + i}",
                 f"frames = {frames}", "fps = 25", "", "[subject]",
                 f"height_m = {rng.uniform(1.60, 1.95):.2f}", f'motion = "{motion}"']
        if low_contrast:
            lines.append('outfit = "like_background"')
        lines += ["", "[cameras]", f"count = {n_cams}", f'layout = "{layout}"', f"resolution = [{w}, {h}]",
                  f"calibration_error_px = {round(float(rng.uniform(0, 10)) * 2) / 2:.1f}",
                  f"spacing_deg = [{max(0.85 * spacing, 30.0):.1f}, {min(1.15 * spacing, hi):.1f}]"]
        if layout == "broadcast":
            lines.append(f"subject_px = {rng.uniform(ZOO_SUBJECT_PX[0], min(ZOO_SUBJECT_PX[1], 0.45 * h)):.0f}")
        kits = "teams" if layout == "broadcast" or rng.random() < 1 / 3 else "random"
        lines += ["", "[players]", f"count = {n_players}", f'path = "{path}"', f'kits = "{kits}"', "",
                  "[novel]", "count = 2", 'placement = "around"', ""]
        name = (f"p{i:02d}_{layout[:2]}{n_cams}_{n_players}p_{path}_{motion}_{h}p"
                + ("_lowc" if low_contrast else ""))
        out.append(parse_spec("\n".join(lines), f"{name}.toml"))
    return out
