"""Experiments of Sec. VI-B: specs, named tiers, work units, and the worker that runs one unit.

An `ExperimentSpec` (YAML, loaded with `load_spec`) names the scenes (a named scene set of
`generators.scene_set`, explicit generated levels and seeds, or shipped scenes), the planners
(``baseline``: Sec. IV; ``physics``: Sec. V from the baseline's candidate; ``push``: the push
planner from it), the approach angles (indices into `approach.approach_angles`, default all
``baseline.num_angles``) and named configurations: each a list of ``section.field=value``
overrides applied to the project `Config` after the spec's common ``overrides``.

`expand` turns a spec into `WorkUnit` s, one per (scene, planner, angle, configuration). A
unit is plain data: `run_unit` rebuilds the scene and the configuration from it, plans that
one angle, replays the result in Bullet (Sec. III) and returns a plain dict (`UnitResult`
fields). It never raises for a planner or evaluation error: the error becomes a row of kind
``planner_failure`` with the error text.

A configuration is identified by `config_hash`, the hash of the whole resolved `Config`
(not of the override strings; drawing settings left out): two spellings of the same settings
share rows, and a change of a default in config.py gives new rows instead of silently
mixing results.

Single angles (ours): `baseline.plan_baseline` plans a scene's angles in a row and seeds each
angle's IK with its neighbour's solution. A unit plans its angle alone, with the same
per-angle random seeds (``ik_seed + index``) but without the neighbour seed, so that every
unit is independent and deterministic whatever the executor and the order of the units.
"""

from __future__ import annotations

import hashlib
import json
import time
import traceback
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Literal

from drake_clutter.common.accepts import SEED_MAX, bounded
from drake_clutter.common.config import Config, config_to_data, load_config
from drake_clutter.common.typed_yaml import InputError, from_data, read_yaml_file
from drake_clutter.planners.registry import (
    PlannerName,
    check_planners,
    planner_names,
    run_planners,
)

TIERS = ("smoke", "small", "paper", "behaviours", "probe", "probe_half", "heldout", "candidates",
         "paper_protocol")
TIER_PACKAGE = "drake_clutter.experiments.tiers"
DEAD_WORKER = "planner_failure"  # the outcome kind of a unit whose worker died or raised


class SpecError(InputError):
    """An experiment spec file is invalid; the message names file, field and reason."""


@dataclass(frozen=True)
class GeneratedScenes:
    """Random scenes (`generators.generate_scene`) of one kind: every level x every seed."""

    kind: Literal["bookshelf", "fridge"]
    levels: tuple[int, ...] = bounded(ge=1, le=40)  # boxes per scene, the target included
    seeds: tuple[int, ...] = bounded(ge=0, le=SEED_MAX)


@dataclass(frozen=True)
class ExperimentSpec:
    """What to run (see the module docstring); every list is run in full (a product)."""

    name: str
    planners: tuple[PlannerName, ...] = ("baseline",)
    scene_set: str = ""  # a named set of generators.scene_set ("" = none)
    # with scene_set: the first k scenes per (kind, level); 0 = all
    scenes_per_level: int = bounded(0, ge=0, le=10000)
    generated: tuple[GeneratedScenes, ...] = ()
    shipped: tuple[str, ...] = ()  # shipped scene names (scenes.shipped_scene_names)
    angles: tuple[int, ...] = ()  # approach-angle indices; () = all baseline.num_angles
    overrides: tuple[str, ...] = ()  # section.field=value applied under every configuration
    configurations: dict[str, tuple[str, ...]] = field(
        default_factory=lambda: {"default": ()})
    description: str = ""
    # ours: Ray re-runs a task whose worker died this many times (a node lost twice in a row
    # is no longer bad luck); then the unit is a failed row
    ray_max_retries: int = bounded(2, ge=0, le=10)


@dataclass(frozen=True)
class WorkUnit:
    """One (scene, planner, angle, configuration): plain data a worker process can rebuild.

    ``source`` is ("generated", kind, num_objects, seed) or ("shipped", name, kind, num_objects).
    """

    scene: str
    kind: str
    num_objects: int
    source: tuple
    planner: str
    angle: int
    config_name: str
    config_hash: str
    overrides: tuple[str, ...]

    @property
    def key(self) -> tuple[str, str, int, str]:
        """The store's unique key: (scene, planner, angle, config_hash)."""
        return (self.scene, self.planner, self.angle, self.config_hash)

    def to_data(self) -> dict:
        """JSON-ready dict (tuples become lists)."""
        return {"scene": self.scene, "kind": self.kind, "num_objects": self.num_objects,
                "source": list(self.source), "planner": self.planner, "angle": self.angle,
                "config_name": self.config_name, "config_hash": self.config_hash,
                "overrides": list(self.overrides)}


# ----------------------------------------------------------------------------- specs


def tier_path(name: str) -> Path:
    """The shipped YAML file of a named tier."""
    return Path(str(resources.files(TIER_PACKAGE) / f"{name}.yaml"))


def load_spec(spec: str | Path) -> tuple[ExperimentSpec, str]:
    """A spec from a YAML file or a tier name (TIERS); returns (spec, the file it came from).

    Raises SpecError naming the file, the field and the reason (also for overrides that do not
    apply to the configuration, unknown scene sets, shipped names or angle indices).
    """
    path = tier_path(str(spec)) if str(spec) in TIERS else Path(spec)
    if str(spec) not in TIERS and not path.exists() and path.suffix not in (".yaml", ".yml"):
        raise SpecError("<command line>", "SPEC", f"{spec!r} is neither a spec file nor a tier "
                        f"(tiers: {', '.join(TIERS)})")
    data = read_yaml_file(path, error_cls=SpecError)
    if not isinstance(data, dict):
        raise SpecError(path, "", "an experiment spec must be a YAML mapping")
    result = from_data(ExperimentSpec, data, file=path, error_cls=SpecError)
    check_spec(result, path)
    return result, str(path)


def check_spec(spec: ExperimentSpec, file) -> None:
    """Raises SpecError for a spec that names nothing to run or things that do not exist."""
    from drake_clutter.scene.generators import SCENE_SETS
    from drake_clutter.scene.scenes import shipped_scene_names

    if not spec.planners:
        raise SpecError(file, "planners", "name at least one planner")
    if len(set(spec.planners)) != len(spec.planners):
        raise SpecError(file, "planners", "lists a planner twice")
    if spec.scene_set and spec.scene_set not in SCENE_SETS:
        raise SpecError(file, "scene_set", f"unknown scene set {spec.scene_set!r} "
                                           f"(known: {', '.join(SCENE_SETS)})")
    for i, gen in enumerate(spec.generated):
        if not gen.levels:
            raise SpecError(file, f"generated[{i}].levels", "must list at least one level")
        if not gen.seeds:
            raise SpecError(file, f"generated[{i}].seeds", "must list at least one seed")
    known = shipped_scene_names()
    for i, name in enumerate(spec.shipped):
        if name not in known:
            raise SpecError(file, f"shipped[{i}]", f"no shipped scene {name!r}")
    if not (spec.scene_set or spec.generated or spec.shipped):
        raise SpecError(file, "scene_set", "name some scenes (scene_set, generated or shipped)")
    if not spec.configurations:
        raise SpecError(file, "configurations", "name at least one configuration")
    hashes: dict[str, str] = {}
    for name in spec.configurations:
        config = resolve_config(spec, name, file)
        bad = [a for a in spec.angles if not 0 <= a < config.baseline.num_angles]
        if bad:
            raise SpecError(file, "angles", f"index {bad[0]} outside 0..."
                            f"{config.baseline.num_angles - 1} (configuration {name!r})")
        digest = config_hash(config)
        if digest in hashes:
            raise SpecError(file, f"configurations.{name}", f"the same settings as "
                                                            f"configuration {hashes[digest]!r}")
        hashes[digest] = name


def resolve_config(spec: ExperimentSpec, name: str, file="<spec>") -> Config:
    """The project Config of configuration ``name``: defaults, the spec's common overrides,
    then the configuration's own. A bad override, a value outside its field's declared range
    (checked on loading) or a setting the planners reject (`Planner.check`) raises SpecError
    naming the field."""
    where = "overrides"
    try:
        load_config(None, list(spec.overrides))
        where = f"configurations.{name}"
        config = load_config(None, list(spec.overrides) + list(spec.configurations[name]))
        check_planners(config, planner_names())
    except InputError as exc:
        raise SpecError(file, f"{where} ({exc.field})", exc.reason) from None
    return config


UNHASHED_SECTIONS = ("viz", "report")  # sections that cannot change a row (drawing, statistics)


def config_hash(config: Config) -> str:
    """16 hex digits of the SHA-256 of the resolved configuration's canonical JSON, without
    the UNHASHED_SECTIONS (a change of colours must not make finished rows stale)."""
    data = {k: v for k, v in config_to_data(config).items() if k not in UNHASHED_SECTIONS}
    text = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _scene_sources(spec: ExperimentSpec, config: Config) -> list[tuple]:
    """("generated", kind, n, seed) / ("shipped", name, kind, n) of the spec, in order."""
    from drake_clutter.scene.generators import scene_set
    from drake_clutter.scene.scenes import load_shipped_scene

    sources: list[tuple] = []
    if spec.scene_set:
        counts: dict[tuple, int] = {}
        for s in scene_set(spec.scene_set, config.generator):
            level = (s.kind, s.num_objects)
            counts[level] = counts.get(level, 0) + 1
            if spec.scenes_per_level == 0 or counts[level] <= spec.scenes_per_level:
                sources.append(("generated", s.kind, s.num_objects, s.seed))
    for gen in spec.generated:
        sources += [("generated", gen.kind, n, seed) for n in gen.levels for seed in gen.seeds]
    for name in spec.shipped:
        scene = load_shipped_scene(name)
        sources.append(("shipped", name, scene.shelf.kind, len(scene.boxes)))
    return list(dict.fromkeys(sources))  # drop repeats, keep the order


def check_scenes(spec: ExperimentSpec, file="<spec>") -> None:
    """Builds every generated scene of the spec once (about 0.3 s each) and raises SpecError
    naming the spec's field if one cannot be placed (too many boxes for the board under the
    configuration's generator settings), so that a run writes no store for it."""
    from drake_clutter.scene.generators import GenerationError

    fields = {("generated", g.kind, n, seed): f"generated[{i}]"
              for i, g in enumerate(spec.generated) for n in g.levels for seed in g.seeds}
    for name in spec.configurations:
        config = resolve_config(spec, name, file)
        for source in _scene_sources(spec, config):
            if source[0] != "generated":
                continue
            _, kind, n, seed = source
            try:
                build_scene(source, config)
            except (GenerationError, ValueError) as exc:
                raise SpecError(file, fields.get(source, "scene_set"),
                                f"{kind} scene with {n} boxes, seed {seed}: {exc}") from None


def _scene_identity(source: tuple) -> tuple[str, str, int]:
    from drake_clutter.scene.generators import SceneSpec

    if source[0] == "generated":
        _, kind, n, seed = source
        return SceneSpec(kind, n, seed).name, kind, n
    _, name, kind, n = source
    return name, kind, n


def expand(spec: ExperimentSpec, file="<spec>") -> list[WorkUnit]:
    """The spec's work units, ordered configuration, scene, planner, angle (deterministic)."""
    units = []
    for name in spec.configurations:
        config = resolve_config(spec, name, file)
        digest = config_hash(config)
        overrides = tuple(spec.overrides) + tuple(spec.configurations[name])
        angles = spec.angles or tuple(range(config.baseline.num_angles))
        for source in _scene_sources(spec, config):
            scene, kind, n = _scene_identity(source)
            for planner in spec.planners:
                units += [WorkUnit(scene, kind, n, source, planner, a, name, digest, overrides)
                          for a in angles]
    return units


# ----------------------------------------------------------------------------- the worker


def build_scene(source, config: Config):
    from drake_clutter.scene.generators import generate_scene
    from drake_clutter.scene.scenes import load_shipped_scene

    if source[0] == "generated":
        _, kind, n, seed = source
        return generate_scene(kind, int(n), int(seed), config.generator)
    return load_shipped_scene(source[1])


def stored_scene(name: str, config: Config):
    """The scene of a stored row's ``scene`` name: a generated scene rebuilt from its name
    (kind, boxes, seed) with ``config.generator``, else a shipped scene (SceneError if
    neither)."""
    from drake_clutter.scene.generators import SceneSpec, generate_scene
    from drake_clutter.scene.scenes import load_shipped_scene

    spec = SceneSpec.from_name(name)
    if spec is not None:
        return generate_scene(spec.kind, spec.num_objects, spec.seed, config.generator)
    return load_shipped_scene(name)


def plan_one_angle(scene, config: Config, planner: str, index: int):
    """The Candidate of approach angle ``index`` (of `approach.approach_angles`) planned alone
    (see the module docstring): Sec. IV's baseline, or Sec. V's physics planner run on that
    baseline candidate."""
    return run_planners(scene, config, [planner], angles=[index])[planner][0]


def run_unit(unit: dict) -> dict:
    """Runs one work unit (`WorkUnit.to_data`): build, plan one angle, evaluate in Bullet.

    Returns plain data: ``outcome`` (`judge.Outcome.to_data` without its wall time),
    ``plan`` (`trajectory.Candidate.to_data` without its timings and the wall times in its
    details), ``timings`` (s: ``plan``, ``eval``, and the planner's and evaluation's own
    breakdown, `split_wall_times`), ``alpha`` (rad) and ``error``
    (the exception text when planning or evaluating raised, then kind planner_failure).
    Outcome and plan are deterministic in the unit; timings are not.
    """
    from drake_clutter.evaluation.judge import evaluate_candidates
    from drake_clutter.evaluation.outcome import Outcome

    result = {"alpha": None, "plan": None, "timings": {}, "error": ""}
    try:
        config = load_config(None, list(unit["overrides"]))
        scene = build_scene(unit["source"], config)
        tic = time.perf_counter()
        candidate = plan_one_angle(scene, config, unit["planner"], int(unit["angle"]))
        plan_seconds = time.perf_counter() - tic
        tic = time.perf_counter()
        outcome = evaluate_candidates(scene, [candidate], config.evaluation)[0]
        eval_seconds = time.perf_counter() - tic
    except Exception as exc:  # any planner or evaluation error is a recorded row, not a crash
        result["outcome"] = Outcome(DEAD_WORKER, f"exception: {exc!r}").to_data()
        result["error"] = "".join(traceback.format_exception(exc))[-4000:]
        return _strip(result)
    plan = candidate.to_data()
    result.update(alpha=candidate.alpha, plan=plan, outcome=outcome.to_data(), timings={
        "plan": plan_seconds, "eval": eval_seconds, "planner": plan.pop("timings"),
        "planner_details": split_wall_times(plan["details"]), "eval_wall": outcome.wall_time})
    return _strip(result)


# in a plan's details: computer time (a budget's longest indivisible step included)
WALL_TIME_KEYS = ("seconds", "timings", "wall_time", "longest_step")


def split_wall_times(details: dict) -> dict:
    """Removes the wall-time entries (WALL_TIME_KEYS, at any depth) from a plan's ``details``
    in place and returns them in the same nesting, so the plan stays deterministic."""
    taken = {}
    for key in list(details):
        value = details[key]
        if key in WALL_TIME_KEYS:
            taken[key] = details.pop(key)
        elif isinstance(value, dict):
            inner = split_wall_times(value)
            if inner:
                taken[key] = inner
    return taken


def _strip(result: dict) -> dict:
    result["outcome"].pop("wall_time", None)
    return result


def failure_result(reason: str, error: str) -> dict:
    """The result of a unit that produced nothing (its worker died, its task was lost)."""
    from drake_clutter.evaluation.outcome import Outcome

    return _strip({"alpha": None, "plan": None, "timings": {}, "error": error,
                   "outcome": Outcome(DEAD_WORKER, reason).to_data()})
