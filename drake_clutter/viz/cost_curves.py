"""Cost curves of a plan made by iLQR: every cost term against the iteration, one PNG per plan.

A planner's record gives, per stage (the physics planner's ``pre``, ``sphere``, ``full``,
``post``; Sec. V), the objective after each accepted iLQR iteration and its value per term
(``histories()``: per stage ``cost_history`` and ``term_history``, index 0 being the start,
and ``stop_reason``); a planner without iLQR gives none. The figure has one panel per stage
(each stage has its own objective), each term a line and the total a dashed black line, on a
symmetric-log y axis (terms span many orders of magnitude and some are exactly 0). Uses
matplotlib's Agg canvas directly (no pyplot state, no display needed).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from drake_clutter.common.typed_yaml import InputError

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


def stage_curves(stages: dict[str, dict]) -> list[StageCurves]:
    """The cost histories of ``stages`` (a record's ``histories()``), stages in pipeline
    order; [] for none (a baseline plan, or a physics plan that failed before iLQR).

    Raises ValueError when a stage record is malformed (terms missing at some iteration, or
    histories of different lengths)."""
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


def plot_cost_curves(stages: dict[str, dict], path: str | Path, title: str = "") -> Path | None:
    """Writes the PNG of the cost curves of ``stages`` (a record's ``histories()``) to
    ``path``, titled ``title``; returns the path, or None (nothing written) when there is no
    iLQR history. Raises InputError when the file cannot be written."""
    curves = stage_curves(stages)
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
    figure.suptitle(title or "cost curves")
    path = Path(path)
    try:
        figure.savefig(path, format="png")
    except OSError as exc:
        raise InputError(path, "--html", f"cannot write the cost curves: {exc.strerror}") from None
    return path
