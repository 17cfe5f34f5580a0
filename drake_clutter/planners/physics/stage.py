"""Sec. V's phi stages: iLQR through phi from a knot path (`physics_stage`, with the restart
from the start path of `phi_stage_or_restart`), and ``select``'s reading of several paths in
one phi (`select_path`).

A stage's problem (`stage_problem`): phi as iLQR's dynamics over the augmented state
z = [x, q^(t-1)] (`AugmentedPhi`, its line-search forward passes run in the derivative workers),
the objective with the knots held after Delta (`HoldTail`), the cap on phi's box-to-box
Jacobians (`cap_spectral_radius`); built for a scene and a knot path: pruned phi, boxes settled
at the start, the arm variant's cost geometry. iLQR runs on z in tangent coordinates
(`ilqr.solve`, or the B-spline controls of `spline.solve_spline` with ``controls`` "spline"),
its controls within `limits.knot_bounds`. Knot paths are (T + 1, 8): the arm's 7 angles (rad)
and the gripper opening (m); times in s.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.phi.derivatives import PhiDynamics
from drake_clutter.phi.dynamics import initial_state, make_spec
from drake_clutter.phi.pruning import make_pruned_spec
from drake_clutter.phi.state import ARM_DIM, BOX_TANGENT, StateLayout, scene_box_states
from drake_clutter.phi.workers import WorkerPool
from drake_clutter.planners.approach import grasp_offset
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import pregrasp_aim
from drake_clutter.planners.physics.limits import GRIPPER, knot_bounds, solver_settings
from drake_clutter.planners.physics.objective import PhysicsObjective
from drake_clutter.solvers import ilqr, spline
from drake_clutter.trajectory import spline_basis

PARKED_TARGET = (0.0, 0.0, -10.0)  # m, where the sphere stage welds the target in phi (away
# from everything: out of the simulation)


class AugmentedPhi:
    """phi with the previous arm configuration appended: z = [x, q^(t-1)], tangent dz =
    [dx, dq^(t-1)]; ``linearize`` returns tangent Jacobians, ``difference`` the tangent
    difference (both for `ilqr.solve`). With ``parallel`` and a worker pool in ``dynamics``
    the line search's forward passes run in the workers (`forward_passes`), each followed by
    ``tail_knots`` knots of the held arm (`HoldTail`'s rollout) so the objective finds them."""

    def __init__(self, dynamics: PhiDynamics, max_spectral_radius: float = float("inf"),
                 parallel: bool = False, tail_knots: int = 0, cap_per_box: bool = False):
        self.dynamics, self.layout = dynamics, dynamics.layout
        self.nx, self.ndx = self.layout.nx, self.layout.ndx
        self.max_spectral_radius, self.cap_per_box = max_spectral_radius, cap_per_box
        self.parallel, self.tail_knots = parallel, tail_knots

    @property
    def parallel_passes(self) -> int:
        """Forward passes `forward_passes` runs at once (`ilqr`'s parallel line search)."""
        pool = getattr(self.dynamics, "pool", None)
        return pool.workers if self.parallel and pool is not None else 1

    def forward_passes(self, zs, us, k, K, alphas, lo, hi, limit) -> list:
        """`ilqr.forward_pass` (with this state difference) at each step size in ``alphas``,
        at once in the dynamics' workers: [(zs, us)]. Their phi steps, the held-arm tails
        included, are remembered by the dynamics as if stepped here."""
        spec = self.dynamics.spec
        tasks = [("call", spec.key, spec, _policy_pass,
                  (zs, us, k, K, alpha, lo, hi, limit, self.tail_knots)) for alpha in alphas]
        out = []
        for new_zs, new_us, records, failures in self.dynamics.pool.map(tasks):
            self.dynamics.remember_steps(records)
            self.dynamics.phi.failures += failures
            out.append((new_zs, new_us))
        return out

    def step(self, t: int, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """[phi(x, u), q^t]; all NaN when phi's result is not a state (non-finite, or a
        quaternion that lost its unit norm: SAP overflowing on a wild control)."""
        x = self.dynamics.step(t, z[:self.nx], u)
        if not self.layout.is_state(x):
            return np.full(len(z), np.nan)
        return np.concatenate([x, z[:ARM_DIM]])

    def linearize(self, zs: np.ndarray, us: np.ndarray):
        """A (T, nz, nz), B (T, nz, 8) in tangent coordinates."""
        A_x, B_x = self.dynamics.linearize_tangent(zs[:, :self.nx], us)
        cap_spectral_radius(A_x, self.max_spectral_radius, self.cap_per_box)
        T, nz = len(us), self.ndx + ARM_DIM
        A, B = np.zeros((T, nz, nz)), np.zeros((T, nz, ARM_DIM))
        A[:, :self.ndx, :self.ndx] = A_x
        A[:, self.ndx:, :ARM_DIM] = np.eye(ARM_DIM)  # q_prev' = q^t (x's arm part)
        B[:, :self.ndx] = B_x
        return A, B

    def difference(self, z_a: np.ndarray, z_b: np.ndarray) -> np.ndarray:
        """z_a (-) z_b in tangent coordinates."""
        return np.concatenate([self.layout.difference(z_a[:self.nx], z_b[:self.nx]),
                               z_a[self.nx:] - z_b[self.nx:]])


class _RecordedPhi:
    """A worker's `Phi` as the stepping half of `PhiDynamics` (``step(t, x, u)``,
    ``layout``), keeping every step's (x, u) and `Phi.step_full` result."""

    def __init__(self, phi):
        self.phi, self.layout, self.records = phi, phi.layout, []

    def step(self, t: int, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """phi(x, u), recorded (``t`` is unused: phi is time-invariant)."""
        result = self.phi.step_full(x, u)
        self.records.append(((np.array(x, dtype=float), np.array(u, dtype=float)), result))
        return result[0].copy()


def _policy_pass(phi, zs, us, k, K, alpha, lo, hi, limit, tail_knots: int):
    """Run in a derivative worker (`AugmentedPhi.forward_passes`): the forward pass over this
    worker's ``phi`` and, when it stayed finite, ``tail_knots`` knots with the arm held at its
    end (`HoldTail.tail`). Returns (zs, us, the steps as ((x, u), result), phi failures)."""
    recorded, failures = _RecordedPhi(phi), phi.failures
    augmented = AugmentedPhi(recorded)
    new_zs, new_us = ilqr.forward_pass(augmented, zs, us, k, K, alpha, lo, hi,
                                       augmented.difference, limit)
    if tail_knots and np.all(np.isfinite(new_zs)):
        ilqr.rollout(recorded, new_zs[-1][:augmented.nx], _held(new_zs[-1], tail_knots)[1])
    return new_zs, new_us, recorded.records, phi.failures - failures


def _held(z_last: np.ndarray, knots: int) -> tuple[np.ndarray, np.ndarray]:
    """The tail's hold after the last knot z_last (its arm configuration, (8,)) and the tail's
    controls, that hold repeated (knots, 8)."""
    hold = np.array(z_last[:ARM_DIM], dtype=float)
    return hold, np.tile(hold, (knots, 1))


class HoldTail:
    """The stage's objective plus the knots after Delta (Table II: c_force, c_motion and
    c_upright are active at "all" times, c_static and c_acc at t <= Delta): phi goes on for
    ``knots`` knots with the arm held still at q^Delta, and those knots' c_motion, c_upright
    and c_force add to the objective, so a box set toppling or sliding off by the last knots is
    paid for as it falls (Sec. III's evaluation replays until the boxes rest). The tail is a
    function of the last state alone, V(z_T) = sum_k c(y_k), y_0 = x_T, y_(k+1) = phi(y_k,
    q^Delta); its expansion enters the terminal vx, vxx through the chain of the tail's
    Jacobians, Gauss-Newton as iLQR treats its knots (its box blocks capped like the stage's).
    ``ilqr.Cost`` protocol over the augmented state z = [x, q^(t-1)] of `AugmentedPhi`."""

    def __init__(self, objective: PhysicsObjective, dynamics: PhiDynamics, knots: int,
                 max_spectral_radius: float = float("inf"), cap_per_box: bool = False):
        self.objective, self.dynamics, self.knots = objective, dynamics, knots
        self.max_spectral_radius, self.cap_per_box = max_spectral_radius, cap_per_box
        self.nx, self.ndx = dynamics.layout.nx, dynamics.layout.ndx

    def tail(self, z_last: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """States y_0..y_K (K + 1, nx) of the held arm after z_last, the hold (8,) and the
        tail's controls (K, 8)."""
        hold, holds = _held(z_last, self.knots)
        return self.dynamics.rollout(z_last[:self.nx], holds), hold, holds

    def _knot_terms(self, y: np.ndarray, hold: np.ndarray) -> dict:
        """Weighted terms (over dz) at a tail state: those of every knot but c_static."""
        terms = self.objective.state_terms(np.concatenate([y, hold]), terminal=False)
        terms.pop("static", None)
        return terms

    def terms(self, zs: np.ndarray, us: np.ndarray) -> dict[str, float]:
        """The objective's terms with the tail's added to c_motion, c_upright and c_force."""
        out = self.objective.terms(zs, us)
        ys, hold, holds = self.tail(zs[-1])
        if not np.all(np.isfinite(ys)):
            return {**out, "hold": float("inf")}
        for y in ys[1:]:
            for name, term in self._knot_terms(y, hold).items():
                out[name] = out.get(name, 0.0) + term.value
        if self.objective.forces is not None:
            for name, value in self.objective.phi_force_terms(ys[:-1], holds).items():
                out[name] = out.get(name, 0.0) + value
        return out

    def quadratize(self, zs: np.ndarray, us: np.ndarray) -> ilqr.Expansion:
        """The objective's expansion with the tail's in vx, vxx over x_T's tangent dx."""
        exp = self.objective.quadratize(zs, us)  # first: it reuses phi's last linearisation
        ys, hold, holds = self.tail(zs[-1])
        if not np.all(np.isfinite(ys)):
            return exp
        A, B = map(np.nan_to_num, self.dynamics.linearize_tangent(ys, holds))
        ndx = self.ndx
        A[:, :, :ARM_DIM] += B  # the hold is x_T's arm: du = dx_arm
        cap_spectral_radius(A, self.max_spectral_radius, self.cap_per_box)
        hold_rows = np.zeros((ARM_DIM, ndx))
        hold_rows[:, :ARM_DIM] = np.eye(ARM_DIM)
        J = np.eye(ndx)  # d y_k / d x_T
        forces = self.objective.forces is not None
        if forces:
            f, Fx, Fu = map(np.nan_to_num,
                            self.dynamics.linearize_forces(ys, holds))
            _, g, d = self.objective.force_cost(f)
        for k in range(self.knots):
            if forces:
                G = Fx[k] @ J + Fu[k] @ hold_rows
                exp.vx[:ndx] += G.T @ g[k]
                exp.vxx[:ndx, :ndx] += G.T @ (d[k][:, None] * G)
            J = A[k] @ J
            P = np.vstack([J, hold_rows])  # d z_k / d x_T, z_k = [y_k, hold]
            for term in self._knot_terms(ys[k + 1], hold).values():
                exp.vx[:ndx] += P.T @ term.gradient
                exp.vxx[:ndx, :ndx] += P.T @ term.hessian @ P
        return exp


def cap_spectral_radius(A: np.ndarray, cap: float, per_box: bool = False) -> np.ndarray:
    """Scales, in place, the box-to-box block of every tangent Jacobian A_t (T, ndx, ndx) whose
    spectral radius exceeds ``cap`` down to it; returns the radii before. The arm's rows are
    exact (zero: the arm is kinematic), so that block's radius is A_t's. With ``per_box``, each
    box whose own diagonal block (BOX_TANGENT square) has a radius above the cap has its rows of
    the block scaled down to it first, the others' rows kept (one toppling box no longer
    shrinks the target's dynamics with its own); the whole block is scaled only if its radius
    is still above the cap after that (boxes unstable together: two leaning on each other).

    Why: a box toppling or rocking on an edge is locally unstable (an inverted pendulum grows
    by e^(sqrt(g/l) 0.2 s) ~ 9 a knot), and phi's A_t had radii of 2-230 on fig8 (the same
    at FD steps 1e-6 to 1e-3: physics, not noise). Through 29 knots the costate V_x reached
    1e12 and every backward pass predicted more decrease than the whole objective, up to mu =
    1e10 (measured). Capped at 1, perturbations are modelled as persisting rather than
    growing; the line search on phi itself still accepts only real decreases."""
    radii = np.zeros(len(A))
    boxes = slice(ARM_DIM, A.shape[1])
    n_boxes = (A.shape[1] - ARM_DIM) // BOX_TANGENT
    for t in range(len(A)):
        block = A[t, boxes, boxes]
        if block.size == 0 or not np.all(np.isfinite(block)):
            continue
        radii[t] = _radius(block)
        if radii[t] <= cap:
            continue
        if per_box:
            for i in range(n_boxes):
                own = slice(BOX_TANGENT * i, BOX_TANGENT * (i + 1))
                r = _radius(block[own, own])
                if r > cap:
                    block[own] *= cap / r
        r = _radius(block) if per_box else radii[t]
        if r > cap:
            block *= cap / r
    return radii


def _radius(M: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(M))))


@dataclass
class StageProblem:
    """What a phi stage optimises: phi (`PhiDynamics`, and as iLQR sees it), the objective
    (with the hold tail), the start z0 = [x0, q^0] (boxes settled in phi), the pruning report
    and the boxes held out of c_force."""

    dynamics: PhiDynamics
    augmented: AugmentedPhi
    objective: PhysicsObjective | HoldTail
    z0: np.ndarray
    report: object
    held: tuple[str, ...]


@contextmanager
def stage_problem(context: PlanningContext, q: np.ndarray, variant: str,
                  pool: WorkerPool | None = None, knot_time: float | None = None,
                  also: tuple[np.ndarray, ...] = (), aim_T: np.ndarray | None = None):
    """The `StageProblem` of a phi stage (``variant`` arm) about the knot path ``q`` (T + 1, 8; phi
    pruned to it and to the paths ``also``), ``knot_time`` s apart (default ``baseline.knot_time``);
    its phi is closed on leaving the ``with`` block. ``aim_T``: c_grasp's point in the target's
    frame (m, `pregrasp_aim`; default: the gripper point at ``q``'s last knot, the target at rest).
    The objective's arm is the stage's own (`PlanningContext.fresh_arm`: it moves the boxes to phi's
    poses)."""
    scene, config = context.scene, context.config
    knot_time = knot_time or config.baseline.knot_time
    spec, report = make_pruned_spec(scene, q, None, knot_time, config.dynamics, config.world,
                                    variant, also)
    held = (scene.target,) if variant == "sphere_gripper" else ()
    if held and config.physics.sphere_target == "passes":
        dynamic = [*spec.dynamic_boxes, *[n for n in held if n not in spec.dynamic_boxes]]
        spec = make_spec(scene, dynamic, None, knot_time, config.dynamics, config.world,
                         variant, arm_passes=held)
        held = ()
    elif held:  # the sphere encloses the open gripper, where the target belongs at the end
        states = scene_box_states(scene)
        states[scene.target] = states[scene.target].copy()
        states[scene.target][4:7] = PARKED_TARGET
        spec = make_spec(scene, [n for n in spec.dynamic_boxes if n not in held], states,
                         knot_time, config.dynamics, config.world, variant)
    layout: StateLayout = spec.layout
    # The sphere reaches 3 cm below the board at the pre-grasp height: c_static keeps the
    # capsule gripper in that stage.
    static = context.arm() if variant == "sphere_gripper" else None
    cfg = config.physics
    geometry = context.fresh_arm(variant)
    offset = grasp_offset(config.baseline)
    if aim_T is None:
        aim_T = pregrasp_aim(geometry, q[-1], scene.target, offset)
    with PhiDynamics(spec, pool) as dynamics:
        x0 = dynamics.phi.settle(initial_state(layout, q[0], scene_box_states(scene)))
        objective = PhysicsObjective(geometry, layout, cfg, x0, scene.target, knot_time,
                                     config.baseline.d_safe, force_exclude=held,
                                     static_geometry=static, forces=dynamics,
                                     grasp_offset=offset, aim_T=aim_T)
        per_box = cfg.spectral_cap_scope == "box"
        augmented = AugmentedPhi(dynamics, cfg.max_spectral_radius, cfg.parallel_line_search,
                                 cfg.hold_knots, per_box)
        if cfg.hold_knots > 0:
            objective = HoldTail(objective, dynamics, cfg.hold_knots, cfg.max_spectral_radius,
                                 per_box)
        yield StageProblem(dynamics, augmented, objective, np.concatenate([x0, q[0]]), report,
                           held)


class PhiFailure(RuntimeError):
    """phi could not simulate a stage's initial path."""


def physics_stage(context: PlanningContext, q: np.ndarray, variant: str, iterations: int,
                  pool: WorkerPool | None = None, times: np.ndarray | None = None,
                  alternatives: tuple[np.ndarray, ...] = (), min_opening: float | None = None,
                  deadline: float | None = None, aim_T: np.ndarray | None = None
                  ) -> tuple[np.ndarray, ilqr.ILQRResult, dict]:
    """iLQR through phi (``variant`` arm) from the knot path ``q`` (T + 1, 8) at ``times`` (s;
    default: ``baseline.knot_time`` apart): the new path, the solver's result and what the
    stage used (kept boxes, pruning, phi statistics). With ``alternatives`` (paths of the same
    shape and start), iLQR starts from whichever of ``q`` and them has the lowest objective in
    this stage's phi (pruned for all of them); info's ``start_objectives`` lists them.
    ``min_opening``: the last knot's least gripper opening
    (m, `knot_bounds`); ``deadline``: see `solver_settings`; ``aim_T``: c_grasp's point in
    the target's frame (`geometry.pregrasp_aim`; default: ``q``'s last knot's)."""
    config = context.config
    knot_time = _knot_time(times, config)
    with stage_problem(context, q, variant, pool, knot_time, also=tuple(alternatives),
                       aim_T=aim_T) as problem:
        augmented, objective, z0 = problem.augmented, problem.objective, problem.z0
        starts = [q, *alternatives]
        basis = None
        if config.physics.controls == "spline":
            basis = spline_basis(len(q), config.physics.control_points,
                                 config.baseline.opt_spline_order)
            starts = [spline_path(basis, path) for path in starts]
        values = [_path_objective(augmented, objective, z0, path) for path in starts]
        if not np.any(np.isfinite(values)):
            raise PhiFailure("phi failed on the initial rollout")
        q = starts[int(np.argmin(values))]
        bounds = knot_bounds(q, min_final_opening=min_opening)
        settings = solver_settings(config, iterations, knot_time, bounds, deadline)
        if basis is None:
            result = ilqr.solve(augmented, objective, z0, q[1:], settings,
                                difference=augmented.difference)
        else:
            result = spline.solve_spline(augmented, objective, z0, q[1:], basis, q[0],
                                         settings, difference=augmented.difference)
        info = {"kept_boxes": list(augmented.layout.box_names),
                "pruning": problem.report.summary(),
                "phi_failures": problem.dynamics.phi.failures,
                "autodiff_fallbacks": problem.dynamics.autodiff_fallbacks,
                "start_objectives": [float(v) for v in values]}
    return np.vstack([q[:1], result.us]), result, info


def spline_path(basis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The knot path (T + 1, 8) nearest ``q`` (least squares) among the B-splines of ``basis``
    (T + 1, P + 1) that start at q[0]; a path that already is one comes back unchanged."""
    controls = spline.SplineControls(basis, q[0])
    return np.vstack([q[:1], controls.controls(controls.fit(q[1:]))])


def path_terms(dynamics: AugmentedPhi, objective: PhysicsObjective, z0: np.ndarray,
               q: np.ndarray) -> dict[str, float] | None:
    """A phi stage's objective per Table I term for the knot path ``q`` (T + 1, 8) rolled out
    from z0; None where phi's rollout is not finite."""
    zs = ilqr.rollout(dynamics, z0, q[1:])
    if not np.all(np.isfinite(zs)):
        return None
    return {k: float(v) for k, v in objective.terms(zs, q[1:]).items()}


def _path_objective(dynamics: AugmentedPhi, objective: PhysicsObjective, z0: np.ndarray,
                    q: np.ndarray) -> float:
    """The stage's objective of the knot path ``q`` rolled out from z0 (inf where phi fails)."""
    terms = path_terms(dynamics, objective, z0, q)
    return float("inf") if terms is None else float(sum(terms.values()))


def _knot_time(times: np.ndarray | None, config: Config) -> float:
    """The knots' spacing (s): of ``times``, else ``baseline.knot_time``."""
    return float(np.diff(times[:2])[0]) if times is not None else config.baseline.knot_time


def select_path(context: PlanningContext, paths: dict[str, np.ndarray], pool=None,
                times: np.ndarray | None = None, aim_T: np.ndarray | None = None
                ) -> tuple[str, dict]:
    """The name of the knot path (each (T + 1, 8), one start) with the lowest objective of the
    full stage (capsule arm, hold tail) in one phi pruned for all ``paths``, and what was
    measured: each path's objective (None where phi fails) and the pruning. Ties go to the
    earlier name; when phi fails on every path, the first. ``aim_T``: c_grasp's point in the
    target's frame (default: the first path's last knot's)."""
    knot_time = _knot_time(times, context.config)
    names = list(paths)
    first, *others = (paths[n] for n in names)
    with stage_problem(context, first, "capsules", pool, knot_time, also=tuple(others),
                       aim_T=aim_T) as problem:
        values = {n: _path_objective(problem.augmented, problem.objective, problem.z0,
                                     paths[n]) for n in names}
        pruning = problem.report.summary()
    chosen = min(names, key=lambda n: (values[n], names.index(n)))
    finite = {n: (v if np.isfinite(v) else None) for n, v in values.items()}
    return chosen, {"objectives": finite, "chosen": chosen, "pruning": pruning}


def phi_stage_or_restart(context: PlanningContext, paths: tuple[np.ndarray, np.ndarray],
                          variant: str, iterations: int, pool, times,
                          alternatives: tuple[np.ndarray, ...] = (),
                          deadline: float | None = None, aim_T: np.ndarray | None = None):
    """`physics_stage` from ``paths[0]`` (or the best of ``alternatives``, see there); if phi
    cannot simulate any of them, from ``paths[1]`` (the baseline's path: phi failed on paths
    the pre-processing or sphere stage produced with the hydroelastic phi, measured on
    fig7); its info says which."""
    opening = (float(paths[1][-1, GRIPPER]) if context.config.physics.keep_open else None)
    try:
        q, result, info = physics_stage(context, paths[0], variant, iterations, pool,
                                        times, alternatives, opening, deadline, aim_T=aim_T)
        best = int(np.argmin(info["start_objectives"]))
        return q, result, {**info, "started_from": "previous stage" if best == 0 else
                           f"alternative {best}"}
    except PhiFailure as exc:
        if np.array_equal(paths[0], paths[1]):
            raise
        q, result, info = physics_stage(context, paths[1], variant, iterations, pool,
                                        times, min_opening=opening, deadline=deadline,
                                        aim_T=aim_T)
        return q, result, {**info, "started_from": f"baseline ({exc})"}
