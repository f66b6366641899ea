"""Bad input to recipes/joint_centres.py (issue 17): a clear error (exit 2, ``error: ...``, no traceback)
or an explicit per-marker / per-frame state, never a crash or a silent wrong label."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from recipes import joint_centres as recipe
from tests.markers.rom_trial import rom_trial
from toolkit.io.c3d import write_c3d
from toolkit.markers.trajectories import BRIDGED, MISSING

CAPTURE = """
seed = 5
frames = 12
fps = 100
name = "bad_markers"

[subject]
height_m = 1.75
motion = "rom"

[markers]
set = "cluster"
noise_px = 0.3
occlusion = 0.0
ghosts = 0.0
cameras = 4
"""


def _fails(argv, capsys, *words):
    """The recipe exits with 2 and one ``error:`` line naming ``words``; no traceback."""
    assert recipe.main([str(a) for a in argv] + ["--no-recording"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)
    return err


def _raw_c3d(path, labels, points, units="mm"):
    """A C3D written with ezc3d directly (points (4, M, T) in the file's units)."""
    import ezc3d

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    if units is not None:
        c.add_parameter("POINT", "UNITS", [units])
    c["data"]["points"] = points
    c.write(str(path))
    return path


@pytest.fixture(scope="module")
def trial():
    traj, _ = rom_trial("plug-in-gait", n_frames=40, noise_m=0.0005, seed=2)
    return list(traj.labels), traj.positions


def test_missing_corrupt_empty_and_too_short_c3d(tmp_path, capsys, trial):
    labels, pos = trial
    _fails([tmp_path / "absent.c3d", "--out", tmp_path / "o1"], capsys, "absent.c3d", "nothing at that path")
    (tmp_path / "corrupt.c3d").write_bytes(b"not a c3d file" * 20)
    _fails([tmp_path / "corrupt.c3d", "--out", tmp_path / "o2"], capsys, "corrupt.c3d", "readable C3D")
    (tmp_path / "zero.c3d").write_bytes(b"")
    _fails([tmp_path / "zero.c3d", "--out", tmp_path / "o3"], capsys, "zero.c3d", "readable C3D")
    _raw_c3d(tmp_path / "nopoints.c3d", [], np.ones((4, 0, 5)))
    _fails([tmp_path / "nopoints.c3d", "--out", tmp_path / "o4"], capsys, "nopoints.c3d", "at least 2 markers")
    for n in (1, 2):
        path = write_c3d(tmp_path / f"f{n}.c3d", labels, pos[:n], 100.0)
        _fails([path, "--out", tmp_path / f"o5{n}"], capsys, f"f{n}.c3d", "at least 3 frames")


def test_nan_only_markers_are_refused(tmp_path, capsys, trial):
    """Before: exit 0 with a fitted stature of 2.1 m and 'too little movement' out of no data at all."""
    labels, pos = trial
    path = write_c3d(tmp_path / "nan.c3d", labels, np.full_like(pos, np.nan), 100.0)
    _fails([path, "--out", tmp_path / "o"], capsys, "nan.c3d", "markers seen", "0 such frames")
    few = np.full_like(pos, np.nan)
    few[:2] = pos[:2]  # seen in two frames only
    path = write_c3d(tmp_path / "few.c3d", labels, few, 100.0)
    _fails([path, "--out", tmp_path / "o2"], capsys, "few.c3d", "2 such frames of 40")


def test_a_trial_of_a_few_frames(tmp_path, trial):
    """Before: with fewer than 10 frames every segment was 'not moving rigidly' (pairs seen together too
    rarely: five such messages here), and with the marker set's segments given (a capture) the stature
    came out 2.10 m for a 1.75 m performer."""
    labels, pos = trial
    path = write_c3d(tmp_path / "short.c3d", labels, pos[:6], 100.0)
    assert recipe.main([str(path), "--out", str(tmp_path / "o"), "--no-recording"]) == 0
    sk = json.loads((tmp_path / "o" / "skeleton.json").read_text())
    assert abs(sk["height_m"] - 1.75) < 0.1, sk["height_m"]
    assert not any("rigidly" in m for m in sk["messages"]), sk["messages"]


def test_units_other_than_mm_or_m(tmp_path, capsys, trial):
    labels, _ = trial
    for units in ("cm", "in", None):
        path = _raw_c3d(tmp_path / f"{units}.c3d", labels, np.ones((4, len(labels), 5)), units=units)
        _fails([path, "--out", tmp_path / f"o{units}"], capsys, "POINT:UNITS", "'mm' or 'm'")


def test_duplicated_c3d_labels(tmp_path, capsys, trial):
    labels, _ = trial
    dup = list(labels)
    dup[1] = dup[0]
    path = _raw_c3d(tmp_path / "dup.c3d", dup, np.ones((4, len(dup), 5)))
    _fails([path, "--out", tmp_path / "o"], capsys, "POINT:LABELS", "distinct labels", repr(dup[0]))


def test_c3d_without_labels_where_a_marker_set_is_named(tmp_path, capsys, trial):
    """Before: the named marker set was ignored (the flag only for capture folders, the [centres] one
    silently fell back to the path without labels), exit 0."""
    labels, pos = trial
    pts = np.ones((4, len(labels), len(pos)))
    pts[:3] = np.transpose(pos * 1000.0, (2, 1, 0))
    path = _raw_c3d(tmp_path / "anon.c3d", [""] * len(labels), pts)
    _fails([path, "--out", tmp_path / "o1", "--marker-set", "plug-in-gait"], capsys,
           "anon.c3d", "marker set 'plug-in-gait'", "0 of them")
    (tmp_path / "pig.toml").write_text('[centres]\nmarker_set = "plug-in-gait"\n')
    _fails([path, "--out", tmp_path / "o2", "--config", tmp_path / "pig.toml"], capsys, "0 of them")
    # without a named set the same file takes the path without labels, and says so
    assert recipe.main([str(path), "--out", str(tmp_path / "o3"), "--no-recording"]) == 0
    sk = json.loads((tmp_path / "o3" / "skeleton.json").read_text())
    assert not sk["labelled"] and any("no labels" in m for m in sk["messages"])


def test_wrong_marker_set_name(tmp_path, capsys, trial):
    labels, pos = trial
    path = write_c3d(tmp_path / "ok.c3d", labels, pos, 100.0)
    _fails([path, "--out", tmp_path / "o1", "--marker-set", "nosuchset"], capsys, "marker set", "'nosuchset'")
    (tmp_path / "bad.toml").write_text('[centres]\nmarker_set = "nosuchset"\n')
    _fails([path, "--out", tmp_path / "o2", "--config", tmp_path / "bad.toml"], capsys, "'nosuchset'")
    (tmp_path / "cl.toml").write_text('[centres]\nmarker_set = "cluster"\n')
    _fails([path, "--out", tmp_path / "o3", "--config", tmp_path / "cl.toml", "--marker-set", "plug-in-gait"],
           capsys, "--marker-set", "'cluster'")


def test_marker_missing_in_every_frame_is_named(tmp_path, trial):
    """A gap longer than the sequence: before, the missing pelvis markers were reported as 'not moving
    rigidly'; now the message names them as missing, and their state is MISSING in every frame."""
    labels, pos = trial
    gone = [i for i, s in enumerate(labels) if s in ("LKNE", "LASI")]
    q = pos.copy()
    q[:, gone] = np.nan
    path = write_c3d(tmp_path / "gap.c3d", labels, q, 100.0)
    assert recipe.main([str(path), "--out", str(tmp_path / "o"), "--no-recording"]) == 0
    sk = json.loads((tmp_path / "o" / "skeleton.json").read_text())
    assert any("['LASI', 'LKNE'] are missing in every frame" in m for m in sk["messages"]), sk["messages"]
    assert not any("LASI" in m and "rigidly" in m for m in sk["messages"])
    z = np.load(tmp_path / "o" / "trajectories.npz")
    assert np.all(z["state"][:, gone] == MISSING)
    assert sk["joints"]["l_knee"]["method"] != "score"  # no functional knee without its marker


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    from toolkit.synthetic.marker_capture import generate_marker_capture
    from toolkit.synthetic.spec import parse_spec

    out = tmp_path_factory.mktemp("cap") / "base"
    generate_marker_capture(parse_spec(CAPTURE, "bad_markers.toml"), out)
    return out


def _edit_blobs(src, dst, drop):
    """Copy a capture and remove the blobs of the true markers where ``drop(frames, markers)`` (arrays)."""
    from toolkit.io.marker_files import read_detection_truth, read_marker_detections, write_marker_detections

    shutil.copytree(src, dst)
    for p in sorted((dst / "markers" / "detections").glob("*.npz")):
        c, f, size = read_marker_detections(p)
        t = dst / "groundtruth" / "marker_detections" / p.name
        m = read_detection_truth(t)
        keep = ~drop(f, m)
        write_marker_detections(p, c[keep], f[keep], size)
        np.savez(t, marker=m[keep].astype(np.int32))
    return dst


def test_fewer_than_three_cameras(tmp_path, capsys, capture):
    from toolkit.cameras import Rig
    from toolkit.io import read_calibration_metadata, read_calibration_toml
    from toolkit.io.calibration import write_calibration

    d = tmp_path / "two"
    shutil.copytree(capture, d)
    cal = d / "markers" / "calibration.toml"
    write_calibration(cal, Rig(list(read_calibration_toml(cal))[:2]), metadata=read_calibration_metadata(cal))
    _fails([d, "--out", tmp_path / "o"], capsys, "calibration.toml: cameras", "at least 3 cameras", "found 2")
    d = tmp_path / "nodet"
    shutil.copytree(capture, d)
    next((d / "markers" / "detections").glob("*.npz")).unlink()
    _fails([d, "--out", tmp_path / "o2"], capsys, "detections", "no such file")


def test_markers_never_seen_in_the_first_frames(tmp_path, capsys, capture):
    d = _edit_blobs(capture, tmp_path / "late", lambda f, m: f < 6)
    (tmp_path / "c.toml").write_text("[label]\nidentify_within = 4\n")
    _fails([d, "--out", tmp_path / "o", "--config", tmp_path / "c.toml"], capsys,
           "first 4 frames", "of the 49 markers reconstructed", "at most 0")


def test_some_markers_unseen_at_first_are_missing_or_bridged_there(tmp_path, capture):
    d = _edit_blobs(capture, tmp_path / "late3", lambda f, m: (f < 6) & np.isin(m, [0, 1, 2]))
    assert recipe.main([str(d), "--out", str(tmp_path / "o"), "--no-recording"]) == 0
    st = np.load(tmp_path / "o" / "trajectories.npz")["state"]
    # no blob of theirs there: never an observed (trinocular / two-view) label in those frames
    assert np.isin(st[:6, :3], [MISSING, BRIDGED]).all(), st[:6, :3]


def _labelling(capture, idx, frame=0):
    from toolkit.io.marker_files import read_marker_truth

    truth = read_marker_truth(capture / "groundtruth" / "markers3d.npz")
    return truth["labels"], {truth["labels"][i]: truth["positions"][frame, i].tolist() for i in idx}


def test_marker_never_seen_and_a_labelling_file_naming_it(tmp_path, capture):
    d = _edit_blobs(capture, tmp_path / "never", lambda f, m: m == 5)
    labels, given = _labelling(capture, range(12))
    (tmp_path / "lab.json").write_text(json.dumps({"frame": 0, "markers": given}))
    for name, extra in (("auto", []), ("file", ["--labelling", str(tmp_path / "lab.json")])):
        assert recipe.main([str(d), "--out", str(tmp_path / name), "--no-recording", *extra]) == 0
        z = np.load(tmp_path / name / "trajectories.npz")
        i = list(z["labels"]).index(labels[5])
        assert np.all(z["state"][:, i] == MISSING), z["state"][:, i]  # a gap as long as the sequence
        assert np.isnan(z["positions"][:, i]).all()


def test_labelling_file_with_a_duplicated_csv_label(tmp_path, capsys, capture):
    labels, given = _labelling(capture, [0, 1, 2])
    rows = ["label,x,y,z"] + [f"{k},{','.join(map(str, given[k]))}" for k in [*given, labels[1]]]
    (tmp_path / "dup.csv").write_text("\n".join(rows) + "\n")
    _fails([capture, "--out", tmp_path / "o", "--labelling", tmp_path / "dup.csv"], capsys,
           "dup.csv", repr(labels[1]), "each label once")
    _fails([capture, "--out", tmp_path / "o2", "--labelling", tmp_path / "absent.json"], capsys, "absent.json")
    _fails([capture, "--out", tmp_path / "o3", "--marker-set", "nosuchset"], capsys, "'nosuchset'")


def test_labelling_file_with_a_duplicated_json_label(tmp_path, capsys, capture):
    """Before: json.loads kept the last of the duplicated keys silently; the run then failed on the
    wrong position ('7 of the 49 markers identified'), not naming the duplicate."""
    labels, given = _labelling(capture, range(8))
    text = json.dumps({"frame": 0, "markers": given})
    text = text.replace("}}", f', "{labels[1]}": {json.dumps(given[labels[3]])}' + "}}")
    (tmp_path / "dup.json").write_text(text)
    _fails([capture, "--out", tmp_path / "o", "--labelling", tmp_path / "dup.json"], capsys,
           "dup.json", repr(labels[1]), "each label once")
