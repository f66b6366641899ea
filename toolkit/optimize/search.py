"""Anthropometrically constrained 3D joint optimisation (source 000 §3.2, claim 10).

Each joint in turn is moved on an adaptive discrete 3D grid around its
position: the ``(2r+1)^3`` grid is scored, then refined (step halved) around
the best ``keep_best`` candidates, down to 1.2 cm.  A candidate that breaks an
anthropometric constraint (:class:`~toolkit.anthropometry.AnthropometricConstraints`;
only the rules the joint takes part in, see :mod:`toolkit.optimize.rules`) scores zero.  Joints are swept until a sweep improves the summed score by
less than a threshold or after a maximum number of sweeps (the source
converges in about four).

Expected failures do not raise: a joint whose every candidate breaks a
constraint, or whose bones no camera pair sees (empty segments, edge-on
billboards), keeps its previous position and its :class:`JointStep` says why.
"""

from __future__ import annotations

import itertools
import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from toolkit.anthropometry import AnthropometricConstraints
from toolkit.anthropometry.constraints import REASONS
from toolkit.billboards.score import PositionScorer
from toolkit.errors import InputError
from toolkit.observe import Observer, as_observer
from toolkit.optimize.config import OptimizeConfig
from toolkit.optimize.rules import joint_rule_reasons

#: Status values of :class:`JointStep`.
STATUSES = ("moved", "kept", "not_decisive", "all_invalid", "unscorable", "few_views")


@dataclass(frozen=True)
class JointStep:
    """Result of optimising one joint once.

    Attributes
    ----------
    joint : int
    position : ndarray of shape (3,)
        Accepted position, metres.
    score, start_score : float
        Score after and before (NaN if unscorable; 0 for ``all_invalid``).  A start
        that breaks a rule has its real score when moves must be decisive (a move
        away from it needs the same margin and evidence as any other), 0 under the
        source's rule (``decisive=False``: any valid candidate beats it).
    n_evaluations : int
        Position-score evaluations spent.
    n_rejected : int
        Candidates that broke a constraint.
    status : str
        One of :data:`STATUSES`.
    reason : str
        Why the joint did not move, empty otherwise.
    """

    joint: int
    position: np.ndarray
    score: float
    start_score: float
    n_evaluations: int
    n_rejected: int
    status: str
    reason: str = ""


@dataclass(frozen=True)
class PoseResult:
    """Result of :func:`optimize_pose`.

    Attributes
    ----------
    joints : ndarray of shape (14, 3)
        Optimised joints, metres.
    scores : ndarray of shape (n_sweeps + 1, n_joints)
        Joint scores before the first sweep (row 0) and after each sweep.
    n_evaluations : int
    n_sweeps : int
    converged : bool
        True when the last sweep improved by less than ``min_improvement``.
    steps : tuple of JointStep
        Every joint step, in order.
    seconds : float
        Wall time.
    """

    joints: np.ndarray
    scores: np.ndarray
    n_evaluations: int
    n_sweeps: int
    converged: bool
    steps: tuple = field(default_factory=tuple)
    seconds: float = 0.0

    def outcomes(self) -> list[str]:
        """Per joint, ``"moved"`` if any sweep moved it, else the status of its last step
        (one of :data:`STATUSES`; ``"not searched"`` for a joint outside ``joint_order``)."""
        out = ["not searched"] * len(self.joints)
        for st in self.steps:
            if out[st.joint] != "moved":
                out[st.joint] = st.status
        return out

    def outcome_counts(self) -> dict[str, int]:
        """How many joints ended with each of :meth:`outcomes`, e.g. ``{"moved": 9, "kept": 5}``."""
        return dict(Counter(self.outcomes()))


def _offsets(r: int) -> np.ndarray:
    g = np.arange(-r, r + 1, dtype=float)
    return np.array(list(itertools.product(g, g, g)))


def _score_color(s: np.ndarray, top: float) -> np.ndarray:
    """Blue (low) to yellow (high) colours (N, 3) uint8."""
    t = np.clip(np.nan_to_num(s) / max(top, 1e-9), 0, 1)
    return np.stack([255 * t, 64 + 191 * t, 255 * (1 - t)], -1).astype(np.uint8)


_REASON_COLORS = np.array([[0, 200, 0], [128, 128, 128], [139, 69, 19], [255, 0, 0], [255, 0, 255],
                           [255, 128, 0]], np.uint8)


def _why_not_searched(scorer: PositionScorer, vis: dict, start: float, joint: int,
                      config: OptimizeConfig) -> tuple[str, str]:
    """Why the joint is not searched at all: unscorable, seen in too few views or by too few camera pairs.

    Parameters
    ----------
    scorer : PositionScorer
    vis : dict of int to ndarray of shape (V, C), bool
        Per adjacent part, the billboards used in each view.
    start : float
        Score of the joint's start.
    joint : int
    config : OptimizeConfig

    Returns
    -------
    status : str
        ``"unscorable"``, ``"few_views"``, ``"not_decisive"``, or "" when the joint is searched.
    why : str
        The reason, for the report ("" when searched).
    """
    sk = scorer.skeleton
    name = sk.joint_names[joint]
    if not np.isfinite(start):
        why = (f"{name}: kept: no camera pair sees its bones "
               f"({', '.join(sk.parts[p].name for p in scorer.adjacent_parts(joint))}): "
               "empty segments or edge-on billboards")
        return "unscorable", why
    n_views = int(np.any([(v.sum(axis=1) >= 2) for v in vis.values()], axis=0).sum()) if vis else 0
    if n_views < config.min_views:
        why = (f"{name}: kept: its bones are scored in {n_views} view(s), fewer than {config.min_views} "
               "(the cameras see each other's billboards edge-on)")
        return "few_views", why
    n_pairs = _scoring_pairs(vis)
    if config.decisive and n_pairs < config.min_pairs:
        # no move could be decisive: skip the search (two cameras: one pair, every view compares
        # the same two images)
        why = (f"{name}: kept: its bones are scored by {n_pairs} camera pair(s), a decisive move needs "
               f"{config.min_pairs}")
        return "not_decisive", why
    return "", ""


def _key(p: np.ndarray) -> tuple:
    """Dictionary key of a position (metres) on a 0.1 mm grid."""
    return tuple(np.round(p / 1e-4).astype(np.int64))


def _grid_search(scorer: PositionScorer, cons: AnthropometricConstraints, J: np.ndarray, joint: int, vis: dict,
                 start_score: float, penalty, config: OptimizeConfig):
    """Adaptive grid search: candidates around the best ``keep_best`` positions, the step halved each level.

    Parameters
    ----------
    scorer : PositionScorer
    cons : AnthropometricConstraints
    J : ndarray of shape (14, 3)
        The pose, metres; ``J[joint]`` is the start.
    joint : int
    vis : dict of int to ndarray of shape (V, C), bool
        Per adjacent part, the billboards used in each view.
    start_score : float
        Score given to the start.
    penalty : callable
        Prior cost of positions (..., 3) -> (...).
    config : OptimizeConfig

    Returns
    -------
    seen : dict of tuple to float
        Score of every evaluated position by :func:`_key` (0 for rejected ones).
    pos_of : dict of tuple to ndarray of shape (3,)
        The position of each key, metres.
    rej_pos : list of ndarray of shape (3,)
        Candidates breaking a rule.
    rej_code : list of int
        Their reasons (:data:`~toolkit.anthropometry.constraints.REASONS`).
    """
    x0 = J[joint].copy()
    offs = _offsets(config.grid_radius)
    seen: dict[tuple, float] = {}
    rej_pos, rej_code = [], []
    seen[_key(x0)] = start_score
    pos_of = {_key(x0): x0}
    centres = [x0]
    step = config.initial_step_m
    while True:
        cands = np.unique(np.concatenate([c + step * offs for c in centres]), axis=0)
        new = [c for c in cands if _key(c) not in seen]
        if new:
            new = np.array(new)
            valid, codes = joint_rule_reasons(cons, J, joint, new)
            # the level's valid candidates are scored together (one batch of the scorer)
            scores = iter(scorer.candidate_scores(J, joint, new[valid], vis) if valid.any() else ())
            for p, ok, code in zip(new, valid, codes):
                k = _key(p)
                pos_of[k] = p
                if ok:
                    s = next(scores)
                    seen[k] = float(s) if np.isfinite(s) else 0.0
                else:
                    seen[k] = 0.0
                    rej_pos.append(p)
                    rej_code.append(int(code))
        ranked = sorted(seen.items(), key=lambda kv: -(kv[1] - penalty(pos_of[kv[0]])))
        centres = [pos_of[k] for k, _ in ranked[:config.keep_best]]
        if step <= config.min_step_m * (1 + 1e-9):
            break
        step = max(step / 2.0, config.min_step_m)
    return seen, pos_of, rej_pos, rej_code


def _report_candidates(obs, name: str, P: np.ndarray, S: np.ndarray, rej_pos: list, rej_code: list,
                       frame: int | None) -> None:
    """Report the evaluated candidates coloured by score and the rejected ones by reason, with their counts.

    Parameters
    ----------
    obs : Observer
    name : str
        The joint's name.
    P : ndarray of shape (N, 3)
        Evaluated positions, metres.
    S : ndarray of shape (N,)
        Their scores.
    rej_pos : list of ndarray of shape (3,)
    rej_code : list of int
    frame : int or None
    """
    obs.report("points3d", name=f"optimize/candidates/{name}", points=P, colors=_score_color(S, S.max()),
               radii=0.004, frame=frame)
    n_rej = len(rej_pos)
    if n_rej:
        codes = np.array(rej_code)
        obs.report("points3d", name=f"optimize/rejected/{name}", points=np.array(rej_pos),
                   colors=_REASON_COLORS[codes], radii=0.004, frame=frame)
        counts = {REASONS[c]: int((codes == c).sum()) for c in np.unique(codes)}
        obs.report("text", name="optimize/rejected", frame=frame,
                   text=f"{name}: {n_rej} candidates rejected: {counts}")


def optimize_joint(scorer: PositionScorer, joints: np.ndarray, joint: int,
                   constraints: AnthropometricConstraints | None = None,
                   config: OptimizeConfig = OptimizeConfig(), *, observer: Observer | None = None,
                   frame: int | None = None, anchor: np.ndarray | None = None) -> JointStep:
    """Adaptive grid search of one joint with the rest of the pose fixed.

    Parameters
    ----------
    scorer : PositionScorer
        Position score of the frame.
    joints : ndarray of shape (14, 3)
        Current pose, metres.
    joint : int
        Joint index.
    constraints : AnthropometricConstraints, optional
        Default: ``AnthropometricConstraints()``.
    config : OptimizeConfig
    observer : Observer, optional
        Receives the evaluated candidates (``points3d`` coloured by score), the
        rejected ones (``points3d`` coloured by reason) and a ``text`` with the
        rejection counts per reason, or why the joint was kept.
    frame : int, optional
    anchor : ndarray of shape (3,), optional
        Where the joint started the whole optimisation (the stage-1 estimate);
        with ``config.prior_weight > 0`` candidates are compared on their score
        minus ``prior_weight * (|x - anchor| / prior_sigma_m)^2``.

    Returns
    -------
    JointStep
    """
    sk = scorer.skeleton
    J = np.array(joints, float)
    if J.shape != (sk.n_joints, 3):
        raise InputError("joints", f"an array of shape ({sk.n_joints}, 3)", f"shape {J.shape}")
    if not 0 <= joint < sk.n_joints:
        raise InputError("joint", f"a joint index in [0, {sk.n_joints})", f"{joint}")
    cons = constraints if constraints is not None else AnthropometricConstraints()
    obs = as_observer(observer)
    name = sk.joint_names[joint]
    x0 = J[joint].copy()
    n0 = scorer.n_evaluations
    start_valid, _ = joint_rule_reasons(cons, J, joint, x0[None])
    vis = {p: scorer.visibility(J, p) for p in scorer.adjacent_parts(joint)}
    start = scorer.joint_score(J, joint, vis)

    def keep(status: str, why: str, score: float, n_rej: int = 0) -> JointStep:
        """The joint stays at its start."""
        if not start_valid[0]:
            why += " (its start breaks an anthropometric rule; no decisive move obeys them)"
        return JointStep(joint, x0, score, score, scorer.n_evaluations - n0, n_rej, status, why)

    status, why = _why_not_searched(scorer, vis, start, joint, config)
    if status:
        obs.report("text", name="optimize/kept", text=why, frame=frame)
        return keep(status, why, start)
    # A start that breaks a rule is not a candidate, but with decisive moves it keeps its real
    # score: the rules say the joint is wrong, not where it should be, so a move still needs the
    # margin and the evidence (taking the best valid candidate, the source's rule, moved stage-1
    # knees 3 cm the wrong way on zoo seed 13 z00: +7 % MPJPE, docs/stage3_billboards.md)
    start_score = start if start_valid[0] or config.decisive else 0.0
    prior_w = config.prior_weight / config.prior_sigma_m ** 2 if anchor is not None else 0.0

    def penalty(p):
        """Prior cost of position(s) ``p`` (..., 3): 0 without an anchor or weight."""
        return prior_w * np.sum((np.asarray(p) - (0.0 if anchor is None else anchor)) ** 2, axis=-1)

    seen, pos_of, rej_pos, rej_code = _grid_search(scorer, cons, J, joint, vis, start_score, penalty, config)
    keys = list(seen)
    P = np.array([pos_of[k] for k in keys])
    S = np.array([seen[k] for k in keys])
    n_rej = len(rej_pos)
    _report_candidates(obs, name, P, S, rej_pos, rej_code, frame)
    n_eval = scorer.n_evaluations - n0
    rejected = {_key(p) for p in rej_pos}
    if not start_valid[0]:
        rejected.add(_key(x0))
    valid_mask = np.array([k not in rejected for k in keys])
    if not valid_mask.any():
        why = f"{name}: kept: every candidate breaks a constraint"
        obs.report("text", name="optimize/kept", text=why, frame=frame)
        return JointStep(joint, x0, 0.0, 0.0, n_eval, n_rej, "all_invalid", why)
    S_valid = np.where(valid_mask, S - penalty(P), -np.inf)
    # the score is flat along a bone: among candidates within tie_tol of the best, take the
    # one nearest the start, so that unobservable directions keep the previous estimate
    near = np.flatnonzero(S_valid >= S_valid.max() - config.tie_tol)
    b = int(near[np.argmin(np.linalg.norm(P[near] - x0, axis=1))])
    if not start_valid[0] and not config.decisive:  # the source's rule: any valid candidate is better
        return JointStep(joint, P[b].copy(), float(S[b]), start_score, n_eval, n_rej, "moved")
    if S_valid[b] > start_score - penalty(x0) + config.min_gain:
        why = decisive_reason(scorer, J, joint, P[b], vis, config) if config.decisive else ""
        if not why:
            return JointStep(joint, P[b].copy(), float(S[b]), start_score, scorer.n_evaluations - n0, n_rej,
                             "moved")
        why = f"{name}: kept: a gain of {S[b] - start_score:.3f} {why}"
        obs.report("text", name="optimize/kept", text=why, frame=frame)
        return keep("not_decisive", why, start_score, n_rej)
    return keep("kept", f"{name}: no candidate scores higher", start_score, n_rej)


def _scoring_pairs(visibility: dict) -> int:
    """Camera pairs ``(i, k)`` whose billboards of one of the bones are both used in some view."""
    pairs = set()
    for v in visibility.values():
        for row in np.asarray(v, bool):
            cams = np.flatnonzero(row)
            pairs.update(itertools.combinations(cams.tolist(), 2))
    return len(pairs)


def decisive_reason(scorer: PositionScorer, joints: np.ndarray, joint: int, position: np.ndarray,
                    visibility: dict, config: OptimizeConfig = OptimizeConfig()) -> str:
    """Why moving ``joint`` to ``position`` is not decisive, or ``""`` when it is.

    The joint score averages views and camera pairs, so a rise can come from one
    of them alone: one view that sees a billboard almost edge-on, or one camera
    whose part labels are off.  A move is decisive when independent evidence
    agrees: every evaluated view that scores the joint's bones rises by more than
    ``config.view_noise`` (the resampling noise) and at least ``config.min_pairs``
    camera pairs each raise the joint's score (:meth:`PositionScorer.move_evidence`).

    Parameters
    ----------
    scorer : PositionScorer
    joints : ndarray of shape (14, 3)
        Current pose, metres.
    joint : int
    position : ndarray of shape (3,)
        The best candidate, metres.
    visibility : dict of int to ndarray (n_views, n_cams) bool
        The views and billboards the search compared the candidates on.
    config : OptimizeConfig

    Returns
    -------
    str
        Empty when decisive; otherwise the reason, e.g. ``"rests on 1 of 3 camera pairs (2 needed)"``.
    """
    ev = scorer.move_evidence(joints, joint, position, visibility)
    g = ev.view_gain[np.isfinite(ev.view_gain)]
    weak = int(np.sum(g <= config.view_noise))
    if weak:
        return (f"is not confirmed by {weak} of {g.size} views (their gains {np.round(np.sort(g)[:weak], 3).tolist()}, "
                f"{config.view_noise} needed)")
    pairs = ev.pair_gain[np.isfinite(ev.pair_gain)]
    rising = int(np.sum(pairs > 0))
    if rising < config.min_pairs:
        return f"rests on {rising} of {pairs.size} camera pairs ({config.min_pairs} needed)"
    return ""


def optimize_pose(scorer: PositionScorer, joints: np.ndarray,
                  constraints: AnthropometricConstraints | None = None,
                  config: OptimizeConfig = OptimizeConfig(), *, joint_order=None,
                  observer: Observer | None = None, frame: int | None = None) -> PoseResult:
    """Sweep the joint grid search over the skeleton until the score converges.

    Parameters
    ----------
    scorer : PositionScorer
    joints : ndarray of shape (14, 3)
        Initial pose (stage 1 or template fit), metres.
    constraints : AnthropometricConstraints, optional
    config : OptimizeConfig
    joint_order : sequence of int, optional
        Joints to optimise in sweep order (default: all, skeleton order).
    observer : Observer, optional
        Receives, besides :func:`optimize_joint`'s reports, ``joints3d``
        (name ``"optimize/joints"``) after each sweep, ``series`` per joint
        (score per sweep, name ``"optimize/score/<joint>"``) and ``scalar`` totals.
    frame : int, optional

    Returns
    -------
    PoseResult
    """
    t0 = time.perf_counter()
    sk = scorer.skeleton
    J = np.array(joints, float)
    if J.shape != (sk.n_joints, 3) or not np.all(np.isfinite(J)):
        raise InputError("joints", f"finite joints of shape ({sk.n_joints}, 3)", f"shape {J.shape}, "
                         f"{int(np.sum(~np.isfinite(J)))} non-finite values")
    order = list(range(sk.n_joints)) if joint_order is None else [int(j) for j in joint_order]
    obs = as_observer(observer)
    n0 = scorer.n_evaluations
    anchors = J.copy()
    first = np.array([scorer.joint_score(J, j) for j in range(sk.n_joints)])
    rows = [first]
    steps = []
    converged = False
    n_sweeps = 0
    for sweep in range(config.max_sweeps):
        for j in order:
            st = optimize_joint(scorer, J, j, constraints, config, observer=observer, frame=frame,
                                anchor=anchors[j])
            J[j] = st.position
            steps.append(st)
        n_sweeps += 1
        row = np.array([scorer.joint_score(J, j) for j in range(sk.n_joints)])
        rows.append(row)
        obs.report("joints3d", name="optimize/joints", joints=J.copy(), skeleton=sk, frame=frame)
        gain = float(np.nansum(row[order]) - np.nansum(rows[-2][order]))
        obs.report("scalar", name="optimize/total_score", value=float(np.nansum(row)), frame=frame)
        if gain < config.min_improvement:
            converged = True
            break
    scores = np.array(rows)
    for j in range(sk.n_joints):
        obs.report("series", name=f"optimize/score/{sk.joint_names[j]}", values=scores[:, j],
                   steps=np.arange(len(rows)), frame=frame)
    return PoseResult(joints=J, scores=scores, n_evaluations=scorer.n_evaluations - n0, n_sweeps=n_sweeps,
                      converged=converged, steps=tuple(steps), seconds=time.perf_counter() - t0)
