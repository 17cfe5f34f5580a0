"""The objective of Sec. V's phi stages over iLQR's states and controls: the Table I terms of
`costs` and the distances of `geometry` chained onto them.

**The physics problem** (`PhysicsObjective`, Sec. V). iLQR's state z = [x, q_prev]: phi's state
x (`state.StateLayout`: the arm's configuration q^t at knot t, then 13 numbers per kept box)
augmented with the previous knot's arm configuration q^(t-1) (8), which c_acc needs; its
tangent dz = [dx, dq_prev] (box rotations as rotation vectors in W). The control u_t = q^(t+1).
Knot 0 (the start, fixed) to knot T = Delta; Table II's time windows, as we read them:

* per knot t = 1..T, on the state z_t (the arm at q^t, the boxes where phi put them):
  c_static (arm vs shelf, "t <= Delta"), c_motion, c_upright ("all": every knot of the plan;
  the boxes' motion after Delta is not simulated by the planner), c_force as a proxy (below);
* per interval t = 0..T-1, on (z_t, u_t): c_acc over (q^(t-1), q^t, q^(t+1)); at t = 0
  q^(-1) = q^0 (the arm starts at rest); c_force from phi's forces of that knot ("all");
* terminal, on z_T: c_grasp (tool frame to the target's centre), c_grp_horiz, c_grp_open.

c_grasp here is Table I's distance (smoothed at 0, `grasp_distance`), not `costs.grasp`'s
squared distance: at w_grasp = 1e3 the square pulls with 2e3 d, too weak to matter against the
clutter terms at a few cm (on fig5 the plan ended 5-15 cm off the target, measured); the
distance pulls with 1e3 at any range, as in the paper.

c_force (Table I: 1/2 ||force(q, x)||^2, the forces between all pairs of objects) comes from
phi itself when the objective is given a ``forces`` source (`derivatives.PhiDynamics`; the
physics planner always gives it): per interval t = 0..T-1, f_t = f(x_t, u_t) is phi's
contact-force vector of that knot (N; the arm's and each kept box's summed contact forces with
every other object, a box's shelf contact beyond its allowance: `dynamics.Phi.contact_forces`),
and its Jacobians (Fx, Fu) come from the same derivatives as A and B, so the term's
Gauss-Newton expansion is w (Fx, Fu)^T f and w (Fx, Fu)^T (Fx, Fu). Without a source
(``PhysicsConfig.force_source`` "proxy", or no phi) it is a penetration proxy on the knot's
state: for every arm-vs-box pair in contact f = k (-d), k = ``force_stiffness``.

Penetration (c_static, c_static_hull, c_dynamic) is `penetration`'s.

The kinematic stages' objective (Sec. V-A, V-B) is `kinematic.KinematicObjective`, on the same
terms.

Every `terms` value is weighted (Table II / `PhysicsConfig`); `quadratize` returns the
`ilqr.Expansion` in tangent coordinates.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform

from drake_clutter.common.config import PhysicsConfig
from drake_clutter.phi.state import ARM_DIM, BOX_TANGENT, StateLayout, box_state_to_pose
from drake_clutter.planners.geometry import SHELF, ArmGeometry, Contact
from drake_clutter.planners.physics import costs
from drake_clutter.planners.physics.costs import Term
from drake_clutter.planners.physics.limits import max_steps
from drake_clutter.planners.physics.penetration import (
    distance_row,
    penetration_term,
)
from drake_clutter.robot import pr2
from drake_clutter.solvers.ilqr import Expansion

OPEN = pr2.GRIPPER_MAX_OPENING  # m, c_grp_open's q_gripper_open


# ----------------------------------------------------------------------------- distances


def grasp_distance(p_tool_W: np.ndarray, dp_dq: np.ndarray, p_target_W: np.ndarray,
                   eps: float, majorize: bool = False,
                   dtarget: np.ndarray | None = None) -> Term:
    """Table I's c_grasp as a distance: sqrt(||p_gripper - p_target||^2 + eps^2) - eps (m),
    smoothed at 0 by ``eps``, over (arm joints, the target point's arguments); Gauss-Newton
    Hessian, or with ``majorize`` J'J / s: the quadratic in r above the distance that touches
    it at r (curvature along r too, where Gauss-Newton has none). ``dtarget`` (3, k): the
    target point's Jacobian over its k arguments (default I: its own position in W)."""
    r = np.asarray(p_tool_W, dtype=float) - np.asarray(p_target_W, dtype=float)
    J = np.hstack([dp_dq, -(np.eye(3) if dtarget is None else np.asarray(dtarget))])
    s = float(np.sqrt(r @ r + eps**2))
    g = J.T @ r / s
    if majorize:
        return Term(s - eps, g, J.T @ J / s)
    # Curvature of the distance across r (the GN of the radial part is zero): J'(I/s - rr'/s^3)J.
    H = J.T @ (np.eye(3) / s - np.outer(r, r) / s**3) @ J
    return Term(s - eps, g, H)


def speed_limit(q: np.ndarray, u: np.ndarray, max_step: np.ndarray) -> Term:
    """sum_j max(0, |u_j - q_j| - max_step_j)^2 over (q, u) (16,): a joint moving farther in
    one knot interval than its speed limit allows (exact Hessian, piecewise constant)."""
    step = np.asarray(u, dtype=float) - np.asarray(q, dtype=float)
    excess = np.abs(step) - max_step
    active = excess > 0
    n = len(step)
    J = np.zeros((int(active.sum()), 2 * n))
    rows = np.flatnonzero(active)
    sign = np.sign(step[rows])
    J[np.arange(len(rows)), rows] = -sign
    J[np.arange(len(rows)), n + rows] = sign
    r = excess[active]
    return Term(float(r @ r), 2.0 * J.T @ r, 2.0 * J.T @ J)


# ----------------------------------------------------------------------------- physics


class PhysicsObjective:
    """Sec. V's objective over z = [x, q_prev] and u = q^(t+1) (see the module docstring).

    ``x0`` is the start state (its boxes' positions are c_motion's p_i^1); ``target`` the target
    box's name (its centre is c_grasp's point: its state position when kept, else its resting pose).
    Boxes in ``force_exclude`` have no proxy c_force (the sphere stage's target);
    ``static_geometry`` (default: ``geometry``) is the arm whose distances to the shelf make
    c_static (the sphere stage's capsules). ``forces``: phi's contact forces (``step_forces(x, u)``
    and ``linearize_forces(xs, us)``, as `derivatives.PhiDynamics`) for c_force, unless
    ``config.force_source`` is "proxy". ``grasp_offset``: c_grasp's gripper point lies this far (m)
    behind G along x_G (`approach.grasp_offset`: the pads' centre). ``aim_T``: where that gripper
    point should end, in the target's frame T (m; the candidate's pre-grasp point, `pregrasp_aim`),
    so it follows the target where phi moves it. None, or ``grasp_aim`` "centre": the target's
    centre (Table I as written).
    """

    def __init__(self, geometry: ArmGeometry, layout: StateLayout, config: PhysicsConfig,
                 x0: np.ndarray, target: str, knot_time: float, d_safe: float,
                 force_exclude: tuple[str, ...] = (),
                 static_geometry: ArmGeometry | None = None, forces=None,
                 grasp_offset: float = 0.0,
                 aim_T: np.ndarray | None = None):
        self.geometry, self.layout, self.config = geometry, layout, config
        self.grasp_offset = grasp_offset
        self.knot_time, self.d_safe = knot_time, d_safe
        self.force_exclude = tuple(force_exclude)
        self.forces = forces if config.force_source == "phi" else None
        self.static_geometry = static_geometry
        self._max_step = max_steps(config, knot_time)
        self.nx, self.ndx = layout.nx, layout.ndx
        self.nz = self.ndx + ARM_DIM
        self.p_start = layout.boxes(x0)[:, 4:7].copy()
        self.target = target
        self.target_index = (layout.box_index(target) if target in layout.box_names else None)
        self.box_columns = {n: ARM_DIM + BOX_TANGENT * i
                            for i, n in enumerate(layout.box_names)}
        self.aim_T = (np.zeros(3) if aim_T is None or config.grasp_aim == "centre"
                      else np.asarray(aim_T, dtype=float))
        if self.target_index is None:
            self.p_target = geometry.rest_pose(target).multiply(self.aim_T)

    # -- per knot

    def box_poses(self, z: np.ndarray) -> dict[str, RigidTransform]:
        """X_WB of the kept boxes in state z."""
        return {n: box_state_to_pose(b)
                for n, b in zip(self.layout.box_names, self.layout.boxes(z[:self.nx]),
                                strict=True)}

    def state_terms(self, z: np.ndarray, terminal: bool) -> dict[str, Term]:
        """Weighted Terms over dz (nz,) of the costs on one knot's state (t >= 1)."""
        cfg, q = self.config, z[:ARM_DIM]
        contacts = self.geometry.contacts(q, self.box_poses(z), self.d_safe)
        out = {"static": self._static(z, contacts)}
        if self.forces is None:
            out["force"] = self._force(contacts).scaled(cfg.w_force)
        out.update(self._box_terms(z))
        if terminal:
            out.update(self._terminal(z))
        return out

    def _static(self, z: np.ndarray, contacts: list[Contact]) -> Term:
        """Weighted c_static over dz at the knot: from ``contacts``, or in ``static_geometry``
        if given."""
        shelf = [c for c in contacts if c.obstacle == SHELF]
        if self.static_geometry is not None:
            shelf = self.static_geometry.contacts(z[:ARM_DIM], None, self.d_safe, "shelf")
        return penetration_term(shelf, self.d_safe, self.nz).scaled(self.config.w_static)

    def _force(self, contacts: list[Contact]) -> Term:
        touching = [c for c in contacts if c.obstacle != SHELF and c.distance < 0.0
                    and c.obstacle not in self.force_exclude]
        if not touching:
            return Term(0.0, np.zeros(self.nz), np.zeros((self.nz, self.nz)))
        k = self.config.force_stiffness
        forces = np.array([-k * c.distance for c in touching])
        J = np.array([-k * distance_row(c, self.nz, self.box_columns) for c in touching])
        return costs.force(forces, J)

    def _box_terms(self, z: np.ndarray) -> dict[str, Term]:
        boxes = self.layout.boxes(z[:self.nx])
        nz = self.nz
        motion = Term(0.0, np.zeros(nz), np.zeros((nz, nz)))
        upright = Term(0.0, np.zeros(nz), np.zeros((nz, nz)))
        for i, b in enumerate(boxes):
            start = ARM_DIM + BOX_TANGENT * i
            m = costs.motion(b[4:7], self.p_start[i])
            motion = motion.plus(_embed(m, [start + 3, start + 4, start + 5], nz))
            u = costs.upright(box_state_to_pose(b).rotation().matrix(), gauss_newton=True,
                              majorize=self.config.distance_curvature == "majorizer",
                              tilt=self.config.upright_curvature == "tilt")
            upright = upright.plus(_embed(u, [start, start + 1, start + 2], nz))
        return {"motion": motion.scaled(self.config.w_motion),
                "upright": upright.scaled(self.config.w_upright)}

    def _terminal(self, z: np.ndarray) -> dict[str, Term]:
        cfg, q = self.config, z[:ARM_DIM]
        p, axis_z, dp, dz = self.geometry.tool(q)
        if self.grasp_offset:
            axis_x, dx = self.geometry.tool_axis(q, 0)
            p, dp = p - self.grasp_offset * axis_x, dp - self.grasp_offset * dx
        p_target, columns, first, dtarget = self._target_point(z)
        majorize = cfg.distance_curvature == "majorizer"
        grasp = _embed(grasp_distance(p, dp, p_target, cfg.grasp_smoothing, majorize, dtarget),
                       columns, self.nz, first=first)
        horiz = _embed(costs.gripper_horizontal(axis_z, dz), list(range(ARM_DIM)), self.nz)
        grp_open = _embed(costs.gripper_open(q[7], OPEN), [7], self.nz)
        return {"grasp": grasp.scaled(cfg.w_grasp), "grp_horiz": horiz.scaled(cfg.w_grp_horiz),
                "grp_open": grp_open.scaled(cfg.w_grp_open)}

    def _target_point(self, z: np.ndarray
                      ) -> tuple[np.ndarray, list[int], int | None, np.ndarray]:
        """c_grasp's point in W (``aim_T`` carried by the target: in its state pose when kept,
        else its resting pose), the columns of dz over (arm, the point's arguments),
        `_embed`'s ``first`` and the point's Jacobian over its arguments (3 x 6: the target's
        rotation vector in W, then its position; 3 x 3 when it is not kept)."""
        arm = list(range(ARM_DIM))
        if self.target_index is None:
            return self.p_target, arm, ARM_DIM, np.eye(3)
        s = self.box_columns[self.target]
        X_WT = box_state_to_pose(self.layout.boxes(z[:self.nx])[self.target_index])
        r_W = X_WT.rotation().multiply(self.aim_T)
        # R' = exp([dtheta]x) R moves the point by dtheta x r = -[r]x dtheta.
        dtarget = np.hstack([-_skew(r_W), np.eye(3)])
        return X_WT.translation() + r_W, arm + list(range(s, s + 6)), None, dtarget

    def acc_term(self, z: np.ndarray, u: np.ndarray) -> Term:
        """Weighted c_acc + w_speed c_speed over (dz, du) (nz + 8,) of the interval from z
        with control u."""
        term = costs.acceleration(z[self.nx:], z[:ARM_DIM], u, self.knot_time)
        cols = (list(range(self.ndx, self.nz)) + list(range(ARM_DIM))
                + list(range(self.nz, self.nz + ARM_DIM)))
        acc = _embed(term, cols, self.nz + ARM_DIM).scaled(self.config.w_acc)
        speed = speed_limit(z[:ARM_DIM], u, self._max_step)
        speed = _embed(speed, list(range(ARM_DIM)) + cols[2 * ARM_DIM:], self.nz + ARM_DIM)
        return acc.plus(speed, self.config.w_speed)

    # -- the ilqr.Cost protocol

    def terms(self, zs: np.ndarray, us: np.ndarray) -> dict[str, float]:
        """Weighted value of every term over the trajectory (knots 1..T, intervals 0..T-1)."""
        out: dict[str, float] = {}
        T = len(us)
        for t in range(1, T + 1):
            terms = self.state_terms(zs[t], terminal=t == T)
            for name, term in terms.items():
                out[name] = out.get(name, 0.0) + term.value
        out["acc"] = sum(self.acc_term(zs[t], us[t]).value for t in range(T))
        if self.forces is not None:
            out.update(self.phi_force_terms(zs[:T, :self.nx], us))
        return out

    def phi_force_terms(self, xs: np.ndarray, us: np.ndarray) -> dict[str, float]:
        """Weighted c_force (`force_cost`) from phi's contact forces
        of the intervals (x_t, u_t)."""
        f = np.array([self.forces.step_forces(x, u) for x, u in zip(xs, us, strict=True)])
        return self.force_cost(f)[0]

    def force_cost(self, f: np.ndarray) -> tuple[dict[str, float], np.ndarray, np.ndarray]:
        """Weighted c_force = w_force/2 ||f||^2 of contact-force vectors f (..., nf) in N: its
        value, the gradient d cost / d f and the diagonal of the Gauss-Newton Hessian (both
        shaped as f)."""
        w = self.config.w_force
        return {"force": 0.5 * w * float(np.sum(f * f))}, w * f, np.full(f.shape, w)

    def quadratize(self, zs: np.ndarray, us: np.ndarray) -> Expansion:
        """Expansion in tangent coordinates (dz, du)."""
        T, nz, nu = len(us), self.nz, ARM_DIM
        lx, lu = np.zeros((T, nz)), np.zeros((T, nu))
        lxx, luu, lux = np.zeros((T, nz, nz)), np.zeros((T, nu, nu)), np.zeros((T, nu, nz))
        vx, vxx = np.zeros(nz), np.zeros((nz, nz))
        for t in range(T):
            acc = self.acc_term(zs[t], us[t])
            lx[t] += acc.gradient[:nz]
            lu[t] += acc.gradient[nz:]
            lxx[t] += acc.hessian[:nz, :nz]
            luu[t] += acc.hessian[nz:, nz:]
            lux[t] += acc.hessian[nz:, :nz]
            if t >= 1:
                for term in self.state_terms(zs[t], False).values():
                    lx[t] += term.gradient
                    lxx[t] += term.hessian
        for term in self.state_terms(zs[T], True).values():
            vx += term.gradient
            vxx += term.hessian
        if self.forces is not None:
            self._add_phi_forces(zs, us, lx, lu, lxx, luu, lux)
        return Expansion(lx, lu, lxx, luu, lux, vx, vxx)

    def _add_phi_forces(self, zs, us, lx, lu, lxx, luu, lux) -> None:
        """`force_cost` per interval, Gauss-Newton in (dx_t, du_t) (q_prev: no effect)."""
        ndx = self.ndx
        # A failed derivative evaluation (NaN) has no known effect, as in `ilqr`.
        f, Fx, Fu = map(np.nan_to_num, self.forces.linearize_forces(zs[:len(us), :self.nx], us))
        _, g, d = self.force_cost(f)
        lx[:, :ndx] += np.einsum("tfi,tf->ti", Fx, g)
        lu += np.einsum("tfi,tf->ti", Fu, g)
        lxx[:, :ndx, :ndx] += np.einsum("tfi,tf,tfj->tij", Fx, d, Fx)
        luu += np.einsum("tfi,tf,tfj->tij", Fu, d, Fu)
        lux[:, :, :ndx] += np.einsum("tfi,tf,tfj->tij", Fu, d, Fx)


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]x, the cross-product matrix of a 3-vector."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _embed(term: Term, columns: list[int], n: int, first: int | None = None) -> Term:
    """A Term over its own arguments placed at ``columns`` of n numbers (``first``: only its
    first arguments are kept, the rest are constants)."""
    k = len(term.gradient) if first is None else first
    g, H = np.zeros(n), np.zeros((n, n))
    idx = np.asarray(columns[:k], dtype=int)
    g[idx] = term.gradient[:k]
    H[np.ix_(idx, idx)] = term.hessian[:k, :k]
    return Term(term.value, g, H)


