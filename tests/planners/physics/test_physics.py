"""The physics planner (Sec. V): its geometry, objectives and pipeline.

Derivatives are checked against central differences (step 1e-6, in the tangent coordinates the
solver uses) on fig5_large_small with the arm at a baseline candidate's pre-grasp knot and boxes
moved into the arm, so that every geometric term is active.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from scipy.spatial.transform import Rotation

from drake_clutter.common.config import PhysicsConfig
from drake_clutter.experiments.specs import load_spec
from drake_clutter.phi.dynamics import initial_state
from drake_clutter.phi.state import (
    StateLayout,
    pose_to_box_state,
    scene_box_states,
)
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import SHELF, ArmGeometry, path_depths, path_press
from drake_clutter.planners.physics.kinematic import KinematicObjective
from drake_clutter.planners.physics.objective import PhysicsObjective
from drake_clutter.planners.physics.penetration import (
    segment_penetration,
)
from drake_clutter.scene import scenes

# The pre-grasp configuration of fig5_large_small (alpha = 0.3 baseline, last knot, board
# front 0.55 m ahead of the robot), rounded; fixed here so the tests need no IK.
Q_PREGRASP = np.array([-0.26, -0.182, -2.726, -1.193, -3.723, -0.881, -0.058, 0.09])
EPS = 1e-6


@pytest.fixture(scope="module")
def geometry(scene):
    return ArmGeometry(scene, "capsules")


def _near_tool_pose(geometry, q, offset, yaw=0.3, tilt=0.1):
    p, *_ = geometry.tool(q)
    return RigidTransform(RollPitchYaw(tilt, 0.05, yaw), p + np.asarray(offset))


def _numeric_jacobian(f, x, step=EPS):
    """Central differences of a vector function: (len(f(x)), len(x))."""
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = step
        cols.append((f(x + e) - f(x - e)) / (2 * step))
    return np.array(cols).T


def _numeric_gradient(f, x, step=EPS):
    g = np.zeros(len(x))
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = step
        g[i] = (f(x + e) - f(x - e)) / (2 * step)
    return g


def test_distance_gradients_match_differences(geometry):
    q = Q_PREGRASP
    X_WB = _near_tool_pose(geometry, q, [0.02, 0.0, 0.0])
    name = "large_stable"
    contacts = [c for c in geometry.contacts(q, {name: X_WB}, 0.05, "boxes")
                if c.obstacle == name]
    assert contacts, "the moved box must be near the arm"
    deepest = min(contacts, key=lambda c: c.distance)

    def distance(q_arm, X):
        found = [c.distance for c in geometry.contacts(q_arm, {name: X}, 0.05, "boxes")
                 if c.obstacle == name]
        return min(found)

    g_q = _numeric_gradient(lambda v: distance(v, X_WB), q)
    np.testing.assert_allclose(deepest.d_dq, g_q, atol=2e-4)

    def moved(d):
        R = Rotation.from_rotvec(d[:3]).as_matrix() @ X_WB.rotation().matrix()
        return RigidTransform(RotationMatrix(R), X_WB.translation() + d[3:])

    g_box = _numeric_gradient(lambda d: distance(q, moved(d)), np.zeros(6))
    np.testing.assert_allclose(deepest.d_dbox, g_box, atol=2e-4)


def test_tool_jacobians_match_differences(geometry):
    q = Q_PREGRASP
    p, z, dp, dz = geometry.tool(q)
    for i in range(8):
        e = np.zeros(8)
        e[i] = EPS
        pp, zp, *_ = geometry.tool(q + e)
        pm, zm, *_ = geometry.tool(q - e)
        np.testing.assert_allclose(dp[:, i], (pp - pm) / (2 * EPS), atol=1e-6)
        np.testing.assert_allclose(dz[:, i], (zp - zm) / (2 * EPS), atol=1e-6)
        xp, xm = geometry.tool_axis(q + e, 0)[0], geometry.tool_axis(q - e, 0)[0]
        np.testing.assert_allclose(geometry.tool_axis(q, 0)[1][:, i], (xp - xm) / (2 * EPS),
                                   atol=1e-6)
    assert np.isclose(np.linalg.norm(z), 1.0)
    np.testing.assert_allclose(geometry.tool_axis(q, 2)[0], z)


def test_shelf_contacts_are_labelled(geometry):
    q = Q_PREGRASP
    found = geometry.contacts(q, None, 1.0, "shelf")
    assert found and all(c.obstacle == SHELF and c.d_dbox is None for c in found)


def test_path_depths_splits_a_box_top_from_its_side(geometry):
    """`path_depths` with every other box out of the way: nothing touched reads (0, 0); the
    wide box under the gripper is a press (as `path_press` reads it); the box beside the
    gripper, entered from the side, is a side penetration as deep as its deepest contact, and
    none where that box is excluded."""
    q = Q_PREGRASP
    path = np.array([q, q])
    p_G = geometry.tool(q)[0]
    box = geometry.scene.box("large_stable")
    away = {b.name: RigidTransform([5.0 + i, 5.0, 0.0])
            for i, b in enumerate(geometry.scene.boxes)}
    geometry.set_state(q, away)
    assert path_depths(geometry, path, 2, 0.5) == (0.0, 0.0)
    geometry.set_state(q, {box.name: RigidTransform(p_G + [0.0, 0.0, 0.005 - box.size[2] / 2])})
    press, _ = path_depths(geometry, path, 2, 0.5)
    assert press > 0.0 and press == path_press(geometry, path, 2, 0.5)
    geometry.set_state(q, {box.name: RigidTransform(p_G + [0.0, box.size[1] / 2, 0.0])})
    entered = [c for c in geometry.contacts(q, None, 0.0, "boxes") if c.obstacle == box.name]
    assert entered and all(c.normal[2] <= 0.5 for c in entered)
    assert path_depths(geometry, path, 2, 0.5) == (0.0, max(-c.distance for c in entered))
    assert path_depths(geometry, path, 2, 0.5, (box.name,)) == (0.0, 0.0)
    geometry.set_state(q, {b.name: geometry.rest_pose(b.name) for b in geometry.scene.boxes})


# ----------------------------------------------------------------------------- objective


@pytest.fixture(scope="module")
def physics_problem(scene, geometry):
    layout = StateLayout(("target", "large_stable", "small_tippy"))
    states = scene_box_states(scene)
    x0 = initial_state(layout, Q_PREGRASP, states)
    q = Q_PREGRASP.copy()
    q[7] = 0.07  # partly closed: c_grp_open active
    moved = dict(states)
    moved["large_stable"] = pose_to_box_state(_near_tool_pose(geometry, q, [0.03, 0.0, 0.0]))
    tilted = RigidTransform(RollPitchYaw(0.2, -0.1, 0.4),
                            states["small_tippy"][4:7] + np.array([0.01, 0.02, 0.0]))
    moved["small_tippy"] = pose_to_box_state(tilted, np.array([0.1, 0.0, 0.2, 0.0, 0.05, 0.0]))
    x = initial_state(layout, q, moved)
    z = np.concatenate([x, Q_PREGRASP + 0.01])
    objective = PhysicsObjective(geometry, layout, PhysicsConfig(), x0, "target",
                                 knot_time=0.2, d_safe=0.02)
    return objective, layout, z


def test_grasp_point_at_the_pads_is_on_the_target_and_its_gradient_matches(scene, geometry):
    """With ``grasp_offset`` (the pads' centre, 1.5 cm behind G along x_G) c_grasp vanishes
    where that point, not G, is on the target's centre; its gradient is the numerical one."""
    from drake_clutter.robot import pr2

    offset = pr2.PADS_BEHIND_TOOL
    layout = StateLayout(("target",))
    p_G, *_ = geometry.tool(Q_PREGRASP)
    x_G, _ = geometry.tool_axis(Q_PREGRASP, 0)
    states = scene_box_states(scene)
    at_pads = dict(states)
    at_pads["target"] = states["target"].copy()
    at_pads["target"][4:7] = p_G - offset * x_G
    x = initial_state(layout, Q_PREGRASP, at_pads)
    z = np.concatenate([x, Q_PREGRASP])
    cfg = PhysicsConfig()
    pads = PhysicsObjective(geometry, layout, cfg, x, "target", knot_time=0.2, d_safe=0.02,
                            grasp_offset=offset)
    tool = PhysicsObjective(geometry, layout, cfg, x, "target", knot_time=0.2, d_safe=0.02)
    assert pads.state_terms(z, True)["grasp"].value < 1e-6 * cfg.w_grasp
    assert tool.state_terms(z, True)["grasp"].value > 0.01 * cfg.w_grasp  # 1.5 cm away
    q = Q_PREGRASP + 0.05  # off the target: a gradient worth checking
    z = np.concatenate([initial_state(layout, q, at_pads), q])
    term = pads.state_terms(z, True)["grasp"]

    def value(d):
        return np.array([pads.state_terms(_retract_z(layout, z, d), True)["grasp"].value])

    numeric = _numeric_jacobian(value, np.zeros(pads.nz))[0]
    assert np.abs(numeric).max() > 1.0
    np.testing.assert_allclose(term.gradient, numeric, atol=1e-4 * np.abs(numeric).max())


def _retract_z(layout, z, dz):
    return np.concatenate([layout.retract(z[:layout.nx], dz[:layout.ndx]),
                           z[layout.nx:] + dz[layout.ndx:]])


@pytest.mark.parametrize("terminal", [False, True])
def test_state_terms_gradients_match_differences(physics_problem, terminal):
    objective, layout, z = physics_problem
    terms = objective.state_terms(z, terminal)
    assert terms["force"].value > 0 and terms["upright"].value > 0 and terms["motion"].value > 0
    if terminal:
        assert terms["grasp"].value > 0 and terms["grp_open"].value > 0
    names = sorted(terms)

    def values(d):
        found = objective.state_terms(_retract_z(layout, z, d), terminal)
        return np.array([found[n].value for n in names])

    numeric_all = _numeric_jacobian(values, np.zeros(objective.nz))
    for i, name in enumerate(names):
        term, numeric = terms[name], numeric_all[i]
        scale = max(1.0, np.abs(numeric).max())
        np.testing.assert_allclose(term.gradient, numeric, atol=1e-3 * scale, err_msg=name)
        eig = np.linalg.eigvalsh(0.5 * (term.hessian + term.hessian.T))
        assert np.all(eig > -1e-6 * scale), name  # Gauss-Newton: positive semi-definite


def test_smooth_state_hessians_match_differences(physics_problem):
    objective, layout, z = physics_problem
    for name in ("motion",):  # (upright's is Gauss-Newton: checked PSD above)
        H = objective._box_terms(z)[name].hessian
        numeric = _numeric_jacobian(
            lambda d, name=name: objective._box_terms(_retract_z(layout, z, d))[name].gradient,
            np.zeros(objective.nz), 1e-5)
        # Rotations compose on the left, so second differences see the Lie bracket: symmetrise.
        np.testing.assert_allclose(H, 0.5 * (numeric + numeric.T), atol=1e-3, err_msg=name)


class _SmoothForces:
    """A stand-in for phi's contact forces: f(x, u) = tanh(P x_arm + Q u) (3 entries)."""

    def __init__(self, ndx: int):
        rng = np.random.default_rng(0)
        self.P, self.Q, self.ndx = rng.normal(size=(3, 8)), rng.normal(size=(3, 8)), ndx

    def step_forces(self, x, u):
        return np.tanh(self.P @ x[:8] + self.Q @ u)

    def linearize_forces(self, xs, us):
        f = np.array([self.step_forces(x, u) for x, u in zip(xs, us, strict=True)])
        d = 1.0 - f**2
        Fx = np.zeros((len(us), 3, self.ndx))
        Fx[:, :, :8] = d[:, :, None] * self.P
        return f, Fx, d[:, :, None] * self.Q


def _force_problem(physics_problem, geometry, config: PhysicsConfig):
    """An objective with `_SmoothForces` and a two-interval path (zs, us) for it."""
    _, layout, z = physics_problem
    objective = PhysicsObjective(geometry, layout, config, z[:layout.nx], "target",
                                 knot_time=0.2, d_safe=0.02, forces=_SmoothForces(layout.ndx))
    zs = np.stack([z, z, z])
    us = np.stack([z[:8] + 0.03, z[:8] - 0.02])
    zs[1:, :8] = us
    return objective, layout, zs, us


def _check_force_expansion(objective, layout, zs, us, cost_of_f):
    """The force terms' part of the expansion (with minus without forces) has the numerical
    gradient of sum_t cost_of_f(f(x_t, u_t)); returns that part's luu per interval."""
    exp = objective.quadratize(zs, us)
    objective.forces.P[:], objective.forces.Q[:] = 0.0, 0.0  # every other term (f = 0)
    base = objective.quadratize(zs, us)
    objective.forces = _SmoothForces(layout.ndx)
    for t in range(len(us)):
        def value(w, t=t):
            x = layout.retract(zs[t, :layout.nx], w[:layout.ndx])
            return cost_of_f(objective.forces.step_forces(x, us[t] + w[layout.ndx:]))

        numeric = _numeric_gradient(value, np.zeros(layout.ndx + 8))
        np.testing.assert_allclose(exp.lx[t, :layout.ndx] - base.lx[t, :layout.ndx],
                                   numeric[:layout.ndx], atol=1e-6)
        np.testing.assert_allclose(exp.lu[t] - base.lu[t], numeric[layout.ndx:], atol=1e-6)
    return exp.luu - base.luu, base


def test_phi_force_term_gradient_matches_differences(physics_problem, geometry):
    """With phi's forces, c_force is w/2 sum_t ||f(x_t, u_t)||^2 over the intervals, and its
    expansion's gradient in (dz_t, du_t) is the numerical one."""
    objective, layout, zs, us = _force_problem(physics_problem, geometry,
                                               PhysicsConfig(w_force=2.0))
    f = [objective.forces.step_forces(zs[t, :layout.nx], us[t]) for t in range(2)]
    assert objective.terms(zs, us)["force"] == pytest.approx(sum(fi @ fi for fi in f))
    _check_force_expansion(objective, layout, zs, us, lambda f: float(np.sum(f ** 2)))


def test_acc_term_matches_differences(physics_problem):
    objective, layout, z = physics_problem
    u = z[:8] + 0.05
    term = objective.acc_term(z, u)
    n = objective.nz

    def value(w):
        return objective.acc_term(_retract_z(layout, z, w[:n]), u + w[n:]).value

    numeric = _numeric_gradient(value, np.zeros(n + 8))
    np.testing.assert_allclose(term.gradient, numeric, rtol=1e-5, atol=1e-3)


def test_speed_limit_term_matches_differences():
    from drake_clutter.planners.physics.limits import max_steps
    from drake_clutter.planners.physics.objective import speed_limit

    limit = max_steps(PhysicsConfig(), 0.2)
    q = Q_PREGRASP
    u = q + np.r_[1.5 * limit[:3], -2.0 * limit[3:5], 0.5 * limit[5:]]
    term = speed_limit(q, u, limit)
    assert term.value > 0
    numeric = _numeric_gradient(lambda w: speed_limit(w[:8], w[8:], limit).value,
                                np.concatenate([q, u]))
    np.testing.assert_allclose(term.gradient, numeric, atol=1e-6)
    assert speed_limit(q, q + 0.5 * limit, limit).value == 0.0


def test_trajectory_terms_and_expansion_agree(physics_problem):
    objective, layout, z = physics_problem
    zs = np.array([z, z, z])
    us = np.array([z[:8], z[:8] + 0.01])
    terms = objective.terms(zs, us)
    assert set(terms) == {"static", "force", "motion", "upright", "grasp", "grp_horiz",
                          "grp_open", "acc"}
    exp = objective.quadratize(zs, us)
    assert exp.lx.shape == (2, objective.nz) and exp.vxx.shape == (objective.nz,) * 2
    state = objective.state_terms(z, False)
    np.testing.assert_allclose(exp.lx[1] - objective.acc_term(z, us[1]).gradient[:objective.nz],
                               sum(t.gradient for t in state.values()), atol=1e-9)


# ----------------------------------------------------------------------------- kinematic


@pytest.mark.parametrize("mode", ["pre", "post"])
def test_kinematic_objective_gradients_match_differences(scene, mode):
    geometry = ArmGeometry(scene, "capsules")  # its own: boxes at rest, whatever ran before
    q_ref = np.array([Q_PREGRASP + d for d in (-0.2, -0.1, 0.0)])
    p_goal = geometry.tool(Q_PREGRASP)[0] + 0.01
    # The fixed sample counts (no sweep_spacing): the spacing only sets how many samples
    # (held fixed in the derivatives). With 10-30 samples of this segment c_dynamic's central
    # differences part from its expansion by 0.1-0.5% (measured; 1.8e-4 with 2), varying
    # with where the samples fall: the arm-box penetration depths are not smooth to 1e-6.
    objective = KinematicObjective(geometry, PhysicsConfig(sweep_spacing=0.0), mode, 0.02,
                                   "target", q_ref=q_ref, p_pregrasp=p_goal)
    q, u = Q_PREGRASP - 0.05, Q_PREGRASP + np.r_[0.0, 0.1, np.zeros(6)]
    for name, term in objective.running(1, q, u).items():
        numeric = _numeric_gradient(
            lambda w, name=name: objective.running(1, w[:8], w[8:])[name].value,
            np.concatenate([q, u]))
        np.testing.assert_allclose(term.gradient, numeric, atol=2e-4 * max(1, abs(
            numeric).max()), err_msg=name)
    for name, term in objective.terminal(u).items():
        numeric = _numeric_gradient(lambda w, name=name: objective.terminal(w)[name].value, u)
        np.testing.assert_allclose(term.gradient, numeric, atol=1e-5, err_msg=name)


def test_postprocessing_clears_the_board_between_knots(scene):
    """A wrist roll of pi in one interval near the board: both knots clear it (2.7 cm) but the
    fingers sweep 7 mm into it half-way. c_static at the knots alone (post_substeps 1, no
    sweep_spacing) sees nothing and leaves the path; over 6 configurations per interval, or
    as many as the sweep needs at 1 cm spacing, the post-processing lifts the sweep clear.
    (c_speed off: the roll is over the speed limit, not the point here.)"""
    import dataclasses

    from drake_clutter.common.config import Config
    from drake_clutter.planners.physics.kinematic import postprocess

    geometry = ArmGeometry(scene, "evaluation")

    def clearance(q_a, q_b):
        return min(min((c.distance for c in geometry.contacts(
            (1 - s) * q_a + s * q_b, None, 0.2, "shelf")), default=0.2)
            for s in np.linspace(0.0, 1.0, 25))

    q_a = Q_PREGRASP + np.r_[0.0, 0.01, np.zeros(6)]
    q_b = q_a + np.r_[np.zeros(6), np.pi, 0.0]
    path = np.array([q_a, q_b, q_b])
    assert clearance(q_a, q_a) > 0.025 and clearance(q_b, q_b) > 0.025
    assert clearance(q_a, q_b) < -0.005
    base = Config()
    for substeps, spacing, clears in ((1, 0.0, False), (6, 0.0, True), (1, 0.01, True)):
        physics = dataclasses.replace(base.physics, post_substeps=substeps, w_speed=0.0,
                                      sweep_spacing=spacing)
        q, result = postprocess(PlanningContext(scene, dataclasses.replace(base,
                                                                           physics=physics)),
                                path)
        if clears:
            assert result.term_history[0]["static"] > 1.0
            assert clearance(q[0], q[1]) > 0.0  # measured 0.0196 m
            assert clearance(q[1], q[2]) > 0.0
        else:
            assert result.term_history[0]["static"] == 0.0
            np.testing.assert_array_equal(q, path)


# A knot interval of a physics plan for fig6 at alpha -0.21 after the post-processing with 6
# fixed samples (2026-11-23; rounded): a finger crosses the 3 cm board within 0.2 s, between
# two samples, and Bullet failed the plan kinematically (8.6 mm deep).
FIG6_WHIP = (np.array([-0.231, -0.458, -2.348, -1.666, -3.522, -1.961, -0.441, 0.036]),
             np.array([-0.607, -0.109, -2.936, -2.005, -2.894, -1.422, -0.425, 0.0]))


def test_a_finger_whipped_through_the_board_is_seen_with_sweep_spacing():
    """FIG6_WHIP: both knots and the 6 evenly spaced samples clear the board, a dense scan
    finds a finger > 5 mm inside it. segment_penetration with 6 samples reads 0; with 1 cm
    sweep spacing it takes enough samples to see the crossing. The sweep bounds how far the
    finger frames and the tool frame travel along the segment."""
    fig6 = scenes.load_shipped_scene("fig6_push_sideways")
    geometry = ArmGeometry(fig6, "evaluation")
    q_a, q_b = FIG6_WHIP

    def depth(s):
        return max((-c.distance for c in geometry.contacts((1 - s) * q_a + s * q_b, None, 0.0,
                                                            "shelf")), default=0.0)

    assert max(depth(s) for s in np.arange(7) / 6) == 0.0
    assert max(depth(s) for s in np.linspace(0.0, 1.0, 201)) > 0.005  # measured 14 mm
    fixed = segment_penetration(geometry, q_a, q_b, 6, 0.01, shelf_only=True)["shelf"]
    swept = segment_penetration(geometry, q_a, q_b, 6, 0.01, shelf_only=True,
                                spacing=0.01)["shelf"]
    assert fixed.value == 0.0 and swept.value > 0.0
    assert np.linalg.norm(swept.gradient) > 0.0
    sweep = geometry.sweep(q_a, q_b)
    assert geometry.sweep(q_a, q_a) == 0.0
    plant = geometry.plant
    frames = [plant.GetFrameByName(n) for n in ("r_gripper_l_finger_link",
                                                 "r_gripper_r_finger_link")]
    frames.append(geometry.world.tool_frame)
    for frame in frames:
        points = []
        for s in np.linspace(0.0, 1.0, 101):
            geometry.set_state((1 - s) * q_a + s * q_b)
            points.append(frame.CalcPoseInWorld(geometry.context).translation())
        assert np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)) <= sweep


# ----------------------------------------------------------------------------- pipeline


@pytest.fixture(scope="module")
def fig5_candidate(scene):
    from drake_clutter.common.config import BaselineConfig
    from drake_clutter.planners.baseline import plan_baseline

    (candidate,) = plan_baseline(scene, BaselineConfig(), alphas=[0.3])
    assert candidate.ok, candidate.reason
    return candidate


def test_preprocessing_keeps_the_pregrasp(scene, geometry, fig5_candidate):
    from drake_clutter.common.config import Config
    from drake_clutter.planners.physics.kinematic import preprocess

    q0 = fig5_candidate.trajectory.q
    q, result = preprocess(PlanningContext(scene, Config()), q0)
    first, last = result.term_history[0], result.term_history[-1]
    assert sum(last.values()) <= sum(first.values())
    np.testing.assert_array_equal(q[0], q0[0])
    np.testing.assert_array_equal(q[-1], q0[-1])  # the pre-grasp pose, a bound
    np.testing.assert_array_equal(q[:, -1], q0[:, -1])  # the gripper's openings
    assert np.abs(q - q0).max() > 1e-3  # it did move the path


def test_knot_bounds_pin_the_last_knot_and_the_gripper():
    from drake_clutter.planners.physics.limits import GRIPPER, control_bounds, knot_bounds

    rng = np.random.default_rng(0)
    low, high = (np.array(b) for b in control_bounds())
    q = low + (high - low) * rng.uniform(0.1, 0.9, (6, 8))  # inside the joint limits
    q[:, GRIPPER] = 0.04
    lo, hi = knot_bounds(q)
    np.testing.assert_array_equal(lo, np.tile(control_bounds()[0], (5, 1)))
    lo, hi = knot_bounds(q, last_knot=True, gripper=True)
    np.testing.assert_array_equal(lo[-1], q[-1])
    np.testing.assert_array_equal(hi[-1], q[-1])
    np.testing.assert_array_equal(lo[:, GRIPPER], q[1:, GRIPPER])
    assert np.all(lo[:-1, :GRIPPER] < hi[:-1, :GRIPPER])  # the other joints stay free
    lo, hi = knot_bounds(q, min_final_opening=0.06)
    assert lo[-1, GRIPPER] == 0.06 and hi[-1, GRIPPER] == control_bounds()[1][GRIPPER]
    assert lo[-2, GRIPPER] == 0.0


@pytest.mark.parametrize("name", ["default_bookshelf", *load_spec("behaviours")[0].shipped])
def test_pre_and_post_processing_keep_the_pregrasp_and_the_open_gripper(name):
    """On every shipped scene, from the baseline's candidate at the scene's own angle: the
    pre-processing ends on the baseline's pre-grasp pose with its gripper openings, and the
    post-processing of that path on its last knot and openings."""
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.baseline import plan_baseline
    from drake_clutter.planners.physics.kinematic import postprocess, preprocess
    from drake_clutter.scene.scenes import load_shipped_scene

    shipped = load_shipped_scene(name)
    config = load_config(None, ["physics.post_iterations=10"])
    alpha = float(shipped.provenance.parameters.get("alpha", 0.0))
    (candidate,) = plan_baseline(shipped, config.baseline, alphas=[alpha])
    assert candidate.ok, candidate.reason
    q0 = candidate.trajectory.q
    context = PlanningContext(shipped, config)
    q_pre, _ = preprocess(context, q0)
    q_post, _ = postprocess(context, q_pre)
    for q in (q_pre, q_post):
        np.testing.assert_array_equal(q[-1], q0[-1])
        np.testing.assert_array_equal(q[:, -1], q0[:, -1])


@pytest.mark.parametrize("controls", ["spline", "knots"])
def test_pipeline_runs_every_stage_and_records_it(scene, fig5_candidate, controls):
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.physics.limits import control_bounds
    from drake_clutter.planners.physics.pipeline import plan_physics

    config = load_config(None, ["physics.iterations=2", "physics.sphere_iterations=1",
                                "physics.pre_iterations=2", "physics.post_iterations=2",
                                "dynamics.workers=0", "dynamics.derivative_stride=4",
                                f"physics.controls={controls}"])
    (plan,) = plan_physics(scene, config, [fig5_candidate])
    assert plan.ok and plan.planner == "physics", plan.reason
    assert set(plan.timings) == {"height", "pre", "sphere", "full", "post", "select"}
    height = plan.details["grasp_height"]  # the start: the first clear height, or as "press"
    assert height["rule"] == "clear" and "0.5" in height["candidates"]
    assert all({"press", "side"} <= set(c) for c in height["candidates"].values())
    assert height["chosen"] in height["candidates"]
    stages = plan.details["stages"]
    for name in ("pre", "sphere", "full", "post"):
        history = stages[name]["cost_history"]
        assert np.all(np.diff(history) <= 0), name  # accepted iterations never raise the cost
        assert len(stages[name]["term_history"]) == len(history)
        log = stages[name]["log"]  # one entry per backward pass, JSON-ready
        assert all(isinstance(e["alpha"], float) and e["alpha"] <= 1.0 for e in log)
        assert sum(e["alpha"] > 0 for e in log) == stages[name]["iterations"]
    assert "target" not in stages["sphere"]["kept_boxes"]  # out of phi in the sphere stage
    # the full stage starts from the best of the sphere stage's, the pre-processed and the
    # baseline's path, compared in one phi
    starts = stages["full"]["start_objectives"]
    assert len(starts) == 3 and min(starts) < float("inf")
    # the spline solver refits its start (a knot moves ~1e-12 rad), which phi's chaos amplifies
    rel = 1e-4 if controls == "spline" else 1e-12
    assert stages["full"]["cost_history"][0] == pytest.approx(min(starts), rel=rel)
    best = int(np.argmin(starts))
    assert stages["full"]["started_from"] == ("previous stage" if best == 0
                                              else f"alternative {best}")
    # the plan is the best in phi of the post-processed, pre-processed and start paths
    select = plan.details["select"]
    values = select["objectives"]
    assert set(values) == {"post", "pre", "baseline"} and values["baseline"] is not None
    assert all(values[n] is None or values[select["chosen"]] <= values[n] for n in values)
    if select["chosen"] == "baseline" and height["chosen"] == "0.5":  # the start unchanged
        np.testing.assert_array_equal(plan.trajectory.q, fig5_candidate.trajectory.q)
    from drake_clutter.planners.physics.record import PhysicsRecord

    record = PhysicsRecord.from_details(plan.details)  # the record the pipeline stored
    assert record.to_details() == plan.details and record.initialization == "baseline"
    assert record.time_budget["returned"] == record.chosen == select["chosen"]
    feedback = plan.details["feedback"]
    nz = 8 + 12 * len(feedback["boxes"]) + 8
    assert np.asarray(feedback["K"]).shape == (fig5_candidate.trajectory.num_knots - 1, 8, nz)
    q = plan.trajectory.q
    np.testing.assert_array_equal(q[0], fig5_candidate.trajectory.q[0])
    lo, hi = control_bounds()
    assert np.all(q[1:] >= np.array(lo) - 1e-12) and np.all(q[1:] <= np.array(hi) + 1e-12)


def test_a_spent_time_budget_returns_the_start_and_records_the_stages_left_out(
        scene, fig5_candidate):
    """A budget spent before the first stage: no further height is planned, no solver takes a step,
    no phi is built, the plan is the baseline's path, and the details say so."""
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.physics.pipeline import plan_physics

    config = load_config(None, ["dynamics.workers=0", "physics.time_budget=1e-6",
                                "physics.iterations=30", "physics.sphere_iterations=10"])
    (plan,) = plan_physics(scene, config, [fig5_candidate])
    assert plan.ok, plan.reason
    budget = plan.details["time_budget"]
    assert budget["spent"] and budget["budget"] == 1e-6 and budget["returned"] == "post"
    assert budget["stopped"] == ["pre", "post"]
    assert budget["skipped"] == ["heights", "sphere", "full", "select"]
    assert set(plan.timings) == {"height", "pre", "post"} and "select" not in plan.details
    assert all(plan.details["stages"][n]["iterations"] == 0 for n in ("pre", "post"))
    # no other grasp height was planned: the start is the baseline's own path
    assert plan.details["grasp_height"]["chosen"] == "0.5"
    np.testing.assert_array_equal(plan.trajectory.q, fig5_candidate.trajectory.q)


def test_a_time_budget_spent_in_a_phi_stage_keeps_that_stages_best_path(scene,
                                                                       fig5_candidate):
    """A 3 s budget on fig5 with Sec. V's phi stages (the free run takes about 25 s): the
    sphere stage stops at the deadline (or is left out on a slow machine), the full stage and
    select are left out, and the plan is the lowest-objective path the phi stage reached,
    within the joint bounds."""
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.physics.limits import control_bounds
    from drake_clutter.planners.physics.pipeline import plan_physics

    config = load_config(None, ["dynamics.workers=0", "physics.time_budget=3",
                                "physics.iterations=30", "physics.sphere_iterations=10"])
    (plan,) = plan_physics(scene, config, [fig5_candidate])
    assert plan.ok, plan.reason
    budget = plan.details["time_budget"]
    assert budget["spent"] and {"full", "select"} <= set(budget["skipped"])
    assert "sphere" in budget["stopped"] + budget["skipped"]
    assert "full" not in plan.details["stages"] and budget["budget"] == 3.0
    sphere = plan.details["stages"].get("sphere")
    if sphere is not None:
        assert sphere["stop_reason"] == "time_budget"
        assert np.all(np.diff(sphere["cost_history"]) <= 0)
    q = plan.trajectory.q
    lo, hi = control_bounds()
    assert np.all(np.isfinite(q)) and np.all(q[1:] >= np.array(lo) - 1e-12)
    assert np.all(q[1:] <= np.array(hi) + 1e-12)


def test_the_model_repairs_run_through_every_stage(scene, fig5_candidate):
    """Box QP, the trust region as QP bounds adapted by actual/predicted, the scaled
    regulariser, arm-only feedback and contact knots differentiated despite the stride: the
    pipeline still plans, every accepted phi-stage step logs its model's decrease at its step
    size (positive) and the radius it was taken with, and no control leaves its bounds."""
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.physics.limits import control_bounds
    from drake_clutter.planners.physics.pipeline import plan_physics

    config = load_config(None, ["physics.iterations=3", "physics.sphere_iterations=1",
                                "physics.pre_iterations=2", "physics.post_iterations=2",
                                "dynamics.workers=0", "dynamics.derivative_stride=4",
                                "physics.box_qp=true",
                                "physics.trust_bounds=true", "physics.trust_adapt=true",
                                "physics.scaled_regulariser=true",
                                "physics.controls=knots"])
    (plan,) = plan_physics(scene, config, [fig5_candidate])
    assert plan.ok, plan.reason
    for name in ("sphere", "full"):
        stage = plan.details["stages"][name]
        assert np.all(np.diff(stage["cost_history"]) <= 0)
        for entry in stage["log"]:
            assert 1 / 64 <= entry["radius"] <= 1.0
            if entry["alpha"] > 0:
                assert entry["predicted"] > 0 and entry["actual"] > 0
    lo, hi = control_bounds()
    q = plan.trajectory.q
    assert np.all(q[1:] >= np.array(lo) - 1e-12) and np.all(q[1:] <= np.array(hi) + 1e-12)


def test_phi_stages_get_the_trust_region_and_kinematic_ones_do_not():
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.physics.limits import max_steps, solver_settings

    config = load_config(None, ["physics.step_limit_fraction=0.25",
                                "physics.line_search_steps=4"])
    phi = solver_settings(config, 7, knot_time=0.2)
    np.testing.assert_allclose(phi.step_limit, 0.25 * max_steps(config.physics, 0.2))
    assert phi.line_search_steps == 4 and phi.adaptive_step and phi.cost_floor == 0.0
    assert phi.max_iterations == 7
    kinematic = solver_settings(config, 7)
    assert kinematic.step_limit is None and kinematic.cost_floor is None


def test_a_phi_stage_restarts_from_the_baseline_path_when_phi_fails(monkeypatch):
    from types import SimpleNamespace

    from drake_clutter.common.config import Config
    from drake_clutter.planners.physics import stage as physics

    calls = []

    def stage(context, q, variant, iterations, pool, times, alternatives=(),
              min_opening=None, deadline=None, aim_T=None):
        calls.append(q)
        if q[0, 0] == 1.0:  # phi cannot simulate the previous stage's path
            raise physics.PhiFailure("phi failed on the initial rollout")
        return q, "result", {"kept_boxes": [], "start_objectives": [1.0]}

    monkeypatch.setattr(physics, "physics_stage", stage)
    previous, baseline = np.ones((3, 8)), np.zeros((3, 8))
    context = SimpleNamespace(config=Config())
    q, _, info = physics.phi_stage_or_restart(context, (previous, baseline), "capsules", 1,
                                               None, None)
    assert q is baseline and len(calls) == 2 and info["started_from"].startswith("baseline")
    with pytest.raises(physics.PhiFailure):  # nothing to fall back to
        physics.phi_stage_or_restart(context, (previous, previous.copy()), "capsules", 1,
                                      None, None)


def test_select_path_takes_the_lowest_objective_ties_to_the_first(monkeypatch):
    """`select_path` on a fake phi: the lowest objective wins, a tie goes to the earlier name,
    a path phi cannot roll out (inf) is reported as None and never chosen over a finite one,
    and when phi fails on every path the first is kept."""
    from contextlib import contextmanager
    from types import SimpleNamespace

    from drake_clutter.common.config import Config
    from drake_clutter.planners.physics import stage as physics

    pruned_for = []

    @contextmanager
    def problem(context, q, variant, pool, knot_time, also=(), aim_T=None):
        pruned_for.append(1 + len(also))
        yield SimpleNamespace(augmented=None, objective=None, z0=None,
                              report=SimpleNamespace(summary=lambda: "kept 0 of 0 boxes"))

    values = {}
    context = SimpleNamespace(config=Config())
    monkeypatch.setattr(physics, "stage_problem", problem)
    monkeypatch.setattr(physics, "_path_objective", lambda d, o, z, q: values[q[0, 0]])
    paths = {name: np.full((3, 8), float(i)) for i, name in enumerate(("post", "pre", "baseline"))}
    values.update({0.0: 5.0, 1.0: 3.0, 2.0: 3.0})
    chosen, info = physics.select_path(context, paths)
    assert chosen == "pre" and info["objectives"] == {"post": 5.0, "pre": 3.0, "baseline": 3.0}
    assert pruned_for == [3]  # one phi pruned for all three paths
    values.update({0.0: float("inf"), 1.0: float("inf"), 2.0: 7.0})
    chosen, info = physics.select_path(context, paths)
    assert chosen == "baseline" and info["objectives"]["post"] is None
    values.update({2.0: float("inf")})
    assert physics.select_path(context, paths)[0] == "post"


def test_failed_candidates_pass_through(scene):
    from drake_clutter.common.config import Config
    from drake_clutter.planners.physics.pipeline import plan_physics
    from drake_clutter.trajectory import Candidate

    (out,) = plan_physics(scene, Config(), [Candidate(0.1, "ik_failed", "start pose")])
    assert out.status == "ik_failed" and out.planner == "physics" and "start pose" in out.reason


def test_bad_physics_config_is_a_config_error(scene):
    from drake_clutter.common.config import ConfigError, load_config
    from drake_clutter.planners.physics.pipeline import plan_physics

    with pytest.raises(ConfigError, match="physics.hull_substeps"):
        plan_physics(scene, load_config(None, ["physics.hull_substeps=0"]), [])
    with pytest.raises(ConfigError, match="physics.step_limit_fraction"):
        plan_physics(scene, load_config(None, ["physics.step_limit_fraction=0"]), [])
    with pytest.raises(ConfigError, match="physics.accept_ratio"):
        plan_physics(scene, load_config(None, ["physics.accept_ratio=1"]), [])
    with pytest.raises(ConfigError, match="physics.control_points"):
        plan_physics(scene, load_config(None, ["physics.control_points=3"]), [])
    with pytest.raises(ConfigError, match="physics.controls"):
        load_config(None, ["physics.controls=bezier"])
    with pytest.raises(ConfigError, match="dynamics.derivative_method"):
        plan_physics(scene, load_config(None, ["world.contact_approximation=similar"]), [])


# ----------------------------------------------------------------------------- behaviours

BEHAVIOUR_SCENES = load_spec("behaviours")[0].shipped  # the experiment tier's four scenes


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="the physics planner does not beat the baseline yet "
                   "(behaviours tier, the defaults of 2026-11-27: 5 better / 18 same / 1 "
                   "worse, P(success) equal; see docs/log/physics_planner.md)")
def test_physics_plans_beat_the_baseline_on_the_behaviour_scenes():
    """Sec. VI-A: from the same angle (the scene's provenance alpha), the physics plan does at
    least as well as the baseline in Bullet on all four scenes, strictly better on three.

    Not reached: one plan per scene is a draw on toppling clutter, and phi's pushes do not
    carry over to the judge (the measurements: docs/log/physics_planner.md)."""
    from drake_clutter.common.config import Config
    from drake_clutter.evaluation.judge import evaluate_candidates
    from drake_clutter.evaluation.outcome import outcome_grade
    from drake_clutter.planners.baseline import plan_baseline
    from drake_clutter.planners.physics.pipeline import plan_physics

    config = Config()
    rows, worse, better = [], 0, 0
    for name in BEHAVIOUR_SCENES:  # all four, so that a failure reports every scene
        scene = scenes.load_shipped_scene(name)
        alpha = float(scene.provenance.parameters["alpha"])
        baseline = plan_baseline(scene, config.baseline, alphas=[alpha])
        physics = plan_physics(scene, config, baseline)
        (base,), (phys,) = (evaluate_candidates(scene, c, config.evaluation)
                            for c in (baseline, physics))
        rows.append(f"{name}: baseline {base.kind} {outcome_grade(base)}, physics {phys.kind} "
                    f"{outcome_grade(phys)}")
        worse += outcome_grade(phys) > outcome_grade(base)
        better += outcome_grade(phys) < outcome_grade(base)
    assert worse == 0 and better >= 3, "\n".join(rows)


def test_plan_command_writes_the_physics_planner(tmp_path, capsys):
    from drake_clutter.cli import main
    from drake_clutter.trajectory import load_plan

    out = tmp_path / "plan.json"
    code = main(["plan", "fig5_large_small", "--planner", "physics", "--angles", "1", "--out",
                 str(out), "--set", "physics.iterations=0", "--set", "physics.sphere_iterations=0",
                 "--set", "physics.pre_iterations=1",
                 "--set", "physics.post_iterations=1"])
    assert code == 0
    _, candidates, doc = load_plan(out)
    assert [c.planner for c in candidates] == ["physics"]
    assert doc["planner"] == "physics" and doc["config"]["physics"]["iterations"] == 0
    assert "cost start" in capsys.readouterr().out


def test_unstable_box_jacobians_are_capped_and_stable_ones_kept():
    """cap_spectral_radius scales a box-to-box block with radius 9 (a toppling box) down to the
    cap, leaves a resting/sliding box's (radius 1: p' = p + dt v) and the arm's columns as they
    are, and returns the radii it found."""
    from drake_clutter.planners.physics.stage import cap_spectral_radius

    ndx = 8 + 12
    rng = np.random.default_rng(0)
    sliding = np.eye(ndx)
    sliding[:8] = 0.0  # the kinematic arm's rows
    sliding[8 + 3:8 + 6, 8 + 9:8 + 12] = 0.2 * np.eye(3)  # dp' = dp + dt dv
    sliding[8:, :8] = rng.normal(size=(12, 8))  # the arm pushes the box
    toppling = sliding.copy()
    toppling[8:11, 8:11] = 9.0 * np.eye(3)  # a tilt that grows 9x in a knot
    A = np.stack([sliding, toppling])
    before = A.copy()
    radii = cap_spectral_radius(A, 1.0)
    np.testing.assert_allclose(radii, [1.0, 9.0])
    np.testing.assert_array_equal(A[0], before[0])
    assert max(abs(np.linalg.eigvals(A[1, 8:, 8:]))) == pytest.approx(1.0)
    np.testing.assert_array_equal(A[1, :, :8], before[1, :, :8])
    np.testing.assert_allclose(A[1, 8:, 8:], before[1, 8:, 8:] / 9.0)


def test_per_box_cap_scales_the_toppling_box_alone():
    """Two boxes, the second toppling (radius 9): per box, only its rows of the box block are
    scaled (its radius then 1) and the first box's rows (the target's dynamics) are kept; two
    boxes unstable together (each stable alone) still get the whole block scaled."""
    from drake_clutter.planners.physics.stage import cap_spectral_radius

    ndx = 8 + 24
    rng = np.random.default_rng(1)
    A = np.eye(ndx)
    A[:8] = 0.0
    A[8:, :8] = rng.normal(size=(24, 8))
    A[8:20, 20:32] = 0.1 * rng.normal(size=(12, 12))  # box 2 pushes box 1
    A[20:23, 20:23] = 9.0 * np.eye(3)  # box 2 topples
    before = A.copy()
    (radius,) = cap_spectral_radius(A[None], 1.0, per_box=True)
    assert radius == pytest.approx(9.0)
    np.testing.assert_array_equal(A[8:20], before[8:20])  # box 1's rows, its coupling too
    np.testing.assert_allclose(A[20:, 8:], before[20:, 8:] / 9.0)
    np.testing.assert_array_equal(A[20:, :8], before[20:, :8])  # the arm's columns
    assert max(abs(np.linalg.eigvals(A[8:, 8:]))) <= 1.0 + 1e-9
    # leaning on each other: each diagonal block stable, together unstable
    pair = np.eye(ndx)
    pair[:8] = 0.0
    pair[8:20, 20:32] = 3.0 * np.eye(12)
    pair[20:32, 8:20] = 3.0 * np.eye(12)
    (radius,) = cap_spectral_radius(pair[None], 1.0, per_box=True)
    assert radius == pytest.approx(4.0)
    assert max(abs(np.linalg.eigvals(pair[8:, 8:]))) == pytest.approx(1.0)


def _toppling_domino():
    """fig7's last domino alone in phi, set toppling off the back of the board at Delta: the
    spec, the states z_0 and z_Delta (stacked) and the held control."""
    from drake_clutter.common.config import DynamicsConfig
    from drake_clutter.phi.dynamics import make_spec

    fig7 = scenes.load_shipped_scene("fig7_cascade")
    spec = make_spec(fig7, ["domino_4"], config=DynamicsConfig(workers=0, derivative_stride=1))
    layout = spec.layout
    park = np.r_[spec.world.park_configuration, 0.0]
    states = scene_box_states(fig7)
    x0 = initial_state(layout, park, states)
    p_tip = states["domino_4"][4:7] + np.array([0.009, 0.0, 0.0])  # over its back edge, 6 deg
    toppling = pose_to_box_state(RigidTransform(RollPitchYaw(0.0, 0.1, 0.0), p_tip),
                                 np.array([0.0, 0.8, 0.0, 0.0, 0.0, 0.0]))
    x_delta = initial_state(layout, park, {**states, "domino_4": toppling})
    return fig7, spec, np.stack([np.r_[x0, park], np.r_[x_delta, park]]), park[None]


def _tail_gradient(tail, objective, layout, zs, us):
    """The tail's terminal gradient over dx_Delta and the numerical one of its terms."""
    def tail_value(dz):
        z = _retract_z(layout, zs[1], np.r_[dz, np.zeros(8)])
        both = np.stack([zs[0], z])
        return sum(tail.terms(both, us).values()) - sum(objective.terms(both, us).values())

    numeric = _numeric_gradient(tail_value, np.zeros(layout.ndx), step=1e-5)
    vx = tail.quadratize(zs, us).vx - objective.quadratize(zs, us).vx
    return vx[:layout.ndx], numeric


def test_hold_tail_pays_for_a_fall_after_delta_and_its_gradient_matches_differences():
    """Table II's "all" times: the last domino, set toppling off the back of the board at
    Delta, costs its fall over the held knots (c_upright far above its terminal tilt alone),
    and the tail's terminal gradient (through phi's Jacobians) is the numerical one of the
    tail's terms w.r.t. x_Delta."""
    from drake_clutter.phi.derivatives import PhiDynamics
    from drake_clutter.planners.physics.stage import HoldTail

    fig7, spec, zs, us = _toppling_domino()
    with PhiDynamics(spec) as dynamics:
        objective = PhysicsObjective(ArmGeometry(fig7, "capsules"), spec.layout,
                                     PhysicsConfig(), zs[0, :spec.layout.nx], "target",
                                     knot_time=0.2, d_safe=0.02, forces=dynamics)
        tail = HoldTail(objective, dynamics, knots=5)
        plain, held = objective.terms(zs, us), tail.terms(zs, us)
        assert plain["upright"] < 0.2  # rad: the tilt at Delta
        assert held["upright"] > plain["upright"] + 2.0  # it falls over in the held second
        assert "settled_upright" not in held  # off by default
        vx, numeric = _tail_gradient(tail, objective, spec.layout, zs, us)
    # measured: |numeric| 3.2e3, |error| 2.7 (upright 5.4 held vs 0.09 at Delta)
    assert np.linalg.norm(numeric) > 1.0
    assert np.linalg.norm(vx - numeric) < 0.05 * np.linalg.norm(numeric), (vx, numeric)


def test_parallel_line_search_gives_the_serial_phi_stage(scene, fig5_candidate):
    """Forward passes in the derivative workers (`AugmentedPhi.forward_passes`) take the
    steps the in-process line search takes: the same path, objective history and log."""
    from drake_clutter.common.config import load_config
    from drake_clutter.phi.workers import WorkerPool
    from drake_clutter.planners.physics.stage import physics_stage

    q = fig5_candidate.trajectory.q
    runs = {}
    with WorkerPool(2) as pool:
        for parallel in (False, True):
            config = load_config(None, ["dynamics.derivative_stride=4",
                                        f"physics.parallel_line_search={parallel}"])
            runs[parallel] = physics_stage(PlanningContext(scene, config), q, "capsules", 2,
                                           pool)
    (q_serial, serial, _), (q_parallel, parallel, info) = runs[False], runs[True]
    assert parallel.iterations >= 1 and info["phi_failures"] == 0
    np.testing.assert_array_equal(q_parallel, q_serial)
    assert parallel.cost_history == serial.cost_history
    assert [(e["alpha"], e["tries"]) for e in parallel.log] == \
        [(e["alpha"], e["tries"]) for e in serial.log]
    assert all(e["passes"] == e["tries"] for e in serial.log)
    assert sum(e["passes"] for e in parallel.log) > sum(e["tries"] for e in parallel.log)


def test_spline_controls_keep_a_phi_stage_on_the_baselines_spline(scene, fig5_candidate):
    """With ``physics.controls=spline`` a phi stage optimises the B-spline's control points:
    the baseline's path (a spline of that basis) starts it unchanged, the objective never
    rises, and the result is still a spline from the same start within the joint limits."""
    from drake_clutter.common.config import load_config
    from drake_clutter.planners.physics.limits import control_bounds
    from drake_clutter.planners.physics.stage import physics_stage, spline_path
    from drake_clutter.trajectory import spline_basis

    config = load_config(None, ["dynamics.workers=0", "dynamics.derivative_stride=4",
                                "physics.controls=spline"])
    q0 = np.asarray(fig5_candidate.trajectory.q, float)
    basis = spline_basis(len(q0), config.physics.control_points,
                         config.baseline.opt_spline_order)
    np.testing.assert_allclose(spline_path(basis, q0), q0, atol=1e-9)
    q, result, info = physics_stage(PlanningContext(scene, config), q0, "capsules", 2)
    assert result.iterations >= 1 and info["phi_failures"] == 0
    # its own fit of the start moves a knot by ~1e-12 rad, which phi's chaos amplifies
    assert result.cost_history[0] == pytest.approx(info["start_objectives"][0], rel=1e-6)
    assert np.all(np.diff(result.cost_history) <= 0)
    assert np.abs(q - q0).max() > 1e-6, "the stage moved the path"
    np.testing.assert_array_equal(q[0], q0[0])
    np.testing.assert_allclose(spline_path(basis, q), q, atol=1e-9)
    lo, hi = control_bounds()
    assert np.all(q[1:] >= np.array(lo) - 1e-12) and np.all(q[1:] <= np.array(hi) + 1e-12)
