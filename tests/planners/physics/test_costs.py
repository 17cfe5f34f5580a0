"""Table I cost terms: gradients and Hessians against numerical differentiation.

Tolerances follow crocoddyl's rule: central differences with step eps^(1/3).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from drake_clutter.planners.physics import costs

STEP = np.finfo(float).eps ** (1 / 3)
RNG = np.random.default_rng(1)


def _num_grad(f, x):
    g = np.zeros_like(x)
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = STEP
        g[i] = (f(x + e) - f(x - e)) / (2 * STEP)
    return g


def _num_hess(grad, x):
    H = np.zeros((len(x), len(x)))
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = STEP
        H[:, i] = (grad(x + e) - grad(x - e)) / (2 * STEP)
    return 0.5 * (H + H.T)


def _check(term_of, x, hessian_exact=True, rtol=1e-5, atol=1e-6):
    term = term_of(x)
    np.testing.assert_allclose(term.gradient, _num_grad(lambda y: term_of(y).value, x),
                               rtol=rtol, atol=atol)
    if hessian_exact:
        np.testing.assert_allclose(term.hessian, _num_hess(lambda y: term_of(y).gradient, x),
                                   rtol=1e-4, atol=1e-4 * max(1.0, np.abs(term.hessian).max()))
    else:
        assert np.all(np.linalg.eigvalsh(term.hessian) >= -1e-9), "Gauss-Newton is PSD"


def test_velocity_acceleration_match_terms():
    n = 8
    q0, q1, q2, r0, r1 = (RNG.standard_normal(n) for _ in range(5))
    _check(lambda x: costs.velocity(x[:n], x[n:]), np.concatenate([q1, q0]))
    _check(lambda x: costs.acceleration(x[:n], x[n:2 * n], x[2 * n:], 0.2),
           np.concatenate([q0, q1, q2]))
    _check(lambda x: costs.match(x, r1), q1)
    _check(lambda x: costs.match_velocity(x[:n], x[n:], r1, r0), np.concatenate([q1, q0]))
    _check(lambda x: costs.gripper_open(x[0], 0.09), np.array([0.03]))
    _check(lambda x: costs.motion(x, np.arange(6.0)), RNG.standard_normal(6))


def test_known_values():
    assert costs.velocity(np.ones(3), np.zeros(3)).value == pytest.approx(3.0)
    q = np.array([0.0]), np.array([1.0]), np.array([0.0])
    assert costs.acceleration(*q, dt=0.5).value == pytest.approx(0.5 * 4 / 0.25)
    R = Rotation.from_rotvec([0.3, 0.0, 0.0]).as_matrix()
    eps = costs.ANGLE_SMOOTHING
    assert costs.upright(R).value == pytest.approx(np.sqrt(0.09 + eps**2) - eps)
    assert costs.upright(np.eye(3)).value == 0.0


@pytest.mark.parametrize("tilt", [0.0, 1e-6, 0.005, 0.3, 1.2, 2.8])
def test_upright_exact_derivatives(tilt):
    axis = np.array([np.cos(0.7), np.sin(0.7), 0.0])
    yaw = Rotation.from_rotvec([0, 0, 0.4]).as_matrix()
    R0 = Rotation.from_rotvec(tilt * axis).as_matrix() @ yaw

    def term_of(w):
        return costs.upright(Rotation.from_rotvec(w).as_matrix() @ R0)

    _check(term_of, np.zeros(3), rtol=1e-4, atol=1e-5 if tilt > 0.01 else 1e-3)


def test_gripper_horizontal_gradient():
    # z axis of a frame rotated by joint angles about x then y: z(q) = Ry(q1) Rx(q0) e_z.
    def z_of(q):
        return (Rotation.from_rotvec([0, q[1], 0]) * Rotation.from_rotvec([q[0], 0, 0])).apply(
            [0, 0, 1.0])

    def term_of(q):
        J = np.stack([_num_grad(lambda y, i=i: z_of(y)[i], q) for i in range(3)])
        return costs.gripper_horizontal(z_of(q), J)

    _check(term_of, np.array([0.2, -0.1]), hessian_exact=False, rtol=1e-4, atol=1e-6)


def test_grasp_and_force():
    A = RNG.standard_normal((3, 7))
    target = np.array([0.6, 0.0, 0.8])

    def grasp_of(x):  # p_tool linear in q
        return costs.grasp(A @ x[:7], A, x[7:])

    _check(grasp_of, np.concatenate([RNG.standard_normal(7), target]))
    F = RNG.standard_normal((6, 4))
    _check(lambda x: costs.force(F @ x, F), RNG.standard_normal(4))


@pytest.mark.parametrize("tilt", [0.005, 0.3, 1.2, 2.8])
def test_upright_gauss_newton_hessian_is_psd_with_the_exact_gradient(tilt):
    axis = np.array([np.cos(0.7), np.sin(0.7), 0.0])
    R0 = Rotation.from_rotvec(tilt * axis).as_matrix()
    exact, gn = costs.upright(R0), costs.upright(R0, gauss_newton=True)
    assert gn.value == exact.value
    np.testing.assert_array_equal(gn.gradient, exact.gradient)
    assert np.all(np.linalg.eigvalsh(gn.hessian) >= -1e-12)
    if tilt > 1.0:  # far from upright the exact Hessian is indefinite, the reason for GN
        assert np.linalg.eigvalsh(exact.hessian).min() < 0


@pytest.mark.parametrize("tilt", [0.005, 0.3, 1.2, 2.8])
def test_upright_majorizer_keeps_value_and_gradient_and_adds_curvature(tilt):
    axis = np.array([np.cos(0.7), np.sin(0.7), 0.0])
    R0 = Rotation.from_rotvec(tilt * axis).as_matrix()
    gn, mm = costs.upright(R0, gauss_newton=True), costs.upright(R0, majorize=True)
    assert mm.value == gn.value
    np.testing.assert_array_equal(mm.gradient, gn.gradient)
    assert np.all(np.linalg.eigvalsh(mm.hessian - gn.hessian) >= -1e-9)
    # Along the tilt the majorizer's curvature is 1 / (smoothed angle): the model's step to
    # upright, -g / H, is the angle itself (Gauss-Newton's would be far longer).
    tilt_axis = np.cross(R0[:, 2], [0.0, 0.0, 1.0])
    tilt_axis /= np.linalg.norm(tilt_axis)
    s = mm.value + costs.ANGLE_SMOOTHING
    assert tilt_axis @ mm.hessian @ tilt_axis == pytest.approx(1.0 / s, rel=1e-6)


def test_grasp_distance_majorizer_lies_above_the_distance():
    from drake_clutter.planners.physics.objective import grasp_distance

    eps = 0.005
    target = np.array([0.8, 0.0, 0.8])
    tool = target + np.array([-0.1, 0.02, 0.03])
    gn = grasp_distance(tool, np.eye(3), target, eps)
    mm = grasp_distance(tool, np.eye(3), target, eps, majorize=True)
    assert mm.value == gn.value
    np.testing.assert_array_equal(mm.gradient, gn.gradient)
    r = tool - target
    assert r @ gn.hessian[:3, :3] @ r < 0.01 * (r @ mm.hessian[:3, :3] @ r)  # GN: ~flat along r
    for step in RNG.standard_normal((50, 6)) * 0.1:
        moved = grasp_distance(tool + step[:3], np.eye(3), target + step[3:], eps).value
        model = mm.value + mm.gradient @ step + 0.5 * step @ mm.hessian @ step
        assert moved <= model + 1e-12


def test_upright_tilt_hessian_is_curved_at_rest_and_majorizes_the_angle():
    """At upright the angle forms' Hessians vanish (built on cos, flat at 0); the tilt form's
    is 1/eps on both horizontal axes and none about z, and its quadratic model lies above the
    smoothed angle for small rotations in any direction (a majorizer: a step it predicts to
    lower the cost does)."""
    from scipy.spatial.transform import Rotation

    at_rest = costs.upright(np.eye(3), gauss_newton=True, majorize=True, tilt=True)
    np.testing.assert_allclose(at_rest.hessian, np.diag([1, 1, 0]) / costs.ANGLE_SMOOTHING,
                               atol=1e-12)
    assert np.abs(costs.upright(np.eye(3), gauss_newton=True, majorize=True).hessian).max() == 0
    rng = np.random.default_rng(3)
    for _ in range(20):
        R0 = Rotation.from_rotvec(rng.normal(0, 0.02, 3)).as_matrix()
        base = costs.upright(R0, gauss_newton=True, majorize=True, tilt=True)
        plain = costs.upright(R0, gauss_newton=True, majorize=True)
        assert base.value == plain.value
        np.testing.assert_array_equal(base.gradient, plain.gradient)
        assert np.all(np.linalg.eigvalsh(base.hessian) >= -1e-9)
        w = rng.normal(0, 0.05, 3)
        model = base.value + base.gradient @ w + 0.5 * w @ base.hessian @ w
        actual = costs.upright(Rotation.from_rotvec(w).as_matrix() @ R0).value
        assert model >= actual - 1e-6


