"""The baseline planner of Sec. IV: straight-line approaches, optimised against the static shelf.

Per approach angle alpha (see `approach`): IK gives the start and pre-grasp configurations;
linear interpolation in joint space over ``num_knots`` knots, ``knot_time`` seconds apart, is the
initial path; an optimisation through Drake's `MathematicalProgram` (SNOPT, IPOPT as fallback)

    min  w_static_hull * sum_t c_static_hull^t + w_vel * sum_t ||q^t - q^(t-1)||^2
    s.t. the tool frame at the last knot stays at the pre-grasp pose (position and rotation)

reshapes the path (knot 1, the start, is fixed; the gripper stays open), and a dense check
then accepts or rejects the result. The boxes are ignored, as in the paper.

The knots are samples of a clamped cubic B-spline whose control points are the decision
variables (`PathOptimiser.build` says why). c_static_hull is `clearance.static_hull_cost`:
sub-sampled between knots, with Table I's penetration made C1. (A squared hinge, also C1, was
tried first: with w_static_hull = 80 it is too weak at contact, 2 * 80 * d_safe = 3.2 per
metre against 80, and SNOPT traded 6-8 mm of penetration for a shorter path.)

Units: joint angles in rad, distances in m, times in s; the tool frame G and the world W as
in `approach`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue
from pydrake.math import RigidTransform
from pydrake.multibody.inverse_kinematics import OrientationConstraint, PositionConstraint
from pydrake.solvers import IpoptSolver, MathematicalProgram, SnoptSolver, SolverOptions

from drake_clutter.common.config import BaselineConfig, check_config
from drake_clutter.planners.approach import (
    ARM_DOF,
    CONTINUOUS_JOINTS,
    GripperExtent,
    PoseIk,
    approach_angles,
    approach_poses,
    gripper_extent,
    ik_seeds,
    quiet_drake_warnings,
    static_planning_world,
)
from drake_clutter.planners.clearance import (
    OPENING,
    ShelfClearance,
    dense_check,
    static_hull_cost,
    velocity_cost,
)
from drake_clutter.planners.clearance import smooth_penetration as smooth_penetration  # re-exported
from drake_clutter.robot import pr2
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate, CandidateStatus, Trajectory, spline_basis
from drake_clutter.worlds.drake_world import World

# ----------------------------------------------------------------------------- optimisation


@dataclass
class OptResult:
    """The optimised path (T, 7 arm angles), the solver that gave it and how it ended."""

    q: np.ndarray
    solver: str
    solver_status: str
    feasible: bool
    cost: float
    evaluations: int


def interpolate(q_start: np.ndarray, q_end: np.ndarray, num_knots: int) -> np.ndarray:
    """Linear interpolation in joint space: (num_knots, n) rows from q_start to q_end."""
    s = np.linspace(0.0, 1.0, num_knots)[:, None]
    return (1.0 - s) * q_start + s * q_end



class PathMap:
    """Knots (T, 7) from control points 2..K (first control point fixed), and the pullback
    of a gradient over the knots to one over those control points (flattened)."""

    def __init__(self, basis: np.ndarray, q_first: np.ndarray):
        self.basis = basis
        self.offset = np.outer(basis[:, 0], q_first)

    def __call__(self, values) -> np.ndarray:
        points = np.reshape(values, (self.basis.shape[1] - 1, ARM_DOF))
        return self.offset + self.basis[:, 1:] @ points

    def pullback(self, grad_knots: np.ndarray) -> np.ndarray:
        return (self.basis[:, 1:].T @ grad_knots).ravel()


class PathOptimiser:
    """Sec. IV's optimisation of one path in a static planning world (see the module doc)."""

    def __init__(self, world: World, clearance: ShelfClearance, config: BaselineConfig):
        self.world, self.clearance, self.config = world, clearance, config
        self.plant_context = world.plant.CreateDefaultContext()
        limits = np.array(list(pr2.arm_joint_limits().values()))
        self.lower, self.upper = limits[:, 0], limits[:, 1]
        speeds = pr2.velocity_limits()
        self.max_step = (config.velocity_limit_scale * config.knot_time
                         * np.array([speeds[name] for name in pr2.ARM_JOINTS]))

    def _terminal_constraints(self, X_WG: RigidTransform):
        plant, tol = self.world.plant, self.config.ik_position_tolerance
        p = X_WG.translation()
        position = PositionConstraint(plant, plant.world_frame(), p - tol, p + tol,
                                      self.world.tool_frame, np.zeros(3), self.plant_context)
        rotation = OrientationConstraint(plant, plant.world_frame(), X_WG.rotation(),
                                         self.world.tool_frame, RigidTransform().rotation(),
                                         self.config.ik_orientation_tolerance,
                                         self.plant_context)
        return position, rotation

    def _bounds(self, q_init: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint limits (7,) each; continuous rolls within pi of the initial path's span."""
        lower, upper = self.lower.copy(), self.upper.copy()
        for j in CONTINUOUS_JOINTS:
            lower[j] = q_init[:, j].min() - np.pi
            upper[j] = q_init[:, j].max() + np.pi
        return lower, upper

    def build(self, q_init: np.ndarray, X_WG: RigidTransform, substeps: int):
        """The MathematicalProgram, its control-point variables (K-1, 7) and a counter.

        The path's knots are samples of a clamped uniform B-spline (`spline_basis`) whose
        first control point is the start configuration (knot 1 fixed) and whose last is the
        last knot. The variables are control points 2..K: K = ``opt_control_points`` is far
        fewer than the 29 free knots, and SNOPT's dense reduced-Hessian QP costs grow about
        cubically with the number of free variables (see the benchmark). Joint limits bound
        the control points, which keeps every knot within them (a B-spline point is a convex
        combination of control points). With ``fix_last_knot`` the last control point is the
        initial path's last knot; otherwise it is free under Drake's tool-frame position and
        orientation constraints. Both cost terms are one Python cost with a NumPy gradient.
        """
        basis = spline_basis(len(q_init), self.config.opt_control_points,
                             self.config.opt_spline_order)
        q_first = q_init[0]
        guess = np.linalg.lstsq(basis[:, 1:], q_init - np.outer(basis[:, 0], q_first),
                                rcond=None)[0]
        prog = MathematicalProgram()
        points = prog.NewContinuousVariables(len(guess), ARM_DOF, "p")
        lower, upper = self._bounds(q_init)
        prog.AddBoundingBoxConstraint(np.tile(lower, len(guess)), np.tile(upper, len(guess)),
                                      points.ravel())
        self._add_velocity_limits(prog, points, basis, q_first)
        if self.config.fix_last_knot:
            prog.AddBoundingBoxConstraint(q_init[-1], q_init[-1], points[-1])
            guess[-1] = q_init[-1]
        else:
            fingers = prog.NewContinuousVariables(2, "finger")
            prog.AddBoundingBoxConstraint(self.clearance.fingers, self.clearance.fingers,
                                          fingers)
            for constraint in self._terminal_constraints(X_WG):
                prog.AddConstraint(constraint, np.concatenate([points[-1], fingers]))
            prog.SetInitialGuess(fingers, self.clearance.fingers)
        counter = {"evaluations": 0}
        path = PathMap(basis, q_first)

        def cost(z):
            counter["evaluations"] += 1
            autodiff = z.dtype == object
            value, grad = self.path_cost(path(ExtractValue(z) if autodiff else z), substeps)
            if not autodiff:
                return value
            return AutoDiffXd(value, path.pullback(grad) @ ExtractGradient(z))

        prog.AddCost(cost, points.ravel())
        prog.SetInitialGuess(points, guess)
        return prog, points, path, counter

    def _add_velocity_limits(self, prog, points, basis: np.ndarray, q_first) -> None:
        """|q_t - q_(t-1)| <= velocity_limit_scale * (PR2 joint speed limit) * knot_time, per
        joint: linear in the control points."""
        steps = np.diff(basis, axis=0)  # (T-1, K): knot steps = steps @ control points
        bound = np.tile(self.max_step, len(steps))
        offset = np.kron(steps[:, :1], np.eye(ARM_DOF)) @ q_first
        prog.AddLinearConstraint(np.kron(steps[:, 1:], np.eye(ARM_DOF)), -bound - offset,
                                 bound - offset, points.ravel())

    def path_cost(self, q: np.ndarray, substeps: int) -> tuple[float, np.ndarray]:
        """w_static_hull * sum c_static_hull + w_vel * sum c_vel of a path (T, 7) with
        ``substeps`` samples per knot interval, and its gradient (T, 7)."""
        config = self.config
        hull, grad_hull = static_hull_cost(self.clearance, q, config.d_safe, substeps)
        step = np.diff(q, axis=0)
        grad_vel = np.zeros_like(q)
        grad_vel[1:] += 2.0 * step
        grad_vel[:-1] -= 2.0 * step
        value = config.w_static_hull * hull + config.w_vel * float(np.sum(step**2))
        return value, config.w_static_hull * grad_hull + config.w_vel * grad_vel

    def optimise(self, q_init: np.ndarray, X_WG: RigidTransform,
                 substeps: int | None = None) -> OptResult:
        """Optimises ``q_init`` (T, 7), knot 1 fixed, with ``substeps`` samples per interval in
        c_static_hull (default ``opt_substeps``); SNOPT first, IPOPT if SNOPT's answer breaks
        the terminal constraints. Solver failures come back as ``feasible=False``."""
        substeps = substeps or self.config.opt_substeps
        result = None
        for name, solver in (("snopt", SnoptSolver()), ("ipopt", IpoptSolver())):
            if not (solver.available() and solver.enabled()):
                continue
            result = self._solve_with(name, solver, q_init, X_WG, substeps)
            if result.feasible:
                return result
        if result is None:
            raise RuntimeError("neither SNOPT nor IPOPT is available in this drake build")
        return result

    def _solve_with(self, name, solver, q_init, X_WG, substeps) -> OptResult:
        prog, points, path, counter = self.build(q_init, X_WG, substeps)
        try:
            with quiet_drake_warnings():
                result = solver.Solve(prog, None, self._options(name))
        except RuntimeError as exc:  # a solver error is an outcome, not a crash
            return OptResult(q_init, name, f"solver error: {exc}", False, np.inf,
                             counter["evaluations"])
        q = path(result.GetSolution(points))
        feasible = bool(np.all(np.isfinite(q))) and self.keeps_pose(q[-1], X_WG)
        status = str(result.get_solution_result()).split(".")[-1]
        return OptResult(q, name, status, feasible, float(result.get_optimal_cost()),
                         counter["evaluations"])

    def pose_error(self, q_arm, X_WG: RigidTransform) -> tuple[float, float]:
        """(position error m, rotation error rad) of the tool frame at ``q_arm`` vs ``X_WG``."""
        self.clearance.set_arm(q_arm)
        X = self.world.tool_frame.CalcPoseInWorld(self.clearance.context)
        angle = X.rotation().InvertAndCompose(X_WG.rotation()).ToAngleAxis().angle()
        return float(np.linalg.norm(X.translation() - X_WG.translation())), float(angle)

    def keeps_pose(self, q_arm, X_WG: RigidTransform) -> bool:
        """Whether the tool frame at ``q_arm`` is at ``X_WG`` within the terminal tolerances."""
        position, rotation = self.pose_error(q_arm, X_WG)
        return (position <= self.config.terminal_position_tolerance
                and rotation <= self.config.terminal_rotation_tolerance)

    def _options(self, name: str) -> SolverOptions:
        options = SolverOptions()
        limit = self.config.opt_max_iterations
        if name == "snopt":
            options.SetOption(SnoptSolver.id(), "Major iterations limit", limit)
            options.SetOption(SnoptSolver.id(), "Major optimality tolerance",
                              float(self.config.opt_optimality_tolerance))
        else:
            options.SetOption(IpoptSolver.id(), "max_iter", limit)
            options.SetOption(IpoptSolver.id(), "tol", float(self.config.opt_optimality_tolerance))
            options.SetOption(IpoptSolver.id(), "print_level", 0)
        return options


# ----------------------------------------------------------------------------- the planner


@dataclass
class _Context:
    """What one scene's angles share: the world, IK, distances, optimiser, gripper extent."""

    scene: Scene
    config: BaselineConfig
    world: World
    ik: PoseIk
    clearance: ShelfClearance
    optimiser: PathOptimiser
    extent: GripperExtent
    previous: list = field(default_factory=list)


def _trajectory(q_arm: np.ndarray, knot_time: float) -> Trajectory:
    q = np.column_stack([q_arm, np.full(len(q_arm), OPENING)])
    return Trajectory(np.arange(len(q_arm)) * knot_time, q)


def _end_configurations(ctx: _Context, poses, index: int, timings: dict):
    """IK of the pre-grasp and start poses: (q_start, q_end, solvers) or a failure reason."""
    config = ctx.config
    end = ctx.ik.solve(poses.X_WPregrasp, ik_seeds(config, ctx.previous[-1:], index))
    timings["ik"] = end.seconds
    if end.q is None:
        return f"pre-grasp pose: {end.reason}"
    ctx.previous.append(end.q)
    start = ctx.ik.solve(poses.X_WStart, ik_seeds(config, [end.q], index), q_near=end.q)
    timings["ik"] += start.seconds
    if start.q is None:
        return f"start pose: {start.reason}"
    # The start was pulled towards the pre-grasp solution; pull a pre-grasp solution back
    # towards the start too and keep it if the pair is closer (the same IK branch).
    closer = ctx.ik.solve(poses.X_WPregrasp, [start.q, end.q], q_near=start.q)
    timings["ik"] += closer.seconds
    if closer.q is not None and (np.linalg.norm(closer.q - start.q)
                                 < np.linalg.norm(end.q - start.q)):
        end = closer
    return start.q, end.q, [start.solver, end.solver]


def _optimise_and_check(ctx: _Context, q_init, X_WG, timings: dict, details: dict):
    """The optimisation, then the dense check; when the check finds penetration, one more
    optimisation from that result with ``opt_refine_substeps`` samples per interval (the
    motion between the first pass's samples can exceed d_safe where the arm swings fast).
    Returns (OptResult, CheckResult or None when the optimisation failed)."""
    config = ctx.config
    tic = time.perf_counter()
    opt = ctx.optimiser.optimise(q_init, X_WG)
    check = dense_check(ctx.clearance, opt.q, config) if opt.feasible else None
    checking = check.seconds if check else 0.0
    details["opt_passes"] = 1
    if check is not None and not check.passed and config.opt_refine_substeps > 0:
        second = ctx.optimiser.optimise(opt.q, X_WG, config.opt_refine_substeps)
        details["opt_passes"] = 2
        if second.feasible:
            opt, check = second, dense_check(ctx.clearance, second.q, config)
            checking += check.seconds
    timings["optimisation"] = time.perf_counter() - tic - checking
    if check is not None:
        timings["check"] = checking
    return opt, check


def plan_angle(ctx: _Context, alpha: float, index: int) -> Candidate:
    """One approach angle: IK, interpolation, optimisation, dense check -> a Candidate."""
    config = ctx.config
    poses = approach_poses(ctx.scene, alpha, config, ctx.extent)
    details = {"height": poses.height,
               "start_xyz": poses.X_WStart.translation().tolist(),
               "pregrasp_xyz": poses.X_WPregrasp.translation().tolist()}
    timings: dict[str, float] = {}
    ends = _end_configurations(ctx, poses, index, timings)
    if isinstance(ends, str):
        return Candidate(alpha, CandidateStatus.IK_FAILED, ends, None, timings=timings,
                         details=details)
    q_start, q_end, details["ik_solvers"] = ends
    q_init = interpolate(q_start, q_end, config.num_knots)
    opt, check = _optimise_and_check(ctx, q_init, poses.X_WPregrasp, timings, details)
    details.update(_opt_details(ctx, q_init, opt, poses.X_WPregrasp))
    trajectory = _trajectory(opt.q, config.knot_time)
    if check is None:
        return Candidate(alpha, CandidateStatus.OPTIMISATION_FAILED,
                         f"{opt.solver}: {opt.solver_status}, terminal pose not kept",
                         trajectory, timings=timings, details=details)
    details.update({"max_penetration": check.depth, "check_samples": check.samples})
    if not check.passed:
        return Candidate(alpha, CandidateStatus.COLLISION_CHECK_FAILED,
                         f"penetrates the shelf by {check.depth * 1000:.1f} mm ({check.where}) "
                         f"at t = {check.time:.2f} s", trajectory, timings=timings,
                         details=details)
    return Candidate(alpha, CandidateStatus.OK, "", trajectory, timings=timings, details=details)


def _opt_details(ctx: _Context, q_init, opt: OptResult, X_WG) -> dict:
    """What the optimisation did: solver, status, evaluations, unweighted costs before/after
    (c_static_hull at opt_substeps), and the last knot's pose error (m, rad)."""
    config = ctx.config
    hull0 = static_hull_cost(ctx.clearance, q_init, config.d_safe, config.opt_substeps)[0]
    hull = static_hull_cost(ctx.clearance, opt.q, config.d_safe, config.opt_substeps)[0]
    position_error, rotation_error = ctx.optimiser.pose_error(opt.q[-1], X_WG)
    return {"opt_solver": opt.solver, "opt_status": opt.solver_status,
            "opt_evaluations": opt.evaluations,
            "c_static_hull": [hull0, hull], "c_vel": [velocity_cost(q_init),
                                                      velocity_cost(opt.q)],
            "terminal_position_error": position_error,
            "terminal_rotation_error": rotation_error}


def prepare(scene: Scene, config: BaselineConfig) -> _Context:
    """Builds what the angles of one scene share (the static planning world and its solvers)."""
    world = static_planning_world(scene)
    clearance = ShelfClearance(world)
    return _Context(scene, config, world, PoseIk(world, config), clearance,
                    PathOptimiser(world, clearance, config), gripper_extent(world))






def plan_baseline(scene: Scene, config: BaselineConfig | None = None,
                  alphas=None) -> list[Candidate]:
    """Sec. IV's baseline on ``scene``: one Candidate per approach angle (rad; default
    `approach.approach_angles`), in order. IK failures, solver failures and paths that fail
    the dense check are candidates with that status and a reason; nothing is raised for them
    (a nonsensical configuration raises ConfigError).
    """
    config = config or BaselineConfig()
    check_config(config, section="baseline")
    alphas = approach_angles(config) if alphas is None else np.asarray(alphas, dtype=float)
    ctx = prepare(scene, config)
    return [plan_angle(ctx, float(alpha), i) for i, alpha in enumerate(alphas)]


def candidates_table(candidates: list[Candidate]) -> str:
    """A text table, one row per angle: alpha, status, IK / optimisation / check times (s),
    deepest penetration found by the dense check (mm) and the reason."""
    rows = [f"{'alpha':>7} {'status':22} {'ik s':>6} {'opt s':>6} {'check s':>7} "
            f"{'pen mm':>6}  reason"]
    for c in candidates:
        t = c.timings
        pen = c.details.get("max_penetration")
        rows.append(f"{c.alpha:+7.3f} {c.status:22} {t.get('ik', 0.0):6.3f} "
                    f"{t.get('optimisation', 0.0):6.3f} {t.get('check', 0.0):7.3f} "
                    f"{'-' if pen is None else f'{pen * 1000:.1f}':>6}  {c.reason}")
    return "\n".join(rows)
