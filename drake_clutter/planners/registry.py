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
from dataclasses import replace
from importlib import import_module
from typing import Literal, Protocol

from drake_clutter.common.config import Config, check_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.scene.scenes import Scene
from drake_clutter.trajectory import Candidate

# the registry's keys, as typed YAML reads them
PlannerName = Literal["baseline", "physics", "push"]


class Planner(Protocol):
    """What a planner offers its callers."""

    name: str  # its registry key, the ``planner`` of its candidates and of stored rows
    starts_from: str | None  # the planner whose candidates it refines; None: from scratch

    def check(self, config: Config, file: str = "<configuration>") -> None:
        """Raises ConfigError naming the first of its settings that makes no sense."""

    def plan(self, scene: Scene, config: Config, angles: Sequence[int] | None = None,
             start: list[Candidate] | None = None) -> list[Candidate]:
        """One Candidate per approach angle (all, or the listed indices), in order; ``start``:
        the ``starts_from`` planner's candidates of the same angles (planned here if None)."""

    def table(self, candidates: list[Candidate]) -> str:
        """A text table of its candidates, one row per angle."""


class BaselinePlanner:
    """Sec. IV: straight-line approach angles, IK, optimisation against the static shelf."""

    name = "baseline"
    starts_from = None

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


class _FromBaseline:
    """A planner that refines the baseline's candidates: its module's ``plan(scene, config,
    start)`` and ``table(candidates)`` functions, imported when first used."""

    starts_from = "baseline"
    module = ""  # the module that holds the two functions
    functions = ("", "")  # (plan, table) function names in ``module``

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


class PhysicsPlanner(_FromBaseline):
    """Sec. V: iLQR through phi, the smooth-contact simulation, from the baseline's paths
    (`physics.pipeline.plan_physics`; table `stages_table`: seconds per stage and the phi
    objective)."""

    name = "physics"
    module = "drake_clutter.planners.physics.pipeline"
    functions = ("plan_physics", "stages_table")


class PushPlanner(_FromBaseline):
    """Beyond the paper: a sampling search over paths that can push, scored by the judge in
    phi, from the baseline's paths at several grasp heights (`push.planner.plan_push`; table
    `push_table`: the path chosen, P(success) in phi, the seconds)."""

    name = "push"
    module = "drake_clutter.planners.push.planner"
    functions = ("plan_push", "push_table")


REGISTRY: dict[str, Planner] = {p.name: p for p in (BaselinePlanner(), PhysicsPlanner(),
                                                    PushPlanner())}


# The planners compared by default ("both" on the command line, the main job, the tiers): the
# baseline and the planner that beats it (the push planner; the paper's Sec. V is "physics").
COMPARED = ("baseline", "push")


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

