"""Table I cost terms: value, gradient and Hessian of each, on plain arrays.

Every term here is a function of the quantities it names (joint vectors, box positions and
rotations, signed distances with their Jacobians), and returns a `Term` with the value, the
gradient and the (exact or Gauss-Newton) Hessian with respect to its own arguments, in the
order documented on each function. The physics planner chains them onto its state and
controls. Weights and time windows (Table II) are applied by the caller from `PhysicsConfig`.

Conventions: joint vectors are TRAJECTORY_JOINTS rows (rad, and m for the gripper opening);
positions in W (m); a rotation perturbation is a rotation vector dtheta in W,
R' = exp([dtheta]x) R, matching `state.StateLayout`.

Penetration (Table I) is not here: the baseline and the physics planner share one definition,
`clearance.smooth_penetration` (linear in depth once touching, quadratic inside d_safe), and
`penetration.penetration_term` chains it onto distance Jacobians.

The upright and gripper-horizontal angles acos(c) have an infinite gradient at 0 (a cone at the
optimum); they are smoothed as sqrt(theta^2 + eps^2) - eps with eps = `ANGLE_SMOOTHING`, equal
to the paper's angle beyond a few eps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ANGLE_SMOOTHING = 0.01  # rad


@dataclass
class Term:
    """A cost value with its gradient (n,) and Hessian (n, n) over the term's arguments."""

    value: float
    gradient: np.ndarray
    hessian: np.ndarray

    def scaled(self, weight: float) -> Term:
        """The term times ``weight``."""
        return Term(weight * self.value, weight * self.gradient, weight * self.hessian)

    def plus(self, other: Term, weight: float = 1.0) -> Term:
        """This term plus ``weight`` times ``other`` (over the same arguments)."""
        return Term(self.value + weight * other.value, self.gradient + weight * other.gradient,
                    self.hessian + weight * other.hessian)

    def pulled(self, S: np.ndarray) -> Term:
        """This term, over y = S w, as a term over w (S constant)."""
        return Term(self.value, S.T @ self.gradient, S.T @ self.hessian @ S)


def _quadratic(residual: np.ndarray, jacobian: np.ndarray) -> Term:
    """||r||^2 for a residual linear in the arguments (exact Hessian 2 J'J)."""
    return Term(float(residual @ residual), 2.0 * jacobian.T @ residual,
                2.0 * jacobian.T @ jacobian)


def velocity(q: np.ndarray, q_prev: np.ndarray) -> Term:
    """c_vel = ||q - q_prev||^2 over (q, q_prev)."""
    n = len(q)
    return _quadratic(q - q_prev, np.hstack([np.eye(n), -np.eye(n)]))


def acceleration(q_prev: np.ndarray, q: np.ndarray, q_next: np.ndarray, dt: float) -> Term:
    """c_acc = 1/2 ||q_prev - 2 q + q_next||^2 / dt^2 over (q_prev, q, q_next)."""
    n = len(q)
    eye = np.eye(n)
    term = _quadratic(q_prev - 2 * q + q_next, np.hstack([eye, -2 * eye, eye]))
    return term.scaled(0.5 / dt**2)


def match(q: np.ndarray, q_ref: np.ndarray) -> Term:
    """c_match = ||q - q_ref||^2 over q."""
    return _quadratic(q - q_ref, np.eye(len(q)))


def match_velocity(q: np.ndarray, q_prev: np.ndarray, q_ref: np.ndarray,
                   q_ref_prev: np.ndarray) -> Term:
    """c_match_vel = ||(q - q_prev) - (q_ref - q_ref_prev)||^2 over (q, q_prev)."""
    n = len(q)
    return _quadratic((q - q_prev) - (q_ref - q_ref_prev), np.hstack([np.eye(n), -np.eye(n)]))


def gripper_open(opening: float, open_value: float) -> Term:
    """c_grp_open = (q_gripper - q_gripper_open)^2 over the opening (m)."""
    r = np.array([opening - open_value])
    return _quadratic(r, np.eye(1))


def motion(p: np.ndarray, p_start: np.ndarray) -> Term:
    """c_motion = sum_i ||p_i - p_i^1||^2 over the stacked box positions p (3n,)."""
    return _quadratic(p - p_start, np.eye(len(p)))


def _smooth_angle(cos_angle: float, dcos: np.ndarray, ddcos: np.ndarray | None,
                  majorize: bool = False) -> Term:
    """f = sqrt(theta^2 + eps^2) - eps for theta = acos(c), from c, dc/dargs and d2c/dargs2.

    With ``ddcos`` the Hessian is exact; without it (unknown second derivatives) it is the
    Gauss-Newton f''(theta) grad(theta) grad(theta)', which is positive semi-definite; with
    ``majorize`` it is (f'(theta) / theta) grad(theta) grad(theta)' = grad grad' / s, the
    curvature of the quadratic in theta that lies above f and touches it at theta (f is
    concave in theta^2), which Gauss-Newton's ~eps^2 / theta^3 is not far from upright.
    """
    c = float(np.clip(cos_angle, -1.0, 1.0))
    theta = float(np.arccos(c))
    eps = ANGLE_SMOOTHING
    s = np.sqrt(theta**2 + eps**2)
    sin_t = np.sin(theta)
    value = s - eps
    if theta < 1e-4:  # series limits of the coefficients below as theta -> 0
        b = -1.0 / eps
        a_exact = -1.0 / eps**3 + 1.0 / (3.0 * eps)
        a_gn = 1.0 / eps**3
    else:
        b = -theta / (s * sin_t)  # d f / d c
        f1, f2 = theta / s, eps**2 / s**3
        a_exact = (f2 - f1 * np.cos(theta) / sin_t) / sin_t**2
        a_gn = f2 / sin_t**2
    gradient = b * dcos
    if majorize:
        return Term(value, gradient, np.outer(dcos, dcos) / (s * max(sin_t, 1e-4) ** 2))
    if ddcos is None:
        return Term(value, gradient, a_gn * np.outer(dcos, dcos))
    return Term(value, gradient, a_exact * np.outer(dcos, dcos) + b * ddcos)


def upright(R_WB: np.ndarray, gauss_newton: bool = False, majorize: bool = False,
            tilt: bool = False) -> Term:
    """c_upright = tilt angle of the box's z axis from W's z, over a rotation vector in W (3,).

    Exact Hessian (it may be indefinite far from upright), or with ``gauss_newton`` the
    positive semi-definite Gauss-Newton one (what iLQR needs: an indefinite term, carried back
    through phi's Jacobians, made Q_uu indefinite beyond any regulariser on fig6, measured),
    or with ``majorize`` the majorizer's (see `_smooth_angle`). Both are built on
    cos(theta), whose gradient vanishes at upright, so they are flat there: a standing box's
    first tip is invisible to the model. With ``tilt`` the Hessian is J'J / s instead, J the
    Jacobian of the tilt residual r = the horizontal part (x, y) of the box's z axis (|r| =
    sin(theta)) and s = sqrt(theta^2 + eps^2): the majorizer's curvature written in r, equal to
    it along the tilt near upright, positive semi-definite, and of rank 2 at rest (1/eps).
    """
    b = R_WB[:, 2]
    z = np.array([0.0, 0.0, 1.0])
    # b(w) = exp([w]x) b = b + w x b + 1/2 w x (w x b) + ...;  c = z . b(w)
    dcos = np.cross(b, z)
    ddcos = 0.5 * (np.outer(z, b) + np.outer(b, z)) - b[2] * np.eye(3)
    term = _smooth_angle(b[2], dcos, None if gauss_newton or majorize else ddcos, majorize)
    if not tilt:
        return term
    theta = float(np.arccos(np.clip(b[2], -1.0, 1.0)))
    J = -_skew(b)[:2]  # d r / d w: b(w) ~ b + w x b = b - [b]x w
    return Term(term.value, term.gradient, J.T @ J / np.hypot(theta, ANGLE_SMOOTHING))


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def gripper_horizontal(z_gripper_W: np.ndarray, dz_dq: np.ndarray) -> Term:
    """c_grp_horiz = angle between the gripper's z axis and W's z, over the arm joints.

    ``z_gripper_W`` is the tool frame's z axis in W (3,), ``dz_dq`` its Jacobian (3, n);
    Gauss-Newton Hessian.
    """
    return _smooth_angle(z_gripper_W[2], dz_dq[2], None)


def grasp(p_tool_W: np.ndarray, dp_dq: np.ndarray, p_target_W: np.ndarray) -> Term:
    """c_grasp = ||p_gripper - p_target||^2 over (arm joints, target position).

    The paper's c_grasp is the distance; its square has the same minimiser and a usable
    Hessian. ``dp_dq`` (3, n) is the tool frame's translational Jacobian.
    """
    return _quadratic(p_tool_W - p_target_W, np.hstack([dp_dq, -np.eye(3)]))


def force(forces: np.ndarray, jacobian: np.ndarray) -> Term:
    """c_force = 1/2 ||force||^2 over the arguments of the force Jacobian (m, n)."""
    forces = np.asarray(forces, dtype=float)
    return _quadratic(forces, np.asarray(jacobian, dtype=float)).scaled(0.5)


