"""What the solvers share: the dynamics and cost protocols they see, the quadratic expansion a
cost returns, the settings, the stop reasons and the result (`ilqr`, `descent`, `spline`).

``xs`` has T + 1 rows (x_0 .. x_T) and ``us`` T rows (u_0 .. u_{T-1}); states may live on a
manifold, with ``difference(x_a, x_b) -> dx`` in tangent coordinates (see `ilqr`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import Protocol

import numpy as np


class Dynamics(Protocol):
    """Discrete-time dynamics x_{t+1} = f_t(x_t, u_t)."""

    def step(self, t: int, x: np.ndarray, u: np.ndarray) -> np.ndarray: ...

    def linearize(self, xs: np.ndarray, us: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass
class Expansion:
    """Second-order expansion of the objective about (xs, us).

    Running terms per knot t = 0..T-1: ``lx`` (T, nx), ``lu`` (T, nu), ``lxx`` (T, nx, nx),
    ``luu`` (T, nu, nu), ``lux`` (T, nu, nx); terminal terms at x_T: ``vx`` (nx,), ``vxx``
    (nx, nx). Costs that couple knots (velocities, accelerations) must be written over an
    augmented state that carries the previous controls.
    """

    lx: np.ndarray
    lu: np.ndarray
    lxx: np.ndarray
    luu: np.ndarray
    lux: np.ndarray
    vx: np.ndarray
    vxx: np.ndarray


class Cost(Protocol):
    """The objective: named weighted terms, and their quadratic expansion."""

    def terms(self, xs: np.ndarray, us: np.ndarray) -> dict[str, float]: ...

    def quadratize(self, xs: np.ndarray, us: np.ndarray) -> Expansion: ...


@dataclass(frozen=True)
class ILQRSettings:
    """Solver settings; the defaults follow Sec. V (30 iterations) where the paper sets one."""

    max_iterations: int = 30  # Sec. V: iLQR capped at 30 iterations
    tolerance: float = 1e-6  # relative objective decrease that counts as converged; ours
    reg_init: float = 1e-6  # initial Levenberg-Marquardt term on Q_uu; ours
    reg_min: float = 1e-9
    reg_max: float = 1e10
    reg_factor: float = 10.0
    line_search_steps: int = 10  # step sizes 1, 1/2, ..., 2^-9
    u_min: tuple | np.ndarray | None = None  # (nu,) for every knot, or (T, nu) per knot
    u_max: tuple | np.ndarray | None = None
    step_limit: tuple[float, ...] | None = None  # trust region: the largest change of each
    # control per knot in one forward pass (|u - u_bar| <= step_limit, feedback included)
    adaptive_step: bool = False  # start each line search at twice the last accepted step size
    # (capped at 1) instead of 1: with inexact derivatives the full step keeps failing and
    # every failed try is a rollout
    cost_floor: float | None = None  # a known lower bound of the objective (0 for sums of
    # non-negative terms): a backward pass predicting a decrease below it is not tried (no
    # rollout), mu is raised instead - the model cannot be trusted that far
    max_failed_searches: int | None = None  # stop ("line_search_failed") after this many
    # failed line searches in one iteration instead of raising mu up to reg_max (each failed
    # search is line_search_steps rollouts); None: no such limit
    open_loop_fallback: bool = False  # when the closed-loop line search fails, try the same
    # step sizes with K = 0 before raising the regulariser (for inexact A: K (x - x_bar)
    # amplifies its errors)
    feedback: bool = True  # the forward pass feeds back K (x - x_bar); False: open loop
    # (K = 0) always, for dynamics whose state deviations are chaotic
    feedback_mask: tuple[bool, ...] | None = None  # the (tangent) state coordinates the
    # forward pass feeds back (None: all); the result's K keeps every column
    min_step: float = 0.0  # stop ("small_step") after an accepted step that changed no
    # control by more than this (its largest |u - u_bar|); 0: no such rule
    box_qp: bool = False  # the backward pass solves each knot's box-constrained QP (bounds,
    # and the trust region when ``trust_bounds``) by projected Newton (Tassa et al. 2014)
    # instead of pinning only the controls already on a bound
    trust_bounds: bool = False  # the trust region is a bound of the backward pass's QP (the
    # predicted decrease then describes the step taken), not only a clip after the policy
    trust_adapt: bool = False  # the trust region's radius adapts to the accepted step's
    # actual / predicted decrease (x2 above 0.75 when the step reached the region's edge, x1/4
    # below 0.25), between 1/64 and 1 of step_limit; a failed line search quarters it and
    # counts as failed (raising mu, for max_failed_searches) only at the smallest radius
    accept_ratio: float = 0.0  # a step is accepted only if its actual decrease is at least
    # this fraction of the model's at its step size (0: any decrease)
    reg_scale: tuple[float, ...] | None = None  # per-control scale of the regulariser: mu
    # diag(reg_scale^2) on Q_uu (controls in mixed units: rad, m); None: mu I
    stall_fraction: float = 0.0  # stop ("stalled") after ``stall_iterations`` accepted steps
    # in a row each lowered the objective by less than this fraction of the decrease since
    # the start (the tail of a converging run buys little); 0: no such rule
    stall_iterations: int = 2
    deadline: float | None = None  # a time.monotonic() value (s): no iteration starts that


class StopReason(StrEnum):
    """Why iLQR stopped (the value is what plan files and stores hold)."""

    MAX_ITERATIONS = "max_iterations"  # the iteration cap
    CONVERGED = "converged"  # relative improvement, or the predicted decrease, under tolerance
    SMALL_STEP = "small_step"  # the accepted step moved the controls less than min_step
    STALLED = "stalled"  # stall_iterations steps in a row each bought < stall_fraction
    REGULARIZATION_LIMIT = "regularization_limit"  # mu passed reg_max without an accepted step
    LINE_SEARCH_FAILED = "line_search_failed"  # max_failed_searches line searches failed
    TIME_BUDGET = "time_budget"  # settings.deadline passed (the best path so far is kept)


@dataclass
class ILQRResult:
    """Everything the solver produced: trajectory, policy, history, why it stopped, timings."""

    xs: np.ndarray
    us: np.ndarray
    K: np.ndarray  # (T, nu, nx) feedback gains
    k: np.ndarray  # (T, nu) feed-forward terms of the last backward pass
    cost: float
    cost_history: list[float]  # objective after each accepted iteration (index 0: the start)
    term_history: list[dict[str, float]]  # per-term values, aligned with cost_history
    iterations: int
    stop_reason: StopReason
    timings: dict[str, float] = field(default_factory=dict)  # s, summed over iterations
    log: list[dict] = field(default_factory=list)  # one entry per backward pass: regulariser
    # mu, the model's predicted decrease at the full step ("expected"), the accepted step
    # size alpha (0: none), the actual decrease and the model's at alpha ("predicted", before
    # any trust-region clip), whether the step was open loop, forward passes tried, and
    # the non-finite derivative entries zeroed; "passes": forward passes run (more than
    # "tries" when a parallel batch ran step sizes after the accepted one)

    @property
    def converged(self) -> bool:
        """True when stopped by the tolerance rule."""
        return self.stop_reason == StopReason.CONVERGED


def rollout(dynamics: Dynamics, x0: np.ndarray, us: np.ndarray) -> np.ndarray:
    """States x_0..x_T of applying ``us`` from ``x0``."""
    xs = np.empty((len(us) + 1, len(x0)))
    xs[0] = x0
    for t, u in enumerate(us):
        xs[t + 1] = dynamics.step(t, xs[t], u)
    return xs


def per_knot_bounds(settings: ILQRSettings,
                    shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The bounds as (T, nu) arrays (a (nu,) bound repeated at every knot)."""
    lo = np.full(shape, -np.inf) if settings.u_min is None else np.asarray(settings.u_min, float)
    hi = np.full(shape, np.inf) if settings.u_max is None else np.asarray(settings.u_max, float)
    if lo.shape not in (shape, shape[1:]) or hi.shape not in (shape, shape[1:]):
        raise ValueError("u_min/u_max must have one entry per control (or a row per knot)")
    lo, hi = np.broadcast_to(lo, shape).copy(), np.broadcast_to(hi, shape).copy()
    if np.any(lo > hi):
        raise ValueError("u_min must not exceed u_max")
    return lo, hi


def subtract(x_a: np.ndarray, x_b: np.ndarray) -> np.ndarray:
    """x_a - x_b: the state difference of plain vector states."""
    return x_a - x_b


def zero_nonfinite(*arrays: np.ndarray) -> int:
    """Sets the non-finite entries of the derivative arrays to 0 in place (a failed
    finite-difference evaluation: no known effect), returning how many there were; without
    this a single NaN makes every Cholesky factorisation fail up to ``reg_max``."""
    count = 0
    for a in arrays:
        bad = ~np.isfinite(a)
        if bad.any():
            count += int(bad.sum())
            a[bad] = 0.0
    return count
