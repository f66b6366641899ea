"""The anthropometric constraint checker of the 3D joint optimisation (source 000, §3.2).

A joint position scores zero when one of these rules breaks:

* the joint is on or above the ground;
* topologically symmetric bones (left/right arm, ...) differ by at most 10 %;
* bone lengths are within the anthropometric standards;
* distances between joints that no bone connects are within the standards.

The standards are the :class:`~toolkit.anthropometry.limits.Limit` table
(:data:`~toolkit.anthropometry.limits.LIMITS_14`).  Joints are joint centres,
so the ground rule asks each joint centre to be at least its *clearance* above
the ground (the ankle centre sits about a malleolus height over the sole, see
:data:`~toolkit.anthropometry.limits.ANKLE_CLEARANCE_M`; other joints 0), less
a margin for the ground-plane calibration and the search grid:
``z >= ground_z + clearance[joint] - ground_margin``.

Every check has a reason code (:data:`REASONS`); the vectorised functions return
the first broken rule in that order, ``0`` (``"ok"``) when none is.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from toolkit.anthropometry.limits import ANKLE_CLEARANCE_M, LIMITS_14, Limit
from toolkit.errors import InputError, check_shape
from toolkit.observe import Observer
from toolkit.skeleton import SKELETON_14, Skeleton

#: Source 000 §3.2: symmetric bones "differ by at most 10 %" (longer <= 1.10 x shorter).
SYMMETRIC_TOLERANCE = 0.10
#: Allowed depth of a joint centre below its lowest height, metres: ground-plane calibration
#: error of 1-2 cm and the 1.2 cm final grid step of the joint search (source 000 §3.2).
GROUND_MARGIN_M = 0.02
#: Lowest height of each joint centre above the ground when not zero, metres.
GROUND_CLEARANCE_14 = (("l_ankle", ANKLE_CLEARANCE_M), ("r_ankle", ANKLE_CLEARANCE_M))

#: Reason codes, in checking order: ``REASONS[code]``; 0 means every enabled rule holds.
REASONS = ("ok", "non_finite", "below_ground", "bone_length", "asymmetric", "joint_distance")
OK, NON_FINITE, BELOW_GROUND, BONE_LENGTH, ASYMMETRIC, JOINT_DISTANCE = range(len(REASONS))

#: Candidates checked per block: keeps the temporaries small (~170 kB for 27 pairs) so
#: they come from the heap; larger blocks were 5-10x slower per candidate (page faults).
_CHUNK = 256


@dataclass(frozen=True)
class Violation:
    """One broken constraint.

    Attributes
    ----------
    kind : str
        One of ``"non_finite"``, ``"below_ground"``, ``"bone_length"``,
        ``"asymmetric"``, ``"joint_distance"``.
    what : str
        The joint, joint pair or bone pair concerned.
    value : float
        The measured value: height (m) for ``below_ground``, distance (m) for
        ``bone_length`` and ``joint_distance``, relative difference
        (longer / shorter - 1) for ``asymmetric``, the coordinate for ``non_finite``.
    lo, hi : float
        The allowed range of ``value``.
    """

    kind: str
    what: str
    value: float
    lo: float
    hi: float

    def __str__(self) -> str:
        if self.kind == "non_finite":
            return f"non_finite: joint {self.what} has a non-finite coordinate ({self.value})"
        if self.kind == "below_ground":
            return (f"below_ground: joint {self.what} at z = {self.value:.3f} m, "
                    f"lowest allowed {self.lo:.3f} m")
        if self.kind == "asymmetric":
            return (f"asymmetric: {self.what} differ by {100 * self.value:.1f} %, "
                    f"at most {100 * self.hi:.1f} % allowed")
        return (f"{self.kind}: {self.what} = {self.value:.3f} m, "
                f"allowed [{self.lo:.2f}, {self.hi:.2f}] m")


@dataclass(frozen=True)
class _Compiled:
    """Index arrays of the enabled constraints."""

    pair_a: np.ndarray      # (P,) joint indices
    pair_b: np.ndarray      # (P,)
    pair_lo: np.ndarray     # (P,) metres
    pair_hi: np.ndarray     # (P,)
    pair_code: np.ndarray   # (P,) BONE_LENGTH or JOINT_DISTANCE
    pair_names: tuple
    sym: np.ndarray         # (S, 4) joints a1, b1, a2, b2 of two symmetric bones
    sym_names: tuple
    floor: np.ndarray       # (J,) lowest allowed z per joint (-inf when the ground check is off)


@dataclass(frozen=True)
class AnthropometricConstraints:
    """Anthropometric constraints on a 3D pose (source 000, §3.2).

    Parameters
    ----------
    limits : tuple of Limit
        Allowed joint-distance ranges; a limit between the two joints of a bone
        is a ``bone_length`` check, any other a ``joint_distance`` check.
    symmetric_tolerance : float
        Largest allowed relative difference of symmetric bones:
        ``longer <= (1 + symmetric_tolerance) * shorter``.
    ground_z : float
        Height of the ground plane, metres (world z up).
    ground_margin : float
        How far below its lowest height a joint centre may be, metres.
    ground_clearance : tuple of (str, float)
        Lowest height of a joint centre above the ground, per joint name (metres);
        joints not listed: 0.
    skeleton : Skeleton
        Joint names, bones and symmetric bone pairs.
    check_ground, check_symmetry, check_bones, check_distances : bool
        Which rules are on; the non-finite check is always on.

    Examples
    --------
    >>> from toolkit.anthropometry import AnthropometricConstraints, BodyProportions
    >>> AnthropometricConstraints().is_valid(BodyProportions.from_height(1.75).rest_pose())
    True
    """

    limits: tuple[Limit, ...] = LIMITS_14
    symmetric_tolerance: float = SYMMETRIC_TOLERANCE
    ground_z: float = 0.0
    ground_margin: float = GROUND_MARGIN_M
    ground_clearance: tuple[tuple[str, float], ...] = GROUND_CLEARANCE_14
    skeleton: Skeleton = SKELETON_14
    check_ground: bool = True
    check_symmetry: bool = True
    check_bones: bool = True
    check_distances: bool = True

    def __post_init__(self):
        for name in ("symmetric_tolerance", "ground_margin"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"AnthropometricConstraints.{name}", "a finite value >= 0",
                                 repr(v))
        if not np.isfinite(self.ground_z):
            raise InputError("AnthropometricConstraints.ground_z", "a finite height in metres",
                             repr(self.ground_z))
        names = set(self.skeleton.joint_names)
        for i, lim in enumerate(self.limits):
            for j in (lim.joint_a, lim.joint_b):
                if j not in names:
                    raise InputError(f"AnthropometricConstraints.limits[{i}] ({lim.name})",
                                     f"joints of skeleton {self.skeleton.name}", repr(j))
            if lim.joint_a == lim.joint_b or not (0 <= lim.min_m <= lim.max_m):
                raise InputError(f"AnthropometricConstraints.limits[{i}] ({lim.name})",
                                 "two different joints and 0 <= min_m <= max_m",
                                 f"{lim.joint_a}, {lim.joint_b}, [{lim.min_m}, {lim.max_m}]")
        for jn, c in self.ground_clearance:
            if jn not in names or not np.isfinite(c):
                raise InputError("AnthropometricConstraints.ground_clearance",
                                 f"(joint of {self.skeleton.name}, finite metres) pairs",
                                 repr((jn, c)))

    # ------------------------------------------------------------ compiled
    @cached_property
    def _c(self) -> _Compiled:
        sk = self.skeleton
        bones = {frozenset(b) for b in sk.bones}
        a, b, lo, hi, code, names = [], [], [], [], [], []
        for lim in self.limits:
            ia, ib = sk.index(lim.joint_a), sk.index(lim.joint_b)
            kind = BONE_LENGTH if frozenset((ia, ib)) in bones else JOINT_DISTANCE
            if not (self.check_bones if kind == BONE_LENGTH else self.check_distances):
                continue
            a.append(ia)
            b.append(ib)
            lo.append(lim.min_m)
            hi.append(lim.max_m)
            code.append(kind)
            names.append(f"{lim.joint_a}-{lim.joint_b} ({lim.name})")
        sym, sym_names = [], []
        if self.check_symmetry:
            for i1, i2 in sk.symmetric_bones:
                sym.append([*sk.bones[i1], *sk.bones[i2]])
                sym_names.append(f"{sk.bone_names[i1]} and {sk.bone_names[i2]}")
        floor = np.full(sk.n_joints, -np.inf)
        if self.check_ground:
            floor[:] = self.ground_z - self.ground_margin
            for jn, c in self.ground_clearance:
                floor[sk.index(jn)] += c
        return _Compiled(np.array(a, int), np.array(b, int), np.array(lo, float),
                         np.array(hi, float), np.array(code, np.int8), tuple(names),
                         np.array(sym, int).reshape(-1, 4), tuple(sym_names), floor)

    @cached_property
    def _by_joint(self) -> tuple:
        """Per joint: (pairs touching it, their other joints, pairs not touching it,
        symmetric pairs touching it, symmetric pairs not touching it)."""
        c = self._c
        out = []
        for j in range(self.skeleton.n_joints):
            touch = (c.pair_a == j) | (c.pair_b == j)
            other = np.where(c.pair_a == j, c.pair_b, c.pair_a)[touch]
            stouch = (c.sym == j).any(axis=1)
            out.append((np.flatnonzero(touch), other, np.flatnonzero(~touch),
                        np.flatnonzero(stouch), np.flatnonzero(~stouch)))
        return tuple(out)

    # -------------------------------------------------------------- checks
    def _check_candidates(self, candidates, name: str) -> np.ndarray:
        c = np.asarray(candidates, dtype=float)
        check_shape(name, c, (None, self.skeleton.n_joints, 3))
        return c

    @staticmethod
    def _pair_lengths(t: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Distances (P, N) between joints a and b of poses laid out as ``t`` (J, 3, N).

        The joint-major layout makes the gathers contiguous (several times faster
        than indexing the middle axis of (N, J, 3)).
        """
        d = t[b]
        d -= t[a]
        d *= d
        return np.sqrt(d.sum(axis=1))

    def _asymmetric(self, l1: np.ndarray, l2: np.ndarray) -> np.ndarray:
        return np.maximum(l1, l2) > (1.0 + self.symmetric_tolerance) * np.minimum(l1, l2)

    def _kind_masks(self, c: np.ndarray) -> np.ndarray:
        """(N, len(REASONS)) bool: which rule kinds break, column = reason code."""
        if c.shape[0] <= _CHUNK:
            return self._kind_masks_chunk(c)
        return np.concatenate([self._kind_masks_chunk(c[i:i + _CHUNK])
                               for i in range(0, c.shape[0], _CHUNK)])

    def _kind_masks_chunk(self, c: np.ndarray) -> np.ndarray:
        cc = self._c
        m = np.zeros((c.shape[0], len(REASONS)), bool)
        m[:, NON_FINITE] = ~np.isfinite(c).all(axis=(1, 2))
        m[:, BELOW_GROUND] = (c[:, :, 2] < cc.floor).any(axis=1)
        t = np.ascontiguousarray(c.transpose(1, 2, 0))
        if cc.pair_a.size:
            d = self._pair_lengths(t, cc.pair_a, cc.pair_b)
            bad = (d < cc.pair_lo[:, None]) | (d > cc.pair_hi[:, None])
            m[:, BONE_LENGTH] = bad[cc.pair_code == BONE_LENGTH].any(axis=0)
            m[:, JOINT_DISTANCE] = bad[cc.pair_code == JOINT_DISTANCE].any(axis=0)
        if cc.sym.size:
            l1 = self._pair_lengths(t, cc.sym[:, 0], cc.sym[:, 1])
            l2 = self._pair_lengths(t, cc.sym[:, 2], cc.sym[:, 3])
            m[:, ASYMMETRIC] = self._asymmetric(l1, l2).any(axis=0)
        return m

    @staticmethod
    def _first(masks: np.ndarray) -> np.ndarray:
        return np.where(masks.any(axis=1), masks.argmax(axis=1), OK).astype(np.int8)

    def first_violation_kind(self, candidates) -> np.ndarray:
        """Reason code of the first broken rule of each candidate pose.

        Parameters
        ----------
        candidates : array_like of shape (N, n_joints, 3)
            Poses, metres.

        Returns
        -------
        ndarray of shape (N,), int8
            Index into :data:`REASONS` (0 = ``"ok"``), in the order non-finite,
            below ground, bone length, asymmetric, joint distance.
        """
        return self._first(self._kind_masks(self._check_candidates(candidates, "candidates")))

    def valid_mask(self, candidates) -> np.ndarray:
        """Whether each candidate pose keeps every enabled rule.

        Parameters
        ----------
        candidates : array_like of shape (N, n_joints, 3)

        Returns
        -------
        ndarray of shape (N,), bool
        """
        return ~self._kind_masks(self._check_candidates(candidates, "candidates")).any(axis=1)

    def valid_positions(self, joints, joint_index: int | str,
                        positions, *, joint_rules_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Check candidate positions of one joint with the rest of the pose fixed.

        Only the rules that involve ``joint_index`` are evaluated per candidate;
        the others are evaluated once on ``joints``.  The result equals
        :meth:`first_violation_kind` of the poses ``joints`` with that joint
        replaced by each position.  With ``joint_rules_only`` the rules that do
        not involve the joint are skipped (the source phrases every rule per
        joint; a noisy pose breaking an unrelated rule then does not block the
        joint's search).

        Parameters
        ----------
        joints : array_like of shape (n_joints, 3)
            Current pose, metres; the entry at ``joint_index`` is ignored.
        joint_index : int or str
            Index or name of the joint that moves.
        positions : array_like of shape (N, 3)
            Candidate positions of that joint, metres.

        Returns
        -------
        valid : ndarray of shape (N,), bool
        reasons : ndarray of shape (N,), int8
            Reason codes, see :data:`REASONS`.
        """
        sk = self.skeleton
        base = np.asarray(joints, dtype=float)
        check_shape("joints", base, (sk.n_joints, 3))
        pos = np.asarray(positions, dtype=float)
        check_shape("positions", pos, (None, 3))
        j = self._joint_index(joint_index)
        touch, other, untouch, stouch, suntouch = self._by_joint[j]
        cc = self._c

        # rules that do not involve joint j: evaluated once on the fixed joints
        fixed = np.ones(sk.n_joints, bool)
        fixed[j] = False
        m0 = np.zeros(len(REASONS), bool)
        if joint_rules_only:
            untouch = suntouch = np.zeros(0, int)
        else:
            m0[NON_FINITE] = not np.isfinite(base[fixed]).all()
            m0[BELOW_GROUND] = bool((base[fixed, 2] < cc.floor[fixed]).any())
        if untouch.size:
            d0 = np.linalg.norm(base[cc.pair_b[untouch]] - base[cc.pair_a[untouch]], axis=-1)
            bad0 = (d0 < cc.pair_lo[untouch]) | (d0 > cc.pair_hi[untouch])
            codes0 = cc.pair_code[untouch]
            m0[BONE_LENGTH] = bad0[codes0 == BONE_LENGTH].any()
            m0[JOINT_DISTANCE] = bad0[codes0 == JOINT_DISTANCE].any()
        if suntouch.size:
            s = cc.sym[suntouch]
            l1 = np.linalg.norm(base[s[:, 1]] - base[s[:, 0]], axis=-1)
            l2 = np.linalg.norm(base[s[:, 3]] - base[s[:, 2]], axis=-1)
            m0[ASYMMETRIC] = self._asymmetric(l1, l2).any()

        # rules that involve joint j: per candidate
        n = pos.shape[0]
        m = np.zeros((n, len(REASONS)), bool)
        m[:, NON_FINITE] = ~np.isfinite(pos).all(axis=1)
        m[:, BELOW_GROUND] = pos[:, 2] < cc.floor[j]
        if touch.size:
            diff = pos[:, None, :] - base[other][None, :, :]
            d = np.sqrt(np.einsum("npk,npk->np", diff, diff))
            bad = (d < cc.pair_lo[touch]) | (d > cc.pair_hi[touch])
            codes = cc.pair_code[touch]
            m[:, BONE_LENGTH] = bad[:, codes == BONE_LENGTH].any(axis=1)
            m[:, JOINT_DISTANCE] = bad[:, codes == JOINT_DISTANCE].any(axis=1)
        for s in cc.sym[stouch]:
            l1 = self._bone_length_with(base, j, pos, s[0], s[1])
            l2 = self._bone_length_with(base, j, pos, s[2], s[3])
            m[:, ASYMMETRIC] |= self._asymmetric(l1, l2)

        reasons = self._first(m | m0)
        return reasons == OK, reasons

    @staticmethod
    def _bone_length_with(base: np.ndarray, j: int, pos: np.ndarray, a: int, b: int) -> np.ndarray:
        """Length (N,) of bone (a, b) when joint j takes each position."""
        if a == j:
            return np.linalg.norm(pos - base[b], axis=-1)
        if b == j:
            return np.linalg.norm(pos - base[a], axis=-1)
        return np.full(pos.shape[0], np.linalg.norm(base[b] - base[a]))

    def _joint_index(self, joint: int | str) -> int:
        n = self.skeleton.n_joints
        if isinstance(joint, str):
            if joint not in self.skeleton.joint_names:
                raise InputError("joint_index",
                                 f"a joint of {self.skeleton.name} {self.skeleton.joint_names}",
                                 repr(joint))
            return self.skeleton.index(joint)
        is_int = isinstance(joint, (int, np.integer)) and not isinstance(joint, (bool, np.bool_))
        if not is_int or not 0 <= joint < n:
            raise InputError("joint_index", f"a joint name or an integer in [0, {n})", repr(joint))
        return int(joint)

    # ------------------------------------------------------- single pose
    def violations(self, joints, observer: Observer | None = None) -> list[Violation]:
        """Every broken rule of one pose, in :data:`REASONS` order.

        Rules that involve a non-finite joint are not evaluated (that joint is
        reported as ``non_finite`` instead).

        Parameters
        ----------
        joints : array_like of shape (n_joints, 3)
            Metres, world frame, z up.
        observer : Observer, optional
            Receives a ``"text"`` report (name ``"anthropometry/violations"``)
            listing the violations.

        Returns
        -------
        list of Violation
            Empty when the pose is valid.
        """
        sk, cc = self.skeleton, self._c
        p = np.asarray(joints, dtype=float)
        check_shape("joints", p, (sk.n_joints, 3))
        finite = np.isfinite(p).all(axis=1)
        out: list[Violation] = []
        for i in np.flatnonzero(~finite):
            bad = p[i][~np.isfinite(p[i])][0]
            out.append(Violation("non_finite", sk.joint_names[i], float(bad), -np.inf, np.inf))
        for i in np.flatnonzero(finite & (p[:, 2] < cc.floor)):
            out.append(Violation("below_ground", sk.joint_names[i], float(p[i, 2]),
                                 float(cc.floor[i]), np.inf))
        pair_ok = finite[cc.pair_a] & finite[cc.pair_b]
        d = np.linalg.norm(p[cc.pair_b] - p[cc.pair_a], axis=-1)
        broken = pair_ok & ((d < cc.pair_lo) | (d > cc.pair_hi))
        sym_v = []
        for k, s in enumerate(cc.sym):
            if finite[s].all():
                l1, l2 = np.linalg.norm(p[s[1]] - p[s[0]]), np.linalg.norm(p[s[3]] - p[s[2]])
                if self._asymmetric(l1, l2):
                    rel = max(l1, l2) / min(l1, l2) - 1.0 if min(l1, l2) > 0 else np.inf
                    sym_v.append(Violation("asymmetric", cc.sym_names[k], float(rel), 0.0,
                                           self.symmetric_tolerance))
        pair_v = {code: [Violation(REASONS[code], cc.pair_names[k], float(d[k]),
                                   float(cc.pair_lo[k]), float(cc.pair_hi[k]))
                         for k in np.flatnonzero(broken & (cc.pair_code == code))]
                  for code in (BONE_LENGTH, JOINT_DISTANCE)}
        out += pair_v[BONE_LENGTH] + sym_v + pair_v[JOINT_DISTANCE]
        if observer is not None:
            text = "\n".join(str(v) for v in out) if out else "all anthropometric constraints hold"
            observer.report("text", name="anthropometry/violations", text=text)
        return out

    def excess(self, joints) -> float:
        """How far one pose is outside the rules: the sum of its violations' relative excesses.

        A bone or joint distance ``d`` outside ``[lo, hi]`` adds ``(lo - d) / lo`` or
        ``(d - hi) / hi``; a symmetric pair adds its difference beyond the
        tolerance; a joint below the floor adds its depth in metres; a
        non-finite joint adds 1.  0 for a valid pose.

        Parameters
        ----------
        joints : array_like of shape (n_joints, 3)
            Metres, world frame, z up.

        Returns
        -------
        float
        """
        total = 0.0
        for v in self.violations(joints):
            if v.kind == "non_finite":
                total += 1.0
            elif v.kind == "below_ground":
                total += float(v.lo - v.value)
            elif v.kind == "asymmetric":
                total += float(v.value - v.hi) if np.isfinite(v.value) else 1.0
            elif v.value < v.lo:
                total += float((v.lo - v.value) / max(v.lo, 1e-9))
            else:
                total += float((v.value - v.hi) / max(v.hi, 1e-9))
        return total

    def is_valid(self, joints) -> bool:
        """Whether one pose ``(n_joints, 3)`` keeps every enabled rule."""
        p = np.asarray(joints, dtype=float)
        check_shape("joints", p, (self.skeleton.n_joints, 3))
        return bool(self.valid_mask(p[None])[0])


def reason_names(codes) -> np.ndarray:
    """Names (:data:`REASONS`) of an array of reason codes."""
    c = np.asarray(codes)
    if c.size and (c.min() < 0 or c.max() >= len(REASONS)):
        raise InputError("codes", f"reason codes in [0, {len(REASONS)})",
                         f"values in [{c.min()}, {c.max()}]")
    return np.asarray(REASONS, dtype=object)[c.astype(int)]
