"""The one configuration: every paper constant and tuning knob, typed, with its source.

Each field's comment gives the paper section (Kitaev et al., ICRA 2015) or says "ours" when
the paper leaves the value open and we chose it (with the reason). Load with
``load_config(path, overrides)``: a YAML file may set any subset of fields (unknown keys are
errors), and ``overrides`` are ``section.field=value`` strings from the command line
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

    low: float
    high: float


@dataclass(frozen=True)
class BoxRanges:
    """Uniform sampling ranges of a box's properties (Sec. VI-B: size, position, density)."""

    footprint: Range = Range(0.04, 0.10)  # m, each horizontal side; ours (grocery-sized boxes)
    height: Range = Range(0.06, 0.24)  # m; ours: tall thin boxes can topple (Sec. III)
    density: Range = Range(150.0, 900.0)  # kg/m^3; ours: cereal-box to full-carton densities
    friction: Range = Range(0.4, 0.8)  # Coulomb coefficient; ours (cardboard on wood)
    yaw: Range = Range(-0.5, 0.5)  # rad about +z; ours (boxes roughly face the front)


@dataclass(frozen=True)
class EnvironmentConfig:
    """One environment of Sec. VI-B: its board, walls and clutter levels."""

    clutter_levels: tuple[int, ...]  # boxes per scene, the target included (Sec. VI-B)
    board_depth: float  # m, along x (ours)
    board_width: float  # m, along y (ours)
    wall_thickness: float | None = None  # m; None = no walls (bookshelf, Sec. VI-B)
    interior_height: float | None = None  # m, board top to ceiling (fridge only; ours)


@dataclass(frozen=True)
class GeneratorConfig:
    """Random scene generation (Sec. VI-B)."""

    bookshelf: EnvironmentConfig = EnvironmentConfig(
        clutter_levels=(1, 5, 10, 15, 20, 25),  # Sec. VI-B: 6 bookshelf clutter levels
        board_depth=0.40,  # ours: 25 boxes jam it (Sec. VI-B "nearly completely filled")
        board_width=0.80,
    )
    fridge: EnvironmentConfig = EnvironmentConfig(
        clutter_levels=(1, 2, 4, 6, 8, 10, 12, 14, 16),  # Sec. VI-B: 9 refrigerator levels
        board_depth=0.40,  # ours: interior 0.38 x 0.56 after the walls; 16 boxes jam it
        board_width=0.60,
        wall_thickness=0.02,
        interior_height=0.36,
    )
    scenes_per_level: int = 10  # Sec. VI-B: 10 random scenes per clutter level (150 in all)
    paper_seed_base: int = 2015  # ours: seeds of the named 'paper' scene set
    board_thickness: float = 0.03  # m; ours
    board_top_height: float = 0.75  # m above the floor; ours (a waist-high shelf)
    # m, board front edge ahead of the robot base; ours: at 0.40 the baseline found IK for 93/168
    # approach angles (none straight in on the Fig. 5-8 scenes), at 0.55 for 157/168.
    shelf_front_x: float = 0.55
    shoulder_above_board: float = 0.25  # m; ours: sets the torso lift from the board height
    boxes: BoxRanges = BoxRanges()
    target: BoxRanges = BoxRanges(  # ours: graspable by the 0.09 m PR2 gripper at any yaw
        footprint=Range(0.04, 0.06), height=Range(0.10, 0.20), yaw=Range(-0.3, 0.3))
    target_depth: Range = Range(0.05, 0.26)  # m behind the board front; ours: within reach
    target_lateral: float = 0.18  # m, |y - shoulder y| of the target; ours: within reach
    min_gap: float = 0.005  # m between generated boxes; ours (robust to rounding)
    max_tries_per_box: int = 400  # rejection-sampling tries before a box's size is re-drawn
    max_redraws_per_box: int = 60  # size re-draws before a scene attempt is abandoned
    max_attempts: int = 20  # whole-scene attempts (same random stream) before giving up


@dataclass(frozen=True)
class WorldConfig:
    """Drake worlds: the kinematic planning world and the smooth-contact dynamics phi (Sec. V)."""

    time_step: float = 0.01  # s, SAP step of phi; ours (ARCHITECTURE: 5.5 ms/step at 25 boxes)
    hydroelastic_modulus: float = 5.0e5  # Pa, phi's compliant boxes; ours: at 1e6 a 10-box
    # reach diverged at 40 ms steps (phi's 5 sub-steps); 5e5 settles (6.8e-6 m/s) and keeps FD
    # vs AutoDiffXd at median 2.4e-3 (measured)
    resolution_hint: float = 0.02  # m, compliant mesh resolution hint; ours
    hunt_crossley_dissipation: float = 5.0  # s/m; ours
    relaxation_time: float = 0.1  # s, SAP dissipation (Drake default); 0.05 let boxes creep 1 mm
    point_stiffness: float = 1.0e5  # N/m for point-contact fallback pairs; ours
    arm_kp: float = 4000.0  # N m/rad (N/m for fingers) PD stiffness: the arm is kinematic (Sec. I)
    arm_kd: float = 100.0  # N m s/rad PD damping; ours
    contact_approximation: Literal["sap", "similar", "lagged"] = "sap"  # phi's discrete
    # contact model (Drake's DiscreteContactApproximation; all solved by SAP): "sap" = linear
    # Kelvin-Voigt dissipation (relaxation_time); "similar" / "lagged" = Hunt-Crossley
    # dissipation (hunt_crossley_dissipation); ours
    friction_as_bullet: bool = False  # phi's box friction chosen so that Drake's pair rule
    # 2ab/(a+b) with the shelf and the arm (1.0) gives Bullet's product a*b (the judge's);
    # False: the scene's coefficient (Drake then grips a 0.4 box with 0.57, Bullet with 0.4).
    # Measured (README, phi's fidelity): True halves the thrown boxes (5 vs 10 of 223) and
    # agrees on 189 vs 187 classes, but the planner did worse with it on fig5 and fig6 (one
    # more box tipped on each), so it stays off
    near_rigid_threshold: float = 1.0  # SAP's near-rigid threshold beta (contacts stiffer
    # than it allows saturate); Drake's default. Measured: 1e-3 made phi's Jacobians 10-100x
    # larger in a push and finite differences worse
    hydroelastic_margin: float = 0.002  # m, ("hydroelastic", "margin") of phi's compliant
    # boxes: pairs this close enter SAP's problem before they touch, so contact starts without
    # a jump (phi is continuous); ours (> one 40 ms step at 5 cm/s)
    robot_hydroelastic: bool = True  # phi's arm as rigid hydroelastic geometry (else arm-box
    # pairs fall back to point contact, which jumps); it then passes through the shelf: the
    # arm is kinematic in Sec. V, and c_static keeps it clear; ours
    park_configuration: tuple[float, ...] = (-1.9, 0.2, 0.0, -1.9, 0.0, -0.6, 0.0)  # rad; ours
    park_gripper_opening: float = 0.09  # m; ours


@dataclass(frozen=True)
class BaselineConfig:
    """The baseline planner (Sec. IV): approach angles, IK, swept-volume optimisation."""

    num_angles: int = 14  # Sec. VI-B: 14 approach angles per scene
    alpha_min: float = -1.0  # rad, about +z from the +x approach; ours (Sec. IV leaves it open)
    alpha_max: float = 1.0  # rad; ours
    num_knots: int = 30  # knots of a trajectory, start and pre-grasp included; ours
    knot_time: float = 0.2  # s between knots (a 5.8 s reach); ours: slow arm (Sec. I)
    w_static_hull: float = 80.0  # Sec. IV: weight of c_static_hull
    w_vel: float = 1.0  # Sec. IV: weight of c_vel
    d_safe: float = 0.02  # m, penetration margin of the collision costs (Table I); ours
    grasp_point: Literal["pads", "tool_frame"] = "pads"  # the gripper's point that the
    # pre-grasp pose and the physics planner's c_grasp put on the target's centre. Sec. IV:
    # "the target centred between the open fingers" = "pads" (the pads' centre, 1.5 cm behind
    # the PR2 tool frame G); "tool_frame" = G itself (ours until 2026-11-24): the target then
    # sat 1.5 cm from the front of the evaluation's pad zone (1.3 cm to spare), and 6 of the
    # physics planner's 24 behaviour-tier plans failed to grasp with the target 0.3-2.6 cm
    # ahead of that zone. Behaviours tier at "pads" (2026-11-24): paired 7/9/8 as at
    # "tool_frame", kinematic failures physics 6 (was 8), baseline 4 (was 6)
    check_substeps: int = 10  # dense check samples per knot interval (issue 3)
    check_tolerance: float = 0.001  # m of penetration the dense check accepts (issue 3)
    # Approach poses (Sec. IV leaves them open; all ours).
    grasp_height_fraction: float = 0.5  # h = this x target height: grip the box mid-height
    pose_clearance: float = 0.005  # m beyond d_safe between the gripper proxies and the board
    # (below the pre-grasp pose; in front of its edge at the start on line l)
    # IK of the two end poses (ours): tight pose tolerances, clear of the shelf.
    ik_position_tolerance: float = 1e-4  # m, box around the wanted tool-frame position
    ik_orientation_tolerance: float = 1e-3  # rad, angle to the wanted tool-frame rotation
    ik_min_distance: float = 0.01  # m, arm-vs-shelf signed distance at both ends (< d_safe)
    ik_influence_distance: float = 0.05  # m, pairs farther than this are ignored by IK
    ik_near_weight: float = 1.0  # weight of ||q_start - q_pregrasp||^2 in the start's IK
    ik_max_iterations: int = 200  # SNOPT major / IPOPT iterations per IK attempt
    ik_nominal_postures: tuple[tuple[float, ...], ...] = (  # rad, arm seeds after neighbours':
        (-0.12, -0.19, -2.51, -1.99, -2.37, -2.14, -0.32),  # the medoids of three clusters of
        (-0.27, -0.35, -3.15, -2.07, 2.22, -1.67, -0.12),  # pre-grasp solutions found on six
        (-0.70, 0.43, -1.57, -1.63, 2.77, -0.42, -1.64))  # generated scenes
    ik_random_seeds: int = 4  # further seeds, uniform within the joint limits
    ik_seed: int = 0  # random seed of those (plus the angle's index)
    # Path optimisation (ours; Sec. IV uses SQP [30]).
    opt_substeps: int = 2  # configurations per knot interval in c_static_hull
    opt_refine_substeps: int = 10  # per interval in a second pass run when the dense check
    # fails (fast swings move the arm more than d_safe between 2 samples); 0 = no second pass
    opt_control_points: int = 10  # B-spline control points whose samples are the knots
    opt_spline_order: int = 4  # B-spline order (4 = cubic)
    fix_last_knot: bool = False  # True: last knot = the pre-grasp IK solution; False: free
    # under tool-frame pose constraints (Sec. IV's formulation)
    opt_max_iterations: int = 100  # SNOPT major / IPOPT iterations
    velocity_limit_scale: float = 1.0  # knots move each joint at most this x its PR2 speed
    # limit x knot_time (ours: keeps the path executable and swings visible to the samples)
    opt_optimality_tolerance: float = 1e-3  # SNOPT major optimality / IPOPT tol
    # The optimised last knot keeps the pre-grasp pose when within these (5x the IK
    # tolerances: room for the solvers' feasibility slack, well inside 1 mm and 0.01 rad).
    terminal_position_tolerance: float = 5e-4  # m
    terminal_rotation_tolerance: float = 5e-3  # rad


@dataclass(frozen=True)
class EvaluationConfig:
    """Hard-contact replay in Bullet and outcome classification (Sec. III)."""

    sim_dt: float = 1.0 / 240.0  # s, Bullet step; ours (Bullet's default rate)
    settle_time_cap: float = 3.0  # s simulated after the last knot at most; ours
    rest_speed: float = 0.01  # m/s: every box slower than this counts as at rest; ours
    max_tilt: float = 0.35  # rad (20 deg): a box tilted more has tipped over (Sec. III); ours
    # Settling and the simulator (all ours).
    rest_angular_speed: float = 0.1  # rad/s: ... and turning slower than this (0.1 m lever)
    rest_hold_time: float = 0.1  # s at rest before settling stops (a topple pauses at its top)
    monitor_interval: int = 4  # steps per motor update and check (60 Hz): speed (1 s target)
    solver_iterations: int = 10  # Bullet's own default (pybullet: 50, 2x slower when pushing)
    contact_breaking_threshold: float = 0.02  # m, Bullet's default; process-global, so set
    arm_friction: float = 1.0  # arm links; Bullet multiplies coefficients: arm-box = the box's
    arm_max_force: float = 1.0e4  # N m (torso: N): kinematic arm, far above any contact load
    # Kinematic failure (Sec. III), all ours.
    max_tracking_error: float = 0.02  # rad on an arm joint: the arm cannot follow the plan
    static_penetration: float = 0.005  # m the arm may sink into the shelf (Bullet slop ~1 mm)
    max_static_force: float = 50.0  # N pressing into the shelf (arm, or box beyond its weight):
    # ~1.5x what the PR2's 30 N m shoulder pushes at 0.8 m, 2.5x the heaviest generated box
    force_window: float = 0.2  # s, forces averaged over this long: impacts are not pressing
    joint_limit_tolerance: float = 1e-3  # rad (m for the gripper) a plan may pass a limit by
    velocity_limit_factor: float = 1.0  # plan speeds allowed up to this x the PR2's limits
    # Pre-grasp zone (Sec. III), in the tool frame G; all ours.
    zone_margin: float = 0.01  # m the zone extends past the pads along the approach (x_G)
    fit_tolerance: float = 0.003  # m the target may reach past a pad's face / height
    intrusion_tolerance: float = 0.002  # m another box must reach into the zone to count
    # Grasp-and-lift check (beyond the paper; issue 4).
    lift_height: float = 0.05  # m the tool frame rises
    lift_close_time: float = 1.0  # s to close the fingers (PR2 effort and speed limits)
    lift_time: float = 1.0  # s for the rise
    lift_hold_time: float = 0.5  # s held at the top before looking
    lift_fraction: float = 0.8  # the target must rise this x lift_height to count as lifted


@dataclass(frozen=True)
class DynamicsConfig:
    """phi as iLQR's dynamics and its derivatives (Sec. V)."""

    fd_step: float = 1e-6  # Sec. V: finite-difference step. Measured against AutoDiffXd
    # (bench_derivatives --validate): in contact 1e-6 is better (whole-Jacobian error median
    # 7.6e-3 vs 4.2 at 1e-5: fewer steps straddle a contact kink); for settled boxes SAP's
    # ~1e-6 relative tolerance can make 1e-6 noisier (up to 2.5e-2 vs 1e-4 at 1e-5)
    fd_scheme: Literal["forward", "central"] = "forward"  # Sec. V uses forward differences
    prune_margin: float = 0.05  # m around the arm's swept volume; ours (Sec. I: affected boxes)
    derivative_stride: int = 3  # compute A_t, B_t every k-th knot (and the last) and
    # interpolate between; 1 = all; ours (Sec. V differentiates every knot). Measured
    # (2026-11-24): `bench_planner --kind bookshelf --levels 25` 174 s -> 110 s per
    # initialization (stride 6: 121 s), phi objective 0.099 -> 0.065 of its start (6: 0.053);
    # on the behaviours tier (24 initializations, `report`'s paired comparison) 7 better / 9
    # same / 8 worse against the baseline, kinematic failures 8 / 6 (stride 1: 7 / 10 / 7,
    # 6 / 6), 1288 s of planning instead of 1903: the same within the tier's noise, 1.5x faster
    derivative_method: Literal["fd", "autodiff", "hybrid"] = "hybrid"  # how phi's Jacobians
    # are taken; ours (Sec. V uses finite differences): "fd" = one phi evaluation per colour
    # group; "autodiff" = one AutoDiffXd knot seeded with the colour groups (exact, and in
    # contact FD's h = 1e-6 was off by 10-25 % at some knots, measured); "hybrid" = autodiff at
    # knots with at least autodiff_min_groups groups, fd at the others. Measured (10 boxes,
    # tests' reach): an AutoDiffXd knot costs ~14 + m/3 double phi evaluations for m groups
    # (its hydroelastic contact surfaces dominate), FD m + 1
    autodiff_min_groups: int = 20  # "hybrid": where AutoDiffXd starts to pay (14 + m/3 < m +
    # 1 from m ~ 20; ours, measured as above)
    linearize_approximation: Literal["rollout", "sap"] = "rollout"  # the contact
    # approximation phi's Jacobians are taken with; ours: "rollout" = world.contact_approximation
    # (the plant that rolls out); "sap" = a SAP copy of phi (AutoDiffXd and clean finite
    # differences) while rollouts and line searches use world.contact_approximation - for
    # Hunt-Crossley phi ("similar"), whose own Jacobians are noise (README: planning with
    # Hunt-Crossley phi)
    workers: int = 2  # parallel derivative workers (Sec. V: "in parallel"); ours: 2 cores
    # (0 = serial, in the calling process)
    # phi's simulation (all ours; measurements in the README's phi section).
    substeps: int = 10  # SAP steps per knot (0.2 s knots / 10 = 20 ms); ours. Measured: at
    # 40 ms (5) a 2 cm thin standing box's rocking mode is under-resolved - solver noise from
    # the moving arm grew ~3x a knot and fig7's dominoes toppled untouched (the planner then
    # optimised against a phantom cascade); at 20 ms they stand. `bench_fidelity.py` (phi vs
    # Bullet on the behaviour scenes' baseline plans, box classes that agree): 22/27 at 5 and
    # at 10, 25/27 at 20 (4x phi's cost); fig6/fig7 displacement errors 2.8/21.4 cm at 5,
    # 1.2/20.5 at 10. FD vs AutoDiffXd (10 boxes, a push): median 3e-3 at 5, 2.6e-2 at 10
    # (the planner takes AutoDiffXd where the arm pushes: `derivative_method`)
    contact_model: Literal["point", "spheres", "hydroelastic"] = "hydroelastic"  # boxes in
    # phi: "hydroelastic" = compliant boxes with world.hydroelastic_margin against the rigid
    # hydroelastic arm and shelf: phi is continuous (measured: point contact jumps by up to 0.3
    # m/s when a perturbation of 1e-7 m decides whether a pair touches at a sub-step's start,
    # since SAP only sees touching point pairs; the margin puts near pairs in its problem
    # first); "point" = corner spheres on the shelf + Box shapes (cheaper per step, but finite
    # differences straddle those jumps at most pushing knots); "spheres" = corner spheres only
    corner_sphere_radius: float = 0.004  # m, spheres inside the box corners; ours (small:
    # the box rests on its real footprint)
    interaction_margin: float = 1e-3  # m: bodies closer than this at a sub-step's start may
    # interact in that step (1000 x the FD step, so a perturbation cannot create a contact)
    known_block_tolerance: float = 1e-7  # max |state change| (m, rad, m/s) for which an
    # isolated box reuses its Jacobian block from an earlier knot (a box at rest); ours: a
    # tenth of fd_step, so the reused difference quotient is as good as a fresh one
    prune_contact_range: float = 0.01  # m: boxes within this of a kept box are kept too
    # (transitively); ours: twice the generator's 5 mm gap, so neighbours a push reaches stay
    prune_rounds: int = 3  # rollouts that check the kept set: frozen boxes a kept box (or
    # the arm) reached in the rollout become dynamic and it is rolled out again; ours (a pushed
    # box travels 10+ cm, past any fixed contact range)
    prune_samples_per_knot: int = 4  # arm poses per knot interval for the swept volume; ours
    # (the gripper moves ~2-5 cm per knot, well under prune_margin between samples)
    settle_time: float = 3.0  # s the boxes rest under the still arm before planning; ours:
    # boxes placed exactly on the board first sink 0.3 mm, then the overdamped corner contacts
    # lift them back; box speeds fall to 2e-7 m/s at 2 s and 2e-9 m/s at 3 s
    step_cache_size: int = 512  # traced steps remembered for linearize (2 iLQR horizons of
    # line search); ours
    shelf_force_allowance: float = 1.5  # x a box's weight: its contact force with the shelf
    # counts in phi's force vector (c_force) only beyond this; ours: at rest the shelf carries
    # 1x, pushes add some; a box pressed into the shelf (Sec. III's kinematic failure, 50 N in
    # the evaluation) is what c_force must see - without it fig8's physics plan jammed a box
    # into the board with 58-102 N (measured in Bullet)
    max_box_speed: float = 5.0  # m/s: a box's translational speed is scaled down to this
    # after every SAP sub-step; ours (a numerical guard: pushed boxes move < 1 m/s, a box
    # falling 0.75 m lands at 3.8 m/s). See max_box_spin
    max_box_spin: float = 30.0  # rad/s: likewise its angular speed; ours: a box toppling in
    # a 40 ms sub-step into the board was thrown out at 180 rad/s and Drake's explicit
    # gyroscopic term then spun it up to 7e3 rad/s in 4 sub-steps, and to NaN (fig8's
    # straight reach, measured); a toppling 24 cm box turns at ~10 rad/s
    divergence_limit: float = 1.0e6  # |number| in a box state (m, m/s, rad/s) beyond which
    # a step counts as diverged (NaN, a failure); ours: a diverged SAP step overflowed the
    # quaternion's norm to a zero quaternion that Drake then aborted on (measured)


@dataclass(frozen=True)
class PhysicsConfig:
    """The physics-based planner (Sec. V, Tables I and II)."""

    iterations: int = 30  # Sec. V: iLQR capped at 30 iterations
    sphere_iterations: int = 10  # Sec. V: first 10 iterations with the sphere gripper proxy
    sphere_target: Literal["passes", "parked"] = "parked"  # the target in the sphere stage's
    # phi (ours; the sphere engulfs the target at the pre-grasp): "passes" = a dynamic box
    # the arm passes through (other boxes still push it; c_grasp follows it); "parked" =
    # welded out of the world (c_grasp aims at its resting pose; boxes pass its place).
    # Measured ("passes"): fig6 worse, fig8 the same kinematic failure (docs/physics_planner_log.md)
    w_static: float = 1e3  # Table II
    w_acc: float = 1e-3  # Table II
    step_smoothing: float = 0.0  # ours, 0 = off: this multiple of c_acc's unweighted Hessian
    # is added to the phi stages' quadratic model only (not to the objective): a metric in
    # which steps that zig-zag between knots are long and smooth ones short, so iLQR's steps
    # stay smooth in time. Why: the alpha-0 phi stages left knot-to-knot jitter (joint second
    # differences up to 0.16-0.36 rad against the baseline's 0.002-0.013) that c_acc at 1e-3
    # prices at 0.001-0.05 (measured)
    w_static_deep: float = 0.0  # ours: weight of c_static's steep part in the phi stages,
    # 1/2 (depth beyond static_depth)^2 per arm-shelf pair and knot (phi's arm passes through
    # the shelf, and the phi stages left it 1-3 cm deep in the board on fig8, measured); 0: off
    # (at 1e7, with or without phi_static_substeps 6, no behaviour scene improved:
    # docs/physics_planner_log.md)
    static_depth: float = 0.003  # m the arm may sink into the shelf before the steep part;
    # ours: below the evaluation's static_penetration (5 mm)
    phi_static_substeps: int = 1  # configurations per knot interval in the phi stages'
    # c_static (their mean, the knot included; 1 = the knot alone); ours, as post_substeps
    w_force: float = 0.01  # Table II says 10; ours: with our force vector (N, the summed
    # contact forces of the arm and of each box, Sec. V) pushing a 1.6 kg box for one knot
    # then costs ~880, as much as ending 0.9 m off the target, so iLQR gave up the grasp (fig5:
    # c_grasp 0.2 -> 135 in two iterations) and preferred toppling the light box to pushing the
    # heavy one, the reverse of Fig. 5. At 0.01 (measured, fig5 at alpha = 0): the physics plan
    # grasps (partial success) where the baseline's fails to grasp
    w_force_excess: float = 0.0  # ours (not in Table I): w/2 ||max(0, f - force_limit)||^2
    # on phi's force vector, a steep wall where the judge fails kinematically (Sec. III: 50 N
    # pressing into the shelf); 0 = off. Measured (bench_fidelity jams): phi's arm force
    # peaked over 50 N in 10 of 14 baseline plans that fail kinematically in Bullet and in 7
    # of 26 others (medians 104 vs 23 N)
    force_limit: float = 30.0  # N, where c_force_excess starts; ours: below Sec. III's 50 N,
    # as phi under-predicts some jams (fig5 at alpha -0.21: phi 30 N, Bullet 400 N)
    w_motion: float = 1e-3  # Table II
    w_upright: float = 1.0  # Table II
    w_grasp: float = 1e3  # Table II (terminal)
    w_grp_horiz: float = 1.0  # Table II (terminal)
    w_grp_open: float = 1.0  # Table II (terminal)
    w_dynamic: float = 80.0  # Sec. V-A pre-processing; ours: as w_static_hull
    w_match: float = 1.0  # Sec. V-B post-processing; ours
    w_match_vel: float = 1.0  # Sec. V-B post-processing; ours
    # Time windows (Table II), as we read them: c_static on the state at every knot 1..Delta,
    # c_acc on every interval up to Delta ("t <= Delta"); c_force, c_motion, c_upright at
    # "all" times: every knot and the hold_knots after Delta; grasp/grp_horiz/grp_open at Delta.
    hold_knots: int = 5  # Table II's "all" past Delta: phi goes on this many knots with the arm
    # held at q^Delta and their c_force/c_motion/c_upright count (phi_stage.HoldTail); ours: 1 s
    # (a domino toppled at the last knot falls in ~0.5 s). Without it the fig7 plan started the
    # cascade at t = 5 s, tilts 30-60 deg at Delta, and c_upright saw 5.8 (measured)
    hold_derivative_stride: int | None = None  # derivative stride of the hold_knots' phi
    # Jacobians (None: dynamics.derivative_stride); ours: the tail's gradient is a chain of its
    # Jacobians, and with every 3rd knot interpolated it was 46 % off the numerical one on a
    # toppling domino (tests/test_physics.py's hold-tail test: |error| 126 of 274). Not 1 by
    # default: `bench_planner --kind bookshelf --levels 25` took 193 s with 1 (6 iterations,
    # objective 0.036 of its start, 17 boxes kept by the last stage) against 113 s with 3
    # (4 iterations, 0.065, 11 kept) (2026-11-24); behaviours tier at the pads 8 better / 8
    # same / 8 worse, 1474 s, against the defaults' 7 / 9 / 8, 1238 s (noise)
    w_speed: float = 1.0e4  # ours (not in Table II): weight of c_speed, the squared excess of
    # a joint's move per knot over speed_fraction x its PR2 speed limit, added to c_acc's
    # interval term (the evaluation rejects plans beyond the limits; at w_acc = 1e-3 alone the
    # physics stage moved the shoulder pan at 2-6 rad/s on fig5, measured)
    speed_fraction: float = 0.25  # ours: c_speed's cap, a fraction of the PR2's joint speed
    # limits (it also scales step_limit_fraction's trust region). Measured (2026-11-24): the
    # baseline's paths stay under 0.10 of the limits; at 0.9, 17 of 21 stored physics plans
    # of the behaviour scenes (alpha +-0.21) went over 0.3 of the limits on 1-29 of 29 knots
    # (15 reached 0.84; one swung a finger 30 cm in 0.2 s) and 10 of those 17 failed
    # kinematically in Bullet, none of the 4 that stayed under 0.25. At 0.25 (same code
    # otherwise) the alpha-0 behaviour plans failed kinematically on 1 of 4 scenes instead
    # of 3 (docs/physics_planner_log.md)
    grasp_smoothing: float = 0.005  # m, c_grasp = sqrt(d^2 + eps^2) - eps; ours: smooth
    # below 5 mm, the paper's distance beyond
    distance_curvature: Literal["gauss_newton", "majorizer"] = "majorizer"  # Hessian of
    # the phi stages' distance-like terms (c_grasp, c_upright); ours. "gauss_newton": none
    # along c_grasp's own direction and ~eps^2/theta^3 for a tilted box, so the quadratic
    # model predicts decreases beyond the whole objective until the regulariser reaches
    # 1e3-1e7 (measured); "majorizer": grad grad' / value, the quadratic above the term.
    # Measured at alpha 0 (2026-11-24, with min_step): fig5 partial success, fig6 the same,
    # fig7 and fig8 fewer boxes disturbed than the baseline - Sec. VI-A's test met on that
    # machine, not on others (docs/physics_planner_log.md)
    approach_knots: int = 0  # ours (not in Table I): the last knots (Delta included) on which
    # c_approach and c_approach_axis hold the gripper on the candidate's straight approach: the
    # tool frame on the line through the target's centre along the baseline's final approach
    # axis d, its approach axis x_G along d (the fingers must straddle the target; Sec. IV's
    # approach lines). 0 = off. Why: the alpha-0 physics plans reached the target from above or
    # sideways (tool 2-20 cm off the line, x_G 13-30 deg off d over the last 0.8 s) where the
    # baseline comes straight in, and a finger landed on fig7's target (149 N, measured).
    # Behaviours tier at the pads (2026-11-24): 5 gave 8 better / 7 same / 9 worse (0: 7/9/8)
    w_approach: float = 1e5  # ours: weight of c_approach = 1/2 offset^2 (m^2): 1 cm costs 5
    w_approach_axis: float = 1e3  # ours: weight of c_approach_axis = 1 - x_G.d: 0.1 rad costs 5
    force_source: Literal["phi", "proxy"] = "phi"  # c_force's force(q, x): "phi" = phi's
    # contact forces per knot (Table I: forces between all pairs of objects, from the
    # simulation) with their Jacobians from phi's derivatives; "proxy" = force_stiffness x the
    # arm's penetration into boxes in the planning geometry (ours, the earlier stand-in)
    force_stiffness: float = 1.0e3  # N/m, c_force's penetration-to-force proxy; ours: at
    # phi's point stiffness (1e5) the proxy read 1e3-1e4 N where the arm sinks cm-deep into
    # boxes in phi, c_force outweighed every other term 1e5-fold and iLQR stopped at the
    # regularisation limit after 1-2 iterations (fig5, measured); at 1e3 it stays comparable
    hull_substeps: int = 2  # configurations per knot interval in c_static_hull / c_dynamic;
    # ours: as the baseline's opt_substeps
    pre_iterations: int = 10  # iLQR iterations of the Sec. V-A pre-processing; ours
    pre_terminal_weight: float = 100.0  # x w_grasp and w_grp_horiz at the pre-processing's
    # last knot; ours: they replace the baseline's terminal pose constraint (Sec. V-A keeps the
    # pre-grasp), and at 1x the squared distance let the tool frame drift 5 cm (measured)
    pre_w_vel: float | None = None  # w_vel of the Sec. V-A pre-processing's c_vel; None = the
    # baseline's (Sec. V-A: "c_static_hull and c_vel from the baseline approach remain"). Ours:
    # the baseline's knots are samples of a B-spline and smooth whatever w_vel is, the
    # pre-processing moves knots one by one, and at w_vel 1 c_dynamic rolls the wrist and
    # forearm back and forth between knots (largest joint second difference 0.13-0.94 rad on
    # fig5/6/8 at angles 5 and 8, against 0.001-0.006 for the baseline; 10: 0.02-0.18, with
    # less of c_dynamic removed: measured 2026-11-24); the judge's arm cannot follow such kinks.
    # Not adopted: on the behaviours tier (2026-11-24) pre_w_vel 10 without phi stages gave 8
    # better / 9 same / 7 worse (median kink 0.07 rad instead of 0.15, yet 3 lag failures
    # still), and with them (stopped after 8 of 24 initializations) 3 / 2 / 3 where the
    # defaults gave 4 / 3 / 1 on the same 8: the phi stages put the kinks back (median 0.34)
    post_iterations: int = 40  # iLQR iterations of the Sec. V-B post-processing; ours (a
    # kinematic iLQR: seconds). Measured (2026-11-23, 16 stored physics plans of the
    # behaviour scenes at alpha -0.21 / +0.21, docs/physics_planner_log.md): at 10, 4 plans
    # ended with c_static 16-58 in the evaluation geometry; 30 more iterations turned fig8
    # +0.21 from a kinematic failure into a failure to grasp with nothing disturbed, left the
    # other failures failures, and changed one outcome by a box (fig7 -0.21, 3 further
    # iterations on a converged path: Bullet's cascade is that sensitive); fig8 -0.21
    # converges at c_static 7.3 (c_match)
    sweep_spacing: float = 0.01  # m; ours: c_static / c_static_hull / c_dynamic sampled on a
    # knot interval take at least sweep / sweep_spacing configurations, sweep bounding how far
    # an arm point travels (`ArmGeometry.sweep`); 0 = the fixed counts alone. Measured
    # (fig6 at alpha -0.21, 2026-11-23): the physics plan swung a finger 30 cm through the
    # 3 cm board within one 0.2 s interval, between two of the post-processing's 6 samples;
    # the post's c_static read 0.002 and Bullet failed kinematically (8.6 mm deep)
    post_variant: str = "evaluation"  # arm geometry of the post-processing's c_static; Sec.
    # V-B: it corrects collisions that appear when switching to the evaluation model
    post_substeps: int = 6  # configurations per knot interval in the post-processing's
    # c_static (their mean, the knot included; 1 = the knot alone); ours: the evaluation's arm
    # passes every configuration between knots, and fig8's physics plan (wrist whipped from
    # -1.6 to +3.2 rad/s at a knot) put a finger into the board 50 ms after a knot - a
    # kinematic failure that c_static at the knots could not see (measured)
    tolerance: float = 1e-6  # relative cost decrease that stops iLQR (the solver's default);
    # ours: at 1e-4 the fig5 pre-processing stopped after a first short line-search step (2e-5)
    # with c_dynamic unchanged, at 1e-6 it went on to halve it in 10 iterations (measured)
    line_search_steps: int = 6  # step sizes tried per backward pass (every stage); ours:
    # each try is a rollout (through phi, or 2 x 29 distance queries); with adaptive_step the
    # search starts near the last accepted size, so 6 halvings (a factor 32) suffice; at 10
    # the fig6 pre-processing spent 60 rollouts failing before its first step (measured)
    parallel_line_search: bool = True  # phi stages roll out dynamics.workers step sizes at
    # once in the derivative workers (the first that lowers the objective is still the one
    # taken: the same plan as one after another); ours
    adaptive_step: bool = True  # start each line search at twice the last accepted step; ours:
    # on fig5 the phi stage's full step failed at every iteration (accepted 1/32..1/128 with
    # 5-10 failed rollouts before each, measured)
    step_limit_fraction: float = 0.5  # trust region of the phi stages: no control moves more
    # than this fraction of its per-knot speed-limit step (c_speed's max step) in one forward
    # pass, feedback included; ours: 5 unlimited iterations on fig5 raised c_static from 0 to
    # 45 (the arm pushed into the board) while trading c_force down (measured)
    max_failed_searches: int = 1  # a stage stops after this many failed line searches in one
    # iteration (mu x 10 after each); ours. Measured (2026-11-24, the four behaviour scenes at
    # angle indices 4-9, 24 initializations: `experiment run behaviours`, then `report`): with
    # 3 searches and the open-loop fallback, 61 % of the phi stages' rollouts went into failed
    # searches (most stages ended on three in a row); 1 and no fallback: physics against the
    # baseline 7 better / 10 same / 7 worse (6 kinematic failures) against 5 / 10 / 9 (9),
    # 1903 s of planning against 4215 s; bench_planner's 25-box initialization 174 s against
    # 685 s, its phi objective down to 0.099 of its start against 0.029
    max_spectral_radius: float = 1.0  # cap on the spectral radius of phi's box-to-box
    # Jacobian per knot in the phi stages (phi_stage.cap_spectral_radius); ours: toppling boxes
    # are locally unstable, and uncapped radii of 2-230 made fig8's costate reach 1e12
    # (measured); 1 leaves resting and sliding boxes (radius 1) as they are; 1e9: no cap
    open_loop_fallback: bool = False  # phi stages retry a failed line search with K = 0;
    # ours: the feedback amplifies the finite-difference errors of A in contact (issue 6); off
    # since 2026-11-24 with max_failed_searches 1 (measured there: it doubled a failed search's
    # rollouts; on the 25-box bench it kept the objective at 0.089 instead of 0.099 for 196 s
    # instead of 174 s)
    feedback: bool = True  # phi stages' forward passes feed back K (x - x_bar); ours. False:
    # open loop always (K = 0: the box states' chaotic deviations in contact do not move the
    # arm; the plan's feedback gains are still computed and saved). Behaviours tier at the pads
    # (2026-11-24): False 6 better / 8 same / 10 worse, 1649 s; True 7 / 9 / 8, 1238 s
    min_step: float = 1e-3  # rad (m for the opening): a phi stage stops after an accepted
    # step that moved no control by this much (1 mrad: < 1 mm at the gripper); ours, 0 = off.
    # Why: late in the phi stages the line search accepts step sizes 1e-4..1e-7 at mu
    # 1e4..1e7 that still lower phi's objective by 0.1-8 (phi's rollouts are that sensitive
    # in contact), and a stage that ends on failed line searches spends 3 x 6 rollouts on
    # them. Measured on the four behaviour scenes at alpha 0 (2026-11-24): the same Bullet
    # outcome on all four (fig7 and fig8 the same plan within 2e-4 rad); full stages 92-254 s
    # instead of 158-746 s (two plans sharing the 2 cores against three); at alpha +-0.21
    # no plan graded worse than without it and one better (fig5 +0.21), 99-415 s a plan
    # instead of 254-730 s (docs/physics_planner_log.md)


@dataclass(frozen=True)
class VizConfig:
    """Meshcat replays of plans (replay.py; issue 8): all ours."""

    fps: float = 30.0  # frames per second of simulated time in the Bullet recording and the
    # animation: smooth, and the evaluation's 60 Hz monitor updates fall on every other frame
    copy_margin: float = 0.3  # m between the shelves of two side-by-side copies of a scene
    camera_offset: tuple[float, float, float] = (1.0, 0.0, 0.85)  # m, camera from the shelf's
    # top centre for one copy: above and beyond the shelf looking back at the robot (from
    # behind the robot the arm hides the boxes)
    camera_spread: float = 0.6  # x camera_offset added per further copy, to see all of them
    force_scale: float = 0.03  # m of arrow per N of contact normal force: the arm's pushes on
    # the default scene peak at 2-5 N (3-15 cm arrows; at 0.01 they hid inside the boxes)
    min_force: float = 0.05  # N: smaller contact forces are not drawn (grazing touches)
    max_arrows: int = 24  # arrows per copy and frame at most (the largest forces)
    arrow_radius: float = 0.004  # m, shaft radius (the cone's base is twice as wide)
    arrow_tip_length: float = 0.02  # m
    arrow_rgba: tuple[float, float, float, float] = (1.0, 0.85, 0.0, 1.0)  # yellow: no box,
    # shelf or arm has that colour
    tipped_rgba: tuple[float, float, float, float] = (1.0, 0.5, 0.0, 1.0)  # orange
    fallen_rgba: tuple[float, float, float, float] = (0.9, 0.05, 0.05, 1.0)  # red
    highlight_padding: float = 0.002  # m the tipped/fallen overlay reaches past the box


@dataclass(frozen=True)
class Config:
    """All settings of drake_clutter, one section per module."""

    generator: GeneratorConfig = field(default_factory=GeneratorConfig)
    world: WorldConfig = field(default_factory=WorldConfig)
    baseline: BaselineConfig = field(default_factory=BaselineConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    dynamics: DynamicsConfig = field(default_factory=DynamicsConfig)
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    viz: VizConfig = field(default_factory=VizConfig)


def config_to_data(config: Config) -> dict:
    """The configuration as plain nested data (YAML-ready)."""
    return to_data(config)


def load_config(path: str | Path | None = None, overrides: list[str] | tuple = ()) -> Config:
    """Defaults, then the YAML file at ``path`` (if any), then ``key=value`` overrides.

    Raises ConfigError naming the file (or '<command line>'), the field and the reason.
    """
    data = config_to_data(Config())
    if path is not None:
        user = read_yaml_file(path, error_cls=ConfigError)
        if user is not None:
            if not isinstance(user, dict):
                raise ConfigError(path, "", "a configuration must be a YAML mapping")
            data = _merge(data, user, path)
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError("<command line>", item, "expected key=value")
        data = apply_override(data, key.strip(), value, error_cls=ConfigError)
    return from_data(Config, data, file=path or "<command line>", error_cls=ConfigError)


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
