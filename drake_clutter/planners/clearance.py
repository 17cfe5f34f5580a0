"""A joint path against the static shelf (Sec. IV): arm-vs-shelf signed distances with their
gradients, Table I's penetration, the sub-sampled static-hull cost, the path optimisation that
lowers it (`PathOptimiser`, `optimise_and_check`) and the dense check that accepts the result.

The static planning world (`approach.static_planning_world`) holds the arm and the shelf only,
so every pair SceneGraph reports is an arm geometry against a shelf part. A path is a (T, 7)
array of arm angles (rad) at knots, linear in joint space between knots; the gripper is held
fully open. c_static_hull^t approximates the penetration of the convex hull of each link's
poses at knots t-1 and t (Table I) by the mean, over ``substeps`` configurations evenly spaced
on the joint-space segment (t-1, t], of the sum over (arm geometry, shelf part) pairs of
Table I's penetration: 0 at d_safe apart, linear in depth once the shapes touch, quadratic in
between (`smooth_penetration`), which makes the cost C1 for SNOPT. Gradients come from the
plant's translational Jacobians at the witness points: d(distance)/dq = n^T J, n the unit
normal that moves the arm's point away from the shelf. (A squared hinge, also C1, was tried
first: with w_static_hull = 80 it is too weak at contact, 2 * 80 * d_safe = 3.2 per metre
against 80, and SNOPT traded 6-8 mm of penetration for a shorter path.)

The optimisation (Drake's `MathematicalProgram`, SNOPT, IPOPT as fallback)

    min  w_static_hull * sum_t c_static_hull^t + w_vel * sum_t ||q^t - q^(t-1)||^2
    s.t. the tool frame at the last knot stays at the pre-grasp pose (position and rotation)

reshapes the path (knot 1, the start, is fixed); its knots are samples of a clamped cubic
B-spline whose control points are the decision variables (`PathOptimiser.build` says why).
Distances in m, angles in rad, times in s.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue
from pydrake.math import RigidTransform
from pydrake.multibody.inverse_kinematics import OrientationConstraint, PositionConstraint
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.solvers import IpoptSolver, MathematicalProgram, SnoptSolver, SolverOptions

from drake_clutter.common.config import BaselineConfig, Config
from drake_clutter.planners.approach import CONTINUOUS_JOINTS, quiet_drake_warnings
from drake_clutter.robot import pr2
from drake_clutter.robot.pr2 import ARM_DOF
from drake_clutter.trajectory import Trajectory, plan_limit_violation, spline_basis
from drake_clutter.worlds.drake_world import World

OPENING = pr2.GRIPPER_MAX_OPENING  # m: the gripper stays fully open (Sec. V: c_grp_open)


# ----------------------------------------------------------------------------- distances


@dataclass(frozen=True)
class Contact:
    """One arm-vs-shelf pair: signed distance (m), the arm's witness point in its body frame,
    the unit normal in W along which moving that point increases the distance, and names."""

    distance: float
    body_index: object
    p_BC: np.ndarray
    n_W: np.ndarray
    arm_geometry: str
    shelf_geometry: str


class ShelfClearance:
    """Arm-vs-shelf signed distances in a static planning world, and the penetration cost.

    The world must have no boxes (`approach.static_planning_world`): its plant positions are
    the 7 arm joints then the 2 finger slides. The gripper is held fully open.
    """

    def __init__(self, world: World):
        index = world.robot_position_indices()
        if world.plant.num_positions() != len(index) or list(index) != list(range(len(index))):
            raise ValueError("ShelfClearance needs a world whose positions are the robot's only")
        self.world, self.plant = world, world.plant
        self.root = world.diagram.CreateDefaultContext()
        self.context = self.plant.GetMyMutableContextFromRoot(self.root)
        self.fingers = np.full(2, pr2.finger_joint_position(OPENING))
        inspector = world.scene_graph.model_inspector()
        robot_frames = {self.plant.GetBodyFrameIdOrThrow(i): i
                        for i in self.plant.GetBodyIndices(world.robot)}
        self._robot_geometry = {}  # geometry id -> (body index, X_BG)
        for gid in inspector.GetAllGeometryIds():
            body = robot_frames.get(inspector.GetFrameId(gid))
            if body is not None:
                self._robot_geometry[gid] = (body, inspector.GetPoseInFrame(gid))
        self._names = {gid: inspector.GetName(gid) for gid in inspector.GetAllGeometryIds()}

    def set_arm(self, q_arm) -> None:
        """Puts the arm at ``q_arm`` (7 angles, rad) with the gripper open."""
        self.plant.SetPositions(self.context, np.concatenate([q_arm, self.fingers]))

    def contacts(self, q_arm, max_distance: float) -> list[Contact]:
        """Every arm-vs-shelf pair closer than ``max_distance`` (m) at ``q_arm``."""
        self.set_arm(q_arm)
        query = self.plant.get_geometry_query_input_port().Eval(self.context)
        found = []
        for pair in query.ComputeSignedDistancePairwiseClosestPoints(max_distance):
            if pair.id_A in self._robot_geometry:
                arm, shelf, p_GC, n = pair.id_A, pair.id_B, pair.p_ACa, pair.nhat_BA_W
            else:
                arm, shelf, p_GC, n = pair.id_B, pair.id_A, pair.p_BCb, -pair.nhat_BA_W
            body, X_BG = self._robot_geometry[arm]
            found.append(Contact(pair.distance, body, X_BG.multiply(p_GC), np.asarray(n),
                                 self._names[arm], self._names[shelf]))
        return found

    def penetration(self, q_arm, d_safe: float) -> tuple[float, np.ndarray]:
        """sum over pairs of `smooth_penetration` (m) at ``q_arm``, and its gradient (7,)."""
        value, grad = 0.0, np.zeros(ARM_DOF)
        for contact in self.contacts(q_arm, d_safe):
            if not np.all(np.isfinite(contact.n_W)):
                continue  # a degenerate normal (exact touching of some shapes): no direction
            v, slope = smooth_penetration(d_safe - contact.distance, d_safe)
            value += v
            J = self.plant.CalcJacobianTranslationalVelocity(
                self.context, JacobianWrtVariable.kQDot,
                self.plant.get_body(contact.body_index).body_frame(), contact.p_BC,
                self.plant.world_frame(), self.plant.world_frame())
            grad -= slope * (contact.n_W @ J[:, :ARM_DOF])
        return value, grad

    def deepest(self, q_arm) -> tuple[float, str]:
        """Penetration depth (m, >= 0; 0 when nothing touches) at ``q_arm`` and the pair's name."""
        worst, name = 0.0, ""
        for contact in self.contacts(q_arm, 0.0):
            if -contact.distance > worst:
                worst, name = -contact.distance, f"{contact.arm_geometry}/{contact.shelf_geometry}"
        return worst, name


def smooth_penetration(gap: float, d_safe: float) -> tuple[float, float]:
    """Table I's penetration, made C1: ``gap`` = d_safe - signed distance (m) > 0. Linear,
    ``gap - d_safe / 2``, once the shapes touch (gap >= d_safe); quadratic inside the margin,
    ``gap^2 / (2 d_safe)``, so value and slope are continuous. Returns (value, d value/d gap).
    """
    if gap >= d_safe:
        return gap - 0.5 * d_safe, 1.0
    return 0.5 * gap * gap / d_safe, gap / d_safe


def segment_samples(num_knots: int, substeps: int) -> tuple[np.ndarray, np.ndarray]:
    """Sub-samples of the joint-space segments between knots: (interval, fraction) pairs.

    For each interval i (knots i and i+1, 0-based) the fractions k/substeps, k = 1..substeps,
    so every sample lies in (knot i, knot i+1] and the first knot is never sampled.
    """
    fractions = np.arange(1, substeps + 1) / substeps
    intervals = np.repeat(np.arange(num_knots - 1), substeps)
    return intervals, np.tile(fractions, num_knots - 1)


def static_hull_cost(clearance: ShelfClearance, q: np.ndarray, d_safe: float,
                     substeps: int) -> tuple[float, np.ndarray]:
    """sum_t c_static_hull^t of a path ``q`` (T, 7) and its gradient (T, 7) (see module doc)."""
    intervals, fractions = segment_samples(len(q), substeps)
    value, grad = 0.0, np.zeros_like(q)
    for i, lam in zip(intervals, fractions, strict=True):
        v, g = clearance.penetration((1.0 - lam) * q[i] + lam * q[i + 1], d_safe)
        if v > 0.0:
            value += v / substeps
            grad[i] += (1.0 - lam) * g / substeps
            grad[i + 1] += lam * g / substeps
    return value, grad


def velocity_cost(q: np.ndarray) -> float:
    """sum_t ||q^t - q^(t-1)||^2 of a path (T, n) (Table I's c_vel)."""
    return float(np.sum(np.diff(q, axis=0) ** 2))


# ----------------------------------------------------------------------------- dense check


@dataclass
class CheckResult:
    """Dense check of a path: passed, the deepest penetration (m), the pair, when (s), how
    many configurations were checked, and how long the check took (s)."""

    passed: bool
    depth: float
    where: str
    time: float
    samples: int
    seconds: float = 0.0


def dense_check(clearance: ShelfClearance, q: np.ndarray, config: BaselineConfig) -> CheckResult:
    """Checks ``check_substeps`` configurations per knot interval (and the first knot) of path
    ``q`` (T, 7): passes when no arm proxy penetrates the shelf by more than check_tolerance."""
    tic = time.perf_counter()
    intervals, fractions = segment_samples(len(q), config.check_substeps)
    samples = [(0, 0.0)] + list(zip(intervals, fractions, strict=True))
    depth, where, when = 0.0, "", 0.0
    for i, lam in samples:
        d, name = clearance.deepest((1.0 - lam) * q[i] + lam * q[i + 1] if lam else q[i])
        if d > depth:
            depth, where, when = d, name, (i + lam) * config.knot_time
    return CheckResult(depth <= config.check_tolerance, depth, where, when, len(samples),
                       time.perf_counter() - tic)


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



def judge_feasible(q: np.ndarray, times: np.ndarray, clearance: ShelfClearance,
                   config: Config) -> bool:
    """Whether a knot path (T + 1, 8, at ``times`` s) keeps the judge's joint and speed limits
    (`trajectory.plan_limit_violation`) and passes the baseline's dense shelf check."""
    return (not plan_limit_violation(Trajectory(np.asarray(times, float), q), config.evaluation)
            and dense_check(clearance, q[:, :ARM_DOF], config.baseline).passed)

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


def optimise_and_check(optimiser: PathOptimiser, q_start: np.ndarray, q_end: np.ndarray,
                       X_WG: RigidTransform, timings: dict
                       ) -> tuple[OptResult, CheckResult | None, dict]:
    """Sec. IV on one straight path: the joint-space line from ``q_start`` to ``q_end`` (7
    angles each, rad) over ``num_knots`` knots, optimised with the tool frame's last pose kept
    at ``X_WG`` (W), then the dense check; when the check finds penetration, one more
    optimisation from that result with ``opt_refine_substeps`` samples per interval (the
    motion between the first pass's samples can exceed d_safe where the arm swings fast).
    Returns (OptResult, CheckResult or None when the optimisation failed, what the
    optimisation did: ``opt_passes`` and `_opt_details`); ``timings`` gets the optimisation
    and check seconds.
    """
    config, clearance = optimiser.config, optimiser.clearance
    q_init = interpolate(q_start, q_end, config.num_knots)
    tic = time.perf_counter()
    opt = optimiser.optimise(q_init, X_WG)
    check = dense_check(clearance, opt.q, config) if opt.feasible else None
    checking = check.seconds if check else 0.0
    passes = 1
    if check is not None and not check.passed and config.opt_refine_substeps > 0:
        second = optimiser.optimise(opt.q, X_WG, config.opt_refine_substeps)
        passes = 2
        if second.feasible:
            opt, check = second, dense_check(clearance, second.q, config)
            checking += check.seconds
    timings["optimisation"] = time.perf_counter() - tic - checking
    if check is not None:
        timings["check"] = checking
    return opt, check, {"opt_passes": passes, **_opt_details(optimiser, q_init, opt, X_WG)}


def _opt_details(optimiser: PathOptimiser, q_init, opt: OptResult, X_WG) -> dict:
    """What the optimisation did: solver, status, evaluations, unweighted costs before/after
    (c_static_hull at opt_substeps), and the last knot's pose error (m, rad)."""
    config, clearance = optimiser.config, optimiser.clearance
    hull0 = static_hull_cost(clearance, q_init, config.d_safe, config.opt_substeps)[0]
    hull = static_hull_cost(clearance, opt.q, config.d_safe, config.opt_substeps)[0]
    position_error, rotation_error = optimiser.pose_error(opt.q[-1], X_WG)
    return {"opt_solver": opt.solver, "opt_status": opt.solver_status,
            "opt_evaluations": opt.evaluations,
            "c_static_hull": [hull0, hull], "c_vel": [velocity_cost(q_init),
                                                      velocity_cost(opt.q)],
            "terminal_position_error": position_error,
            "terminal_rotation_error": rotation_error}
