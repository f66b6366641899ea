"""The joint-angle run behind ``recipes/joint_angles.py``: a run's 3D output in, angles and animations out.

Steps: :func:`toolkit.biomech.files.load_run` (the system's joints, and for a
marker capture its markers) -> joint angles by the chosen engine (the
project's own, :func:`toolkit.biomech.angles.joint_angles`, or OpenSim's
scaling and inverse kinematics, :mod:`toolkit.biomech.opensim_model`) ->
``OUT/angles.csv`` (+ the engine's files) -> optional BVH and glTF
(:mod:`toolkit.biomech.export`) -> the angles and joints reported to the
observer (per joint a plot over time: ``angles/<side>_<joint>/<motion>``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolkit.biomech.angles import JointAngles, joint_angles
from toolkit.biomech.files import load_run, write_angles_csv, write_json
from toolkit.biomech.mapping import skeleton14_from_points
from toolkit.errors import InputError

#: The engines of ``--engine``.
ENGINES = ("own", "opensim")


@dataclass(frozen=True)
class JointAnglesConfig:
    """Options of a joint-angle run.

    Parameters
    ----------
    engine : {"own", "opensim"}
    fps : float or None
        Frames per second when the run's files do not say.
    static : Path or None
        A static trial's run (or file) of the same person: the feet's pitch offsets.
    bvh, gltf : bool
        Also write ``OUT/motion.bvh`` / ``OUT/motion.glb``.
    recording : bool
        Write ``OUT/recording.rrd`` (angles plotted per joint, the joints in 3D).
    person : str or None
        One person of a free-viewpoint run's ``people3d.npz`` (:func:`run_every_person` takes them all).
    """

    engine: str = "own"
    fps: float | None = None
    static: Path | None = None
    bvh: bool = False
    gltf: bool = False
    recording: bool = True
    person: str | None = None


@dataclass(frozen=True)
class JointAnglesResult:
    """What :func:`run` returns: the angles and the files written (name -> path)."""

    angles: JointAngles
    files: dict
    system: str
    seconds: float
    notes: tuple = field(default_factory=tuple)
    person: str | None = None


def report_angles(observer, angles: JointAngles, joints14: np.ndarray | None = None) -> None:
    """Report every angle as a scalar per frame (``angles/<side>_<joint>/<motion>``) and the joints in 3D.

    Parameters
    ----------
    observer : Observer
    angles : JointAngles
    joints14 : ndarray of shape (T, 14, 3), optional
        Metres; reported as ``joints3d`` per frame.
    """
    from toolkit.skeleton import SKELETON_14

    if joints14 is not None:
        observer.report("skeleton", skeleton=SKELETON_14)
    paths = []
    for n in angles.names:
        side, joint, motion = n.split("_", 2)
        paths.append(f"angles/{side}_{joint}/{motion}")
    for t in range(len(angles.time)):
        if joints14 is not None:
            observer.report("joints3d", joints=joints14[t], skeleton=SKELETON_14, name="joints", frame=t)
        for k, path in enumerate(paths):
            v = angles.degrees[t, k]
            if np.isfinite(v):
                observer.report("scalar", name=path, value=float(v), frame=t)


def _angles(config: JointAnglesConfig, points: dict, fps: float, out: Path, static_points, log):
    if config.engine == "own":
        return joint_angles(points, fps, static=static_points), {}, ()
    from toolkit.biomech.opensim_model import opensim_angles

    res = opensim_angles(points, fps, out, static=static_points, log=log)
    return res.angles, res.files, res.notes


def run(config: JointAnglesConfig, *, source, out, observer=None, log=print) -> JointAnglesResult:
    """Joint angles (and animations) of a run's 3D output.

    Parameters
    ----------
    config : JointAnglesConfig
    source : path
        A run folder (``poses3d.npz``, ``joint_centres.npz``, ``skeleton.npz``
        or ``joints.npz``; ``people3d.npz`` with ``config.person``) or one of those files.
    out : path
        Output folder (created).
    observer : Observer, optional
        Receives the angles and joints; default: ``OUT/recording.rrd`` when ``config.recording``.
    log : callable or None

    Returns
    -------
    JointAnglesResult

    Raises
    ------
    InputError
        Unknown engine, no frame rate, a run without the joints the angles need;
        OpenSim asked for but not installed.
    """
    from toolkit.observe import MultiObserver, as_observer

    if config.engine not in ENGINES:
        raise InputError("engine", f"one of {ENGINES}", repr(config.engine))
    t0 = time.perf_counter()
    data = load_run(source, config.person)
    fps = config.fps or data.fps
    if fps is None:
        raise InputError(f"{data.source}: frame rate", "a frame rate in the file or --fps", "none")
    static = load_run(config.static).points if config.static is not None else None
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    angles, files, notes = _angles(config, data.points, float(fps), out, static, log)
    if data.people and data.person is None:
        notes = (f"the run holds {len(data.people)} people ({', '.join(data.people)}) in people3d.npz; these are "
                 f"the angles of {Path(data.source).name} (the main person): --person NAME or --person all for "
                 "the others",) + tuple(notes)
    files = {"angles": write_angles_csv(out / "angles.csv", angles), **files}
    joints14 = skeleton14_from_points(data.points)
    if config.bvh or config.gltf:
        from toolkit.biomech.export import export_bvh, export_gltf

        if config.bvh:
            export_bvh(out / "motion.bvh", joints14, float(fps))
            files["bvh"] = out / "motion.bvh"
        if config.gltf:
            export_gltf(out / "motion.glb", joints14, float(fps))
            files["gltf"] = out / "motion.glb"
    rec = None
    if observer is None and config.recording:
        from toolkit.viz import RerunObserver

        rec = RerunObserver(application_id="joint_angles", path=out / "recording.rrd")
        files["recording"] = out / "recording.rrd"
    obs = as_observer(MultiObserver(rec, observer) if (rec or observer) else None)
    try:
        report_angles(obs, angles, joints14)
    finally:
        if rec is not None:
            rec.close()
    summary = {"source": data.source, "system": data.system, "person": data.person, "people": list(data.people),
               "engine": angles.engine, "fps": float(fps),
               "frames": int(len(angles.time)), "static": str(config.static) if config.static else None,
               "landmarks": sorted(data.points), "angles": list(angles.names),
               "range_deg": {n: [float(np.nanmin(angles[n])), float(np.nanmax(angles[n]))]
                             for n in angles.names if np.isfinite(angles[n]).any()},
               "notes": list(notes), "files": {k: str(v) for k, v in files.items()}}
    files["summary"] = write_json(out / "summary.json", summary)
    return JointAnglesResult(angles, files, data.system, time.perf_counter() - t0, tuple(notes), data.person)


def run_every_person(config: JointAnglesConfig, *, source, out, log=print) -> dict:
    """:func:`run` for every person of a free-viewpoint run's ``people3d.npz``, each into ``OUT/<person>/``.

    Parameters
    ----------
    config : JointAnglesConfig
        ``person`` is ignored.
    source : path
        The run folder or its ``people3d.npz``.
    out : path
        Output folder; one subfolder per person.
    log : callable or None

    Returns
    -------
    dict of str to JointAnglesResult
        Person -> their result.

    Raises
    ------
    InputError
        The run has no ``people3d.npz``; as :func:`run`.
    """
    from dataclasses import replace

    from toolkit.biomech.files import PEOPLE_FILE, run_people

    people = run_people(source)
    if not people:
        raise InputError(str(source), f"a run with several people ({PEOPLE_FILE}) for --person all", "none")
    return {p: run(replace(config, person=p), source=source, out=Path(out) / p, log=log) for p in people}


def summary_lines(result: JointAnglesResult) -> list[str]:
    """A few lines for the terminal."""
    a = result.angles
    who = f" ({result.person})" if result.person else ""
    lines = [f"joint angles ({a.engine}) of a {result.system} run{who}: {len(a.time)} frames, {len(a.names)} "
             f"angles in {result.seconds:.1f} s"]
    for n in a.names:
        v = a[n]
        if np.isfinite(v).any():
            lines.append(f"  {n:26s} {np.nanmin(v):7.1f} .. {np.nanmax(v):7.1f} deg")
    lines += [f"  {k + ':':10s} {v}" for k, v in result.files.items()]
    lines += [f"note: {n}" for n in result.notes]
    return lines
