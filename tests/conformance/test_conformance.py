"""The contact conformance suite (drake_clutter/conformance, benchmarks/bench_contact.py): the
scripted scenarios, the friction each engine realises, and phi against MuJoCo and mechanics."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drake_clutter.common.config import Config, load_config
from drake_clutter.conformance import scenarios as sc
from drake_clutter.conformance.friction import (
    UnrealisableFriction,
    bullet_coefficients,
    drake_coefficients,
)
from drake_clutter.conformance.outcomes import box_outcomes, realised_friction
from drake_clutter.conformance.suite import run_cases, simulate, summarise
from drake_clutter.planners.phi_judge import judge_dynamics
from drake_clutter.scene.mechanics import tip_ratio
from drake_clutter.scene.shelf import SHELF_LINK

REPO = Path(__file__).resolve().parents[2]
BENCH = REPO / "benchmarks" / "bench_contact.py"
EDGES = ("dynamics.contact_model=edges",)  # phi's default: the boxes stand on edge spheres
HYDROELASTIC = ("dynamics.contact_model=hydroelastic",)  # phi's default until 2026-11-27


def _config(*overrides) -> Config:
    return load_config(None, list(overrides))


def _single(**parameters) -> sc.Scenario:
    """The default grid's single push with these parameters."""
    found = [s for s in sc.single_scenarios()
             if all(s.parameters[k] == v for k, v in parameters.items())]
    assert len(found) == 1, parameters
    return found[0]


# ----------------------------------------------------------------------------- scenarios


def test_the_default_families_have_the_documented_cases():
    single = sc.single_scenarios()
    assert len(single) == 112  # 4 lengths x 3 heights x 3 push heights x 2 masses x 2 frictions
    # less the 8 x 4 where the capsule (radius 4 cm) would touch the board
    assert all(s.pusher.start[2] - sc.BOARD_TOP - s.pusher.radius >= sc.BOARD_CLEARANCE
               for s in single)
    assert {len(sc.chain_scenarios()), len(sc.edge_scenarios()), len(sc.squeeze_scenarios()),
            len(sc.topple_scenarios())} == {16, 12, 3, 1}
    assert sum(s.prediction == "slides" for s in single) == 60


def test_the_tip_ratio_is_quasi_static_mechanics():
    """mu_b z > (w / 2)(1 + mu_b mu_p): the issue's example, an 8 x 6 x 22 cm box pushed at
    mid-height on mu_b 0.3 with mu_p 0.5, is 28 % below the threshold."""
    case = _single(length=0.08, height=0.22, push_height=0.5, mass=0.2, board_friction=0.3)
    assert case.ratio == pytest.approx(0.3 * 0.11 / (0.04 * 1.15))
    assert case.ratio == pytest.approx(0.717, abs=1e-3) and case.prediction == "slides"
    assert tip_ratio(0.1, 0.05 * 1.15 / 0.3, 0.3, 0.5) == pytest.approx(1.0)


def test_the_pusher_ramps_up_cruises_and_stops_where_told():
    p = sc.Pusher(0.04, 0.12, (0.0, 0.0, 0.8), travel=0.101, speed=0.08, ramp=0.5)
    times = np.linspace(-0.1, p.push_time + 0.5, 400)
    x = np.array([p.x_at(t) for t in times])
    assert x[0] == 0.0 and x[-1] == pytest.approx(0.101)
    assert np.all(np.diff(x) >= -1e-15)
    speeds = np.diff(x) / np.diff(times)
    assert speeds.max() == pytest.approx(0.08, rel=1e-2)
    assert p.speed_at(0.25) == pytest.approx(0.04) and p.speed_at(1.0) == 0.08
    assert p.speed_at(p.push_time) == 0.0


@pytest.mark.parametrize("travel", [0.002, 0.006, 0.04])
def test_a_short_push_never_passes_its_end(travel):
    """A squeeze's 2-6 mm travel is shorter than the ramps (8 cm/s x 0.5 s): the capsule
    ramps over travel / speed instead, never beyond its end and never backwards."""
    p = sc.Pusher(0.04, 0.12, (0.0, 0.0, 0.8), travel=travel, speed=0.08, ramp=0.5)
    times = np.linspace(0.0, p.push_time + 0.1, 2001)
    x = np.array([p.x_at(t) for t in times])
    assert np.all(np.diff(x) >= -1e-15) and x.max() == pytest.approx(travel)
    speeds = np.array([p.speed_at(t) for t in times[:-1]])
    np.testing.assert_allclose(np.diff(x) / np.diff(times), speeds, atol=0.08 * 0.02)


# ----------------------------------------------------------------------------- friction


@pytest.mark.parametrize("scenario", sc.default_scenarios(), ids=lambda s: s.name)
def test_every_pair_is_realised_by_drakes_and_bullets_rules(scenario):
    drake, bullet = drake_coefficients(scenario), bullet_coefficients(scenario)
    for a, b, mu in scenario.friction:
        assert 2 * drake[a] * drake[b] / (drake[a] + drake[b]) == pytest.approx(mu, rel=1e-6)
        assert bullet[a] * bullet[b] == pytest.approx(mu, rel=1e-6)
        assert drake[a] > 0 and drake[b] > 0


def test_pairs_no_positive_drake_coefficients_give_are_refused():
    """Two boxes gripping the board (1.9) but sliding on each other (0.1): Drake's harmonic
    rule needs 1/a + 1/b = 2/1.9 for both box-board pairs and 2/0.1 between the boxes."""
    base = sc.chain_scenarios()[0]
    scenario = dataclasses.replace(base, friction=(
        ("board", "box_a", 1.9), ("board", "box_b", 1.9), ("box_a", "box_b", 0.1),
        ("pusher", "box_a", 0.5), ("pusher", "box_b", 0.5)))
    with pytest.raises(UnrealisableFriction, match="Drake cannot realise"):
        drake_coefficients(scenario)
    bullet_coefficients(scenario)  # products can


@pytest.mark.parametrize("engine", ["bullet", "mujoco_default", "phi"])
def test_a_drag_realises_the_pair_friction(engine):
    """A cube launched at 1 m/s on pair 0.3 decelerates at 0.3 g in every engine (phi within
    5 %: measured 0.313 on edge spheres, 0.306 on hydroelastic boxes, where SAP lifts a fast
    slider a few mm)."""
    drag = next(s for s in sc.drag_scenarios() if s.parameters == {"speed": 1.0,
                                                                   "board_friction": 0.3})
    mu = realised_friction(drag, simulate(engine, drag, Config()))
    assert mu == pytest.approx(0.3, rel=0.05 if engine == "phi" else 0.01)


# ----------------------------------------------------------------------------- phi's world


@pytest.mark.parametrize("overrides, spheres", [(HYDROELASTIC, 0), ((), 9)])
def test_the_suite_steps_phis_own_world(overrides, spheres):
    """The Drake engine builds the world phi builds: same step, approximation, contact model,
    box geometry (a compliant Box; with "edges", phi's default, also spheres on its edges)
    and board (with "edges" a collision box ``edge_board_depth`` deep)."""
    from pydrake.geometry import Role

    from drake_clutter.conformance.drake_engine import build_world
    from drake_clutter.phi.dynamics import Phi, make_spec
    from drake_clutter.scene.generators import generate_scene

    config = _config(*overrides)
    scenario = _single(length=0.08, height=0.16, push_height=0.5, mass=0.2, board_friction=0.3)
    ours = build_world(scenario, config)
    scene = generate_scene("bookshelf", 1, seed=0)
    phi = Phi(make_spec(scene, [scene.boxes[0].name], config=config.dynamics,
                        world=config.world))
    for world in (ours, phi.world):
        assert world.plant.time_step() == pytest.approx(
            config.baseline.knot_time / config.dynamics.substeps)
    assert (ours.plant.get_discrete_contact_approximation()
            == phi.plant.get_discrete_contact_approximation())
    assert ours.plant.get_contact_model() == phi.plant.get_contact_model()
    for world, box in ((ours, "box"), (phi.world, scene.boxes[0].name)):
        inspector = world.scene_graph.model_inspector()
        geometries = world.plant.GetCollisionGeometriesForBody(world.box_body(box))
        names = [inspector.GetName(g) for g in geometries]
        assert sum(n.endswith("_collision") for n in names) == 1
        assert (sum("_corner" in n for n in names) >= spheres) and (spheres or len(names) == 1)
        box_geometry = next(g for g, n in zip(geometries, names, strict=True)
                            if n.endswith("_collision"))
        assert inspector.GetProperties(box_geometry, Role.kProximity).HasProperty(
            "hydroelastic", "compliance_type")
    depth = config.dynamics.edge_board_depth if spheres else scene.shelf.thickness
    for world in (ours, phi.world):
        inspector = world.scene_graph.model_inspector()
        (board,) = [g for g in world.plant.GetCollisionGeometriesForBody(world.plant.GetBodyByName(
            SHELF_LINK)) if inspector.GetName(g).endswith("board")]
        assert inspector.GetShape(board).height() == pytest.approx(depth)


# ----------------------------------------------------------------------------- phi vs physics


@pytest.mark.parametrize("parameters, prediction", [
    ({"length": 0.05, "height": 0.22, "push_height": 0.25, "mass": 1.0, "board_friction": 0.3},
     "slides"),  # ratio 0.57
    ({"length": 0.08, "height": 0.22, "push_height": 0.5, "mass": 0.2, "board_friction": 0.3},
     "slides"),  # 0.72, the example: the hydroelastic phi threw it 1.8 m
    ({"length": 0.03, "height": 0.16, "push_height": 0.75, "mass": 0.2, "board_friction": 0.6},
     "tips"),  # 3.7
])
def test_a_push_far_from_the_threshold_ends_as_mechanics_says_in_every_engine(parameters,
                                                                             prediction):
    """Bullet, MuJoCo and phi on edge spheres (the hydroelastic phi tips both slides: see the
    suite's test below)."""
    scenario = _single(**parameters)
    expected = "upright" if prediction == "slides" else "tipped"
    config = _config(*EDGES)
    for engine in ("phi", "bullet", "mujoco_default"):
        (outcome,) = box_outcomes(scenario, simulate(engine, scenario, config),
                                  config.evaluation.max_tilt, config.evaluation.force_window)
        assert outcome.kind == expected, (engine, outcome)
        assert not outcome.thrown, (engine, outcome)


def _suite_summary(config: Config) -> dict:
    families = ("single", "chain", "edge", "topple", "squeeze")
    results = run_cases(sc.default_scenarios(families=families), config,
                        ("phi", "mujoco_default"))
    return summarise(results, ("phi", "mujoco_default"))


def _passes(summary: dict) -> None:
    """The suite's targets: single pushes at least 108 / 112 agree with MuJoCo, none thrown,
    every case more than 15 % from the tipping threshold agrees; chains 15 / 16; edges 12 / 12;
    the thin box lands."""
    single = summary["single"]
    assert single["phi_agrees_with_mujoco"] >= 108, single
    assert single["phi_thrown"] == 0 and single["phi_failed"] == 0, single
    assert single["phi_agrees_with_mujoco_far_from_threshold"] == single["far_from_threshold"]
    assert summary["chain"]["phi_agrees_with_mujoco"] >= 15, summary["chain"]
    assert summary["edge"]["phi_agrees_with_mujoco"] == 12, summary["edge"]
    assert summary["topple"]["phi_agrees_with_mujoco"] == 1 and summary["topple"]["phi_thrown"] == 0


def _reads_jams(summary: dict) -> None:
    """phi's jam measure: every squeeze a jam; no chain, edge or topple; of the single pushes
    only the two where the tipped box ends under the capsule (measured 2026-11-27, 6.5 and
    6.7 mm; MuJoCo stiff presses them into the board with 316 and 1579 N on the way)."""
    assert all(row["phi_reads_jam"] for row in summary["squeeze"]), summary["squeeze"]
    assert summary["chain"]["phi_jams"] == summary["edge"]["phi_jams"] == 0
    assert summary["topple"]["phi_jams"] == 0 and summary["single"]["phi_jams"] == 2


def test_phi_as_configured_passes_the_conformance_suite():
    """The default phi (boxes on edge spheres) against MuJoCo (its defaults); measured
    2026-11-27: 109 / 112, 94 / 94 far from the threshold, none thrown, chains 16, edges 12,
    the thin box lands."""
    summary = _suite_summary(Config())
    _passes(summary)
    _reads_jams(summary)


def test_the_mujoco_phi_passes_the_conformance_suite_at_the_reference_level():
    """The MuJoCo phi (``dynamics.engine: mujoco``: its own model and stepping, the suite's
    capsule as its actor) ends every box in the reference's class: single pushes 112 / 112,
    chains 16 / 16, edges 12 / 12, the thin box lands, none thrown; every squeeze reads as a
    jam and nothing else does (measured 2026-11-27: squeezes 1.36, 2.57, 5.15 mm)."""
    summary = _suite_summary(_config("dynamics.engine=mujoco"))
    single = summary["single"]
    assert single["phi_agrees_with_mujoco"] == single["cases"] == 112, single
    assert single["phi_thrown"] == 0 and single["phi_failed"] == 0, single
    assert summary["chain"]["phi_agrees_with_mujoco"] == summary["chain"]["cases"] == 16
    assert summary["edge"]["phi_agrees_with_mujoco"] == 12, summary["edge"]
    assert summary["topple"]["phi_agrees_with_mujoco"] == 1 and summary["topple"]["phi_thrown"] == 0
    assert all(row["phi_reads_jam"] for row in summary["squeeze"]), summary["squeeze"]
    assert sum(summary[f]["phi_jams"] for f in ("single", "chain", "edge", "topple")) == 0


def test_the_judges_mujoco_phi_passes_the_conformance_suite_at_the_reference_level():
    """The MuJoCo phi at the judge in phi's settings (`phi_judge.judge_dynamics`: 4 ms steps
    read every 20 ms, resting boxes asleep; the suite steps one kept world, as the judge does)
    passes as the MuJoCo phi does: every box in the reference's class, none thrown, every
    squeeze a jam and nothing else (measured 2026-12-07: squeezes 1.36, 2.57, 5.15 mm, as at
    2 ms)."""
    config = Config()
    summary = _suite_summary(dataclasses.replace(config, dynamics=judge_dynamics(config)))
    for family, cases in (("single", 112), ("chain", 16), ("edge", 12), ("topple", 1)):
        assert summary[family]["phi_agrees_with_mujoco"] == cases, summary[family]
        assert summary[family]["phi_thrown"] == 0 and summary[family]["phi_jams"] == 0
    assert all(row["phi_reads_jam"] for row in summary["squeeze"]), summary["squeeze"]


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="phi's fidelity: the hydroelastic box-board contact tips "
                   "boxes that slide (20 of 60) and SAP's lift throws toppled ones (25)")
def test_phi_on_hydroelastic_boxes_passes_the_conformance_suite():
    """phi on hydroelastic boxes (its default until 2026-11-27), measured 2026-11-27: 71 / 112,
    63 / 94 far from the threshold, 25 thrown, chains 12, edges 12, the thin box thrown."""
    _passes(_suite_summary(_config(*HYDROELASTIC)))


def test_hard_contact_reads_a_squeeze_as_a_jam():
    """A 1 mm squeeze against the wall: Bullet (the judge) and MuJoCo press the wall beyond
    the judge's 50 N kinematic-failure force."""
    scenario = sc.squeeze_scenarios()[0]
    config = Config()
    for engine in ("bullet", "mujoco_default"):
        (outcome,) = box_outcomes(scenario, simulate(engine, scenario, config),
                                  config.evaluation.max_tilt, config.evaluation.force_window)
        assert outcome.squeeze > config.evaluation.max_static_force, (engine, outcome)


# ----------------------------------------------------------------------------- the benchmark


SMALL_GRID = """single:
  lengths: [0.05]
  widths: [0.06]
  heights: [0.22]
  push_heights: [0.25, 0.75]
  masses: [0.5]
  board_friction: [0.3]
  pusher_friction: 0.5
  pusher_radius: 0.04
  speed: 0.08
  distance: 0.05
"""


def _bench(*args, cwd=REPO):
    return subprocess.run([sys.executable, str(BENCH), *args], capture_output=True, text=True,
                          cwd=cwd, timeout=600)


def test_bench_contact_writes_its_summary_and_cases(tmp_path):
    grid = tmp_path / "grid.yaml"
    grid.write_text(SMALL_GRID)
    out, cases = tmp_path / "summary.json", tmp_path / "cases.json"
    run = _bench("--grid", str(grid), "--families", "single,squeeze", "--json", str(out),
                 "--cases", str(cases))
    assert run.returncode == 0, run.stderr
    summary = json.loads(out.read_text())
    single = summary["single"]
    for key in ("cases", "phi_agrees_with_mujoco", "bullet_agrees_with_mujoco", "phi_thrown",
                "phi_tips_where_mechanics_slides"):
        assert key in single, key
    assert single["cases"] == 2 and single["mechanics_slides"] == 1
    assert len(summary["squeeze"]) == 3 and "phi_force_N" in summary["squeeze"][0]
    assert len(json.loads(cases.read_text())) == 5
    assert "classes agree with MuJoCo" in run.stdout


@pytest.mark.parametrize("text, field", [
    (SMALL_GRID.replace("  speed: 0.08\n", ""), "single.speed"),
    (SMALL_GRID.replace("masses: [0.5]", "masses: [-0.5]"), "single.masses[0]"),
    (SMALL_GRID + "squeeze: {}\n", "squeeze"),
    (SMALL_GRID.replace("pusher_friction: 0.5", "pusher_friction: 5000"), "single_"),
    (SMALL_GRID.replace("lengths: [0.05]", "lengths: 0.05"), "single.lengths"),
])
def test_a_bad_grid_is_one_line_exit_2_and_nothing_written(tmp_path, text, field):
    grid = tmp_path / "grid.yaml"
    grid.write_text(text)
    out = tmp_path / "summary.json"
    run = _bench("--grid", str(grid), "--json", str(out))
    assert run.returncode == 2, run.stdout
    assert len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert str(grid) in run.stderr and field in run.stderr, run.stderr
    assert not out.exists()


def test_without_mujoco_the_benchmark_names_the_package(tmp_path):
    """The reference engine is optional for the library: without it the benchmark says what to
    install and exits 2 (MuJoCo hidden by a sitecustomize that blocks its import)."""
    blocker = tmp_path / "sitecustomize.py"
    blocker.write_text("import sys\nsys.modules['mujoco'] = None\n")
    out = tmp_path / "summary.json"
    env = {**__import__("os").environ, "PYTHONPATH": str(tmp_path)}
    run = subprocess.run([sys.executable, str(BENCH), "--families", "drag", "--json", str(out)],
                         capture_output=True, text=True, cwd=REPO, timeout=600, env=env)
    assert run.returncode == 2, run.stdout
    assert "pip install mujoco" in run.stderr and len(run.stderr.strip().splitlines()) == 1
    assert not out.exists()
