"""The one configuration: every paper constant and tuning knob, typed, with its source.

Each field has one comment line above it: what it is, its unit, and its source - a section or
table of Kitaev et al., ICRA 2015 ("Sec. V", "Table II"), or "ours" where the paper leaves the
value open. The sections of phi and the physics-based planners (`DynamicsConfig`, `PhysicsConfig`,
`StartsConfig`, `PhiJudgeConfig`, `PushSearchConfig`) live in `physics_config` and are imported
here. Why each value is what it is:
one line per field in docs/decisions.md, the dated measurements under the field's dotted name
(``physics.w_force``) in docs/log/decisions.md; ``drake-clutter config show`` prints the
values. Load with ``load_config(path, overrides)``: a YAML file may set any subset of fields
(unknown keys are errors), and ``overrides`` are ``section.field=value`` strings from the
command line (``--set generator.bookshelf.board_width=0.8``), applied after the file.

A field that moved to its owner's section (`RENAMED`) is refused under its old name with one
line naming the new one; a stored configuration (an experiment store's) is read with its old
names moved (`upgrade_stored`).
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from drake_clutter.common.accepts import SEED_MAX, bounded, check
from drake_clutter.common.physics_config import (
    DynamicsConfig,
    PhiJudgeConfig,
    PhysicsConfig,
    PushSearchConfig,
    RearrangeConfig,
    StartsConfig,
)
from drake_clutter.common.typed_yaml import (
    InputError,
    apply_override,
    from_data,
    read_yaml_file,
    to_data,
)

ArmAngles = tuple[float, float, float, float, float, float, float]  # the PR2 arm's 7 joints, rad


class ConfigError(InputError):
    """A configuration file or override is invalid."""


@dataclass(frozen=True)
class Range:
    """A closed interval [low, high] sampled uniformly."""

    # lower end of the interval, in the unit of the ranged quantity; Sec. VI-B (uniform ranges)
    low: float
    # upper end of the interval, in the unit of the ranged quantity; Sec. VI-B (uniform ranges)
    high: float

    def relations(self):
        """(field, holds, what it must be) between this dataclass's fields."""
        return [("high", self.low <= self.high, f"at least low ({self.low:g})")]


@dataclass(frozen=True)
class BoxRanges:
    """Uniform sampling ranges of a box's properties (Sec. VI-B: size, position, density)."""

    # range of each horizontal side of a box's footprint, m; ours
    footprint: Range = bounded(Range(0.04, 0.10), gt=0.0, le=1.0)
    # range of a box's height, m; ours
    height: Range = bounded(Range(0.06, 0.24), gt=0.0, le=1.0)
    # range of a box's density, kg/m^3; ours
    density: Range = bounded(Range(150.0, 900.0), gt=0.0)
    # range of a box's Coulomb friction coefficient, unitless; ours
    friction: Range = bounded(Range(0.4, 0.8), ge=0.0)
    # range of a box's yaw about +z, rad; ours
    yaw: Range = bounded(Range(-0.5, 0.5), ge=-3.1416, le=3.1416)


@dataclass(frozen=True)
class EnvironmentConfig:
    """One environment of Sec. VI-B: its board, walls and clutter levels."""

    # boxes per scene at each clutter level, the target included, count; Sec. VI-B
    clutter_levels: tuple[int, ...] = bounded(ge=1, le=40)
    # depth of the board along x, m; ours
    board_depth: float = bounded(gt=0.0, le=3.0)
    # width of the board along y, m; ours
    board_width: float = bounded(gt=0.0, le=3.0)
    # thickness of the walls, m; None = no walls (the bookshelf); Sec. VI-B
    wall_thickness: float | None = bounded(None, gt=0.0, le=0.5)
    # height from the board top to the ceiling (fridge only), m; ours
    interior_height: float | None = bounded(None, gt=0.0, le=3.0)


@dataclass(frozen=True)
class GeneratorConfig:
    """Random scene generation (Sec. VI-B)."""

    # the bookshelf environment: its clutter levels and board, section; Sec. VI-B
    bookshelf: EnvironmentConfig = EnvironmentConfig(
        clutter_levels=(1, 5, 10, 15, 20, 25),
        board_depth=0.40,
        board_width=0.80,
    )
    # the refrigerator shelf: its clutter levels, board and walls, section; Sec. VI-B
    fridge: EnvironmentConfig = EnvironmentConfig(
        clutter_levels=(1, 2, 4, 6, 8, 10, 12, 14, 16),
        board_depth=0.40,
        board_width=0.60,
        wall_thickness=0.02,
        interior_height=0.36,
    )
    # random scenes per clutter level (150 in all), count; Sec. VI-B
    scenes_per_level: int = bounded(10, ge=1, le=10000)
    # base of the seeds of the named 'paper' scene set, seed; ours
    paper_seed_base: int = bounded(2015, ge=0, le=SEED_MAX)
    # thickness of the board, m; ours
    board_thickness: float = bounded(0.03, gt=0.0)
    # height of the board top above the floor, m; ours
    board_top_height: float = bounded(0.75, gt=0.0)
    # distance of the board's front edge ahead of the robot base, m; ours
    shelf_front_x: float = bounded(0.55, gt=0.0)
    # height of the shoulder above the board (sets the torso lift), m; ours
    shoulder_above_board: float = bounded(0.25, gt=0.0)
    # sampling ranges of the clutter boxes, section; ours
    boxes: BoxRanges = BoxRanges()
    # sampling ranges of the target box (density and friction as the boxes'), section; ours
    target: BoxRanges = BoxRanges(
        footprint=Range(0.04, 0.06), height=Range(0.10, 0.20), yaw=Range(-0.3, 0.3))
    # range of the target's depth behind the board front, m; ours
    target_depth: Range = bounded(Range(0.05, 0.26), ge=0.0)
    # largest |y - shoulder y| of the target, m; ours
    target_lateral: float = bounded(0.18, ge=0.0)
    # smallest gap between generated boxes, m; ours
    min_gap: float = bounded(0.005, ge=0.0)
    # rejection-sampling tries before a box's size is re-drawn, count; ours
    max_tries_per_box: int = bounded(400, ge=1, le=100000)
    # size re-draws before a scene attempt is abandoned, count; ours
    max_redraws_per_box: int = bounded(60, ge=1, le=10000)
    # whole-scene attempts (same random stream) before giving up, count; ours
    max_attempts: int = bounded(20, ge=1, le=1000)

    def relations(self):
        """(field, holds, what it must be) between this dataclass's fields."""
        depth = min(self.bookshelf.board_depth, self.fridge.board_depth)
        return [("target_depth", self.target_depth.high < depth,
                 f"within the boards' depth ({depth:g} m)")]


@dataclass(frozen=True)
class WorldConfig:
    """Drake worlds: the kinematic planning world and the smooth-contact dynamics phi (Sec. V)."""

    # SAP step of dynamics worlds built directly (phi steps knot_time / substeps), s; ours
    time_step: float = bounded(0.01, ge=1e-5)
    # hydroelastic modulus of phi's compliant boxes, Pa; ours
    hydroelastic_modulus: float = bounded(5.0e5, gt=0.0)
    # resolution hint of the compliant meshes, m; ours
    resolution_hint: float = bounded(0.02, gt=0.0)
    # Hunt-Crossley dissipation ("similar" / "lagged" contact approximations), s/m; ours
    hunt_crossley_dissipation: float = bounded(5.0, ge=0.0)
    # SAP's dissipation relaxation time ("sap" contact approximation; Drake's default), s; ours
    relaxation_time: float = bounded(0.1, ge=0.0)
    # stiffness of point-contact fallback pairs, N/m; ours
    point_stiffness: float = bounded(1.0e5, gt=0.0)
    # PD stiffness that holds the kinematic arm (Sec. I), N m/rad (N/m for fingers); ours
    arm_kp: float = bounded(4000.0, gt=0.0)
    # PD damping of the arm, N m s/rad; ours
    arm_kd: float = bounded(100.0, ge=0.0)
    # phi's discrete contact approximation ("sap", "similar", "lagged"), choice; ours
    contact_approximation: Literal["sap", "similar", "lagged"] = "sap"
    # phi's box friction chosen to reproduce Bullet's product rule, flag; ours
    friction_as_bullet: bool = False
    # SAP's near-rigid threshold beta (Drake's default), unitless; ours
    near_rigid_threshold: float = bounded(1.0, ge=0.0)
    # ("hydroelastic", "margin") of phi's compliant boxes, m; ours
    hydroelastic_margin: float = bounded(0.002, ge=0.0)
    # phi's arm as rigid hydroelastic geometry (else arm-box pairs use point contact), flag; ours
    robot_hydroelastic: bool = True
    # arm joint positions of the parked arm (outside the shelf), rad; ours
    park_configuration: ArmAngles = bounded(
        (-1.9, 0.2, 0.0, -1.9, 0.0, -0.6, 0.0), ge=-6.2832, le=6.2832)
    # gripper opening of the parked arm, m; ours
    park_gripper_opening: float = bounded(0.09, ge=0.0, le=0.09)


@dataclass(frozen=True)
class BaselineConfig:
    """The baseline planner (Sec. IV): approach angles, IK, swept-volume optimisation."""

    # approach angles per scene, count; Sec. VI-B
    num_angles: int = bounded(14, ge=1, le=180)
    # smallest approach angle alpha, about +z from the +x approach, rad; ours
    alpha_min: float = bounded(-1.0, gt=-1.5708, lt=1.5708)
    # largest approach angle alpha, rad; ours
    alpha_max: float = bounded(1.0, gt=-1.5708, lt=1.5708)
    # knots of a trajectory, start and pre-grasp included, count; ours
    num_knots: int = bounded(30, ge=2, le=500)
    # time between knots (a 5.8 s reach), s; ours
    knot_time: float = bounded(0.2, gt=0.0, le=10.0)
    # weight of c_static_hull, unitless; Sec. IV
    w_static_hull: float = bounded(80.0, ge=0.0)
    # weight of c_vel, unitless; Sec. IV
    w_vel: float = bounded(1.0, ge=0.0)
    # penetration margin d_safe of the collision costs (Table I), m; ours
    d_safe: float = bounded(0.02, ge=0.0)
    # gripper point the pre-grasp pose and c_grasp put on the target ("pads"), choice; Sec. IV
    grasp_point: Literal["pads", "tool_frame"] = "pads"
    # dense collision-check samples per knot interval, count; ours
    check_substeps: int = bounded(10, ge=1, le=1000)
    # penetration the dense collision check accepts, m; ours
    check_tolerance: float = bounded(0.001, ge=0.0)
    # grasp height h as a fraction of the target's height, unitless; ours
    grasp_height_fraction: float = bounded(0.5, gt=0.0, le=1.0)
    # clearance beyond d_safe between the gripper proxies and the board, m; ours
    pose_clearance: float = bounded(0.005, ge=0.0)
    # IK tolerance: a box around the wanted tool-frame position, m; ours
    ik_position_tolerance: float = bounded(1e-4, gt=0.0)
    # IK tolerance: angle to the wanted tool-frame rotation, rad; ours
    ik_orientation_tolerance: float = bounded(1e-3, gt=0.0)
    # arm-vs-shelf signed distance IK keeps at both end poses (< d_safe), m; ours
    ik_min_distance: float = bounded(0.01, ge=0.0)
    # arm-shelf pairs farther apart than this are ignored by IK, m; ours
    ik_influence_distance: float = bounded(0.05, gt=0.0)
    # weight of ||q_start - q_pregrasp||^2 in the start pose's IK, unitless; ours
    ik_near_weight: float = bounded(1.0, ge=0.0)
    # SNOPT major / IPOPT iterations per IK attempt, count; ours
    ik_max_iterations: int = bounded(200, ge=1, le=100000)
    # nominal arm postures seeding IK after the neighbours' solutions, rad; ours
    ik_nominal_postures: tuple[ArmAngles, ...] = (
        bounded(((-0.12, -0.19, -2.51, -1.99, -2.37, -2.14, -0.32),
                 (-0.27, -0.35, -3.15, -2.07, 2.22, -1.67, -0.12),
                 (-0.70, 0.43, -1.57, -1.63, 2.77, -0.42, -1.64)), ge=-6.2832, le=6.2832))
    # further IK seeds, uniform within the joint limits, count; ours
    ik_random_seeds: int = bounded(4, ge=0, le=100)
    # random seed of those seeds (plus the angle's index), seed; ours
    ik_seed: int = bounded(0, ge=0, le=SEED_MAX)
    # configurations per knot interval in the path optimisation's c_static_hull, count; ours
    opt_substeps: int = bounded(2, ge=1, le=100)
    # configurations per interval in a second pass if the dense check fails (0: none), count; ours
    opt_refine_substeps: int = bounded(10, ge=0, le=100)
    # B-spline control points whose samples are the knots, count; ours
    opt_control_points: int = bounded(10, ge=2, le=200)
    # B-spline order (4 = cubic), count; ours
    opt_spline_order: int = bounded(4, ge=2, le=10)
    # last knot fixed at the pre-grasp IK solution (else free under pose constraints), flag; Sec. IV
    fix_last_knot: bool = False
    # SNOPT major / IPOPT iterations of the path optimisation, count; ours
    opt_max_iterations: int = bounded(100, ge=1, le=100000)
    # per-knot joint move cap, a multiple of the PR2 speed limit x knot_time, unitless; ours
    velocity_limit_scale: float = bounded(1.0, gt=0.0)
    # SNOPT major optimality / IPOPT tol of the path optimisation, unitless; ours
    opt_optimality_tolerance: float = bounded(1e-3, gt=0.0)
    # last knot's position tolerance within which it keeps the pre-grasp pose, m; ours
    terminal_position_tolerance: float = bounded(5e-4, ge=0.0)
    # last knot's rotation tolerance within which it keeps the pre-grasp pose, rad; ours
    terminal_rotation_tolerance: float = bounded(5e-3, ge=0.0)

    def relations(self):
        """(field, holds, what it must be) between this dataclass's fields."""
        return [("alpha_max", self.alpha_min < self.alpha_max, "above alpha_min"),
                ("ik_min_distance", self.ik_min_distance < self.d_safe, "below d_safe"),
                ("ik_influence_distance", self.ik_influence_distance > self.ik_min_distance,
                 "greater than ik_min_distance"),
                ("opt_control_points",
                 self.opt_spline_order <= self.opt_control_points <= self.num_knots,
                 "between opt_spline_order and num_knots")]


@dataclass(frozen=True)
class EvaluationConfig:
    """Hard-contact replay in Bullet and outcome classification (Sec. III)."""

    # Bullet's time step (4x Bullet's default rate: converged classes), s; ours
    sim_dt: float = bounded(1.0 / 960.0, ge=1e-5, le=0.01)
    # longest simulated settling after the last knot, s; ours
    settle_time_cap: float = bounded(3.0, ge=0.0, le=600.0)
    # speed below which a box counts as at rest, m/s; ours
    rest_speed: float = bounded(0.01, gt=0.0)
    # tilt beyond which a box has tipped over (Sec. III's class; 20 deg), rad; ours
    max_tilt: float = bounded(0.35, gt=0.0, lt=1.5708)
    # angular speed below which a box counts as at rest, rad/s; ours
    rest_angular_speed: float = bounded(0.1, gt=0.0)
    # time every box must stay at rest before settling stops, s; ours
    rest_hold_time: float = bounded(0.1, ge=0.0, le=60.0)
    # Bullet steps per motor update and check (60 Hz at sim_dt), count; ours
    monitor_interval: int = bounded(16, ge=1, le=10000)
    # Bullet's solver iterations (5x Bullet's default: converged classes), count; ours
    solver_iterations: int = bounded(50, ge=1, le=10000)
    # Bullet's contact breaking threshold (Bullet's default; process-global), m; ours
    contact_breaking_threshold: float = bounded(0.02, gt=0.0)
    # friction coefficient of the arm links, unitless; ours
    arm_friction: float = bounded(1.0, ge=0.0)
    # force limit of the kinematic arm's motors, N m (torso: N); ours
    arm_max_force: float = bounded(1.0e4, gt=0.0)
    # arm joint tracking error beyond which the plan is a kinematic failure (Sec. III), rad; ours
    max_tracking_error: float = bounded(0.02, gt=0.0)
    # depth the arm may sink into the shelf before a kinematic failure (Sec. III), m; ours
    static_penetration: float = bounded(0.005, ge=0.0)
    # force into the shelf (arm, or box beyond its weight) that fails kinematically, N; ours
    max_static_force: float = bounded(50.0, gt=0.0)
    # window over which the shelf forces are averaged, s; ours
    force_window: float = bounded(0.2, gt=0.0, le=10.0)
    # how far a plan may pass a joint limit, rad (m for the gripper); ours
    joint_limit_tolerance: float = bounded(1e-3, ge=0.0)
    # plan speeds allowed, a multiple of the PR2's joint speed limits, unitless; ours
    velocity_limit_factor: float = bounded(1.0, gt=0.0)
    # pre-grasp zone (Sec. III): its reach past the pads along the approach x_G, m; ours
    zone_margin: float = bounded(0.01, ge=0.0)
    # pre-grasp zone: how far the target may reach past a pad's face or height, m; ours
    fit_tolerance: float = bounded(0.003, ge=0.0)
    # pre-grasp zone: depth another box must reach into it to count, m; ours
    intrusion_tolerance: float = bounded(0.002, ge=0.0)
    # lift check (beyond the paper): rise of the tool frame, m; ours
    lift_height: float = bounded(0.05, gt=0.0)
    # lift check: time to close the fingers, s; ours
    lift_close_time: float = bounded(1.0, ge=0.0, le=60.0)
    # lift check: time of the rise, s; ours
    lift_time: float = bounded(1.0, gt=0.0, le=60.0)
    # lift check: time held at the top before looking, s; ours
    lift_hold_time: float = bounded(0.5, ge=0.0, le=60.0)
    # lift check: fraction of lift_height the target must rise to count as lifted, unitless; ours
    lift_fraction: float = bounded(0.8, gt=0.0, le=1.0)
    # robust judge (beyond the paper): replays per plan, the first nominal (1: nominal), count; ours
    robust_replays: int = bounded(1, ge=1, le=1000)
    # robust judge: seed of the perturbed worlds (replay k uses [seed, k]), integer; ours
    robust_seed: int = bounded(0, ge=0, le=SEED_MAX)
    # robust judge: half-range of each box's initial shift along x and y (uniform), m; ours
    robust_position: float = bounded(0.003, ge=0.0)
    # robust judge: half-range of each box's initial yaw change (uniform; 3 deg), rad; ours
    robust_yaw: float = bounded(0.05, ge=0.0)
    # robust judge: half-range of each box's relative mass change (uniform), unitless; ours
    robust_mass: float = bounded(0.2, ge=0.0, lt=1.0)
    # robust judge: half-range of each box's relative friction change (uniform), unitless; ours
    robust_friction: float = bounded(0.2, ge=0.0, lt=1.0)

    def relations(self):
        """(field, holds, what it must be) between this dataclass's fields."""
        period = self.sim_dt * self.monitor_interval
        return [("force_window", self.force_window >= period,
                 f"at least the motors' control period sim_dt x monitor_interval ({period:g} s)")]


@dataclass(frozen=True)
class VizConfig:
    """Meshcat replays of plans (beyond the paper): all ours."""

    # frames per second of simulated time in the recording and the animation, Hz; ours
    fps: float = bounded(30.0, gt=0.0)
    # gap between the shelves of two side-by-side copies of a scene, m; ours
    copy_margin: float = bounded(0.3, ge=0.0)
    # camera offset from the shelf's top centre for one copy, m; ours
    camera_offset: tuple[float, float, float] = bounded((0.45, 0.0, 0.75))
    # multiple of camera_offset added per further copy, unitless; ours
    camera_spread: float = bounded(0.6, ge=0.0)
    # arrow length per N of contact normal force, m/N; ours
    force_scale: float = bounded(0.03, gt=0.0)
    # contact forces below this are not drawn, N; ours
    min_force: float = bounded(0.05, ge=0.0)
    # arrows per copy and frame at most (the largest forces), count; ours
    max_arrows: int = bounded(24, ge=0, le=10000)
    # radius of an arrow's shaft (the cone's base is twice as wide), m; ours
    arrow_radius: float = bounded(0.004, gt=0.0)
    # length of an arrow's tip, m; ours
    arrow_tip_length: float = bounded(0.02, gt=0.0)
    # colour of the force arrows (yellow), RGBA in [0, 1]; ours
    arrow_rgba: tuple[float, float, float, float] = bounded((1.0, 0.85, 0.0, 1.0), ge=0.0, le=1.0)
    # colour of a tipped box's overlay (orange), RGBA in [0, 1]; ours
    tipped_rgba: tuple[float, float, float, float] = bounded((1.0, 0.5, 0.0, 1.0), ge=0.0, le=1.0)
    # colour of a fallen box's overlay (red), RGBA in [0, 1]; ours
    fallen_rgba: tuple[float, float, float, float] = bounded((0.9, 0.05, 0.05, 1.0), ge=0.0, le=1.0)
    # how far the tipped/fallen overlay reaches past the box, m; ours
    highlight_padding: float = bounded(0.002, ge=0.0)
    # height of the planner's name drawn in front of each copy of a replayed scene, m; ours
    label_height: float = bounded(0.05, gt=0.0)


@dataclass(frozen=True)
class ReportConfig:
    """Statistics of the experiment report (beyond the paper): all ours."""

    # bootstrap resamples of the paired comparison's confidence intervals, count; ours
    bootstrap_resamples: int = bounded(10000, ge=1, le=10000000)
    # seed of the bootstrap resampling, integer; ours
    bootstrap_seed: int = bounded(0, ge=0, le=SEED_MAX)
    # coverage of the confidence intervals, unitless (0.95 = 95 %); ours
    confidence: float = bounded(0.95, gt=0.0, lt=1.0)
    # scenes listed per configuration where the P(success) difference lies, count; ours
    contribution_scenes: int = bounded(5, ge=1, le=10000)


@dataclass(frozen=True)
class Config:
    """All settings of drake_clutter, one section per module."""

    # random scene generation, section; Sec. VI-B
    generator: GeneratorConfig = field(default_factory=GeneratorConfig)
    # Drake worlds: the planning world and phi, section; Sec. V
    world: WorldConfig = field(default_factory=WorldConfig)
    # the baseline planner, section; Sec. IV
    baseline: BaselineConfig = field(default_factory=BaselineConfig)
    # Bullet replay and outcome classification, section; Sec. III
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    # phi as iLQR's dynamics and its derivatives, section; Sec. V
    dynamics: DynamicsConfig = field(default_factory=DynamicsConfig)
    # the physics-based planner, section; Sec. V
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    # the straight starts of the physics-based planners (beyond the paper), section; ours
    starts: StartsConfig = field(default_factory=StartsConfig)
    # the judge in phi: its engine, members' worlds and readings (beyond the paper), section; ours
    phi_judge: PhiJudgeConfig = field(default_factory=PhiJudgeConfig)
    # the push planner: its path family and search (beyond the paper), section; ours
    push_search: PushSearchConfig = field(default_factory=PushSearchConfig)
    # the rearrange planner: pushes that make room, then the reach (beyond the paper), section; ours
    rearrange: RearrangeConfig = field(default_factory=RearrangeConfig)
    # Meshcat replays of plans (beyond the paper), section; ours
    viz: VizConfig = field(default_factory=VizConfig)
    # statistics of the experiment report (beyond the paper), section; ours
    report: ReportConfig = field(default_factory=ReportConfig)

    def relations(self):
        """(dotted field, holds, what it must be) between fields of different sections."""
        b, p, d = self.baseline, self.physics, self.dynamics
        period = self.evaluation.sim_dt * self.evaluation.monitor_interval
        autodiff_ok = d.derivative_method == "fd" or self.world.contact_approximation == "sap"
        return [
            ("physics.control_points", b.opt_spline_order <= p.control_points <= b.num_knots,
             f"between baseline.opt_spline_order ({b.opt_spline_order}) and "
             f"baseline.num_knots ({b.num_knots})"),
            ("evaluation.monitor_interval", period <= b.knot_time,
             f"such that the judge's control period sim_dt x monitor_interval ({period:g} s) "
             f"is at most baseline.knot_time ({b.knot_time:g} s)"),
            ("phi_judge.time_step", d.mujoco_contact_time >= 2 * self.phi_judge.time_step,
             f"at most half dynamics.mujoco_contact_time ({d.mujoco_contact_time:g} s): MuJoCo "
             f"would raise a shorter contact time constant silently"),
            ("dynamics.derivative_method", autodiff_ok,
             f"'fd' with world.contact_approximation {self.world.contact_approximation!r} "
             f"(Drake's AutoDiffXd derivatives under Hunt-Crossley contact did not match "
             f"themselves or finite differences)"),
        ]


_STARTS = ("grasp_heights", "approach_offsets", "recovery_turns", "press_normal_z",
           "press_tolerance", "side_tolerance", "press_substeps")
_FAMILY = ("lateral", "vertical_low", "vertical_high", "knot_low", "knot_high", "progress_low",
           "progress_high", "closed_chance", "vias", "aimed_chance", "own_side_chance",
           "aside_chance", "gripper_half_width", "aim_standoff", "aim_slack")
_MEMBERS = ("seed", "position", "yaw", "mass", "friction", "bullet_friction_member")
# Fields that moved to the section of their owner: old dotted name -> new dotted name.
RENAMED: dict[str, str] = {
    **{f"physics.{f}": f"starts.{f}" for f in _STARTS},
    **{f"push.{f}": f"push_search.{f}" for f in _FAMILY},
    **{f"ensemble.{f}": f"phi_judge.{f}" for f in _MEMBERS},
    "ensemble.members": "phi_judge.members", "push_search.members": "phi_judge.members",
    "push_search.engine": "phi_judge.engine",
    "push_search.veto_members": "phi_judge.veto_members",
    "ensemble.judge_hold_knots": "phi_judge.hold_knots",
    "ensemble.judge_threads": "phi_judge.threads", "dynamics.jam_depth": "phi_judge.jam_depth",
}
# Stored configurations from before the moves also held ensemble.members (the judge in phi's
# members outside the search), which the search's push_search.members replaced: read the latter.
_STORED_DROPPED = ("ensemble.members",)


def upgrade_stored(data: dict) -> dict:
    """A stored configuration's plain data with the fields of `RENAMED` under their new names
    (a copy; data in today's layout comes back equal)."""
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    for old, new in RENAMED.items():
        section, name = old.split(".")
        if name not in (out.get(section) or {}):
            continue
        value = out[section].pop(name)
        if old in _STORED_DROPPED:
            continue
        new_section, new_name = new.split(".")
        out.setdefault(new_section, {})[new_name] = value
    for section in ("ensemble", "push"):
        if section in out and not out[section]:
            del out[section]
    return out


def config_to_data(config: Config) -> dict:
    """The configuration as plain nested data (YAML-ready)."""
    return to_data(config)


def load_config(path: str | Path | None = None, overrides: list[str] | tuple = ()) -> Config:
    """Defaults, then the YAML file at ``path`` (if any), then ``key=value`` overrides.

    Raises ConfigError naming the file (or '<command line>'), the field and the reason; also
    where ``dynamics.engine`` names an engine whose package is not installed.
    """
    user = None if path is None else read_yaml_file(path, error_cls=ConfigError)
    config = config_from_data(user, overrides, path)
    if config.dynamics.engine == "mujoco" and importlib.util.find_spec("mujoco") is None:
        raise ConfigError(path or "<command line>", "dynamics.engine",
                          "'mujoco' needs the package 'mujoco', which is not installed "
                          "(pip install mujoco)")
    return config


def config_from_data(user, overrides: list[str] | tuple = (),
                     file: str | Path | None = None) -> Config:
    """Defaults, then ``user`` (plain nested data, any subset of the fields, e.g. a stored
    configuration written before a field existed), then ``key=value`` overrides."""
    data = config_to_data(Config())
    if user is not None:
        if not isinstance(user, dict):
            raise ConfigError(file or "<configuration>", "",
                              "a configuration must be a YAML mapping")
        data = _merge(data, user, file or "<configuration>")
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError("<command line>", item, "expected key=value")
        if key.strip() in RENAMED:
            raise ConfigError("<command line>", key.strip(), f"renamed to {RENAMED[key.strip()]}")
        data = apply_override(data, key.strip(), value, error_cls=ConfigError)
    return from_data(Config, data, file=file or "<command line>", error_cls=ConfigError)


def check_config(config, file: str | Path = "<configuration>", section: str = "") -> None:
    """Raises ConfigError naming the file, the field's dotted path and the reason for the first
    value of ``config`` (a Config, or its section named ``section``) outside the range its
    field declares (`accepts.bounded`) or breaking a relation between fields. `load_config`
    and `config_from_data` check on loading; call this on a configuration built in code
    (``dataclasses.replace``)."""
    check(config, str(file), ConfigError, section)


def _merge(base: dict, user: dict, file, prefix: str = "") -> dict:
    out = dict(base)
    for key, value in user.items():
        where = f"{prefix}.{key}" if prefix else str(key)
        if where in RENAMED:
            raise ConfigError(file, where, f"renamed to {RENAMED[where]}")
        if key not in base and isinstance(value, dict):
            for name in value:  # a section whose fields moved: name the first one's new home
                if f"{where}.{name}" in RENAMED:
                    raise ConfigError(file, f"{where}.{name}",
                                      f"renamed to {RENAMED[f'{where}.{name}']}")
        if key not in base:
            moved = sorted({new.split(".")[0] for old, new in RENAMED.items()
                            if old.startswith(f"{where}.")})
            hint = f"; its fields moved to {', '.join(moved)}" if moved else ""
            raise ConfigError(file, where, f"unknown key (known keys: {', '.join(base)}){hint}")
        if isinstance(base[key], dict) and isinstance(value, dict):
            out[key] = _merge(base[key], value, file, where)
        else:
            out[key] = value
    return out
