"""phi's jam measure (phi/jam.py): the rigid, quasi-static blocked test on synthetic contacts,
and `Phi.step_jam` on a real reach."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.common.config import DynamicsConfig
from drake_clutter.phi.dynamics import ARM_NODE, Phi, initial_state
from drake_clutter.phi.jam import (
    ACTOR,
    Contact,
    approach_speeds,
    blocked,
    cone_generators,
    held,
    outside_cone_hull,
    outside_cones,
    proved_free,
)
from drake_clutter.phi.pruning import make_pruned_spec
from drake_clutter.phi.state import scene_box_states
from drake_clutter.scene.generators import generate_scene
from drake_clutter.testing.reach_paths import straight_reach

UP = np.array([0.0, 0.0, 1.0])


def _both(a, b, normal_into_a, mu=0.5) -> list[Contact]:
    n = np.asarray(normal_into_a, float)
    return [Contact(a, b, n, np.zeros(3), mu, None), Contact(b, a, -n, np.zeros(3), mu, None)]


def _board(box, mu=0.5) -> list[Contact]:
    return _both(box, None, UP, mu)


def test_a_horizontal_push_on_a_board_is_not_blocked_but_a_push_down_is():
    contacts = _board(0) + _both(0, ACTOR, [-1.0, 0.0, 0.0])
    assert not blocked(0, np.array([1.0, 0.0, 0.0]), contacts)
    assert blocked(0, np.array([0.0, 0.0, -1.0]), contacts)
    steep = np.array([np.sin(0.3), 0.0, -np.cos(0.3)])  # 17 deg from vertical: inside mu 0.5
    shallow = np.array([np.sin(0.8), 0.0, -np.cos(0.8)])  # 46 deg: outside (26.6 deg)
    assert blocked(0, steep, contacts) and not blocked(0, shallow, contacts)


def test_a_wall_blocks_a_push_into_it_and_a_free_box_in_a_chain_does_not():
    wall = _both(0, None, [-1.0, 0.0, 0.0])  # a wall ahead along +x
    push = np.array([1.0, 0.0, 0.0])
    assert blocked(0, push, _board(0) + wall)
    chain = _board(0) + _board(1) + _both(0, 1, [-1.0, 0.0, 0.0])  # box 1 ahead of box 0
    assert not blocked(0, push, chain)
    assert blocked(0, push, chain + _both(1, None, [-1.0, 0.0, 0.0]))  # box 1 at a wall


def test_held_is_cone_membership():
    assert held(np.array([0.0, 0.0, -1.0]), [UP])
    assert not held(np.array([0.0, 0.0, 1.0]), [UP])
    assert not held(np.array([1.0, 0.0, 0.0]), [])


def test_cone_generators_are_unit_edges_at_the_friction_angle_around_the_normal():
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(50, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    normals[:3] = [UP, -UP, [1.0, 0.0, 0.0]]  # axis-aligned, as on a board or a wall
    mus = rng.uniform(0.05, 1.0, 50)
    bulk = cone_generators(normals, mus)
    assert bulk.shape == (50, 8, 3)
    np.testing.assert_allclose(np.linalg.norm(bulk, axis=2), 1.0, atol=1e-12)
    angles = np.arccos(np.clip(np.einsum("nkj,nj->nk", bulk, normals), -1, 1))
    np.testing.assert_allclose(angles, np.arctan(mus)[:, None] * np.ones((1, 8)), atol=1e-9)
    spread = np.einsum("nkj,nkj->nk", bulk - normals[:, None], np.roll(bulk, 1, axis=1)
                       - normals[:, None])  # neighbouring edges 45 deg apart about the normal
    assert np.all(spread > 0)


def _random_cones(rng, n):
    normals = rng.normal(size=(n, 3)) + np.array([0.0, 0.0, rng.uniform(0, 3)])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return normals, rng.uniform(0.02, 1.2, n)


def test_the_proofs_never_contradict_the_least_squares_answer():
    """Where the enclosing-cone test, the plane test or both (`proved_free`) prove a
    direction outside the cones, `held` (non-negative least squares over the pyramids'
    generators) says not held, on 3000 random sets of 1-6 cones; each proves often enough to
    be worth asking, and both prove a sideways push on a board."""
    rng = np.random.default_rng(7)
    proved = {"hull": 0, "planes": 0, "either": 0}
    for _ in range(3000):
        normals, mus = _random_cones(rng, int(rng.integers(1, 7)))
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        answers = {"hull": outside_cone_hull(d, normals, mus, 2e-3),
                   "planes": outside_cones(d, normals, mus, 2e-3),
                   "either": proved_free(d, normals, mus)}
        assert answers["either"] == (answers["hull"] or answers["planes"])
        for name, answer in answers.items():
            proved[name] += answer
        if answers["either"]:
            assert not held(-d, list(cone_generators(normals, mus).reshape(-1, 3)))
    assert min(proved.values()) > 600
    board = np.array([UP, UP, UP, UP])
    for angle in np.linspace(0.0, 2 * np.pi, 12):
        sideways = np.array([np.cos(angle), np.sin(angle), 0.0])
        assert outside_cones(sideways, board, np.full(4, 0.5), 2e-3)
        assert outside_cone_hull(sideways, board, np.full(4, 0.5), 2e-3)
    assert not proved_free(UP, board, np.full(4, 0.5))  # a push down: held


def test_approach_speeds_reads_only_the_arm_advancing_into_a_blocked_box():
    """Box 0 against a wall ahead (+x), box 1 free on the board; the arm touches both from
    behind. Advancing at 0.2 m/s: box 0 blocked at that speed, box 1 absent (free). Receding
    (the arm's point moving away): no box, whatever blocks it."""
    wall = _both(0, None, [-1.0, 0.0, 0.0])
    contacts = (_board(0) + wall + _both(0, ACTOR, [1.0, 0.0, 0.0])
                + _board(1) + _both(1, ACTOR, [1.0, 0.0, 0.0]))
    ahead = approach_speeds(contacts, lambda c: np.array([0.2, 0.0, 0.0]))
    assert ahead == {0: pytest.approx(0.2)}
    assert approach_speeds(contacts, lambda c: np.array([-0.2, 0.0, 0.0])) == {}


@pytest.fixture(scope="module")
def reach():
    scene = generate_scene("bookshelf", 10, seed=0)
    path = straight_reach(scene)
    spec, _ = make_pruned_spec(scene, path, config=DynamicsConfig(workers=0))
    phi = Phi(spec)
    return phi, phi.settle(initial_state(spec.layout, path[0], scene_box_states(scene))), path


def test_step_jam_steps_phi_bit_for_bit_and_reads_no_jam_on_a_free_reach(reach):
    """The reach pushes box_06 6 cm along the board: it slides, nothing is blocked."""
    phi, x0, path = reach
    x_plain, x_jam = x0, x0
    touched = False
    for u in path[1:15]:
        touched |= any(ARM_NODE in e and min(e) >= 0 for e in phi.step_traced(x_plain, u)[1])
        x_plain = phi.step(x_plain, u)
        x_jam, jam = phi.step_jam(x_jam, u)
        np.testing.assert_array_equal(x_plain, x_jam)
        assert jam.shape == (phi.layout.num_boxes,) and np.all(jam == 0.0)
    assert touched
    x_nan, jam = phi.step_jam(np.full_like(x0, np.nan), path[1])
    assert np.isnan(x_nan).all() and np.isnan(jam).all()
