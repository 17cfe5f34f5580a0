"""What Sec. V's physics planner did at one approach angle (`PhysicsRecord`), and the score it
ranks by.

The pipeline (`pipeline.optimise_candidate`) fills a record stage by stage and stores it as the
candidate's ``details`` (`PhysicsRecord.to_details`); a stored one reads back with
`PhysicsRecord.from_details`. The keys: ``initialization`` (the planner the start came from),
``stages`` (per stage: iterations, stop reason, ``cost_history``, ``term_history``, the
line-search ``log``), ``grasp_height`` (the straight starts measured and the one chosen),
``start_score`` (the baseline's score of the path it started from), ``select`` (the objectives
in phi of the paths it chose among and the ``chosen`` one), ``time_budget`` (what the budget
cut), ``feedback`` (the last phi stage's gains and the boxes they refer to).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

PHI_STAGES = ("sphere", "full")  # the stages through phi, in order
SELECTIONS = ("post", "pre", "baseline", "search")  # the paths ``select`` chooses among
# the keys written whether or not they hold anything (``start_score`` may be None)
_ALWAYS = ("initialization", "stages", "start_score")


@dataclass
class PhysicsRecord:
    """A physics candidate's record (module docstring), filled by the pipeline as its stages
    run; fields absent from ``details`` are empty."""

    initialization: str = ""
    stages: dict = field(default_factory=dict)
    grasp_height: dict = field(default_factory=dict)
    start_score: float | None = None
    select: dict = field(default_factory=dict)
    time_budget: dict = field(default_factory=dict)
    feedback: dict = field(default_factory=dict)

    @classmethod
    def from_details(cls, details: dict) -> PhysicsRecord:
        """The record of a candidate's ``details`` (stored or fresh)."""
        start = details.get("start_score")
        return cls(initialization=str(details.get("initialization", "")),
                   stages=dict(details.get("stages") or {}),
                   grasp_height=dict(details.get("grasp_height") or {}),
                   start_score=None if start is None else float(start),
                   select=dict(details.get("select") or {}),
                   time_budget=dict(details.get("time_budget") or {}),
                   feedback=dict(details.get("feedback") or {}))

    def to_details(self) -> dict:
        """The record as a candidate's ``details`` (JSON-ready; empty fields other than
        ``initialization``, ``stages`` and ``start_score`` left out), the inverse of
        `from_details`."""
        out = {"stages": self.stages, "initialization": self.initialization,
               "grasp_height": self.grasp_height, "start_score": self.start_score,
               "select": self.select, "time_budget": self.time_budget,
               "feedback": self.feedback}
        return {k: v for k, v in out.items() if v or k in _ALWAYS}

    bent = False  # the physics planner's paths are iLQR's, not a family's members

    @property
    def chosen(self) -> str | None:
        """Which path ``select`` returned (one of `SELECTIONS`); None without a choice."""
        return self.select.get("chosen")

    @property
    def label(self) -> str:
        """The returned path in a few words (for titles and tables)."""
        return f"{self.chosen} path" if self.chosen else "optimised path"

    def histories(self) -> dict[str, dict]:
        """Per stage run, its ``cost_history`` and ``term_history`` (index 0: the start) and
        ``stop_reason`` (`viz.cost_curves`)."""
        return {name: {"cost_history": s.get("cost_history", []),
                       "term_history": s.get("term_history", []),
                       "stop_reason": s.get("stop_reason", "")}
                for name, s in self.stages.items() if isinstance(s, dict)}

    def score(self) -> float | None:
        """The physics planner's rank of the candidate, lower first: the objective in phi of
        the path it chose; for plans made before that choice existed, its last phi stage's
        final objective; with neither, ``start_score``; None without any."""
        if self.select:
            value = (self.select.get("objectives") or {}).get(self.chosen)
        else:
            last = self.stages.get("full") or self.stages.get("sphere") or {}
            value = (last.get("cost_history") or [None])[-1]
            if value is None:
                value = self.start_score
        return None if value is None else float(value)


def stage_statistics(plans: dict[str, list[dict]]) -> list[dict]:
    """Per configuration (``plans``: configuration name -> its stored plans' ``details``) and
    phi stage: the stages run, those that accepted at least one iLQR iteration (count and %),
    the accepted steps and the quartiles of their actual / predicted decrease (the model's at
    the accepted step size), and how often each path was the plan (`SELECTIONS`; stages
    without a choice are not counted)."""
    out = []
    for config_name, details in plans.items():
        records = [PhysicsRecord.from_details(d) for d in details]
        chosen = [r.chosen for r in records]
        for stage in PHI_STAGES:
            runs = [r.stages[stage] for r in records if stage in r.stages]
            ratios = [e["actual"] / e["predicted"] for run in runs for e in run["log"]
                      if e.get("alpha", 0.0) > 0 and e.get("predicted", 0.0) > 0]
            accepting = sum(run["iterations"] > 0 for run in runs)
            q = (np.percentile(ratios, [25, 50, 75]) if ratios else [None] * 3)
            out.append({"configuration": config_name, "stage": stage, "stages": len(runs),
                        "accepting": accepting,
                        "accepting_pct": 100.0 * accepting / len(runs) if runs else None,
                        "accepted_steps": len(ratios), "ratio_q25": q[0], "ratio_median": q[1],
                        "ratio_q75": q[2],
                        **{f"chosen_{n}": chosen.count(n) for n in SELECTIONS}})
    return out


def markdown_stages(table: list[dict]) -> str:
    """`stage_statistics` as Markdown."""
    lines = ["| configuration | stage | stages | accepting >= 1 iteration | accepted steps | "
             "actual / predicted: median [quartiles] | plan chosen: post / pre / baseline / "
             "search |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for r in table:
        ratio = ("-" if r["ratio_median"] is None else f"{r['ratio_median']:.2f} "
                 f"[{r['ratio_q25']:.2f}, {r['ratio_q75']:.2f}]")
        accepting = "-" if r["accepting_pct"] is None else f"{r['accepting_pct']:.1f}%"
        lines.append(f"| {r['configuration']} | {r['stage']} | {r['stages']} | "
                     f"{r['accepting']} ({accepting}) | {r['accepted_steps']} | "
                     f"{ratio} | {r['chosen_post']} / {r['chosen_pre']} / "
                     f"{r['chosen_baseline']} / {r['chosen_search']} |")
    return "\n".join(lines)


def stages_section(plans: dict[str, list[dict]]) -> tuple[list[dict], list[str]]:
    """The report's section on the phi stages of ``plans`` (as `stage_statistics`): its table
    and its Markdown lines; nothing without plans."""
    table = stage_statistics(plans)
    if not table:
        return table, []
    return table, [
        "## The physics planner's phi stages (Sec. V)", "",
        "Per phi stage: how many accepted at least one iLQR iteration, and for the accepted "
        "steps the actual decrease of phi's objective over the quadratic model's at the "
        "accepted step size (1: the model was right; the trust region clips steps after the "
        "model). The plan is the best in phi of the post-processed, pre-processed and "
        "baseline paths. Per stage: stages.csv.", "", markdown_stages(table), ""]
