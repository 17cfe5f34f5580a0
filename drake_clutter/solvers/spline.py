"""Gauss-Newton shooting over B-spline control points: smooth controls for iLQR's problems.

iLQR (`ilqr`) optimises one control per knot, so nothing but the costs couples neighbouring
knots and a step may put a kink anywhere. Here the controls are samples of a B-spline,
u_t = basis[t + 1, 0] c_0 + sum_j basis[t + 1, j] c_j (t = 0..T-1), whose first control point
c_0 is fixed (the start; a clamped basis samples it at knot 0) and whose others, P of them
(nu numbers each), are the unknowns: the plan stays a spline, smooth by construction, as the
baseline's is (Sec. IV).

One iteration takes the same derivatives as iLQR (``dynamics.linearize``: A_t, B_t, in tangent
coordinates with ``difference``; ``cost.quadratize``), carries the states' sensitivities to the
control points forward (S_{t+1} = A_t S_t + B_t G_t, G_t = du_t / dc) and forms the objective's
gradient and Gauss-Newton Hessian in the P nu control-point numbers. The step minimises that
model plus mu diag(reg_scale^2) within the control points' bounds and the trust region
(`ilqr.box_qp_solve`); step sizes 1, 1/2, ... are rolled out open loop and the first that
lowers the objective (by ``accept_ratio`` of the model's decrease) is taken. The regulariser,
the trust region's adaptation, the cost floor and the stop rules are iLQR's, run by the same
loop (`ilqr.descend`; `ILQRSettings`;
``feedback``, ``feedback_mask``, ``open_loop_fallback``, ``box_qp`` and ``trust_bounds`` do not
apply: every step is open loop and box-constrained).

Bounds: a B-spline knot is a convex combination of the control points it sees (a clamped
basis is non-negative and sums to 1), so the per-knot bounds (T, nu) hold at every knot when
each control point lies within the tightest bounds of the knots it touches; the clamped basis
samples the last control point alone at the last knot, so a pinned last knot pins it exactly.
"""

from __future__ import annotations

import time

import numpy as np

from drake_clutter.solvers.descent import descend, past
from drake_clutter.solvers.ilqr import box_qp_solve, forward_passes_of, nearest_psd
from drake_clutter.solvers.problem import (
    Cost,
    Dynamics,
    ILQRResult,
    ILQRSettings,
    per_knot_bounds,
    rollout,
    subtract,
    zero_nonfinite,
)

SUPPORT = 1e-12  # basis values at or below this do not tie a knot to a control point


class SplineControls:
    """The map from the free control points C (P, nu) to the controls u (T, nu) of a knot path
    whose knot 0 is ``q0``: u = basis[1:, 0] q0 + basis[1:, 1:] C (``basis`` (T + 1, P + 1))."""

    def __init__(self, basis: np.ndarray, q0: np.ndarray):
        basis = np.asarray(basis, float)
        if basis.ndim != 2 or basis.shape[1] < 2:
            raise ValueError("the basis must be (knots, control points) with 2 or more points")
        self.M = basis[1:, 1:]
        self.offset = np.outer(basis[1:, 0], np.asarray(q0, float))

    def controls(self, C: np.ndarray) -> np.ndarray:
        """u (T, nu) of the control points C (P, nu)."""
        return self.offset + self.M @ C

    def fit(self, us: np.ndarray) -> np.ndarray:
        """The control points C (P, nu) whose controls are nearest ``us`` (least squares)."""
        return np.linalg.lstsq(self.M, np.asarray(us, float) - self.offset, rcond=None)[0]

    def point_bounds(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(P, nu) bounds of the control points under which every knot keeps its (T, nu)
        bounds: each point within the tightest bounds of the knots it touches (ValueError
        where those bounds do not meet, e.g. neighbouring knots pinned to different values)."""
        P, nu = self.M.shape[1], lo.shape[1]
        lo_c, hi_c = np.full((P, nu), -np.inf), np.full((P, nu), np.inf)
        for j in range(P):
            touched = self.M[:, j] > SUPPORT
            if touched.any():
                lo_c[j] = lo[touched].max(axis=0)
                hi_c[j] = hi[touched].min(axis=0)
        if np.any(lo_c > hi_c):
            raise ValueError("the per-knot bounds leave no control point a feasible value")
        return lo_c, hi_c


def sensitivities(A: np.ndarray, B: np.ndarray, M: np.ndarray) -> np.ndarray:
    """S (T + 1, ndx, P nu): the tangent states' derivatives by the control points, stacked
    point by point (vec of C (P, nu) row-major), from A (T, ndx, ndx), B (T, ndx, nu) and the
    basis rows M (T, P) of the controls."""
    T, ndx, nu = B.shape
    P = M.shape[1]
    S = np.zeros((T + 1, ndx, P * nu))
    for t in range(T):
        S[t + 1] = A[t] @ S[t] + np.kron(M[t], B[t])  # B_t G_t, G_t = kron(M[t], I_nu)
    return S


def gauss_newton_model(S: np.ndarray, M: np.ndarray, exp) -> tuple[np.ndarray, np.ndarray]:
    """Gradient g (P nu) and Gauss-Newton Hessian H (P nu, P nu, positive semi-definite) of
    the objective in the control points, from the sensitivities ``S`` (`sensitivities`), the
    basis rows ``M`` (T, P) and the cost's `ilqr.Expansion` about the same path."""
    T, nu = exp.lu.shape
    n = S.shape[2]
    g, H = S[T].T @ exp.vx, S[T].T @ exp.vxx @ S[T]
    for t in range(T):
        G = np.kron(M[t], np.eye(nu))  # (nu, P nu)
        St = S[t]
        g = g + St.T @ exp.lx[t] + G.T @ exp.lu[t]
        cross = G.T @ exp.lux[t] @ St
        H = H + St.T @ exp.lxx[t] @ St + G.T @ exp.luu[t] @ G + cross + cross.T
    return g, nearest_psd(H.reshape(n, n))


def solve_spline(dynamics: Dynamics, cost: Cost, x0: np.ndarray, us_init: np.ndarray,
                 basis: np.ndarray, q0: np.ndarray, settings: ILQRSettings | None = None,
                 difference=None) -> ILQRResult:
    """Runs the Gauss-Newton shooting of the module docstring from the control points nearest
    ``us_init`` (T, nu; least squares, clamped into the points' bounds). ``basis`` (T + 1,
    P + 1): the B-spline's values at the knots; ``q0`` (nu,): the fixed first control point
    (knot 0's control values). The result's ``K`` is zero (open loop) and ``k`` the last
    step's change of the controls."""
    settings = settings or ILQRSettings()
    spline = SplineControls(basis, q0)
    T, nu = np.shape(us_init)
    if spline.M.shape[0] != T:
        raise ValueError(f"the basis has {spline.M.shape[0] + 1} knots, the controls {T + 1}")
    lo, hi = per_knot_bounds(settings, (T, nu))
    lo_c, hi_c = spline.point_bounds(lo, hi)
    C = np.clip(spline.fit(us_init), lo_c, hi_c)
    if not np.all(np.isfinite(C)):
        raise ValueError("the initial controls are not all finite")
    state = _State(dynamics, cost, x0, spline, C, difference)
    return _iterate(state, settings, lo_c, hi_c)


class _State:
    """The current control points, controls, states and objective of a `solve_spline` run."""

    def __init__(self, dynamics, cost, x0, spline: SplineControls, C, difference):
        self.dynamics, self.cost, self.spline, self.C = dynamics, cost, spline, C
        self.difference = difference or subtract
        self.timings = {"rollout": 0.0, "linearize": 0.0, "quadratize": 0.0, "backward": 0.0,
                        "forward": 0.0}
        tic = time.perf_counter()
        self.us = spline.controls(C)
        self.xs = rollout(dynamics, np.asarray(x0, float), self.us)
        self.timings["rollout"] += time.perf_counter() - tic
        self.terms = cost.terms(self.xs, self.us)
        self.total = float(sum(self.terms.values()))
        self.ndx = len(self.difference(self.xs[0], self.xs[0]))

    def model(self) -> tuple[np.ndarray, np.ndarray, int]:
        """(g, H, non-finite derivative entries zeroed) about the current path."""
        tic = time.perf_counter()
        A, B = self.dynamics.linearize(self.xs, self.us)
        self.timings["linearize"] += time.perf_counter() - tic
        tic = time.perf_counter()
        exp = self.cost.quadratize(self.xs, self.us)
        self.timings["quadratize"] += time.perf_counter() - tic
        nonfinite = zero_nonfinite(A, B, *vars(exp).values())
        tic = time.perf_counter()
        g, H = gauss_newton_model(sensitivities(A, B, self.spline.M), self.spline.M, exp)
        self.timings["backward"] += time.perf_counter() - tic
        return g, H, nonfinite


class _Points:
    """The control points' problem for `ilqr.descend`: the Gauss-Newton model in the points,
    a box-constrained step per proposal (`ilqr.box_qp_solve`), the open-loop line search of
    `_line_search`."""

    open_loop = True

    def __init__(self, s: _State, settings: ILQRSettings, lo_c, hi_c):
        self.s, self.settings, self.lo_c, self.hi_c = s, settings, lo_c, hi_c
        P, nu = s.C.shape
        scale = (np.ones(nu) if settings.reg_scale is None
                 else np.asarray(settings.reg_scale, float) ** 2)
        self.reg = np.tile(scale, P)
        self.du = np.zeros_like(s.us)

    @property
    def total(self) -> float:
        return self.s.total

    @property
    def terms(self) -> dict:
        return self.s.terms

    def model(self) -> int:
        """g and H about the current path (`_State.model`)."""
        self.g, self.H, nonfinite = self.s.model()
        return nonfinite

    def propose(self, mu: float, limit):
        """The points' step minimising the regularised model within their bounds and the
        trust region (``limit`` per control, the same for every point)."""
        s = self.s
        P, nu = s.C.shape
        lower, upper = (self.lo_c - s.C).ravel(), (self.hi_c - s.C).ravel()
        if limit is not None:
            trust = np.tile(limit, P)
            lower, upper = np.maximum(lower, -trust), np.minimum(upper, trust)
        tic = time.perf_counter()
        solved = box_qp_solve(self.H + np.diag(mu * self.reg), self.g, lower, upper)
        s.timings["backward"] += time.perf_counter() - tic
        if solved is None:
            return None
        dC = solved[0]
        self.dC = dC.reshape(P, nu)
        return float(self.g @ dC), float(0.5 * dC @ self.H @ dC)

    def search(self, entry: dict, alpha0: float, model, limit) -> bool:
        """`_line_search` along the proposed step; the accepted change of the controls kept."""
        if not _line_search(self.s, self.dC, self.settings, entry, alpha0, model, limit):
            return False
        self.du = entry.pop("du")
        return True


def _iterate(s: _State, settings: ILQRSettings, lo_c, hi_c) -> ILQRResult:
    problem = _Points(s, settings, lo_c, hi_c)
    base = None if settings.step_limit is None else np.asarray(settings.step_limit, float)
    history, term_history, log = [s.total], [s.terms], []
    stop_reason, iteration = descend(problem, settings, base, history, term_history, log)
    return ILQRResult(xs=s.xs, us=s.us, K=np.zeros((len(s.us), s.us.shape[1], s.ndx)),
                      k=problem.du, cost=s.total, cost_history=history,
                      term_history=term_history, iterations=iteration,
                      stop_reason=stop_reason, timings=s.timings, log=log)


def _line_search(s: _State, dC: np.ndarray, settings: ILQRSettings, entry: dict,
                 alpha0: float, model: tuple[float, float], limit) -> bool:
    """Rolls out C + alpha dC for alpha = alpha0, alpha0 / 2, ... (in batches where the
    dynamics run several forward passes at once) and moves ``s`` to the first that lowers the
    objective enough (as `ilqr`'s line search); False when none does."""
    k = s.spline.M @ dC  # the controls' change at alpha = 1 (the map is linear)
    K = np.zeros((len(s.us), s.us.shape[1], s.ndx))
    batch = max(1, int(getattr(s.dynamics, "parallel_passes", 1)))
    alphas = [alpha0 * 0.5 ** i for i in range(settings.line_search_steps)]
    free = np.full(s.us.shape, -np.inf), np.full(s.us.shape, np.inf)
    for start in range(0, len(alphas), batch):
        if start and past(settings.deadline):
            return False
        chunk = alphas[start:start + batch]
        tic = time.perf_counter()
        passes = forward_passes_of(s.dynamics, s.xs, s.us, k, K, chunk, *free, s.difference,
                                   None)
        s.timings["forward"] += time.perf_counter() - tic
        entry["passes"] += len(chunk)
        for alpha, (xs, us) in zip(chunk, passes, strict=True):
            entry["tries"] += 1
            if not np.all(np.isfinite(xs)):
                continue
            terms = s.cost.terms(xs, us)
            total = float(sum(terms.values()))
            predicted = -(alpha * model[0] + alpha ** 2 * model[1])
            if total < s.total and s.total - total >= settings.accept_ratio * predicted:
                step = alpha * dC
                entry.update(alpha=alpha, actual=s.total - total, predicted=predicted,
                             step=float(np.max(np.abs(us - s.us), initial=0.0)),
                             step_ratio=(0.0 if limit is None else
                                         float(np.max(np.abs(step) / limit, initial=0.0))),
                             du=us - s.us)
                s.C, s.us, s.xs, s.terms, s.total = s.C + step, us, xs, terms, total
                return True
    return False
