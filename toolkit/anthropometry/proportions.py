"""Body proportions: segment lengths of a person, from stature.

Ratios of stature are the medians of the ANSUR II survey (2012, male subjects;
see ``docs/anthropometry.md``), converted from surface landmarks to joint
centres the way ``../shared/anthropometry/README.md`` describes:

=================  =======  ===================================================
segment            ratio    ANSUR II expression (male medians, mm / 1755)
=================  =======  ===================================================
neck height        0.864    cervicaleheight (C7) 1516
hip height         0.513    trochanterionheight 900
knee height        0.280    lateralfemoralepicondyleheight 492
ankle height       0.042    lateralmalleolusheight 74
neck to head       0.062    stature - tragiontopofhead - cervicaleheight 108
shoulder half      0.105    biacromialbreadth / 2 = 207 minus ~2 cm (glenohumeral centre)
shoulder drop      0.040    cervicaleheight - acromialheight, minus joint offset
upper arm          0.191    acromionradialelength 335
forearm            0.152    radialestylionlength 267
hip half width     0.054    0.72 * bicristalbreadth / 2 = 99 (Bell et al. 1990)
=================  =======  ===================================================
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from toolkit.errors import InputError

#: Median ratio of each segment to stature (see module docstring).
STATURE_RATIOS = {
    "neck_height": 0.864,
    "hip_height": 0.513,
    "knee_height": 0.280,
    "ankle_height": 0.042,
    "neck_to_head": 0.062,
    "shoulder_half_width": 0.105,
    "shoulder_drop": 0.040,
    "upper_arm": 0.191,
    "forearm": 0.152,
    "hip_half_width": 0.054,
}

#: Allowed stature range of generated people (ANSUR II female p5 rounded down to male p95 rounded up).
STATURE_RANGE_M = (1.52, 1.87)


@dataclass(frozen=True)
class BodyProportions:
    """Segment lengths of one person, metres.

    Attributes
    ----------
    height : float
        Stature (floor to top of head).
    neck_to_head : float
        Neck (C7) to head centre.
    shoulder_half_width : float
        Horizontal distance from the neck to each shoulder joint.
    shoulder_drop : float
        Vertical drop from the neck to the shoulder joints.
    upper_arm, forearm : float
        Shoulder-elbow and elbow-wrist lengths.
    torso : float
        Vertical distance from the neck to the hip joints.
    hip_half_width : float
        Half the distance between the hip joint centres.
    thigh, shank : float
        Hip-knee and knee-ankle lengths.
    ankle_height : float
        Ankle joint above the floor when standing.
    """

    height: float
    neck_to_head: float
    shoulder_half_width: float
    shoulder_drop: float
    upper_arm: float
    forearm: float
    torso: float
    hip_half_width: float
    thigh: float
    shank: float
    ankle_height: float

    @classmethod
    def from_height(cls, height: float) -> "BodyProportions":
        """Median proportions for a stature ``height`` in metres."""
        if not np.isfinite(height) or not (1.0 <= height <= 2.5):
            raise InputError("height_m", "a stature between 1.0 and 2.5 metres", f"{height!r}")
        r = STATURE_RATIOS
        return cls(
            height=float(height),
            neck_to_head=r["neck_to_head"] * height,
            shoulder_half_width=r["shoulder_half_width"] * height,
            shoulder_drop=r["shoulder_drop"] * height,
            upper_arm=r["upper_arm"] * height,
            forearm=r["forearm"] * height,
            torso=(r["neck_height"] - r["hip_height"]) * height,
            hip_half_width=r["hip_half_width"] * height,
            thigh=(r["hip_height"] - r["knee_height"]) * height,
            shank=(r["knee_height"] - r["ankle_height"]) * height,
            ankle_height=r["ankle_height"] * height,
        )

    @classmethod
    def sample(cls, height: float, rng: np.random.Generator | int | None = None,
               spread: float = 0.03) -> "BodyProportions":
        """Proportions for ``height`` with each segment varied by a relative ``spread`` (1 sigma).

        Variations are clipped at 2 sigma and the stature is kept: the leg and
        torso changes are compensated so that the standing height stays
        ``height``.  Left and right are identical.
        """
        rng = np.random.default_rng(rng)
        base = cls.from_height(height)
        vals = {}
        for f in fields(cls):
            v = getattr(base, f.name)
            if f.name != "height":
                v *= 1.0 + float(np.clip(rng.normal(0, spread), -2 * spread, 2 * spread))
            vals[f.name] = v
        p = cls(**vals)
        # keep the stature: rescale the vertical chain to the requested height
        vertical = p.ankle_height + p.shank + p.thigh + p.torso + p.neck_to_head
        target = base.ankle_height + base.shank + base.thigh + base.torso + base.neck_to_head
        k = target / vertical
        return replace(p, ankle_height=p.ankle_height * k, shank=p.shank * k, thigh=p.thigh * k,
                       torso=p.torso * k, neck_to_head=p.neck_to_head * k)

    @property
    def head_center_height(self) -> float:
        """Height of the head centre when standing upright, metres."""
        return self.ankle_height + self.shank + self.thigh + self.torso + self.neck_to_head

    def rest_pose(self) -> np.ndarray:
        """Joints of the 14-joint skeleton standing upright, arms hanging, facing +y.

        The person stands at the origin (z up) facing +y; with z up and +y
        ahead, the person's left side is at -x.

        Returns
        -------
        ndarray of shape (14, 3)
            Metres, order of :data:`toolkit.skeleton.JOINTS_14`.
        """
        a = self.ankle_height
        knee = a + self.shank
        hip = knee + self.thigh
        neck = hip + self.torso
        head = neck + self.neck_to_head
        sh = neck - self.shoulder_drop
        sw, hw = self.shoulder_half_width, self.hip_half_width
        el = sh - self.upper_arm
        wr = el - self.forearm
        # facing +y: the person's left is -x
        return np.array([
            [0, 0, head], [0, 0, neck],
            [-sw, 0, sh], [-sw, 0, el], [-sw, 0, wr],
            [sw, 0, sh], [sw, 0, el], [sw, 0, wr],
            [-hw, 0, hip], [-hw, 0, knee], [-hw, 0, a],
            [hw, 0, hip], [hw, 0, knee], [hw, 0, a],
        ], dtype=float)
