"""The one configuration: every paper constant and tuning knob, typed, with its source.

Each field has one comment line above it: what it is, its unit, and its source - a section or
table of Kitaev et al., ICRA 2015 ("Sec. V", "Table II"), or "ours" where the paper leaves the
value open. The sections of phi and the physics planner (`DynamicsConfig`, `PhysicsConfig`,
`EnsembleConfig`) live in `physics_config` and are imported here. The reasons and measurements
behind the values live in docs/decisions.md, under the field's dotted name
(``physics.w_force``); ``drake-clutter config show`` prints the values. Load with
``load_config(path, overrides)``: a YAML file may set any subset of fields (unknown keys are
errors), and ``overrides`` are ``section.field=value`` strings from the command line
(``--set generator.bookshelf.board_width=0.8``), applied after the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from drake_clutter.common.physics_config import DynamicsConfig, EnsembleConfig, PhysicsConfig
from drake_clutter.common.typed_yaml import (
    InputError,
    apply_override,
    from_data,
    read_yaml_file,
    to_data,
)


class ConfigError(InputError):
    """A configuration file or override is invalid."""


@dataclass(frozen=True)
class Range:
    """A closed interval [low, high] sampled uniformly."""

    # lower end of the interval, in the unit of the ranged quantity; Sec. VI-B (uniform ranges)
    low: float
    # upper end of the interval, in the unit of the ranged quantity; Sec. VI-B (uniform ranges)
    high: float


@dataclass(frozen=True)
class BoxRanges:
    """Uniform sampling ranges of a box's properties (Sec. VI-B: size, position, density)."""

    # range of each horizontal side of a box's footprint, m; ours
    footprint: Range = Range(0.04, 0.10)
    # range of a box's height, m; ours
    height: Range = Range(0.06, 0.24)
    # range of a box's density, kg/m^3; ours
    density: Range = Range(150.0, 900.0)
    # range of a box's Coulomb friction coefficient, unitless; ours
    friction: Range = Range(0.4, 0.8)
    # range of a box's yaw about +z, rad; ours
    yaw: Range = Range(-0.5, 0.5)


@dataclass(frozen=True)
class EnvironmentConfig:
    """One environment of Sec. VI-B: its board, walls and clutter levels."""

    # boxes per scene at each clutter level, the target included, count; Sec. VI-B
    clutter_levels: tuple[int, ...]
    # depth of the board along x, m; ours
    board_depth: float
    # width of the board along y, m; ours
    board_width: float
    # thickness of the walls, m; None = no walls (the bookshelf); Sec. VI-B
    wall_thickness: float | None = None
    # height from the board top to the ceiling (fridge only), m; ours
    interior_height: float | None = None


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
    scenes_per_level: int = 10
    # base of the seeds of the named 'paper' scene set, seed; ours
    paper_seed_base: int = 2015
    # thickness of the board, m; ours
    board_thickness: float = 0.03
    # height of the board top above the floor, m; ours
    board_top_height: float = 0.75
    # distance of the board's front edge ahead of the robot base, m; ours
    shelf_front_x: float = 0.55
    # height of the shoulder above the board (sets the torso lift), m; ours
    shoulder_above_board: float = 0.25
    # sampling ranges of the clutter boxes, section; ours
    boxes: BoxRanges = BoxRanges()
    # sampling ranges of the target box (density and friction as the boxes'), section; ours
    target: BoxRanges = BoxRanges(
        footprint=Range(0.04, 0.06), height=Range(0.10, 0.20), yaw=Range(-0.3, 0.3))
    # range of the target's depth behind the board front, m; ours
    target_depth: Range = Range(0.05, 0.26)
    # largest |y - shoulder y| of the target, m; ours
    target_lateral: float = 0.18
    # smallest gap between generated boxes, m; ours
    min_gap: float = 0.005
    # rejection-sampling tries before a box's size is re-drawn, count; ours
    max_tries_per_box: int = 400
    # size re-draws before a scene attempt is abandoned, count; ours
    max_redraws_per_box: int = 60
    # whole-scene attempts (same random stream) before giving up, count; ours
    max_attempts: int = 20


@dataclass(frozen=True)
class WorldConfig:
    """Drake worlds: the kinematic planning world and the smooth-contact dynamics phi (Sec. V)."""

    # phi's SAP time step, s; ours
    time_step: float = 0.01
    # hydroelastic modulus of phi's compliant boxes, Pa; ours
    hydroelastic_modulus: float = 5.0e5
    # resolution hint of the compliant meshes, m; ours
    resolution_hint: float = 0.02
    # Hunt-Crossley dissipation ("similar" / "lagged" contact approximations), s/m; ours
    hunt_crossley_dissipation: float = 5.0
    # SAP's dissipation relaxation time ("sap" contact approximation; Drake's default), s; ours
    relaxation_time: float = 0.1
    # stiffness of point-contact fallback pairs, N/m; ours
    point_stiffness: float = 1.0e5
    # PD stiffness that holds the kinematic arm (Sec. I), N m/rad (N/m for fingers); ours
    arm_kp: float = 4000.0
    # PD damping of the arm, N m s/rad; ours
    arm_kd: float = 100.0
    # phi's discrete contact approximation ("sap", "similar", "lagged"), choice; ours
    contact_approximation: Literal["sap", "similar", "lagged"] = "sap"
    # phi's box friction chosen to reproduce Bullet's product rule, flag; ours
    friction_as_bullet: bool = False
    # SAP's near-rigid threshold beta (Drake's default), unitless; ours
    near_rigid_threshold: float = 1.0
    # ("hydroelastic", "margin") of phi's compliant boxes, m; ours
    hydroelastic_margin: float = 0.002
    # phi's arm as rigid hydroelastic geometry (else arm-box pairs use point contact), flag; ours
    robot_hydroelastic: bool = True
    # arm joint positions of the parked arm (outside the shelf), rad; ours
    park_configuration: tuple[float, ...] = (-1.9, 0.2, 0.0, -1.9, 0.0, -0.6, 0.0)
    # gripper opening of the parked arm, m; ours
    park_gripper_opening: float = 0.09


@dataclass(frozen=True)
class BaselineConfig:
    """The baseline planner (Sec. IV): approach angles, IK, swept-volume optimisation."""

    # approach angles per scene, count; Sec. VI-B
    num_angles: int = 14
    # smallest approach angle alpha, about +z from the +x approach, rad; ours
    alpha_min: float = -1.0
    # largest approach angle alpha, rad; ours
    alpha_max: float = 1.0
    # knots of a trajectory, start and pre-grasp included, count; ours
    num_knots: int = 30
    # time between knots (a 5.8 s reach), s; ours
    knot_time: float = 0.2
    # weight of c_static_hull, unitless; Sec. IV
    w_static_hull: float = 80.0
    # weight of c_vel, unitless; Sec. IV
    w_vel: float = 1.0
    # penetration margin d_safe of the collision costs (Table I), m; ours
    d_safe: float = 0.02
    # gripper point the pre-grasp pose and c_grasp put on the target ("pads"), choice; Sec. IV
    grasp_point: Literal["pads", "tool_frame"] = "pads"
    # dense collision-check samples per knot interval, count; ours
    check_substeps: int = 10
    # penetration the dense collision check accepts, m; ours
    check_tolerance: float = 0.001
    # grasp height h as a fraction of the target's height, unitless; ours
    grasp_height_fraction: float = 0.5
    # clearance beyond d_safe between the gripper proxies and the board, m; ours
    pose_clearance: float = 0.005
    # IK tolerance: a box around the wanted tool-frame position, m; ours
    ik_position_tolerance: float = 1e-4
    # IK tolerance: angle to the wanted tool-frame rotation, rad; ours
    ik_orientation_tolerance: float = 1e-3
    # arm-vs-shelf signed distance IK keeps at both end poses (< d_safe), m; ours
    ik_min_distance: float = 0.01
    # arm-shelf pairs farther apart than this are ignored by IK, m; ours
    ik_influence_distance: float = 0.05
    # weight of ||q_start - q_pregrasp||^2 in the start pose's IK, unitless; ours
    ik_near_weight: float = 1.0
    # SNOPT major / IPOPT iterations per IK attempt, count; ours
    ik_max_iterations: int = 200
    # nominal arm postures seeding IK after the neighbours' solutions, rad; ours
    ik_nominal_postures: tuple[tuple[float, ...], ...] = (
        (-0.12, -0.19, -2.51, -1.99, -2.37, -2.14, -0.32),
        (-0.27, -0.35, -3.15, -2.07, 2.22, -1.67, -0.12),
        (-0.70, 0.43, -1.57, -1.63, 2.77, -0.42, -1.64))
    # further IK seeds, uniform within the joint limits, count; ours
    ik_random_seeds: int = 4
    # random seed of those seeds (plus the angle's index), seed; ours
    ik_seed: int = 0
    # configurations per knot interval in the path optimisation's c_static_hull, count; ours
    opt_substeps: int = 2
    # configurations per interval in a second pass if the dense check fails (0: none), count; ours
    opt_refine_substeps: int = 10
    # B-spline control points whose samples are the knots, count; ours
    opt_control_points: int = 10
    # B-spline order (4 = cubic), count; ours
    opt_spline_order: int = 4
    # last knot fixed at the pre-grasp IK solution (else free under pose constraints), flag; Sec. IV
    fix_last_knot: bool = False
    # SNOPT major / IPOPT iterations of the path optimisation, count; ours
    opt_max_iterations: int = 100
    # per-knot joint move cap, a multiple of the PR2 speed limit x knot_time, unitless; ours
    velocity_limit_scale: float = 1.0
    # SNOPT major optimality / IPOPT tol of the path optimisation, unitless; ours
    opt_optimality_tolerance: float = 1e-3
    # last knot's position tolerance within which it keeps the pre-grasp pose, m; ours
    terminal_position_tolerance: float = 5e-4
    # last knot's rotation tolerance within which it keeps the pre-grasp pose, rad; ours
    terminal_rotation_tolerance: float = 5e-3


@dataclass(frozen=True)
class EvaluationConfig:
    """Hard-contact replay in Bullet and outcome classification (Sec. III)."""

    # Bullet's time step (4x Bullet's default rate: converged classes), s; ours
    sim_dt: float = 1.0 / 960.0
    # longest simulated settling after the last knot, s; ours
    settle_time_cap: float = 3.0
    # speed below which a box counts as at rest, m/s; ours
    rest_speed: float = 0.01
    # tilt beyond which a box has tipped over (Sec. III's class; 20 deg), rad; ours
    max_tilt: float = 0.35
    # angular speed below which a box counts as at rest, rad/s; ours
    rest_angular_speed: float = 0.1
    # time every box must stay at rest before settling stops, s; ours
    rest_hold_time: float = 0.1
    # Bullet steps per motor update and check (60 Hz at sim_dt), count; ours
    monitor_interval: int = 16
    # Bullet's solver iterations (5x Bullet's default: converged classes), count; ours
    solver_iterations: int = 50
    # Bullet's contact breaking threshold (Bullet's default; process-global), m; ours
    contact_breaking_threshold: float = 0.02
    # friction coefficient of the arm links, unitless; ours
    arm_friction: float = 1.0
    # force limit of the kinematic arm's motors, N m (torso: N); ours
    arm_max_force: float = 1.0e4
    # arm joint tracking error beyond which the plan is a kinematic failure (Sec. III), rad; ours
    max_tracking_error: float = 0.02
    # depth the arm may sink into the shelf before a kinematic failure (Sec. III), m; ours
    static_penetration: float = 0.005
    # force into the shelf (arm, or box beyond its weight) that fails kinematically, N; ours
    max_static_force: float = 50.0
    # window over which the shelf forces are averaged, s; ours
    force_window: float = 0.2
    # how far a plan may pass a joint limit, rad (m for the gripper); ours
    joint_limit_tolerance: float = 1e-3
    # plan speeds allowed, a multiple of the PR2's joint speed limits, unitless; ours
    velocity_limit_factor: float = 1.0
    # pre-grasp zone (Sec. III): its reach past the pads along the approach x_G, m; ours
    zone_margin: float = 0.01
    # pre-grasp zone: how far the target may reach past a pad's face or height, m; ours
    fit_tolerance: float = 0.003
    # pre-grasp zone: depth another box must reach into it to count, m; ours
    intrusion_tolerance: float = 0.002
    # lift check (beyond the paper): rise of the tool frame, m; ours
    lift_height: float = 0.05
    # lift check: time to close the fingers, s; ours
    lift_close_time: float = 1.0
    # lift check: time of the rise, s; ours
    lift_time: float = 1.0
    # lift check: time held at the top before looking, s; ours
    lift_hold_time: float = 0.5
    # lift check: fraction of lift_height the target must rise to count as lifted, unitless; ours
    lift_fraction: float = 0.8
    # robust judge (beyond the paper): replays per plan, the first nominal (1: nominal), count; ours
    robust_replays: int = 1
    # robust judge: seed of the perturbed worlds (replay k uses [seed, k]), integer; ours
    robust_seed: int = 0
    # robust judge: half-range of each box's initial shift along x and y (uniform), m; ours
    robust_position: float = 0.003
    # robust judge: half-range of each box's initial yaw change (uniform; 3 deg), rad; ours
    robust_yaw: float = 0.05
    # robust judge: half-range of each box's relative mass change (uniform), unitless; ours
    robust_mass: float = 0.2
    # robust judge: half-range of each box's relative friction change (uniform), unitless; ours
    robust_friction: float = 0.2


@dataclass(frozen=True)
class VizConfig:
    """Meshcat replays of plans (beyond the paper): all ours."""

    # frames per second of simulated time in the recording and the animation, Hz; ours
    fps: float = 30.0
    # gap between the shelves of two side-by-side copies of a scene, m; ours
    copy_margin: float = 0.3
    # camera offset from the shelf's top centre for one copy, m; ours
    camera_offset: tuple[float, float, float] = (1.0, 0.0, 0.85)
    # multiple of camera_offset added per further copy, unitless; ours
    camera_spread: float = 0.6
    # arrow length per N of contact normal force, m/N; ours
    force_scale: float = 0.03
    # contact forces below this are not drawn, N; ours
    min_force: float = 0.05
    # arrows per copy and frame at most (the largest forces), count; ours
    max_arrows: int = 24
    # radius of an arrow's shaft (the cone's base is twice as wide), m; ours
    arrow_radius: float = 0.004
    # length of an arrow's tip, m; ours
    arrow_tip_length: float = 0.02
    # colour of the force arrows (yellow), RGBA in [0, 1]; ours
    arrow_rgba: tuple[float, float, float, float] = (1.0, 0.85, 0.0, 1.0)
    # colour of a tipped box's overlay (orange), RGBA in [0, 1]; ours
    tipped_rgba: tuple[float, float, float, float] = (1.0, 0.5, 0.0, 1.0)
    # colour of a fallen box's overlay (red), RGBA in [0, 1]; ours
    fallen_rgba: tuple[float, float, float, float] = (0.9, 0.05, 0.05, 1.0)
    # how far the tipped/fallen overlay reaches past the box, m; ours
    highlight_padding: float = 0.002


@dataclass(frozen=True)
class ReportConfig:
    """Statistics of the experiment report (beyond the paper): all ours."""

    # bootstrap resamples of the paired comparison's confidence intervals, count; ours
    bootstrap_resamples: int = 10000
    # seed of the bootstrap resampling, integer; ours
    bootstrap_seed: int = 0
    # coverage of the confidence intervals, unitless (0.95 = 95 %); ours
    confidence: float = 0.95
    # scenes listed per configuration where the P(success) difference lies, count; ours
    contribution_scenes: int = 5


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
    # phi's ensemble of perturbed rollouts (beyond the paper), section; ours
    ensemble: EnsembleConfig = field(default_factory=EnsembleConfig)
    # Meshcat replays of plans (beyond the paper), section; ours
    viz: VizConfig = field(default_factory=VizConfig)
    # statistics of the experiment report (beyond the paper), section; ours
    report: ReportConfig = field(default_factory=ReportConfig)


def config_to_data(config: Config) -> dict:
    """The configuration as plain nested data (YAML-ready)."""
    return to_data(config)


def load_config(path: str | Path | None = None, overrides: list[str] | tuple = ()) -> Config:
    """Defaults, then the YAML file at ``path`` (if any), then ``key=value`` overrides.

    Raises ConfigError naming the file (or '<command line>'), the field and the reason.
    """
    user = None if path is None else read_yaml_file(path, error_cls=ConfigError)
    return config_from_data(user, overrides, path)


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
        data = apply_override(data, key.strip(), value, error_cls=ConfigError)
    return from_data(Config, data, file=file or "<command line>", error_cls=ConfigError)


def _merge(base: dict, user: dict, file, prefix: str = "") -> dict:
    out = dict(base)
    for key, value in user.items():
        where = f"{prefix}.{key}" if prefix else str(key)
        if key not in base:
            raise ConfigError(file, where, f"unknown key (known keys: {', '.join(base)})")
        if isinstance(base[key], dict) and isinstance(value, dict):
            out[key] = _merge(base[key], value, file, where)
        else:
            out[key] = value
    return out
