"""The one configuration: every paper constant and tuning knob, typed, with its source.

Each field has one comment line above it: what it is, its unit, and its source - a section or
table of Kitaev et al., ICRA 2015 ("Sec. V", "Table II"), or "ours" where the paper leaves the
value open. The reasons and measurements behind the values live in docs/decisions.md, under
the field's dotted name (``physics.w_force``); ``drake-clutter config show`` prints the values.
Load with ``load_config(path, overrides)``: a YAML file may set any subset of fields (unknown
keys are errors), and ``overrides`` are ``section.field=value`` strings from the command line
(``--set generator.bookshelf.board_width=0.8``), applied after the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

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
class DynamicsConfig:
    """phi as iLQR's dynamics and its derivatives (Sec. V)."""

    # finite-difference step of phi's Jacobians, state units (m, rad, m/s); Sec. V
    fd_step: float = 1e-6
    # finite-difference scheme ("forward" or "central"), choice; Sec. V
    fd_scheme: Literal["forward", "central"] = "forward"
    # margin around the arm's swept volume within which boxes stay dynamic, m; ours
    prune_margin: float = 0.05
    # Jacobians A_t, B_t every k-th knot and the last, interpolated between (1: all), count; ours
    derivative_stride: int = 3
    # the stride skips only quiet knots (no arm-box contact, no box moving), flag; ours
    stride_quiet_only: bool = False
    # a box moves at a knot when |v| + 0.1 m x |w| at its end exceeds this, m/s; ours
    quiet_speed: float = 0.01
    # how phi's Jacobians are taken ("fd", "autodiff", "hybrid"), choice; ours
    derivative_method: Literal["fd", "autodiff", "hybrid"] = "hybrid"
    # colour groups at a knot from which "hybrid" takes AutoDiffXd, count; ours
    autodiff_min_groups: int = 20
    # contact approximation phi's Jacobians are taken with ("rollout", "sap"), choice; ours
    linearize_approximation: Literal["rollout", "sap"] = "rollout"
    # parallel derivative workers (0 = serial, in the calling process), count; ours
    workers: int = 2
    # SAP sub-steps of phi per knot (0.2 s knots / 10 = 20 ms), count; ours
    substeps: int = 10
    # contact geometry of the boxes in phi ("point", "spheres", "hydroelastic"), choice; ours
    contact_model: Literal["point", "spheres", "hydroelastic"] = "hydroelastic"
    # radius of the spheres inside the box corners, m; ours
    corner_sphere_radius: float = 0.004
    # bodies closer than this at a sub-step's start may interact in that step, m; ours
    interaction_margin: float = 1e-3
    # largest state change for which a resting box reuses its Jacobian block, m, rad, m/s; ours
    known_block_tolerance: float = 1e-7
    # boxes within this of a kept box are kept too (transitively), m; ours
    prune_contact_range: float = 0.01
    # rollouts that check the kept set (frozen boxes reached become dynamic), count; ours
    prune_rounds: int = 3
    # arm poses per knot interval for the swept volume, count; ours
    prune_samples_per_knot: int = 4
    # time the boxes rest under the still arm before planning, s; ours
    settle_time: float = 3.0
    # traced steps remembered for linearize (2 iLQR horizons of line search), count; ours
    step_cache_size: int = 512
    # multiple of a box's weight beyond which its shelf force counts in c_force, unitless; ours
    shelf_force_allowance: float = 1.5
    # cap on a box's translational speed after every SAP sub-step, m/s; ours
    max_box_speed: float = 5.0
    # cap on a box's angular speed after every SAP sub-step, rad/s; ours
    max_box_spin: float = 30.0
    # |number| in a box state beyond which a step counts as diverged, m, m/s, rad/s; ours
    divergence_limit: float = 1.0e6


@dataclass(frozen=True)
class PhysicsConfig:
    """The physics-based planner (Sec. V, Tables I and II)."""

    # cap on the iLQR iterations, count; Sec. V
    iterations: int = 30
    # first iterations run with the sphere gripper proxy, count; Sec. V
    sphere_iterations: int = 10
    # the target in the sphere stage's phi ("passes" or "parked"), choice; ours
    sphere_target: Literal["passes", "parked"] = "parked"
    # weight of c_static, unitless; Table II
    w_static: float = 1e3
    # weight of c_acc, unitless; Table II
    w_acc: float = 1e-3
    # multiple of c_acc's Hessian added to the phi stages' model only (0 = off), unitless; ours
    step_smoothing: float = 0.0
    # weight of c_static's steep part in the phi stages (0 = off), unitless; ours
    w_static_deep: float = 0.0
    # depth the arm may sink into the shelf before c_static's steep part, m; ours
    static_depth: float = 0.003
    # configurations per knot interval in the phi stages' c_static (1: the knot), count; ours
    phi_static_substeps: int = 1
    # weight of c_force (Table II says 10), unitless; ours
    w_force: float = 0.01
    # weight of c_force_excess on phi's forces beyond force_limit (0 = off), unitless; ours
    w_force_excess: float = 0.0
    # force at which c_force_excess starts, N; ours
    force_limit: float = 30.0
    # weight of c_motion, unitless; Table II
    w_motion: float = 1e-3
    # weight of c_upright, unitless; Table II
    w_upright: float = 1.0
    # weight of the terminal c_grasp, unitless; Table II
    w_grasp: float = 1e3
    # weight of the terminal c_grp_horiz, unitless; Table II
    w_grp_horiz: float = 1.0
    # weight of the terminal c_grp_open, unitless; Table II
    w_grp_open: float = 1.0
    # weight of c_dynamic in the Sec. V-A pre-processing (as w_static_hull), unitless; ours
    w_dynamic: float = 80.0
    # weight of c_match in the Sec. V-B post-processing, unitless; ours
    w_match: float = 1.0
    # weight of c_match_vel in the Sec. V-B post-processing, unitless; ours
    w_match_vel: float = 1.0
    # knots phi runs past Delta with the arm held (Table II's "all"), count; ours
    hold_knots: int = 5
    # weight of c_settled_upright, each box's tilt (rad) at the hold tail's end, unitless; ours
    w_settled_upright: float = 0.0
    # weight of c_settled_fall, each box's saturated distance off the board there, unitless; ours
    w_settled_fall: float = 0.0
    # distance off the board at which a box's c_settled_fall is half its weight, m; ours
    settled_fall_scale: float = 0.02
    # derivative stride of the hold knots' Jacobians (None: dynamics'), count; ours
    hold_derivative_stride: int | None = None
    # weight of c_speed, the squared excess over the speed cap, unitless; ours
    w_speed: float = 1.0e4
    # c_speed's cap, a fraction of the PR2's joint speed limits, unitless; ours
    speed_fraction: float = 0.25
    # smoothing eps of c_grasp = sqrt(d^2 + eps^2) - eps, m; ours
    grasp_smoothing: float = 0.005
    # Hessian of the phi stages' c_grasp and c_upright ("gauss_newton", "majorizer"), choice; ours
    distance_curvature: Literal["gauss_newton", "majorizer"] = "majorizer"
    # Hessian of c_upright ("tilt": J'J/s of z's horizontal part; "angle": as c_grasp), choice; ours
    upright_curvature: Literal["tilt", "angle"] = "tilt"
    # last knots (Delta included) held on the straight approach (0 = off), count; ours
    approach_knots: int = 0
    # weight of c_approach = 1/2 offset^2 (m^2; 1 cm costs 5), unitless; ours
    w_approach: float = 1e5
    # weight of c_approach_axis = 1 - x_G.d (0.1 rad costs 5), unitless; ours
    w_approach_axis: float = 1e3
    # force(q, x) of c_force ("phi": phi's contact forces, or "proxy"), choice; Table I
    force_source: Literal["phi", "proxy"] = "phi"
    # stiffness of c_force's penetration-to-force proxy, N/m; ours
    force_stiffness: float = 1.0e3
    # configurations per knot interval in c_static_hull / c_dynamic, count; ours
    hull_substeps: int = 2
    # iLQR iterations of the Sec. V-A pre-processing, count; ours
    pre_iterations: int = 10
    # multiple of w_grasp and w_grp_horiz at the pre-processing's last knot, unitless; ours
    pre_terminal_weight: float = 100.0
    # w_vel of the pre-processing's c_vel (None: the baseline's), unitless; Sec. V-A
    pre_w_vel: float | None = None
    # the pre-processing keeps the baseline's last knot and gripper openings (bounds), flag; ours
    pre_keep_pregrasp: bool = True
    # the post-processing keeps its reference's last knot and gripper openings (bounds), flag; ours
    post_keep_end: bool = True
    # the phi stages' last knot opens the gripper at least as wide as the baseline's, flag; ours
    keep_open: bool = True
    # the plan is the best in one phi of the baseline, pre- and post-processed paths, flag; ours
    select_in_phi: bool = True
    # search before the phi stages ("none", or "sampling": see sampling.py), choice; ours
    search: Literal["none", "sampling"] = "none"
    # rounds of the sampling search (cross-entropy refits), count; ours
    search_rounds: int = 3
    # paths drawn per round of the sampling search, count; ours
    search_samples: int = 8
    # best fraction of a round's scored paths the next round's Gaussian is fitted to, unitless; ours
    search_elite: float = 0.25
    # half-range of the search's sideways move of the tool frame (W's y), m; ours
    search_lateral: float = 0.03
    # half-range of the search's vertical move of the tool frame (W's z), m; ours
    search_height: float = 0.02
    # half-range of the search's turn of the tool frame about W's z, rad; ours
    search_yaw: float = 0.15
    # half-range of the search's change of the gripper's opening, m; ours
    search_opening: float = 0.02
    # seed of the sampling search's draws, integer; ours
    search_seed: int = 0
    # knots before the start path's first arm-box contact where search offsets begin, count; ours
    search_lead_knots: int = 3
    # the search scores every sample in one phi per member built once for the search, flag; ours
    search_shared_phi: bool = True
    # extra prune margin of that shared phi, for the samples' own sweeps, m; ours
    search_prune_margin: float = 0.08
    # times the search rebuilds its phis to free frozen boxes its samples reach, count; ours
    search_rebuilds: int = 2
    # iLQR iterations of the Sec. V-B post-processing, count; ours
    post_iterations: int = 40
    # largest arm-point travel between swept-cost samples (0: fixed counts alone), m; ours
    sweep_spacing: float = 0.01
    # arm geometry variant of the post-processing's c_static, name; Sec. V-B
    post_variant: str = "evaluation"
    # configurations per knot interval in the post-processing's c_static, count; ours
    post_substeps: int = 6
    # relative cost decrease that stops iLQR (the solver's default), unitless; ours
    tolerance: float = 1e-6
    # a step's share of a phi stage's decrease that counts as stalled (0 = off), unitless; ours
    stall_fraction: float = 0.0
    # accepted steps in a row under stall_fraction that stop a phi stage, count; ours
    stall_iterations: int = 2
    # step sizes tried per backward pass (every stage), count; ours
    line_search_steps: int = 6
    # phi stages roll out dynamics.workers step sizes at once, flag; ours
    parallel_line_search: bool = True
    # each line search starts at twice the last accepted step, flag; ours
    adaptive_step: bool = True
    # phi stages' trust region, a fraction of the per-knot speed-limit step, unitless; ours
    step_limit_fraction: float = 0.5
    # failed line searches in one iteration that stop a stage, count; ours
    max_failed_searches: int = 1
    # cap on the spectral radius of phi's box-to-box Jacobian per knot, unitless; ours
    max_spectral_radius: float = 1.0
    # rows the cap scales ("box": each unstable box's own first; "block": every box's), choice; ours
    spectral_cap_scope: Literal["box", "block"] = "box"
    # phi stages retry a failed line search open loop (K = 0), flag; ours
    open_loop_fallback: bool = False
    # phi stages' forward passes feed back K (x - x_bar), flag; ours
    feedback: bool = True
    # state the phi stages feed back ("all", or "arm": not the boxes' chaotic part), choice; ours
    feedback_state: Literal["all", "arm"] = "all"
    # smallest control move that keeps a phi stage going (0 = off), rad (m: opening); ours
    min_step: float = 1e-3
    # every stage's backward pass solves each knot's box-constrained QP (Tassa 2014), flag; ours
    box_qp: bool = True
    # the phi stages' trust region bounds the backward pass's QP, not only clips, flag; ours
    trust_bounds: bool = True
    # the phi stages' trust region adapts to actual / predicted decrease, flag; ours
    trust_adapt: bool = True
    # least actual / predicted decrease of an accepted phi-stage step (0: any), unitless; ours
    accept_ratio: float = 0.0
    # the phi stages' regulariser is scaled per control by its trust-region step, flag; ours
    scaled_regulariser: bool = True


@dataclass(frozen=True)
class EnsembleConfig:
    """phi's ensemble: a plan scored over K perturbed rollouts (beyond the paper): all ours."""

    # members of phi's ensemble, the nominal scene first (1: phi alone), count; ours
    members: int = 1
    # seed of the members' worlds (member k draws from [seed, k]), integer; ours
    seed: int = 1000
    # half-range of each box's initial shift along x and y (uniform), m; ours
    position: float = 0.003
    # half-range of each box's initial yaw change (uniform; 3 deg), rad; ours
    yaw: float = 0.05
    # half-range of each box's relative mass change (uniform), unitless; ours
    mass: float = 0.2
    # half-range of each box's relative friction change (uniform), unitless; ours
    friction: float = 0.2
    # member 1 pairs friction as Bullet does (world.friction_as_bullet), flag; ours
    bullet_friction_member: bool = True
    # the score over members ("mean", "mean_std": mean + weight std, "cvar"), choice; ours
    risk: Literal["mean", "mean_std", "cvar"] = "mean"
    # lambda of the "mean_std" score, unitless; ours
    risk_weight: float = 1.0
    # worst fraction of the members the "cvar" score averages, unitless; ours
    cvar_fraction: float = 0.5


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
