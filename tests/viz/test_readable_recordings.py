"""Recordings that read at a glance and stay small (issue 19, item 6).

A subject walks across a 640 x 360 camera over a textured static background; the
observer gets the camera image before the frame's 3D joints, as the pipeline reports
them.  Checked from the saved file: joint labels off, overlays cropped and placed back
exactly, the camera image stored in full only now and then with the subject's crop on
top (what the viewer shows equals the frame around the subject, and no earlier subject
shows outside the crop), the blueprint's stage tabs and its 3D view framed on the subject.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import rerun as rr

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.cameras import Camera, Rig
from toolkit.skeleton import SKELETON_14
from toolkit.viz import RerunConfig, RerunObserver
from toolkit.viz.blueprint import EYE_DISTANCE_M, STAGE_TABS, SUBJECT_CROP, make_blueprint
from toolkit.viz.rerun_observer import KEYFRAME_INTERVAL

SIZE = (640, 360)
N_FRAMES = 12
#: Subject speed, metres per frame (a run, 2.5 m/s at 25 fps: the crop must follow it).
STEP_M = 0.1
#: JPEG at quality 90 of a textured image: mean absolute error in 8-bit levels.
JPEG_MEAN_ABS_ERR = 4.0
#: Stored size with crops and key frames against every full frame (measured 0.42 on this small scene:
#: the 12-frame file is a third metadata; 0.3 on the default scene).
SIZE_RATIO = 0.5
IMG = "world/cams/cam/image"


def _rig() -> Rig:
    return Rig((Camera.look_at("cam", [0.0, -12.0, 2.0], [0.0, 0.0, 1.0], size=SIZE, fov_x_deg=40),))


def _joints(t: int) -> np.ndarray:
    return BodyProportions.from_height(1.75).rest_pose() + np.array([-1.5 + STEP_M * t, 0.0, 0.0])


def _background() -> np.ndarray:
    rng = np.random.default_rng(3)
    return cv2.GaussianBlur(rng.integers(0, 256, (SIZE[1], SIZE[0], 3), dtype=np.uint8), (0, 0), 2)


def _frame(cam: Camera, t: int, bg: np.ndarray) -> np.ndarray:
    """The background with the subject's box painted in a colour of the frame."""
    img = bg.copy()
    px = cam.project(_joints(t))
    x0, y0 = np.floor(px.min(axis=0)).astype(int)
    x1, y1 = np.ceil(px.max(axis=0)).astype(int)
    img[y0:y1 + 1, x0:x1 + 1] = (200, 40 + 15 * t, 40)
    return img


def _mask(cam: Camera, t: int) -> np.ndarray:
    px = cam.project(_joints(t))
    m = np.zeros(SIZE[::-1], bool)
    x0, y0 = np.floor(px.min(axis=0)).astype(int)
    x1, y1 = np.ceil(px.max(axis=0)).astype(int)
    m[y0:y1 + 1, x0:x1 + 1] = True
    return m


def _record(path, config=None, flush_frames=False):
    rig = _rig()
    bg = _background()
    with RerunObserver(path=path, camera_names=rig.names, config=config) as obs:
        obs.report("rig", rig=rig)
        obs.report("skeleton", skeleton=SKELETON_14)
        for t in range(N_FRAMES):
            obs.report("image", camera="cam", image=_frame(rig[0], t, bg), frame=t)
            obs.report("mask", camera="cam", mask=_mask(rig[0], t), name="silhouettes/silhouette")
            obs.report("joints2d", camera="cam", joints=rig[0].project(_joints(t)), skeleton=SKELETON_14,
                       name="silhouettes/pose")
            obs.report("joints3d", joints=_joints(t), skeleton=SKELETON_14, name="multiview/joints3d")
            obs.report("image", camera="cam", image=_frame(rig[0], t, bg), name="render/articulated")
            if flush_frames:  # as in a pipeline, where a frame takes seconds: one chunk per entity and frame
                obs.flush()
    return rig, bg


def _rows(path) -> dict[str, dict[int | None, dict]]:
    """Entity -> frame (None: static) -> {column: value} (later rows of a frame win)."""
    out: dict = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        rb = chunk.to_record_batch()
        cols = [n for n in rb.schema.names if ":" in n]
        frames = rb.column("frame").to_pylist() if "frame" in rb.schema.names else [None] * rb.num_rows
        for i in range(rb.num_rows):
            row = out.setdefault(chunk.entity_path.strip("/"), {}).setdefault(frames[i], {})
            row.update({n: rb.column(n)[i].as_py() for n in cols if rb.column(n)[i].as_py() is not None})
    return out


def _latest(rows: dict, entity: str, column: str, t: int):
    """The value the viewer shows at frame ``t`` (latest at)."""
    best = None
    for f, d in rows.get(entity, {}).items():
        if column in d and (f is None or f <= t) and (best is None or (f or -1) >= best[0]):
            best = (f if f is not None else -1, d[column])
    return None if best is None else best[1]


def _jpeg(blob) -> np.ndarray:
    return cv2.cvtColor(cv2.imdecode(np.array(blob[0], np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("readable") / "rec.rrd"
    rig, bg = _record(path)
    return path, rig, bg, _rows(path)


def test_joint_labels_are_off(recorded):
    _, _, _, rows = recorded
    assert _latest(rows, f"{IMG}/silhouettes/pose", "Points2D:show_labels", 0) == [False]
    assert _latest(rows, "world/multiview/joints3d", "Points3D:show_labels", 0) == [False]


def test_what_the_viewer_shows_is_each_frame_with_no_ghost(recorded):
    _, rig, bg, rows = recorded
    full_frames = sorted(f for f, d in rows[IMG].items() if f is not None and "EncodedImage:blob" in d)
    assert full_frames[0] == 0 and 1 < len(full_frames) < N_FRAMES / 2  # full images only now and then
    for t in range(N_FRAMES):
        shown = _jpeg(_latest(rows, IMG, "EncodedImage:blob", t)).astype(float)
        if t > 0:  # the subject's crop over the last full image
            x0, y0, _ = _latest(rows, f"{IMG}/{SUBJECT_CROP}", "Transform3D:translation", t)[0]
            crop = _jpeg(_latest(rows, f"{IMG}/{SUBJECT_CROP}", "EncodedImage:blob", t))
            shown[int(y0):int(y0) + crop.shape[0], int(x0):int(x0) + crop.shape[1]] = crop
            assert crop.shape[0] * crop.shape[1] < 0.5 * SIZE[0] * SIZE[1]
        err = np.abs(shown - _frame(rig[0], t, bg)).mean()
        assert err < JPEG_MEAN_ABS_ERR, (t, err)  # the whole picture: no subject of an earlier frame


def test_overlays_are_cropped_and_placed_back_exactly(recorded):
    _, rig, _, rows = recorded
    for t in range(N_FRAMES):
        m = _mask(rig[0], t)
        d = rows[f"{IMG}/silhouettes/silhouette"][t]
        x0, y0, _ = d["Transform3D:translation"][0]
        h, w = d["SegmentationImage:format"][0]["height"], d["SegmentationImage:format"][0]["width"]
        crop = np.array(d["SegmentationImage:buffer"][0], np.uint8).reshape(h, w)
        placed = np.zeros(m.shape, np.uint8)
        placed[int(y0):int(y0) + h, int(x0):int(x0) + w] = crop
        np.testing.assert_array_equal(placed > 0, m)
    # a rendered colour view: cropped around the subject of its frame
    d = rows[f"{IMG}/render/articulated"][5]
    x0, y0, _ = d["Transform3D:translation"][0]
    crop = _jpeg(d["EncodedImage:blob"])
    px = rig[0].project(_joints(5))
    assert x0 <= px[:, 0].min() and x0 + crop.shape[1] >= px[:, 0].max()
    assert y0 <= px[:, 1].min() and y0 + crop.shape[0] >= px[:, 1].max()


def test_crops_and_key_frames_make_the_recording_small(recorded, tmp_path):
    path = recorded[0]
    full = tmp_path / "full.rrd"
    _record(full, RerunConfig(crop_overlays=False))
    assert path.stat().st_size < SIZE_RATIO * full.stat().st_size
    assert N_FRAMES < KEYFRAME_INTERVAL  # (the key frames above came from the subject leaving the crop)


def _blueprint_views(path):
    """Every blueprint row sent: {column: value}."""
    reader = rr.chunk.RrdReader(path)
    out = []
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            rb = chunk.to_record_batch()
            out.append({n: rb.column(n).to_pylist()[-1] for n in rb.schema.names if ":" in n})
    return out


def test_blueprint_groups_stages_in_tabs_and_frames_the_subject(recorded):
    rows = _blueprint_views(recorded[0])
    names = {str(np.ravel(r[k])[0]) for r in rows for k in ("ViewBlueprint:display_name",
                                                              "ContainerBlueprint:display_name") if r.get(k)}
    assert {"overview", STAGE_TABS[0][0], STAGE_TABS[2][0]} <= names
    assert STAGE_TABS[1][0] not in names  # no camera has stage-2 overlays: no empty tab
    eye = [r for r in rows if "EyeControls3D:position" in r]
    assert eye and all(r == eye[0] for r in eye)  # the overview's and stage 1's 3D views, sent once
    pos = np.ravel(eye[0]["EyeControls3D:position"])
    target = np.ravel(eye[0]["EyeControls3D:look_target"])
    np.testing.assert_allclose(target, _joints(0).mean(axis=0), atol=1e-6)  # on the subject
    assert np.linalg.norm((pos - target)[:2]) == pytest.approx(EYE_DISTANCE_M)
    assert pos[1] < target[1]  # from the camera's side


def test_make_blueprint_without_overlays_has_every_stage_tab():
    bp = make_blueprint(["a", "b"])
    assert bp is not None  # stage tabs for every camera (checked through the recording above)


def test_the_saved_file_is_compacted_on_close(recorded, tmp_path):
    path, loose = tmp_path / "compact.rrd", tmp_path / "loose.rrd"
    _record(path, flush_frames=True)
    _record(loose, RerunConfig(compact_on_close=False), flush_frames=True)
    n_chunks = {p: sum(1 for _ in rr.chunk.RrdReader(p).stream()) for p in (path, loose)}
    assert n_chunks[path] < n_chunks[loose] / 2  # each entity's rows merged
    assert path.stat().st_size < loose.stat().st_size
    a, b = _rows(path), _rows(loose)
    a.pop("__properties"), b.pop("__properties")  # start times differ
    assert a == b  # the same data
    assert sorted(p.name for p in tmp_path.iterdir()) == ["compact.rrd", "loose.rrd"]  # no temporary file


NOVEL = "novel00"


def _record_with_novel_camera(path):
    """Like the pipeline's free-viewpoint run: the novel camera's rig first, then the source camera;
    the novel camera has no image of its own, only its rendered view."""
    rig = _rig()
    novel = Rig((Camera.look_at(NOVEL, [8.0, -8.0, 2.0], [0.0, 0.0, 1.0], size=SIZE, fov_x_deg=40),))
    bg = _background()
    with RerunObserver(path=path, camera_names=rig.names + novel.names) as obs:
        obs.report("rig", rig=novel)
        obs.report("skeleton", skeleton=SKELETON_14)
        obs.report("rig", rig=rig)
        for t in range(4):
            obs.report("image", camera="cam", image=_frame(rig[0], t, bg), frame=t)
            obs.report("joints2d", camera="cam", joints=rig[0].project(_joints(t)), skeleton=SKELETON_14,
                       name="silhouettes/pose")
            obs.report("joints3d", joints=_joints(t), skeleton=SKELETON_14, name="multiview/joints3d")
            obs.report("image", camera=NOVEL, image=_frame(novel[0], t, bg), name="render/articulated")
            obs.report("image", camera="cam", image=_frame(rig[0], t, bg), name="render/articulated")


def _included(entity: str, origin: str, rules: list[str]) -> bool:
    """Whether a view's contents (rerun query expressions) take ``entity``: the most specific matching
    rule decides, an exclusion winning a tie."""
    best = None
    for rule in rules:
        sign, pattern = rule.split(" ", 1)
        pattern = pattern.replace("$origin", origin).strip("/")
        if pattern.endswith("/**"):
            base = pattern[:-3]
            hit = entity == base or entity.startswith(base + "/")
        else:
            hit = entity == pattern
        if hit:
            key = (len(pattern), sign == "-")
            if best is None or key > best[0]:
                best = (key, sign == "+")
    return best is not None and best[1]


def test_the_file_opens_on_the_last_layout_and_every_camera_view_shows_its_images(tmp_path):
    """The viewer shows the layout whose activation comes last in the file; ``rerun rrd optimize``
    (the compaction) writes blueprint stores in an order of its own, so the file must hold one: the
    last.  In it, each camera's 2D view takes image entities logged for that camera, the novel
    camera's rendered view included (it has no camera image of its own), and starts on the subject."""
    path = tmp_path / "novel.rrd"
    _record_with_novel_camera(path)
    reader = rr.chunk.RrdReader(path)
    assert len(reader.blueprints()) == 1
    rows: dict = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        rb = chunk.to_record_batch()
        d = rows.setdefault(chunk.entity_path.strip("/"), {})
        d.update({n: rb.column(n).to_pylist()[-1] for n in rb.schema.names if ":" in n})
    names = {str(np.ravel(d[k])[0]) for d in rows.values()
             for k in ("ViewBlueprint:display_name", "ContainerBlueprint:display_name") if d.get(k)}
    assert STAGE_TABS[2][0] in names  # the layout after the rendered views arrived
    assert any("EyeControls3D:position" in d for d in rows.values())  # and after the subject's 3D joints
    images = {e for e, cols in _rows(path).items()
              if any(c.startswith(("EncodedImage:", "Image:")) for d in cols.values() for c in d)}
    views = {e: d for e, d in rows.items() if d.get("ViewBlueprint:class_identifier") == ["2D"]}
    seen = set()
    for view, d in views.items():
        origin = str(np.ravel(d["ViewBlueprint:space_origin"])[0])
        camera = origin.split("/")[2]
        rules = [str(r) for r in np.ravel(rows[f"{view}/ViewContents"]["ViewContents:query"])]
        shown = {e for e in images if _included(e, origin, rules)}
        assert shown and all(e.startswith(origin) for e in shown), (view, origin, rules)
        assert f"{view}/VisualBounds2D" in rows, (view, origin)  # starts zoomed on the subject
        seen.add(camera)
    assert seen == {"cam", NOVEL}
    novel_overview = [d for v, d in views.items() if np.ravel(d["ViewBlueprint:display_name"])[0] == NOVEL]
    assert novel_overview
