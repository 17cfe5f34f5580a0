"""iLQR against known answers: LQR (batch least squares), monotone cost, control bounds."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.solvers.ilqr import (
    Expansion,
    ILQRSettings,
    box_qp_solve,
    rollout,
    solve,
    zero_nonfinite,
)
from drake_clutter.testing.control_problems import (
    LinearDynamics,
    Pendulum,
    QuadraticCost,
    SwingUpCost,
    lqr_problem,
    stacked_lqr,
)


def _batch_lqr(A, B, Q, R, Qf, x0, T):
    """Optimal controls by stacking x = Sx x0 + Su U and solving the normal equations."""
    nu = B.shape[1]
    Sx, Su, Qbar, Rbar = stacked_lqr(A, B, Q, R, Qf, T)
    H = Su.T @ Qbar @ Su + Rbar
    g = Su.T @ Qbar @ Sx @ x0
    return np.linalg.solve(H, -g).reshape(T, nu)


def test_lqr_is_solved_in_one_iteration_and_matches_batch_solution():
    A, B, Q, R, Qf, x0, T = lqr_problem()
    settings = ILQRSettings(reg_init=0.0, reg_min=0.0)
    result = solve(LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)), settings)
    expected = _batch_lqr(A, B, Q, R, Qf, x0, T)
    np.testing.assert_allclose(result.us, expected, rtol=1e-8, atol=1e-10)
    assert result.iterations == 1 and result.converged
    # The feedback policy reproduces the optimum from a perturbed start too (it is the LQR law).
    dyn = LinearDynamics(A, B)
    x0b = x0 + 0.3
    xs = rollout(dyn, x0, result.us)
    us_fb = []
    x = x0b
    for t in range(T):
        u = result.us[t] + result.K[t] @ (x - xs[t])
        us_fb.append(u)
        x = A @ x + B @ u
    np.testing.assert_allclose(np.array(us_fb), _batch_lqr(A, B, Q, R, Qf, x0b, T), atol=1e-8)


def test_nonlinear_cost_never_increases_and_bounds_hold():
    settings = ILQRSettings(max_iterations=60, u_min=(-2.5,), u_max=(2.5,))
    result = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)), settings)
    history = np.array(result.cost_history)
    assert np.all(np.diff(history) <= 0), "accepted iterations never raise the objective"
    assert history[-1] < 0.01 * history[0]
    assert np.all(np.abs(result.us) <= 2.5 + 1e-12)
    assert np.max(np.abs(result.us)) == pytest.approx(2.5), "the bound is active (free peak 3.6)"
    assert result.term_history[-1].keys() == {"effort", "terminal"}
    assert sum(result.term_history[-1].values()) == pytest.approx(result.cost)
    np.testing.assert_allclose(result.xs, rollout(Pendulum(), np.zeros(2), result.us))
    assert set(result.timings) >= {"linearize", "backward", "forward"}


def test_iteration_cap_is_a_stop_reason():
    settings = ILQRSettings(max_iterations=2)
    result = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)), settings)
    assert result.iterations == 2 and result.stop_reason == "max_iterations"


def test_a_step_below_min_step_stops_the_solver_after_it_is_taken():
    free = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)),
                 ILQRSettings(max_iterations=60))
    steps = [e["step"] for e in free.log if e.get("actual", 0.0) > 0]
    assert len(steps) == free.iterations and steps[-1] < steps[0]
    threshold = 0.5 * (steps[0] + steps[-1])
    first_small = next(i for i, s in enumerate(steps) if s < threshold)
    stopped = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)),
                    ILQRSettings(max_iterations=60, min_step=threshold))
    assert stopped.stop_reason == "small_step" and stopped.iterations == first_small + 1
    np.testing.assert_allclose(stopped.cost_history, free.cost_history[:first_small + 2])


@pytest.mark.parametrize("fraction, n", [(0.05, 2), (0.01, 1), (0.2, 3)])
def test_a_stall_stops_the_solver_where_the_rule_says(fraction, n):
    """The stall rule on the pendulum: the run stops right after the first ``n`` accepted
    steps in a row that each bought less than ``fraction`` of the decrease so far, and up to
    there it is the free run."""
    free = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)),
                 ILQRSettings(max_iterations=60))
    h = np.array(free.cost_history)
    small = [(h[i - 1] - h[i]) < fraction * (h[0] - h[i]) for i in range(1, len(h))]
    expected = next(i + 1 for i in range(len(small))
                    if i + 1 >= n and all(small[i + 1 - n:i + 1]))
    stopped = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)),
                    ILQRSettings(max_iterations=60, stall_fraction=fraction,
                                 stall_iterations=n))
    assert stopped.stop_reason == "stalled" and stopped.iterations == expected
    assert expected < free.iterations
    np.testing.assert_allclose(stopped.cost_history, free.cost_history[:expected + 1])


def test_bad_bounds_are_rejected():
    with pytest.raises(ValueError):
        solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((5, 1)),
              ILQRSettings(u_min=(1.0,), u_max=(0.0,)))


def test_solver_imports_no_pydrake():
    import subprocess
    import sys

    code = "import sys, drake_clutter.solvers.ilqr; print('pydrake' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


class RotationDynamics:
    """A heading stored as the unit vector (cos, sin) (2 numbers, 1 tangent direction), turned
    by the control each step: a state on a manifold."""

    def step(self, t, x, u):
        a = np.arctan2(x[1], x[0]) + u[0]
        return np.array([np.cos(a), np.sin(a)])

    def linearize(self, xs, us):
        T = len(us)
        return np.ones((T, 1, 1)), np.ones((T, 1, 1))


def _heading_difference(x_a, x_b):
    return np.array([np.arctan2(x_b[0] * x_a[1] - x_b[1] * x_a[0], x_a @ x_b)])


class HeadingCost:
    """sum_t 1/2 u^2 + 1/2 w (heading_T - goal)^2, expanded in the tangent space."""

    def __init__(self, goal, w):
        self.goal, self.w = goal, w

    def _error(self, x):
        return _heading_difference(x, np.array([np.cos(self.goal), np.sin(self.goal)]))[0]

    def terms(self, xs, us):
        return {"control": 0.5 * float(np.sum(us**2)),
                "terminal": 0.5 * self.w * self._error(xs[-1]) ** 2}

    def quadratize(self, xs, us):
        T = len(us)
        return Expansion(lx=np.zeros((T, 1)), lu=us.copy(), lxx=np.zeros((T, 1, 1)),
                         luu=np.ones((T, 1, 1)), lux=np.zeros((T, 1, 1)),
                         vx=np.array([self.w * self._error(xs[-1])]), vxx=np.array([[self.w]]))


def test_manifold_states_use_the_difference_function():
    T, goal, w = 5, 2.0, 100.0
    result = solve(RotationDynamics(), HeadingCost(goal, w), np.array([1.0, 0.0]),
                   np.zeros((T, 1)), ILQRSettings(max_iterations=20, tolerance=1e-12),
                   difference=_heading_difference)
    assert result.K.shape == (T, 1, 1)
    # Optimum of sum u^2/2 + w/2 (sum u - goal)^2: every u = w goal / (1 + w T).
    np.testing.assert_allclose(result.us[:, 0], w * goal / (1 + w * T), atol=1e-6)
    assert np.all(np.diff(result.cost_history) <= 0)


# ----------------------------------------------------------------------------- inexact derivatives


def test_log_predicts_the_exact_decrease_on_lqr():
    """On an LQR problem the quadratic model is exact: the logged predicted decrease of the
    full step equals the actual one."""
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=1)
    result = solve(LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)),
                   ILQRSettings(reg_init=0.0, reg_min=0.0))
    first = result.log[0]
    assert first["alpha"] == 1.0 and first["tries"] == 1 and not first["open_loop"]
    assert first["actual"] == pytest.approx(first["expected"], rel=1e-9)
    assert first["actual"] == pytest.approx(result.cost_history[0] - result.cost_history[1])
    assert first["predicted"] == pytest.approx(first["expected"], rel=1e-12)  # at alpha 1


def test_log_predicts_the_decrease_at_the_accepted_step_size():
    """When the full step fails (the dynamics refuse controls beyond 3/4 of the optimum's
    largest, returning NaN) the line search accepts alpha 1/2, and the log's "predicted" is the
    model's decrease at that alpha, equal to the actual one on an exact quadratic model."""
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=1)
    largest = np.abs(_batch_lqr(A, B, Q, R, Qf, x0, T)).max()

    class Refusing(LinearDynamics):
        def step(self, t, x, u):
            out = super().step(t, x, u)
            return out * np.nan if np.abs(u).max() > 0.75 * largest else out

    result = solve(Refusing(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)),
                   ILQRSettings(reg_init=0.0, reg_min=0.0, max_iterations=1))
    (entry,) = result.log
    assert entry["alpha"] == 0.5
    assert entry["predicted"] == pytest.approx(entry["actual"], rel=1e-9)
    # LQR: d2 = -d1 / 2, so the model's decrease at alpha 1/2 is 3/4 of the full step's
    assert entry["predicted"] == pytest.approx(0.75 * entry["expected"], rel=1e-9)


def test_trust_region_bounds_every_step_and_still_reaches_the_optimum():
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=2)
    x0 = 5.0 * x0  # far from the optimum, so that the first steps are clipped
    limit = 0.5
    settings = ILQRSettings(max_iterations=300, tolerance=1e-14, reg_init=0.0, reg_min=0.0,
                            step_limit=(limit, limit))
    result = solve(LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)), settings)
    expected = _batch_lqr(A, B, Q, R, Qf, x0, T)
    assert np.max(np.abs(expected)) > 3 * limit, "the unconstrained step must be clipped"
    np.testing.assert_allclose(result.us, expected, atol=1e-6)
    assert result.iterations > 3
    assert np.all(np.diff(result.cost_history) <= 0)
    # Every accepted iterate moved each control by at most the limit.
    us_prev = np.zeros((T, 2))
    rerun = solve(LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, us_prev,
                  ILQRSettings(max_iterations=1, reg_init=0.0, reg_min=0.0,
                               step_limit=(limit, limit)))
    assert np.max(np.abs(rerun.us - us_prev)) <= limit + 1e-12
    assert np.max(np.abs(rerun.us - us_prev)) == pytest.approx(limit)


class WrongA(LinearDynamics):
    """True dynamics A, B; linearize reports A with large errors (as phi's finite differences
    in contact), B exact."""

    def __init__(self, A, B, error):
        super().__init__(A, B)
        self.error = error

    def linearize(self, xs, us):
        A, B = super().linearize(xs, us)
        return A + self.error, B


def test_open_loop_fallback_makes_progress_with_a_wrong_state_jacobian():
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=3)
    rng = np.random.default_rng(3)
    dyn = WrongA(A, B, 1.5 * rng.standard_normal(A.shape))
    cost = QuadraticCost(Q, R, Qf)
    base = ILQRSettings(max_iterations=15, reg_init=1e-6, line_search_steps=8)
    plain = solve(dyn, cost, x0, np.zeros((T, 2)), base)
    fallback = solve(dyn, cost, x0, np.zeros((T, 2)),
                     ILQRSettings(**{**base.__dict__, "open_loop_fallback": True}))
    for result in (plain, fallback):
        assert np.all(np.diff(result.cost_history) <= 0)
    assert any(e["open_loop"] for e in fallback.log), "the fallback was used"
    assert not any(e["open_loop"] for e in plain.log)
    assert fallback.cost < fallback.cost_history[0]
    optimum = sum(cost.terms(rollout(LinearDynamics(A, B), x0, _batch_lqr(A, B, Q, R, Qf, x0, T)),
                             _batch_lqr(A, B, Q, R, Qf, x0, T)).values())
    assert fallback.cost >= optimum - 1e-9  # no solver beats the LQR optimum


def test_without_feedback_every_step_is_open_loop_and_the_cost_still_falls():
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=3)
    cost = QuadraticCost(Q, R, Qf)
    result = solve(LinearDynamics(A, B), cost, x0, np.zeros((T, 2)),
                   ILQRSettings(max_iterations=5, feedback=False))
    accepted = [e for e in result.log if e.get("actual", 0.0) > 0]
    assert accepted and all(e["open_loop"] for e in accepted)
    assert np.all(np.diff(result.cost_history) < 0)
    closed = solve(LinearDynamics(A, B), cost, x0, np.zeros((T, 2)), ILQRSettings(max_iterations=1))
    assert closed.cost < result.cost  # LQR's k assumes its K: open loop is not one Newton step


def test_adaptive_step_starts_near_the_last_accepted_step():
    settings = ILQRSettings(max_iterations=40, adaptive_step=True)
    result = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)), settings)
    accepted = [e["alpha"] for e in result.log if e["alpha"] > 0]
    assert accepted
    for previous, current in zip(accepted, accepted[1:], strict=False):
        assert current <= min(1.0, 2.0 * previous)
    assert np.all(np.diff(result.cost_history) <= 0)
    assert result.cost < 0.01 * result.cost_history[0]


def test_bounded_controls_reach_the_constrained_optimum_with_nonnegative_predictions():
    """A one-step problem with box bounds: the constrained optimum from L-BFGS-B."""
    from scipy.optimize import minimize

    A, B, Q, R, Qf, x0, _ = lqr_problem(seed=4, T=1)
    B = np.eye(4)[:, :2] + 0.3 * B  # well-conditioned inputs
    dyn, cost = LinearDynamics(A, B), QuadraticCost(Q, R, Qf)
    free = _batch_lqr(A, B, Q, R, Qf, x0, 1)[0]
    hi = 0.5 * np.abs(free)  # every bound active at the optimum
    lo = -hi

    def objective(u):
        return sum(cost.terms(rollout(dyn, x0, u[None]), u[None]).values())

    known = minimize(objective, np.zeros(2), bounds=list(zip(lo, hi, strict=True)),
                     method="L-BFGS-B", options={"ftol": 1e-15, "gtol": 1e-12}).x
    result = solve(dyn, cost, x0, np.zeros((1, 2)),
                   ILQRSettings(max_iterations=20, u_min=tuple(lo), u_max=tuple(hi),
                                tolerance=1e-14))
    np.testing.assert_allclose(result.us[0], known, atol=1e-6)
    assert all(e["expected"] >= 0 for e in result.log)


def test_per_knot_bounds_pin_controls_and_the_rest_solve_the_reduced_problem():
    """Bounds (T, nu) that meet pin those controls; the free ones are the equality-constrained
    optimum (the batch normal equations with the pinned columns moved to the right side)."""
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=2, T=6)
    nu = B.shape[1]
    lo, hi = np.full((T, nu), -np.inf), np.full((T, nu), np.inf)
    pinned = np.zeros((T, nu), dtype=bool)
    pinned[-1, :] = True  # the last control, both numbers
    pinned[:, 1] = True  # the second control at every knot
    values = np.where(pinned, 0.3, 0.0)
    lo[pinned], hi[pinned] = values[pinned], values[pinned]
    result = solve(LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, nu)),
                   ILQRSettings(max_iterations=10, u_min=lo, u_max=hi, tolerance=1e-14))
    np.testing.assert_array_equal(result.us[pinned], values[pinned])
    # the reduced problem: J(U) = 1/2 U'HU + g'U over the free entries of U
    Sx, Su, Qbar, Rbar = stacked_lqr(A, B, Q, R, Qf, T)
    H = Su.T @ Qbar @ Su + Rbar
    g = Su.T @ Qbar @ Sx @ x0
    free, fixed = ~pinned.ravel(), values.ravel()
    rhs = -(g[free] + H[np.ix_(free, ~free)] @ fixed[~free])
    known = np.linalg.solve(H[np.ix_(free, free)], rhs)
    np.testing.assert_allclose(result.us.ravel()[free], known, atol=1e-8)


def test_per_knot_bounds_of_the_wrong_shape_are_rejected():
    A, B, Q, R, Qf, x0, T = lqr_problem(T=4)
    with pytest.raises(ValueError):
        solve(LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)),
              ILQRSettings(u_min=np.zeros((T + 1, 2))))


class Unimprovable(LinearDynamics):
    """Reports a linearisation whose model step always raises the true cost: B's sign
    flipped."""

    def linearize(self, xs, us):
        A, B = super().linearize(xs, us)
        return A, -B


def test_failed_line_searches_stop_the_solver():
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=5)
    settings = ILQRSettings(max_iterations=10, max_failed_searches=2, line_search_steps=3)
    result = solve(Unimprovable(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)), settings)
    assert result.stop_reason == "line_search_failed" and result.iterations == 0
    assert len(result.log) == 2 and all(e["tries"] == 3 and e["alpha"] == 0 for e in result.log)
    assert result.log[1]["mu"] == pytest.approx(10 * result.log[0]["mu"])


class Integrator:
    def step(self, t, x, u):
        return x + u

    def linearize(self, xs, us):
        T = len(us)
        return np.ones((T, 1, 1)), np.ones((T, 1, 1))


class FlatDistance:
    """|x_T - 1| smoothed, with a curvature far too small (as a linear penalty's Gauss-Newton
    Hessian): the model's minimum lies far below zero."""

    def terms(self, xs, us):
        return {"distance": float(np.sqrt((xs[-1, 0] - 1.0) ** 2 + 1e-6))}

    def quadratize(self, xs, us):
        T = len(us)
        r = xs[-1, 0] - 1.0
        return Expansion(lx=np.zeros((T, 1)), lu=np.zeros((T, 1)), lxx=np.zeros((T, 1, 1)),
                         luu=np.zeros((T, 1, 1)), lux=np.zeros((T, 1, 1)),
                         vx=np.array([r / np.sqrt(r**2 + 1e-6)]), vxx=np.array([[1e-6]]))


def test_cost_floor_rejects_models_predicting_below_it_without_a_rollout():
    settings = ILQRSettings(max_iterations=30, cost_floor=0.0, reg_init=1e-6)
    result = solve(Integrator(), FlatDistance(), np.zeros(1), np.zeros((3, 1)), settings)
    skipped = [e for e in result.log if e["tries"] == 0 and e["expected"] > 1.0]
    tried = [e for e in result.log if e["tries"] > 0]
    assert skipped, "the first models predict far below 0 and are skipped"
    assert tried and all(e["expected"] <= result.cost_history[0] for e in tried)
    assert np.all(np.diff(result.cost_history) <= 0)
    assert result.cost < 0.05 * result.cost_history[0]


class BatchedPendulum(Pendulum):
    """Runs forward passes in batches of three (as worker processes would), recording them."""

    parallel_passes = 3

    def __init__(self):
        self.batches = []

    def forward_passes(self, xs, us, k, K, alphas, lo, hi, limit):
        from drake_clutter.solvers.ilqr import forward_pass

        self.batches.append(list(alphas))
        return [forward_pass(self, xs, us, k, K, a, lo, hi, None, limit) for a in alphas]


def test_a_parallel_line_search_takes_the_serial_steps():
    """Batches of step sizes, accepting the first that lowers the objective: the same
    iterates, step sizes and tries as one pass after another."""
    settings = ILQRSettings(max_iterations=15, line_search_steps=8, adaptive_step=True)
    serial = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)), settings)
    dynamics = BatchedPendulum()
    batched = solve(dynamics, SwingUpCost(), np.zeros(2), np.zeros((80, 1)), settings)
    np.testing.assert_array_equal(batched.us, serial.us)
    assert batched.cost_history == serial.cost_history
    assert [(e["alpha"], e["tries"]) for e in batched.log] == \
        [(e["alpha"], e["tries"]) for e in serial.log]
    assert dynamics.batches and all(2 <= len(b) <= 3 for b in dynamics.batches)
    for b in dynamics.batches:  # halving step sizes, largest first
        assert all(s == 0.5 * a for a, s in zip(b, b[1:], strict=False))
    assert sum(e["passes"] for e in batched.log) == sum(len(b) for b in dynamics.batches)
    assert any(e["passes"] > e["tries"] for e in batched.log)  # a batch ran past the step taken


class NaNJacobian(LinearDynamics):
    """A linearisation with one failed (NaN) entry of B at knot 3."""

    def linearize(self, xs, us):
        A, B = super().linearize(xs, us)
        B = B.copy()
        B[3, 0, 1] = np.nan
        return A, B


def test_a_nan_derivative_entry_is_zeroed_counted_and_the_solve_still_descends():
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=4)
    cost = QuadraticCost(Q, R, Qf)
    result = solve(NaNJacobian(A, B), cost, x0, np.zeros((T, 2)),
                   ILQRSettings(max_iterations=4))
    assert [e["nonfinite"] for e in result.log][:1] == [1.0]
    assert np.all(np.isfinite(result.us)) and result.cost < 0.5 * result.cost_history[0]
    arrays = [np.array([1.0, np.inf]), np.array([[np.nan, 2.0]])]
    assert zero_nonfinite(*arrays) == 2
    assert arrays[0].tolist() == [1.0, 0.0] and arrays[1].tolist() == [[0.0, 2.0]]


@pytest.mark.parametrize("seed", range(6))
def test_box_qp_matches_a_reference_solver(seed):
    """Projected Newton against L-BFGS-B on random positive-definite 8 x 8 QPs whose bounds
    cut the unconstrained minimiser, one entry pinned (its bounds meet at 0)."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(seed)
    M = rng.normal(size=(8, 8))
    H = M @ M.T + 0.1 * np.eye(8)
    g = rng.normal(size=8) * 3
    lower, upper = -rng.uniform(0.05, 0.5, 8), rng.uniform(0.05, 0.5, 8)
    lower[3] = upper[3] = 0.0
    x, free = box_qp_solve(H, g, lower, upper)
    known = minimize(lambda v: 0.5 * v @ H @ v + g @ v, np.zeros(8), jac=lambda v: H @ v + g,
                     bounds=list(zip(lower, upper, strict=True)), method="L-BFGS-B",
                     options={"ftol": 1e-16, "gtol": 1e-12, "maxiter": 10000}).x
    np.testing.assert_allclose(x, known, atol=1e-6)
    assert x[3] == 0.0 and not free[3]
    assert np.all(x >= lower) and np.all(x <= upper)
    grad = H @ x + g
    np.testing.assert_allclose(grad[free], 0.0, atol=1e-9)  # stationary in the free entries


def test_trust_bounds_make_the_prediction_describe_the_step():
    """Far from an LQR optimum with a trust region: clipped after the policy, the model's
    predicted decrease is of a step never taken (the actual is a fraction of it); as bounds of
    the backward pass's box QP, the first step's prediction is exact and no control moves by
    more than the region."""
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=2)
    x0 = 5.0 * x0
    problem = (LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)))
    clip = solve(*problem, ILQRSettings(max_iterations=1, step_limit=(0.5, 0.5)))
    bounded = solve(*problem, ILQRSettings(max_iterations=1, step_limit=(0.5, 0.5),
                                           box_qp=True, trust_bounds=True))
    (c,), (b,) = clip.log, bounded.log
    assert c["actual"] < 0.5 * c["predicted"]
    assert b["actual"] == pytest.approx(b["predicted"], rel=1e-9)
    assert np.abs(bounded.us).max() <= 0.5 + 1e-12


def test_the_trust_region_shrinks_on_a_poor_model_and_accept_ratio_refuses_small_gains():
    """With a wrong state Jacobian the model overpromises: the adaptive region shrinks below
    its start; a step whose decrease is under accept_ratio of the prediction is refused."""
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=3)
    wrong = WrongA(A, B, 0.5 * np.random.default_rng(0).normal(size=A.shape))
    settings = ILQRSettings(max_iterations=15, step_limit=(1.0, 1.0), box_qp=True,
                            trust_bounds=True, trust_adapt=True)
    result = solve(wrong, QuadraticCost(Q, R, Qf), 3.0 * x0, np.zeros((T, 2)), settings)
    radii = [e["radius"] for e in result.log]
    assert min(radii) < 1.0
    assert np.all(np.diff(result.cost_history) <= 0)
    strict = solve(wrong, QuadraticCost(Q, R, Qf), 3.0 * x0, np.zeros((T, 2)),
                   ILQRSettings(max_iterations=15, accept_ratio=0.9))
    loose = solve(wrong, QuadraticCost(Q, R, Qf), 3.0 * x0, np.zeros((T, 2)),
                  ILQRSettings(max_iterations=15))
    # without the ratio every step is taken though it keeps under 0.9 of its promise (about
    # 0.5 here); with it every such step is refused and the path stays where it started
    taken = [e for e in loose.log if e["alpha"] > 0]
    assert len(taken) == 15 and all(0 < e["actual"] < 0.9 * e["predicted"] for e in taken)
    assert strict.iterations == 0 and strict.cost == strict.cost_history[0]
    assert not any(e["alpha"] > 0 for e in strict.log)


def test_a_feedback_mask_feeds_back_only_its_coordinates():
    """With a mask, the forward pass's gains are K with the unmasked columns zero: masking
    every coordinate is the open-loop solve, masking none the closed-loop one."""
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=5)
    wrong = WrongA(A, B, 0.3 * np.random.default_rng(1).normal(size=A.shape))
    cost = QuadraticCost(Q, R, Qf)
    run = {}
    for name, extra in {"closed": {}, "open": {"feedback": False},
                        "all": {"feedback_mask": (True,) * 4},
                        "none": {"feedback_mask": (False,) * 4},
                        "half": {"feedback_mask": (True, True, False, False)}}.items():
        run[name] = solve(wrong, cost, x0, np.zeros((T, 2)),
                          ILQRSettings(max_iterations=5, **extra))
    np.testing.assert_array_equal(run["all"].us, run["closed"].us)
    np.testing.assert_array_equal(run["none"].us, run["open"].us)
    assert not np.array_equal(run["half"].us, run["closed"].us)
    assert not np.array_equal(run["half"].us, run["open"].us)
    assert np.abs(run["none"].K).max() > 0  # the result keeps the full gains


class _SlowPendulum(Pendulum):
    """The pendulum with a linearization that takes ``seconds`` of wall time."""

    def __init__(self, seconds: float):
        super().__init__()
        self.seconds = seconds

    def linearize(self, xs, us):
        import time

        time.sleep(self.seconds)
        return super().linearize(xs, us)


def test_a_passed_deadline_stops_the_solver_before_its_first_iteration():
    import time

    settings = ILQRSettings(max_iterations=30, deadline=time.monotonic() - 1.0)
    result = solve(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((80, 1)), settings)
    assert result.stop_reason == "time_budget" and result.iterations == 0
    np.testing.assert_array_equal(result.us, np.zeros((80, 1)))
    assert len(result.cost_history) == 1


def test_a_deadline_stops_the_solve_before_an_iteration_that_would_pass_it():
    import time

    free = solve(_SlowPendulum(0.0), SwingUpCost(), np.zeros(2), np.zeros((80, 1)),
                 ILQRSettings(max_iterations=30))
    assert free.iterations > 6
    tic = time.monotonic()
    settings = ILQRSettings(max_iterations=30, deadline=tic + 0.25)
    result = solve(_SlowPendulum(0.1), SwingUpCost(), np.zeros(2), np.zeros((80, 1)), settings)
    elapsed = time.monotonic() - tic
    assert result.stop_reason == "time_budget"
    # the third iteration would end past the deadline: the solver stops before it
    assert 1 <= result.iterations <= 2 and elapsed < 0.25
    # the same steps as the free run: the path is that run's after as many iterations
    np.testing.assert_allclose(result.cost_history, free.cost_history[:result.iterations + 1])
