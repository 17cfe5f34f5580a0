"""Cost curves of a physics plan: every cost term against the iLQR iteration, one PNG per plan.

The physics planner (`pipeline.optimise_candidate`) stores, per stage (``pre``, ``sphere``,
``full``, ``post``; Sec. V), the objective after each accepted iLQR iteration and its value per
term (``details["stages"][stage]["cost_history"]`` and ``["term_history"]``, index 0 being the
start). The figure has one panel per stage (each stage has its own objective), each term a
line and the total a dashed black line, on a symmetric-log y axis (terms span many orders of
magnitude and some are exactly 0). Uses matplotlib's Agg canvas directly (no pyplot state, no
display needed).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from drake_clutter.common.typed_yaml import InputError
from drake_clutter.trajectory import Candidate

STAGE_ORDER = ("pre", "sphere", "full", "post")  # physics.optimise_candidate's stages
_LINTHRESH = 1e-6  # symlog's linear range around 0; ours: below every term's useful scale


@dataclass(frozen=True)
class StageCurves:
    """One stage's history: iterations (0 = start), the total and each term per iteration."""

    stage: str
    iterations: np.ndarray
    total: np.ndarray
    terms: dict[str, np.ndarray]
    stop_reason: str = ""


def stage_curves(candidate: Candidate) -> list[StageCurves]:
    """The cost histories in a physics candidate's details, stages in pipeline order; [] for a
    candidate without any (a baseline plan, or a physics plan that failed before iLQR).

    Raises ValueError when a stage record is malformed (terms missing at some iteration, or
    histories of different lengths)."""
    stages = candidate.details.get("stages", {}) if isinstance(candidate.details, dict) else {}
    names = [s for s in STAGE_ORDER if s in stages] + sorted(set(stages) - set(STAGE_ORDER))
    curves = []
    for name in names:
        record = stages[name]
        totals = np.asarray(record.get("cost_history", []), dtype=float)
        history = record.get("term_history", [])
        if len(history) != len(totals):
            raise ValueError(f"stage {name}: {len(history)} term records for {len(totals)} "
                             f"costs")
        if not len(totals):
            continue
        keys = list(dict.fromkeys(k for h in history for k in h))
        missing = [k for k in keys if any(k not in h for h in history)]
        if missing:
            raise ValueError(f"stage {name}: term {missing[0]!r} missing at some iteration")
        terms = {k: np.array([h[k] for h in history], dtype=float) for k in keys}
        curves.append(StageCurves(name, np.arange(len(totals)), totals, terms,
                                  str(record.get("stop_reason", ""))))
    return curves


def plot_cost_curves(candidate: Candidate, path: str | Path, title: str = "") -> Path | None:
    """Writes the PNG of a physics candidate's cost curves to ``path``; returns the path, or
    None (nothing written) when the candidate has no iLQR history. Raises InputError when the
    file cannot be written."""
    curves = stage_curves(candidate)
    if not curves:
        return None
    figure = Figure(figsize=(4.2 * len(curves), 3.8), dpi=100, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(1, len(curves), squeeze=False)[0]
    for ax, curve in zip(axes, curves, strict=True):
        for name, values in curve.terms.items():
            ax.plot(curve.iterations, values, marker=".", label=name)
        ax.plot(curve.iterations, curve.total, "k--", label="total")
        ax.set_yscale("symlog", linthresh=_LINTHRESH)
        ax.set_xlabel("iLQR iteration")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_title(f"{curve.stage} ({curve.stop_reason})" if curve.stop_reason
                     else curve.stage, fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("weighted cost")
    figure.suptitle(title or f"{candidate.planner} plan, alpha = {candidate.alpha:+.3f} rad")
    path = Path(path)
    try:
        figure.savefig(path, format="png")
    except OSError as exc:
        raise InputError(path, "--html", f"cannot write the cost curves: {exc.strerror}") from None
    return path
