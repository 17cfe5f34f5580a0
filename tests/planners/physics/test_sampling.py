"""The sampling search around a candidate path: its family of paths, feasibility, the search."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drake_clutter.common.config import Config, ConfigError, load_config
from drake_clutter.planners.physics import pipeline
from drake_clutter.planners.physics.ensemble import (
    first_contact_knot,
    member_problems,
    score_in_members,
)
from drake_clutter.planners.physics.geometry import ArmGeometry
from drake_clutter.planners.physics.objective import max_steps
from drake_clutter.planners.physics.sampling import (
    PathOffset,
    bump,
    offset_path,
    sampling_search,
    speed_ok,
)


def _bounds():
    return tuple(np.array(b) for b in pipeline.control_bounds())


def test_bump_is_zero_with_zero_slope_at_both_ends():
    b = bump(31)
    assert b[0] == 0.0 and b[-1] == pytest.approx(0.0, abs=1e-30) and b[15] == pytest.approx(1)
    assert b[1] < 0.02 and b[-2] < 0.02  # zero slope: the first step is second order
    assert np.all(b >= 0) and np.all(b <= 1)
    late = bump(31, begin=10)
    assert np.all(late[:11] == 0.0) and late[20] == pytest.approx(1)
    assert late[11] < 0.03 and late[-2] < 0.03
    np.testing.assert_array_equal(bump(31, begin=0), b)


def test_an_offset_moves_the_tool_frame_as_asked_and_keeps_both_ends(scene, baseline_path):
    geometry = ArmGeometry(scene, "capsules")
    lo, hi = _bounds()
    q = baseline_path
    np.testing.assert_array_equal(offset_path(geometry, q, PathOffset(), lo, hi), q)
    moved = offset_path(geometry, q, PathOffset(lateral=0.02, height=-0.01, opening=0.01),
                        lo, hi)
    np.testing.assert_array_equal(moved[0], q[0])
    np.testing.assert_array_equal(moved[-1], q[-1])  # the pre-grasp pose and opening
    mid = len(q) // 2
    b = bump(len(q))[mid]
    shift = geometry.tool(moved[mid])[0] - geometry.tool(q[mid])[0]
    np.testing.assert_allclose(shift, b * np.array([0.0, 0.02, -0.01]), atol=2e-3)
    assert moved[mid, 7] == pytest.approx(min(q[mid, 7] + b * 0.01, hi[7]))
    z_before = geometry.tool_axis(q[mid], 0)[0]
    turned = offset_path(geometry, q, PathOffset(yaw=0.1), lo, hi)
    z_after = geometry.tool_axis(turned[mid], 0)[0]
    angle = np.arctan2(z_after[1], z_after[0]) - np.arctan2(z_before[1], z_before[0])
    assert angle == pytest.approx(0.1 * b, abs=0.01)


def test_speed_ok_allows_the_start_path_own_speed_and_the_limit():
    start = np.zeros((4, 8))
    start[2, 0] = 0.3  # the start itself jumps 0.3 rad
    steps = np.full(8, 0.1)
    assert speed_ok(start, start, steps)
    faster = start.copy()
    faster[2, 0] = 0.35
    assert not speed_ok(faster, start, steps)
    slow = start.copy()
    slow[1, 3] = 0.1
    assert speed_ok(slow, start, steps)


def test_the_search_never_returns_a_worse_path_and_keeps_the_ends(scene, baseline_path):
    config = load_config(None, ["physics.search_rounds=1", "physics.search_samples=3",
                                "physics.search_rebuilds=0"])
    lo, hi = _bounds()
    steps = max_steps(config.physics, config.baseline.knot_time)
    found = sampling_search(scene, baseline_path, config, lo, hi, steps)
    assert found.score <= found.start_score and np.isfinite(found.start_score)
    np.testing.assert_array_equal(found.q[0], baseline_path[0])
    np.testing.assert_array_equal(found.q[-1], baseline_path[-1])
    assert found.rounds[0]["drawn"] == 3 and 0 <= found.rounds[0]["kept"] <= 3
    again = sampling_search(scene, baseline_path, config, lo, hi, steps)
    np.testing.assert_array_equal(again.q, found.q)  # seeded: same search, same path
    assert again.score == found.score
    other = baseline_path.copy()
    other[1:-1, 1] += 0.05  # the shoulder lifted: another start
    centred = sampling_search(scene, other, config, lo, hi, steps, alternatives=(baseline_path,))
    starts = {"a": other, "b": baseline_path}
    margin = config.physics.search_prune_margin  # the search's phi: one for all its paths
    with member_problems(scene, starts, config, extra_margin=margin) as problems:
        scores, _, _ = score_in_members(problems, starts, config)
    assert centred.start_score == pytest.approx(min(scores.values()))  # the better start
    assert centred.score <= centred.start_score


def test_the_offsets_begin_before_the_first_contact_and_spare_the_knots_before(
        scene, baseline_path):
    """Every sample keeps the start's knots up to ``begin``, which lies ``search_lead_knots``
    before the arm first touches a box; the reference search (a phi per round) offsets from
    knot 0; both record what they scored."""
    config = load_config(None, ["physics.search_rounds=1", "physics.search_samples=2"])
    lo, hi = _bounds()
    steps = max_steps(config.physics, config.baseline.knot_time)
    found = sampling_search(scene, baseline_path, config, lo, hi, steps)
    with member_problems(scene, {"q": baseline_path}, config,
                         extra_margin=config.physics.search_prune_margin) as (problem,):
        contact = first_contact_knot(problem, baseline_path)
    assert contact is not None
    assert found.begin == max(0, contact + 1 - config.physics.search_lead_knots) > 0
    np.testing.assert_array_equal(found.q[:found.begin + 1], baseline_path[:found.begin + 1])
    np.testing.assert_array_equal(found.centre, baseline_path)
    assert found.rounds[0]["reached_frozen"] <= found.rounds[0]["kept"]
    assert found.score <= found.start_score
    reference = replace(config, physics=replace(config.physics, search_shared_phi=False))
    ref = sampling_search(scene, baseline_path, reference, lo, hi, steps)
    assert ref.begin == 0 and ref.score <= ref.start_score


def test_an_unknown_search_is_a_config_error():
    with pytest.raises(ConfigError, match="physics.search"):
        load_config(None, ["physics.search=beam"])
    assert replace(Config().physics, search="sampling").search == "sampling"


def test_the_pipeline_searches_and_offers_the_found_path_to_the_selection(scene):
    """physics.search=sampling on fig5 (no phi iLQR stages, to stay quick): the search runs
    after the pre-processing, its record says how many paths it scored, and its path is one
    of the selection's candidates, chosen only if no other scores lower."""
    from drake_clutter.planners.baseline import plan_baseline
    from drake_clutter.planners.physics.pipeline import plan_physics

    config = load_config(None, ["physics.search=sampling", "physics.search_rounds=1",
                                "physics.search_samples=2", "physics.iterations=0",
                                "physics.sphere_iterations=0",
                                "physics.pre_iterations=2", "physics.post_iterations=2"])
    candidates = plan_baseline(scene, config.baseline, alphas=[0.3])
    (plan,) = plan_physics(scene, config, candidates)
    assert plan.ok, plan.reason
    search = plan.details["search"]
    assert search["score"] <= search["start_score"]
    assert search["rounds"][0]["drawn"] == 2
    select = plan.details["select"]
    assert set(select["objectives"]) == {"post", "pre", "baseline", "search"}
    finite = {n: v for n, v in select["objectives"].items() if v is not None}
    assert select["chosen"] == min(finite, key=finite.get)
    assert "search" in plan.timings
