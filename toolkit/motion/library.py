"""Procedural motion library for the 14-joint skeleton.

Every motion is built the same way: a plan of the pelvis path, trunk, head
and arm angles, and ankle targets (planted feet stay exactly where they were
put), then two-bone inverse kinematics for the legs with the pelvis lowered
wherever a planted foot would otherwise be out of reach, then
:func:`~toolkit.motion.kinematics.forward_kinematics`.  So bone lengths are
those of the :class:`BodyProportions` in every frame, a planted ankle is at
``ankle_height`` above the ground and does not move, no ankle goes below
``ankle_height``, and knees never hyper-extend.

Each motion's parameters are drawn from ``rng`` (same seed, same motion) and
recorded in :attr:`Motion.params`; ``docs/motion.md`` lists them and their
ranges.  The subject stays near the origin: in-place motions start within
:data:`PLACEMENT_RADIUS_M` of it, walks and runs follow a line through the
origin when it fits within :data:`LINE_HALF_LENGTH_M` and otherwise a circle
around it, so that ``|x|, |y| < 4 m``.
"""

from __future__ import annotations

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.motion.actions import GRAVITY_M_S2, _crouch, _idle, _jump, _kick, _turn, _wave
from toolkit.motion.gait import LINE_HALF_LENGTH_M, RUN_CADENCE_HZ, WALK_CADENCE_HZ, _run, _walk
from toolkit.motion.planning import PLACEMENT_RADIUS_M, Motion, _Ctx, _finish
from toolkit.motion.rom import rom_motion
from toolkit.observe import as_observer
from toolkit.skeleton import SKELETON_14

__all__ = ["MOTIONS", "SCENE_MOTIONS", "Motion", "synthesize_motion", "generate_motion", "GRAVITY_M_S2",
           "WALK_CADENCE_HZ", "RUN_CADENCE_HZ", "PLACEMENT_RADIUS_M", "LINE_HALF_LENGTH_M"]


#: Motion names understood by :func:`generate_motion`.
MOTIONS = ("walk", "run", "jump", "kick", "turn", "wave", "crouch", "idle", "rom")

#: The motions of everyday scenes: all but ``rom`` (the functional calibration trial of marker
#: captures).  What the databases built from the library hold by default (the silhouette
#: database's :class:`~toolkit.silhouettes.building.BuildConfig`, the template fit's pose
#: database), so a motion added to :data:`MOTIONS` does not change them (or their cache key).
SCENE_MOTIONS = ("walk", "run", "jump", "kick", "turn", "wave", "crouch", "idle")

#: Builders return a plan (finished by ``_finish``) or a finished Motion (``rom``).
_BUILDERS = {"walk": _walk, "run": _run, "jump": _jump, "kick": _kick, "turn": _turn,
             "wave": _wave, "crouch": _crouch, "idle": _idle, "rom": rom_motion}


# ---------------------------------------------------------------------- API
def _check_args(name, n_frames, fps):
    if name not in _BUILDERS:
        raise InputError("motion", f"one of {list(MOTIONS)}", repr(name))
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames <= 0:
        raise InputError("n_frames", "a positive integer", repr(n_frames))
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not np.isfinite(fps) or fps <= 0:
        raise InputError("fps", "a positive frame rate", repr(fps))


def synthesize_motion(name: str, proportions: BodyProportions, n_frames: int, fps: float,
                      rng: np.random.Generator | int | None = None, observer=None,
                      area_m: float | None = None) -> Motion:
    """Generate a motion and its ground truth (angles, foot contacts, parameters).

    Parameters
    ----------
    name : str
        One of :data:`MOTIONS`.
    proportions : BodyProportions
        Segment lengths of the person, metres.
    n_frames : int
        Number of frames, > 0.
    fps : float
        Frames per second, > 0.
    rng : numpy.random.Generator or int or None
        Source of the per-scene variation (speed, stride, amplitudes, phase,
        heading, position, which arm waves or leg kicks).
    observer : Observer, optional
        Receives one ``joints3d`` report per frame (``name="motion/<name>"``).
    area_m : float, optional
        Walks and runs: the largest distance (metres) of the pelvis path from its mean position.  A
        path drawn as usual that goes further is replaced by a closed loop inside that distance
        (:func:`toolkit.motion.gait._loop_path`; the person turns round and comes back), so that a
        sequence of any length stays where the cameras look.  None (the default): paths as drawn.
        Other motions ignore it.

    Returns
    -------
    Motion

    Raises
    ------
    InputError
        Unknown motion name, or non-positive ``n_frames`` or ``fps``, or ``area_m`` not a positive
        number.
    """
    _check_args(name, n_frames, fps)
    if area_m is not None and (isinstance(area_m, bool) or not isinstance(area_m, (int, float, np.integer,
                                                                                   np.floating))
                               or not np.isfinite(area_m) or area_m <= 0):
        raise InputError("area_m", "a positive distance in metres, or None", repr(area_m))
    if not isinstance(proportions, BodyProportions):
        raise InputError("proportions", "a BodyProportions", type(proportions).__name__)
    rng = np.random.default_rng(rng)
    ctx = _Ctx(proportions, int(n_frames), float(fps), rng, None if area_m is None else float(area_m))
    plan = _BUILDERS[name](ctx)
    motion = plan if isinstance(plan, Motion) else _finish(ctx, plan, name)
    obs = as_observer(observer)
    for i, frame in enumerate(motion.joints):
        obs.report("joints3d", joints=frame, name=f"motion/{name}", skeleton=SKELETON_14, frame=i)
    return motion


def generate_motion(name: str, proportions: BodyProportions, n_frames: int, fps: float,
                    rng: np.random.Generator | int | None = None, observer=None,
                    area_m: float | None = None) -> np.ndarray:
    """Joint positions of a procedural motion.

    Same arguments as :func:`synthesize_motion`.

    Returns
    -------
    ndarray of shape (n_frames, 14, 3)
        Metres, world, z up, ground z = 0, order of ``SKELETON_14.joint_names``.

    Examples
    --------
    >>> from toolkit.anthropometry.proportions import BodyProportions
    >>> j = generate_motion("walk", BodyProportions.from_height(1.75), 50, 25.0, rng=0)
    >>> j.shape
    (50, 14, 3)
    """
    return synthesize_motion(name, proportions, n_frames, fps, rng, observer, area_m).joints

