"""Runs scenarios in the engines and compares them: agreement of the boxes' classes with the
reference engine (MuJoCo at its defaults), quasi-static mechanics' misses, thrown boxes,
squeeze forces and the time per case.

Engines: "phi" (phi's own model under the given configuration: its Drake world, or with
``dynamics.engine: mujoco`` the MuJoCo phi's model), "bullet" (the judge's engine
settings), "mujoco_default" and "mujoco_stiff" (`mujoco_engine.SETTINGS`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.conformance import bullet_engine, drake_engine
from drake_clutter.conformance.outcomes import BoxOutcome, Trace, box_outcomes, realised_friction
from drake_clutter.conformance.scenarios import FAMILIES, Scenario

ENGINES: tuple[str, ...] = ("phi", "bullet", "mujoco_default", "mujoco_stiff")
REFERENCE = "mujoco_default"
FAR_FROM_THRESHOLD = 0.15  # relative distance of a single push's tip ratio from 1


class MissingMujoco(ImportError):
    """The reference engine is not installed."""


def mujoco_engine():
    """The MuJoCo engine module; MissingMujoco (naming the package) without MuJoCo installed."""
    try:
        from drake_clutter.conformance import mujoco_engine as engine
    except ImportError as error:
        raise MissingMujoco("the contact suite's reference engine needs MuJoCo: "
                            "pip install mujoco (it is in the dev extras)") from error
    return engine


def simulate(engine: str, scenario: Scenario, config: Config) -> Trace:
    """One engine's run of a scenario (a simulation failure is recorded in the trace)."""
    if engine == "phi" and config.dynamics.engine == "mujoco":
        try:
            from drake_clutter.conformance import mujoco_phi_engine
        except ImportError as error:
            raise MissingMujoco("dynamics.engine 'mujoco' needs MuJoCo: pip install mujoco "
                                "(it is in the dev extras)") from error
        return mujoco_phi_engine.simulate(scenario, config)
    if engine == "phi":
        return drake_engine.simulate(scenario, config)
    if engine == "bullet":
        return bullet_engine.simulate(scenario, config)
    if engine.startswith("mujoco_"):
        return mujoco_engine().simulate(scenario, engine.removeprefix("mujoco_"))
    raise ValueError(f"unknown engine {engine!r} ({', '.join(ENGINES)})")


@dataclass
class CaseResult:
    """A scenario's traces and box outcomes per engine, and the jam reading's threshold (m,
    ``phi_judge.jam_depth``)."""

    scenario: Scenario
    traces: dict[str, Trace]
    outcomes: dict[str, list[BoxOutcome]]
    jam_depth: float = float("inf")

    def kinds(self, engine: str) -> tuple[str, ...]:
        """The boxes' classes in an engine's run."""
        return tuple(o.kind for o in self.outcomes[engine])

    def agrees(self, engine: str, reference: str = REFERENCE) -> bool:
        """Every box ends in the same class as in the reference engine."""
        return self.kinds(engine) == self.kinds(reference)

    def jams(self) -> bool:
        """phi's jam measure reads a jam on some box (``phi_judge.jam_depth``)."""
        return "phi" in self.outcomes and any(o.jam >= self.jam_depth
                                              for o in self.outcomes["phi"])

    def thrown(self, engine: str) -> bool:
        """Some box fell off the board or moved more than 0.5 m."""
        return any(o.thrown for o in self.outcomes[engine])


def run_cases(scenarios: Sequence[Scenario], config: Config, engines: Sequence[str] = ENGINES,
              progress: Callable[[], None] | None = None) -> list[CaseResult]:
    """Every scenario in every engine (``progress`` is called after each scenario)."""
    results = []
    for scenario in scenarios:
        traces = {engine: simulate(engine, scenario, config) for engine in engines}
        outcomes = {engine: box_outcomes(scenario, trace, config.evaluation.max_tilt,
                                         config.evaluation.force_window)
                    for engine, trace in traces.items()}
        results.append(CaseResult(scenario, traces, outcomes, config.phi_judge.jam_depth))
        if progress is not None:
            progress()
    return results


def _family_summary(results: list[CaseResult], engines: Sequence[str]) -> dict:
    summary: dict = {"cases": len(results)}
    compared = [e for e in engines if e != REFERENCE] if REFERENCE in engines else []
    for engine in engines:
        if engine in compared:
            summary[f"{engine}_agrees_with_mujoco"] = sum(r.agrees(engine) for r in results)
        summary[f"{engine}_thrown"] = sum(r.thrown(engine) for r in results)
        summary[f"{engine}_failed"] = sum(bool(r.traces[engine].failure) for r in results)
    if "phi" in engines:
        summary["phi_jams"] = sum(r.jams() for r in results)
    if results and results[0].scenario.family == "single":
        summary |= _mechanics_summary(results, engines, compared)
    return summary


def _mechanics_summary(results: list[CaseResult], engines: Sequence[str],
                       compared: Sequence[str]) -> dict:
    """Single pushes against quasi-static mechanics, and the agreement far from its threshold."""
    slides = [r for r in results if r.scenario.prediction == "slides"]
    tips = [r for r in results if r.scenario.prediction == "tips"]
    far = [r for r in results if abs(r.scenario.ratio - 1.0) > FAR_FROM_THRESHOLD]
    summary: dict = {"mechanics_slides": len(slides), "far_from_threshold": len(far)}
    for engine in engines:
        summary[f"{engine}_tips_where_mechanics_slides"] = sum(
            r.kinds(engine) != ("upright",) for r in slides)
        summary[f"{engine}_slides_where_mechanics_tips"] = sum(
            r.kinds(engine) == ("upright",) for r in tips)
    for engine in compared:
        summary[f"{engine}_agrees_with_mujoco_far_from_threshold"] = sum(
            r.agrees(engine) for r in far)
    return summary


def _squeeze_rows(results: list[CaseResult], engines: Sequence[str]) -> list[dict]:
    rows = [{"depth_mm": r.scenario.parameters["depth"] * 1000,
             **{f"{engine}_force_N": r.outcomes[engine][0].squeeze for engine in engines}}
            for r in results]
    if "phi" in engines:
        for row, r in zip(rows, results, strict=True):
            row |= {"phi_jam_mm": r.outcomes["phi"][0].jam * 1000, "phi_reads_jam": r.jams()}
    return rows


def _drag_rows(results: list[CaseResult], engines: Sequence[str]) -> list[dict]:
    return [{"speed": r.scenario.parameters["speed"],
             "pair": r.scenario.parameters["board_friction"],
             **{f"{engine}_realised": realised_friction(r.scenario, r.traces[engine])
                for engine in engines},
             **{f"{engine}_rise_m": r.outcomes[engine][0].rise for engine in engines}}
            for r in results]


def summarise(results: list[CaseResult], engines: Sequence[str] = ENGINES) -> dict:
    """The suite's summary: per family the agreement counts (classes equal to MuJoCo's),
    thrown boxes and failures; single pushes also against mechanics; squeezes and drags as
    rows; seconds per case per engine."""
    by_family = {f: [r for r in results if r.scenario.family == f] for f in FAMILIES}
    summary: dict = {}
    for family, rows in by_family.items():
        if not rows:
            continue
        if family == "squeeze":
            summary[family] = _squeeze_rows(rows, engines)
        elif family == "drag":
            summary[family] = _drag_rows(rows, engines)
        else:
            summary[family] = _family_summary(rows, engines)
    summary["seconds_per_case"] = {e: float(np.mean([r.traces[e].seconds for r in results]))
                                   for e in engines}
    return summary


def case_rows(results: list[CaseResult], engines: Sequence[str] = ENGINES) -> list[dict]:
    """One row per scenario: its family, name, prediction, tip ratio, and per engine the boxes'
    classes, the first box's displacement and tilt, thrown, and the run's failure."""
    rows = []
    for r in results:
        row = {"family": r.scenario.family, "name": r.scenario.name,
               "prediction": r.scenario.prediction, "ratio": r.scenario.ratio}
        for e in engines:
            first = r.outcomes[e][0]
            row |= {f"{e}_kinds": "/".join(r.kinds(e)), f"{e}_moved": first.moved,
                    f"{e}_tilt": first.tilt, f"{e}_thrown": r.thrown(e),
                    f"{e}_failure": r.traces[e].failure}
        rows.append(row)
    return rows
