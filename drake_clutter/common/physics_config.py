"""The physics planners' sections of the one configuration (`config.Config`): phi as iLQR's
dynamics (``dynamics``), Sec. V's planner (``physics``, Tables I and II), and beyond the paper
the straight starts both physics-based planners use (``starts``), the judge in phi
(``phi_judge``) and the push planner's family and search (``push_search``).

The same rule as in `config`: each field has one comment line above it (what, unit, source:
a section or table of the paper, or "ours"); why each value is what it is: one line per field
in docs/decisions.md, the dated measurements in docs/log/decisions.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from drake_clutter.common.accepts import SEED_MAX, bounded


@dataclass(frozen=True)
class DynamicsConfig:
    """phi as iLQR's dynamics and its derivatives (Sec. V)."""

    # phi's simulation engine ("drake": Drake's SAP; "mujoco": the paper's engine), choice; ours
    engine: Literal["drake", "mujoco"] = "drake"
    # longest time step of the MuJoCo phi (a knot is split into equal steps), s; MuJoCo's default
    mujoco_time_step: float = bounded(0.002, ge=1e-5)
    # contact time constant of the MuJoCo phi (MJCF solref[0]), s; MuJoCo's default
    mujoco_contact_time: float = bounded(0.02, gt=0.0)
    # contact damping ratio of the MuJoCo phi (MJCF solref[1]), unitless; MuJoCo's default
    mujoco_contact_damping: float = bounded(1.0, gt=0.0)
    # impedance of the MuJoCo phi's contacts at zero penetration (MJCF solimp[0]), unitless; ours
    mujoco_impedance_min: float = bounded(1e-4, ge=1e-4, lt=1.0)
    # impedance they reach at mujoco_impedance_width (MJCF solimp[1]), unitless; MuJoCo's default
    mujoco_impedance_max: float = bounded(0.95, ge=1e-4, lt=1.0)
    # penetration over which the impedance rises (MJCF solimp[2]), m; ours
    mujoco_impedance_width: float = bounded(0.0005, gt=0.0)
    # MuJoCo phi's solver tolerance (MuJoCo's 1e-8 stops early: steps jump), unitless; ours
    mujoco_solver_tolerance: float = bounded(1e-14, ge=0.0)
    # MuJoCo phi's line-search tolerance (MuJoCo's default 0.01), unitless; ours
    mujoco_line_search_tolerance: float = bounded(1e-10, ge=0.0)
    # MuJoCo steps between phi's readings (forces, contacts, jam, speed cap), count; ours
    mujoco_sample_steps: int = bounded(10, ge=1, le=1000)
    # armature of the MuJoCo phi's arm joints (contacts cannot move it), kg m^2 or kg; ours
    mujoco_arm_armature: float = bounded(1.0e6, gt=0.0)
    # resting boxes sleep in the MuJoCo phi (MuJoCo's islands; the judge in phi sets it), flag; ours
    mujoco_sleep: bool = False
    # speed below which a MuJoCo tree counts as at rest and may sleep, m/s or rad/s; MuJoCo's
    mujoco_sleep_tolerance: float = bounded(1e-3, gt=0.0, le=0.1)
    # finite-difference step of phi's Jacobians, state units (m, rad, m/s); Sec. V
    fd_step: float = bounded(1e-6, gt=0.0)
    # finite-difference scheme ("forward" or "central"), choice; Sec. V
    fd_scheme: Literal["forward", "central"] = "forward"
    # margin around the arm's swept volume within which boxes stay dynamic, m; ours
    prune_margin: float = bounded(0.05, ge=0.0)
    # Jacobians A_t, B_t every k-th knot and the last, interpolated between (1: all), count; ours
    derivative_stride: int = bounded(3, ge=1, le=500)
    # how phi's Jacobians are taken ("fd", "autodiff", "hybrid"), choice; ours
    derivative_method: Literal["fd", "autodiff", "hybrid"] = "hybrid"
    # colour groups at a knot from which "hybrid" takes AutoDiffXd, count; ours
    autodiff_min_groups: int = bounded(20, ge=1, le=100000)
    # parallel derivative workers (0 = serial, in the calling process), count; ours
    workers: int = bounded(2, ge=0, le=64)
    # SAP sub-steps of phi per knot (0.2 s knots / 10 = 20 ms), count; ours
    substeps: int = bounded(10, ge=1, le=1000)
    # box contact geometry in phi ("point", "spheres", "hydroelastic", "edges"), choice; ours
    contact_model: Literal["point", "spheres", "hydroelastic", "edges"] = "edges"
    # radius of the spheres inside the box corners ("point", "spheres"), m; ours
    corner_sphere_radius: float = bounded(0.004, gt=0.0)
    # radius of the spheres on the box edges that meet the shelf ("edges"), m; ours
    edge_sphere_radius: float = bounded(0.001, gt=0.0)
    # largest gap between the spheres along a box edge ("edges"; 0: corners only), m; ours
    edge_sphere_spacing: float = bounded(0.02, ge=0.0)
    # depth of phi's board collision box under the edge spheres ("edges": none tunnel), m; ours
    edge_board_depth: float = bounded(0.1, gt=0.0)
    # bodies closer than this at a sub-step's start may interact in that step, m; ours
    interaction_margin: float = bounded(1e-3, gt=0.0)
    # largest state change for which a resting box reuses its Jacobian block, m, rad, m/s; ours
    known_block_tolerance: float = bounded(1e-7, ge=0.0)
    # boxes within this of a kept box are kept too (transitively), m; ours
    prune_contact_range: float = bounded(0.01, ge=0.0)
    # rollouts that check the kept set (frozen boxes reached become dynamic), count; ours
    prune_rounds: int = bounded(3, ge=0, le=20)
    # arm poses per knot interval for the swept volume, count; ours
    prune_samples_per_knot: int = bounded(4, ge=1, le=100)
    # time the boxes rest under the still arm before planning, s; ours
    settle_time: float = bounded(3.0, ge=0.0, le=60.0)
    # traced steps remembered for linearize (2 iLQR horizons of line search), count; ours
    step_cache_size: int = bounded(512, ge=1, le=1000000)
    # multiple of a box's weight beyond which its shelf force counts in c_force, unitless; ours
    shelf_force_allowance: float = bounded(1.5, ge=0.0)
    # cap on a box's translational speed after every SAP sub-step, m/s; ours
    max_box_speed: float = bounded(5.0, gt=0.0)
    # cap on a box's angular speed after every SAP sub-step, rad/s; ours
    max_box_spin: float = bounded(30.0, gt=0.0)
    # |number| in a box state beyond which a step counts as diverged, m, m/s, rad/s; ours
    divergence_limit: float = bounded(1.0e6, gt=0.0)

    def relations(self):
        """(field, holds, what it must be) between this dataclass's fields."""
        return [("derivative_method",
                 not (self.derivative_method == "autodiff" and self.contact_model == "point"),
                 "other than 'autodiff' with contact_model 'point' (no AutoDiffXd Box-Box "
                 "queries)"),
                ("derivative_method",
                 not (self.derivative_method == "autodiff" and self.engine == "mujoco"),
                 "other than 'autodiff' with engine 'mujoco' (its Jacobians are finite "
                 "differences)"),
                ("mujoco_contact_time", self.mujoco_contact_time >= 2 * self.mujoco_time_step,
                 f"at least twice mujoco_time_step ({self.mujoco_time_step:g} s): MuJoCo "
                 f"would raise a shorter one silently")]


@dataclass(frozen=True)
class PhysicsConfig:
    """The physics-based planner (Sec. V, Tables I and II)."""

    # cap on the iLQR iterations through phi (0: no phi stages; Sec. V: 30), count; ours
    iterations: int = bounded(0, ge=0, le=100000)
    # first iterations run with the sphere gripper proxy (Sec. V: 10 of the 30), count; ours
    sphere_iterations: int = bounded(0, ge=0, le=100000)
    # the target in the sphere stage's phi ("passes" or "parked"), choice; ours
    sphere_target: Literal["passes", "parked"] = "parked"
    # weight of c_static, unitless; Table II
    w_static: float = bounded(1e3, ge=0.0)
    # weight of c_acc, unitless; Table II
    w_acc: float = bounded(1e-3, ge=0.0)
    # weight of c_force (Table II says 10), unitless; ours
    w_force: float = bounded(0.01, ge=0.0)
    # weight of c_motion, unitless; Table II
    w_motion: float = bounded(1e-3, ge=0.0)
    # weight of c_upright, unitless; Table II
    w_upright: float = bounded(1.0, ge=0.0)
    # weight of the terminal c_grasp, unitless; Table II
    w_grasp: float = bounded(1e3, ge=0.0)
    # weight of the terminal c_grp_horiz, unitless; Table II
    w_grp_horiz: float = bounded(1.0, ge=0.0)
    # weight of the terminal c_grp_open, unitless; Table II
    w_grp_open: float = bounded(1.0, ge=0.0)
    # weight of c_dynamic in the Sec. V-A pre-processing (as w_static_hull), unitless; ours
    w_dynamic: float = bounded(80.0, ge=0.0)
    # weight of c_match in the Sec. V-B post-processing, unitless; ours
    w_match: float = bounded(1.0, ge=0.0)
    # weight of c_match_vel in the Sec. V-B post-processing, unitless; ours
    w_match_vel: float = bounded(1.0, ge=0.0)
    # knots phi runs past Delta with the arm held (Table II's "all"), count; ours
    hold_knots: int = bounded(5, ge=0, le=100)
    # weight of c_speed, the squared excess over the speed cap, unitless; ours
    w_speed: float = bounded(1.0e4, ge=0.0)
    # c_speed's cap, a fraction of the PR2's joint speed limits, unitless; ours
    speed_fraction: float = bounded(0.25, gt=0.0)
    # smoothing eps of c_grasp = sqrt(d^2 + eps^2) - eps, m; ours
    grasp_smoothing: float = bounded(0.005, gt=0.0)
    # c_grasp's point ("pregrasp" point carried by the target, or its "centre"), choice; ours
    grasp_aim: Literal["pregrasp", "centre"] = "pregrasp"
    # Hessian of the phi stages' c_grasp and c_upright ("gauss_newton", "majorizer"), choice; ours
    distance_curvature: Literal["gauss_newton", "majorizer"] = "majorizer"
    # Hessian of c_upright ("tilt": J'J/s of z's horizontal part; "angle": as c_grasp), choice; ours
    upright_curvature: Literal["tilt", "angle"] = "tilt"
    # force(q, x) of c_force ("phi": phi's contact forces, or "proxy"), choice; Table I
    force_source: Literal["phi", "proxy"] = "phi"
    # stiffness of c_force's penetration-to-force proxy, N/m; ours
    force_stiffness: float = bounded(1.0e3, gt=0.0)
    # configurations per knot interval in c_static_hull / c_dynamic, count; ours
    hull_substeps: int = bounded(2, ge=1, le=100)
    # wall time of an initialization's stages (then the best path so far is the plan), s; ours
    time_budget: float | None = bounded(600.0, gt=0.0, le=86400.0)
    # iLQR iterations of the Sec. V-A pre-processing, count; ours
    pre_iterations: int = bounded(10, ge=0, le=100000)
    # multiple of w_grasp and w_grp_horiz at the pre-processing's last knot, unitless; ours
    pre_terminal_weight: float = bounded(100.0, ge=0.0)
    # the pre-processing keeps the baseline's last knot and gripper openings (bounds), flag; ours
    pre_keep_pregrasp: bool = True
    # the post-processing keeps its reference's last knot and gripper openings (bounds), flag; ours
    post_keep_end: bool = True
    # the phi stages' last knot opens the gripper at least as wide as the baseline's, flag; ours
    keep_open: bool = True
    # the plan is the best in one phi of the baseline, pre- and post-processed paths, flag; ours
    select_in_phi: bool = True
    # iLQR iterations of the Sec. V-B post-processing, count; ours
    post_iterations: int = bounded(40, ge=0, le=100000)
    # largest arm-point travel between swept-cost samples (0: fixed counts alone), m; ours
    sweep_spacing: float = bounded(0.01, ge=0.0)
    # arm geometry variant of the post-processing's c_static, name; Sec. V-B
    post_variant: Literal["capsules", "sphere_gripper", "evaluation"] = "evaluation"
    # configurations per knot interval in the post-processing's c_static, count; ours
    post_substeps: int = bounded(6, ge=1, le=100)
    # relative cost decrease that stops iLQR (the solver's default), unitless; ours
    tolerance: float = bounded(1e-6, ge=0.0)
    # a step's share of a phi stage's decrease that counts as stalled (0 = off), unitless; ours
    stall_fraction: float = bounded(0.05, ge=0.0, lt=1.0)
    # accepted steps in a row under stall_fraction that stop a phi stage, count; ours
    stall_iterations: int = bounded(2, ge=1, le=1000)
    # step sizes tried per backward pass (every stage), count; ours
    line_search_steps: int = bounded(6, ge=1, le=100)
    # phi stages roll out dynamics.workers step sizes at once, flag; ours
    parallel_line_search: bool = True
    # each line search starts at twice the last accepted step, flag; ours
    adaptive_step: bool = True
    # phi stages' trust region, a fraction of the per-knot speed-limit step, unitless; ours
    step_limit_fraction: float = bounded(0.5, gt=0.0)
    # failed line searches in one iteration that stop a stage, count; ours
    max_failed_searches: int = bounded(1, ge=1, le=100)
    # cap on the spectral radius of phi's box-to-box Jacobian per knot, unitless; ours
    max_spectral_radius: float = bounded(1.0, gt=0.0)
    # rows the cap scales ("box": each unstable box's own first; "block": every box's), choice; ours
    spectral_cap_scope: Literal["box", "block"] = "box"
    # controls of the phi stages: every knot ("knots", Sec. V) or B-spline points, choice; ours
    controls: Literal["knots", "spline"] = "spline"
    # B-spline control points of "spline" controls (the baseline's, Sec. IV), count; ours
    control_points: int = bounded(10, ge=2, le=200)
    # smallest control move that keeps a phi stage going (0 = off), rad (m: opening); ours
    min_step: float = bounded(1e-3, ge=0.0)
    # every stage's backward pass solves each knot's box-constrained QP (Tassa 2014), flag; ours
    box_qp: bool = True
    # the phi stages' trust region bounds the backward pass's QP, not only clips, flag; ours
    trust_bounds: bool = True
    # the phi stages' trust region adapts to actual / predicted decrease, flag; ours
    trust_adapt: bool = True
    # least actual / predicted decrease of an accepted phi-stage step (0: any), unitless; ours
    accept_ratio: float = bounded(0.0, ge=0.0, lt=1.0)
    # the phi stages' regulariser is scaled per control by its trust-region step, flag; ours
    scaled_regulariser: bool = True

    def relations(self):
        """(field, holds, what it must be) between this dataclass's fields."""
        return [("sphere_iterations", self.sphere_iterations <= self.iterations,
                 f"at most iterations ({self.iterations})")]


@dataclass(frozen=True)
class StartsConfig:
    """The straight starts of the physics-based planners (beyond the paper): the baseline's path
    at other grasp heights and yaws, the check that keeps a start off the boxes, and the turns
    tried where no start plans at an angle. All ours."""

    # grasp heights also tried per angle (the first clear start is taken), of target height; ours
    grasp_heights: tuple[float, ...] = bounded((0.6, 0.7, 0.8, 0.9), gt=0.0, le=1.0)
    # approach angle offsets also tried at every grasp height (the first clear start), rad; ours
    approach_offsets: tuple[float, ...] = bounded((), ge=-0.5, le=0.5)
    # yaw turns toward alpha = 0 tried when no start plans at the angle (push planner), rad; ours
    recovery_turns: tuple[float, ...] = bounded((0.1, 0.2, 0.3), gt=0.0, le=0.5)
    # up component of a contact normal (box to arm) beyond which the arm presses, unitless; ours
    press_normal_z: float = bounded(0.5, ge=0.0, lt=1.0)
    # deepest press (starts.press_normal_z) a straight start counts as none, m; ours
    press_tolerance: float = bounded(0.0005, ge=0.0)
    # deepest entry into a non-target box's side a straight start counts as none, m; ours
    side_tolerance: float = bounded(0.005, ge=0.0)
    # configurations per knot interval the press check reads, count; ours
    press_substeps: int = bounded(4, ge=1, le=100)


@dataclass(frozen=True)
class PhiJudgeConfig:
    """The judge in phi (beyond the paper): a plan rolled out in phi's ensemble of perturbed
    worlds and read into the judge's classes; its engine, members and readings. All ours."""

    # phi's engine the judge in phi rolls plans out in (gate measured in MuJoCo), choice; ours
    engine: Literal["drake", "mujoco"] = "mujoco"
    # members a plan is judged in (member 0 the scene; the search scores every path), count; ours
    members: int = bounded(4, ge=1, le=256)
    # held-out members (the next ones) a bent path must win on to replace its start, count; ours
    veto_members: int = bounded(4, ge=1, le=256)
    # seed of the members' worlds (member k draws from [seed, k]), integer; ours
    seed: int = bounded(1000, ge=0, le=SEED_MAX)
    # half-range of each box's initial shift along x and y (uniform), m; ours
    position: float = bounded(0.003, ge=0.0)
    # half-range of each box's initial yaw change (uniform; 3 deg), rad; ours
    yaw: float = bounded(0.05, ge=0.0)
    # half-range of each box's relative mass change (uniform), unitless; ours
    mass: float = bounded(0.2, ge=0.0, lt=1.0)
    # half-range of each box's relative friction change (uniform), unitless; ours
    friction: float = bounded(0.2, ge=0.0, lt=1.0)
    # member 1 pairs friction as Bullet does (world.friction_as_bullet), flag; ours
    bullet_friction_member: bool = True
    # knots the judge in phi holds the arm after Delta before reading the boxes, count; ours
    hold_knots: int = bounded(5, ge=0, le=100)
    # threads rolling out the paths of one member's MuJoCo phi at once (1: in turn), count; ours
    threads: int = bounded(1, ge=1, le=64)
    # one knot's commanded approach into a blocked box read as a jam (phi.jam), m; ours
    jam_depth: float = bounded(0.001, gt=0.0)
    # how a path is rolled out ("knot": phi(x, u) per knot; "kept": one MuJoCo world), choice; ours
    stepping: Literal["knot", "kept"] = "kept"
    # MuJoCo time step of the judge's phi (dynamics.mujoco_time_step for it), s; ours
    time_step: float = bounded(0.004, ge=1e-4, le=0.01)
    # MuJoCo steps between the judge's phi readings (its mujoco_sample_steps), count; ours
    sample_steps: int = bounded(10, ge=1, le=1000)
    # resting boxes sleep in the judge's kept MuJoCo worlds (MuJoCo's islands), flag; ours
    sleep: bool = True
    # phi pruned to the boxes near the paths (false: all kept, resting ones asleep), flag; ours
    prune: bool = False

    def relations(self):
        """(field, holds, what it must be) between this dataclass's fields."""
        return [("sleep", not self.sleep or (self.stepping == "kept" and self.engine == "mujoco"),
                 "false unless stepping is 'kept' and engine 'mujoco' (a world reset at every "
                 "knot wakes every box)")]


@dataclass(frozen=True)
class PushSearchConfig:
    """The push planner (beyond the paper): its path family's draws and its sampling search over
    them. All ours."""

    # family members drawn in the first round, over all starts, count; ours
    samples: int = bounded(12, ge=0, le=100000)
    # rounds of the search (the later ones perturb the best bent paths), count; ours
    rounds: int = bounded(2, ge=1, le=1000)
    # best bent paths perturbed in each later round, count; ours
    elite: int = bounded(2, ge=1, le=1000)
    # perturbations drawn per elite path in a later round, count; ours
    perturbations: int = bounded(3, ge=1, le=1000)
    # standard deviation of a perturbation's sideways and vertical via-point offsets, m; ours
    jitter_offset: float = bounded(0.015, ge=0.0)
    # standard deviation of a perturbation's via-point progress and time, fraction; ours
    jitter_progress: float = bounded(0.04, ge=0.0)
    # how a later round draws: the elite perturbed at fixed spreads, or cross-entropy, choice; ours
    method: Literal["perturb", "cem"] = "perturb"
    # paths drawn per later round by the cross-entropy search, over the elite in turn, count; ours
    population: int = bounded(24, ge=1, le=100000)
    # smallest spread of the cross-entropy search's via-point offsets, m; ours
    spread_floor_offset: float = bounded(0.003, ge=0.0, le=0.5)
    # smallest spread of the cross-entropy search's via-point progress and time, fraction; ours
    spread_floor_progress: float = bounded(0.01, ge=0.0, le=0.5)
    # weight of the old spread when the cross-entropy search refits it to the elite, unitless; ours
    smoothing: float = bounded(0.5, ge=0.0, le=1.0)
    # return the first straight start that keeps off the boxes without a search, flag; ours
    clear_first: bool = True
    # rank the judged paths by the margin beneath the classes (PhiVerdict.key), flag; ours
    margin: bool = True
    # return the baseline's own path when no judged path reads success or partial in phi, flag; ours
    fallback: bool = True
    # P(success) in phi of the best start at which the search does not run, unitless; ours
    stop_at: float = bounded(1.0, ge=0.0, le=1.0)
    # seed of the search's draws (a candidate draws from [seed, angle index]), integer; ours
    seed: int = bounded(0, ge=0, le=SEED_MAX)
    # wall time of the push planner on one initialization, starts to veto (None: no limit), s; ours
    time_budget: float | None = bounded(300.0, gt=0.0, le=86400.0)
    # half-range of a via-point's sideways offset from the straight path (uniform), m; ours
    lateral: float = bounded(0.10, ge=0.0)
    # lowest vertical offset of a via-point above the straight path, m; ours
    vertical_low: float = bounded(-0.01, le=0.0)
    # highest vertical offset of a via-point above the straight path, m; ours
    vertical_high: float = bounded(0.06, ge=0.0)
    # earliest via-point time, a fraction of the path's duration, unitless; ours
    knot_low: float = bounded(0.2, gt=0.0, lt=1.0)
    # latest via-point time, a fraction of the path's duration, unitless; ours
    knot_high: float = bounded(0.9, gt=0.0, lt=1.0)
    # least progress along the straight path at a via-point, a fraction, unitless; ours
    progress_low: float = bounded(0.2, ge=0.0, le=1.0)
    # most progress along the straight path at a via-point, a fraction, unitless; ours
    progress_high: float = bounded(0.95, ge=0.0, le=1.0)
    # chance that a drawn member keeps the gripper closed until a drawn time, unitless; ours
    closed_chance: float = bounded(0.3, ge=0.0, le=1.0)
    # via-points per drawn member, count; ours
    vias: int = bounded(2, ge=1, le=10)
    # chance that a member is aimed at a box the straight path meets (else drawn blind); ours
    aimed_chance: float = bounded(1.0, ge=0.0, le=1.0)
    # chance that an aimed move pushes or passes the box toward its own side of the line; ours
    own_side_chance: float = bounded(0.75, ge=0.0, le=1.0)
    # chance that an aimed move pushes the box aside (else it goes around it), unitless; ours
    aside_chance: float = bounded(0.5, ge=0.0, le=1.0)
    # half the closed gripper's width across the approach (PR2 palm, ~0.05), m; ours
    gripper_half_width: float = bounded(0.05, gt=0.0)
    # how far before a box's near face an aimed move starts sideways, m; ours
    aim_standoff: float = bounded(0.03, ge=0.0)
    # range of the uniform extra clearance and depth of an aimed move, m; ours
    aim_slack: float = bounded(0.04, ge=0.0)

    def relations(self):
        """(dotted field, holds, what it must be) between this section's fields."""
        return [("knot_high", self.knot_low <= self.knot_high,
                 f"at least push_search.knot_low ({self.knot_low:g})"),
                ("progress_high", self.progress_low <= self.progress_high,
                 f"at least push_search.progress_low ({self.progress_low:g})")]


@dataclass(frozen=True)
class RearrangeConfig:
    """The rearrange planner (beyond the paper): which boxes crowding the final reach to push
    where and in what order (a beam search on the board, geometry first), the push actions'
    paths, and the judgement in phi that accepts a sequence. All ours."""

    # depth a box other than the target may enter the reach's swept arm and open gripper, m; ours
    deep: float = bounded(0.005, ge=0.0, le=0.1)
    # last knots of the reach whose swept arm is the region to clear (0: all), count; ours
    region_knots: int = bounded(1, ge=0, le=1000)
    # push moves in a sequence at most, count; ours (Dogar & Srinivasa; M4M)
    max_moves: int = bounded(6, ge=1, le=20)
    # board states kept per depth of the beam search, count; ours
    beam_width: int = bounded(4, ge=1, le=100)
    # push directions tried per box, evenly spread on the board, count; ours
    directions: int = bounded(16, ge=1, le=64)
    # most a push direction may point back at the robot (minus its cosine with d), unitless; ours
    pull_limit: float = bounded(0.1, ge=0.0, le=1.0)
    # increment of a push's travel while the board search looks for room, m; ours
    step: float = bounded(0.01, gt=0.0, le=0.1)
    # longest travel of one pushed box, m; ours
    max_travel: float = bounded(0.2, gt=0.0, le=1.0)
    # travel added past the point where the pushed box leaves the reach, m; ours
    travel_margin: float = bounded(0.02, ge=0.0, le=0.2)
    # boxes one push moves at most, the pushed box and those it shoves ahead, count; ours
    chain: int = bounded(3, ge=1, le=10)
    # gap between the closed gripper and the box's face before a push, m; ours
    standoff: float = bounded(0.03, ge=0.0, le=0.2)
    # how far the gripper backs off along the push after it, m; ours
    retreat: float = bounded(0.05, ge=0.0, le=0.3)
    # height of the push above the box's bottom, a fraction of its height, unitless; ours
    push_height: float = bounded(0.4, gt=0.0, lt=1.0)
    # a push tried at push_height first, below G's pre-grasp height (else never below), flag; ours
    push_low: bool = False
    # downward tilt of the closed gripper's axis from the pre-grasp's while it pushes, rad; ours
    push_pitch: float = bounded(0.0, ge=0.0, le=1.2)
    # angular speed of G turning to and from push_pitch in front of the shelf, rad/s; ours
    turn_speed: float = bounded(1.0, gt=0.0, le=3.0)
    # pushes mechanics says tip their box: "ignore", "rank" after the rest, "refuse"; ours
    tipping: Literal["ignore", "rank", "refuse"] = "ignore"
    # a push whose arm another box blocks may push that box out of its way first, flag; ours
    clear_ways: bool = False
    # speed of the tool frame moving to and from a push, m/s; ours
    tool_speed: float = bounded(0.15, gt=0.0, le=1.0)
    # speed of the tool frame while it pushes, m/s; ours
    push_speed: float = bounded(0.05, gt=0.0, le=1.0)
    # depth the closed gripper and arm may enter a box it is not pushing, m; ours
    entry_tolerance: float = bounded(0.045, ge=0.0, le=0.1)
    # depth the closed gripper and arm may enter the target at any time, m; ours
    target_tolerance: float = bounded(0.008, ge=0.0, le=0.05)
    # sequences that make room on the board judged in phi, the cheapest first, count; ours
    sequences: int = bounded(4, ge=1, le=100)
    # least P(success) in phi's members for a sequence to replace the push answer, unitless; ours
    acceptance: float = bounded(0.5, ge=0.0, le=1.0)
    # a sequence whose classes tie the crowded push answer's in phi replaces it, flag; ours
    prefer_room: bool = True
    # wall time of the rearrange planner on one initialization, after the push planner, s; ours
    time_budget: float | None = bounded(120.0, gt=0.0, le=86400.0)

    def relations(self):
        """(dotted field, holds, what it must be) between this section's fields."""
        return [("max_travel", self.step <= self.max_travel,
                 f"at least rearrange.step ({self.step:g})")]
