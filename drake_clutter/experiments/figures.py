"""Fig. 9 of Sec. VI-B as pictures: per environment the percentage of scenes with success and
with success or partial success against the number of objects (9a bookshelf, 9b refrigerator),
and the mean planning time per initialization (9c), one series per configuration and planner,
from `report.fig9_data`'s points; also the environments' names as the report's tables print
them.
"""

from __future__ import annotations

from pathlib import Path

ENVIRONMENTS = ("bookshelf", "fridge")
ENV_LABELS = {"bookshelf": "Bookshelf", "fridge": "Refrigerator", "aggregate": "Aggregate"}


def _axes_figure(title: str):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0, 4.0), dpi=100)
    ax = fig.add_subplot()
    ax.set_title(title)
    return fig, ax


def _draw_success(ax, data: list[dict], env: str) -> None:
    """% scenes with success (solid), success or partial (dashed) and robust success (dotted:
    the mean of each scene's best P(success)) against the number of objects, one colour per
    (configuration, planner)."""
    for i, (key, points) in enumerate(_series(data, env).items()):
        x = [p["num_objects"] for p in points]
        colour = f"C{i}"
        ax.plot(x, [p["success_pct"] for p in points], "o-", color=colour,
                label=f"{key[1]} ({key[0]}): success")
        ax.plot(x, [p["success_or_partial_pct"] for p in points], "s--", color=colour,
                alpha=0.6, label=f"{key[1]} ({key[0]}): success or partial")
        ax.plot(x, [p["robust_success_pct"] for p in points], "^:", color=colour,
                alpha=0.8, label=f"{key[1]} ({key[0]}): robust success")
    ax.set_xlabel("number of objects")
    ax.set_ylabel("scenes (%)")
    ax.set_ylim(-5, 105)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")


def _draw_time(ax, data: list[dict]) -> None:
    """Mean planning time per initialization (s, log scale) against the number of objects."""
    i = 0
    for env in ENVIRONMENTS:
        for key, points in _series(data, env).items():
            points = [p for p in points if p["mean_seconds_per_init"] is not None]
            if points:
                ax.plot([p["num_objects"] for p in points],
                        [p["mean_seconds_per_init"] for p in points], "o-", color=f"C{i}",
                        label=f"{key[1]} ({key[0]}), {ENV_LABELS[env].lower()}")
                i += 1
    ax.set_xlabel("number of objects")
    ax.set_ylabel("seconds per initialization")
    ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    if i:
        ax.legend(fontsize=7)


def plot_success(data: list[dict], env: str, path: Path) -> Path:
    """Fig. 9a (bookshelf) / 9b (fridge) as a PNG (see `_draw_success`)."""
    letter = "a" if env == "bookshelf" else "b"
    fig, ax = _axes_figure(f"Fig. 9{letter}: {ENV_LABELS[env]} (ours)")
    _draw_success(ax, data, env)
    fig.tight_layout()
    fig.savefig(path, format="png")
    return path


def plot_time(data: list[dict], path: Path) -> Path:
    """Fig. 9c as a PNG: mean planning time per initialization against the number of objects."""
    fig, ax = _axes_figure("Fig. 9c: time per initialization (ours)")
    _draw_time(ax, data)
    fig.tight_layout()
    fig.savefig(path, format="png")
    return path


def plot_combined(data: list[dict], path: Path) -> Path:
    """Fig. 9 as the paper lays it out: (a), (b) and (c) side by side, one PNG."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(16.0, 4.5), dpi=100)
    axes = fig.subplots(1, 3)
    for ax, env, letter in ((axes[0], "bookshelf", "a"), (axes[1], "fridge", "b")):
        ax.set_title(f"({letter}) {ENV_LABELS[env]}")
        _draw_success(ax, data, env)
    axes[2].set_title("(c) time per initialization")
    _draw_time(axes[2], data)
    fig.tight_layout()
    fig.savefig(path, format="png")
    return path


def _series(data: list[dict], env: str) -> dict[tuple[str, str], list[dict]]:
    out: dict[tuple[str, str], list[dict]] = {}
    for p in data:
        if p["environment"] == env:
            out.setdefault((p["configuration"], p["planner"]), []).append(p)
    return out

