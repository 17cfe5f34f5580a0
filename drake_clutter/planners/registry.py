"""The planners every caller picks from: one `Planner` interface, one registry entry each.

A planner turns a scene and the configuration into one `Candidate` per approach angle (Sec. IV:
the angles of `approach.approach_angles`, in order). Some planners refine the candidates of
another (``starts_from``): the physics planner (Sec. V) optimises the baseline's (Sec. IV), and
the push planner searches from them. `run_planners` runs the planners asked for, each of their
starting planners once, and hands each its start.

Angles: ``angles=None`` plans every angle of ``config.baseline`` in a row (the baseline seeds
each angle's IK with its neighbour's solution); a list of indices plans each listed angle
alone, with that angle's own seeds and no neighbour, so that its result does not depend on
which other angles are planned (what an experiment's work unit does).

The modules behind the entries are imported when a planner runs, so that importing the
registry (the CLI, the experiment specs) stays cheap.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from importlib import import_module
from typing import Literal, Protocol

from drake_clutter.common.config import Config, check_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate

# the registry's keys, as typed YAML reads them
PlannerName = Literal["baseline", "physics", "push", "rearrange"]


class PlanRecord(Protocol):
    """A planner's typed reading of what it did at one angle (its candidates' ``details``)."""

    bent: bool  # the returned path is a bent member of a path family, not a straight line
    label: str  # the returned path in a few words (titles, tables)

    def histories(self) -> dict[str, dict]:
        """Per iLQR stage its cost and term histories (`viz.cost_curves`); {} without iLQR."""


class Planner(Protocol):
    """What a planner offers its callers; only the planner reads its candidates' ``details``."""

    name: str  # its registry key, the ``planner`` of its candidates and of stored rows
    starts_from: str | None  # the planner whose candidates it refines; None: from scratch
    paper_row: str | None  # the paper's rows it reproduces (report.PAPER_*); None: beyond it

    def check(self, config: Config, file: str = "<configuration>") -> None:
        """Raises ConfigError naming the first of its settings that makes no sense."""

    def plan(self, scene: Scene, config: Config, angles: Sequence[int] | None = None,
             start: list[Candidate] | None = None) -> list[Candidate]:
        """One Candidate per approach angle (all, or the listed indices), in order; ``start``:
        the ``starts_from`` planner's candidates of the same angles (planned here if None)."""

    def table(self, candidates: list[Candidate]) -> str:
        """A text table of its candidates, one row per angle."""

    def record(self, details: dict) -> PlanRecord:
        """Its typed record of a candidate's ``details`` (stored or fresh)."""

    def score(self, details: dict, config: Config | None = None) -> float | None:
        """The rank it gives a candidate with these ``details`` without the judge, lower
        first (``config``: its settings, default the defaults); None without a record."""

    def plan_seconds(self, timings: dict) -> float | None:
        """The planning seconds of one initialization from a stored row's ``timings``."""

    def report_section(self, plans: dict[str, list[dict]]) -> ReportSection | None:
        """Its own section of an experiment report on its stored plans (``plans``:
        configuration name -> the plans' ``details``); None when it has none."""


@dataclass(frozen=True)
class ReportSection:
    """A planner's own section of an experiment report: a CSV file's name and rows, and the
    Markdown lines of the section (none: nothing to say)."""

    csv_name: str
    table: list[dict]
    lines: list[str]


def _plan_seconds(timings: dict) -> float | None:
    """The seconds of the experiment's ``plan`` timing (planners that time one call)."""
    return float(timings["plan"]) if "plan" in timings else None


class BaselinePlanner:
    """Sec. IV: straight-line approach angles, IK, optimisation against the static shelf."""

    name = "baseline"
    starts_from = None
    paper_row = "paper: baseline"

    def check(self, config: Config, file: str = "<configuration>") -> None:
        """`config.check_config` (the baseline reads only ``config.baseline``)."""
        check_config(config, file)

    def plan(self, scene: Scene, config: Config, angles: Sequence[int] | None = None,
             start: list[Candidate] | None = None) -> list[Candidate]:
        """`baseline.plan_baseline` (all angles), or each listed angle planned alone."""
        from drake_clutter.planners import baseline
        from drake_clutter.planners.approach import approach_angles

        if angles is None:
            return baseline.plan_baseline(scene, config.baseline)
        check_config(config.baseline, section="baseline")
        alphas = approach_angles(config.baseline)
        return [baseline.plan_angle(baseline.prepare(scene, config.baseline),
                                    float(alphas[index]), index) for index in angles]

    def table(self, candidates: list[Candidate]) -> str:
        """`baseline.candidates_table`: IK / optimisation / check seconds and penetration."""
        from drake_clutter.planners.baseline import candidates_table

        return candidates_table(candidates)

    def record(self, details: dict):
        """`baseline.BaselineRecord`: the optimisation's costs, the dense check's depth."""
        from drake_clutter.planners.baseline import BaselineRecord

        return BaselineRecord.from_details(details)

    def score(self, details: dict, config: Config | None = None) -> float | None:
        """Sec. IV's kinematic cost at the end of the optimisation (`BaselineRecord.score`
        with ``config.baseline``'s weights)."""
        return self.record(details).score(None if config is None else config.baseline)

    def plan_seconds(self, timings: dict) -> float | None:
        """The experiment's ``plan`` timing (s)."""
        return _plan_seconds(timings)

    def report_section(self, plans: dict[str, list[dict]]) -> ReportSection | None:
        """None: the baseline's plans are read in the common tables."""
        return None


class _FromBaseline:
    """A planner that refines the baseline's candidates: its module's ``plan(scene, config,
    start)`` and ``table(candidates)`` functions, imported when first used."""

    starts_from = "baseline"
    paper_row: str | None = None
    module = ""  # the module that holds the two functions
    functions = ("", "")  # (plan, table) function names in ``module``
    record_class = ("", "")  # (module, class) of its typed record, with ``from_details``

    def check(self, config: Config, file: str = "<configuration>") -> None:
        """`config.check_config` on the whole configuration."""
        check_config(config, file)

    def plan(self, scene: Scene, config: Config, angles: Sequence[int] | None = None,
             start: list[Candidate] | None = None) -> list[Candidate]:
        """The module's plan function on ``start`` (the baseline's candidates, planned here
        if None)."""
        if start is None:
            start = REGISTRY["baseline"].plan(scene, config, angles)
        return getattr(import_module(self.module), self.functions[0])(scene, config, start)

    def table(self, candidates: list[Candidate]) -> str:
        """The module's table function: a text table of the candidates, one row per angle."""
        return getattr(import_module(self.module), self.functions[1])(candidates)

    def record(self, details: dict):
        """Its record class's ``from_details``."""
        module, name = self.record_class
        return getattr(import_module(module), name).from_details(details)

    def score(self, details: dict, config: Config | None = None) -> float | None:
        """Its record's ``score()``."""
        return self.record(details).score()

    def plan_seconds(self, timings: dict) -> float | None:
        """The experiment's ``plan`` timing (s)."""
        return _plan_seconds(timings)

    def report_section(self, plans: dict[str, list[dict]]) -> ReportSection | None:
        """None unless the planner has a section of its own."""
        return None


class PhysicsPlanner(_FromBaseline):
    """Sec. V: iLQR through phi, the smooth-contact simulation, from the baseline's paths
    (`physics.pipeline.plan_physics`; table `stages_table`: seconds per stage and the phi
    objective)."""

    name = "physics"
    paper_row = "paper: physics-aware"
    module = "drake_clutter.planners.physics.pipeline"
    functions = ("plan_physics", "stages_table")
    record_class = ("drake_clutter.planners.physics.record", "PhysicsRecord")
    # the steps its ``timings["planner"]`` times (s)
    stages = ("pre", "search", "sphere", "full", "post", "select")

    def plan_seconds(self, timings: dict) -> float | None:
        """The sum of its steps' seconds (``timings["planner"]``); None for a row without
        them."""
        stages = timings.get("planner") or {}
        if "pre" not in stages:
            return None
        return float(sum(stages.get(s, 0.0) for s in self.stages))

    def report_section(self, plans: dict[str, list[dict]]) -> ReportSection | None:
        """Its phi stages per configuration (`physics.record.stages_section`, stages.csv)."""
        from drake_clutter.planners.physics.record import stages_section

        table, lines = stages_section(plans)
        return ReportSection("stages.csv", table, lines)


class PushPlanner(_FromBaseline):
    """Beyond the paper: a sampling search over paths that can push, scored by the judge in
    phi, from the baseline's paths at several grasp heights (`push.planner.plan_push`; table
    `push_table`: the path chosen, P(success) in phi, the seconds)."""

    name = "push"
    module = "drake_clutter.planners.push.planner"
    functions = ("plan_push", "push_table")
    record_class = ("drake_clutter.planners.push.record", "PushRecord")


class RearrangePlanner(_FromBaseline):
    """Beyond the paper: pushes that make room for the reach before it, from the push
    planner's answers (`rearrange.planner.plan_rearrange`; table `rearrange_table`: the plan,
    the boxes crowding the reach, P(success) in phi of it and of the push answer)."""

    name = "rearrange"
    starts_from = PushPlanner.name
    module = "drake_clutter.planners.rearrange.planner"
    functions = ("plan_rearrange", "rearrange_table")
    record_class = ("drake_clutter.planners.rearrange.record", "RearrangeRecord")

    def plan(self, scene: Scene, config: Config, angles: Sequence[int] | None = None,
             start: list[Candidate] | None = None) -> list[Candidate]:
        """`plan_rearrange` on ``start`` (the push planner's candidates, planned here if
        None)."""
        if start is None:
            start = REGISTRY[self.starts_from].plan(scene, config, angles)
        return super().plan(scene, config, angles, start)

    def score(self, details: dict, config: Config | None = None) -> float | None:
        """Its record's score where it rearranged, else the push planner's of the push
        answer it returned."""
        mine = self.record(details).score()
        if mine is not None:
            return mine
        return REGISTRY[self.starts_from].score(details.get("push") or {}, config)


REGISTRY: dict[str, Planner] = {p.name: p for p in (BaselinePlanner(), PhysicsPlanner(),
                                                    PushPlanner(), RearrangePlanner())}


# The reference every other planner is compared with (Sec. IV), by name.
BASELINE = BaselinePlanner.name
# The planners compared by default ("both" on the command line, the main job, the tiers): the
# baseline and the planner that beats it (the push planner; the paper's Sec. V is "physics").
COMPARED = (BASELINE, PushPlanner.name)
# The command-line name that stands for the `COMPARED` planners, in that order.
ALL_PLANNERS = "both"


def named_planners(names) -> tuple[str, ...]:
    """The planners ``names`` (an iterable of names) stand for, each once, in the order
    named; `ALL_PLANNERS` stands for `COMPARED`. Unknown names pass through (`get_planner`
    rejects them)."""
    out: list[str] = []
    for name in names:
        for one in COMPARED if name == ALL_PLANNERS else (name,):
            if one not in out:
                out.append(one)
    return tuple(out)


def planner_names() -> tuple[str, ...]:
    """The registered planners' names, in the registry's order."""
    return tuple(REGISTRY)


def get_planner(name: str, file: str = "<command line>", field: str = "planner") -> Planner:
    """The planner registered as ``name``; an unknown name raises InputError naming
    ``file`` and ``field``."""
    if name not in REGISTRY:
        raise InputError(file, field, f"unknown planner {name!r} (known: "
                                      f"{', '.join(REGISTRY)})")
    return REGISTRY[name]


def check_planners(config: Config, names: Sequence[str],
                   file: str = "<configuration>") -> None:
    """Checks the settings of the named planners and of the planners they start from."""
    seen: set[str] = set()
    for name in names:
        while name is not None and name not in seen:
            seen.add(name)
            planner = get_planner(name)
            planner.check(config, file)
            name = planner.starts_from


def run_planners(scene: Scene, config: Config, names: Sequence[str],
               angles: Sequence[int] | None = None,
               num_angles: int | None = None) -> dict[str, list[Candidate]]:
    """{name: candidates} for the named planners, in the order asked, each planner (and
    each planner one starts from) run once; ``num_angles`` overrides
    ``config.baseline.num_angles`` (rad angles spread over the same interval)."""
    if num_angles is not None:
        config = replace(config, baseline=replace(config.baseline, num_angles=num_angles))
    done: dict[str, list[Candidate]] = {}

    def run(name: str) -> list[Candidate]:
        if name not in done:
            planner = get_planner(name)
            start = run(planner.starts_from) if planner.starts_from else None
            done[name] = planner.plan(scene, config, angles, start)
        return done[name]

    return {name: run(name) for name in names}

