"""planners.loop: the one outer loop of the planners that refine the baseline's candidates, and
the angle index a candidate carries."""

from dataclasses import replace

import pytest

from drake_clutter.common.config import Config, ConfigError, load_config
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.loop import refine_each
from drake_clutter.planners.registry import run_planners
from drake_clutter.scene.scenes import load_shipped_scene
from drake_clutter.trajectory import Candidate


@pytest.fixture(scope="module")
def scene():
    return load_shipped_scene("fig6_push_sideways")


def test_each_candidate_is_refined_in_one_context_with_its_angle_index(scene):
    config = load_config(None, ["dynamics.workers=0"])
    alphas = approach_angles(config.baseline)
    start = [Candidate(float(alphas[4]), "ik_failed", index=4),
             Candidate(float(alphas[9]) + 1e-3, "ik_failed")]  # hand-made: the nearest angle
    calls = []

    def refine(context, candidate, index, pool, started):
        calls.append((context, index, pool, started))
        return Candidate(candidate.alpha, candidate.status, planner="test")

    out = refine_each(scene, config, start, refine)
    assert [c.index for c in out] == [4, 9] and [c[1] for c in calls] == [4, 9]
    assert calls[0][0] is calls[1][0] and calls[0][0].scene is scene  # one context
    assert calls[0][2] is None  # no workers asked for: no pool
    assert calls[0][3] is not None and calls[1][3] is None  # the first pays for the worlds


def test_a_nonsensical_configuration_is_refused_before_anything_runs(scene):
    config = load_config(None, ["dynamics.workers=0"])
    bad = replace(config, physics=replace(config.physics, hull_substeps=0))
    with pytest.raises(ConfigError):
        refine_each(scene, bad, [Candidate(0.0, "ik_failed")],
                    lambda *a: pytest.fail("refined a candidate under a bad configuration"))


def test_the_baseline_candidates_carry_their_angle_index(scene):
    config = Config()
    plans = run_planners(scene, config, ["baseline"], angles=[3, 10])
    assert [c.index for c in plans["baseline"]] == [3, 10]
    assert "index" not in plans["baseline"][0].to_data()  # a stored row has its angle


def test_a_context_under_other_settings_shares_the_worlds(scene):
    context = PlanningContext(scene, Config())
    arm, clearance = context.arm(), context.clearance
    other = context.with_config(load_config(None, ["push_search.rounds=1"]))
    assert other.arm() is arm and other.config.push_search.rounds == 1
    assert other.clearance is clearance and other.config is not context.config
    moved = context.with_config(load_config(None, ["baseline.num_angles=5"]))
    assert moved.arm() is arm and moved._baselines is not context._baselines
