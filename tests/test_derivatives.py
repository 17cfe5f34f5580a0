"""phi's Jacobians (derivatives.py): colouring, known blocks, workers, stride, and agreement
with brute-force finite differences and with Drake's AutoDiffXd."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from reach_paths import straight_reach

from drake_clutter.config import DynamicsConfig
from drake_clutter.derivatives import (
    PhiDynamics,
    WorkerPool,
    colour_groups,
    components,
    dense_jacobians,
    differentiated_knots,
    interpolate_between,
    node_columns,
)
from drake_clutter.derivatives_autodiff import AutoDiffPhi
from drake_clutter.dynamics import ARM_DIM, ARM_NODE, StateLayout, initial_state, scene_box_states
from drake_clutter.generators import generate_scene
from drake_clutter.pruning import make_pruned_spec


def _setup(num_boxes: int, seed: int, **config):
    scene = generate_scene("bookshelf", num_boxes, seed=seed)
    path = straight_reach(scene)
    assert path is not None
    spec, report = make_pruned_spec(scene, path, config=DynamicsConfig(workers=0, **config))
    dynamics = PhiDynamics(spec)
    x0 = dynamics.phi.settle(initial_state(spec.layout, path[0], scene_box_states(scene)))
    return dynamics, dynamics.rollout(x0, path[1:]), path[1:]


def _edges(dynamics, x, u) -> set:
    return {e for e in dynamics.phi.step_traced(x, u)[1] if min(e) >= 0}


def _with_config(dynamics: PhiDynamics, **changes) -> PhiDynamics:
    config = dataclasses.replace(dynamics.config, **changes)
    return PhiDynamics(dataclasses.replace(dynamics.spec, config=config))


def _rel(J, ref) -> float:
    return float(np.linalg.norm(J - ref) / np.linalg.norm(ref))


@pytest.fixture(scope="module")
def point10():
    """Bookshelf, 10 boxes, seed 1: the reach pushes into kept boxes in its second half.
    fd_step 1e-5: settled boxes are where SAP's stopping tolerance makes 1e-6 noisy (2e-2),
    and these tests check the bookkeeping, not the step."""
    return _setup(10, 1, fd_step=1e-5)


# ----------------------------------------------------------------------------- pure parts


def test_components_ignore_frozen_boxes_and_isolate_the_rest():
    comps = components(5, {(0, 2), (2, 3), (1, -1), (4, -2)})
    assert comps == [[0, 2, 3], [1], [4]]


def test_colour_groups_take_one_column_per_component():
    groups = colour_groups([[0, 1, 2], [10, 11], [20]])
    assert groups == [[0, 10, 20], [1, 11], [2]]
    layout = StateLayout(("a", "b"))
    arm = node_columns(layout, ARM_NODE)
    assert arm == list(range(8)) + list(range(layout.ndx, layout.ndx + 8))
    assert node_columns(layout, 2) == list(range(20, 32))


def test_stride_knots_and_interpolation():
    assert differentiated_knots(29, 1) == list(range(29))
    assert differentiated_knots(29, 5) == [0, 5, 10, 15, 20, 25, 28]
    A = np.zeros((5, 2, 2))
    B = np.zeros((5, 2, 1))
    A[0], A[4] = 1.0, 5.0
    B[4] = 4.0
    interpolate_between(A, B, [0, 4])
    np.testing.assert_allclose(A[:, 0, 0], [1, 2, 3, 4, 5])
    np.testing.assert_allclose(B[:, 0, 0], [0, 1, 2, 3, 4])


# ----------------------------------------------------------------------------- against brute force


def test_coloured_jacobians_equal_dense_ones(point10):
    """Free knots, and knots where the arm pushes a box and brute force is reproducible, agree
    with brute force to finite-difference noise; structural zeros are zero in brute force too.
    Brute force counts as reproducible where its answers with steps h and 2h agree to 1e-3.
    (Elsewhere in a push it is itself noise: on this scene h and 2h differ by 60-270 % at five
    of the seven pushing knots - SAP's stopping tolerance - and no reference exists there.)"""
    dynamics, xs, us = point10
    A, B = dynamics.linearize_tangent(xs, us)
    edges = [_edges(dynamics, xs[t], us[t]) for t in range(len(us))]
    free = [t for t in range(len(us)) if not edges[t]][:2]
    pushing = [t for t in range(1, len(us)) if any(ARM_NODE in e for e in edges[t])]
    h = dynamics.config.fd_step
    checked = []
    for t in free + pushing:
        Jd = np.hstack(dense_jacobians(dynamics.phi, xs[t], us[t], h))
        if t in pushing and _rel(np.hstack(dense_jacobians(dynamics.phi, xs[t], us[t], 2 * h)),
                                 Jd) > 1e-3:
            continue
        J = np.hstack([A[t], B[t]])
        assert _rel(J, Jd) < 2e-3, (t, _rel(J, Jd))
        assert np.all(np.abs(Jd[J == 0]) <= 2e-3 * np.abs(Jd).max()), t
        checked.append(t)
    assert free and set(checked) & set(pushing), (free, pushing, checked)
    assert dynamics.stats.mean_evaluations < dynamics.layout.ndx + 8 + 1


def test_arm_rows_are_exact_and_state_coordinates_follow(point10):
    dynamics, xs, us = point10
    t = len(us) - 1
    A_tan, B_tan = dynamics.linearize_tangent(xs[t:t + 2], us[t:t + 1])
    np.testing.assert_array_equal(A_tan[0][:ARM_DIM], 0.0)
    np.testing.assert_array_equal(B_tan[0][:ARM_DIM], np.eye(8))
    A, B = dynamics.linearize(xs[t:t + 2], us[t:t + 1])
    layout = dynamics.layout
    assert A.shape == (1, layout.nx, layout.nx) and B.shape == (1, layout.nx, 8)
    G_next, P = layout.tangent_to_state(xs[t + 1]), layout.state_to_tangent(xs[t])
    np.testing.assert_allclose(A[0], G_next @ A_tan[0] @ P)
    np.testing.assert_allclose(B[0], G_next @ B_tan[0])


def test_known_blocks_match_fresh_differences(point10):
    dynamics, xs, us = point10
    dynamics.linearize_tangent(xs, us)
    assert dynamics.stats.known_boxes > 0  # resting boxes reused their blocks
    fresh = _with_config(dynamics, known_block_tolerance=0.0)  # resting boxes still creep
    A0, B0 = dynamics.linearize_tangent(xs[:6], us[:5])
    A1, B1 = fresh.linearize_tangent(xs[:6], us[:5])
    assert fresh.stats.known_boxes == 0
    assert _rel(A0, A1) < 2e-3
    np.testing.assert_array_equal(B0, B1)


def test_stride_differentiates_fewer_knots(point10):
    dynamics, xs, us = point10
    A1, B1 = dynamics.linearize_tangent(xs, us)
    strided = _with_config(dynamics, derivative_stride=4)
    A4, B4 = strided.linearize_tangent(xs, us)
    knots = differentiated_knots(len(us), 4)
    assert strided.stats.differentiated_knots == len(knots) < len(us)
    for t in knots:
        assert _rel(A4[t], A1[t]) < 2e-3
    np.testing.assert_allclose(A4[1], 0.75 * A4[0] + 0.25 * A4[4])


def test_parallel_workers_give_the_serial_bits():
    dynamics, xs, us = _setup(5, 0)
    A, B = dynamics.linearize_tangent(xs, us)
    with WorkerPool(2) as pool:
        parallel = PhiDynamics(dynamics.spec, pool=pool)
        Ap, Bp = parallel.linearize_tangent(xs, us)  # traces every knot in the workers first
        assert parallel.stats.traced == len(us)
    np.testing.assert_array_equal(A, Ap)
    np.testing.assert_array_equal(B, Bp)


# ----------------------------------------------------------------------------- AutoDiffXd


@pytest.fixture(scope="module")
def spheres10():
    """The AutoDiffXd-capable corner-spheres variant: the reach pushes a box from knot 2."""
    dynamics, xs, us = _setup(10, 0, contact_model="spheres")
    return dynamics, xs[:15], us[:14]


@pytest.mark.xfail(strict=True, reason=(
    "since the shelf moved to 0.55 m (this scene's reach now pushes box 4 for knots 2-13), FD "
    "and AutoDiffXd disagree in contact: whole-Jacobian relative error 1e-2 to 2e4 at every "
    "contact knot, and FD with h = 1e-6, 1e-5, 1e-4 disagree with each other as much; free "
    "knots agree to 6.5e-5. Open in issue 5: phi's derivatives through sustained contact."))
def test_finite_differences_agree_with_autodiff(spheres10):
    dynamics, xs, us = spheres10
    A, B = dynamics.linearize_tangent(xs, us)
    autodiff = AutoDiffPhi(dynamics.phi)
    free_errors, contact_errors, medians = [], [], []
    for t in range(len(us)):
        Aa, Ba = autodiff.jacobians(xs[t], us[t])
        J, Ja = np.hstack([A[t], B[t]]), np.hstack([Aa, Ba])
        big = np.abs(Ja) > 1e-6 * np.abs(Ja).max()
        medians.append(np.median(np.abs(J - Ja)[big] / np.abs(Ja)[big]))
        touching = any(ARM_NODE in e for e in _edges(dynamics, xs[t], us[t]))
        (contact_errors if touching else free_errors).append(_rel(J, Ja))
    assert free_errors and contact_errors
    assert max(medians) < 1e-2  # entry-wise, every knot (measured: <= 3e-3)
    assert max(free_errors) < 1e-3  # whole Jacobian, no contact (measured: ~1e-4)
    # In contact, a corner sphere that touches or leaves within the step makes a few entries
    # secants across a kink: those knots are off as a whole; steady pushing agrees.
    assert sum(e < 1e-3 for e in contact_errors) >= 3


def test_autodiff_needs_the_spheres_variant(point10):
    dynamics, _, _ = point10
    with pytest.raises(ValueError, match="spheres"):
        AutoDiffPhi(dynamics.phi)
