"""The baseline planner of Sec. IV: straight-line approaches, optimised against the static shelf.

Per approach angle alpha: the start and pre-grasp poses and their IK (`approach`); the
joint-space line between them over ``num_knots`` knots, ``knot_time`` seconds apart, optimised
against the static shelf and densely checked (`clearance.optimise_and_check`); the result is a
`Candidate`, "ok" or with the reason it is not. The boxes are ignored, as in the paper. The
angles of one scene share one prepared context (`prepare`): the static planning world, IK, the
clearance and the optimiser; each angle's IK is seeded with its neighbour's solution.

Units: joint angles in rad, distances in m, times in s; the tool frame G and the world W as
in `approach`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

from drake_clutter.common.config import BaselineConfig, check_config
from drake_clutter.planners.approach import (
    GripperExtent,
    PoseIk,
    approach_angles,
    approach_poses,
    end_configurations,
    gripper_extent,
    static_planning_world,
)
from drake_clutter.planners.clearance import (
    OPENING,
    CheckResult,
    OptResult,
    PathOptimiser,
    ShelfClearance,
    optimise_and_check,
)
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate, CandidateStatus, Trajectory
from drake_clutter.worlds.drake_world import World


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


def plan_angle(ctx: _Context, alpha: float, index: int) -> Candidate:
    """One approach angle (``alpha`` rad, index ``index`` of the scene's angles): IK,
    interpolation, optimisation, dense check -> a Candidate carrying ``index``."""
    candidate = _plan_angle(ctx, alpha, index)
    candidate.index = index
    return candidate


def _plan_angle(ctx: _Context, alpha: float, index: int) -> Candidate:
    config = ctx.config
    poses = approach_poses(ctx.scene, alpha, config, ctx.extent)
    record = BaselineRecord(height=poses.height,
                            start_xyz=tuple(poses.X_WStart.translation().tolist()),
                            pregrasp_xyz=tuple(poses.X_WPregrasp.translation().tolist()))
    timings: dict[str, float] = {}
    ends = end_configurations(ctx.ik, poses, config, ctx.previous, index, timings)
    if isinstance(ends, str):
        return Candidate(alpha, CandidateStatus.IK_FAILED, ends, None, timings=timings,
                         details=record.to_details())
    q_start, q_end, solvers = ends
    opt, check, done = optimise_and_check(ctx.optimiser, q_start, q_end, poses.X_WPregrasp,
                                          timings)
    record = replace(record, ik_solvers=tuple(solvers), **_as_fields(done))
    return _candidate(alpha, opt, check, config, timings, record)


def _as_fields(values: dict) -> dict:
    """``values`` with its lists as tuples (the record's sequences are immutable)."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}


def _candidate(alpha: float, opt: OptResult, check: CheckResult | None,
               config: BaselineConfig, timings: dict, record: BaselineRecord) -> Candidate:
    """The angle's Candidate from its optimised path and dense check (None: the
    optimisation failed): "ok", or why not; ``record`` completed and stored as its details."""
    trajectory = _trajectory(opt.q, config.knot_time)
    if check is None:
        return Candidate(alpha, CandidateStatus.OPTIMISATION_FAILED,
                         f"{opt.solver}: {opt.solver_status}, terminal pose not kept",
                         trajectory, timings=timings, details=record.to_details())
    details = replace(record, max_penetration=check.depth,
                      check_samples=check.samples).to_details()
    if not check.passed:
        return Candidate(alpha, CandidateStatus.COLLISION_CHECK_FAILED,
                         f"penetrates the shelf by {check.depth * 1000:.1f} mm ({check.where}) "
                         f"at t = {check.time:.2f} s", trajectory, timings=timings,
                         details=details)
    return Candidate(alpha, CandidateStatus.OK, "", trajectory, timings=timings, details=details)


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


@dataclass(frozen=True)
class BaselineRecord:
    """What the baseline did at one approach angle; the planner builds it and stores it as
    the candidate's ``details`` (`to_details`), read back with `from_details`. Fields not
    reached (IK failed, the optimisation failed) are None or empty and left out of
    ``details``.

    - ``height``: the grasp height (m, W); ``start_xyz``, ``pregrasp_xyz``: the tool frame's
      start and pre-grasp positions (m, W);
    - ``ik_solvers``: the solvers that found the start and pre-grasp configurations;
    - ``opt_passes`` (1, or 2 with the refining pass), ``opt_solver``, ``opt_status``,
      ``opt_evaluations``: the path optimisation;
    - ``c_static_hull``, ``c_vel``: its unweighted costs before and after (the last entry is
      the final cost); ``terminal_position_error`` (m), ``terminal_rotation_error`` (rad):
      the last knot's pose error;
    - ``max_penetration`` (m), ``check_samples``: the dense check's deepest penetration and
      its samples.
    """

    height: float | None = None
    start_xyz: tuple[float, ...] = ()
    pregrasp_xyz: tuple[float, ...] = ()
    ik_solvers: tuple[str, ...] = ()
    opt_passes: int | None = None
    opt_solver: str | None = None
    opt_status: str | None = None
    opt_evaluations: int | None = None
    c_static_hull: tuple[float, ...] = ()
    c_vel: tuple[float, ...] = ()
    terminal_position_error: float | None = None
    terminal_rotation_error: float | None = None
    max_penetration: float | None = None
    check_samples: int | None = None

    bent = False  # a straight line
    label = "straight path"

    @classmethod
    def from_details(cls, details: dict) -> BaselineRecord:
        """The record of a candidate's ``details`` (stored or fresh; keys it does not know are
        ignored)."""
        names = {f.name for f in fields(cls)}
        return cls(**_as_fields({k: v for k, v in details.items() if k in names}))

    def to_details(self) -> dict:
        """The record as a candidate's ``details`` (JSON-ready, the fields not reached left
        out), the inverse of `from_details`."""
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None or (isinstance(value, tuple) and not value):
                continue
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out

    def histories(self) -> dict[str, dict]:
        """No iLQR histories: the path is optimised by SNOPT/IPOPT."""
        return {}

    def score(self, weights: BaselineConfig | None = None) -> float | None:
        """Sec. IV's kinematic cost at the end of the path optimisation, lower first:
        w_static_hull x c_static_hull + w_vel x c_vel (``weights``, default the defaults);
        None without an optimisation record."""
        if not self.c_vel:
            return None
        weights = weights or BaselineConfig()
        hull = self.c_static_hull[-1] if self.c_static_hull else 0.0
        return weights.w_static_hull * hull + weights.w_vel * self.c_vel[-1]


def candidates_table(candidates: list[Candidate]) -> str:
    """A text table, one row per angle: alpha, status, IK / optimisation / check times (s),
    deepest penetration found by the dense check (mm) and the reason."""
    rows = [f"{'alpha':>7} {'status':22} {'ik s':>6} {'opt s':>6} {'check s':>7} "
            f"{'pen mm':>6}  reason"]
    for c in candidates:
        t = c.timings
        pen = BaselineRecord.from_details(c.details).max_penetration
        rows.append(f"{c.alpha:+7.3f} {c.status:22} {t.get('ik', 0.0):6.3f} "
                    f"{t.get('optimisation', 0.0):6.3f} {t.get('check', 0.0):7.3f} "
                    f"{'-' if pen is None else f'{pen * 1000:.1f}':>6}  {c.reason}")
    return "\n".join(rows)
