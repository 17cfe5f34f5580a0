"""Gauss-Newton shooting over B-spline control points against known answers: the LQR optimum
within the spline, derivatives against differences, bounds, pins and a nonlinear descent."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drake_clutter.solvers.ilqr import ILQRSettings, rollout
from drake_clutter.solvers.spline import (
    SplineControls,
    gauss_newton_model,
    sensitivities,
    solve_spline,
)
from drake_clutter.testing.control_problems import (
    LinearDynamics,
    Pendulum,
    QuadraticCost,
    SwingUpCost,
    lqr_problem,
    stacked_lqr,
)
from drake_clutter.trajectory import spline_basis


def _batch_spline_lqr(A, B, Q, R, Qf, x0, T, basis, q0):
    """The controls minimising the LQR objective among u = offset + M C, by the normal
    equations in C."""
    nu = B.shape[1]
    spline = SplineControls(basis, q0)
    P = spline.M.shape[1]
    G = np.kron(spline.M, np.eye(nu))  # (T nu, P nu): vec(u) = vec(offset) + G vec(C)
    Sx, Su, Qbar, Rbar = stacked_lqr(A, B, Q, R, Qf, T)
    off = spline.offset.ravel()
    Sc = Su @ G
    H = Sc.T @ Qbar @ Sc + G.T @ Rbar @ G
    g = Sc.T @ Qbar @ (Sx @ x0 + Su @ off) + G.T @ Rbar @ off
    C = np.linalg.solve(H, -g).reshape(P, nu)
    return spline.controls(C)


def test_lqr_is_solved_in_one_iteration_within_the_spline():
    A, B, Q, R, Qf, x0, T = lqr_problem()
    basis, q0 = spline_basis(T + 1, 8, 4), np.array([0.3, -0.2])
    settings = ILQRSettings(reg_init=0.0, reg_min=0.0, tolerance=1e-12)
    result = solve_spline(LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)),
                          basis, q0, settings)
    expected = _batch_spline_lqr(A, B, Q, R, Qf, x0, T, basis, q0)
    np.testing.assert_allclose(result.us, expected, atol=1e-8)
    assert result.cost_history[1] == pytest.approx(result.cost, rel=1e-10), "one step"
    assert result.log[0]["expected"] == pytest.approx(result.log[0]["actual"], rel=1e-8)
    np.testing.assert_allclose(result.xs, rollout(LinearDynamics(A, B), x0, result.us))


def test_the_gradient_and_hessian_match_differences_of_the_objective():
    dyn, cost, T = Pendulum(), SwingUpCost(), 40
    basis, q0 = spline_basis(T + 1, 7, 4), np.zeros(1)
    spline = SplineControls(basis, q0)
    rng = np.random.default_rng(1)
    C = rng.uniform(-1.0, 1.0, (6, 1))
    x0 = np.array([0.2, 0.0])

    def objective(c):
        us = spline.controls(c.reshape(6, 1))
        return sum(cost.terms(rollout(dyn, x0, us), us).values())

    us = spline.controls(C)
    xs = rollout(dyn, x0, us)
    A, B = dyn.linearize(xs, us)
    g, H = gauss_newton_model(sensitivities(A, B, spline.M), spline.M, cost.quadratize(xs, us))
    h = 1e-6
    numeric = np.array([(objective(C.ravel() + h * e) - objective(C.ravel() - h * e)) / (2 * h)
                        for e in np.eye(6)])
    np.testing.assert_allclose(g, numeric, rtol=1e-5, atol=1e-7)
    assert np.all(np.linalg.eigvalsh(H) >= -1e-9)


def test_bounds_hold_at_every_knot_and_a_pinned_last_knot_is_kept():
    A, B, Q, R, Qf, x0, T = lqr_problem(seed=4)
    x0 = 5.0 * x0
    basis, q0 = spline_basis(T + 1, 9, 4), np.zeros(2)
    lo, hi = np.full((T, 2), -0.4), np.full((T, 2), 0.4)
    lo[-1], hi[-1] = (0.25, -0.1), (0.25, -0.1)  # the last knot pinned
    settings = ILQRSettings(max_iterations=50, u_min=lo, u_max=hi, reg_init=0.0, reg_min=0.0)
    result = solve_spline(LinearDynamics(A, B), QuadraticCost(Q, R, Qf), x0, np.zeros((T, 2)),
                          basis, q0, settings)
    assert np.all(result.us >= lo - 1e-12) and np.all(result.us <= hi + 1e-12)
    np.testing.assert_allclose(result.us[-1], (0.25, -0.1), atol=1e-12)
    free = _batch_spline_lqr(A, B, Q, R, Qf, x0, T, basis, q0)
    assert np.max(np.abs(free)) > 0.6, "the bounds must bind"
    assert np.all(np.diff(result.cost_history) <= 0)


def test_a_nonlinear_descent_stays_a_spline_and_beats_its_start():
    T = 80
    basis = spline_basis(T + 1, 20, 4)  # 12 points cannot swing it up within the bounds
    settings = ILQRSettings(max_iterations=60, u_min=(-2.5,), u_max=(2.5,), step_limit=(1.0,),
                            trust_adapt=True)
    result = solve_spline(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((T, 1)), basis,
                          np.zeros(1), settings)
    history = np.array(result.cost_history)
    assert np.all(np.diff(history) <= 0) and history[-1] < 0.01 * history[0]
    spline = SplineControls(basis, np.zeros(1))
    np.testing.assert_allclose(spline.controls(spline.fit(result.us)), result.us, atol=1e-9)
    assert np.all(np.abs(result.us) <= 2.5 + 1e-12)
    assert result.K.shape == (T, 1, 2) and not result.K.any(), "open loop"
    np.testing.assert_allclose(result.xs, rollout(Pendulum(), np.zeros(2), result.us))


def test_a_basis_for_another_horizon_is_rejected():
    with pytest.raises(ValueError, match="knots"):
        solve_spline(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((20, 1)),
                     spline_basis(31, 10, 4), np.zeros(1))


def test_per_knot_pins_no_spline_can_meet_are_rejected():
    lo, hi = np.full((20, 1), -1.0), np.full((20, 1), 1.0)
    lo[-2], hi[-2], lo[-1], hi[-1] = 0.5, 0.5, -0.5, -0.5  # the last point sees both knots
    with pytest.raises(ValueError, match="feasible"):
        solve_spline(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((20, 1)),
                     spline_basis(21, 8, 4), np.zeros(1), ILQRSettings(u_min=lo, u_max=hi))


def test_a_deadline_stops_the_spline_solver_with_its_best_path():
    import time

    T = 80
    basis = spline_basis(T + 1, 20, 4)
    settings = ILQRSettings(max_iterations=60, u_min=(-2.5,), u_max=(2.5,))
    free = solve_spline(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((T, 1)), basis,
                        np.zeros(1), settings)
    spent = solve_spline(Pendulum(), SwingUpCost(), np.zeros(2), np.zeros((T, 1)), basis,
                         np.zeros(1), replace(settings, deadline=time.monotonic()))
    assert free.stop_reason != "time_budget" and free.iterations > 0
    assert spent.stop_reason == "time_budget" and spent.iterations == 0
    assert spent.cost_history == free.cost_history[:1]
