"""phi's ensemble: members' worlds, risk scores, and the members' rollouts on a shipped scene."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drake_clutter.common.config import Config, EnsembleConfig
from drake_clutter.phi.derivatives import arm_touches_box
from drake_clutter.planners.physics import pipeline
from drake_clutter.planners.physics.ensemble import (
    ensemble_scores,
    first_contact_knot,
    member_problems,
    member_rollouts,
    member_world,
    risk_score,
    score_in_members,
)
from drake_clutter.solvers import ilqr


@pytest.mark.parametrize("risk, extra, expected", [
    ("mean", {}, 4.0),
    ("mean_std", {"risk_weight": 1.0}, 4.0 + np.sqrt(12.5)),
    ("mean_std", {"risk_weight": 0.0}, 4.0),
    ("cvar", {"cvar_fraction": 0.5}, 6.5),
    ("cvar", {"cvar_fraction": 0.3}, 6.5),  # ceil(0.3 x 4) = 2 worst members
    ("cvar", {"cvar_fraction": 0.25}, 10.0),
    ("cvar", {"cvar_fraction": 1.0}, 4.0),
])
def test_risk_scores_known_answers(risk, extra, expected):
    ens = EnsembleConfig(risk=risk, **extra)
    assert risk_score([1.0, 2.0, 3.0, 10.0], ens) == pytest.approx(expected)
    assert risk_score([1.0, float("inf"), 3.0], ens) == float("inf")


def test_member_worlds_are_seeded_and_member_one_pairs_friction_as_bullet(scene):
    config = replace(Config(), ensemble=EnsembleConfig(members=3, seed=5))
    world0, config0 = member_world(scene, config, 0)
    assert world0 is scene and config0 is config
    world1, config1 = member_world(scene, config, 1)
    world2, config2 = member_world(scene, config, 2)
    assert config1.world.friction_as_bullet and not config2.world.friction_as_bullet
    assert world1 != scene and world2 != scene and world1 != world2
    assert member_world(scene, config, 2)[0] == world2  # same seed, same world
    other = replace(config, ensemble=replace(config.ensemble, seed=6))
    assert member_world(scene, other, 2)[0] != world2
    plain = replace(config, ensemble=replace(config.ensemble, bullet_friction_member=False))
    assert not member_world(scene, plain, 1)[1].world.friction_as_bullet


def test_member_zero_is_phi_and_members_meet_the_same_worlds(scene, baseline_path):
    """Member 0 prices a path exactly as the planner's own choice in phi does; a perturbed
    member ends with the boxes elsewhere; the ensemble's mean is the mean of its members."""
    config = replace(Config(), ensemble=EnsembleConfig(members=2))
    paths = {"baseline": baseline_path}
    nominal = member_rollouts(scene, paths, config, 0)["baseline"]
    _, info = pipeline.select_path(scene, paths, Config())  # one phi: members = 1
    assert sum(nominal.terms.values()) == pytest.approx(info["objectives"]["baseline"])
    perturbed = member_rollouts(scene, paths, config, 1)["baseline"]
    assert set(perturbed.final_boxes) == set(nominal.final_boxes)
    for state in nominal.final_boxes.values():
        assert state.shape == (13,) and np.all(np.isfinite(state))
        assert np.linalg.norm(state[:4]) == pytest.approx(1.0, abs=1e-6)
    assert any(np.linalg.norm(nominal.final_boxes[n][4:7] - perturbed.final_boxes[n][4:7])
               > 1e-4 for n in nominal.final_boxes)
    scores, totals = ensemble_scores(scene, paths, config)
    assert totals["baseline"][0] == pytest.approx(sum(nominal.terms.values()))
    assert totals["baseline"][1] == pytest.approx(sum(perturbed.terms.values()))
    assert scores["baseline"] == pytest.approx(np.mean(totals["baseline"]))
    _, info = pipeline.select_path(scene, paths, config)  # two members: ranked by the mean
    assert info["objectives"]["baseline"] == pytest.approx(scores["baseline"])
    assert info["members"]["baseline"] == pytest.approx(totals["baseline"])


def test_a_path_phi_cannot_roll_out_fails_alone(scene, baseline_path, monkeypatch):
    """Drake raising on one path's steps makes that path FAILED in the member; the other
    paths of the same call are still priced."""
    from drake_clutter.planners.physics import ensemble

    real = ensemble._rollout

    def raising(problem, q, jam=False):
        if q[-1, 0] != baseline_path[-1, 0]:
            raise RuntimeError("SAP failed to converge")
        return real(problem, q, jam)

    monkeypatch.setattr(ensemble, "_rollout", raising)
    moved = baseline_path.copy()
    moved[-1, 0] += 1e-3
    out = member_rollouts(scene, {"baseline": baseline_path, "moved": moved}, Config(), 0)
    assert out["moved"] == ensemble.FAILED
    assert out["baseline"].terms is not None and np.isfinite(sum(out["baseline"].terms.values()))
    assert out["baseline"].jam is None  # read only when asked for
    jammed = member_rollouts(scene, {"baseline": baseline_path, "moved": moved}, Config(), 0,
                             jam=True)
    assert jammed["moved"] == ensemble.FAILED and jammed["baseline"].jam >= 0.0
    assert jammed["baseline"].terms == out["baseline"].terms


def test_scores_in_shared_members_do_not_depend_on_what_was_scored_before(scene, baseline_path):
    """One phi per member for many paths (the search's): phi's step cache serves the steps
    paths share, so a path scores the same after others as in members built for it alone,
    and a path that reaches no frozen box says so."""
    config = replace(Config(), ensemble=EnsembleConfig(members=2))
    other = baseline_path.copy()
    other[12:-1, 0] += 0.02  # the same first 12 knots, then another way
    paths = {"baseline": baseline_path, "other": other}
    with member_problems(scene, paths, config, extra_margin=0.05) as problems:
        scores, totals, frozen = score_in_members(problems, paths, config)
        again, _, _ = score_in_members(problems, {"other": other}, config)
    with member_problems(scene, paths, config, extra_margin=0.05) as cold:
        alone, _, _ = score_in_members(cold, {"other": other}, config)
    assert np.isfinite(scores["other"]) and len(totals["other"]) == 2
    assert again["other"] == scores["other"] == alone["other"]  # bit for bit
    assert frozen == {"baseline": False, "other": False}


def test_first_contact_knot_is_where_the_arm_first_touches_a_box(scene, baseline_path):
    config = Config()
    paths = {"baseline": baseline_path}
    with member_problems(scene, paths, config) as (problem,):
        t = first_contact_knot(problem, baseline_path)
        still = np.tile(baseline_path[0], (len(baseline_path), 1))  # the arm never moves
        assert first_contact_knot(problem, still) is None
        assert first_contact_knot(None, baseline_path) is None
        zs = ilqr.rollout(problem.augmented, problem.z0, baseline_path[1:])
        nx = problem.dynamics.layout.nx
        touching = [arm_touches_box(problem.dynamics.edges(zs[k][:nx], baseline_path[k + 1]))
                    for k in range(len(baseline_path) - 1)]
    assert t is not None and touching[t] and not any(touching[:t])
