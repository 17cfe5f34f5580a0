"""Iterative LQR (Li and Todorov 2004; Sec. V of the paper) in pure NumPy.

The solver sees two small protocols and nothing of Drake:

* ``dynamics.step(t, x, u) -> x_next`` and ``dynamics.linearize(xs, us) -> (A, B)`` with
  ``A[t] = d x_{t+1} / d x_t`` (nx x nx) and ``B[t] = d x_{t+1} / d u_t`` (nx x nu), t = 0..T-1;
* ``cost.terms(xs, us) -> dict[name, float]`` (the weighted value of every term over the whole
  trajectory; their sum is the objective) and ``cost.quadratize(xs, us) -> Expansion``.

``xs`` has T + 1 rows (x_0 .. x_T) and ``us`` T rows (u_0 .. u_{T-1}).

Controls may be box-bounded (``u_min``/``u_max``: one bound per control, or one row per knot,
(T, nu), to pin a knot's control where lower and upper bound meet): the forward pass clamps
every control into the box, and the backward pass holds the controls that sit on a bound in
the nominal trajectory with their gradient pushing outwards (no step, no feedback) and solves
the free controls' block of Q_uu alone, so the linear policy does not fight the clamp - the
simple form of the control-limited iLQR of Tassa et al. (2014).

Manifold states: with ``difference(x_a, x_b) -> dx`` (x_a minus x_b in tangent coordinates,
e.g. rotation vectors for quaternion states) the linearisation and the expansion live in the
tangent space (A: ndx x ndx, B: ndx x nu, lx: ndx, ...), and the forward pass feeds back
K (x (-) x_bar); without it the states are plain vectors and x - x_bar is used.

Regularisation: Levenberg-Marquardt on Q_uu (``mu * I``), raised by ``reg_factor`` whenever Q_uu is
not positive definite or the line search fails, lowered after every accepted step. Line search: step
sizes 1, 1/2, 1/4, ... (with ``adaptive_step``: from twice the last accepted size); a step is
accepted only if it lowers the objective, so the cost never increases across accepted iterations.
For inexact derivatives (phi's finite differences in contact) two safeguards are optional: a trust
region on the controls (``step_limit``: no control changes by more than its limit per forward pass,
feedback included) and an open-loop retry of the line search (``open_loop_fallback``: K = 0, so
errors in A are not fed back), and ``cost_floor``: a model that predicts a decrease below a known
lower bound of the objective is rejected without a rollout (mu is raised). Options that make the
model describe the step taken: ``box_qp`` (each knot's step minimises the model within the bounds,
`box_qp_solve`), ``trust_bounds`` (the trust region is a bound of that QP, not only a clip after the
policy), ``trust_adapt`` (its radius follows the accepted steps' actual / predicted decrease),
``accept_ratio`` (a ratio test), ``reg_scale`` (mu diag(s^2) for controls in mixed units) and
``feedback_mask`` (feed back only some state coordinates). ``ILQRResult.log`` records every backward
pass: regulariser, predicted and actual decrease, step size. Stop rules: the iteration cap, a
relative decrease below ``tolerance``, the regulariser exceeding ``reg_max``,
``max_failed_searches`` failed line searches in one iteration, or an accepted step that moved no
control by ``min_step`` or more (on a chaotic rollout, a decrease from a step that small is noise to
exploit, not progress). The loop that applies all of these is `descent.descend`, shared with the
spline solver (`spline.solve_spline`): a problem supplies the model, the proposed step and the line
search.

Parallel line search: dynamics that can run several forward passes at once (elsewhere: worker
processes) say how many with ``parallel_passes`` (an int, > 1) and run them in
``forward_passes(xs, us, k, K, alphas, lo, hi, limit)``, a list of (xs, us) per step size with
their own state difference; the line search then rolls out that many step sizes per batch and
still accepts the first (largest) that lowers the objective, so the result is the serial one.
"""

from __future__ import annotations

import time

import numpy as np

from drake_clutter.solvers.descent import descend, past
from drake_clutter.solvers.problem import (
    Cost,
    Dynamics,
    Expansion,
    ILQRResult,
    ILQRSettings,
    StopReason,
    per_knot_bounds,
    rollout,
    subtract,
    zero_nonfinite,
)

# The solver's face: its types (`problem`) are importable from here too.
__all__ = ["Cost", "Dynamics", "Expansion", "ILQRResult", "ILQRSettings", "StopReason", "past",
           "per_knot_bounds", "rollout", "subtract", "zero_nonfinite", "solve", "backward_pass",
           "forward_pass", "box_qp_solve", "nearest_psd", "forward_passes_of"]



    # the last one's duration says would end past it, no line search once it has passed
    # ("time_budget"); the result is the best path so far



def backward_pass(A, B, exp: Expansion, mu: float, us: np.ndarray | None = None,
                  lo: np.ndarray | None = None, hi: np.ndarray | None = None,
                  box_qp: bool = False, reg_scale: np.ndarray | None = None):
    """Riccati-like recursion. Returns (k, K, expected decrease terms (d1, d2)) or None when
    Q_uu + mu I is not positive definite at some knot. ``lo``/``hi``: (nu,) or (T, nu); a
    control whose bounds meet is pinned (no step, no feedback). Without ``box_qp`` the controls
    sitting on a bound with the gradient pushing outwards are held and the rest solve their
    block; with it each knot's step is the minimiser of the model within the bounds
    (`box_qp`), the controls it clamps held. ``reg_scale`` (nu,): the regulariser is mu
    diag(reg_scale^2) (controls in mixed units), default mu I."""
    T, nu, nx = exp.lu.shape[0], exp.lu.shape[1], exp.lx.shape[1]
    if us is not None:
        lo, hi = np.broadcast_to(lo, (T, nu)), np.broadcast_to(hi, (T, nu))
    reg = mu * (np.ones(nu) if reg_scale is None else np.asarray(reg_scale, float) ** 2)
    k, K = np.zeros((T, nu)), np.zeros((T, nu, nx))
    vx, vxx = exp.vx.copy(), exp.vxx.copy()
    d1 = d2 = 0.0
    for t in range(T - 1, -1, -1):
        At, Bt = A[t], B[t]
        qx = exp.lx[t] + At.T @ vx
        qu = exp.lu[t] + Bt.T @ vx
        qxx = exp.lxx[t] + At.T @ vxx @ At
        quu = exp.luu[t] + Bt.T @ vxx @ Bt
        qux = exp.lux[t] + Bt.T @ vxx @ At
        H = quu + np.diag(reg)
        kt, Kt = np.zeros(nu), np.zeros((nu, nx))
        if us is not None and box_qp:
            solved = box_qp_solve(H, qu, lo[t] - us[t], hi[t] - us[t])
            if solved is None:
                return None
            kt, free = solved
        else:
            free = np.ones(nu, dtype=bool)
            if us is not None:  # controls pinned on a bound with the gradient pushing outwards
                free = ~_held(us[t], qu, lo[t], hi[t])
        # Held controls stay put (k = 0, K = 0); the free ones solve their own block, so the
        # step is the minimiser of the model over the free controls (the predicted decrease is
        # then never negative; zeroing rows of the full solution could make it so).
        if free.any():
            try:
                chol = np.linalg.cholesky(H[np.ix_(free, free)])
            except np.linalg.LinAlgError:
                return None
            if not (us is not None and box_qp):
                kt[free] = -_chol_solve(chol, qu[free])
            Kt[free] = -_chol_solve(chol, qux[free])
        k[t], K[t] = kt, Kt
        d1 += kt @ qu
        d2 += 0.5 * kt @ quu @ kt
        vx = qx + Kt.T @ quu @ kt + Kt.T @ qu + qux.T @ kt
        vxx = nearest_psd(qxx + Kt.T @ quu @ Kt + Kt.T @ qux + qux.T @ Kt)
    return k, K, (d1, d2)


def box_qp_solve(H: np.ndarray, g: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                 iterations: int = 30) -> tuple[np.ndarray, np.ndarray] | None:
    """min 1/2 x'Hx + g'x subject to lower <= x <= upper (lower <= 0 <= upper expected; a
    bound pair that meets holds its x there) by projected Newton from x = 0, as in Tassa et
    al. (2014): the free set's Newton step, an Armijo search along its projection, until the
    clamped set and x settle. Returns (x, free) with free the entries not clamped, or None
    when H's free block is not positive definite."""
    n = len(g)
    lower, upper = np.minimum(lower, 0.0), np.maximum(upper, 0.0)
    x = np.zeros(n)
    value = 0.0
    free = np.ones(n, dtype=bool)
    for _ in range(iterations):
        grad = g + H @ x
        clamped = _held(x, grad, lower, upper)
        free = ~clamped
        if not free.any():
            break
        try:
            chol = np.linalg.cholesky(H[np.ix_(free, free)])
        except np.linalg.LinAlgError:
            return None
        target = x.copy()
        target[free] = -_chol_solve(chol, g[free] + H[np.ix_(free, clamped)] @ x[clamped])
        direction = target - x
        if np.max(np.abs(direction), initial=0.0) < 1e-13:
            break
        step, accepted = 1.0, False
        while step > 1e-8:
            trial = np.clip(x + step * direction, lower, upper)
            trial_value = 0.5 * trial @ H @ trial + g @ trial
            if trial_value <= value + 0.1 * grad @ (trial - x):
                accepted = True
                break
            step *= 0.5
        if not accepted:
            break
        moved = np.max(np.abs(trial - x))
        x, value = trial, trial_value
        if moved < 1e-12:
            break
    return x, ~_held(x, g + H @ x, lower, upper)


def _held(x: np.ndarray, grad: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The entries of x held on a bound: at it with the gradient pushing outwards, or with
    bounds that meet."""
    return ((x <= lower) & (grad > 0)) | ((x >= upper) & (grad < 0)) | (lower >= upper)


def nearest_psd(M: np.ndarray) -> np.ndarray:
    """The nearest symmetric positive semi-definite matrix (negative eigenvalues set to 0).

    With positive semi-definite cost Hessians V_xx is too in exact arithmetic without
    regularisation; the LM term (K from Q_uu + mu I) and large, inexact A (phi's finite
    differences, entries up to 1e3) make it indefinite, and Q_uu then stayed indefinite up to
    mu = 1e10 on fig6 and fig7 (measured)."""
    M = 0.5 * (M + M.T)
    w, V = np.linalg.eigh(M)
    if w.min() >= 0.0:
        return M
    return (V * np.maximum(w, 0.0)) @ V.T


def _chol_solve(chol: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    y = np.linalg.solve(chol, rhs)
    return np.linalg.solve(chol.T, y)



def forward_pass(dynamics: Dynamics, xs, us, k, K, alpha: float, lo, hi, difference=None,
                 limit: np.ndarray | None = None):
    """New (xs, us) from the policy u = clamp(u_bar + alpha k + K (x (-) x_bar)); ``difference``
    is the state difference (default: plain subtraction); ``limit`` (nu,) bounds each control's
    change |u - u_bar| (None: unbounded); ``lo``/``hi`` (nu,) or (T, nu)."""
    difference = difference or subtract
    lo, hi = np.broadcast_to(lo, us.shape), np.broadcast_to(hi, us.shape)
    new_xs = np.empty_like(xs)
    new_us = np.empty_like(us)
    new_xs[0] = xs[0]
    for t in range(len(us)):
        if not np.all(np.isfinite(new_xs[t])):  # the dynamics failed: the step is rejected
            new_xs[t:] = np.nan
            new_us[t:] = us[t:]
            break
        du = alpha * k[t] + K[t] @ difference(new_xs[t], xs[t])
        if limit is not None:
            du = np.clip(du, -limit, limit)
        new_us[t] = np.clip(us[t] + du, lo[t], hi[t])
        if not np.all(np.isfinite(new_us[t])):  # an overflowing policy: the step is rejected
            new_xs[t + 1:] = np.nan
            new_us[t:] = us[t:]
            break
        new_xs[t + 1] = dynamics.step(t, new_xs[t], new_us[t])
    return new_xs, new_us


def solve(dynamics: Dynamics, cost: Cost, x0: np.ndarray, us_init: np.ndarray,
          settings: ILQRSettings | None = None, difference=None) -> ILQRResult:
    """Runs iLQR from the control sequence ``us_init`` (clamped into the bounds);
    ``difference`` as in the module docstring (None: plain vector states)."""
    settings = settings or ILQRSettings()
    problem = _Knots(dynamics, cost, x0, us_init, settings, difference)
    base = None if settings.step_limit is None else np.asarray(settings.step_limit, float)
    history, term_history, log = [problem.total], [problem.terms], []
    stop_reason, iteration = descend(problem, settings, base, history, term_history, log)
    return ILQRResult(xs=problem.xs, us=problem.us, K=problem.K, k=problem.k,
                      cost=problem.total, cost_history=history, term_history=term_history,
                      iterations=iteration, stop_reason=stop_reason, timings=problem.timings,
                      log=log)



class _Knots:
    """iLQR's problem for `descend`: one control per knot, a backward pass per proposal
    (feedback gains K and feed-forward k), the line search of `_line_search`."""

    open_loop = False

    def __init__(self, dynamics, cost, x0, us_init, settings: ILQRSettings, difference):
        self.dynamics, self.cost, self.settings, self.difference = (dynamics, cost, settings,
                                                                    difference)
        us = np.array(us_init, dtype=float)
        self.lo, self.hi = per_knot_bounds(settings, us.shape)
        self.reg_scale = (None if settings.reg_scale is None
                          else np.asarray(settings.reg_scale, float))
        us = np.clip(us, self.lo, self.hi)
        if not np.all(np.isfinite(us)):
            raise ValueError("the initial controls are not all finite")
        self.timings = {"rollout": 0.0, "linearize": 0.0, "quadratize": 0.0, "backward": 0.0,
                        "forward": 0.0}
        tic = time.perf_counter()
        self.xs = rollout(dynamics, np.asarray(x0, dtype=float), us)
        self.timings["rollout"] += time.perf_counter() - tic
        self.us = us
        self.terms = cost.terms(self.xs, us)
        self.total = float(sum(self.terms.values()))
        ndx = self.xs.shape[1] if difference is None else len(difference(self.xs[0],
                                                                          self.xs[0]))
        self.K = np.zeros((len(us), us.shape[1], ndx))
        self.k = np.zeros_like(us)

    def model(self) -> int:
        """A and B (``dynamics.linearize``) and the cost's expansion about the path."""
        tic = time.perf_counter()
        self.A, self.B = self.dynamics.linearize(self.xs, self.us)
        self.timings["linearize"] += time.perf_counter() - tic
        tic = time.perf_counter()
        self.exp = self.cost.quadratize(self.xs, self.us)
        self.timings["quadratize"] += time.perf_counter() - tic
        return zero_nonfinite(self.A, self.B, *vars(self.exp).values())

    def propose(self, mu: float, limit):
        """The backward pass's policy (k, K kept) and its predicted decrease."""
        settings = self.settings
        qp_lo, qp_hi = self.lo, self.hi
        if limit is not None and settings.trust_bounds:
            qp_lo = np.maximum(self.lo, self.us - limit)
            qp_hi = np.minimum(self.hi, self.us + limit)
        tic = time.perf_counter()
        bp = backward_pass(self.A, self.B, self.exp, mu, self.us, qp_lo, qp_hi,
                           settings.box_qp, self.reg_scale)
        self.timings["backward"] += time.perf_counter() - tic
        if bp is None:
            return None
        self.k, self.K, decrease = bp
        return decrease

    def search(self, entry: dict, alpha0: float, model, limit) -> bool:
        """`_line_search` along the policy; moves the path to the step it accepts."""
        tic = time.perf_counter()
        step = _line_search(self.dynamics, self.cost, self.xs, self.us, self.k, self.K,
                            self.total, self.lo, self.hi, self.settings, self.difference,
                            limit, entry, alpha0, model)
        self.timings["forward"] += time.perf_counter() - tic
        if step is None:
            return False
        self.xs, self.us, self.terms, self.total = step
        return True



def _line_search(dynamics, cost, xs, us, k, K, total, lo, hi, settings, difference=None,
                 limit=None, entry=None, alpha0: float = 1.0, model=(0.0, 0.0)):
    """First step size alpha0, alpha0/2, ... that lowers the objective (by at least
    ``accept_ratio`` of the model's decrease at that size, -(alpha d1 + alpha^2 d2) from
    ``model`` = (d1, d2)), closed loop, then (with ``open_loop_fallback``) open loop: (xs,
    us, terms, total) or None. ``entry`` (a log dict) receives the accepted alpha, the actual
    and predicted decrease, the largest control change (also as a fraction of ``limit``) and
    the forward passes tried."""
    entry = entry if entry is not None else {}
    if settings.feedback_mask is not None:  # feed back only the chosen state coordinates
        K = K * np.asarray(settings.feedback_mask, dtype=float)[None, None, :]
    gains = [K, np.zeros_like(K)] if settings.open_loop_fallback else [K]
    if not settings.feedback:
        gains = [np.zeros_like(K)]
    batch = max(1, int(getattr(dynamics, "parallel_passes", 1)))
    for gain in gains:
        alphas = [alpha0 * 0.5 ** i for i in range(settings.line_search_steps)]
        for start in range(0, len(alphas), batch):
            if entry.get("tries") and past(settings.deadline):
                return None
            chunk = alphas[start:start + batch]
            passes = forward_passes_of(dynamics, xs, us, k, gain, chunk, lo, hi, difference,
                                     limit)
            entry["passes"] = entry.get("passes", 0) + len(chunk)
            for alpha, (new_xs, new_us) in zip(chunk, passes, strict=True):
                entry["tries"] = entry.get("tries", 0) + 1
                if not np.all(np.isfinite(new_xs)):
                    continue
                terms = cost.terms(new_xs, new_us)
                new_total = float(sum(terms.values()))
                predicted = -(alpha * model[0] + alpha ** 2 * model[1])
                if new_total < total and total - new_total >= settings.accept_ratio * predicted:
                    change = np.abs(new_us - us)
                    entry.update(alpha=alpha, actual=total - new_total, predicted=predicted,
                                 open_loop=gain is not K,
                                 step=float(np.max(change, initial=0.0)),
                                 step_ratio=(0.0 if limit is None else
                                             float(np.max(change / limit, initial=0.0))))
                    return new_xs, new_us, terms, new_total
    return None


def forward_passes_of(dynamics, xs, us, k, K, alphas, lo, hi, difference, limit) -> list:
    """(xs, us) of the forward passes at ``alphas``: at once through the dynamics'
    ``forward_passes`` when it has more than one to run, else one after another."""
    if len(alphas) > 1 and hasattr(dynamics, "forward_passes"):
        return dynamics.forward_passes(xs, us, k, K, alphas, lo, hi, limit)
    return [forward_pass(dynamics, xs, us, k, K, a, lo, hi, difference, limit) for a in alphas]
