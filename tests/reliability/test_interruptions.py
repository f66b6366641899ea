"""Interruptions of every system's run: Ctrl-C, SIGTERM, a full disk and a run killed outright.

Each leaves the finished frames or results on disk, recordings that ``rerun rrd verify`` accepts (and
no other recording offered as openable), and a rerun that resumes or recomputes to the result of an
uninterrupted run (:func:`toolkit.pipeline.run.compare_runs`).  The soft-body and marker runs are
computed as a whole (:func:`toolkit.pipeline.run.whole_run`); the depth and free-viewpoint runs frame
by frame.  A signal is sent from inside the run (a patched step), in this process where the run
catches it, in a child process where it could end the process.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tests.recipes.test_pose_from_silhouettes import small_db_path, tiny_dataset  # noqa: F401  (fixtures)
from toolkit.pipeline.run import STOPPED_INTERRUPTED, compare_runs, whole_run

ROOT = Path(__file__).resolve().parents[2]
RERUN = Path(sys.executable).with_name("rerun")


def verify(*files) -> None:
    """``rerun rrd verify`` accepts every file (and there is at least one)."""
    assert files, "no recording to verify"
    p = subprocess.run([str(RERUN), "rrd", "verify", *map(str, files)], capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr


def snapshot(folder: Path) -> dict:
    """Every file of a folder (hidden ones included) and its bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def in_child(recipe: str, target: str, sig: str, args: list) -> subprocess.CompletedProcess:
    """Run ``recipes/<recipe>.py ARGS`` in a child process that sends itself ``sig`` when ``target``
    (``module:function``) is first called."""
    module, name = target.split(":")
    code = textwrap.dedent(f"""
        import importlib, os, signal, sys
        sys.path.insert(0, {str(ROOT)!r})
        mod = importlib.import_module({module!r})
        real = getattr(mod, {name!r})
        def stop(*a, **k):
            os.kill(os.getpid(), signal.{sig})
            return real(*a, **k)
        setattr(mod, {name!r}, stop)
        from recipes import {recipe}
        sys.exit({recipe}.main({[str(a) for a in args]!r}))
    """)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=600)


def full_disk_at(monkeypatch, name: str) -> None:
    """From now on an atomic write of a file called ``name`` meets a full disk (ENOSPC when it is synced)."""
    from toolkit.io import atomic

    real = os.fsync

    def fsync(fd):
        if f".{Path(name).stem}.tmp-" in os.readlink(f"/proc/self/fd/{fd}"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd)

    monkeypatch.setattr(atomic.os, "fsync", fsync)


def interrupt(monkeypatch, module, name: str) -> None:
    """``module.name`` raises KeyboardInterrupt (Ctrl-C) when called."""
    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(module, name, stop)


def check_ctrl_c_then_rerun(main, args, module, name: str, out: Path, result: str, ref: Path, monkeypatch, capsys):
    """A whole run stopped by Ctrl-C in ``module.name`` writes no ``result`` and a recording that opens; the
    rerun gives the reference result; an interrupted rerun after it keeps results and recording as they were."""
    real = getattr(module, name)
    interrupt(monkeypatch, module, name)
    assert main(args) == 130                                         # a first run stopped: nothing written
    assert "interrupted" in capsys.readouterr().out and not (out / result).exists()
    verify(out / "recording.rrd")                                    # what it recorded so far opens
    monkeypatch.setattr(module, name, real)
    assert main(args) == 0                                           # recomputed: the uninterrupted result
    assert compare_runs(ref, out) == []
    complete = snapshot(out)
    interrupt(monkeypatch, module, name)
    capsys.readouterr()
    assert main(args) == 130
    assert "earlier complete results (and recording) are kept" in capsys.readouterr().out
    assert snapshot(out) == complete                                 # results and recording as they were
    verify(out / "recording.rrd")


# ------------------------------------------------------------ the library's mechanism
def test_a_stop_while_results_are_written_waits_for_them(tmp_path):
    """Ctrl-C or SIGTERM while a whole run writes its results lets every file be written first."""
    before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    for sig in (signal.SIGINT, signal.SIGTERM):
        after = []
        with whole_run(tmp_path, own=False, earlier=False) as state:
            with state.writing():
                os.kill(os.getpid(), sig)
                (tmp_path / "results").write_text("all")   # still written
            after.append("not reached")
        assert state.stopped == STOPPED_INTERRUPTED and state.written and not after
        assert (tmp_path / "results").read_text() == "all"
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)) == before


def test_a_dropped_recording_leaves_the_earlier_file(tmp_path):
    """A recording written in parts and dropped leaves the file it would have replaced as it was."""
    from toolkit.viz import RerunObserver

    path = tmp_path / "recording.rrd"
    with RerunObserver(path=path, parts=True) as first:
        first.report("scalar", name="x", value=1.0, frame=0)
    assert first.saved == path
    before = path.read_bytes()
    second = RerunObserver(path=path, parts=True)
    second.report("scalar", name="x", value=2.0, frame=0)
    second.checkpoint()
    second.close(keep=False)
    assert second.saved is None and path.read_bytes() == before and sorted(tmp_path.iterdir()) == [path]
    verify(path)


# ------------------------------------------------------------ soft body
SOFT_FRAMES = ["--frames", "2", "--quiet"]


@pytest.fixture(scope="module")
def soft(tmp_path_factory):
    """A tiny depth dataset and an uninterrupted soft-body run of its first two frames (the reference)."""
    from recipes import fit_soft_body
    from tests.pipeline.test_soft_body import SPEC
    from toolkit.synthetic.generator import render_depth_dataset
    from toolkit.synthetic.spec import parse_spec

    root = tmp_path_factory.mktemp("soft")
    render_depth_dataset(parse_spec(SPEC, "soft"), root / "ds")
    assert fit_soft_body.main([str(root / "ds"), "--out", str(root / "ref"), *SOFT_FRAMES]) == 0
    return root / "ds", root / "ref"


def test_soft_body_ctrl_c_keeps_the_complete_results(soft, tmp_path, monkeypatch, capsys):
    """Ctrl-C ended the soft-body recipe with a traceback; a rerun stopped so replaced a complete run's recording."""
    import toolkit.pipeline.soft_body as sb
    from recipes import fit_soft_body

    ds, ref = soft
    out, args = tmp_path / "o", [str(ds), "--out", str(tmp_path / "o"), *SOFT_FRAMES]
    check_ctrl_c_then_rerun(fit_soft_body.main, args, sb, "fit_clouds", out, "joints.npz", ref, monkeypatch, capsys)


def test_soft_body_sigterm_and_kill_leave_valid_recordings(soft, tmp_path):
    """SIGTERM and SIGKILL left the soft-body recording without its footer (rerun rrd verify failed)."""
    from recipes import fit_soft_body

    ds, ref = soft
    out = tmp_path / "o"
    args = [ds, "--out", out, *SOFT_FRAMES]
    p = in_child("fit_soft_body", "toolkit.pipeline.soft_body:fit_clouds", "SIGTERM", args)
    assert p.returncode == 130, p.stderr[-2000:]
    assert "interrupted" in p.stdout and "Traceback" not in p.stderr
    verify(out / "recording.rrd")
    p = in_child("fit_soft_body", "toolkit.pipeline.soft_body:fit_clouds", "SIGKILL", args)
    assert p.returncode == -signal.SIGKILL
    verify(*sorted((out / "recording.parts").glob("*.rrd")))         # the finished part (the clouds)
    assert fit_soft_body.main([str(a) for a in args]) == 0
    assert compare_runs(ref, out) == []
    assert sorted(p.name for p in out.glob("recording*")) == ["recording.rrd"]   # no part, no stale file
    verify(out / "recording.rrd")


def test_soft_body_full_disk_keeps_the_earlier_results(soft, tmp_path, monkeypatch, capsys):
    """A full disk during a soft-body rerun's writes left its recording in place of the complete run's."""
    from recipes import fit_soft_body

    ds, ref = soft
    out = tmp_path / "o"
    shutil.copytree(ref, out)
    before = snapshot(out)
    full_disk_at(monkeypatch, "joints.npz")
    assert fit_soft_body.main([str(ds), "--out", str(out), *SOFT_FRAMES]) == 2
    err = capsys.readouterr().err
    assert "joints.npz" in err and "No space left" in err and "Traceback" not in err
    assert snapshot(out) == before


def test_soft_body_mesh_on_a_full_disk(tmp_path, monkeypatch):
    """A mesh Open3D could not write (a full disk) was an OSError traceback naming a temporary file."""
    import open3d as o3d

    import toolkit.pipeline.soft_body as sb
    from toolkit.errors import InputError

    path = tmp_path / "meshes" / "000000.ply"
    vertices, triangles = np.eye(3), np.array([[0, 1, 2]])
    sb._write_ply(path, vertices, triangles)
    before = path.read_bytes()
    monkeypatch.setattr(o3d.io, "write_triangle_mesh", lambda *a, **k: False)
    with pytest.raises(InputError, match="PLY writer failed") as e:
        sb._write_ply(path, vertices, triangles)
    assert e.value.where == str(path) and path.read_bytes() == before
    assert [p.name for p in path.parent.iterdir()] == ["000000.ply"]


# ------------------------------------------------------------ marker joint centres
@pytest.fixture(scope="module")
def markers(tmp_path_factory):
    """A tiny marker capture and an uninterrupted joint-centres run of it (the reference)."""
    from recipes import joint_centres
    from tests.markers.test_joint_centres_recipe import TINY
    from toolkit.synthetic.marker_capture import generate_marker_capture
    from toolkit.synthetic.spec import parse_spec

    root = tmp_path_factory.mktemp("markers")
    generate_marker_capture(parse_spec(TINY, "tiny.toml"), root / "cap")
    assert joint_centres.main([str(root / "cap"), "--out", str(root / "ref")]) == 0
    return root / "cap", root / "ref"


def test_joint_centres_ctrl_c_keeps_the_complete_results(markers, tmp_path, monkeypatch, capsys):
    """Ctrl-C ended the marker recipe with a traceback; a rerun stopped so replaced a complete run's recording."""
    import toolkit.markers.functional as functional
    from recipes import joint_centres

    cap, ref = markers
    out, args = tmp_path / "o", [str(cap), "--out", str(tmp_path / "o")]
    check_ctrl_c_then_rerun(joint_centres.main, args, functional, "joint_centres", out, "joint_centres.npz", ref,
                            monkeypatch, capsys)


def test_joint_centres_sigterm_kill_and_full_disk(markers, tmp_path, monkeypatch, capsys):
    """SIGTERM and SIGKILL left the marker recording without its footer; a full disk replaced the recording."""
    from recipes import joint_centres

    cap, ref = markers
    out = tmp_path / "o"
    args = [cap, "--out", out]
    p = in_child("joint_centres", "toolkit.markers.functional:joint_centres", "SIGTERM", args)
    assert p.returncode == 130 and "Traceback" not in p.stderr, p.stderr[-2000:]
    verify(out / "recording.rrd")
    p = in_child("joint_centres", "toolkit.markers.functional:joint_centres", "SIGKILL", args)
    assert p.returncode == -signal.SIGKILL
    verify(*sorted((out / "recording.parts").glob("*.rrd")))         # the finished part (the labelling)
    assert joint_centres.main([str(a) for a in args]) == 0
    assert compare_runs(ref, out) == []
    assert sorted(p.name for p in out.glob("recording*")) == ["recording.rrd"]
    verify(out / "recording.rrd")
    recording = (out / "recording.rrd").read_bytes()
    full_disk_at(monkeypatch, "skeleton.json")
    capsys.readouterr()
    assert joint_centres.main([str(a) for a in args]) == 2
    err = capsys.readouterr().err
    assert "skeleton.json" in err and "No space left" in err
    assert (out / "recording.rrd").read_bytes() == recording and compare_runs(ref, out) == []
    assert not [p.name for p in out.iterdir() if p.name.startswith(".") or p.suffix == ".parts"]


# ------------------------------------------------------------ keypoints
def test_keypoints_sigterm_kill_and_an_interrupted_rerun(tmp_path, monkeypatch, capsys):
    """SIGTERM and SIGKILL left the keypoint run's recording without its footer; an interrupted rerun kept a
    complete run's poses3d.npz but wrote its recording over the complete one."""
    import toolkit.pipeline.pose_from_keypoints as pfk
    from recipes import pose_from_keypoints
    from tests.recipes.test_pose_from_keypoints import make_scene

    _, _, kp = make_scene(tmp_path, n_frames=3)
    out = tmp_path / "o"
    args = ["--calibration", tmp_path / "calib.toml", "--keypoints", kp, "--out", out, "--quiet", "--export", "none"]
    p = in_child("pose_from_keypoints", "toolkit.pipeline.pose_from_keypoints:_triangulate", "SIGTERM", args)
    assert p.returncode == 130 and "Traceback" not in p.stderr, p.stderr[-2000:]
    verify(out / "recording.rrd")
    p = in_child("pose_from_keypoints", "toolkit.pipeline.pose_from_keypoints:_triangulate", "SIGKILL", args)
    assert p.returncode == -signal.SIGKILL
    assert pose_from_keypoints.main([str(a) for a in args]) == 0
    assert sorted(p.name for p in out.glob("recording*")) == ["recording.rrd"]
    verify(out / "recording.rrd")
    complete = snapshot(out)
    interrupt(monkeypatch, pfk, "_triangulate")
    assert pose_from_keypoints.main([str(a) for a in args]) == 130
    assert snapshot(out) == complete


# ------------------------------------------------------------ depth tracking
def test_depth_interrupted_rerun_keeps_the_complete_recording(tmp_path, monkeypatch, capsys):
    """An interrupted depth rerun kept the complete skeleton.npz but replaced its recording by a partial one."""
    from recipes import depth_tracking
    from tests.reliability.test_no_output_lost import ctrl_c_at_frame, raw_frames

    frames, out = raw_frames(tmp_path / "frames", 5), tmp_path / "out"
    args = [str(frames), "--out", str(out), "--size", "64", "48", "--quiet"]
    assert depth_tracking.main(args) == 0
    verify(*advertised(capsys.readouterr().out))
    complete = snapshot(out)
    ctrl_c_at_frame(monkeypatch, 3)
    assert depth_tracking.main(args) == 130
    shown = advertised(capsys.readouterr().out)
    assert shown == [out / "recording.rrd"] and snapshot(out) == complete
    verify(*shown)


# ------------------------------------------------------------ free viewpoint
def advertised(text: str) -> list:
    """The recordings a run's summary offers (``rerun FILE`` or ``rerun PATTERN``), each pattern expanded."""
    files = []
    for token in re.findall(r"rerun (\S+\.rrd)", text):
        p = Path(token)
        files += sorted(p.parent.glob(p.name)) if "*" in p.name else [p]
    return files


def fv_config():
    """The whole free-viewpoint chain less the baselines, in this process (a patched step stays patched)."""
    from toolkit.pipeline.free_viewpoint import FreeViewpointRunConfig
    from toolkit.rendering.freeviewpoint import FreeViewpointConfig

    return FreeViewpointRunConfig(frame=FreeViewpointConfig(baselines=False), progress=False, workers=1)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    from toolkit.synthetic import generate_scene, parse_spec

    root = tmp_path_factory.mktemp("fv")
    spec = ROOT / "datasets_synthetic" / "tiny.toml"
    generate_scene(parse_spec(spec.read_text(), str(spec)), root / "tiny", progress=False).close()
    return root / "tiny"


def test_free_viewpoint_resumed_recordings_all_verify(tiny, tmp_path, monkeypatch):
    """After an interrupted, then resumed run, every recording the summary offers opens; a part of the
    recording that was not finalised (its merge failed) is not offered as openable."""
    import toolkit.pipeline.free_viewpoint as fv
    import toolkit.viz.rerun_observer as ro

    out = tmp_path / "o"
    real_frame, real_finish = fv._Frames.__call__, ro.finish_parts

    def stop_at(k):
        def call(self, est, *a, **kw):
            if est.frame == k:
                raise KeyboardInterrupt
            return real_frame(self, est, *a, **kw)
        monkeypatch.setattr(fv._Frames, "__call__", call)

    def once(**kw):
        r = fv.run(fv_config(), dataset=tiny, out=out, log=None, **kw)
        files = advertised("\n".join(fv.summary_lines(r)))
        assert r.recording is None or r.recording in files
        for f in files:
            assert f.is_file(), f"{f} offered as openable"
        verify(*files)
        return r

    stop_at(1)
    r = once()
    assert r.stopped == STOPPED_INTERRUPTED and r.finished == 1 and r.recording == out / "recording.rrd"
    stop_at(2)
    monkeypatch.setattr(ro, "finish_parts", lambda parts, path=None: False)   # e.g. no rerun CLI
    r = once()
    assert r.stopped and r.finished == 2 and r.recording is None          # its parts were not merged
    parts = sorted((out / "recording.resume-1.parts").glob("*.rrd"))
    verify(*parts)                                                        # each part complete all the same
    monkeypatch.setattr(ro, "finish_parts", real_finish)
    monkeypatch.setattr(fv._Frames, "__call__", real_frame)
    r = once()
    assert r.complete and r.processed == 2 and not list(out.glob("*.parts"))
    assert {p.name for p in out.glob("recording*.rrd")} == {"recording.rrd", "recording.resume-1.rrd",
                                                            "recording.resume-2.rrd"}
    assert np.isfinite(np.load(out / "poses3d.npz")["joints"]).all()


def test_free_viewpoint_recipe_stopped_exits_130_and_resumes(tiny, tmp_path, monkeypatch, capsys):
    """The recipe stopped by Ctrl-C exits 130 like every recipe (not 1, which reads as a failure) and
    the same command finishes the run."""
    import toolkit.pipeline.free_viewpoint as fv
    from recipes import free_viewpoint as recipe

    real_frame = fv._Frames.__call__

    def call(self, est, *a, **kw):
        if est.frame == 1:
            raise KeyboardInterrupt
        return real_frame(self, est, *a, **kw)

    args = [str(tiny), "--out", str(tmp_path / "o"), "--max-frames", "2", "--no-recording", "--no-baselines",
            "--workers", "1", "--quiet"]
    monkeypatch.setattr(fv._Frames, "__call__", call)
    assert recipe.main(args) == 130
    monkeypatch.setattr(fv._Frames, "__call__", real_frame)
    assert recipe.main(args) == 0
    assert np.isfinite(np.load(tmp_path / "o" / "poses3d.npz")["joints"]).all()


def test_free_viewpoint_joints_behind_the_cameras_are_not_a_success(tiny, tmp_path, monkeypatch):
    """A calibration in the wrong convention that the readers cannot tell gave joints behind the cameras,
    drawn and reported as 'ok'; each such frame is now said, not drawn, and counted in the summary."""
    import toolkit.pipeline.free_viewpoint as fv
    from toolkit.pipeline.frame import STATUS_BEHIND

    # stage 1's joints mirrored through the first camera's centre: behind it, where a flipped pose puts them
    from toolkit.io import Dataset

    with Dataset.open(tiny) as ds:
        centre = ds.rig[0].center
    real = fv._Stage1.estimates

    def mirrored(est):
        return replace(est, joints3d=2 * centre - np.asarray(est.joints3d, float))

    def flipped(self, frames):
        for est, masks in real(self, frames):
            yield (replace(est, estimates=[mirrored(e) for e in est.estimates]) if hasattr(est, "estimates")
                   else mirrored(est)), masks

    monkeypatch.setattr(fv._Stage1, "estimates", flipped)
    r = fv.run(replace(fv_config(), max_frames=2), dataset=tiny, out=tmp_path / "o", log=None)
    status = np.load(tmp_path / "o" / "poses3d.npz")["status"]
    assert status.tolist() == [STATUS_BEHIND] * 2 and np.isnan(np.load(tmp_path / "o" / "poses3d.npz")["joints"]).all()
    assert f"frames without a result: 2 {STATUS_BEHIND}" in "\n".join(fv.summary_lines(r))


# ------------------------------------------------------------ stage 1 from silhouettes
def stage1_child(args: list, sig: str, after: int) -> subprocess.CompletedProcess:
    """``recipes/pose_from_silhouettes.py ARGS`` in a child process that sends itself ``sig`` once
    ``after`` frames of stage 1 are estimated."""
    code = textwrap.dedent(f"""
        import os, signal, sys
        sys.path.insert(0, {str(ROOT)!r})
        import toolkit.silhouettes.pipeline as sp
        real = sp.estimate_dataset
        def stopping(*a, **k):
            for i, item in enumerate(real(*a, **k)):
                if i == {after}:
                    os.kill(os.getpid(), signal.{sig})
                yield item
        sp.estimate_dataset = stopping
        from recipes import pose_from_silhouettes
        sys.exit(pose_from_silhouettes.main({[str(a) for a in args]!r}))
    """)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=600)


def test_stage1_sigterm_kill_and_an_interrupted_rerun(tiny_dataset, small_db_path, tmp_path, monkeypatch, capsys):
    """SIGTERM ended stage 1 from silhouettes with no results and a recording without its footer; an
    interrupted rerun wrote its partial results (and recording) over a complete run's."""
    import toolkit.silhouettes.pipeline as sp
    from recipes import pose_from_silhouettes
    from toolkit.silhouettes.pipeline import FRAME_NOT_PROCESSED, FRAME_OK

    out = tmp_path / "o"
    args = [tiny_dataset.root, "--out", out, "--db", small_db_path, "--foreground", "chroma", "--quiet"]
    p = stage1_child(args, "SIGTERM", after=1)
    assert p.returncode == 130 and "Traceback" not in p.stderr, p.stderr[-2000:]
    assert "interrupted" in p.stdout
    state = np.load(out / "poses3d.npz")["state"]                      # the frame estimated before the stop
    assert state[0] == FRAME_OK and (state[2:] == FRAME_NOT_PROCESSED).all()
    verify(out / "recording.rrd")
    p = stage1_child(args, "SIGKILL", after=2)
    assert p.returncode == -signal.SIGKILL
    verify(*sorted((out / "recording.parts").glob("*.rrd")))           # the frames finished before the kill
    assert pose_from_silhouettes.main([str(a) for a in args]) == 0
    assert (np.load(out / "poses3d.npz")["state"] == FRAME_OK).all()
    assert sorted(p.name for p in out.glob("recording*")) == ["recording.rrd"]
    verify(out / "recording.rrd")
    complete = snapshot(out)
    capsys.readouterr()
    real = sp.estimate_dataset

    def stop_at_two(*a, **k):
        for i, item in enumerate(real(*a, **k)):
            if i == 2:
                raise KeyboardInterrupt
            yield item

    monkeypatch.setattr(sp, "estimate_dataset", stop_at_two)
    assert pose_from_silhouettes.main([str(a) for a in args]) == 130
    assert "complete results of the earlier run are kept" in capsys.readouterr().out
    assert snapshot(out) == complete                                   # results and recording as they were
    monkeypatch.setattr(sp, "estimate_dataset", real)
    assert pose_from_silhouettes.main([str(a) for a in args] + ["--max-frames", "2"]) == 2   # fewer frames
    assert snapshot(out) == complete
