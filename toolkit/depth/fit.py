"""Local and global minimisation of the fitting energy (source 001, step 230, figure 9).

**Local**: iterated closest primitives: the data are assigned to the nearest
primitive of the current skeleton, then the stacked residuals of
:mod:`toolkit.depth.energy` are minimised by Levenberg-Marquardt
(``scipy.optimize.least_squares``); this repeats ``outer_iterations`` times or
until the skeleton stops moving.

**Global**: once the local minimisation has converged, guided configuration
changes try to leave its local minimum: each *move* proposes another skeleton
from a known pose pattern (swap the arms or the legs, put an arm or a leg on an
unexplained extremity of the radial profile, let an unsupported arm hang,
start over from the initial-pose search, ...), which is then minimised locally
and kept if its energy is lower.  Every move keeps a record of how often it was
tried, how often it won and how much energy it saved; moves are tried in order
of the weight ``(wins + 1) / (tries + 2) * (1 + mean relative gain)`` and at
most ``max_moves`` per frame, so the moves that work for this user and this
scene are tried first.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from toolkit.depth.constraints import ConstraintConfig
from toolkit.depth.energy import (
    Assignment,
    EnergyConfig,
    EnergyTerms,
    FitData,
    Residuals,
    assign,
    unexplained_penalty,
)
from toolkit.body.control_points import N_POINTS, BodyDimensions
from toolkit.observe import as_observer

__all__ = ["FitConfig", "GlobalSearch", "LocalFit", "Move", "MoveRecord", "fit_local", "levenberg_marquardt"]


@dataclass(frozen=True)
class FitConfig:
    """Settings of the minimisation.

    Attributes
    ----------
    outer_iterations : int
        Assignment / Levenberg-Marquardt rounds.
    lm_max_evaluations : int
        Residual evaluations of the first Levenberg-Marquardt run ...
    lm_refine_evaluations : int
        ... and of the later ones (after the data are assigned again).
    init_outer_iterations, init_lm_max_evaluations : int
        The same for the fits of the initial-pose candidates (once per (re)start, so more).
    solver : {"lm", "scipy"}
        ``"scipy"``: ``scipy.optimize.least_squares(method="lm")`` (MINPACK);
        ``"lm"``: the same damped Gauss-Newton steps in a small loop here
        (:func:`levenberg_marquardt`), which evaluates the stacked residuals
        and their Jacobian together once per step and is several times faster
        per frame on this 39-parameter problem.
    converged_m : float
        Stop when no control point moved more than this in a round.
    max_moves : int
        Global moves tried per frame.
    move_trigger_explained : float
        Global moves are tried when less than this fraction of the user's bins is explained ...
    move_every : int
        ... or every this many frames.
    """

    outer_iterations: int = 2
    lm_max_evaluations: int = 4
    lm_refine_evaluations: int = 3
    init_outer_iterations: int = 2
    init_lm_max_evaluations: int = 4
    solver: str = "lm"
    converged_m: float = 0.003
    max_moves: int = 2
    move_trigger_explained: float = 0.97
    move_every: int = 10

    def __post_init__(self):
        from toolkit.errors import InputError

        if self.solver not in ("lm", "scipy"):
            raise InputError("FitConfig.solver", "'lm' or 'scipy'", repr(self.solver))


def levenberg_marquardt(residuals, x0: np.ndarray, max_evaluations: int, lam0: float = 1e-3,
                        xtol: float = 1e-4, ftol: float = 5e-3) -> tuple[np.ndarray, int]:
    """Minimise ``|r(x)|^2`` by Levenberg-Marquardt with Marquardt's diagonal scaling.

    Parameters
    ----------
    residuals : object
        With ``evaluate(x) -> (r (M,), J (M, N))``.
    x0 : ndarray of shape (N,)
    max_evaluations : int
        Residual evaluations (accepted or rejected steps).
    lam0 : float
        Initial damping.
    xtol : float
        Stop when no parameter moves more than this ...
    ftol : float
        ... or when an accepted step lowers the cost by less than this fraction.

    Returns
    -------
    x : ndarray of shape (N,)
    n_evaluations : int
    """
    x = np.array(x0, float)
    r, J = residuals.evaluate(x)
    cost = float(r @ r)
    lam = lam0
    n = 1
    while n < max_evaluations:
        A = J.T @ J
        g = J.T @ r
        d = np.maximum(np.diag(A), 1e-9)
        try:
            dx = -np.linalg.solve(A + lam * np.diag(d), g)
        except np.linalg.LinAlgError:
            break
        xn = x + dx
        rn, Jn = residuals.evaluate(xn)
        n += 1
        cn = float(rn @ rn)
        if cn < cost:
            small = cost - cn < ftol * cost
            x, r, J, cost = xn, rn, Jn, cn
            lam = max(lam / 4.0, 1e-9)
            if small or np.max(np.abs(dx)) < xtol:
                break
        else:
            lam *= 8.0
            if lam > 1e8:
                break
    return x, n


@dataclass(frozen=True)
class LocalFit:
    """Result of a local minimisation.

    Attributes
    ----------
    X : ndarray of shape (13, 3)
        View frame, metres.
    energy : EnergyTerms
        At ``X`` with the data re-assigned.
    history : list of dict
        Block energies after each round.
    n_evaluations : int
    """

    X: np.ndarray
    energy: EnergyTerms
    history: list = field(default_factory=list)
    n_evaluations: int = 0


def fit_local(X0: np.ndarray, data: FitData, dims: BodyDimensions, X_pred: np.ndarray, w_prev: np.ndarray,
              config: FitConfig = FitConfig(), energy: EnergyConfig = EnergyConfig(),
              constraints: ConstraintConfig = ConstraintConfig(), ground_y=None, observer=None,
              frame: int | None = None, tag: str = "local", first: Assignment | None = None) -> LocalFit:
    """Minimise the energy from ``X0`` by iterated assignment and Levenberg-Marquardt.

    Parameters
    ----------
    X0 : ndarray of shape (13, 3)
        Start skeleton, view frame.
    data : FitData
    dims : BodyDimensions
    X_pred : ndarray of shape (13, 3)
        Predicted skeleton of the previous-skeleton term.
    w_prev : ndarray of shape (13,)
        Per-point weights of that term.
    config, energy, constraints
    ground_y : float or None
    observer : Observer, optional
        Receives one ``depth_energy`` report per round (block energies).
    frame : int, optional
    tag : str
        Name of the minimisation in the reports.
    first : Assignment, optional
        The data assignment at ``X0`` if the caller has it already.

    Returns
    -------
    LocalFit
    """
    obs = as_observer(observer)
    X = np.array(X0, float)
    history = []
    nfev = 0
    for it in range(config.outer_iterations):
        a = first if (it == 0 and first is not None) else assign(data, X, dims, energy)
        res = Residuals(data, a, dims, X_pred, w_prev, energy, constraints, ground_y)
        if config.solver == "scipy":
            sol = least_squares(res.fun, X.ravel(), jac=res.jac, method="lm", xtol=1e-4, ftol=1e-4,
                                max_nfev=config.lm_max_evaluations if it == 0 else config.lm_refine_evaluations)
            x, k = sol.x, sol.nfev
        else:
            x, k = levenberg_marquardt(res, X.ravel(), config.lm_max_evaluations if it == 0
                                       else config.lm_refine_evaluations)
        nfev += k
        Xn = x.reshape(N_POINTS, 3)
        terms = res.block_energies(x)
        history.append(terms)
        if observer is not None:
            obs.report("depth_energy", frame=frame, stage=tag, iteration=it, total=float(sum(terms.values())),
                       blocks=dict(terms))
        moved = float(np.max(np.linalg.norm(Xn - X, axis=1)))
        X = Xn
        if moved < config.converged_m:
            break
    # the energy at the result: block energies of the last round, unexplained data re-assigned at X
    a = assign(data, X, dims, energy)
    terms = dict(history[-1]) if history else {}
    terms["unexplained"] = unexplained_penalty(data, a, energy)
    e = EnergyTerms(terms, float(sum(terms.values())), a.explained_fraction(), a)
    return LocalFit(X, e, history, nfev)


# ---------------------------------------------------------------- global
@dataclass
class MoveRecord:
    """How a guided configuration change has fared so far."""

    tries: int = 0
    wins: int = 0
    gain: float = 0.0        # summed relative energy gains of the wins
    seconds: float = 0.0

    @property
    def weight(self) -> float:
        """Success ratio times (1 + mean relative gain): moves with a higher weight go first."""
        mean_gain = self.gain / self.wins if self.wins else 0.0
        return (self.wins + 1.0) / (self.tries + 2.0) * (1.0 + mean_gain)


@dataclass(frozen=True)
class Move:
    """A guided configuration change: ``propose(X, context) -> list of candidate skeletons``."""

    name: str
    propose: Callable


class GlobalSearch:
    """Guided configuration changes weighted by their record of success.

    Parameters
    ----------
    moves : list of Move
    config : FitConfig
    """

    def __init__(self, moves: list, config: FitConfig = FitConfig()):
        self.moves = list(moves)
        self.config = config
        self.records = {m.name: MoveRecord() for m in self.moves}

    def ranked(self) -> list:
        """Moves by decreasing weight (ties keep the given order)."""
        return sorted(self.moves, key=lambda m: -self.records[m.name].weight)

    def run(self, best: LocalFit, context, fit: Callable, max_moves: int | None = None, observer=None,
            frame: int | None = None) -> tuple[LocalFit, str | None]:
        """Try up to ``max_moves`` moves from ``best``; return the lowest-energy fit and the winning move.

        Parameters
        ----------
        best : LocalFit
            The local minimum to leave.
        context : object
            Passed to each move's ``propose``.
        fit : callable
            ``fit(X0) -> LocalFit``, the local minimisation.
        """
        obs = as_observer(observer)
        winner = None
        n = self.config.max_moves if max_moves is None else max_moves
        tried = 0
        for m in self.ranked():
            if tried >= n:
                break
            t0 = time.perf_counter()
            cands = m.propose(best.X, context)
            if not cands:
                continue
            tried += 1
            rec = self.records[m.name]
            rec.tries += 1
            won = False
            for X0 in cands:
                f = fit(X0)
                if f.energy.total < best.energy.total * (1 - 1e-3):
                    gain = (best.energy.total - f.energy.total) / max(best.energy.total, 1e-9)
                    rec.gain += gain
                    best = f
                    won = True
            if won:
                rec.wins += 1
                winner = m.name
            rec.seconds += time.perf_counter() - t0
            if observer is not None:
                obs.report("depth_move", frame=frame, move=m.name, won=won, weight=rec.weight,
                           energy=float(best.energy.total))
        return best, winner
