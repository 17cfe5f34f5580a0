"""phi in MuJoCo (phi/mujoco_phi.py, phi/mujoco_model.py; ``dynamics.engine: mujoco``): the
model built from the one PR2 description, the state and outputs of the Drake phi, finite
differences against central ones, and the bad input the engine brings."""

from __future__ import annotations

import copy
import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from drake_clutter.common.config import ConfigError, DynamicsConfig, load_config
from drake_clutter.phi import mujoco_phi
from drake_clutter.phi.colouring import dense_jacobians
from drake_clutter.phi.derivatives import PhiDynamics
from drake_clutter.phi.dynamics import (
    ARM_NODE,
    GRAVITY,
    Phi,
    initial_state,
    make_spec,
)
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.jam import Contact, approach_speeds, blocked
from drake_clutter.phi.mujoco_model import check_scene
from drake_clutter.phi.mujoco_phi import (
    MujocoPhi,
    commanded_point_velocity,
    contact_magnitudes,
    jam_contacts,
)
from drake_clutter.phi.pruning import make_pruned_spec
from drake_clutter.phi.state import ARM_DIM, scene_box_states
from drake_clutter.robot import pr2
from drake_clutter.scene.scenes import SceneError, save_scene
from drake_clutter.testing.reach_paths import straight_reach
from drake_clutter.trajectory import robot_positions

REPO = Path(__file__).resolve().parents[2]
MUJOCO = DynamicsConfig(workers=0, engine="mujoco")
# the 10-box bookshelf of conftest.py whose straight reach pushes kept boxes
SCENE_SEED = 1


@pytest.fixture(scope="module")
def pushed(scene10, reach10):
    """The straight reach of bookshelf 10 / seed 1 through the pruned MuJoCo phi: it pushes
    kept boxes in its second half."""
    spec, _ = make_pruned_spec(scene10, reach10, config=MUJOCO)
    phi = build_phi(spec)
    x0 = phi.settle(initial_state(spec.layout, reach10[0], scene_box_states(scene10)))
    return spec, phi, x0, phi.rollout(x0, reach10[1:])


def test_the_engine_setting_builds_the_mujoco_phi(pushed):
    spec, phi, _, _ = pushed
    assert isinstance(phi, MujocoPhi) and spec.config.engine == "mujoco"
    assert isinstance(build_phi(dataclasses.replace(spec, config=DynamicsConfig(workers=0))), Phi)


@pytest.mark.parametrize("variant", ["capsules", "sphere_gripper"])
def test_the_arm_is_the_pr2_description_with_drakes_kinematics(scene10, variant):
    """The arm's links sit where Drake's plant of the same URDF puts them, and its geometry is
    the variant's collision shapes of the moving links."""
    names = [b.name for b in scene10.boxes[:2]]
    spec = make_spec(scene10, names, config=MUJOCO, variant=variant)
    mj = MujocoPhi(spec)
    drake = Phi(dataclasses.replace(spec, config=DynamicsConfig(workers=0)))
    q = np.array([-0.3, 0.4, -0.5, -1.2, 0.7, -0.8, 1.1, 0.06])
    mj.data.qpos[mj._arm_q] = robot_positions(q)
    mujoco.mj_kinematics(mj.model, mj.data)
    drake.set_state(initial_state(spec.layout, q, scene_box_states(scene10)), q)
    for link in ("r_shoulder_lift_link", "r_elbow_flex_link", "r_wrist_roll_link", pr2.PALM_LINK,
                 *pr2.FINGER_LINKS):
        X = drake.plant.EvalBodyPoseInWorld(drake.context, drake.plant.GetBodyByName(link))
        np.testing.assert_allclose(mj.data.xpos[mj.model.body(link).id], X.translation(),
                                   atol=1e-9)
    moving = pr2.collision_shapes(variant)
    expected = sum(len(moving[link]) for link in moving if link not in
                   ("base_link", "torso_lift_link"))
    assert int(np.sum(mj._nodes == ARM_NODE)) == expected


def test_step_is_deterministic_and_the_arm_kinematic(pushed, reach10):
    spec, phi, _, xs = pushed
    t = 20
    first = phi.step(xs[t], reach10[t + 1])
    phi.step(xs[3], reach10[4])  # something else in between
    assert np.array_equal(first, phi.step(xs[t], reach10[t + 1]))
    assert np.array_equal(first, xs[t + 1])
    np.testing.assert_array_equal(first[:ARM_DIM], reach10[t + 1])
    # The simulated arm really went there (its armature keeps it on the line).
    np.testing.assert_allclose(phi.data.qpos[phi._arm_q], robot_positions(reach10[t + 1]),
                               atol=1e-6)
    quats = spec.layout.boxes(first)[:, :4]
    np.testing.assert_allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-12)
    assert np.all(quats[:, 0] >= 0)


def test_settled_boxes_stay_put_under_a_still_arm(pushed, reach10):
    spec, phi, x0, _ = pushed
    xs = phi.rollout(x0, np.tile(reach10[0], (5, 1)))
    b0, b1 = spec.layout.boxes(xs[0]), spec.layout.boxes(xs[-1])
    assert np.max(np.abs(b1[:, 4:7] - b0[:, 4:7])) < 1e-5  # m in 1 s
    assert np.max(np.abs(b1[:, 7:])) < 1e-4  # m/s, rad/s


def test_the_reach_pushes_boxes_and_the_state_keeps_world_angular_velocity(pushed, reach10):
    """The straight reach moves kept boxes; phi's w_WB (W) is MuJoCo's body-frame w rotated."""
    spec, phi, _, xs = pushed
    moved = np.linalg.norm(spec.layout.boxes(xs[-1])[:, 4:7] - spec.layout.boxes(xs[0])[:, 4:7],
                           axis=1)
    assert moved.max() > 0.02
    x = phi.step(xs[18], reach10[19])
    boxes = spec.layout.boxes(x)
    for i, name in enumerate(spec.layout.box_names):
        body = phi.model.body(f"box/{name}").id
        w_body = phi.data.qvel[phi._box_v[i, 3:]]
        np.testing.assert_allclose(boxes[i, 7:10], phi.data.xmat[body].reshape(3, 3) @ w_body,
                                   atol=1e-9)


def test_forces_decode_mujocos_contacts_and_a_resting_box_weighs_on_the_shelf(pushed, reach10):
    spec, phi, x0, xs = pushed
    phi.step(xs[20], reach10[21])
    magnitude = contact_magnitudes(phi.model, phi.data)
    wrench = np.zeros(6)
    for i in range(phi.data.ncon):
        mujoco.mj_contactForce(phi.model, phi.data, i, wrench)
        assert magnitude[i] == pytest.approx(np.linalg.norm(wrench[:3]), abs=1e-9)
    _, f = phi.step_forces(x0, reach10[0])
    np.testing.assert_allclose(f, 0.0, atol=1e-6)  # at rest: no force between bodies
    np.testing.assert_allclose(phi.shelf_forces[1:], phi.weights[1:], rtol=0.02)
    _, f = phi.step_forces(xs[20], reach10[21])
    assert f[ARM_NODE] > 1.0  # the arm pushes there


def test_a_failed_step_is_a_nan_state_not_an_exception(pushed, reach10):
    _, phi, x0, _ = pushed
    before = phi.failures
    bad = x0.copy()
    bad[ARM_DIM + 4] = np.nan
    assert np.all(np.isnan(phi.step(bad, reach10[1]))) and phi.failures == before + 1
    assert np.all(np.isfinite(phi.step(x0, reach10[1])))


def test_finite_differences_agree_with_central_differences(scene10, reach10):
    """The coloured forward differences (fd_step 1e-6) against brute-force central ones (h
    1e-5) at the knots where the arm pushes; measured: median 2.6e-3, 8 of 13 below 1e-2,
    largest 0.36 (knot 19, where central differences with h and 10 h differ by 0.41 too).
    With MuJoCo's default impedance and solver tolerance the same check measured a median of
    11 (the finite differences were noise)."""
    config = dataclasses.replace(MUJOCO, derivative_stride=1, derivative_method="fd")
    spec, _ = make_pruned_spec(scene10, reach10, config=config)
    dynamics = PhiDynamics(spec)
    x0 = dynamics.phi.settle(initial_state(spec.layout, reach10[0], scene_box_states(scene10)))
    xs, us = dynamics.rollout(x0, reach10[1:]), reach10[1:]
    A, B = dynamics.linearize_tangent(xs, us)
    assert dynamics.stats.autodiff_knots == 0  # "hybrid" never seeds AutoDiffXd here
    errors = []
    for t in range(len(us)):
        if not any(ARM_NODE in e and min(e) >= 0 for e in dynamics.edges(xs[t], us[t])):
            continue
        central = np.hstack(dense_jacobians(dynamics.phi, xs[t], us[t], 1e-5, "central"))
        J = np.hstack([A[t], B[t]])
        errors.append(np.linalg.norm(J - central) / np.linalg.norm(central))
    assert len(errors) >= 10, errors
    assert np.median(errors) < 1e-2, errors
    assert sum(e < 1e-2 for e in errors) >= len(errors) // 2, errors
    assert max(errors) < 1.0, errors


def test_worker_processes_give_the_serial_bits(pushed, reach10):
    spec, _, _, xs = pushed
    us = reach10[1:]
    serial = PhiDynamics(dataclasses.replace(spec, config=dataclasses.replace(
        spec.config, derivative_stride=1)))
    parallel = PhiDynamics(dataclasses.replace(spec, config=dataclasses.replace(
        spec.config, derivative_stride=1, workers=2)))
    with parallel:
        window = slice(16, 20)
        A1, B1 = serial.linearize_tangent(xs[16:21], us[window])
        A2, B2 = parallel.linearize_tangent(xs[16:21], us[window])
    assert np.array_equal(A1, A2) and np.array_equal(B1, B2)


# ----------------------------------------------------------------------------- bad input


# ----------------------------------------------------------------------------- the kept world


@pytest.fixture(scope="module")
def kept(scene10, reach10):
    """The straight reach of bookshelf 10 / seed 1 in a kept MuJoCo world, every box of the
    scene dynamic (no pruning) and the resting ones asleep, at 4 ms steps read every 20 ms."""
    config = dataclasses.replace(MUJOCO, mujoco_sleep=True, mujoco_time_step=0.004,
                                 mujoco_sample_steps=5)
    states = scene_box_states(scene10)
    spec = make_spec(scene10, [b.name for b in scene10.boxes], states, 0.2, config)
    phi = build_phi(spec)
    x0 = phi.keep_world(initial_state(spec.layout, reach10[0], states))
    return spec, phi, x0


def test_resting_boxes_sleep_in_the_kept_world_and_the_reach_wakes_and_moves_them(kept,
                                                                                  reach10):
    spec, phi, x0 = kept
    assert np.all(np.isfinite(x0))
    mujoco.mj_copyData(phi.data, phi.model, phi.kept)
    assert phi.data.ntree_awake <= 1  # after the settle at most the arm is awake
    runs = list(phi.kept_knots(reach10))
    assert len(runs) == len(reach10) - 1
    assert all(np.all(np.isfinite(jam)) for jam, _ in runs)
    moved = np.linalg.norm(spec.layout.boxes(phi.kept_state)[:, 4:7]
                           - spec.layout.boxes(x0)[:, 4:7], axis=1)
    assert moved.max() > 0.02  # the reach pushes boxes, as in the functional phi
    assert np.sum(moved > 1e-4) < len(moved)  # and the boxes it never meets stay put
    np.testing.assert_array_equal(phi.kept_state[:ARM_DIM], reach10[-1])


def test_the_kept_world_starts_every_run_from_its_settle_and_repeats_its_bits(kept, reach10):
    spec, phi, _ = kept
    first = [jam for jam, _ in phi.kept_knots(reach10)]
    end = phi.kept_state.copy()
    list(phi.kept_knots(reach10[:5]))  # something else in between
    again = [jam for jam, _ in phi.kept_knots(reach10)]
    assert np.array_equal(np.array(first), np.array(again))
    assert np.array_equal(end, phi.kept_state)


def _runs_from_a_spoiled_world(phi, reach, spoil) -> list:
    """The kept world's runs through ``reach`` after ``spoil(data)`` edits (a copy of) its
    settled start, which is restored after."""
    saved = phi.kept
    phi.kept = copy.copy(saved)
    spoil(phi.kept)
    try:
        return list(phi.kept_knots(reach))
    finally:
        phi.kept = saved


def test_a_mujoco_reset_in_the_kept_world_is_a_recorded_failure(kept, reach10):
    """A bad speed makes MuJoCo warn and reset the data: the run yields NaN jams and ends,
    counted in ``failures``, never a silent success from the reset world."""
    spec, phi, _ = kept
    before = phi.failures
    runs = _runs_from_a_spoiled_world(
        phi, reach10, lambda d: d.qvel.__setitem__(phi._box_v[0, 0], np.nan))
    assert len(runs) == 1 and np.all(np.isnan(runs[0][0]))
    assert phi.failures == before + 1


def test_a_diverged_box_in_the_kept_world_is_a_recorded_failure(kept, reach10):
    """A box past ``divergence_limit`` (finite, no MuJoCo warning) ends the run with NaN
    jams, as `_read` marks it diverged: the quick soundness proof falls back to the read."""
    spec, phi, _ = kept
    before = phi.failures
    far = 2.0 * spec.config.divergence_limit
    runs = _runs_from_a_spoiled_world(
        phi, reach10, lambda d: d.qpos.__setitem__(phi._box_q[-1, 0], far))
    assert len(runs) == 1 and np.all(np.isnan(runs[0][0]))
    assert phi.failures == before + 1


def test_as_slice_reads_the_same_entries_as_the_index():
    data = np.arange(20.0) * 1.5
    for index in ([3, 4, 5, 6], [[2, 3, 4], [5, 6, 7]], [1, 3, 4], [5], []):
        index = np.array(index, dtype=int)
        got = mujoco_phi.as_slice(index)
        assert isinstance(got, slice) == (index.size > 0 and index.tolist() != [1, 3, 4])
        np.testing.assert_array_equal(data[got], data[index.ravel()])


@pytest.mark.parametrize("override, field", [
    ("dynamics.engine=bullet", "dynamics.engine"),
    ("dynamics.mujoco_contact_time=0.003", "dynamics.mujoco_contact_time"),
    ("dynamics.derivative_method=autodiff", "dynamics.derivative_method"),
    ("dynamics.mujoco_sleep_tolerance=0", "dynamics.mujoco_sleep_tolerance"),
    ("phi_judge.time_step=0.02", "phi_judge.time_step"),
    ("phi_judge.time_step=0.008 --set dynamics.mujoco_contact_time=0.015", "phi_judge.time_step"),
    ("phi_judge.sample_steps=0", "phi_judge.sample_steps"),
    ("phi_judge.stepping=fast", "phi_judge.stepping"),
    ("phi_judge.sleep=maybe", "phi_judge.sleep"),
    ("phi_judge.sleep=true --set phi_judge.stepping=knot", "phi_judge.sleep"),
])
def test_bad_engine_settings_name_the_field(override, field):
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        load_config(None, ["dynamics.engine=mujoco", *override.split(" --set ")])


def test_a_scene_mujoco_cannot_express_names_its_file_and_field(scene10):
    boxes = list(scene10.boxes)
    boxes[3] = dataclasses.replace(boxes[3], friction=0.0)
    scene = dataclasses.replace(scene10, boxes=tuple(boxes))
    with pytest.raises(SceneError, match=r"shelf\.yaml.*boxes\[3\]\.friction"):
        check_scene(scene, "shelf.yaml")
    check_scene(scene10, "shelf.yaml")  # the generator's scenes are expressible


def test_plan_refuses_such_a_scene_with_one_line_and_exit_2(scene10, tmp_path):
    boxes = list(scene10.boxes)
    boxes[2] = dataclasses.replace(boxes[2], friction=0.0)
    path = save_scene(dataclasses.replace(scene10, boxes=tuple(boxes)), tmp_path / "s.yaml")
    run = subprocess.run([sys.executable, "-m", "drake_clutter.cli", "plan", str(path),
                          "--planner", "physics", "--out", str(tmp_path / "p.json"),
                          "--set", "dynamics.engine=mujoco"], cwd=REPO, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 2, run.stderr
    assert len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert "s.yaml" in run.stderr and "boxes[2].friction" in run.stderr
    assert not (tmp_path / "p.json").exists()


def test_without_mujoco_the_engine_names_the_package(tmp_path):
    blocker = tmp_path / "sitecustomize.py"
    blocker.write_text("import sys\nsys.modules['mujoco'] = None\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    run = subprocess.run([sys.executable, "-m", "drake_clutter.cli", "config", "show", "--set",
                          "dynamics.engine=mujoco"], cwd=REPO, capture_output=True, text=True,
                         timeout=300, env=env)
    assert run.returncode == 2, run.stdout
    assert len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert "dynamics.engine" in run.stderr and "pip install mujoco" in run.stderr


def test_the_resting_shelf_force_is_the_weight_in_both_engines(scene10):
    """The shelf force of a resting box is its weight (Sec. III's kinematic failure reads
    it beyond that) in the Drake phi and in the MuJoCo phi alike."""
    names = [b.name for b in scene10.boxes[:3]]
    q = straight_reach(scene10)[0]
    for config in (MUJOCO, DynamicsConfig(workers=0)):
        phi = build_phi(make_spec(scene10, names, config=config))
        x0 = phi.settle(initial_state(phi.layout, q, scene_box_states(scene10)))
        phi.step_forces(x0, q)
        masses = np.array([scene10.box(n).mass for n in names])
        np.testing.assert_allclose(phi.shelf_forces[1:], GRAVITY * masses, rtol=0.02)


def test_pushes_proved_free_are_those_the_full_jam_reading_finds_unblocked(kept, reach10,
                                                                           monkeypatch):
    """Along the kept reach, wherever `pushes_free` proves the arm's pushes free, the full
    reading (`jam.approach_speeds` of `jam_contacts`) finds no blocked box; and it proves
    most of them (it is what saves the full reading)."""
    spec, phi, _ = kept
    checked = {"proved": 0, "asked": 0}
    original, approaching = mujoco_phi.pushes_free, mujoco_phi.approaching

    def remembering(model, data, nodes, v_commanded):
        checked["v"] = v_commanded
        return approaching(model, data, nodes, v_commanded)

    def checking(model, data, nodes, pushes):
        answer = original(model, data, nodes, pushes)
        checked["asked"] += 1
        if answer:
            checked["proved"] += 1
            full = approach_speeds(jam_contacts(model, data, nodes),
                                   commanded_point_velocity(model, data, checked["v"]))
            assert full == {}
        return answer

    monkeypatch.setattr(mujoco_phi, "pushes_free", checking)
    monkeypatch.setattr(mujoco_phi, "approaching", remembering)
    list(phi.kept_knots(reach10))
    assert checked["asked"] > 10 and checked["proved"] > checked["asked"] / 2


def _pairs(*rows):
    """(node pairs, frames from geom1 into geom2, mus) of hand-made contacts."""
    return ([[a, b] for a, b, _ in rows], [list(n) for _, _, n in rows], [0.5] * len(rows))


@pytest.mark.parametrize("rows, push, free", [
    ([(-1, 1, (0, 0, 1))], (1, 0, 0), True),  # box 1 on the board, pushed sideways
    ([(-1, 1, (0, 0, 1))], (0, 0, -1), False),  # pushed down into the board
    ([(-1, 1, (0, 0, 1)), (1, -1, (1, 0, 0))], (1, 0, 0), False),  # into a wall ahead
    ([(-1, 1, (0, 0, 1)), (-1, 2, (0, 0, 1)), (1, 2, (1, 0, 0))], (1, 0, 0), True),  # a chain
    ([(-1, 1, (0, 0, 1)), (-1, 2, (0, 0, 1)), (1, 2, (1, 0, 0)), (2, -1, (1, 0, 0))],
     (1, 0, 0), False),  # a chain ending at a wall
])
def test_a_push_is_proved_free_only_where_the_blocked_test_says_so(rows, push, free):
    """`_Touching.free` against `jam.blocked` on the same hand-made contacts (nodes: -1
    static, 1 and 2 kept boxes; jam's box index is the node - 1)."""
    pairs, frames, mus = _pairs(*rows)
    contacts = []
    for (a, b), n, mu in zip(pairs, frames, mus, strict=True):
        na, nb = (None if a < 0 else a - 1), (None if b < 0 else b - 1)
        contacts += [Contact(nb, na, np.array(n, float), np.zeros(3), mu, None),
                     Contact(na, nb, -np.array(n, float), np.zeros(3), mu, None)]
    proved = mujoco_phi._Touching(pairs, frames, mus).free(1, tuple(map(float, push)), (1,))
    assert proved == free
    assert blocked(0, np.array(push, float), contacts, (0,)) == (not free)
