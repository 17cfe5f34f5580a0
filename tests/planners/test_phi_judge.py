"""The judge in phi: Sec. III's classes read on phi's boxes, the box overlap it reads
intruders with (against known answers and Bullet's own), and whole plans judged in phi's
members (deterministic, every class a real rollout can give)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pybullet as pb
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from scipy.spatial.transform import Rotation

from drake_clutter.common.config import Config, load_config
from drake_clutter.phi.state import pose_to_box_state, scene_box_states
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.phi_judge import (
    JudgedRollout,
    PhiFindings,
    PhiReading,
    PhiVerdict,
    judge_paths,
    member_findings,
    member_margin,
    reading_of,
)
from drake_clutter.scene.grading import (
    box_overlap,
    target_zone_ratio,
    target_zone_reason,
    zone_extent,
)

# ----------------------------------------------------------------------------- box overlap


def test_box_overlap_known_answers():
    eye = np.eye(3)
    half = np.array([0.05, 0.05, 0.05])
    assert box_overlap([0, 0, 0], eye, half, [0.09, 0, 0], eye, half) == pytest.approx(0.01)
    assert box_overlap([0, 0, 0], eye, half, [0.11, 0, 0], eye, half) == 0.0
    assert box_overlap([0, 0, 0], eye, half, [0.09, 0.08, 0], eye, half) == pytest.approx(0.01)
    # A cube turned 45 deg about z, its edge 0.01 m into the other's face.
    R = Rotation.from_euler("z", 45, degrees=True).as_matrix()
    x = 0.05 + 0.05 * np.sqrt(2) - 0.01
    assert box_overlap([0, 0, 0], eye, half, [x, 0, 0], R, half) == pytest.approx(0.01)
    # Separated only along an edge-edge axis: two cubes crossed at their edges.
    Ra = Rotation.from_euler("x", 45, degrees=True).as_matrix()
    Rb = Rotation.from_euler("y", 45, degrees=True).as_matrix()
    gap = 2 * 0.05 * np.sqrt(2)
    assert box_overlap([0, 0, 0], Ra, half, [0, 0, gap + 0.001], Rb, half) == 0.0
    assert box_overlap([0, 0, 0], Ra, half, [0, 0, gap - 0.004], Rb, half) == pytest.approx(
        0.004, abs=1e-9)


def test_box_overlap_matches_bullets_penetration():
    """Random pairs of boxes: the same depth as Bullet's closest points (GJK/EPA)."""
    rng = np.random.default_rng(3)
    client = pb.connect(pb.DIRECT)
    try:
        checked = 0
        for _ in range(60):
            half_a, half_b = rng.uniform(0.01, 0.06, 3), rng.uniform(0.01, 0.06, 3)
            R_a = Rotation.random(random_state=rng).as_matrix()
            R_b = Rotation.random(random_state=rng).as_matrix()
            p_b = rng.uniform(-0.06, 0.06, 3)
            bodies = []
            for half, p, R in ((half_a, np.zeros(3), R_a), (half_b, p_b, R_b)):
                shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half.tolist(),
                                                physicsClientId=client)
                bodies.append(pb.createMultiBody(0.0, shape, -1, p.tolist(),
                                                 Rotation.from_matrix(R).as_quat().tolist(),
                                                 physicsClientId=client))
            points = pb.getClosestPoints(*bodies, 0.0, physicsClientId=client)
            bullet = max([0.0] + [-pt[8] for pt in points])
            ours = box_overlap(np.zeros(3), R_a, half_a, p_b, R_b, half_b)
            for body in bodies:
                pb.removeBody(body, physicsClientId=client)
            if bullet > 1e-4 or ours > 1e-4:
                checked += 1
                assert ours == pytest.approx(bullet, abs=1e-3)  # Bullet's margin
        assert checked > 20
    finally:
        pb.disconnect(client)


# ----------------------------------------------------------------------------- readings


@pytest.fixture(scope="module")
def setting(scene, baseline_path):
    """fig5, the baseline's path at alpha 0.3 (its last knot's pads around the target), the
    capsule arm, and the boxes where the scene puts them."""
    return scene, baseline_path, ArmGeometry(scene, "capsules"), scene_box_states(scene)


def _moved(states, name, X):
    out = dict(states)
    out[name] = pose_to_box_state(X)
    return out


def _read(setting, final, limit="", jam=0.0, press=0.0, config=None):
    scene, q, geometry, _ = setting
    config = config or Config()
    findings = member_findings(scene, geometry, q, JudgedRollout(final, jam), limit,
                               press, config.evaluation)
    return reading_of(findings, config)


def test_readings_give_every_class_of_sec_iii(setting):
    scene, q, geometry, states = setting
    assert _read(setting, states).kind == "success"
    rest = {b.name: geometry.rest_pose(b.name) for b in scene.boxes}
    # An obstacle lying on its side: partial success, one box disturbed.
    side = RigidTransform(RollPitchYaw(np.pi / 2, 0, 0), rest["large_stable"].translation()
                          + [0, 0, 0.01])
    tipped = _read(setting, _moved(states, "large_stable", side))
    assert (tipped.kind, tipped.disturbed) == ("partial_success", 1)
    # The same box on the floor: objects falling.
    floor = RigidTransform([0.3, 0.1, 0.06])
    assert _read(setting, _moved(states, "large_stable", floor)).kind == "objects_falling"
    # The target pushed 10 cm deeper: failure to grasp.
    deeper = RigidTransform(rest["target"].translation() + [0.10, 0, 0])
    assert _read(setting, _moved(states, "target", deeper)).kind == "failure_to_grasp"
    # Another box inside the pad zone (the target moved out of the way): its name is the reason.
    X_WG = geometry.tool_jacobian(q[-1])[0]
    centre, _ = zone_extent(float(q[-1, 7]), Config().evaluation)
    final = _moved(states, "target", deeper)
    final = _moved(final, "small_tippy", RigidTransform(X_WG.multiply(centre)
                                                        - [0, 0, 0.05]))
    reading = _read(setting, final)
    assert reading.kind == "failure_to_grasp"
    # A jam, a limit and a failed rollout are kinematic failures, above a fall.
    assert _read(setting, _moved(states, "large_stable", floor), jam=0.002).kind == \
        "kinematic_failure"
    assert _read(setting, states, limit="too fast").reason == "too fast"

    # A press on a box's top is recorded, not read: phi's jam decides.
    assert _read(setting, states, press=0.01).kind == "success"
    failed = member_findings(scene, geometry, q, JudgedRollout(None, None), "", 0.0,
                             Config().evaluation)
    assert failed.failed and reading_of(failed, Config()).kind == "kinematic_failure"


def test_findings_round_trip_and_read_again(setting):
    scene, q, geometry, states = setting
    findings = member_findings(scene, geometry, q, JudgedRollout(states, 0.002),
                               "", 0.01, Config().evaluation)
    assert PhiFindings.from_data(findings.to_data()) == findings
    verdict = PhiVerdict.from_findings([findings.to_data()] * 2, Config())
    assert verdict.p_success == 0.0 and verdict.findings == (findings, findings)
    assert verdict.readings[0].reason.startswith("jam")
    shallow = replace(Config(), phi_judge=replace(Config().phi_judge, jam_depth=0.005))
    assert PhiVerdict.from_findings(verdict.findings, shallow).readings[0].kind == "success"


def test_intruder_in_the_zone_fails_the_grasp_with_the_target_in_place(setting):
    scene, q, geometry, states = setting
    X_WG = geometry.tool_jacobian(q[-1])[0]
    centre, half = zone_extent(float(q[-1, 7]), Config().evaluation)
    size = scene.box("small_tippy").size
    # small_tippy standing just beside the target, 5 mm into the zone along y_G.
    y = half[1] + size[1] / 2 - 0.005
    p = X_WG.multiply(centre + [0.0, -y, 0.0])
    p[2] = geometry.rest_pose("small_tippy").translation()[2]
    reading = _read(setting, _moved(states, "small_tippy", RigidTransform(
        X_WG.rotation(), p)))
    assert reading.kind == "failure_to_grasp"
    assert "small_tippy" in reading.reason


def test_verdict_summarises_members_as_the_robust_judge():
    v = PhiVerdict((PhiReading("success", ""), PhiReading("partial_success", "", 1),
                    PhiReading("kinematic_failure", ""), PhiReading("success", "")))
    assert v.p_success == 0.5
    assert v.expected_grade == pytest.approx((0 + 1 + 3 + 0) / 4)
    assert v.disturbed == 0.25
    worse = PhiVerdict((PhiReading("success", ""), PhiReading("objects_falling", "", 2)))
    assert v.key() < worse.key()  # same P(success) and expected grade: fewer boxes disturbed
    assert v.to_data()["kinds"][2] == "kinematic_failure"


def test_the_zone_ratio_passes_1_exactly_where_the_zone_test_names_a_reason():
    evaluation = Config().evaluation
    rng = np.random.default_rng(7)
    size, opening = (0.05, 0.06, 0.12), 0.08
    seen = set()
    for _ in range(2000):
        p = rng.normal(0.0, [0.03, 0.01, 0.03]) + [zone_extent(opening, evaluation)[0][0], 0, 0]
        R = Rotation.from_rotvec(rng.normal(0.0, 0.2, 3)).as_matrix()
        reason = target_zone_reason(p, R, size, opening, evaluation)
        ratio = target_zone_ratio(p, R, size, opening, evaluation)
        assert (ratio > 1.0) == bool(reason), (ratio, reason)
        seen.add(bool(reason))
    assert seen == {True, False}


def test_the_margin_orders_failures_by_how_near_they_came(setting):
    """The target pushed 5 cm and 10 cm deeper: both fail the grasp, the nearer with the
    smaller margin; a success reads a margin below 1, a jam its depth over the limit, a plan
    out of the limits an infinite one; the verdict order puts the margin after the classes."""
    scene, q, geometry, states = setting
    rest = geometry.rest_pose("target").translation()
    near = _read(setting, _moved(states, "target", RigidTransform(rest + [0.05, 0, 0])))
    far = _read(setting, _moved(states, "target", RigidTransform(rest + [0.10, 0, 0])))
    assert near.kind == far.kind == "failure_to_grasp"
    assert 1.0 < near.margin < far.margin
    assert _read(setting, states).margin < 1.0
    config = Config()
    assert _read(setting, states, jam=0.003).margin == pytest.approx(
        0.003 / config.phi_judge.jam_depth)
    assert member_margin(PhiFindings(limit="too fast"), config) == np.inf
    nearer = PhiVerdict((near, near))
    farther = PhiVerdict((far, far))
    assert nearer.margin < farther.margin
    assert nearer.key() < farther.key()  # the same classes: the margin orders them
    assert PhiVerdict((_read(setting, states), far)).key() < nearer.key()  # P(success) first


def test_a_box_pushed_toward_the_board_edge_reads_nearer_a_fall(setting):
    scene, q, geometry, states = setting
    rest = geometry.rest_pose("large_stable")
    shelf = scene.shelf
    offset = rest.translation()[:2] - np.asarray(shelf.center_xy)
    inside = np.array([shelf.depth, shelf.width]) / 2 - np.abs(offset)
    axis = int(np.argmin(inside))  # the nearer edge
    shift = np.zeros(3)
    shift[axis] = np.sign(offset[axis]) * inside[axis] * 0.8
    moved = RigidTransform(rest.rotation(), rest.translation() + shift)
    found = member_findings(scene, geometry, q, JudgedRollout(
        _moved(states, "large_stable", moved), 0.0), "", 0.0, Config().evaluation)
    assert found.edge == pytest.approx(0.8, abs=1e-6)
    fallen = member_findings(scene, geometry, q, JudgedRollout(_moved(
        states, "large_stable", RigidTransform([0.3, 0.1, 0.06])), 0.0), "", 0.0,
        Config().evaluation)
    assert fallen.edge >= 1.0


# ----------------------------------------------------------------------------- whole plans


# Fixed knots on fig5 (no IK: the same path on every machine): outside the shelf, 6 cm above
# large_stable's top, then 4 cm down into it, the gripper level as the baseline's at alpha 0.3.
START = np.array([-0.558, -0.316, -2.812, -2.106, -3.851, -1.511, -0.366, 0.09])
ABOVE = np.array([-0.278, -0.524, -2.475, -1.806, -3.334, -1.071, -0.482, 0.09])
INTO = np.array([-0.245, -0.247, -2.555, -1.707, -3.482, -1.22, -0.481, 0.09])


def _pressing_path() -> np.ndarray:
    """30 knots: 15 from START to ABOVE, then 14 down to INTO, pressing large_stable into the
    board (a box a rigid world would not let move: phi's jam, 8 mm at a knot, measured)."""
    s = np.linspace(0.0, 1.0, 15)[:, None]
    s2 = np.linspace(0.0, 1.0, 16)[1:, None]
    return np.vstack([(1 - s) * START + s * ABOVE, (1 - s2) * ABOVE + s2 * INTO])


def test_judge_paths_is_deterministic_and_reads_the_plans(scene):
    """Two paths in phi's nominal member and one perturbed member (MuJoCo phi, for speed):
    the same verdicts twice; the path that presses large_stable into the board jams in both
    members, the path kept outside the shelf never reaches the target (failure to grasp)."""
    config = load_config(None, ["dynamics.engine=mujoco", "phi_judge.members=2",
                                "dynamics.workers=0"])
    pressing = _pressing_path()
    times = np.arange(len(pressing)) * config.baseline.knot_time
    paths = {"pressing": pressing, "outside": np.repeat(pressing[:1], len(pressing), axis=0)}
    first = judge_paths(scene, paths, times, config, ArmGeometry(scene, "capsules"))
    again = judge_paths(scene, paths, times, config, ArmGeometry(scene, "capsules"))
    assert {k: v.to_data() for k, v in first.items()} == \
        {k: v.to_data() for k, v in again.items()}
    assert len(first["pressing"].readings) == 2
    assert first["outside"].readings[0].kind == "failure_to_grasp"
    assert first["outside"].p_success == 0.0
    assert all(r.kind == "kinematic_failure" and r.reason.startswith("jam")
               for r in first["pressing"].readings)


def test_the_short_judge_reads_the_same_classes_with_stopped_rollouts(scene, baseline_path):
    """``complete=False``: the same readings; the jammed path's rollouts stop at the jam
    (no box fates read) and a path out of the judge's speed limits is not rolled out."""
    config = load_config(None, ["dynamics.engine=mujoco", "phi_judge.members=2",
                                "dynamics.workers=0"])
    pressing = _pressing_path()
    times = np.arange(len(pressing)) * config.baseline.knot_time
    fast = pressing.copy()
    fast[1:, 0] += 2.0  # a 2 rad jump of the first joint in one knot: over its speed limit
    paths = {"pressing": pressing, "outside": np.repeat(pressing[:1], len(pressing), axis=0),
             "fast": fast, "baseline": baseline_path}
    full = judge_paths(scene, paths, times, config, ArmGeometry(scene, "capsules"))
    quick = judge_paths(scene, paths, times, config, ArmGeometry(scene, "capsules"),
                        complete=False)
    for name in paths:
        assert [r.kind for r in quick[name].readings] == [r.kind for r in full[name].readings]
    assert all(f.stopped and f.jam >= config.phi_judge.jam_depth and f.fallen == ()
               for f in quick["pressing"].findings)
    assert not any(f.stopped for f in full["pressing"].findings)
    assert all(f.stopped and f.limit and f.jam is None for f in quick["fast"].findings)
    assert not any(f.stopped for f in quick["outside"].findings)


def test_threads_roll_out_the_same_verdicts_as_in_turn(scene, baseline_path):
    """``phi_judge.threads``: the paths of a member rolled out in two threads, each its
    own clone of the MuJoCo phi, read the very same findings as one after the other."""
    pressing = _pressing_path()
    paths = {"pressing": pressing, "outside": np.repeat(pressing[:1], len(pressing), axis=0),
             "baseline": baseline_path}
    found = []
    for threads in (1, 2):
        config = load_config(None, ["dynamics.engine=mujoco", "phi_judge.members=2",
                                    "dynamics.workers=0", f"phi_judge.threads={threads}"])
        times = np.arange(len(pressing)) * config.baseline.knot_time
        verdicts = judge_paths(scene, paths, times, config, ArmGeometry(scene, "capsules"),
                               complete=False)
        found.append({k: v.to_data() for k, v in verdicts.items()})
    assert found[0] == found[1]
    assert found[0]["pressing"]["kinds"] == ["kinematic_failure"] * 2


@pytest.mark.parametrize("stepping", [
    ["phi_judge.stepping=knot", "phi_judge.sleep=false", "phi_judge.time_step=0.002",
     "phi_judge.sample_steps=10"],
    ["phi_judge.stepping=kept", "phi_judge.sleep=false", "phi_judge.prune=true"],
    ["phi_judge.stepping=kept", "phi_judge.sleep=true", "phi_judge.prune=false",
     "phi_judge.time_step=0.004", "phi_judge.sample_steps=5"],
    [],  # the defaults: read every 40 ms
])
def test_every_stepping_reads_the_plans_and_repeats_its_verdicts(scene, baseline_path, stepping):
    """The judge's phi knot by knot, in a kept world, and in a kept world of sleeping boxes
    at a longer step read every 20 ms or (the defaults) every 40 ms: the pressing path jams
    in every member, the path kept outside the shelf fails to grasp, and the same settings
    give the same findings again, in one thread or two."""
    pressing = _pressing_path()
    paths = {"pressing": pressing, "outside": np.repeat(pressing[:1], len(pressing), axis=0),
             "baseline": baseline_path}
    found = []
    for threads in (1, 1, 2):
        config = load_config(None, ["dynamics.workers=0", "phi_judge.members=2",
                                    f"phi_judge.threads={threads}", *stepping])
        times = np.arange(len(pressing)) * config.baseline.knot_time
        verdicts = judge_paths(scene, paths, times, config, ArmGeometry(scene, "capsules"),
                               complete=False)
        found.append({k: v.to_data() for k, v in verdicts.items()})
    assert found[0] == found[1] == found[2]
    assert found[0]["pressing"]["kinds"] == ["kinematic_failure"] * 2
    assert found[0]["outside"]["kinds"] == ["failure_to_grasp"] * 2


def test_a_failed_kept_rollout_reads_a_kinematic_failure_of_that_member(scene, monkeypatch):
    """A MuJoCo reset inside a kept world's run (its NaN jams, `MujocoPhi.kept_knots`) is a
    failed rollout: a kinematic failure of the member, never a crash or a success."""
    from drake_clutter.phi.mujoco_phi import MujocoPhi

    def failing(self, knots, trace=False):
        yield np.full(self.layout.num_boxes, np.nan), set()

    monkeypatch.setattr(MujocoPhi, "kept_knots", failing)
    config = load_config(None, ["dynamics.workers=0", "phi_judge.members=2"])
    pressing = _pressing_path()
    times = np.arange(len(pressing)) * config.baseline.knot_time
    verdict = judge_paths(scene, {"pressing": pressing}, times, config,
                          ArmGeometry(scene, "capsules"))["pressing"]
    assert [r.kind for r in verdict.readings] == ["kinematic_failure"] * 2
    assert all(f.failed and r.reason == "phi failed on the rollout"
               for f, r in zip(verdict.findings, verdict.readings, strict=True))
