"""Generate a synthetic multi-camera dataset with exact ground truth.

The flow of :func:`generate_scene`:

1. independent random streams (one per concern) from the spec's seed;
2. body proportions within the anthropometric limits, an outfit, a motion;
3. true cameras for the layout, the perturbed ("measured") calibration, novel cameras;
4. per frame: the posed body mesh, an Open3D render per camera, and a ray cast
   per camera for the exact part labels, mask and depth;
5. ground truth: 3D joints, their projections through the *true* cameras, masks,
   part labels, depth, novel views; and a ``scene_info.json`` with the
   achieved calibration error and subject size per camera.

Every report goes to the observer (the recipe passes a rerun observer).

A spec with a ``[players]`` table has several people (:mod:`toolkit.synthetic.players`):
all are rendered and ray-cast together; the masks are their union, the part
labels and depth the front-most body's, and the ground truth gains
``people.npz`` (every person's joints) and ``instances/`` (which person each
pixel shows).  Player 0 is the subject of ``joints3d.npz`` and ``joints2d.npz``.
A spec without the table writes exactly what it wrote before the table existed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.anthropometry import BodyProportions
from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.io import DatasetWriter, atomic_write_text
from toolkit.motion import generate_motion, motion_from_bvh
from toolkit.observe import Observer, as_observer
from toolkit.skeleton import SKELETON_14
from toolkit.body.model import BodyMesh, BodyModel, BodyShape, dress
from toolkit.synthetic.depth_sensor import DepthCameraOutput, DepthCameraSpec, depth_camera_for, render_depth_camera
from toolkit.synthetic.environment import BACKGROUND_COLOUR, SURROUNDING_COLOURS, field_model, make_environment
from toolkit.synthetic.players import (Crossing, draw_players, frame_group, group_extent, place_players,
                                       player_streams, turn_to_camera)
from toolkit.synthetic.render import Raycaster, RaycastRenderer, SceneRenderer
from toolkit.synthetic.rigs import make_rig, novel_rig, perturb_rig
from toolkit.synthetic.spec import SceneSpec

#: Names of the independent random streams drawn from the spec's seed (order matters).  The extra people
#: of a ``[players]`` table draw from streams of their own (:func:`toolkit.synthetic.players.player_streams`,
#: a child of the seed beyond these and the marker capture's), so one-person scenes keep their draws.
RNG_STREAMS = ("body", "motion", "cameras", "calibration", "environment", "novel", "light", "depth", "outfit")


@dataclass(frozen=True)
class Scene:
    """Everything about a synthetic scene except its images.

    Attributes
    ----------
    spec : SceneSpec
    proportions : BodyProportions
    body : BodyModel
    joints : ndarray of shape (T, 14, 3)
        Ground-truth joints, metres, world (z up).
    rig : Rig
        True cameras.
    measured_rig : Rig
        Perturbed calibration written for the pipeline.
    calibration_errors_px : ndarray of shape (n_cams,)
        Mean reprojection error of the joints through the measured rig.
    novel : Rig
        Evaluation cameras.
    light_dir : ndarray of shape (3,)
        Direction towards the light (world).
    rngs : dict of str to numpy.random.Generator
        The streams of :data:`RNG_STREAMS` (as left by the draws above).
    players : tuple of toolkit.synthetic.players.Player
        Every person of a spec with a ``[players]`` table (player 0 is ``proportions``, ``body`` and
        ``joints``); empty for a one-person spec.
    crossing : Crossing or None
        The pair crossing mid-sequence (``[players] path = "cross"``).
    kit_kinds : tuple of str
        Where each player's outfit comes from (``scene_info.json``).
    """

    spec: SceneSpec
    proportions: BodyProportions
    body: BodyModel
    joints: np.ndarray
    rig: Rig
    measured_rig: Rig
    calibration_errors_px: np.ndarray
    novel: Rig
    light_dir: np.ndarray
    rngs: dict
    players: tuple = ()
    crossing: Crossing | None = None
    kit_kinds: tuple = ()

    def body_mesh(self, t: int) -> BodyMesh:
        """The posed body mesh of frame ``t``."""
        return self.body.mesh(self.joints[t])

    @property
    def people_joints(self) -> np.ndarray:
        """Every person's joints, (P, T, 14, 3) metres (P = 1 for a one-person spec)."""
        return np.stack([p.joints for p in self.players]) if self.players else self.joints[None]

    def posed_bodies(self, t: int) -> list[tuple[int, BodyMesh]]:
        """``(person index, posed mesh)`` of everyone present at frame ``t``."""
        if not self.players:
            return [(0, self.body_mesh(t))]
        return [(p.index, p.body.mesh(p.joints[t])) for p in self.players if np.isfinite(p.joints[t]).all()]


#: Joints of the subject that a spec with ``[subject] area_m`` keeps inside every camera's image (and a
#: depth camera's range) in every frame: the trunk and head, where the body is (a hand or a foot swinging
#: past the image's edge is allowed).
VIEW_JOINTS = ("head", "neck", "l_shoulder", "r_shoulder", "l_hip", "r_hip")
#: A walk or run whose trunk leaves a camera's view is drawn again with its area shrunk by this factor ...
AREA_SHRINK = 0.8
#: ... at most this many times (the last draw is kept).
AREA_TRIES = 8


def frames_out_of_view(cameras, joints: np.ndarray, depth_range_m=None) -> np.ndarray:
    """Which frames have a :data:`VIEW_JOINTS` joint outside a camera's image (or depth range).

    Parameters
    ----------
    cameras : sequence of Camera
    joints : ndarray of shape (T, 14, 3)
        Metres, world.
    depth_range_m : tuple of float, optional
        ``(near, far)`` metres along each camera's optical axis the joints must lie within (a depth
        camera's valid readings); None: in front of the camera.

    Returns
    -------
    ndarray of shape (T,), bool
    """
    idx = [SKELETON_14.joint_names.index(n) for n in VIEW_JOINTS]
    J = np.asarray(joints, float)[:, idx]
    T = len(J)
    near, far = depth_range_m if depth_range_m is not None else (1e-6, np.inf)
    out = np.zeros(T, bool)
    for cam in cameras:
        z = cam.depth_of(J)
        inside = cam.in_image(cam.project(J)) & (z >= near) & (z <= far)
        out |= ~inside.all(axis=1)
    return out


def build_scene(spec: SceneSpec) -> Scene:
    """Draw the person (or people), motion and cameras of ``spec`` (no rendering).

    With ``[subject] area_m`` (walks and runs; :func:`toolkit.motion.synthesize_motion`'s ``area_m``) the
    scene is drawn again, from the same seed, with the area shrunk by :data:`AREA_SHRINK` while a frame's
    trunk (:data:`VIEW_JOINTS`) is outside a source camera's image or, with a ``[depth_camera]``, the depth
    camera's image and range (:func:`frames_out_of_view`), at most :data:`AREA_TRIES` times: a sequence
    of any length then stays where every camera sees it.  A path drawn within the area and in view is
    the one drawn without the field.
    """
    if spec.players is not None or spec.area_m is None or spec.motion not in ("walk", "run"):
        return _build_scene(spec, spec.area_m)
    area = spec.area_m
    for _ in range(AREA_TRIES - 1):
        scene = _build_scene(spec, area)
        out = frames_out_of_view(scene.rig, scene.joints)
        if spec.depth_camera is not None:
            dspec = DepthCameraSpec.from_table(spec.depth_camera, spec.source)
            out |= frames_out_of_view([depth_camera_for(dspec, scene.joints)], scene.joints, dspec.range_m)
        if not out.any():
            return scene
        area *= AREA_SHRINK
    return _build_scene(spec, area)


def _build_scene(spec: SceneSpec, area_m: float | None) -> Scene:
    """:func:`build_scene` with the walk's or run's area ``area_m`` (metres; None: the path as drawn)."""
    seqs = np.random.SeedSequence(spec.seed).spawn(len(RNG_STREAMS))
    rngs = {name: np.random.default_rng(s) for name, s in zip(RNG_STREAMS, seqs)}
    if spec.players is not None:
        return _build_players_scene(spec, rngs)
    props = BodyProportions.sample(spec.height_m, rngs["body"])
    shape = BodyShape.sample(props, rngs["body"])  # the draws of BodyModel.sample, dressed in between
    if spec.outfit != "random" or spec.shirt_rgb or spec.trousers_rgb or spec.pattern:
        near = SURROUNDING_COLOURS[spec.layout] if spec.outfit == "like_background" else None
        shape = dress(shape, near=near, shirt_rgb=spec.shirt_rgb, trousers_rgb=spec.trousers_rgb,
                      pattern=spec.pattern, rng=rngs["outfit"])
    body = BodyModel(shape, rngs["body"])
    if spec.motion_is_bvh:
        joints = motion_from_bvh(spec.motion, props, spec.frames, spec.fps, rngs["motion"])
    else:
        joints = generate_motion(spec.motion, props, spec.frames, spec.fps, rngs["motion"], area_m=area_m)
    centre = np.r_[np.nanmean(joints[:, 1, :2], axis=0), 0.0]
    kw = {}
    if spec.subject_px is not None:  # a size asked for: keep only the motion's own extent in view
        kw = dict(subject_px=spec.subject_px,
                  working_radius_m=float(np.nanmax(np.linalg.norm(joints[..., :2] - centre[:2], axis=-1))) + 0.5)
    rig = make_rig(spec.layout, spec.camera_count, spec.resolution, spec.height_m, rngs["cameras"], centre=centre,
                   spacing_deg=spec.spacing_deg, baseline_m=spec.baseline_m, **kw)
    measured, errs = perturb_rig(rig, spec.calibration_error_px, joints.reshape(-1, 3), rngs["calibration"])
    novel = novel_rig(spec.layout, rig, spec.novel_count, spec.height_m, rngs["novel"], centre=centre,
                      placement=spec.novel_placement, **kw)
    az = rngs["light"].uniform(0, 2 * np.pi)
    el = rngs["light"].uniform(np.radians(35), np.radians(70))
    light = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return Scene(spec, props, body, joints, rig, measured, errs, novel, light, rngs)


def _build_players_scene(spec: SceneSpec, rngs: dict) -> Scene:
    """:func:`build_scene` of a spec with a ``[players]`` table.

    The people are drawn and laid out first; the cameras are drawn around the
    group's middle keeping its whole extent in view (``working_radius_m``);
    then the group is turned about that middle so that the first camera looks
    along the crossing pair, and cameras some player would leave are widened.
    """
    ps = spec.players
    players, lines, kinds = draw_players(spec, rngs)
    players, crossing = place_players(players, lines, ps.path, ps.spread_m, spec.fps,
                                      player_streams(spec.seed)["place"])
    centre, radius = group_extent(players)
    kw = dict(working_radius_m=radius)  # the whole group in view
    if spec.subject_px is not None:
        kw["subject_px"] = spec.subject_px
    rig = make_rig(spec.layout, spec.camera_count, spec.resolution, spec.height_m, rngs["cameras"], centre=centre,
                   spacing_deg=spec.spacing_deg, baseline_m=spec.baseline_m, **kw)
    if crossing is not None:
        players = turn_to_camera(players, crossing, rig[0], centre)
    rig = frame_group(rig, players)
    points = np.concatenate([p.joints.reshape(-1, 3) for p in players])
    measured, errs = perturb_rig(rig, spec.calibration_error_px, points, rngs["calibration"])
    novel = frame_group(novel_rig(spec.layout, rig, spec.novel_count, spec.height_m, rngs["novel"], centre=centre,
                                  placement=spec.novel_placement, **kw), players)
    az = rngs["light"].uniform(0, 2 * np.pi)
    el = rngs["light"].uniform(np.radians(35), np.radians(70))
    light = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    p0 = players[0]
    return Scene(spec, p0.proportions, p0.body, p0.joints, rig, measured, errs, novel, light, rngs,
                 players=tuple(players), crossing=crossing, kit_kinds=tuple(kinds))


def _players_info(scene: Scene) -> dict:
    """The ``scene_info.json`` entries of a scene with several people."""
    out = {"players": [{"index": p.index, "stature_m": p.proportions.height, "motion": p.motion, "path": p.path,
                        "outfit": p.outfit(kind),
                        "subject_height_px": dict(zip(scene.rig.names, _subject_heights_px(scene.rig, p.joints)))}
                       for p, kind in zip(scene.players, scene.kit_kinds)]}
    c = scene.crossing
    if c is not None:
        cam = scene.rig[0]
        z = [float(np.nanmean(cam.to_cam(scene.players[k].joints[c.frame])[:, 2])) for k in (c.first, c.second)]
        out["crossing"] = {"frame": c.frame, "players": [c.first, c.second], "camera": cam.name,
                           "front": c.first if z[0] < z[1] else c.second, "gap_m": round(c.gap_m, 3),
                           "sight_offset_deg": round(c.sight_offset_deg, 2)}
    return out


def make_renderer(spec: SceneSpec, surfaces):
    """The colour renderer the spec asks for (``[render] engine``)."""
    if spec.engine == "open3d":
        return SceneRenderer(spec.resolution, surfaces, BACKGROUND_COLOUR[spec.layout], spec.sample_count)
    return RaycastRenderer(spec.resolution, surfaces, BACKGROUND_COLOUR[spec.layout], spec.supersample)


def _subject_heights_px(rig: Rig, joints: np.ndarray) -> list[float]:
    out = []
    for cam in rig:
        uv = cam.project(joints)
        out.append(float(np.nanmedian(np.nanmax(uv[..., 1], 1) - np.nanmin(uv[..., 1], 1))))
    return out


def _spacings_deg(rig: Rig, joints: np.ndarray) -> list[float]:
    """Azimuth gaps between neighbouring cameras around the subject, degrees (sorted by azimuth)."""
    c = np.nanmean(joints[:, 1, :2], axis=0)
    az = np.sort([np.arctan2(*(cam.center[:2] - c)[::-1]) for cam in rig])
    if len(az) < 2:
        return []
    gaps = np.degrees(np.diff(np.r_[az, az[0] + 2 * np.pi]))
    return [round(float(g), 1) for g in gaps]


def _scene_info(spec: SceneSpec, scene) -> dict:
    """The scene's ``groundtruth/scene_info.json``: seed, layout, calibration errors, subject, outfit, spacing.

    Parameters
    ----------
    spec : SceneSpec
    scene : Scene
        From :func:`build_scene`.

    Returns
    -------
    dict
        JSON-serialisable.
    """
    several = bool(scene.players)
    info = {
        "seed": spec.seed,
        "layout": spec.layout,
        "calibration_error_px_target": spec.calibration_error_px,
        "calibration_error_px": dict(zip(scene.rig.names, map(float, scene.calibration_errors_px))),
        "subject_height_px": dict(zip(scene.rig.names, _subject_heights_px(scene.rig, scene.joints))),
        "stature_m": scene.proportions.height,
        "motion": spec.motion,
        "light_dir": scene.light_dir.tolist(),
        "outfit": {"pattern": scene.body.shape.pattern_kind, "long_sleeves": scene.body.shape.long_sleeves,
                   "long_trousers": scene.body.shape.long_trousers, "kind": spec.outfit,
                   "shirt_rgb": [round(float(v), 3) for v in scene.body.shape.colours[2]],
                   "trousers_rgb": [round(float(v), 3) for v in scene.body.shape.colours[3]]},
        "camera_spacing_deg": _spacings_deg(scene.rig, scene.people_joints.reshape(-1, *scene.joints.shape[1:])),
        "novel_placement": spec.novel_placement,
    }
    if several:
        info.update(_players_info(scene))
    return info


def _render_view(writer: DatasetWriter, obs, renderer, caster: Raycaster, cam, t: int, meshes: list,
                 ids: np.ndarray, novel: bool, several: bool, joints2d_t: np.ndarray | None) -> None:
    """Render one camera's frame ``t``, write its image, mask, parts (depth, instances) and report them.

    Parameters
    ----------
    writer : DatasetWriter
    obs : Observer
    renderer
        The colour renderer, bodies set for frame ``t``.
    caster : Raycaster
        Gives the part labels, subject ids and depth.
    cam : Camera
    t : int
        Frame index.
    meshes : list of Mesh
        The posed bodies.
    ids : ndarray of uint8, shape (n_bodies + 1,)
        Person id of the caster's body ``i + 1`` (0: none).
    novel : bool
        A novel (held-out) view: no depth and no 2D joints written or reported.
    several : bool
        Several people: instance masks too.
    joints2d_t : ndarray of shape (14, 2) or None
        The camera's ground-truth 2D joints of frame ``t``, pixels (None for a novel view).
    """
    rgb = renderer.render(cam)
    labels, subject, depth = caster.cast(cam, meshes)
    mask = subject > 0
    if novel:
        writer.write_novel_image(cam.name, t, rgb)
        writer.write_novel_mask(cam.name, t, mask)
        writer.write_novel_parts(cam.name, t, labels)
        if several:
            writer.write_novel_instances(cam.name, t, ids[subject])
        root = "world/novel"
    else:
        writer.write_frame(cam.name, t, rgb)
        writer.write_mask(cam.name, t, mask)
        writer.write_parts(cam.name, t, labels)
        writer.write_depth(cam.name, t, depth)
        if several:
            writer.write_instances(cam.name, t, ids[subject])
        root = "world/cams"
    cam_path = f"{root}/{cam.name}"
    obs.report("image", frame=t, camera=cam_path, image=rgb)
    obs.report("labels", frame=t, camera=cam_path, labels=labels, name="groundtruth/parts")
    if not novel:
        obs.report("depth", frame=t, camera=cam_path, depth=np.nan_to_num(depth),
                   name="groundtruth/depth")
        obs.report("joints2d", frame=t, camera=cam_path, joints=joints2d_t,
                   name="groundtruth/joints2d", skeleton=SKELETON_14)


def generate_scene(spec: SceneSpec, out: str | Path, observer: Observer | None = None, progress: bool = True):
    """Render ``spec`` into the dataset folder ``out``.

    Parameters
    ----------
    spec : SceneSpec
    out : str or Path
        Dataset folder (created; existing files are overwritten).
    observer : Observer, optional
        Receives the rig, skeleton, images, masks, labels, depth and joints per frame.
    progress : bool
        Show a progress bar.

    Returns
    -------
    toolkit.io.Dataset
        The written dataset, reopened and validated.
    """
    if spec.markers is not None:  # a marker capture has no videos: toolkit.synthetic.marker_capture writes it
        raise InputError(f"{spec.source}: [markers]", "a colour scene (generate_marker_capture writes a marker "
                         "capture)", "a [markers] table")
    obs = as_observer(observer)
    scene = build_scene(spec)
    out = Path(out)
    writer = DatasetWriter(out, spec.fps)
    try:
        writer.write_calibration(scene.measured_rig)
        writer.write_gt_calibration(scene.rig)
        if len(scene.novel):
            writer.write_novel_calibration(scene.novel)
        writer.write_scene_toml(spec.text)
        if (lines := field_model(spec.layout)) is not None:  # a broadcast crew knows its pitch
            writer.write_field_model(lines)
        joints2d = {cam.name: cam.project(scene.joints) for cam in scene.rig}
        writer.write_joints3d(scene.joints, SKELETON_14.joint_names)
        writer.write_joints2d(joints2d)
        several = bool(scene.players)  # a [players] table: per-person ground truth too
        if several:
            writer.write_people(scene.people_joints, SKELETON_14.joint_names)
        info = _scene_info(spec, scene)
        atomic_write_text(out / "groundtruth" / "scene_info.json", json.dumps(info, indent=2))

        obs.report("rig", rig=scene.rig, path="world/cams")
        if len(scene.novel):
            obs.report("rig", rig=scene.novel, path="world/novel")
        obs.report("skeleton", skeleton=SKELETON_14)
        obs.report("text", name="scene", text=json.dumps(info))

        env = make_environment(spec.layout, scene.rngs["environment"])
        renderer = make_renderer(spec, env)
        renderer.prepare([*scene.rig, *scene.novel])
        for cam in scene.rig:  # clean plates, as a broadcast crew records the empty pitch
            plate = np.clip(renderer.background_plate(cam) + 0.5, 0, 255).astype(np.uint8)
            writer.write_background(cam.name, plate)
        caster = Raycaster(env)
        frames = range(spec.frames)
        if progress:
            from tqdm import tqdm
            frames = tqdm(frames, desc=f"rendering {out.name}", unit="frame")
        for t in frames:
            bodies = scene.posed_bodies(t)
            meshes = [m for _, m in bodies]
            ids = np.array([0] + [k + 1 for k, _ in bodies], np.uint8)  # caster's body i + 1 -> person id
            renderer.set_bodies([(m, m.shaded_colors(scene.light_dir)) for m in meshes])
            obs.report("joints3d", frame=t, joints=scene.joints[t], name="groundtruth/joints", skeleton=SKELETON_14)
            for p in scene.players[1:]:
                obs.report("joints3d", frame=t, joints=p.joints[t], name=f"groundtruth/people/{p.index}",
                           skeleton=SKELETON_14)
            for rig, novel in ((scene.rig, False), (scene.novel, True)):
                for cam in rig:
                    _render_view(writer, obs, renderer, caster, cam, t, meshes, ids, novel, several,
                                 None if novel else joints2d[cam.name][t])
        if spec.depth_camera is not None:
            dspec = DepthCameraSpec.from_table(spec.depth_camera, spec.source)
            render_depth_camera(out, dspec, scene.body, scene.joints, scene.rngs["depth"], observer=obs, fps=spec.fps)
    except BaseException:
        writer.abort()
        raise
    return writer.close()


def render_depth_dataset(spec, out: str | Path, observer=None) -> DepthCameraOutput:
    """Write only the depth camera of a scene spec (no colour videos).

    The person, motion and random streams are those of :func:`build_scene`, so
    the depth data match the colour dataset :func:`generate_scene` writes for
    the same spec.

    Parameters
    ----------
    spec : SceneSpec
        A parsed scene spec with a ``[depth_camera]`` table.
    out : str or Path
        Dataset folder.
    observer : Observer, optional

    Raises
    ------
    InputError
        If the spec has no ``[depth_camera]`` table.
    """
    if spec.depth_camera is None:
        raise InputError(f"{spec.source}: [depth_camera]", "a [depth_camera] table", "none")
    dspec = DepthCameraSpec.from_table(spec.depth_camera, spec.source)
    scene = build_scene(spec)
    return render_depth_camera(out, dspec, scene.body, scene.joints, scene.rngs["depth"], observer=observer,
                               fps=spec.fps)
