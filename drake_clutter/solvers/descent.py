"""The descent loop both solvers run (`descend`): the Levenberg-Marquardt regulariser, the
trust region, the cost floor, the deadline and the stop rules of `ilqr`, over a problem that
supplies its model, its proposed step and its line search (`DescentProblem`: iLQR's knots,
`ilqr._Knots`, or the spline's control points, `spline._Points`).
"""

from __future__ import annotations

import time
from typing import Protocol

import numpy as np

from drake_clutter.solvers.problem import ILQRSettings, StopReason


def past(deadline: float | None, ahead: float = 0.0) -> bool:
    """True when ``deadline`` (a time.monotonic() value, s) is set and will have passed
    ``ahead`` seconds from now."""
    return deadline is not None and time.monotonic() + ahead >= deadline


class DescentProblem(Protocol):
    """What `descend` asks of a problem: its current objective (``total``, ``terms``), a local
    model about its current path, a step proposed for a regulariser and a trust region, and a
    line search along it that moves the path when it lowers the objective."""

    open_loop: bool  # whether a step is rolled out without feedback (the log's entry)
    total: float
    terms: dict

    def model(self) -> int:
        """Builds the local model about the current path; returns the non-finite derivative
        entries it zeroed."""

    def propose(self, mu: float, limit: np.ndarray | None) -> tuple[float, float] | None:
        """The model's step for regulariser ``mu`` within the trust region ``limit`` (None:
        none): its predicted decrease as (d1, d2) (first- and second-order parts, negative
        for a decrease), or None when the regularised model has no minimum."""

    def search(self, entry: dict, alpha0: float, model: tuple[float, float],
               limit: np.ndarray | None) -> bool:
        """Rolls out the proposed step from size ``alpha0`` down and moves to the first that
        lowers the objective enough, recording it in ``entry``; False when none does."""


def descend(problem: DescentProblem, settings: ILQRSettings, base: np.ndarray | None,
            history: list[float], term_history: list[dict], log: list[dict]
            ) -> tuple[StopReason, int]:
    """The regularised descent loop both solvers share (module docstring): per iteration one
    model, then steps proposed with the regulariser raised until a line search succeeds or a
    stop rule fires; the trust region's radius (a fraction of ``base``, the step limit)
    adapted; the deadline, the cost floor and the stop rules applied. Appends every accepted
    objective to ``history`` / ``term_history`` and every proposal to ``log``; returns the stop
    reason and the iterations taken."""
    mu, radius, alpha0 = settings.reg_init, 1.0, 1.0
    stop_reason, iteration = StopReason.MAX_ITERATIONS, 0
    last = 0.0  # the last iteration's wall time (s), the next one's forecast
    while iteration < settings.max_iterations:
        if past(settings.deadline, last):
            stop_reason = StopReason.TIME_BUDGET
            break
        iteration += 1
        begun = time.perf_counter()
        nonfinite = problem.model()
        accepted, failed = False, 0
        while (mu <= settings.reg_max and not past(settings.deadline)
               and (settings.max_failed_searches is None
                    or failed < settings.max_failed_searches)):
            limit = None if base is None else radius * base
            proposed = problem.propose(mu, limit)
            if proposed is None:
                mu = max(mu * settings.reg_factor, settings.reg_min)
                continue
            d1, d2 = proposed
            entry = {"mu": mu, "expected": -(d1 + d2), "alpha": 0.0, "actual": 0.0,
                     "predicted": 0.0, "radius": radius, "open_loop": problem.open_loop,
                     "tries": 0, "passes": 0, "nonfinite": nonfinite}
            log.append(entry)
            if -(d1 + d2) < settings.tolerance * max(abs(problem.total), 1e-12):
                break  # the model predicts no worthwhile decrease: a stationary point
            if (settings.cost_floor is not None
                    and -(d1 + d2) > problem.total - settings.cost_floor):
                mu = max(mu * settings.reg_factor, settings.reg_min)
                continue  # predicted below the floor: raise mu without a rollout
            if problem.search(entry, alpha0, (d1, d2), limit):
                accepted = True
                radius = adapted_radius(radius, entry, limit, settings)
                break
            if settings.trust_adapt and base is not None and radius > TRUST_MIN:
                # a smaller region before a larger mu; not counted as a failed search
                radius = max(radius / 4.0, TRUST_MIN)
                continue
            failed += 1
            mu = max(mu * settings.reg_factor, settings.reg_min)
        if not accepted:
            stop_reason = stop_without_step(mu, failed, settings)
            iteration -= 1
            break
        last = time.perf_counter() - begun
        if settings.adaptive_step:
            alpha0 = min(1.0, 2.0 * entry["alpha"])
        mu = max(mu / settings.reg_factor, settings.reg_min)
        improvement = (history[-1] - problem.total) / max(abs(history[-1]), 1e-12)
        history.append(problem.total)
        term_history.append(problem.terms)
        stop = stop_after_step(improvement, entry, history, settings)
        if stop is not None:
            stop_reason = stop
            break
    return stop_reason, iteration


def stop_after_step(improvement: float, entry: dict, history: list[float],
                    settings: ILQRSettings) -> StopReason | None:
    """The stop rules after an accepted step (tolerance, min_step, stall), or None."""
    if improvement < settings.tolerance:
        return StopReason.CONVERGED
    if entry["step"] < settings.min_step:
        return StopReason.SMALL_STEP
    if stalled(history, settings):
        return StopReason.STALLED
    return None


def stop_without_step(mu: float, failed: int, settings: ILQRSettings) -> StopReason:
    """Why the solver stops when an iteration accepted no step: the regulariser past
    reg_max, max_failed_searches failed line searches, the deadline, or else a model
    predicting no worthwhile decrease (converged)."""
    if past(settings.deadline):
        return StopReason.TIME_BUDGET
    if mu > settings.reg_max:
        return StopReason.REGULARIZATION_LIMIT
    if failed and failed == settings.max_failed_searches:
        return StopReason.LINE_SEARCH_FAILED
    return StopReason.CONVERGED


def stalled(history: list[float], settings: ILQRSettings) -> bool:
    """True when the last ``stall_iterations`` accepted steps each lowered the objective by
    less than ``stall_fraction`` of the decrease from history[0] to their own value."""
    n = settings.stall_iterations
    if settings.stall_fraction <= 0 or len(history) <= n:
        return False
    h = np.asarray(history, float)
    steps = h[-n - 1:-1] - h[-n:]
    return bool(np.all(steps < settings.stall_fraction * (h[0] - h[-n:])))


TRUST_MIN = 1.0 / 64.0  # the adaptive trust region's smallest radius (of step_limit)


def adapted_radius(radius: float, entry: dict, limit, settings: ILQRSettings) -> float:
    """The trust region's next radius after an accepted step (``trust_adapt``): doubled (up
    to 1) when the model was good (actual / predicted > 0.75) and the step reached the
    region's edge, quartered (down to TRUST_MIN) when it was poor (< 0.25)."""
    if not settings.trust_adapt or limit is None or entry["predicted"] <= 0.0:
        return radius
    ratio = entry["actual"] / entry["predicted"]
    if ratio < 0.25:
        return max(radius / 4.0, TRUST_MIN)
    if ratio > 0.75 and entry["step_ratio"] >= 0.99:
        return min(2.0 * radius, 1.0)
    return radius
