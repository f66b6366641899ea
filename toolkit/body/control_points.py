"""The 13-control-point body model of the depth tracker (source 001, figure 1).

Control points (order of :data:`toolkit.skeleton.JOINTS_13`): head, shoulders,
elbows, hands, hips, knees, feet; 9 segments (forearms, upper arms, shanks,
thighs and the neck) and the torso patch of the four shoulder and hip points.

What a control point means on a body (used by the synthetic ground truth and
by the fit alike; ``s = stature / 1.75``):

* head: centre of the head, :data:`HEAD_CENTRE_UP` ``* s`` above the top of the neck joint;
* hand: centre of the hand, :data:`HAND_CENTRE_BEYOND_WRIST` ``* s`` beyond the wrist
  along the forearm (the hand reaches :data:`HAND_HALF_LENGTH` ``* s`` further);
* foot: centre of the foot, :data:`FOOT_CENTRE_FORWARD` ``* s`` forward of and
  :data:`FOOT_CENTRE_DOWN` ``* s`` below the ankle (toes :data:`FOOT_HALF_LENGTH` ``* s``
  further forward);
* shoulders, elbows, hips, knees: the joint centres.

For fitting, the body is a set of primitives around the control points:
tapered capsules on the eight limb segments, spheres on the head, hands and
feet, and an elliptic cylinder on the torso patch.  Their sizes are fractions
of stature of an average adult build (:data:`TYPICAL_RADII`); segment lengths
start from the median proportions of :class:`toolkit.anthropometry.BodyProportions`
and are refined while tracking.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from toolkit.anthropometry.limits import LIMITS_14
from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.skeleton import JOINTS_13, JOINTS_14, JOINTS_17, SKELETON_13, SKELETON_14

__all__ = [
    "DEFAULT_STATURE_M",
    "END_SPHERES",
    "FOOT_CENTRE_DOWN",
    "FOOT_CENTRE_FORWARD",
    "FOOT_HALF_LENGTH",
    "HAND_CENTRE_BEYOND_WRIST",
    "HAND_HALF_LENGTH",
    "HEAD",
    "HEAD_CENTRE_UP",
    "INDEX",
    "LENGTH_BOUNDS",
    "LENGTH_NAMES",
    "LENGTH_PAIRS",
    "LIMBS",
    "L_ELBOW",
    "L_FOOT",
    "L_HAND",
    "L_HIP",
    "L_KNEE",
    "L_SHOULDER",
    "N_POINTS",
    "R_ELBOW",
    "R_FOOT",
    "R_HAND",
    "R_HIP",
    "R_KNEE",
    "R_SHOULDER",
    "TYPICAL_RADII",
    "BodyDimensions",
    "control_points",
    "mirror13",
    "rest_pose13",
]

#: Index of each control point, from the skeleton data (:data:`toolkit.skeleton.JOINTS_13`), not by hand.
INDEX = {name: i for i, name in enumerate(JOINTS_13)}
HEAD, L_SHOULDER, R_SHOULDER = INDEX["head"], INDEX["l_shoulder"], INDEX["r_shoulder"]
L_ELBOW, R_ELBOW, L_HAND, R_HAND = INDEX["l_elbow"], INDEX["r_elbow"], INDEX["l_hand"], INDEX["r_hand"]
L_HIP, R_HIP, L_KNEE, R_KNEE = INDEX["l_hip"], INDEX["r_hip"], INDEX["l_knee"], INDEX["r_knee"]
L_FOOT, R_FOOT = INDEX["l_foot"], INDEX["r_foot"]
N_POINTS = len(JOINTS_13)

#: Head centre above the head joint of the 14-joint skeleton, fraction of s = stature / 1.75.
HEAD_CENTRE_UP = 0.02
#: Hand centre beyond the wrist along the forearm, fraction of s.
HAND_CENTRE_BEYOND_WRIST = 0.075
#: Half the hand's length, fraction of s.
HAND_HALF_LENGTH = 0.085
#: Foot centre forward of the ankle, fraction of s.
FOOT_CENTRE_FORWARD = 0.065
#: Foot centre below the ankle (along the shank), fraction of s.
FOOT_CENTRE_DOWN = 0.031
#: Half the foot's length, fraction of s.
FOOT_HALF_LENGTH = 0.125

#: Radii of the fitting primitives of an average adult, fraction of s = stature / 1.75:
#: limb capsules (proximal, distal), end spheres, torso half-depth and how far the torso
#: reaches beyond the shoulder and hip joints sideways, above the shoulders and below the hips.
TYPICAL_RADII = {
    "upper_arm": (0.050, 0.040),
    "forearm": (0.040, 0.032),
    "thigh": (0.080, 0.055),
    "shank": (0.052, 0.040),
    "head": 0.085,
    "hand": 0.045,
    "foot": 0.050,
    "torso_half_depth": (0.105, 0.110),
    "torso_side_extent": (0.035, 0.075),
    "torso_top_extent": 0.060,
    "torso_bottom_extent": 0.060,
}

#: Control-point pairs whose distances are the geometric constraints: the 12
#: bones of SKELETON_13, then shoulder-shoulder and hip-hip.
LENGTH_PAIRS = tuple(SKELETON_13.bones) + ((L_SHOULDER, R_SHOULDER), (L_HIP, R_HIP))
LENGTH_NAMES = tuple(f"{JOINTS_13[a]}-{JOINTS_13[b]}" for a, b in LENGTH_PAIRS)

#: Limb capsules: (name, proximal point, distal point, radius key).
LIMBS = (
    ("l_upper_arm", L_SHOULDER, L_ELBOW, "upper_arm"),
    ("r_upper_arm", R_SHOULDER, R_ELBOW, "upper_arm"),
    ("l_forearm", L_ELBOW, L_HAND, "forearm"),
    ("r_forearm", R_ELBOW, R_HAND, "forearm"),
    ("l_thigh", L_HIP, L_KNEE, "thigh"),
    ("r_thigh", R_HIP, R_KNEE, "thigh"),
    ("l_shank", L_KNEE, L_FOOT, "shank"),
    ("r_shank", R_KNEE, R_FOOT, "shank"),
)
#: End spheres: (name, point, radius key).
END_SPHERES = (("head", HEAD, "head"), ("l_hand", L_HAND, "hand"), ("r_hand", R_HAND, "hand"),
               ("l_foot", L_FOOT, "foot"), ("r_foot", R_FOOT, "foot"))

#: Default stature when it cannot be measured (the person is cut by the image border).
DEFAULT_STATURE_M = 1.75


def _limit(a: str, b: str) -> tuple[float, float]:
    for lim in LIMITS_14:
        if {lim.joint_a, lim.joint_b} == {a, b}:
            return lim.min_m, lim.max_m
    raise KeyError((a, b))


def _length_bounds() -> np.ndarray:
    """Anthropometric (min, max) of each LENGTH_PAIRS distance, metres.

    From ANSUR II (``LIMITS_14``) where the 14-joint skeleton has the same
    distance; the head, hand and foot control points add their offsets
    (head: neck-head limit plus the neck-shoulder span; hand: forearm plus 5 to
    10 cm; foot: shank plus 2 to 8 cm).
    """
    ua = _limit("l_shoulder", "l_elbow")
    fa = _limit("l_elbow", "l_wrist")
    sh = _limit("l_knee", "l_ankle")
    th = _limit("l_hip", "l_knee")
    ss = _limit("l_shoulder", "r_shoulder")
    hh = _limit("l_hip", "r_hip")
    sside = _limit("l_shoulder", "l_hip")
    nh = _limit("neck", "head")
    ns = _limit("neck", "l_shoulder")
    head_sh = (max(nh[0], ns[0]), nh[1] + ns[1])
    hand = (fa[0] + 0.05, fa[1] + 0.10)
    foot = (sh[0] + 0.02, sh[1] + 0.08)
    per = {"head-l_shoulder": head_sh, "head-r_shoulder": head_sh, "l_shoulder-l_elbow": ua,
           "r_shoulder-r_elbow": ua, "l_elbow-l_hand": hand, "r_elbow-r_hand": hand, "l_shoulder-l_hip": sside,
           "r_shoulder-r_hip": sside, "l_hip-l_knee": th, "r_hip-r_knee": th, "l_knee-l_foot": foot,
           "r_knee-r_foot": foot, "l_shoulder-r_shoulder": ss, "l_hip-r_hip": hh}
    return np.array([per[n] for n in LENGTH_NAMES])


#: (min, max) metres of every LENGTH_PAIRS distance (see :func:`_length_bounds`).
LENGTH_BOUNDS = _length_bounds()


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-9)


_J14 = {n: i for i, n in enumerate(JOINTS_14)}


def control_points(joints14: np.ndarray, stature: float) -> tuple[np.ndarray, np.ndarray]:
    """The 13 and 17 control points of a body posed on the 14-joint skeleton.

    The 13 points are defined in the module docstring; the 17-point variant
    (source 001) replaces each hand by the wrist and the hand's tip and each
    foot by the ankle and the toes' tip.

    Parameters
    ----------
    joints14 : ndarray of shape (..., 14, 3)
        Metres, order of ``SKELETON_14``.
    stature : float
        Standing height of the body, metres.

    Returns
    -------
    joints13 : ndarray of shape (..., 13, 3)
        Order of :data:`toolkit.skeleton.JOINTS_13`.
    joints17 : ndarray of shape (..., 17, 3)
        Order of :data:`toolkit.skeleton.JOINTS_17`.
    """
    J = SKELETON_14.check_joints(joints14, "joints14")
    if J.shape[-1] != 3:
        raise InputError("joints14", "an array of shape (..., 14, 3)", f"shape {J.shape}")
    s = float(stature) / 1.75
    g = lambda n: J[..., _J14[n], :]
    up = _unit(g("head") - g("neck"))
    head = g("head") + HEAD_CENTRE_UP * s * up
    lateral = _unit((g("r_shoulder") - g("l_shoulder")) + (g("r_hip") - g("l_hip")))
    p13 = {"head": head}
    p17 = {"head": head}
    for side in ("l", "r"):
        for n in ("shoulder", "elbow", "hip", "knee"):
            p13[f"{side}_{n}"] = p17[f"{side}_{n}"] = g(f"{side}_{n}")
        wr, el = g(f"{side}_wrist"), g(f"{side}_elbow")
        f = _unit(wr - el)
        p13[f"{side}_hand"] = wr + HAND_CENTRE_BEYOND_WRIST * s * f
        p17[f"{side}_wrist"] = wr
        p17[f"{side}_hand"] = wr + (HAND_CENTRE_BEYOND_WRIST + HAND_HALF_LENGTH) * s * f
        an, kn = g(f"{side}_ankle"), g(f"{side}_knee")
        d = _unit(an - kn)
        w = _unit(np.cross(-d, lateral))
        centre = an + FOOT_CENTRE_FORWARD * s * w + FOOT_CENTRE_DOWN * s * d
        p13[f"{side}_foot"] = centre
        p17[f"{side}_ankle"] = an
        p17[f"{side}_foot"] = centre + FOOT_HALF_LENGTH * s * w
    j13 = np.stack([p13[n] for n in JOINTS_13], axis=-2)
    j17 = np.stack([p17[n] for n in JOINTS_17], axis=-2)
    return j13, j17


def rest_pose13(stature: float = DEFAULT_STATURE_M) -> np.ndarray:
    """The 13 control points of a median person standing at the world origin facing +y, z up, (13, 3)."""
    return control_points(BodyProportions.from_height(stature).rest_pose(), stature)[0]


def mirror13(points: np.ndarray) -> np.ndarray:
    """Swap left and right control points (..., 13, 3)."""
    return np.asarray(points)[..., SKELETON_13.flip_permutation, :]


@dataclass(frozen=True)
class BodyDimensions:
    """Sizes of the tracked person.

    Attributes
    ----------
    stature : float
        Metres.
    lengths : ndarray of shape (14,)
        Expected distance of each :data:`LENGTH_PAIRS` pair, metres.
    """

    stature: float
    lengths: np.ndarray

    @classmethod
    def from_stature(cls, stature: float) -> BodyDimensions:
        """Median proportions for a stature (clipped to 1.3 - 2.2 m)."""
        if not np.isfinite(stature) or stature <= 0:
            raise InputError("stature", "a positive number of metres", repr(stature))
        h = float(np.clip(stature, 1.3, 2.2))
        J = rest_pose13(h)
        L = np.array([np.linalg.norm(J[a] - J[b]) for a, b in LENGTH_PAIRS])
        return cls(h, L)

    @property
    def scale(self) -> float:
        """``s = stature / 1.75``."""
        return self.stature / 1.75

    def radius(self, key: str):
        """Radius (or pair of radii) of a primitive, metres."""
        v = TYPICAL_RADII[key]
        return tuple(x * self.scale for x in v) if isinstance(v, tuple) else v * self.scale

    @cached_property
    def limb_radii(self) -> np.ndarray:
        """(proximal, distal) radii of the limb capsules, (8, 2) metres, order of :data:`LIMBS`."""
        return np.array([self.radius(key) for *_, key in LIMBS])

    @cached_property
    def sphere_radii(self) -> np.ndarray:
        """Radii of the end spheres, (5,) metres, order of :data:`END_SPHERES`."""
        return np.array([self.radius(key) for *_, key in END_SPHERES])

    def with_lengths(self, lengths: np.ndarray) -> BodyDimensions:
        return replace(self, lengths=np.asarray(lengths, float).copy())

    def length(self, a: int, b: int) -> float:
        """Expected distance between control points ``a`` and ``b`` (a :data:`LENGTH_PAIRS` pair)."""
        k = _PAIR_INDEX.get((a, b), _PAIR_INDEX.get((b, a)))
        if k is None:
            raise KeyError((a, b))
        return float(self.lengths[k])


_PAIR_INDEX = {pair: k for k, pair in enumerate(LENGTH_PAIRS)}
