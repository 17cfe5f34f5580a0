"""Sec. V-A and V-B: the kinematic stages before and after the phi stages. The boxes are held
at rest; iLQR's state is the arm's knot q^t (8) and its control the next knot q^(t+1)
(`KinematicArm`), under `KinematicObjective`:

* ``pre`` (`preprocess`, Sec. V-A): c_static_hull + c_dynamic + c_vel, c_grasp and c_grp_horiz
  at the end; the start path's last knot and gripper openings kept as bounds
  (``pre_keep_pregrasp``).
* ``post`` (`postprocess`, Sec. V-B): c_static in the ``post_variant`` geometry + c_match +
  c_match_vel to the reference path, its last knot and openings kept (``post_keep_end``).

Knot paths are (T + 1, 8): the arm's 7 angles (rad) and the gripper opening (m).
"""

from __future__ import annotations

import numpy as np

from drake_clutter.common.config import Config, PhysicsConfig
from drake_clutter.phi.state import ARM_DIM
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.physics import costs
from drake_clutter.planners.physics.costs import Term
from drake_clutter.planners.physics.limits import knot_bounds, max_steps, solver_settings
from drake_clutter.planners.physics.objective import speed_limit
from drake_clutter.planners.physics.penetration import segment_penetration
from drake_clutter.solvers import ilqr
from drake_clutter.solvers.ilqr import Expansion


class KinematicArm:
    """The arm alone as iLQR dynamics: state q^t (8), control q^(t+1), x_{t+1} = u_t."""

    def step(self, t: int, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The next configuration is the control."""
        return np.array(u, dtype=float)

    def linearize(self, xs: np.ndarray, us: np.ndarray):
        """A = 0, B = I at every interval."""
        T, n = len(us), xs.shape[1]
        return np.zeros((T, n, n)), np.repeat(np.eye(n)[None], T, axis=0)


class KinematicObjective:
    """Sec. V-A / V-B objectives over the state q^t (8) and control q^(t+1), boxes fixed.

    ``mode`` "pre": w_static_hull c_static_hull + w_dynamic c_dynamic (not the target) + w_vel
    c_vel per interval, c_grasp to
    ``p_pregrasp`` and c_grp_horiz at the end, their Table II
    weights times ``pre_terminal_weight`` (they stand in for the baseline's hard constraint).
    ``mode`` "post": w_static c_static (the mean over ``post_substeps`` configurations of
    the interval up to q^(t+1)) + w_match c_match + w_match_vel c_match_vel
    against ``q_ref`` (T + 1, 8), + w_speed c_speed over knots ``knot_time`` (s) apart (ours:
    pushing the arm out of the shelf made fig5's plan exceed a joint speed limit, measured).
    """

    def __init__(self, geometry: ArmGeometry, config: PhysicsConfig, mode: str, d_safe: float,
                 target: str, q_ref: np.ndarray | None = None,
                 p_pregrasp: np.ndarray | None = None, w_static_hull: float = 80.0,
                 w_vel: float = 1.0, knot_time: float = 0.2):
        if mode not in ("pre", "post"):
            raise ValueError(f"mode must be 'pre' or 'post', got {mode!r}")
        self.geometry, self.config, self.mode, self.d_safe = geometry, config, mode, d_safe
        self.target, self.q_ref, self.p_pregrasp = target, q_ref, p_pregrasp
        self.w_static_hull, self.w_vel = w_static_hull, w_vel
        self._max_step = max_steps(config, knot_time)

    def running(self, t: int, q: np.ndarray, u: np.ndarray) -> dict[str, Term]:
        """Weighted Terms over (q, u) (16,) of interval t."""
        cfg, eye = self.config, np.eye(ARM_DIM)
        if self.mode == "pre":
            hull = segment_penetration(self.geometry, q, u, cfg.hull_substeps, self.d_safe,
                                       (self.target,), spacing=cfg.sweep_spacing)
            return {"static_hull": hull["shelf"].scaled(self.w_static_hull),
                    "dynamic": hull["boxes"].scaled(cfg.w_dynamic),
                    "vel": _reorder(costs.velocity(u, q)).scaled(self.w_vel)}
        swept = segment_penetration(self.geometry, q, u, cfg.post_substeps, self.d_safe,
                                    shelf_only=True, spacing=cfg.sweep_spacing)
        on_u = np.hstack([np.zeros((ARM_DIM, ARM_DIM)), eye])
        match = costs.match(u, self.q_ref[t + 1])
        mvel = costs.match_velocity(u, q, self.q_ref[t + 1], self.q_ref[t])
        out = {"static": swept["shelf"].scaled(cfg.w_static),
               "match": match.pulled(on_u).scaled(cfg.w_match),
               "match_vel": _reorder(mvel).scaled(cfg.w_match_vel),
               "speed": speed_limit(q, u, self._max_step).scaled(cfg.w_speed)}
        return out

    def terminal(self, q: np.ndarray) -> dict[str, Term]:
        """Weighted Terms over q (8,) at the last knot ("pre" only)."""
        if self.mode != "pre":
            return {}
        p, axis_z, dp, dz = self.geometry.tool(q)
        grasp = costs.grasp(p, dp, self.p_pregrasp)
        grasp = Term(grasp.value, grasp.gradient[:ARM_DIM], grasp.hessian[:ARM_DIM, :ARM_DIM])
        w = self.config.pre_terminal_weight
        return {"grasp": grasp.scaled(w * self.config.w_grasp),
                "grp_horiz": costs.gripper_horizontal(axis_z, dz).scaled(
                    w * self.config.w_grp_horiz)}

    def terms(self, qs: np.ndarray, us: np.ndarray) -> dict[str, float]:
        """Weighted value of every term over the path."""
        out: dict[str, float] = {}
        for t in range(len(us)):
            for name, term in self.running(t, qs[t], us[t]).items():
                out[name] = out.get(name, 0.0) + term.value
        for name, term in self.terminal(qs[-1]).items():
            out[name] = term.value
        return out

    def quadratize(self, qs: np.ndarray, us: np.ndarray) -> Expansion:
        """Expansion over (q, u)."""
        T, n = len(us), ARM_DIM
        lx, lu = np.zeros((T, n)), np.zeros((T, n))
        lxx, luu, lux = np.zeros((T, n, n)), np.zeros((T, n, n)), np.zeros((T, n, n))
        for t in range(T):
            for term in self.running(t, qs[t], us[t]).values():
                lx[t] += term.gradient[:n]
                lu[t] += term.gradient[n:]
                lxx[t] += term.hessian[:n, :n]
                luu[t] += term.hessian[n:, n:]
                lux[t] += term.hessian[n:, :n]
        vx, vxx = np.zeros(n), np.zeros((n, n))
        for term in self.terminal(qs[-1]).values():
            vx += term.gradient
            vxx += term.hessian
        return Expansion(lx, lu, lxx, luu, lux, vx, vxx)


def _reorder(term: Term) -> Term:
    """A Term over (u, q) as one over (q, u)."""
    n = len(term.gradient) // 2
    p = np.r_[np.arange(n, 2 * n), np.arange(n)]
    return Term(term.value, term.gradient[p], term.hessian[np.ix_(p, p)])


def preprocess(context: PlanningContext, q_init: np.ndarray, deadline: float | None = None
               ) -> tuple[np.ndarray, ilqr.ILQRResult]:
    """Sec. V-A on a knot path (T + 1, 8): the path with less box contact (the capsule arm,
    the boxes at rest), and the solver's result (stopped at ``deadline``, see
    `solver_settings`)."""
    scene, config, geometry = context.scene, context.config, context.arm()
    objective = KinematicObjective(
        geometry, config.physics, "pre", config.baseline.d_safe, scene.target,
        p_pregrasp=geometry.tool(q_init[-1])[0], w_static_hull=config.baseline.w_static_hull,
        w_vel=config.baseline.w_vel)
    return _solve(objective, q_init, config.physics.pre_keep_pregrasp,
                  config.physics.pre_iterations, config, deadline)


def postprocess(context: PlanningContext, q_ref: np.ndarray, deadline: float | None = None
                ) -> tuple[np.ndarray, ilqr.ILQRResult]:
    """Sec. V-B on a knot path (T + 1, 8): c_static in the ``physics.post_variant`` geometry,
    c_match and c_match_vel to ``q_ref`` (stopped at ``deadline``, see `solver_settings`)."""
    scene, config = context.scene, context.config
    geometry = context.arm(config.physics.post_variant)
    objective = KinematicObjective(geometry, config.physics, "post", config.baseline.d_safe,
                                   scene.target, q_ref=q_ref,
                                   knot_time=config.baseline.knot_time)
    return _solve(objective, q_ref, config.physics.post_keep_end,
                  config.physics.post_iterations, config, deadline)


def _solve(objective: KinematicObjective, q: np.ndarray, keep: bool, iterations: int,
           config: Config, deadline: float | None) -> tuple[np.ndarray, ilqr.ILQRResult]:
    """Kinematic iLQR from the knot path ``q`` (T + 1, 8) under ``objective``: with ``keep``,
    the last knot and every gripper opening pinned to q's (`limits.knot_bounds`)."""
    bounds = knot_bounds(q, last_knot=keep, gripper=keep)
    settings = solver_settings(config, iterations, bounds=bounds, deadline=deadline)
    result = ilqr.solve(KinematicArm(), objective, q[0], q[1:], settings)
    return result.xs, result
