"""Frames as tasks on Dask (issue 20): the same outputs with one worker, two, or a cluster started by hand;
a worker that dies loses only its frame; a run killed outright resumes and its recording verifies.

On ``datasets_synthetic/tiny.toml`` (4 frames, two 320 x 180 cameras, one novel camera).  "The same
outputs" is :func:`toolkit.pipeline.run.compare_runs`: every image byte for byte, poses to 1e-9 m,
records and metrics less their wall times.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.observe import RecordingObserver
from toolkit.pipeline.free_viewpoint import PLATE_STORE, VIEW_STORE, FreeViewpointRunConfig, run
from toolkit.pipeline.parallel import AUTO, ParallelConfig, available_cores, map_scenes, map_tasks, resolve_workers
from toolkit.pipeline.run import compare_runs
from toolkit.rendering.freeviewpoint import FreeViewpointConfig
from toolkit.synthetic import generate_scene, parse_spec

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
N_FRAMES = 4
#: The whole chain less the baselines (half the time of a tiny frame, and nothing a frame's order could change).
CONFIG = FreeViewpointRunConfig(frame=FreeViewpointConfig(baselines=False), progress=False, workers=1)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny scene and a run of it with one worker (the reference)."""
    root = tmp_path_factory.mktemp("parallel")
    spec = REPO / "datasets_synthetic" / "tiny.toml"
    generate_scene(parse_spec(spec.read_text(), str(spec)), root / "tiny", progress=False).close()
    ref = run(CONFIG, dataset=root / "tiny", out=root / "one", log=None)
    assert ref.complete and ref.frames == N_FRAMES
    return root / "tiny", root / "one"


def _verify(*files) -> None:
    assert files
    p = subprocess.run([str(BIN / "rerun"), "rrd", "verify", *map(str, files)], capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr


def _square(x):
    if x < 0:
        raise InputError("x", "a number >= 0", repr(x))
    return x * x


def test_tasks_in_order_errors_in_the_main_process():
    got = []
    map_tasks(_square, ((x,) for x in range(5)), on_result=lambda i, r: got.append((i, r)))
    assert got == [(i, i * i) for i in range(5)]
    with pytest.raises(InputError, match="x"):
        map_tasks(_square, [(1,), (-1,)])
    with pytest.raises(InputError, match="--workers"):
        ParallelConfig(workers=0)
    with pytest.raises(InputError, match="--scheduler"):
        ParallelConfig(scheduler="localhost:8786")
    assert map_scenes(_square, [3, 1, 2]) == [9, 1, 4]


def test_auto_workers_are_the_cores_this_process_may_use():
    import os

    assert FreeViewpointRunConfig().workers == AUTO  # the recipe's default
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert 1 <= available_cores() <= cores
    assert resolve_workers(AUTO) == available_cores()
    assert resolve_workers(AUTO, tasks=1) == 1  # one frame to do: no cluster
    assert resolve_workers("3") == 3 and resolve_workers(2) == 2
    for bad in (0, -1, "two", 1.5, True, None):
        with pytest.raises(InputError, match="--workers"):
            resolve_workers(bad)
    with pytest.raises(InputError, match="--workers"):
        FreeViewpointRunConfig(workers="many")


def test_two_workers_give_the_outputs_of_one(tiny, tmp_path):
    dataset, one = tiny
    obs = RecordingObserver()
    two = run(replace(CONFIG, workers=2), dataset=dataset, out=tmp_path / "two", observer=obs, log=None)
    assert two.complete and two.processed == N_FRAMES
    assert compare_runs(one, tmp_path / "two") == []
    assert not (tmp_path / "two" / PLATE_STORE).exists()  # the shared plates go when every frame is done
    assert not (tmp_path / "two" / VIEW_STORE).exists()  # and so do the scene model's shared views
    # every frame's reports came back from the workers, in frame order
    frames = [d["frame"] for d in obs.of_kind("joints3d") if d.get("name") == "free_viewpoint/joints"]
    assert frames == list(range(N_FRAMES))
    _verify(one / "recording.rrd")
    assert not (one / "recording.parts").exists()


def _start_cluster(tmp_path: Path):
    """``dask scheduler`` and two ``dask worker`` processes (no nanny: a killed worker stays dead)."""
    pytest.importorskip("distributed", reason="dask.distributed is not installed")
    if not (BIN / "dask").exists():
        pytest.skip("no dask command beside this Python")
    sched_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([str(BIN / "dask"), "scheduler", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sched_file)], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    for _ in range(100):
        if sched_file.exists() and sched_file.stat().st_size:
            break
        time.sleep(0.2)
    address = json.loads(sched_file.read_text())["address"]
    for i in range(2):
        procs.append(subprocess.Popen([str(BIN / "dask"), "worker", address, "--nthreads", "1", "--no-nanny",
                                       "--no-dashboard", "--name", f"w{i}"], stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL, cwd=tmp_path))
    from dask.distributed import Client

    with Client(address, timeout="30s") as c:
        c.wait_for_workers(2, timeout=60)
    return address, procs


@pytest.mark.timeout(300)
def test_cluster_from_the_command_line_and_a_worker_killed_mid_run(tiny, tmp_path):
    dataset, one = tiny
    address, procs = _start_cluster(tmp_path)
    out = tmp_path / "cluster"
    result = {}
    try:
        th = threading.Thread(target=lambda: result.update(r=run(replace(CONFIG, scheduler=address),
                                                                 dataset=dataset, out=out, log=None)))
        th.start()
        for _ in range(600):  # a first frame finished: the workers are busy with the next ones
            if any((out / "frames").glob("*.json")) or not th.is_alive():
                break
            time.sleep(0.1)
        procs[1].send_signal(signal.SIGKILL)
        th.join(240)
        assert not th.is_alive()
    finally:
        for p in procs:
            p.kill()
            p.wait()
    r = result["r"]
    assert r.complete and r.processed == N_FRAMES  # the dead worker's frame was done again elsewhere
    assert compare_runs(one, out) == []
    _verify(out / "recording.rrd")


@pytest.mark.timeout(300)
def test_the_recipe_on_a_scheduler_and_two_dask_workers_gives_the_outputs_of_one(tiny, tmp_path):
    """``free_viewpoint.py --scheduler ADDRESS`` with ``dask scheduler`` + two ``dask worker`` processes
    started from the command line: the same outputs as one worker in this process."""
    from recipes import free_viewpoint as recipe

    dataset, one = tiny
    address, procs = _start_cluster(tmp_path)
    out = tmp_path / "cli"
    try:
        rc = recipe.main([str(dataset), "--out", str(out), "--scheduler", address, "--no-baselines", "--quiet"])
    finally:
        for p in procs:
            p.kill()
            p.wait()
    assert rc == 0
    assert compare_runs(one, out) == []


@pytest.mark.timeout(300)
def test_a_killed_run_leaves_a_recording_that_verifies_and_resumes(tiny, tmp_path):
    dataset, one = tiny
    out = tmp_path / "killed"
    log = tmp_path / "killed.log"
    with open(log, "w") as err:
        p = subprocess.Popen([sys.executable, str(REPO / "recipes" / "free_viewpoint.py"), str(dataset), "--out",
                              str(out), "--quiet", "--no-baselines", "--workers", "1"], stdout=err, stderr=err)
    try:
        while p.poll() is None and not (any((out / "frames").glob("*.json"))
                                        and any((out / "recording.parts").glob("*.rrd"))):
            time.sleep(0.05)
        p.send_signal(signal.SIGKILL)
    finally:
        p.wait()
    done = len(list((out / "frames").glob("*.json")))
    assert 1 <= done < N_FRAMES, f"the run was not killed mid-run: {log.read_text()[-2000:]}"
    parts = sorted((out / "recording.parts").glob("*.rrd"))
    assert parts  # a part per frame (the first also holds the set-up); the one being written is left out
    _verify(*parts)
    r = run(CONFIG, dataset=dataset, out=out, log=None)
    assert r.complete and r.earlier == done and r.processed == N_FRAMES - done
    assert compare_runs(one, out) == []
    assert not (out / "recording.parts").exists()  # merged into one file when the run resumed
    _verify(out / "recording.rrd", out / "recording.resume-1.rrd")
    assert np.load(out / "poses3d.npz")["joints"].shape == (N_FRAMES, 14, 3)


def test_several_depth_sequences_each_in_its_folder(tmp_path):
    """``recipes/depth_tracking.py A B --out OUT``: OUT/A and OUT/B, each what a run of its own gives."""
    from recipes import depth_tracking
    from toolkit.anthropometry.proportions import BodyProportions
    from toolkit.body.model import BodyModel
    from toolkit.motion import generate_motion
    from toolkit.synthetic.depth_sensor import DepthCameraSpec, render_depth_camera

    inputs = []
    for seed, motion in ((11, "idle"), (12, "wave")):
        props = BodyProportions.sample(1.72, seed)
        J = generate_motion(motion, props, 4, 30.0, rng=seed)
        root = tmp_path / f"seq_{motion}"
        render_depth_camera(root, DepthCameraSpec(resolution=(160, 120), environment="floor"),
                            BodyModel.sample(props, seed, detail=0.5), J, rng=seed)
        inputs.append(root)
    assert depth_tracking.main([*map(str, inputs), "--out", str(tmp_path / "all"), "--quiet", "--no-recording"]) == 0
    assert depth_tracking.main([str(inputs[1]), "--out", str(tmp_path / "alone"), "--quiet", "--no-recording"]) == 0
    for root in inputs:
        z = np.load(tmp_path / "all" / root.name / "skeleton.npz")
        assert z["joints"].shape == (4, 13, 3)
    a, b = (np.load(p / "skeleton.npz") for p in (tmp_path / "all" / inputs[1].name, tmp_path / "alone"))
    assert np.array_equal(a["joints"], b["joints"], equal_nan=True)
    assert depth_tracking.main([str(inputs[0]), str(inputs[0]), "--out", str(tmp_path / "x"), "--quiet"]) == 2
