"""phi's Jacobians (phi/derivatives.py): colouring, known blocks, workers, stride, and agreement
with brute-force finite differences and with Drake's AutoDiffXd."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drake_clutter.common.config import DynamicsConfig
from drake_clutter.phi.autodiff import AutoDiffPhi
from drake_clutter.phi.colouring import colour_groups, components, dense_jacobians, node_columns
from drake_clutter.phi.derivatives import PhiDynamics, differentiated_knots, interpolate_between
from drake_clutter.phi.dynamics import ARM_NODE, Phi, initial_state, make_spec
from drake_clutter.phi.pruning import make_pruned_spec
from drake_clutter.phi.state import ARM_DIM, StateLayout, scene_box_states
from drake_clutter.phi.workers import WorkerPool
from drake_clutter.scene.generators import generate_scene
from drake_clutter.testing.reach_paths import straight_reach


def _setup(num_boxes: int, seed: int, **config):
    scene = generate_scene("bookshelf", num_boxes, seed=seed)
    path = straight_reach(scene)
    assert path is not None
    config = {"derivative_stride": 1, **config}  # every knot differentiated: exact Jacobians
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
    fd_step 1e-5: these tests check the finite differences' bookkeeping (colouring, known
    blocks, stride, workers), not the step (AutoDiffXd's: further down). 5 sub-steps (40 ms),
    where the thresholds below were measured (see hydro10)."""
    return _setup(10, 1, fd_step=1e-5, derivative_method="fd", substeps=5)


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
    Brute force counts as reproducible where its answers with steps h and 2h agree to 1e-3
    (elsewhere in a push it has truncation error of its own and is no reference)."""
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
    # a call's stride overrides the configured one (the hold tail's), and is part of the cache key
    As, _ = strided.linearize_tangent(xs, us, stride=1)
    assert strided.stats.differentiated_knots == len(us)
    assert max(_rel(As[t], A1[t]) for t in range(len(us))) < 2e-3  # known blocks reused
    A4_again, _ = strided.linearize_tangent(xs, us)
    assert strided.stats.differentiated_knots == len(knots)
    assert max(_rel(A4_again[t], A4[t]) for t in knots) < 2e-3


def test_parallel_workers_give_the_serial_bits():
    dynamics, xs, us = _setup(5, 0)
    A, B = dynamics.linearize_tangent(xs, us)
    with WorkerPool(2) as pool:
        parallel = PhiDynamics(dynamics.spec, pool=pool)
        Ap, Bp = parallel.linearize_tangent(xs, us)  # traces every knot in the workers first
        assert parallel.stats.traced == len(us)
    np.testing.assert_array_equal(A, Ap)
    np.testing.assert_array_equal(B, Bp)


def test_a_dead_worker_raises_instead_of_hanging_and_the_pool_restarts():
    import os

    from drake_clutter.phi.workers import WorkerDied

    with WorkerPool(2) as pool:
        assert pool.run(abs, [-1, 2, -3]) == [1, 2, 3]
        with pytest.raises(WorkerDied, match="died"):
            pool.run(os._exit, [1])  # the worker process ends mid-task, as if killed
        assert pool.run(abs, [-4]) == [4]  # fresh workers on the next call


# ----------------------------------------------------------------------------- AutoDiffXd


@pytest.fixture(scope="module")
def hydro10():
    """phi's hydroelastic boxes (phi's default until 2026-11-27, where these tests' thresholds
    were measured) with a margin at 5 sub-steps (40 ms), 10 boxes, seed 0: the
    arm is within reach of a kept box from knot 0 and pushes box_06 6 cm over knots 2-13.
    The FD thresholds below were measured at 5 sub-steps; at the planner's 10 (20 ms) forward
    differences are coarser against AutoDiffXd (median 2.3e-2 on this push, measured
    2026-11-23), one reason the planner takes AutoDiffXd where the arm pushes (hybrid)."""
    dynamics, xs, us = _setup(10, 0, derivative_method="fd", substeps=5,
                              contact_model="hydroelastic")
    return dynamics, xs[:15], us[:14]


@pytest.fixture(scope="module")
def edges10():
    """hydro10's push on phi's default boxes ("edges": standing on edge spheres) at the
    planner's 10 sub-steps (20 ms)."""
    dynamics, xs, us = _setup(10, 0, derivative_method="fd")
    assert dynamics.config.contact_model == "edges"
    return dynamics, xs[:15], us[:14]


def test_finite_differences_agree_with_autodiff(hydro10):
    """FD (forward, fd_step 1e-6) against Drake's AutoDiffXd through the same SAP steps.

    Measured here: whole-Jacobian relative error per knot 4.4e-3 7.8e-4 8.7e-4 4.3e-4 3.0e-3
    0.25 1.2e-3 1.9e-3 0.10 9.2e-3 6.5e-3 3.5e-3 4.6e-5 8.6e-5 (median 2.4e-3); FD with h and
    2h differ about as much (median 1.5e-3): the remaining error is forward differences' O(h)
    truncation where contact makes phi curve (central differences: about 5x smaller). The
    point-contact (corner spheres) phi on the same push: median 54, 0 of 12 contact knots below
    1e-2 (SAP sees a point pair only once it touches: a jump)."""
    dynamics, xs, us = hydro10
    A, B = dynamics.linearize_tangent(xs, us)
    autodiff = AutoDiffPhi(dynamics.phi)
    errors, medians = [], []
    for t in range(len(us)):
        Aa, Ba = autodiff.jacobians(xs[t], us[t])
        J, Ja = np.hstack([A[t], B[t]]), np.hstack([Aa, Ba])
        big = np.abs(Ja) > 1e-6 * np.abs(Ja).max()
        medians.append(np.median(np.abs(J - Ja)[big] / np.abs(Ja)[big]))
        errors.append(_rel(J, Ja))
    assert any(ARM_NODE in e for t in range(len(us)) for e in _edges(dynamics, xs[t], us[t]))
    assert np.median(errors) < 1e-2, errors  # measured 2.4e-3
    assert sum(e < 1e-2 for e in errors) >= 11, errors  # measured 12 of 14
    assert max(errors) < 0.5, errors  # measured 0.25 and 0.10 at knots 5 and 8, where h and 2h
    # differ as much: contact curves phi at the step's scale
    assert max(medians) < 1e-3, medians  # entry-wise, every knot (measured <= 8.2e-5)


def test_edge_sphere_jacobians_autodiff_coloured_equals_dense_and_fd_agrees(edges10):
    """phi's default boxes at 20 ms: the coloured, block-reusing AutoDiffXd Jacobians equal the
    dense AutoDiffXd ones, and forward differences (fd_step 1e-6) agree with them except where
    a contact makes or breaks inside the difference. Measured 2026-11-27: coloured against
    dense <= 1.7e-11; FD against AutoDiffXd, whole Jacobian, median 4.8e-3 over 14 knots, 12
    below 2e-2, one jump (7.8e3 at knot 2, where the arm reaches box_06; entry-wise median
    there 5.7e-6, every knot <= 2.9e-5)."""
    dynamics, xs, us = edges10
    A, B = dynamics.linearize_tangent(xs, us)
    exact = _with_config(dynamics, derivative_method="autodiff")
    Ae, Be = exact.linearize_tangent(xs, us)
    reference = AutoDiffPhi(dynamics.phi)
    errors, medians = [], []
    for t in range(len(us)):
        Ja = np.hstack(reference.jacobians(xs[t], us[t]))
        assert _rel(np.hstack([Ae[t], Be[t]]), Ja) < 1e-6, t
        J = np.hstack([A[t], B[t]])
        big = np.abs(Ja) > 1e-6 * np.abs(Ja).max()
        medians.append(np.median(np.abs(J - Ja)[big] / np.abs(Ja)[big]))
        errors.append(_rel(J, Ja))
    assert any(ARM_NODE in e for t in range(len(us)) for e in _edges(dynamics, xs[t], us[t]))
    assert np.median(errors) < 1e-2, errors
    assert sum(e < 3e-2 for e in errors) >= 12, errors
    assert max(medians) < 1e-4, medians


def test_seeded_autodiff_is_the_full_jacobian_times_the_seeds(hydro10):
    """AutoDiffXd seeded with colour groups gives J S exactly (state and force rows), and
    agrees with the groups' finite differences."""
    from drake_clutter.phi.colouring import group_autodiff, group_differences, group_seeds

    dynamics, xs, us = hydro10
    t = 6  # the arm pushes box_06
    layout, phi = dynamics.layout, dynamics.phi
    autodiff = AutoDiffPhi(phi)
    full = autodiff.directional(xs[t], us[t], np.eye(layout.ndx + 8))
    groups = [[0, 9, layout.ndx + 2], [3, layout.ndx + 7], [12]]
    D = group_autodiff(autodiff, xs[t], us[t], groups)
    np.testing.assert_allclose(D, (full @ group_seeds(layout, groups)).T, rtol=1e-9,
                               atol=1e-9 * np.abs(full).max())
    nominal = phi.step_forces(xs[t], us[t])
    fd = group_differences(phi, xs[t], us[t], nominal, groups, 1e-6, "forward")
    assert _rel(fd, D) < 2e-2, _rel(fd, D)  # FD's own error in this push (see above)
    assert np.any(D[:, layout.ndx:] != 0)  # the pushed box's and the arm's contact forces


def test_autodiff_linearization_equals_dense_autodiff(hydro10):
    """derivative_method 'autodiff': coloured, known-block-reusing AutoDiffXd Jacobians equal
    the dense AutoDiffXd ones; the worker pool gives the same bits; 'hybrid' uses AutoDiffXd
    only at knots with many groups (here: the arm and two boxes, 40 groups)."""
    dynamics, xs, us = hydro10
    exact = _with_config(dynamics, derivative_method="autodiff")
    A, B = exact.linearize_tangent(xs, us)
    assert exact.stats.autodiff_knots > 0 and exact.stats.evaluations == []
    reference = AutoDiffPhi(exact.phi)
    for t in range(len(us)):
        Aa, Ba = reference.jacobians(xs[t], us[t])
        assert _rel(np.hstack([A[t], B[t]]), np.hstack([Aa, Ba])) < 1e-6, t
    with WorkerPool(2) as pool:
        parallel = PhiDynamics(exact.spec, pool=pool)
        Ap, Bp = parallel.linearize_tangent(xs, us)
    np.testing.assert_array_equal(A, Ap)
    np.testing.assert_array_equal(B, Bp)
    hybrid = _with_config(dynamics, derivative_method="hybrid", autodiff_min_groups=30)
    hybrid.linearize_tangent(xs, us)
    assert 0 < hybrid.stats.autodiff_knots < exact.stats.autodiff_knots


def test_a_failed_autodiff_knot_is_differenced_instead(hydro10, monkeypatch):
    """Where AutoDiffXd gives non-finite derivatives (Drake's SAP step can: NaN gradients with
    finite values, fig8) the knot's groups are finite-differenced: the same Jacobians as
    derivative_method 'fd', none zero or NaN, and the stats count the fallbacks."""
    dynamics, xs, us = hydro10
    reference = _with_config(dynamics, derivative_method="fd")
    A_fd, B_fd = reference.linearize_tangent(xs, us)
    exact = _with_config(dynamics, derivative_method="autodiff")

    def failing(self, x, u, S):
        return np.full((self.phi.layout.ndx + self.phi.num_forces, S.shape[1]), np.nan)

    monkeypatch.setattr(AutoDiffPhi, "directional", failing)
    A, B = exact.linearize_tangent(xs, us)
    assert exact.stats.autodiff_knots > 0
    assert exact.stats.autodiff_fallbacks == exact.stats.autodiff_knots
    assert exact.autodiff_fallbacks == exact.stats.autodiff_fallbacks
    assert np.all(np.isfinite(A)) and np.all(np.isfinite(B))
    np.testing.assert_array_equal(A, A_fd)
    np.testing.assert_array_equal(B, B_fd)


def test_autodiff_with_point_contact_is_a_config_error():
    from drake_clutter.common.config import ConfigError

    scene = generate_scene("bookshelf", 2, seed=0)
    config = DynamicsConfig(workers=0, contact_model="point", derivative_method="autodiff")
    with pytest.raises(ConfigError, match="derivative_method"):
        Phi(make_spec(scene, [], config=config))


@pytest.mark.parametrize("method", ["autodiff", "hybrid"])
def test_autodiff_with_hunt_crossley_contact_is_a_config_error(method):
    """Measured (10 boxes, the tests' reach): under world.contact_approximation "similar"
    seeded AutoDiffXd differed from the full AutoDiffXd Jacobian times the seeds by 106x
    (relative) and finite differences from AutoDiffXd by a median of 65x."""
    from drake_clutter.common.config import ConfigError, WorldConfig

    scene = generate_scene("bookshelf", 2, seed=0)
    spec = make_spec(scene, [], config=DynamicsConfig(workers=0, derivative_method=method),
                     world=WorldConfig(contact_approximation="similar"))
    with pytest.raises(ConfigError, match="dynamics.derivative_method.*similar"):
        PhiDynamics(spec)
    fd = make_spec(scene, [], config=DynamicsConfig(workers=0, derivative_method="fd"),
                   world=WorldConfig(contact_approximation="similar"))
    PhiDynamics(fd)  # finite differences are allowed


def test_autodiff_refuses_box_point_contact():
    scene = generate_scene("bookshelf", 2, seed=0)
    spec = make_spec(scene, [], config=DynamicsConfig(workers=0, contact_model="point"))
    with pytest.raises(ValueError, match="point"):
        AutoDiffPhi(Phi(spec))


# ----------------------------------------------------------------------------- contact forces


def test_contact_forces_and_their_jacobians_match_brute_force(point10):
    """f_t (one entry per node: arm, kept boxes) is zero where nothing touches, positive for
    the arm and the box it pushes, and its coloured Jacobian equals brute force's where brute
    force is reproducible (h and 2h agree to 1e-3, as above)."""
    dynamics, xs, us = point10
    f, Fx, Fu = dynamics.linearize_forces(xs, us)
    nf = 1 + dynamics.layout.num_boxes
    assert f.shape == (len(us), nf) and Fx.shape == (len(us), nf, dynamics.layout.ndx)
    assert Fu.shape == (len(us), nf, 8) and np.all(np.isfinite(f)) and np.all(f >= 0)
    edges = [_edges(dynamics, xs[t], us[t]) for t in range(len(us))]
    for t in range(len(us)):
        np.testing.assert_array_equal(f[t], dynamics.step_forces(xs[t], us[t]))
        touched = {n for e in edges[t] for n in e}
        assert np.all(f[t][[n for n in range(nf) if n not in touched]] == 0), t
    pushing = [t for t in range(1, len(us)) if any(ARM_NODE in e for e in edges[t])]
    assert sum(f[t][ARM_NODE] > 0 for t in pushing) >= len(pushing) // 2, pushing
    h, checked = dynamics.config.fd_step, []
    for t in pushing:
        dense = np.hstack(dense_jacobians(dynamics.phi, xs[t], us[t], h, forces=True)[2:])
        dense2 = np.hstack(dense_jacobians(dynamics.phi, xs[t], us[t], 2 * h, forces=True)[2:])
        if _rel(dense2, dense) > 1e-3:
            continue
        assert _rel(np.hstack([Fx[t], Fu[t]]), dense) < 2e-3, t
        checked.append(t)
    assert checked, pushing
