"""No output replaced by a worse one, no run silently wrong: the recipes on bad input and interruptions."""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

from tests.recipes.test_pose_from_keypoints import make_scene as keypoint_scene
from toolkit.cameras import Rig
from toolkit.errors import InputError
from toolkit.io import write_calibration
from toolkit.io.dataset import Dataset
from toolkit.pipeline.run import FrameRecords, open_run

ROOT = Path(__file__).resolve().parents[2]


def recipe(name):
    return importlib.import_module(f"recipes.{name}").main


# ------------------------------------------------------------ make_scene
def tiny_spec(tmp_path, frames: int) -> Path:
    spec = tmp_path / f"s{frames}.toml"
    spec.write_text((ROOT / "datasets_synthetic" / "tiny.toml").read_text().replace("frames = 4", f"frames = {frames}")
                    .replace("[novel]\ncount = 1", "[novel]\ncount = 0"))
    return spec


def test_make_scene_never_overwrites_a_dataset_unasked(tmp_path, capsys, monkeypatch):
    """make_scene wrote over an existing dataset without a word, leaving a mix with more frames."""
    make_scene = recipe("make_scene")
    out = tmp_path / "ds"
    assert make_scene([str(tiny_spec(tmp_path, 1)), "--out", str(out), "--quiet", "--no-recording"]) == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert make_scene([str(tiny_spec(tmp_path, 2)), "--out", str(out), "--quiet", "--no-recording"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    import toolkit.synthetic as synthetic

    real = synthetic.generate_scene

    def dies(spec, stage, **kw):  # a full disk half-way through the new dataset
        (Path(stage) / "calibration.toml").write_text("half")
        raise InputError(str(stage), "space on the disk", "none left")

    monkeypatch.setattr(synthetic, "generate_scene", dies)
    assert make_scene([str(tiny_spec(tmp_path, 2)), "--out", str(out), "--quiet", "--no-recording",
                       "--overwrite"]) == 2
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before                                              # untouched
    monkeypatch.setattr(synthetic, "generate_scene", real)
    assert make_scene([str(tiny_spec(tmp_path, 2)), "--out", str(out), "--quiet", "--no-recording",
                       "--overwrite"]) == 0
    with Dataset.open(out) as ds:
        assert ds.n_frames == 2 and ds.gt_joints3d().shape == (2, 14, 3)
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_dir()) == ["ds"]   # no staging folder left


def test_make_scene_out_that_is_a_file(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert recipe("make_scene")([str(tiny_spec(tmp_path, 1)), "--out", str(f), "--quiet", "--no-recording"]) == 2
    err = capsys.readouterr().err
    assert "a file" in err and "Traceback" not in err


# ------------------------------------------------------------ pose_from_keypoints
def kp_args(root, kp, out, *extra):
    return [str(a) for a in ("--calibration", root / "calib.toml", "--keypoints", kp, "--out", out, "--quiet",
                             "--no-recording", "--export", "none", *extra)]


def test_keypoint_run_of_other_options_is_refused(tmp_path, capsys):
    """pose_from_keypoints rewrote a folder made with other options without a word."""
    rig, _, kp = keypoint_scene(tmp_path, n_frames=3)
    out, run = tmp_path / "o", recipe("pose_from_keypoints")
    assert run(kp_args(tmp_path, kp, out)) == 0
    first = np.load(out / "poses3d.npz")["joints"]
    assert run(kp_args(tmp_path, kp, out)) == 0                      # the same run again: replaced, same result
    np.testing.assert_array_equal(np.load(out / "poses3d.npz")["joints"], first)
    capsys.readouterr()
    assert run(kp_args(tmp_path, kp, out, "--offsets", "none")) == 2
    assert "config.offsets" in capsys.readouterr().err
    np.testing.assert_array_equal(np.load(out / "poses3d.npz")["joints"], first)
    assert run(kp_args(tmp_path, kp, out, "--offsets", "none", "--replace-stale")) == 0
    np.testing.assert_array_equal(np.load(tmp_path / "o.stale-1" / "poses3d.npz")["joints"], first)
    # other keypoints in the same folder: another input
    f = next((kp / "cam01_json").iterdir())
    f.write_text(f.read_text().replace("0.9", "0.8"))
    assert run(kp_args(tmp_path, kp, out, "--offsets", "none")) == 2
    assert "inputs.keypoints" in capsys.readouterr().err
    write_calibration(tmp_path / "calib.toml", Rig(tuple(c.replace(K=c.K * [[1.01], [1.01], [1]]) for c in rig)))
    assert run(kp_args(tmp_path, kp, out, "--offsets", "none")) == 2     # another calibration: another input
    assert "inputs.files" in capsys.readouterr().err


@pytest.mark.parametrize("error", [AttributeError, KeyboardInterrupt])
def test_failed_rerun_keeps_the_complete_results(tmp_path, monkeypatch, error):
    """An AttributeError in a rerun made the finally block overwrite a complete poses3d.npz with NaNs."""
    _, poses, kp = keypoint_scene(tmp_path, n_frames=3)
    out, run = tmp_path / "o", recipe("pose_from_keypoints")
    assert run(kp_args(tmp_path, kp, out)) == 0
    before = {f: (out / f).read_bytes() for f in ("poses3d.npz", "poses3d.json", "offsets.npz", "poses2d.npz")}
    import toolkit.pipeline.pose_from_keypoints as pfk

    def broken(*a, **k):
        raise error("broken")

    monkeypatch.setattr(pfk, "_triangulate", broken)
    if error is KeyboardInterrupt:
        assert run(kp_args(tmp_path, kp, out)) == 130
    else:
        with pytest.raises(AttributeError):
            run(kp_args(tmp_path, kp, out))
    assert {f: (out / f).read_bytes() for f in before} == before
    assert np.isfinite(np.load(out / "poses3d.npz")["joints"][:2]).all()


def test_inverse_pose_convention_is_refused(tmp_path, capsys):
    """A calibration written as world_from_cam gave joints 3.4 m off reported as success."""
    rig, _, kp = keypoint_scene(tmp_path, n_frames=3)
    write_calibration(tmp_path / "calib.toml", Rig(tuple(c.replace(cam_from_world=c.world_from_cam) for c in rig)))
    assert recipe("pose_from_keypoints")(kp_args(tmp_path, kp, tmp_path / "o")) == 2
    err = capsys.readouterr().err
    assert "calib.toml" in err and "behind" in err


def test_swapped_keypoint_folders_are_said(tmp_path, capsys):
    """Keypoint folders swapped between two cameras ran to 'complete' with joints 20 cm off and no warning."""
    _, _, kp = keypoint_scene(tmp_path, n_frames=3)
    (kp / "cam01_json").rename(kp / "tmp")
    (kp / "cam02_json").rename(kp / "cam01_json")
    (kp / "tmp").rename(kp / "cam02_json")
    assert recipe("pose_from_keypoints")(kp_args(tmp_path, kp, tmp_path / "o")) == 0
    assert "warning: median ray distance" in capsys.readouterr().out


def test_unrelated_folder_names_and_shifted_frames_are_said(tmp_path, capsys):
    _, _, kp = keypoint_scene(tmp_path, n_frames=3)
    for i, name in enumerate(("left", "middle", "right")):
        (kp / f"cam{i + 1:02d}_json").rename(kp / name)
    for f in sorted((kp / "right").iterdir(), reverse=True):
        t = int(f.stem.split(".")[1])
        f.rename(f.with_name(f"right.{t + 1:04d}.json"))
    assert recipe("pose_from_keypoints")(kp_args(tmp_path, kp, tmp_path / "o")) == 0
    out = capsys.readouterr().out
    assert "paired in sorted order" in out
    assert "start at different values (cam_01 0, cam_02 0, cam_03 1)" in out


# ------------------------------------------------------------ frame-record runs
def test_smaller_frame_limit_does_not_rewrite_the_run(tmp_path):
    """A smaller --max-frames rerun resumed the folder and rewrote its aggregates for the subset."""
    ds = tmp_path / "ds"
    ds.mkdir()
    (ds / "calibration.toml").write_text("x")
    from toolkit.pipeline.depth_tracking import DepthTrackingRunConfig

    config = DepthTrackingRunConfig()
    folder = open_run(tmp_path / "o", "test", ds, config, 3, recording=False, log=None)
    for t in range(3):
        folder.records.write(t, {"t": t})
    with pytest.raises(InputError, match="3 frames"):
        open_run(tmp_path / "o", "test", ds, config, 2, recording=False, log=None)
    assert open_run(tmp_path / "o", "test", ds, config, 3, recording=False, log=None).resumed
    assert open_run(tmp_path / "o", "test", ds, config, 5, recording=False, log=None).records.todo() == [3, 4]
    assert len(FrameRecords(tmp_path / "o", 5).read_all()) == 3
    (ds / "background").mkdir()
    (ds / "background" / "cam.png").write_bytes(b"plate")
    with pytest.raises(InputError, match="dataset"):                     # a changed dataset: another run
        open_run(tmp_path / "o", "test", ds, config, 5, recording=False, log=None)


# ------------------------------------------------------------ depth tracking
def raw_frames(folder: Path, n: int) -> Path:
    folder.mkdir()
    for i in range(n):
        np.full((48, 64), 2000, "<u2").tofile(folder / f"depth-{i}")
    return folder


def ctrl_c_at_frame(monkeypatch, frame: int):
    """From now on reading depth frame ``frame`` raises KeyboardInterrupt (Ctrl-C); returns the real reader."""
    from toolkit.io.depth_readers import DepthInput

    real = DepthInput.read

    def read(self, i):
        if i == frame:
            raise KeyboardInterrupt
        return real(self, i)

    monkeypatch.setattr(DepthInput, "read", read)
    return real


def depth_args(frames, out, *extra):
    return [str(frames), "--out", str(out), "--size", "64", "48", "--quiet", "--no-recording", *extra]


def test_depth_ctrl_c_keeps_the_frames_tracked(tmp_path, monkeypatch, capsys):
    """depth_tracking lost every result on Ctrl-C."""
    from toolkit.io.depth_readers import DepthInput

    frames, out = raw_frames(tmp_path / "frames", 5), tmp_path / "out"
    real = ctrl_c_at_frame(monkeypatch, 3)
    assert recipe("depth_tracking")(depth_args(frames, out)) == 130
    z = np.load(out / "skeleton.npz")
    assert len(z["frames"]) == 3 and str(z["status"]) == "interrupted"
    assert "interrupted: 3 of 5 frames" in capsys.readouterr().out
    # the complete run, then an interrupted rerun: the complete results stay
    monkeypatch.setattr(DepthInput, "read", real)
    assert recipe("depth_tracking")(depth_args(frames, out)) == 0
    complete = (out / "skeleton.npz").read_bytes()
    ctrl_c_at_frame(monkeypatch, 3)
    assert recipe("depth_tracking")(depth_args(frames, out)) == 130
    assert (out / "skeleton.npz").read_bytes() == complete


def test_depth_unreadable_frame_does_not_end_the_run(tmp_path, capsys):
    """One unreadable frame lost every result of depth_tracking."""
    frames = raw_frames(tmp_path / "frames", 4)
    (frames / "depth-2").write_bytes(b"\x00" * 100)                     # truncated
    out = tmp_path / "out"
    assert recipe("depth_tracking")(depth_args(frames, out)) == 0
    z = np.load(out / "skeleton.npz")
    assert len(z["frames"]) == 4 and z["unreadable"].tolist() == [False, False, True, False]
    assert "unreadable frames tracked as frames without depth: depth-2" in capsys.readouterr().out
    for f in frames.iterdir():
        f.write_bytes(b"\x00")
    assert recipe("depth_tracking")(depth_args(frames, tmp_path / "out2")) == 2
    assert "at least one readable depth frame" in capsys.readouterr().err


# ------------------------------------------------------------ SIGTERM
def _terminate_at_two(t, observer=None):
    import os
    import signal

    if t == 2:
        os.kill(os.getpid(), signal.SIGTERM)
    _terminate_at_two.done.append(t)


_terminate_at_two.done = []


def test_sigterm_stops_a_frame_loop_like_ctrl_c():
    """SIGTERM ended a run without its finally blocks: its last results and recording unwritten."""
    import signal

    from toolkit.pipeline.run import STOPPED_INTERRUPTED, run_frames

    before = signal.getsignal(signal.SIGTERM)
    _terminate_at_two.done.clear()
    processed, stopped, _ = run_frames(_terminate_at_two, ((t,) for t in range(5)), total=5, progress=False)
    assert stopped == STOPPED_INTERRUPTED and processed == 2 and _terminate_at_two.done == [0, 1]
    assert signal.getsignal(signal.SIGTERM) is before                  # the handler is put back


def test_sigterm_keeps_the_depth_frames_tracked(tmp_path, monkeypatch):
    import os
    import signal

    from toolkit.io.depth_readers import DepthInput

    frames, out = raw_frames(tmp_path / "frames", 4), tmp_path / "out"
    real = DepthInput.read

    def read(self, i):
        if i == 2:
            os.kill(os.getpid(), signal.SIGTERM)
        return real(self, i)

    monkeypatch.setattr(DepthInput, "read", read)
    assert recipe("depth_tracking")(depth_args(frames, out)) == 130
    assert len(np.load(out / "skeleton.npz")["frames"]) == 2


def test_make_scene_too_large_to_render_is_refused_first(tmp_path, capsys, monkeypatch):
    """An 8192 x 8192 scene with supersampling 4 started without a memory estimate."""
    from toolkit.synthetic import load_spec
    from toolkit.synthetic import memory
    from toolkit.synthetic.memory import check_render_memory

    spec = tmp_path / "huge.toml"
    spec.write_text(tiny_spec(tmp_path, 1).read_text().replace("resolution = [320, 180]", "resolution = [8192, 8192]")
                    + "\n[render]\nsupersample = 4\n")
    with pytest.raises(InputError, match="supersample 4: about 120") as e:   # 2**30 rays x 120 bytes
        check_render_memory(load_spec(spec), available=64 << 30)
    assert "huge.toml" in str(e.value)
    assert check_render_memory(load_spec(tiny_spec(tmp_path, 1)), available=8 << 30) < 1 << 30
    monkeypatch.setattr(memory, "available_memory", lambda: 64 << 30)
    assert recipe("make_scene")([str(spec), "--out", str(tmp_path / "o"), "--quiet", "--no-recording"]) == 2
    assert "GiB" in capsys.readouterr().err and not (tmp_path / "o").exists()
